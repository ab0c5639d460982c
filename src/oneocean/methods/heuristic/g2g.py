"""G2G heuristic and oracle: plan the transit through the briefing's field, then fly the plan.

A policy of the public view only (:class:`oneocean.tasks.loop.Ctx`): the briefing
(:class:`oneocean.tasks.g2g.G2GBriefing`) and each step's observation.

Plan
    Made in Python by :func:`prepare` before the first step, into the method's memory
    (:class:`G2GMemory`: the route's vertices and programmed speeds, the active segment). The
    least-energy route and speed schedule from the launch fix to the goal through the
    briefing's field (:func:`oneocean.tasks.routing.plan_on_field`: time-dependent Dijkstra
    over the lattice, string pulling, then the programmed speed of every stretch of at most
    ``PIECE_M`` m among the mission speeds ``SPEED_MIN .. v_max``, with the vehicle's power
    model from the briefing; without one: the fastest route at ``v_max``). The field is the
    forecast for the heuristic and the truth for the oracle: the briefing says which.
Act
    ``act``, every step. Line-of-sight following of the planned polyline
    (:func:`~oneocean.tasks.routing.follow_path`: a carrot ``LOOKAHEAD_M`` ahead of the
    observed position), crabbing with the observed current estimate
    (:func:`~oneocean.methods.steering.seek_max`: the cross-track current is cancelled first) at
    the stretch's programmed speed, raised when the current needs it
    (:func:`~oneocean.tasks.routing.hold_speed`: cross-current headroom and a minimum ground
    speed, up to ``v_max``).

Heuristic and oracle differ in information only (the briefing and observation they are given):
the same planner, steering and gains. :func:`straight_plan` is the plan of a vehicle that
does not plan (the straight line at its cruise speed,
:func:`~oneocean.tasks.routing.cruise_speed`): the baseline the calibration compares against.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...tasks.common import O_CE, O_CN, O_DEPTH, O_X, O_Z
from ...tasks.waypoints import ARRIVE_M
from ...tasks.loop import noop_plan as plan  # noqa: F401  (the plan is made in Python
from ...tasks import routing
from ...tasks.routing import follow_path, hold_speed
from ..steering import seek_max
from . import SENSING  # noqa: F401

#: Proportional gain of the final approach (ground speed <= KP * distance to the carrot), s-1.
KP = 0.5
#: Line-of-sight lookahead along the planned route, m.
LOOKAHEAD_M = 30.0
#: A corner of the planned route counts as passed within this distance (m): wider than the
#: torpedo's turning diameter, so it never orbits a corner (tasks.waypoints.ARRIVE_M).
WP_TOL_M = ARRIVE_M


class G2GPolicy(NamedTuple):
    """Parameters ``M`` of the G2G policy (the same for heuristic and oracle).

    Attributes
    ----------
    v_max : float
        Vehicle speed limit through the water, m s-1.
    kp : float
        Approach gain, s-1 (:data:`KP`).
    look : float
        Line-of-sight lookahead, m (:data:`LOOKAHEAD_M`).
    tol : float
        Corner capture distance, m (:data:`WP_TOL_M`).
    hotel_w : float
        Hotel power of the vehicle's power model ``P(u) = hotel_w + pk u^3``, W (0 and
        ``pk = 0``: no power model; plan the fastest route at ``v_max``).
    pk : float
        Propulsion coefficient of the power model, W s3 m-3.
    """
    v_max: float    # vehicle speed limit through the water, m s-1
    kp: float       # approach gain, s-1
    look: float     # line-of-sight lookahead, m
    tol: float      # corner capture distance, m
    hotel_w: float  # power model (0, 0: none; plan the fastest route at v_max)
    pk: float


def params(method: str, B) -> G2GPolicy:
    """The policy's params: the same for every method (they differ in information only).

    Returns
    -------
    G2GPolicy
    """
    return G2GPolicy(float(B.v_max), KP, LOOKAHEAD_M, WP_TOL_M, float(B.hotel_w), float(B.pk))


def _power(M):
    return routing.briefing_power(M.hotel_w, M.pk)


class G2GMemory(NamedTuple):
    """The method's memory ``H``: its plan (:func:`oneocean.tasks.routing.follow_path`)."""
    wps: np.ndarray         # (E, MAX_VERTICES, 2) route vertices (x, z), m
    wspd: np.ndarray        # (E, MAX_VERTICES) programmed speed of each segment, m s-1
    wcount: np.ndarray      # (E,) int64 vertices
    widx: np.ndarray        # (E,) int64 active segment


