"""The public view of a task: what every method may know (docs/policy.md).

A method -- the built-in heuristic, behaviour cloning, PPO, the LLM planner, a user's policy
-- knows two things: the task's **briefing**, given at reset (what the mission provides before
the episode), and the **observation**, given every step (what the sensors and the team's
communication give each agent; :data:`oneocean.tasks.common.OBS_FIELDS` then the task's own
``OBS_EXTRA``). Every non-oracle method gets the same briefing and observation, fused or
through the step API; the oracle gets the truth in the same shape.

A briefing is a typed NamedTuple of the task module (``<ID>Briefing``, built by its ``brief``):
the fields of :data:`COMMON` first, then the task's own (its ``BRIEF_FIELDS``: documentation
of each, with shape and unit). Arrays lead with the episode axis E; scalars hold for every
episode of the batch. Fields starting ``fc_`` are a mission field packed per episode
(:func:`oneocean.tasks.routing.pack_fields`).
"""

from __future__ import annotations

import collections
from typing import NamedTuple

import numpy as np

from ..engine.grid import Grid
from ..sensing import SensingParams


class Mission(NamedTuple):
    """What a task's ``brief`` may draw on besides its own params, work arrays and reset:
    the environment's knowledge, of which the briefing gives each method its share. A task
    whose own sensors depend on what the method is given (the oracle perceives UPL's object
    or FH's school exactly: ``sens.true_target``), or whose own sensors draw errors (a sonar:
    the run's ``seed`` and the row's episode ``e0 + e``), sets that in its work arrays in
    ``brief``: the task's hooks see only ``P`` and ``W``."""
    grid: Grid            # the rollout's grid export (the truth)
    tier: dict            # the cell's tier parameters (plus dt_s, v_max)
    vehicle: object       # the task's vehicle (oneocean.engine.dynamics.Vehicle)
    sens: SensingParams   # what the method is given (oneocean.sensing; the truth: oracle)
    fc: np.ndarray        # (E, 5) each episode's forecast error (LoopState.fc)
    X0: np.ndarray        # (E, N, STATE_DIM) the agents' start fixes (known states at step 0)
    t0: np.ndarray        # (E,) start times, s since the grid's time0
    seed: int = 0         # the run seed (the sensor models' error streams)
    e0: int = 0           # the cell's episode of row 0 (row e draws episode e0 + e's streams)

    @property
    def forecast(self):
        """The forecast-error models to apply to the truth (None: the method knows the true
        current, the oracle or an ablation)."""
        return None if self.sens.true_current != 0 else self.fc


#: The fields every briefing starts with: name -> (shape, unit, meaning).
COMMON = {
    "t0": ("(E,)", "s", "start time of each episode, since the product's time origin "
           "(time0_unix_s)"),
    "t_lim": ("", "s", "the tier's time limit"),
    "dt": ("", "s", "the step"),
    "n_agents": ("", "", "team size N"),
    "v_max": ("", "m s-1", "the vehicle's speed limit through the water"),
    "guidance": ("", "", "the vehicle's guidance: 0 holonomic (hovers, crabs), 1 torpedo "
                 "(turns no tighter than its radius, dives only when moving)"),
    "hotel_w": ("", "W", "power model P(u) = hotel_w + pk u^3 at speed u through the water "
                "(0 and 0: the vehicle has none)"),
    "pk": ("", "W s3 m-3", "propulsion coefficient of the power model"),
    "energy_allocation": ("(E,)", "J", "the energy the mission allocates (inf: none); a "
                          "method over it fails"),
    "sens": ("", "", "the sensor models' error class the method is given "
             "(oneocean.sensing.SensingParams; zeros and truth flags for the oracle)"),
    "chart": ("", "", "the nautical chart: the product's bathymetry and land mask "
              "(a Grid with no currents; oneocean.engine.grid.sample_elevation)"),
}


