"""DPT heuristic and oracle: horizontal line-of-sight guidance with a depth loop.

A policy of the public view only (:class:`oneocean.tasks.loop.Ctx`): the briefing
(:class:`oneocean.tasks.dpt.DPTBriefing`: the route and its depth profile) and each step's
observation (the navigation estimate, depth, velocity over ground, the current estimate).

The active leg is the method's own (its memory, :class:`DPTMemory`): a waypoint pointer
advanced on the observed position as the task's mission computer advances its own
(:func:`~oneocean.tasks.waypoints.nav_waypoint`, within the briefing's waypoint radius,
horizontally; the last leg once it believes the route done). A depth loop
``w = KZ (y* - y)`` goes first (at most half the budget), then horizontal line-of-sight
guidance with the rest: aim at the point ``LOOKAHEAD_M`` ahead of the agent's horizontal
projection on the active leg with :func:`~oneocean.methods.steering.seek_max` (cross-track current
fed forward first, P-control ``KP``), both with the full ``v_max``, and both feed the profile
slope times the along-track ground speed forward (a preview of the depth profile the mission
gives them). They differ in information only: the heuristic's current estimate and navigation
come from the sensor models (:mod:`oneocean.sensing`), the oracle's are the truth.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...tasks.common import O_CE, O_CN, O_DEPTH, O_VX, O_VZ, O_X, O_Z
from ...tasks.waypoints import nav_waypoint, profile_at
from ...tasks.loop import noop_plan as plan  # noqa: F401  (no team-level decision
from ..steering import seek_max
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
    radius : float
        Waypoint radius of the active-leg pointer, m (the briefing's).
    """
    budget: float   # speed budget through the water, m s-1
    kp: float       # horizontal gain toward the lookahead point, s-1
    look: float     # horizontal lookahead along the active leg, m
    kz: float       # depth-loop gain, s-1
    preview: int    # 1: feed the profile slope times the along-track ground speed forward
    radius: float   # waypoint radius of the active-leg pointer, m


class DPTMemory(NamedTuple):
    """The method's memory ``H``: its active waypoint."""
    nwp: np.ndarray     # (E,) int64 active waypoint (1..W; W + 1 once it believes the route done)


def params(method: str, B) -> DPTPolicy:
    """The policy's params: the same for every method (they differ in information only).

    Returns
    -------
    DPTPolicy
        Budget ``v_max``, :data:`KP`, :data:`LOOKAHEAD_M`, :data:`KZ`, preview on, the
        waypoint radius.
    """
    return DPTPolicy(float(B.v_max), KP, LOOKAHEAD_M, KZ, 1, float(B.radius))


def memory(B, M: DPTPolicy) -> DPTMemory:
    """A fresh memory: the first waypoint active.

    Returns
    -------
    DPTMemory
    """
    return DPTMemory(np.ones(B.t0.shape[0], np.int64))


@hot_kernel
def act(C, e, k, i):
    """Agent ``i``'s action: the depth loop, then line-of-sight guidance along the active leg.
    Policy hook (:mod:`oneocean.tasks.loop`); advances the memory's waypoint pointer.

    Returns
    -------
    ax, ay, az : float
        Desired velocity relative to the water, world frame (x east, y down, z north), m s-1;
        the loop clips it to ``v_max``.
    psi : float
        Commanded heading, rad (NaN: free).
    """
    M = C.M
    route = C.B.route
    o = C.O[e, i]
    px = o[O_X]
    py = o[O_DEPTH]
    pz = o[O_Z]
    # the active leg as the method knows it (the last leg once it thinks it is done)
    wp = min(nav_waypoint(route, C.H.nwp, e, px, py, pz, M.radius, 1), route.shape[1] - 1)
    a = route[e, wp - 1]
    b = route[e, wp]
    sh, ln, tx, tz, ytgt, slope, _ = profile_at(a[0], a[1], a[2], b[0], b[1], b[2], px, pz)
    a0x = a[0]
    a0z = a[2]
    budget = M.budget
    # depth loop first (at most half the budget), then horizontal LOS with the rest
    w = M.kz * (ytgt - py)
    if M.preview != 0 and 0.0 <= sh <= ln:
        w += slope * (o[O_VX] * tx + o[O_VZ] * tz)
    wlim = 0.5 * budget
    w = min(max(w, -wlim), wlim)
    bh = math.sqrt(budget * budget - w * w)
    sl = min(max(sh, 0.0) + M.look, ln)
    ax, _, az = seek_max(px, 0.0, pz, a0x + sl * tx, 0.0, a0z + sl * tz, bh, M.kp, o[O_CE],
                         o[O_CN])
    return ax, w, az, math.nan