def memory(B, M: G2GPolicy) -> G2GMemory:
    """A fresh memory: the straight line from the launch fix to the goal at the cruise speed
    (the plan until :func:`prepare` makes one).

    Returns
    -------
    G2GMemory
    """
    n_ep = B.goal.shape[0]
    wps = np.zeros((n_ep, routing.MAX_VERTICES, 2))
    wps[:, 0] = B.start[:, [0, 2]]
    wps[:, 1] = B.goal[:, [0, 2]]
    wspd = np.zeros((n_ep, routing.MAX_VERTICES))
    wspd[:, 0] = routing.cruise_speed(M.v_max, _power(M))
    return G2GMemory(wps, wspd, np.full(n_ep, 2, np.int64), np.zeros(n_ep, np.int64))


def plan_episode(B, M: G2GPolicy, e: int) -> routing.Route:
    """The method's route and speed schedule for episode ``e``.

    :func:`oneocean.tasks.routing.plan_on_field` from the launch fix to the goal on the
    briefing's field; :func:`straight_plan` where no plan holds: no speed, no field (the
    mission lies off the product), or no passable route through it.

    Parameters
    ----------
    B : G2GBriefing
        The briefing.
    M : G2GPolicy
        The policy's params.
    e : int
        Episode.

    Returns
    -------
    Route
        The plan (:class:`oneocean.tasks.routing.Route`).
    """
    start = (float(B.start[e, 0]), float(B.start[e, 2]))
    goal = (float(B.goal[e, 0]), float(B.goal[e, 2]))
    f = routing.unpack_field(B, e)
    if not M.v_max > 0.0 or f is None:
        return straight_plan(M, start, goal, float(B.t0[e]))
    r = routing.plan_on_field(f, np.array([start, goal]), float(B.t0[e]), M.v_max, _power(M))
    if not r.ok:   # no passable route through the field the method knows: the straight line
        return straight_plan(M, start, goal, float(B.t0[e]))
    return r


def straight_plan(M: G2GPolicy, start, goal, t0: float) -> routing.Route:
    """The plan of a vehicle that does not plan: the straight line at its cruise speed
    (:func:`oneocean.tasks.routing.cruise_speed`: the mission speed nearest the vehicle's
    maximum-range speed, else ``v_max``).

    Parameters
    ----------
    M : G2GPolicy
        The policy's params (:func:`params`).
    start, goal : tuple of float
        Start and goal (x, z), m.
    t0 : float
        Departure time, s since the product's time origin.

    Returns
    -------
    Route
        Vertices ``[start, goal]``, one speed, arrival times ``[t0, NaN]``, cost NaN, ``ok``.
    """
    u = routing.cruise_speed(M.v_max, _power(M))
    return routing.Route(np.array([start, goal], dtype=np.float64), np.array([u]),
                         np.array([float(t0), math.nan]), math.nan, True)


def prepare(B, M: G2GPolicy, H: G2GMemory) -> None:
    """The Python planner: plan every episode (:func:`plan_episode`) into the memory ``H``
    (:func:`oneocean.tasks.routing.write_plan`). Run once, before the first step."""
    for e in range(B.goal.shape[0]):
        routing.write_plan(plan_episode(B, M, e), H.wps, H.wspd, H.wcount, H.widx, e)


@hot_kernel
def act(C, e, k, i):
    """The vehicle's action: line-of-sight following of the planned route at its programmed
    speed.

    A carrot ``M.look`` ahead along the planned polyline
    (:func:`~oneocean.tasks.routing.follow_path`) from the observed position, at the goal's
    depth, sought with :func:`~oneocean.methods.steering.seek_max` at the programmed speed raised
    where the observed current needs it (:func:`~oneocean.tasks.routing.hold_speed`).
    Policy hook (:mod:`oneocean.tasks.loop`).

    Returns
    -------
    ax, ay, az : float
        Desired velocity relative to the water, world frame (x east, y down, z north), m s-1;
        the loop clips it to ``v_max``.
    psi : float
        Commanded heading, rad (NaN: free).
    """
    M = C.M
    H = C.H
    o = C.O[e, i]
    px = o[O_X]
    pz = o[O_Z]
    pe = o[O_CE]
    pn = o[O_CN]
    cx, cz, u = follow_path(H.wps, H.wspd, H.wcount, H.widx, e, px, pz, M.look, M.tol, 1)
    gy = C.B.goal[e, 1]
    u = hold_speed(u, cx - px, cz - pz, pe, pn, M.v_max)
    ax, ay, az = seek_max(px, o[O_DEPTH], pz, cx, gy, cz, u, M.kp, pe, pn)
    return ax, ay, az, math.nan
