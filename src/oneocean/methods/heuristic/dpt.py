"""DPT heuristic and oracle: horizontal line-of-sight guidance with a depth loop.

A depth loop ``w = KZ (y* - y)`` goes first (at most half the budget), then horizontal
line-of-sight guidance with the rest: aim at the point ``LOOKAHEAD_M`` ahead of the agent's
horizontal projection on the active leg (the mission computer's leg, ``W.nwp``, advanced on
the position the method knows: :func:`~oneocean.tasks.common.nav_waypoint`) with
:func:`~oneocean.tasks.common.seek_max` (cross-track current fed forward first, P-control
``KP``), both with the full ``v_max``, and both feed the profile slope times the
along-track ground speed forward (a preview of the depth profile the mission gives them).
They differ in information only: the heuristic's current estimate and navigation come from
the sensor models (:mod:`oneocean.sensing`), the oracle's are the truth.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from ...engine._jit import hot_kernel
from ...engine.dynamics import VX, VZ
from ...tasks.common import nav_waypoint, profile_at, seek_max
from ...tasks.loop import noop_plan as plan  # noqa: F401  (no team-level decision)
from . import SENSING  # noqa: F401

#: Horizontal line-of-sight lookahead, m.
LOOKAHEAD_M = 20.0
#: Horizontal proportional gain toward the lookahead point, s-1.
KP = 0.5
#: Depth-loop gain, s-1.
KZ = 0.3


class DPTPolicy(NamedTuple):
    """Parameters ``M`` of the DPT policy (the same for heuristic and oracle).

    Attributes
    ----------
    budget : float
        Speed budget through the water, m s-1 (the vehicle's ``v_max``).
    kp : float
        Horizontal gain toward the lookahead point, s-1 (:data:`KP`).
    look : float
        Horizontal lookahead along the active leg, m (:data:`LOOKAHEAD_M`).
    kz : float
        Depth-loop gain, s-1 (:data:`KZ`).
    preview : int
        1: feed the profile slope times the along-track ground speed forward; 0: do not.
    """
    budget: float   # speed budget through the water, m s-1
    kp: float       # horizontal gain toward the lookahead point, s-1
    look: float     # horizontal lookahead along the active leg, m
    kz: float       # depth-loop gain, s-1
    preview: int    # 1: feed the profile slope times the along-track ground speed forward


def params(method: str, tier: dict, vehicle) -> DPTPolicy:
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
    DPTPolicy
        Budget ``v_max``, :data:`KP`, :data:`LOOKAHEAD_M`, :data:`KZ`, preview on.
    """
    v_max = float(vehicle.v_max)
    return DPTPolicy(v_max, KP, LOOKAHEAD_M, KZ, 1)


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    """Agent ``i``'s action: the depth loop, then line-of-sight guidance along the active leg.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : DPTParams
        The task's params (:func:`oneocean.tasks.dpt.make`).
    W : DPTWork
        The task's per-episode work arrays (:func:`oneocean.tasks.dpt.make`); reads the route
        ``W.route`` (E, n_waypoints + 1, 3) m and advances the mission computer's leg ``W.nwp``.
    M : DPTPolicy
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
        Desired velocity relative to the water, world frame (x east, y down, z north), m s-1;
        the loop clips it to ``v_max``.
    psi : float
        Commanded heading, rad (NaN: free).
    """
    s = state[e, i]
    px = s[0]
    py = s[1]
    pz = s[2]
    # the active leg as the mission computer knows it (the last leg once it thinks it is done)
    wp = min(nav_waypoint(W.route, W.nwp, e, px, py, pz, P.radius, 1), W.route.shape[1] - 1)
    a = W.route[e, wp - 1]
    b = W.route[e, wp]
    sh, ln, tx, tz, ytgt, slope, _ = profile_at(a[0], a[1], a[2], b[0], b[1], b[2], px, pz)
    a0x = a[0]
    a0z = a[2]
    budget = M.budget
    # depth loop first (at most half the budget), then horizontal LOS with the rest
    w = M.kz * (ytgt - py)
    if M.preview != 0 and 0.0 <= sh <= ln:
        w += slope * (s[VX] * tx + s[VZ] * tz)
    wlim = 0.5 * budget
    w = min(max(w, -wlim), wlim)
    bh = math.sqrt(budget * budget - w * w)
    sl = min(max(sh, 0.0) + M.look, ln)
    ax, _, az = seek_max(px, 0.0, pz, a0x + sl * tx, 0.0, a0z + sl * tz, bh, M.kp, pe, pn)
    return ax, w, az, math.nan
