"""DPT — depth-profile tracking along a route under currents (1 agent).

Objective
    Follow a route of ``n_waypoints`` legs (``leg_m`` metres horizontally, turns of at most
    ``MAX_TURN_DEG``) while tracking a target depth profile: piecewise linear in the
    along-route distance between per-vertex depths drawn in
    ``[PROFILE_MIN_DEPTH_M, PROFILE_MIN_DEPTH_M + depth_span_m]``. Every straight 3-D leg of
    the profile keeps ``MIN_ALTITUDE_M`` above the product's seafloor (checked every 20 m), so
    the profile is always above the seafloor plus clearance.
Target depth at the agent
    ``y*(x, z)`` = the profile at the agent's horizontal projection on the active leg
    (clamped to the leg). Depth error = ``y - y*``.
Success
    Route completed (every waypoint reached in order, horizontal distance within
    ``wp_radius_m``) before ``time_limit_s`` AND RMS depth error at most ``depth_tol_m``.
    The episode stops at the last waypoint (``T_s``; the time limit on failure).
Metrics
    ``depth_error_m`` (primary: RMS depth error over the steps run, m),
    ``waypoints_reached`` (count), ``max_depth_error_m`` (m), ``cross_track_error_m``
    (mean horizontal distance to the active leg, m).
Active leg
    The judge's active waypoint ``W.wp`` advances on the true position; the vehicle's
    mission computer keeps its own, ``W.nwp``, advanced on the position it knows
    (:func:`~oneocean.tasks.waypoints.nav_waypoint`): a vehicle whose navigation has drifted
    turns for the next leg where it believes the waypoint is, and a waypoint it missed does
    not count.
Briefing (:class:`DPTBriefing`, after the common fields of :mod:`oneocean.tasks.public`)
    The ``route`` with its depth profile (vertex 0: where the vehicle starts), the waypoint
    radius and the bound on the RMS depth error.
Observation
    The cue is the point ``CUE_LOOKAHEAD_M`` ahead of the agent's known horizontal
    projection on the mission computer's active leg (``W.nwp``, advanced in the cue; clamped
    to the waypoint), at the target depth ``y*`` (the profile at the projection itself, so
    ``goal_dy_m`` is minus the depth error as the vehicle knows it); once the route is done
    as far as the vehicle knows, the last waypoint. The task has no observation fields of its own.
Methods
    :mod:`oneocean.methods.heuristic.dpt` (depth loop plus horizontal line-of-sight guidance
    on its own copy of the mission computer's leg pointer; both at full speed, both with the
    profile's slope fed forward; heuristic: the sensor models of :mod:`oneocean.sensing`;
    oracle: true current and position).

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset``; ``DPTParams`` / ``DPTWork`` and ``make``; the briefing
    (``DPTBriefing``, ``BRIEF_FIELDS``, ``brief``); the env hooks ``begin``, ``cue``,
    ``post_step``, ``finish``; the compiled loop is :mod:`oneocean.kernels.dpt`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..engine.constraints import DEFAULT_LAND_THRESHOLD
from ..engine._jit import hot_kernel
from ..errors import ConfigError
from .common import MIN_ALTITUDE_M, PURPOSE_RESET, STANDARD
from .spawn import sample_routes, start_times
from .tiers import need_tier
from .waypoints import nav_waypoint, profile_at
from .public import briefing_class, common_brief
from ..engine import streams
from ..engine import libm

TASK_ID = "DPT"
METRICS = ("depth_error_m", "waypoints_reached", "max_depth_error_m", "cross_track_error_m")
INT_METRICS = ("waypoints_reached",)
COLUMNS = STANDARD + METRICS

#: Shallowest vertex depth of the target profile, m.
PROFILE_MIN_DEPTH_M = 3.0
#: Largest heading change between consecutive legs, degrees.
MAX_TURN_DEG = 120.0
#: Horizontal lookahead of the observation's route cue along the active leg, m.
CUE_LOOKAHEAD_M = 20.0

_C_DERR, _C_WP, _C_DMAX, _C_XTE = (len(STANDARD) + i for i in range(len(METRICS)))


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the route with its depth profile and the start time of every episode.

    Returns
    -------
    dict
        ``route`` (E, W + 1, 3) vertices (x, target depth, z), m; ``pos0`` (E, 1, 3) m (on
        vertex 0); ``psi0`` (E, 1) facing the first leg, rad; ``t0`` (E,) s.

    Raises
    ------
    ConfigError
        Wrong team size, missing tier keys, ``n_waypoints < 1`` or a negative
        ``depth_span_m``.
    NotApplicable
        No valid route for some episode.
    """
    if int(n_agents) != 1:
        raise ConfigError(f"task {TASK_ID}: single-agent task, got n_agents={n_agents}")
    need_tier(TASK_ID, tier, "n_waypoints", "leg_m", "depth_span_m", "time_limit_s")
    n_wp = int(tier["n_waypoints"])
    if n_wp < 1:
        raise ConfigError(f"task {TASK_ID}: n_waypoints must be >= 1, got {n_wp}")
    span = float(tier["depth_span_m"])
    if not span >= 0:
        raise ConfigError(f"task {TASK_ID}: depth_span_m must be >= 0, got {span}")
    rngs = streams.episode_states(seed, n_episodes, PURPOSE_RESET)    # one stream per episode
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    route, failed = sample_routes(grid, rngs, n_wp, float(tier["leg_m"]),
                                  (PROFILE_MIN_DEPTH_M, PROFILE_MIN_DEPTH_M + span),
                                  MIN_ALTITUDE_M, max_turn_rad=math.radians(MAX_TURN_DEG),
                                  land_threshold=DEFAULT_LAND_THRESHOLD, vary_depth=True,
                                  what=lambda e: f"task {TASK_ID} reset (episode {e})")
    if failed:
        raise failed[min(failed)]
    d = route[:, 1] - route[:, 0]
    psi0 = libm.arctan2(d[:, 0], d[:, 2])[:, None]
    return {"route": route, "pos0": route[:, :1].copy(), "psi0": psi0, "t0": t0}


