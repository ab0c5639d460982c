"""RF heuristic and oracle: plan the speed schedule along the route, then fly it.

A policy of the public view only (:class:`oneocean.tasks.loop.Ctx`): the briefing
(:class:`oneocean.tasks.rf.RFBriefing`) and each step's observation. The route is the
mission: its legs are fixed, and the vehicle must keep to them (the task's cross-track bound).
What a method plans is how fast to fly each stretch of it.

Plan
    Made in Python by :func:`prepare` before the first step, into the method's memory
    (:class:`RFMemory`: the route's vertices and programmed speeds, the active segment). The
    route's legs split into stretches of at most ``PIECE_M`` m, each with the programmed
    speed (among the mission speeds ``SPEED_MIN .. v_max``) that spends the least energy on
    it in the current the vehicle will meet there and then, keeping ``HOLD_MS`` of
    cross-current headroom (:func:`oneocean.tasks.routing.plan_on_field` with ``fixed``, on
    the briefing's field, with the vehicle's power model from the briefing). The field is
    the forecast for the heuristic and the truth for the oracle: the briefing says which.
Act
    ``act``, every step. Line-of-sight following of the route
    (:func:`~oneocean.tasks.routing.follow_path`: a carrot ``LOOKAHEAD_M`` ahead along the
    legs from the observed position), crabbing with the observed current estimate
    (:func:`~oneocean.methods.steering.seek_max`) at the stretch's programmed speed, raised when
    the current needs it (:func:`~oneocean.tasks.routing.hold_speed`).

Heuristic and oracle differ in information only: the same planner, steering and gains.
:func:`straight_plan` (the legs at the cruise speed) is the plan of a vehicle that does not
plan, the calibration's baseline.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...tasks.common import O_CE, O_CN, O_DEPTH, O_X, O_Z
from ...tasks.loop import noop_plan as plan  # noqa: F401  (the plan is made in Python
from ...tasks import routing
from ...tasks.routing import follow_path, hold_speed
from ..steering import seek_max
from . import SENSING  # noqa: F401

#: Line-of-sight lookahead along the route, m.
LOOKAHEAD_M = 20.0
#: Proportional gain toward the carrot, s-1 (saturates on the route; slows at its end).
KP = 0.5
#: A waypoint counts as passed (the vehicle turns for the next leg) within this fraction of
#: the task's waypoint radius, on the position the vehicle knows.
CAPTURE_FRAC = 0.5


class RFPolicy(NamedTuple):
    """Parameters ``M`` of the RF policy (the same for heuristic and oracle).

    Attributes
    ----------
    v_max : float
        Vehicle speed limit through the water, m s-1.
    kp : float
        Gain toward the carrot, s-1 (:data:`KP`).
    look : float
        Lookahead along the route, m (:data:`LOOKAHEAD_M`).
    capture : float
        Waypoint capture distance, m: :data:`CAPTURE_FRAC` of the briefing's waypoint radius.
    hotel_w : float
        Hotel power of the vehicle's power model ``P(u) = hotel_w + pk u^3``, W (0 and
        ``pk = 0``: no power model; fly the route at ``v_max``).
    pk : float
        Propulsion coefficient of the power model, W s3 m-3.
    """
    v_max: float    # vehicle speed limit through the water, m s-1
    kp: float       # gain toward the carrot, s-1
    look: float     # lookahead along the route, m
    capture: float  # waypoint capture distance, m
    hotel_w: float  # power model (0, 0: none; fly the route at v_max)
    pk: float


def params(method: str, B) -> RFPolicy:
    """The policy's params: the same for every method (they differ in information only).

    Returns
    -------
    RFPolicy
    """
    return RFPolicy(float(B.v_max), KP, LOOKAHEAD_M, CAPTURE_FRAC * float(B.radius),
                    float(B.hotel_w), float(B.pk))


def _power(M):
    return routing.briefing_power(M.hotel_w, M.pk)


class RFMemory(NamedTuple):
    """The method's memory ``H``: its plan (:func:`oneocean.tasks.routing.follow_path`)."""
    wps: np.ndarray         # (E, MAX_VERTICES, 2) plan vertices (x, z), m
    wspd: np.ndarray        # (E, MAX_VERTICES) programmed speed of each segment, m s-1
    wcount: np.ndarray      # (E,) int64 vertices
    widx: np.ndarray        # (E,) int64 active segment


