"""RF — route following under currents (1 agent).

Objective
    Follow a route of ``n_waypoints`` straight legs of ``leg_m`` metres (consecutive legs
    turn by at most ``MAX_TURN_DEG``) at a constant depth, in order. The route is in valid
    water with ``MIN_ALTITUDE_M`` of clearance along every leg; the agent starts at rest on
    its first vertex, facing the first leg.
Success
    Every waypoint reached in order (within ``wp_radius_m``) before ``time_limit_s`` AND a
    mean cross-track error at most ``xte_max_m``. The episode stops when the last waypoint is
    reached (``T_s`` = that time; the time limit on failure).
Metrics
    ``cross_track_error_m`` (primary: mean over the steps run of the distance to the route
    near the agent = the nearer of the active leg and the previous leg, as segments, m),
    ``waypoints_reached`` (count), ``max_cross_track_m`` (m).
Observation cue
    The route point ``CUE_LOOKAHEAD_M`` ahead of the agent's projection on the active leg
    (clamped to the waypoint). Before every step the env also writes the agent's frame on the
    active leg (``leg_geometry``: along-track, tangent, length) into ``W.leg`` for the policy.
Methods
    :mod:`oneocean.methods.heuristic.rf` (line-of-sight guidance at full speed; heuristic:
    noisy probe; oracle: exact current).

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset``; ``RFParams`` / ``RFWork`` and ``make``; the env hooks
    ``begin``, ``pre_step``, ``cue``, ``post_step``, ``finish``; ``POLICY``; ``_kernel`` and
    ``_observe_kernel``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..engine.constraints import DEFAULT_LAND_THRESHOLD
from ..engine._jit import hot_kernel
from ..errors import ConfigError
from ..methods.heuristic import rf as POLICY
from .common import (DEPTH_RANGE_M, MIN_ALTITUDE_M, STANDARD, episode_generators, fresh_cache,
                     need_tier, sample_route, start_times)
from .loop import noop_after_agent, observe_next, run_episode

TASK_ID = "RF"
METRICS = ("cross_track_error_m", "waypoints_reached", "max_cross_track_m")
INT_METRICS = ("waypoints_reached",)
COLUMNS = STANDARD + METRICS

#: Largest heading change between consecutive legs, degrees.
MAX_TURN_DEG = 120.0
#: Lookahead of the observation's route cue along the active leg, m.
CUE_LOOKAHEAD_M = 20.0

_C_XTE, _C_WP, _C_XMAX = (len(STANDARD) + i for i in range(len(METRICS)))


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the route and start time of every episode.

    Returns
    -------
    dict
        ``route`` (E, W + 1, 3) vertices, m (vertex 0 = start, 1..W = waypoints);
        ``pos0`` (E, 1, 3) m; ``psi0`` (E, 1) facing the first leg, rad; ``t0`` (E,) s.
    """
    if int(n_agents) != 1:
        raise ConfigError(f"task {TASK_ID}: single-agent task, got n_agents={n_agents}")
    need_tier(TASK_ID, tier, "n_waypoints", "leg_m", "time_limit_s")
    n_wp = int(tier["n_waypoints"])
    if n_wp < 1:
        raise ConfigError(f"task {TASK_ID}: n_waypoints must be >= 1, got {n_wp}")
    rngs = episode_generators(seed, n_episodes)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    route = np.empty((n_episodes, n_wp + 1, 3))
    for e, rng in enumerate(rngs):
        route[e] = sample_route(grid, rng, n_wp, float(tier["leg_m"]), DEPTH_RANGE_M,
                                MIN_ALTITUDE_M, max_turn_rad=math.radians(MAX_TURN_DEG),
                                land_threshold=DEFAULT_LAND_THRESHOLD,
                                what=f"task {TASK_ID} reset (episode {e})")
    d = route[:, 1] - route[:, 0]
    psi0 = np.arctan2(d[:, 0], d[:, 2])[:, None]
    return {"route": route, "pos0": route[:, :1].copy(), "psi0": psi0, "t0": t0}


@hot_kernel(inline="always")
def leg_geometry(ax_, ay_, az_, bx, by, bz, px, py, pz):
    """Projection of point p on segment a->b: (along-track m, cross-track distance m, unit
    tangent (tx, ty, tz), leg length m). The cross-track distance is to the segment."""
    lx = bx - ax_
    ly = by - ay_
    lz = bz - az_
    ln = math.sqrt(lx * lx + ly * ly + lz * lz)
    if ln <= 1e-12:
        return 0.0, math.sqrt((px - ax_) ** 2 + (py - ay_) ** 2 + (pz - az_) ** 2), 0.0, 0.0, \
            0.0, 0.0
    tx = lx / ln
    ty = ly / ln
    tz = lz / ln
    s = (px - ax_) * tx + (py - ay_) * ty + (pz - az_) * tz
    sc = min(max(s, 0.0), ln)
    qx = ax_ + sc * tx - px
    qy = ay_ + sc * ty - py
    qz = az_ + sc * tz - pz
    return s, math.sqrt(qx * qx + qy * qy + qz * qz), tx, ty, tz, ln


