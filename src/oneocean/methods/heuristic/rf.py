"""RF heuristic and oracle: plan the speed schedule along the route, then fly it.

The route is the mission: its legs are fixed, and the vehicle must keep to them (the task's
cross-track bound). What a method plans is how fast to fly each stretch of it.

Plan
    Made in Python by :func:`prepare` before the episode's first step; the plan tokens are
    the work arrays ``W.wps``, ``W.wspd``, ``W.wcount``, ``W.widx`` of
    :mod:`oneocean.tasks.rf`. The route's legs split into stretches of at most ``PIECE_M`` m,
    each with the programmed speed (among the mission speeds ``SPEED_MIN .. v_max``) that
    spends the least energy on it in the current the vehicle will meet there and then,
    keeping ``HOLD_MS`` of cross-current headroom
    (:func:`oneocean.tasks.routing.plan_mission` with ``fixed``: the power model of
    ``data/vehicles.yaml`` ``power:``). The field is what the method knows of the currents:
    the truth with the true current (the oracle; an information ablation), else its FORECAST
    of it (the episode's forecast-error model ``LoopState.fc``).
Act
    ``act``, every step. Line-of-sight following of the route
    (:func:`~oneocean.tasks.routing.follow_path`: a carrot ``LOOKAHEAD_M`` ahead along the
    legs), crabbing with the current estimate (:func:`~oneocean.tasks.common.seek_max`) at
    the stretch's programmed speed, raised when the sensed current needs it
    (:func:`~oneocean.tasks.routing.hold_speed`).

Heuristic and oracle differ in information only: the same planner, steering and gains.
:func:`straight_plan` (the legs at the cruise speed) is the plan of a vehicle that does not
plan, the calibration's baseline.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...tasks.common import seek_max
from ...tasks.loop import noop_plan as plan  # noqa: F401  (the plan is made in Python)
from ...tasks import routing
from ...tasks.routing import follow_path, hold_speed
from . import SENSING  # noqa: F401
from .g2g import vehicle_power

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
        Waypoint capture distance as a fraction of the task's waypoint radius
        (:data:`CAPTURE_FRAC`).
    hotel_w : float
        Hotel power of the vehicle's power model ``P(u) = hotel_w + pk u^3``, W (0 and
        ``pk = 0``: no power model; fly the route at ``v_max``).
    pk : float
        Propulsion coefficient of the power model, W s3 m-3.
    """
    v_max: float    # vehicle speed limit through the water, m s-1
    kp: float       # gain toward the carrot, s-1
    look: float     # lookahead along the route, m
    capture: float  # waypoint capture distance as a fraction of the task's radius
    hotel_w: float  # power model (0, 0: none; fly the route at v_max)
    pk: float


