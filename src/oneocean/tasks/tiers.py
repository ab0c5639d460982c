"""Tier tables: a task's table file (``data/tasks/<ID>.yaml``) parsed and checked, one
tier's parameters (for a scene, its ``scene_tiers`` row on top), the tasks that run in a
scene, and the two tier checks every task makes (:func:`need_tier`, :func:`episode_steps`).
"""

from __future__ import annotations

import copy
import functools
import math
import os
from importlib import resources
from pathlib import Path

import yaml

from ..errors import ConfigError, NotApplicable


def _tiers_dir() -> Path:
    return Path(str(resources.files("oneocean") / "data" / "tasks"))


def load_task_table(task_id: str, path: str | Path | None = None) -> dict:
    """The tier table of one task.

    Parsed once per file version; every call returns a fresh copy (callers may change it).

    Parameters
    ----------
    task_id : str
        Registered task id.
    path : str or Path, optional
        The table file; default the registry spec's ``table_path`` (for the built-ins
        ``data/tasks/<ID>.yaml``).

    Returns
    -------
    dict
        ``agents``, ``dt_s``, ``harder``, ``tiers`` (int keys) and the table's other blocks
        (``spec``, ``scene_tiers``, ``vehicle``, ``calibration``, ...).

    Raises
    ------
    ConfigError
        If the file cannot be read or is malformed (missing key, undeclared tier parameter, bad
        ``vehicle`` or ``calibration.seeds``).
    """
    return copy.deepcopy(shared_task_table(task_id, path))


def shared_task_table(task_id: str, path: str | Path | None = None) -> dict:
    """:func:`load_task_table`'s table itself, not a copy: for readers on a hot path (an
    episode batch's set-up reads a key or two), which must not change it.

    Parameters
    ----------
    task_id : str
        Registered task id.
    path : str or Path, optional
        The table file (as :func:`load_task_table`).

    Returns
    -------
    dict
        The parsed table, shared by every caller until the file changes.

    Raises
    ------
    ConfigError
        As :func:`load_task_table`.
    """
    if path is None:
        from ..registry import task_spec

        path = task_spec(task_id).table_path
    f = Path(path)
    try:
        stamp = f.stat()
    except OSError as exc:
        raise ConfigError(f"{f}: cannot read tier table ({exc.strerror})") from None
    return _task_table(os.path.abspath(f), stamp.st_mtime_ns, stamp.st_size)


@functools.lru_cache(maxsize=64)
def _task_table(path: str, mtime_ns: int, size: int) -> dict:
    f = Path(path)
    try:
        doc = yaml.safe_load(f.read_text())
    except OSError as exc:
        raise ConfigError(f"{f}: cannot read tier table ({exc.strerror})") from None
    for key in ("agents", "dt_s", "harder", "tiers"):
        if key not in doc:
            raise ConfigError(f"{f}: missing key '{key}'")
    doc["tiers"] = {int(k): v for k, v in doc["tiers"].items()}
    for tier, params in doc["tiers"].items():
        undeclared = sorted(set(params) - set(doc["harder"]))
        if undeclared:
            raise ConfigError(f"{f}: tier {tier} parameter '{undeclared[0]}' has no 'harder' "
                              "direction")
    if "vehicle" in doc and not isinstance(doc["vehicle"], str):
        raise ConfigError(f"{f}: 'vehicle' must be a vehicle name (data/vehicles.yaml), got "
                          f"{doc['vehicle']!r}")
    for tier, params in (doc.get("scene_tiers") or {}).items():
        bad = sorted(set(params) - set(doc["harder"]) - {"current_gain"})
        if bad:
            raise ConfigError(f"{f}: scene_tiers {tier} parameter '{bad[0]}' is not a tier "
                              f"parameter (declared in 'harder') nor current_gain")
    cal = doc.get("calibration")
    if cal is not None:
        seeds = cal.get("seeds") if isinstance(cal, dict) else None
        if not (isinstance(seeds, list) and seeds
                and all(isinstance(x, int) and not isinstance(x, bool) for x in seeds)):
            raise ConfigError(f"{f}: 'calibration.seeds' must be a non-empty list of integer "
                              f"seeds, got {seeds!r}")
    return doc


def tier_params(task_id: str, tier: int, scene: bool = False) -> dict:
    """The parameters of one tier of a task.

    Parameters
    ----------
    task_id : str
        Registered task id.
    tier : int
        Tier number.
    scene : bool
        True for a scene (either backend on a scene's local grid): the table's ``scene_tiers``
        row goes on top (the mission at scene scale and the tier's current multiplier
        ``current_gain``).

    Returns
    -------
    dict
        The tier's row of the tier table (a copy).

    Raises
    ------
    ConfigError
        Unknown tier, or a scene tier missing from ``scene_tiers``.
    NotApplicable
        ``scene=True`` for a task without ``scene_tiers`` (the message names the tasks that
        have one).
    """
    table = load_task_table(task_id)
    if tier not in table["tiers"]:
        raise ConfigError(f"task {task_id}: unknown tier {tier!r}; valid tiers are "
                          f"{sorted(table['tiers'])}")
    out = dict(table["tiers"][tier])
    if scene:
        rows = table.get("scene_tiers")
        if not rows:
            raise NotApplicable(f"task {task_id} has no scene_tiers in its tier table, so it "
                                f"does not run in a scene; tasks with scene tiers: "
                                f"{', '.join(scene_tasks())}")
        if tier not in rows:
            raise ConfigError(f"task {task_id}: scene_tiers has no tier {tier}")
        out.update(rows[tier])
    return out


def scene_tasks() -> tuple[str, ...]:
    """The tasks whose tier table has ``scene_tiers``.

    Returns
    -------
    tuple of str
        Task ids (:func:`oneocean.registry.scene_tasks`).
    """
    from ..registry import scene_tasks as _scene_tasks

    return _scene_tasks()


def need_tier(task_id: str, tier: dict, *keys: str) -> None:
    """Check that a tier has the parameters a task needs.

    Parameters
    ----------
    task_id : str
        Task id, for the message.
    tier : dict
        Tier parameters.
    *keys : str
        Parameters the task needs.

    Raises
    ------
    ConfigError
        One line naming the parameters ``keys`` missing from ``tier``.
    """
    missing = [k for k in keys if k not in tier]
    if missing:
        raise ConfigError(f"task {task_id}: tier parameters missing: {', '.join(missing)}")


def episode_steps(tier: dict) -> int:
    """Steps of an episode: ``ceil(time_limit_s / dt_s)`` (round-off tolerant).

    Parameters
    ----------
    tier : dict
        Tier parameters with ``time_limit_s`` and ``dt_s``, s.

    Returns
    -------
    int
        Number of steps.
    """
    return int(math.ceil(float(tier["time_limit_s"]) / float(tier["dt_s"]) - 1e-9))
