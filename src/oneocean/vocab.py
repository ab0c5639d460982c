"""The one vocabulary of OneOcean: ``Literal`` aliases plus a single validator.

Snakemake's ``wildcard_constraints`` and the config schema are built from the same tuples.
Task ids and method names are not listed here: they come from :mod:`oneocean.registry`
(``TASK_IDS`` and ``METHODS`` are live read-only views of it).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal, get_args

from .errors import ConfigError

Variant = Literal["tiny", "scene", "public"]
SourceKind = Literal["synthetic", "cmems", "gebco", "etopo", "files"]
Dynamics = Literal["kinematic", "3dof", "4dof", "6dof"]
#: A registered task id (:func:`oneocean.registry.task_ids`).
TaskId = str
Tier = Literal[1, 2, 3]
#: A registered method name (:func:`oneocean.registry.method_names`).
Method = str

VARIANTS: tuple[str, ...] = get_args(Variant)
SOURCE_KINDS: tuple[str, ...] = get_args(SourceKind)
DYNAMICS: tuple[str, ...] = get_args(Dynamics)
TIERS: tuple[int, ...] = get_args(Tier)


class _RegistryView(Sequence):
    """A read-only, always-current tuple-like view of a registry listing (lazy: reading the
    registry happens on first use, not at import)."""

    def __init__(self, getter):
        self._get = getter

    def __getitem__(self, i):
        return self._get()[i]

    def __len__(self):
        return len(self._get())

    def __iter__(self):
        return iter(self._get())

    def __contains__(self, value):
        return value in self._get()

    def __eq__(self, other):
        if isinstance(other, (_RegistryView, tuple, list)):
            return tuple(self) == tuple(other)
        return NotImplemented

    __hash__ = None

    def __repr__(self):
        return repr(self._get())


def _task_ids():
    from .registry import task_ids
    return task_ids()


def _method_names():
    from .registry import method_names
    return method_names()


#: Every registered task id, the paper's ladder (G2G, SK, RF, DPT, AS, PI, FT, SPC, UPL, FH)
#: first (a live view of :func:`oneocean.registry.task_ids`).
TASK_IDS: Sequence[str] = _RegistryView(_task_ids)
#: Every registered method: the paper's heuristic baseline, a privileged oracle (solvability
#: check), behaviour cloning (``bc``), then the configured LLM planners' and plugins' (a live
#: view of :func:`oneocean.registry.method_names`).
METHODS: Sequence[str] = _RegistryView(_method_names)

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
    """Return ``value`` if it is one of ``options``; otherwise raise a one-line ConfigError.

    Parameters
    ----------
    value : object
        The value to check.
    options : collection
        The valid values (membership test; listed in the error message).
    name : str
        The key or argument name, for the message.

    Returns
    -------
    object
        ``value`` itself.

    Raises
    ------
    ConfigError
        If ``value`` is not in ``options``.
    """
    if value not in options:
        opts = ", ".join(repr(o) for o in options)
        raise ConfigError(f"{name}: invalid value {value!r}. Valid options are ({opts}).")
    return value

#: The default evaluation seed (``rollouts.seed``; ``oneocean evaluate --seed``): held out from
#: every tier table's ``calibration.seeds`` (checked by the config validation).
EVALUATION_SEED = 1000