def params(method: str, tier: dict, vehicle) -> RFPolicy:
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
        Its power model (:func:`~oneocean.methods.heuristic.g2g.vehicle_power`), if any.

    Returns
    -------
    RFPolicy
        ``v_max``, the module's gains, the power model's ``hotel_w`` and ``k`` (0 without one).
    """
    pw = vehicle_power(vehicle)
    return RFPolicy(float(vehicle.v_max), KP, LOOKAHEAD_M, CAPTURE_FRAC,
                    0.0 if pw is None else pw.hotel_w, 0.0 if pw is None else pw.k)


def _power(M: RFPolicy):
    return None if M.hotel_w <= 0.0 and M.pk <= 0.0 else routing.PowerModel(1.0, M.hotel_w,
                                                                            M.pk)


def plan_episode(grid, M: RFPolicy, route_xz, depth: float, t0: float, duration: float,
                 fc=None, e: int = 0) -> routing.Route:
    """The method's speed schedule along the route.

    :func:`oneocean.tasks.routing.plan_mission` with ``fixed=True``; :func:`straight_plan`
    (the legs at the cruise speed) where no schedule holds: no speed, a route outside the grid,
    or no passable plan.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    M : RFPolicy
        The policy's params (:func:`params`).
    route_xz : (n_waypoints + 1, 2) array_like
        The route's vertices (x, z), m, the start first.
    depth : float
        The route's depth, m (positive down).
    t0 : float
        Episode start time, s since the grid's ``time0_unix_s``.
    duration : float
        The episode's time limit, s (the planner's field window).
    fc : (E, 5) float64, optional
        The episodes' forecast errors (``LoopState.fc``); None: plan on the true currents.
    e : int, optional
        Episode index into ``fc`` (default 0).

    Returns
    -------
    Route
        The plan (:class:`oneocean.tasks.routing.Route`).
    """
    if not (M.v_max > 0.0 and routing.within_grid(grid, route_xz)):
        return straight_plan(grid, M, route_xz, depth, t0, duration, fc, e)
    r = routing.plan_mission(grid, route_xz, depth, t0, duration, M.v_max, _power(M),
                             fixed=True, fc=fc, e=e)
    if not r.ok:
        return straight_plan(grid, M, route_xz, depth, t0, duration, fc, e)
    return r


def straight_plan(grid, M: RFPolicy, route_xz, depth: float, t0: float, duration: float,
                  fc=None, e: int = 0) -> routing.Route:
    """The plan of a vehicle that does not plan: the legs at its cruise speed.

    The cruise speed is :func:`oneocean.tasks.routing.cruise_speed` (the mission speed nearest
    the vehicle's maximum-range speed, else ``v_max``).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    M : RFPolicy
        The policy's params (:func:`params`).
    route_xz : (n_waypoints + 1, 2) array_like
        The route's vertices (x, z), m, the start first.
    depth : float
        The route's depth, m (positive down).
    t0 : float
        Episode start time, s since the grid's ``time0_unix_s``.
    duration : float
        The episode's time limit, s (the planner's field window).
    fc : (E, 5) float64, optional
        The episodes' forecast errors (``LoopState.fc``); None: plan on the true currents.
    e : int, optional
        Episode index into ``fc`` (default 0).
        ``depth``, ``t0``, ``duration``, ``fc`` and ``e`` are unused (the signature of
        :func:`plan_episode`).

    Returns
    -------
    Route
        The route's vertices, one speed for every leg, arrival times and cost NaN, ``ok``.
    """
    p = np.asarray(route_xz, dtype=np.float64).reshape(-1, 2)
    u = routing.cruise_speed(M.v_max, _power(M))
    return routing.Route(p.copy(), np.full(p.shape[0] - 1, u),
                         np.full(p.shape[0], math.nan), math.nan, True)


#: The task's observation cue does not read this policy's plan tokens (its route and speed
#: schedule), so a rollout with external actions (the step API) skips :func:`prepare`.
PREPARE_EXTERNAL = False


def prepare(grid, P, W, M: RFPolicy, t0, LP=None, LS=None, X=None) -> None:
    """The Python planner: the speed schedule of every episode not yet planned (``W.planned``).

    Planned on the field the method knows (``LP.sens.true_current``: the truth, else the
    forecast ``LS.fc``), at the route's depth, from its first vertex (where the vehicle
    starts); written as the plan tokens ``W.wps``, ``W.wspd``, ``W.wcount``, ``W.widx``
    (:func:`oneocean.tasks.routing.write_plan`).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : RFParams
        The task's params (:func:`oneocean.tasks.rf.make`).
    W : RFWork
        The task's per-episode work arrays; the plan tokens are written in place.
    M : RFPolicy
        This policy's params (:func:`params`).
    t0 : (E,) float64
        Episode start times, s since the grid's ``time0_unix_s``.
    LP : LoopParams, optional
        The loop's params (:class:`oneocean.tasks.loop.LoopParams`); ``LP.sens`` says what the
        method knows. None: the truth.
    LS : LoopState, optional
        The loop's state (:class:`oneocean.tasks.loop.LoopState`); ``LS.fc`` (E, 5) is each
        episode's forecast error. None: the truth.
    X : (E, N, STATE_DIM) float64, optional
        The agents' state as the method knows it before the first step
        (:attr:`oneocean.tasks.episodes.Episodes.known_state`).
        Unused: the route starts where the vehicle does.
    """
    todo = np.flatnonzero(W.planned == 0)
    truth = LP is None or LS is None or LP.sens.true_current != 0
    for e in todo:
        pts = np.ascontiguousarray(W.route[e][:, [0, 2]])
        r = plan_episode(grid, M, pts, float(W.route[e, 0, 1]), float(t0[e]), P.t_lim,
                         None if truth else LS.fc, int(e))
        routing.write_plan(r, W.wps, W.wspd, W.wcount, W.widx, int(e))
        W.planned[e] = 1


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    """The vehicle's action: line-of-sight route following at the stretch's programmed speed.

    A carrot ``M.look`` ahead along the planned legs
    (:func:`~oneocean.tasks.routing.follow_path`), at the route's depth, sought with
    :func:`~oneocean.tasks.common.seek_max` at the programmed speed raised where the sensed
    current needs it (:func:`~oneocean.tasks.routing.hold_speed`).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : RFParams
        The task's params (:func:`oneocean.tasks.rf.make`).
    W : RFWork
        The task's per-episode work arrays (:func:`oneocean.tasks.rf.make`); reads the route and
        the plan tokens ``wps`` / ``wspd`` / ``wcount``, advances ``widx``.
    M : RFPolicy
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
    cx, cz, u = follow_path(W.wps, W.wspd, W.wcount, W.widx, e, s[0], s[2], M.look,
                            M.capture * P.radius, 1)
    gy = W.route[e, 0, 1]
    u = hold_speed(u, cx - s[0], cz - s[2], pe, pn, M.v_max)
    ax, ay, az = seek_max(s[0], s[1], s[2], cx, gy, cz, u, M.kp, pe, pn)
    return ax, ay, az, math.nan
