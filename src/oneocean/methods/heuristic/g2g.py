"""G2G heuristic and oracle: plan the transit through the field, then fly the plan.

Plan
    Made in Python by :func:`prepare` before the episode's first step; the plan tokens are
    the work arrays ``W.wps``, ``W.wspd``, ``W.wcount``, ``W.widx`` of
    :mod:`oneocean.tasks.g2g`. The least-energy route and speed schedule from the start (as
    the method knows it) to the goal through the current field over the episode
    (:func:`oneocean.tasks.routing.plan_mission`: time-dependent Dijkstra over a lattice,
    string pulling, then the programmed speed of every stretch of at most ``PIECE_M`` m among
    the mission speeds ``SPEED_MIN .. v_max``, with the vehicle's power model
    ``data/vehicles.yaml`` ``power:``; without a power model: the fastest route at
    ``v_max``). The field is what the method knows of the currents: a method with the true
    current (the oracle; an information ablation) plans on the truth, every other method on
    its FORECAST of it (the true field through the episode's forecast-error model
    ``LoopState.fc``, :mod:`oneocean.sensing`).
Act
    ``act``, every step. Line-of-sight following of the planned polyline
    (:func:`~oneocean.tasks.routing.follow_path`: a carrot ``LOOKAHEAD_M`` ahead), crabbing
    with the current estimate (:func:`~oneocean.tasks.common.seek_max`: the cross-track
    current is cancelled first) at the stretch's programmed speed, raised when the sensed
    current needs it (:func:`~oneocean.tasks.routing.hold_speed`: cross-current headroom and
    a minimum ground speed, up to ``v_max``). The carrot is the observation's goal cue.

Heuristic and oracle differ in information only (forecast vs true field for the plan, the
sensor models vs the truth for steering and navigation): the same planner, steering and
gains. :func:`straight_plan` is the plan of a vehicle that does not plan (the straight line
at its cruise speed, :func:`~oneocean.tasks.routing.cruise_speed`): the baseline the
calibration compares against.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...errors import ConfigError
from ...tasks.common import ARRIVE_M, seek_max
from ...tasks.loop import noop_plan as plan  # noqa: F401  (the plan is made in Python)
from ...tasks import routing
from ...tasks.routing import follow_path, hold_speed
from . import SENSING  # noqa: F401

#: Proportional gain of the final approach (ground speed <= KP * distance to the carrot), s-1.
KP = 0.5
#: Line-of-sight lookahead along the planned route, m.
LOOKAHEAD_M = 30.0
#: A corner of the planned route counts as passed within this distance (m): wider than the
#: torpedo's turning diameter, so it never orbits a corner (tasks.common.ARRIVE_M).
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


def params(method: str, tier: dict, vehicle) -> G2GPolicy:
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
        Its power model (:func:`vehicle_power`), if any.

    Returns
    -------
    G2GPolicy
        ``v_max``, the module's gains, the power model's ``hotel_w`` and ``k`` (0 without one).
    """
    pw = vehicle_power(vehicle)
    return G2GPolicy(float(vehicle.v_max), KP, LOOKAHEAD_M, WP_TOL_M,
                     0.0 if pw is None else pw.hotel_w, 0.0 if pw is None else pw.k)


def vehicle_power(vehicle):
    """The vehicle's power model (``power:`` section of ``data/vehicles.yaml``).

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle (:class:`oneocean.engine.dynamics.Vehicle`); its ``name`` is looked up.

    Returns
    -------
    PowerModel or None
        :class:`~oneocean.tasks.routing.PowerModel`, None if the vehicle has none.
    """
    try:
        return routing.power_model(vehicle.name)
    except ConfigError:
        return None


def _power(M: G2GPolicy):
    return None if M.hotel_w <= 0.0 and M.pk <= 0.0 else routing.PowerModel(1.0, M.hotel_w,
                                                                            M.pk)