def memory(B, M: RFPolicy) -> RFMemory:
    """A fresh memory: the route's legs at the cruise speed (the plan until :func:`prepare`
    makes one).

    Returns
    -------
    RFMemory
    """
    n_ep, n_v = B.route.shape[:2]
    wps = np.zeros((n_ep, routing.MAX_VERTICES, 2))
    wps[:, :n_v] = B.route[:, :, [0, 2]]
    wspd = np.zeros((n_ep, routing.MAX_VERTICES))
    wspd[:, :n_v - 1] = routing.cruise_speed(M.v_max, _power(M))
    return RFMemory(wps, wspd, np.full(n_ep, n_v, np.int64), np.zeros(n_ep, np.int64))


def plan_episode(B, M: RFPolicy, e: int) -> routing.Route:
    """The method's speed schedule along episode ``e``'s route.

    :func:`oneocean.tasks.routing.plan_on_field` with ``fixed=True`` on the briefing's field,
    from the route's first vertex (where the vehicle starts); :func:`straight_plan` (the legs
    at the cruise speed) where no schedule holds: no speed, no field (the route lies off the
    product), or no passable plan.

    Parameters
    ----------
    B : RFBriefing
        The briefing.
    M : RFPolicy
        The policy's params (:func:`params`).
    e : int
        Episode index.

    Returns
    -------
    Route
        The plan (:class:`oneocean.tasks.routing.Route`).
    """
    f = routing.unpack_field(B, e)
    if not M.v_max > 0.0 or f is None:
        return straight_plan(B, M, e)
    pts = np.ascontiguousarray(B.route[e][:, [0, 2]])
    r = routing.plan_on_field(f, pts, float(B.t0[e]), M.v_max, _power(M), fixed=True)
    if not r.ok:
        return straight_plan(B, M, e)
    return r


def straight_plan(B, M: RFPolicy, e: int) -> routing.Route:
    """The plan of a vehicle that does not plan: episode ``e``'s legs at its cruise speed
    (:func:`oneocean.tasks.routing.cruise_speed`: the mission speed nearest the vehicle's
    maximum-range speed, else ``v_max``). The signature of :func:`plan_episode`.

    Parameters
    ----------
    B : RFBriefing
        The briefing.
    M : RFPolicy
        The policy's params (:func:`params`).
    e : int
        Episode index.

    Returns
    -------
    Route
        The route's vertices, one speed for every leg, arrival times and cost NaN, ``ok``.
    """
    p = np.ascontiguousarray(B.route[e][:, [0, 2]], dtype=np.float64)
    u = routing.cruise_speed(M.v_max, _power(M))
    return routing.Route(p.copy(), np.full(p.shape[0] - 1, u),
                         np.full(p.shape[0], math.nan), math.nan, True)


def prepare(B, M: RFPolicy, H: RFMemory) -> None:
    """The Python planner: the speed schedule of every episode (:func:`plan_episode`) into
    the memory ``H`` (:func:`oneocean.tasks.routing.write_plan`). Run once, before the first
    step.
    """
    for e in range(B.route.shape[0]):
        routing.write_plan(plan_episode(B, M, e), H.wps, H.wspd, H.wcount, H.widx, e)


@hot_kernel
def act(C, e, k, i):
    """The vehicle's action: line-of-sight route following at the stretch's programmed speed.

    A carrot ``M.look`` ahead along the planned legs
    (:func:`~oneocean.tasks.routing.follow_path`) from the observed position, at the route's
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
    cx, cz, u = follow_path(H.wps, H.wspd, H.wcount, H.widx, e, px, pz, M.look, M.capture, 1)
    gy = C.B.route[e, 0, 1]
    u = hold_speed(u, cx - px, cz - pz, pe, pn, M.v_max)
    ax, ay, az = seek_max(px, o[O_DEPTH], pz, cx, gy, cz, u, M.kp, pe, pn)
    return ax, ay, az, math.nan