def briefing_class(task_id: str, fields, module: str) -> type:
    """The NamedTuple class of a task's briefing, ``<ID>Briefing``: the :data:`COMMON` fields,
    then the task's own.

    Parameters
    ----------
    task_id : str
        The task's id (the class's name prefix: numba tells NamedTuple classes apart by name).
    fields : iterable of str
        The task's own fields, in order (its ``BRIEF_FIELDS``).
    module : str
        The task module's name (the class's ``__module__``).

    Returns
    -------
    type
    """
    cls = collections.namedtuple(f"{task_id}Briefing", tuple(COMMON) + tuple(fields),
                                 module=module)
    cls.__doc__ = (f"{task_id}'s briefing: the common fields "
                   f"(:data:`oneocean.tasks.public.COMMON`), then its ``BRIEF_FIELDS``.")
    return cls


def chart(grid: Grid) -> Grid:
    """The chart of a grid export: its bathymetry, land mask and axes, no currents (empty
    current arrays, gain 0). The same numba type as the grid.

    Parameters
    ----------
    grid : Grid
        The grid export.

    Returns
    -------
    Grid
    """
    return grid._replace(uv=np.zeros((0, 0, 0, 0, 2), dtype=grid.uv.dtype),
                         uv_tide=np.zeros((0, 0, 0, 2), dtype=grid.uv_tide.dtype),
                         valid=np.zeros((0, 0, 0), dtype=grid.valid.dtype),
                         current_mask=np.zeros((0, 0), dtype=grid.current_mask.dtype),
                         cell_full=np.zeros((0, 0), dtype=grid.cell_full.dtype),
                         gain=0.0, tide_layers=0, tide_amp=0.0)


def common_brief(m: Mission, allocation=None) -> dict:
    """The :data:`COMMON` fields of a briefing.

    Parameters
    ----------
    m : Mission
        The batch's mission.
    allocation : (E,) array_like, optional
        The energy allocation of each episode, J (default: none, inf).

    Returns
    -------
    dict
    """
    from .routing import power_model
    from ..errors import ConfigError

    n_ep, n_ag = m.X0.shape[:2]
    try:
        pw = power_model(m.vehicle.name)
        hotel, pk = float(pw.hotel_w), float(pw.k)
    except ConfigError:
        hotel, pk = 0.0, 0.0
    alloc = (np.full(n_ep, np.inf) if allocation is None
             else np.ascontiguousarray(allocation, dtype=np.float64).reshape(n_ep))
    torpedo = m.vehicle.spec.get("guidance", "holonomic") == "torpedo"
    return {"t0": np.ascontiguousarray(m.t0, dtype=np.float64),
            "t_lim": float(m.tier["time_limit_s"]), "dt": float(m.tier["dt_s"]),
            "n_agents": int(n_ag), "v_max": float(m.vehicle.v_max),
            "guidance": int(torpedo), "hotel_w": hotel, "pk": pk,
            "energy_allocation": alloc, "sens": m.sens, "chart": chart(m.grid)}


def briefing_dict(B) -> dict:
    """A briefing as a plain dict: its fields, with the sensor models and the chart as dicts.

    Parameters
    ----------
    B : NamedTuple
        A task's briefing.

    Returns
    -------
    dict
    """
    out = {}
    for name, v in B._asdict().items():
        out[name] = v._asdict() if isinstance(v, tuple) and hasattr(v, "_asdict") else v
    return out


def briefing_rows(B, rows):
    """The briefing of some episodes of a batch: the E-leading arrays' ``rows`` (copies),
    every other field as is.

    Parameters
    ----------
    B : NamedTuple
        A briefing of E episodes.
    rows : (n,) int array_like or slice
        Episodes to keep.

    Returns
    -------
    NamedTuple
        The same type, n episodes (a packed mission field, ``fc_*``, padded to their own
        largest: the same whatever batch they came from).
    """
    n_ep = B.t0.shape[0]
    vals = {}
    for name, v in B._asdict().items():
        if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == n_ep:
            vals[name] = np.ascontiguousarray(v[rows])
        else:
            vals[name] = v
    if "fc_shape" in vals:     # a packed mission field: padded to these episodes' own
        nt, ny, nx = (max(int(n), 1) for n in vals["fc_shape"].max(axis=0, initial=0))
        vals["fc_cur"] = np.ascontiguousarray(vals["fc_cur"][:, :nt, :ny, :nx])
        vals["fc_times"] = np.ascontiguousarray(vals["fc_times"][:, :nt])
        vals["fc_free"] = np.ascontiguousarray(vals["fc_free"][:, :ny, :nx])
    return type(B)(**vals)
