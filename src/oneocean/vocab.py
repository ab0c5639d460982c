"""The one vocabulary of OneOcean: ``Literal`` aliases plus a single validator.

Snakemake's ``wildcard_constraints`` and the config schema are built from the same tuples.
"""

from __future__ import annotations

from typing import Literal, get_args

from .errors import ConfigError

Variant = Literal["tiny", "scene", "public"]
SourceKind = Literal["synthetic", "cmems", "gebco", "etopo", "files"]
Dynamics = Literal["kinematic", "3dof", "4dof", "6dof"]
TaskId = Literal["G2G", "SK", "RF", "DPT", "AS", "PI", "FT", "SPC", "UPL", "FH"]
Tier = Literal[1, 2, 3]
#: Implemented rollout methods: the paper's heuristic baseline and a privileged oracle
#: (solvability check). BC and the LLM planner are not implemented yet.
Method = Literal["heuristic", "oracle"]

VARIANTS: tuple[str, ...] = get_args(Variant)
SOURCE_KINDS: tuple[str, ...] = get_args(SourceKind)
DYNAMICS: tuple[str, ...] = get_args(Dynamics)
TASK_IDS: tuple[str, ...] = get_args(TaskId)
TIERS: tuple[int, ...] = get_args(Tier)
METHODS: tuple[str, ...] = get_args(Method)

#: Canonical (CF) names used everywhere downstream of the readers.
CF = {
    "u": "eastward_sea_water_velocity",
    "v": "northward_sea_water_velocity",
    "u_tide": "eastward_sea_water_velocity_due_to_tides",
    "v_tide": "northward_sea_water_velocity_due_to_tides",
    "elevation": "height_above_mean_sea_level",
    "land_mask": "land_binary_mask",
    "valid_mask": "status_flag",
}


def validate_choice(value, options, name: str):
    """Return ``value`` if it is one of ``options``; otherwise raise a one-line ConfigError."""
    if value not in options:
        opts = ", ".join(repr(o) for o in options)
        raise ConfigError(f"{name}: invalid value {value!r}. Valid options are ({opts}).")
    return value