class RFParams(NamedTuple):
    radius: float           # waypoint radius, m
    xte_max: float          # bound on the mean cross-track error for success, m
    look: float             # lookahead of the observation's route cue, m


class RFWork(NamedTuple):
    route: np.ndarray       # (E, W + 1, 3) route vertices, m
    wp: np.ndarray          # (E,) int64 active waypoint (1..W; W + 1 when the route is done)
    leg: np.ndarray         # (E, 5) agent on the active leg before the step: along-track m,
                            #        unit tangent (x, y, z), leg length m
    acc: np.ndarray         # (E, 2) sum and max of the cross-track error, m


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`)."""
    need_tier(TASK_ID, tier, "wp_radius_m", "xte_max_m")
    route = np.ascontiguousarray(init["route"], dtype=np.float64)
    n_ep = route.shape[0]
    return (RFParams(float(tier["wp_radius_m"]), float(tier["xte_max_m"]), CUE_LOOKAHEAD_M),
            RFWork(route, np.ones(n_ep, np.int64), np.zeros((n_ep, 5)), np.zeros((n_ep, 2))))


@hot_kernel(inline="always")
def begin(grid, P, W, state, e):
    W.wp[e] = 1
    W.acc[e, 0] = 0.0
    W.acc[e, 1] = 0.0
    return W.wp[e] > W.route.shape[1] - 1


@hot_kernel(inline="always")
def pre_step(grid, P, W, state, e, k, t):
    s = state[e, 0]
    wp = W.wp[e]
    a0 = W.route[e, wp - 1]
    b0 = W.route[e, wp]
    al, _, tx, ty, tz, ln = leg_geometry(a0[0], a0[1], a0[2], b0[0], b0[1], b0[2],
                                         s[0], s[1], s[2])
    g = W.leg[e]
    g[0] = al
    g[1] = tx
    g[2] = ty
    g[3] = tz
    g[4] = ln


@hot_kernel(inline="always")
def cue(grid, P, W, state, e, k, i):
    s = state[e, i]
    wp = W.wp[e]
    if wp > W.route.shape[1] - 1:   # route done: the last waypoint
        g = W.route[e, wp - 1]
        return g[0], g[1], g[2], math.nan
    a0 = W.route[e, wp - 1]
    b0 = W.route[e, wp]
    al, _, tx, ty, tz, ln = leg_geometry(a0[0], a0[1], a0[2], b0[0], b0[1], b0[2],
                                         s[0], s[1], s[2])
    sl = min(max(al, 0.0) + P.look, ln)
    return a0[0] + sl * tx, a0[1] + sl * ty, a0[2] + sl * tz, math.nan


@hot_kernel(inline="always")
def post_step(grid, P, W, state, prev, e, k, t):
    s = state[e, 0]
    wp = W.wp[e]
    a0 = W.route[e, wp - 1]
    b0 = W.route[e, wp]
    _, xt, _, _, _, _ = leg_geometry(a0[0], a0[1], a0[2], b0[0], b0[1], b0[2],
                                     s[0], s[1], s[2])
    if wp >= 2:  # just past a waypoint the previous leg is still the route nearby
        z0 = W.route[e, wp - 2]
        _, xp, _, _, _, _ = leg_geometry(z0[0], z0[1], z0[2], a0[0], a0[1], a0[2],
                                         s[0], s[1], s[2])
        if xp < xt:
            xt = xp
    a = W.acc[e]
    a[0] += xt
    if xt > a[1]:
        a[1] = xt
    if (s[0] - b0[0]) ** 2 + (s[1] - b0[1]) ** 2 + (s[2] - b0[2]) ** 2 <= P.radius * P.radius:
        wp += 1
        W.wp[e] = wp
    return wp > W.route.shape[1] - 1


@hot_kernel(inline="always")
def finish(grid, P, W, state, e, k, row):
    a = W.acc[e]
    wp = W.wp[e]
    xte = a[0] / k if k > 0 else 0.0
    row[_C_XTE] = xte
    row[_C_WP] = wp - 1
    row[_C_XMAX] = a[1]
    return wp > W.route.shape[1] - 1 and xte <= P.xte_max


# the one loop specialised to this task's hooks (see oneocean.tasks.loop for why two levels)
@hot_kernel
def _episode(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop):
    run_episode(begin, pre_step, cue, noop_after_agent, post_step, finish, POLICY.plan,
                POLICY.act, grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e,
                k_stop)


@njit(cache=True, nogil=True)
def _kernel(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, k_stop, e_lo, e_hi):
    for e in range(e_lo, e_hi):
        _episode(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop)


@hot_kernel
def _observe(grid, LP, P, W, LS, t0, state, nobs, nact, e):
    observe_next(grid, cue, P, W, LP, state, t0, e, LS.k[e], nobs, nact)


@njit(cache=True, nogil=True)
def _observe_kernel(grid, LP, P, W, LS, t0, state, nobs, nact, e_lo, e_hi):
    for e in range(e_lo, e_hi):
        _observe(grid, LP, P, W, LS, t0, state, nobs, nact, e)


# numba keys a cache entry on this file only; drop it when the engine or the task layer
# changes.
fresh_cache(_kernel, __file__, POLICY.__file__)