class DPTParams(NamedTuple):
    """DPT's params (one rollout).

    Attributes
    ----------
    radius : float
        Horizontal waypoint radius, m.
    depth_tol : float
        Bound on the RMS depth error for success, m.
    look : float
        Horizontal lookahead of the observation's route cue, m.
    """
    radius: float           # horizontal waypoint radius, m
    depth_tol: float        # bound on the RMS depth error for success, m
    look: float             # horizontal lookahead of the observation's route cue, m


class DPTWork(NamedTuple):
    """DPT's per-episode work arrays.

    Attributes
    ----------
    route : (E, W + 1, 3) float64
        Route vertices (x, target depth, z), m.
    wp : (E,) int64
        The judge's active waypoint (true position; 1..W; W + 1 when the route is done).
    nwp : (E,) int64
        The mission computer's (known position;
        :func:`~oneocean.tasks.waypoints.nav_waypoint`).
    acc : (E, 3) float64
        Sum of squared depth errors (m2), max depth error (m), sum of cross-track errors (m).
    """
    route: np.ndarray       # (E, W + 1, 3) route vertices (x, target depth, z), m
    wp: np.ndarray          # (E,) int64 the judge's active waypoint (true position; 1..W;
                            #        W + 1 when the route is done)
    nwp: np.ndarray         # (E,) int64 the mission computer's (known position; nav_waypoint)
    acc: np.ndarray         # (E, 3) sum of squared and max depth error, sum of cross-track, m


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    Returns
    -------
    P : DPTParams
        The env's typed scalars.
    W : DPTWork
        The env's per-episode work arrays.

    Raises
    ------
    ConfigError
        Missing tier parameters.
    """
    need_tier(TASK_ID, tier, "wp_radius_m", "depth_tol_m")
    route = np.ascontiguousarray(init["route"], dtype=np.float64)
    n_ep = route.shape[0]
    return (DPTParams(float(tier["wp_radius_m"]), float(tier["depth_tol_m"]), CUE_LOOKAHEAD_M),
            DPTWork(route, np.ones(n_ep, np.int64), np.ones(n_ep, np.int64), np.zeros((n_ep, 3))))


#: The task's own observation fields: none (the cue carries the target depth).
OBS_EXTRA_DOCS: dict = {}
OBS_EXTRA = ()
#: What the cue is (the observation's ``goal_d*`` fields).
CUE_DOC = ("the route point 20 m ahead of the vehicle's known horizontal projection on the active "
           "leg, at the target depth at the projection (so goal_dy_m is minus the depth error); "
           "the last waypoint once the route is done")

#: The briefing's own fields (after :data:`oneocean.tasks.public.COMMON`): name -> (shape,
#: unit, meaning).
BRIEF_FIELDS = {
    "route": ("(E, W + 1, 3)", "m", "the route's vertices (world x east, y the target depth, "
              "z north): vertex 0 where the vehicle starts, then the waypoints in order; the "
              "target depth is linear in the horizontal distance along each leg"),
    "radius": ("", "m", "horizontal waypoint radius"),
    "depth_tol": ("", "m", "success: RMS depth error at most this"),
}


DPTBriefing = briefing_class("DPT", BRIEF_FIELDS, __name__)


def brief(P: DPTParams, W: DPTWork, init: dict, m) -> DPTBriefing:
    """The briefing of every episode of a batch (:class:`oneocean.tasks.public.Mission`
    ``m``): the route and its depth profile, the waypoint radius, the depth tolerance.

    Returns
    -------
    DPTBriefing
    """
    return DPTBriefing(**common_brief(m), route=W.route.copy(), radius=P.radius,
                       depth_tol=P.depth_tol)


@hot_kernel
def begin(ctx, e):
    """Reset the waypoint pointers and accumulators.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``ctx.state`` holds the start.

    Returns
    -------
    bool
        True (the episode ends) for a route without waypoints.
    """
    W = ctx.W
    W.wp[e] = 1
    W.nwp[e] = 1
    W.acc[e, 0] = 0.0
    W.acc[e, 1] = 0.0
    W.acc[e, 2] = 0.0
    return W.wp[e] > W.route.shape[1] - 1


@hot_kernel
def cue(ctx, e, k, i):
    """The route point ``P.look`` m ahead of the agent's known horizontal projection on the
    active leg, at the target depth (the profile at the projection).

    Env hook (:mod:`oneocean.tasks.loop`): the observation's goal cue and probe.

    The leg is the mission computer's: its pointer ``W.nwp`` is advanced here, on the
    known horizontal position (:func:`~oneocean.tasks.waypoints.nav_waypoint`); the point is
    clamped to the waypoint, and once the route is done the cue is the last waypoint.

    Returns
    -------
    gx, gy, gz : float
        The goal cue, world m.
    probe : float
        NaN (the task has no field).
    """
    P, W, X = ctx.P, ctx.W, ctx.X
    s = X[e, i]
    wp = nav_waypoint(W.route, W.nwp, e, s[0], s[1], s[2], P.radius, 1)
    if wp > W.route.shape[1] - 1:   # route done as far as the vehicle knows: the last waypoint
        g = W.route[e, wp - 1]
        return g[0], g[1], g[2], math.nan
    a0 = W.route[e, wp - 1]
    b0 = W.route[e, wp]
    sh, ln, tx, tz, ytgt, _, _ = profile_at(a0[0], a0[1], a0[2], b0[0], b0[1], b0[2],
                                            s[0], s[2])
    sl = min(max(sh, 0.0) + P.look, ln)
    return a0[0] + sl * tx, ytgt, a0[2] + sl * tz, math.nan


@hot_kernel
def post_step(ctx, e, k):
    """Depth and cross-track error and the judge's waypoint after the step.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``.

    Returns
    -------
    bool
        True (STOP) once the last waypoint is reached (horizontally, on the true position).
    """
    P, W, state = ctx.P, ctx.W, ctx.state
    s = state[e, 0]
    wp = W.wp[e]
    a0 = W.route[e, wp - 1]
    b0 = W.route[e, wp]
    _, _, _, _, ytgt, _, xt = profile_at(a0[0], a0[1], a0[2], b0[0], b0[1], b0[2], s[0], s[2])
    de = s[1] - ytgt
    a = W.acc[e]
    a[0] += de * de
    if abs(de) > a[1]:
        a[1] = abs(de)
    a[2] += xt
    if (s[0] - b0[0]) ** 2 + (s[2] - b0[2]) ** 2 <= P.radius * P.radius:
        wp += 1
        W.wp[e] = wp
    return wp > W.route.shape[1] - 1


@hot_kernel
def finish(ctx, e, k):
    """Write the DPT metrics.

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Returns
    -------
    bool
        Success: every waypoint reached and the RMS depth error at most ``P.depth_tol``.
    """
    P, W = ctx.P, ctx.W
    row = ctx.res[e]
    a = W.acc[e]
    wp = W.wp[e]
    kk = k if k > 0 else 1
    rms = math.sqrt(a[0] / kk)
    row[_C_DERR] = rms
    row[_C_WP] = wp - 1
    row[_C_DMAX] = a[1]
    row[_C_XTE] = a[2] / kk
    return wp > W.route.shape[1] - 1 and rms <= P.depth_tol