def plan_episode(grid, M: G2GPolicy, start, goal, depth: float, t0: float, duration: float,
                 fc=None, e: int = 0) -> routing.Route:
    """The method's route and speed schedule for one episode.

    :func:`oneocean.tasks.routing.plan_mission` from ``start`` to ``goal``; :func:`straight_plan`
    where no plan holds: no speed, a point outside the grid, or no passable route through the
    field the method knows.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    M : G2GPolicy
        The policy's params (:func:`params`).
    start, goal : tuple of float
        Start and goal (x, z), m.
    depth : float
        The transit's depth, m (positive down).
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
    pts = np.array([start, goal], dtype=np.float64)
    if not (M.v_max > 0.0 and routing.within_grid(grid, pts)):
        return straight_plan(grid, M, start, goal, depth, t0, duration, fc, e)
    r = routing.plan_mission(grid, pts, depth, t0, duration, M.v_max, _power(M), fc=fc, e=e)
    if not r.ok:   # no passable route through the field the method knows: the straight line
        return straight_plan(grid, M, start, goal, depth, t0, duration, fc, e)
    return r


def straight_plan(grid, M: G2GPolicy, start, goal, depth: float, t0: float, duration: float,
                  fc=None, e: int = 0) -> routing.Route:
    """The plan of a vehicle that does not plan: the straight line at its cruise speed.

    The cruise speed is :func:`oneocean.tasks.routing.cruise_speed` (the mission speed nearest
    the vehicle's maximum-range speed, else ``v_max``).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    M : G2GPolicy
        The policy's params (:func:`params`).
    start, goal : tuple of float
        Start and goal (x, z), m.
    depth : float
        The transit's depth, m (positive down).
    t0 : float
        Episode start time, s since the grid's ``time0_unix_s``.
    duration : float
        The episode's time limit, s (the planner's field window).
    fc : (E, 5) float64, optional
        The episodes' forecast errors (``LoopState.fc``); None: plan on the true currents.
    e : int, optional
        Episode index into ``fc`` (default 0).
        ``depth``, ``duration``, ``fc`` and ``e`` are unused (the signature of
        :func:`plan_episode`).

    Returns
    -------
    Route
        Vertices ``[start, goal]``, one speed, arrival times ``[t0, NaN]``, cost NaN, ``ok``.
    """
    u = routing.cruise_speed(M.v_max, _power(M))
    return routing.Route(np.array([start, goal], dtype=np.float64), np.array([u]),
                         np.array([float(t0), math.nan]), math.nan, True)


#: The task's observation cue does not read this policy's plan tokens (its route and speed
#: schedule), so a rollout with external actions (the step API) skips :func:`prepare`.
PREPARE_EXTERNAL = False


def prepare(grid, P, W, M: G2GPolicy, t0, LP=None, LS=None, X=None) -> None:
    """The Python planner: plan every episode not yet planned (``W.planned``).

    From the start the method knows (``X``: the known state, else the task's start
    ``W.start``) to the goal at its depth, on the field it knows (``LP.sens.true_current``:
    the truth, else the forecast ``LS.fc``); written as the plan tokens ``W.wps``, ``W.wspd``,
    ``W.wcount``, ``W.widx`` (:func:`oneocean.tasks.routing.write_plan`).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : G2GParams
        The task's params (:func:`oneocean.tasks.g2g.make`).
    W : G2GWork
        The task's per-episode work arrays; the plan tokens are written in place.
    M : G2GPolicy
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
    """
    todo = np.flatnonzero(W.planned == 0)
    truth = LP is None or LS is None or LP.sens.true_current != 0
    for e in todo:
        s = X[e, 0] if X is not None else W.start[e]
        start = (float(s[0]), float(s[2]))
        goal = (float(W.goal[e, 0]), float(W.goal[e, 2]))
        r = plan_episode(grid, M, start, goal, float(W.goal[e, 1]), float(t0[e]), P.t_lim,
                         None if truth else LS.fc, int(e))
        routing.write_plan(r, W.wps, W.wspd, W.wcount, W.widx, int(e))
        W.planned[e] = 1


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    """The vehicle's action: line-of-sight following of the planned route at its programmed speed.

    A carrot ``M.look`` ahead along the planned polyline
    (:func:`~oneocean.tasks.routing.follow_path`), at the goal's depth, sought with
    :func:`~oneocean.tasks.common.seek_max` at the programmed speed raised where the sensed
    current needs it (:func:`~oneocean.tasks.routing.hold_speed`).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : G2GParams
        The task's params (:func:`oneocean.tasks.g2g.make`).
    W : G2GWork
        The task's per-episode work arrays (:func:`oneocean.tasks.g2g.make`); reads the goal and
        the plan tokens ``wps`` / ``wspd`` / ``wcount``, advances ``widx``.
    M : G2GPolicy
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
    cx, cz, u = follow_path(W.wps, W.wspd, W.wcount, W.widx, e, s[0], s[2], M.look, M.tol, 1)
    gy = W.goal[e, 1]
    u = hold_speed(u, cx - s[0], cz - s[2], pe, pn, M.v_max)
    ax, ay, az = seek_max(s[0], s[1], s[2], cx, gy, cz, u, M.kp, pe, pn)
    return ax, ay, az, math.nan
