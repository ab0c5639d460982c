"""G2G heuristic and oracle: plan the transit through the field, then fly the plan.

Plan (Python, :func:`prepare` before the episode's first step; the plan tokens are the work
arrays ``W.wps``, ``W.wspd``, ``W.wcount``, ``W.widx`` of :mod:`oneocean.tasks.g2g`)
    The least-energy route and speed schedule from the start (as the method knows it) to the
    goal through the current field over the episode (:func:`oneocean.tasks.routing.
    plan_mission`: time-dependent Dijkstra over a lattice, string pulling, then the
    programmed speed of every stretch of at most ``PIECE_M`` m among the mission speeds
    ``SPEED_MIN .. v_max``, with the vehicle's power model ``data/vehicles.yaml`` ``power:``;
    without a power model: the fastest route at ``v_max``). The field is what the method
    knows of the currents: a method with the true current (the oracle; an information
    ablation) plans on the truth, every other method on its FORECAST of it (the true field
    through the episode's forecast-error model ``LoopState.fc``, :mod:`oneocean.sensing`).
Act (``act``, every step)
    Line-of-sight following of the planned polyline (:func:`~oneocean.tasks.routing.
    follow_path`: a carrot ``LOOKAHEAD_M`` ahead), crabbing with the current estimate
    (:func:`~oneocean.tasks.common.seek_max`: the cross-track current is cancelled first) at
    the stretch's programmed speed, raised when the sensed current needs it
    (:func:`~oneocean.tasks.routing.hold_speed`: cross-current headroom and a minimum
    ground speed, up to ``v_max``). The carrot is the observation's goal cue.

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
    v_max: float    # vehicle speed limit through the water, m s-1
    kp: float       # approach gain, s-1
    look: float     # line-of-sight lookahead, m
    tol: float      # corner capture distance, m
    hotel_w: float  # power model (0, 0: none; plan the fastest route at v_max)
    pk: float


def params(method: str, tier: dict, vehicle) -> G2GPolicy:
    pw = vehicle_power(vehicle)
    return G2GPolicy(float(vehicle.v_max), KP, LOOKAHEAD_M, WP_TOL_M,
                     0.0 if pw is None else pw.hotel_w, 0.0 if pw is None else pw.k)


def vehicle_power(vehicle):
    """The vehicle's :class:`~oneocean.tasks.routing.PowerModel`, None if it has none."""
    try:
        return routing.power_model(vehicle.name)
    except ConfigError:
        return None


def _power(M: G2GPolicy):
    return None if M.hotel_w <= 0.0 and M.pk <= 0.0 else routing.PowerModel(1.0, M.hotel_w,
                                                                            M.pk)


def plan_episode(grid, M: G2GPolicy, start, goal, depth: float, t0: float, duration: float,
                 fc=None, e: int = 0) -> routing.Route:
    """The method's route for one episode (``fc``: plan on the forecast of episode ``e``)."""
    pts = np.array([start, goal], dtype=np.float64)
    if not (M.v_max > 0.0 and routing.within_grid(grid, pts)):
        return straight_plan(grid, M, start, goal, depth, t0, duration, fc, e)
    r = routing.plan_mission(grid, pts, depth, t0, duration, M.v_max, _power(M), fc=fc, e=e)
    if not r.ok:   # no passable route through the field the method knows: the straight line
        return straight_plan(grid, M, start, goal, depth, t0, duration, fc, e)
    return r


def straight_plan(grid, M: G2GPolicy, start, goal, depth: float, t0: float, duration: float,
                  fc=None, e: int = 0) -> routing.Route:
    """The plan of a vehicle that does not plan: the straight line at its cruise speed."""
    u = routing.cruise_speed(M.v_max, _power(M))
    return routing.Route(np.array([start, goal], dtype=np.float64), np.array([u]),
                         np.array([float(t0), math.nan]), math.nan, True)


#: The task's observation cue does not read this policy's plan tokens (its route and speed
#: schedule), so a rollout with external actions (the step API) skips :func:`prepare`.
PREPARE_EXTERNAL = False


def prepare(grid, P, W, M: G2GPolicy, t0, LP=None, LS=None, X=None) -> None:
    """The Python planner: plan every episode not yet planned (``W.planned``) from the start
    the method knows (``X``: the known state, else the task's start) on the field it knows
    (``LP.sens.true_current``: the truth, else the forecast ``LS.fc``)."""
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
    s = state[e, i]
    cx, cz, u = follow_path(W.wps, W.wspd, W.wcount, W.widx, e, s[0], s[2], M.look, M.tol, 1)
    gy = W.goal[e, 1]
    u = hold_speed(u, cx - s[0], cz - s[2], pe, pn, M.v_max)
    ax, ay, az = seek_max(s[0], s[1], s[2], cx, gy, cz, u, M.kp, pe, pn)
    return ax, ay, az, math.nan
