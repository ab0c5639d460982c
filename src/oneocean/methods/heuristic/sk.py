"""SK heuristic and oracle: dynamic positioning on the station with current feed-forward.

Both: P-control (``KP``) to the station plus feed-forward of the sensed current within the
vehicle's full speed budget ``|a| <= v_max`` (:func:`~oneocean.tasks.common.seek_max`), heading
commanded to the station heading. They differ in information only: ``heuristic`` feeds forward
its current estimate and steers by its navigation estimate (:mod:`oneocean.sensing`);
``oracle`` the true current and position. Neither can hold against a current above ``v_max``.
"""

from __future__ import annotations

from typing import NamedTuple

from ...engine._jit import hot_kernel
from ...tasks.common import seek_max
from ...tasks.loop import noop_plan as plan  # noqa: F401  (no team-level decision)
from . import SENSING  # noqa: F401

#: Proportional position gain, s-1 (ground-speed request = KP * error, plus feed-forward).
KP = 0.4


class SKPolicy(NamedTuple):
    """Parameters ``M`` of the SK policy (the same for heuristic and oracle).

    Attributes
    ----------
    budget : float
        Speed budget through the water, m s-1 (the vehicle's ``v_max``).
    kp : float
        Position gain, s-1 (:data:`KP`).
    """
    budget: float   # speed budget through the water, m s-1
    kp: float       # position gain, s-1


def params(method: str, tier: dict, vehicle) -> SKPolicy:
    """The policy's params: the same for every method (they differ in information only).

    Parameters
    ----------
    method : str
        The fused method, ``"heuristic"`` or ``"oracle"``
        (:data:`oneocean.methods.heuristic.SENSING`).
    tier : dict
        The cell's tier parameters plus ``dt_s`` and ``v_max``
        (:attr:`oneocean.tasks.Cell.params`).
    vehicle : Vehicle
        The task's vehicle (:class:`oneocean.engine.dynamics.Vehicle`).

    Returns
    -------
    SKPolicy
        Budget ``v_max`` and :data:`KP`.
    """
    return SKPolicy(float(vehicle.v_max), KP)


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    """Agent ``i``'s action: P-control to the station plus current feed-forward, station heading.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : SKParams
        The task's params (:func:`oneocean.tasks.sk.make`).
    W : SKWork
        The task's per-episode work arrays (:func:`oneocean.tasks.sk.make`); reads the station
        ``W.station`` (E, 3) m and its heading ``W.heading`` (E,) rad.
    M : SKPolicy
        This policy's params (:func:`params`).
    state : (E, N, STATE_DIM) float64
        Vehicle states as the method knows them (its navigation estimate; the truth for the
        oracle); layout in :mod:`oneocean.engine.dynamics`.
    e : int
        Episode index.
    k : int
        Step index.
    i : int
        Agent index.
    t : float
        Time of the step, s since the grid's ``time0_unix_s`` (``t0[e] + k dt``).
    pe, pn : float
        The method's current estimate at the agent, east and north, m s-1 (the true current
        for the oracle).

    Returns
    -------
    ax, ay, az : float
        Desired velocity relative to the water, world frame (x east, y down, z north), m s-1
        (:func:`~oneocean.tasks.common.seek_max`, ``|a| <= M.budget``).
    psi : float
        Commanded heading, rad: the station heading ``W.heading[e]``.
    """
    s = state[e, i]
    g = W.station[e]
    ax, ay, az = seek_max(s[0], s[1], s[2], g[0], g[1], g[2], M.budget, M.kp, pe, pn)
    return ax, ay, az, W.heading[e]
