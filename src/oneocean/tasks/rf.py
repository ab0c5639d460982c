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
Methods
    Both use line-of-sight guidance: aim at the point ``LOOKAHEAD_M`` ahead of the agent's
    projection on the active leg (clamped to the waypoint) with
    :func:`~oneocean.tasks.common.seek_max` (cross-track current fed forward first).
    ``heuristic``: NOISY probed current, throttle cap ``CRUISE_FRAC * v_max``.
    ``oracle``: exact current, full ``v_max``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..engine.constraints import DEFAULT_LAND_THRESHOLD
from ..engine.dynamics import CMD_DIM, model_id, new_state
from ..engine._jit import hot_kernel
from ..errors import ConfigError
from .common import (CLEARANCE_M, CRUISE_FRAC, DEPTH_RANGE_M, HEURISTIC, MIN_ALTITUDE_M, OK,
                     STANDARD, advance_agent, current_at, episode_generators, episode_steps,
                     fresh_cache, method_id, need_tier, obs_buffers, observe, rollout_results,
                     sample_route, seek_max, sensed_current, set_velocity_cmd, start_times)

TASK_ID = "RF"
METRICS = ("cross_track_error_m", "waypoints_reached", "max_cross_track_m")
COLUMNS = STANDARD + METRICS

#: Line-of-sight lookahead distance along the active leg, m.
LOOKAHEAD_M = 20.0
#: Proportional gain toward the lookahead point, s-1 (saturates: full speed on the route).
KP = 0.5
#: Largest heading change between consecutive legs, degrees.
MAX_TURN_DEG = 120.0

_I_MODEL, _I_METHOD, _I_STEPS, _I_SEED = range(4)
_F_DT, _F_VMAX, _F_SPEED, _F_KP, _F_NOISE, _F_RADIUS, _F_LAND, _F_CLEAR, _F_LOOK, _F_XTE = \
    range(10)
_C = {k: i for i, k in enumerate(COLUMNS)}
_C_SUCCESS, _C_T, _C_E, _C_COLL, _C_VIOL = (_C[k] for k in STANDARD)
_C_XTE, _C_WP, _C_XMAX = (_C[k] for k in METRICS)


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


@hot_kernel
def _episode(grid, vp, ipar, fpar, route, t0, state, cmd, obs, act, res, e):
    """Run episode ``e`` (serial) and write row ``e`` of ``res`` (see ``COLUMNS``)."""
    model = ipar[_I_MODEL]
    method = ipar[_I_METHOD]
    n_steps = ipar[_I_STEPS]
    seed = ipar[_I_SEED]
    dt = fpar[_F_DT]
    v_max = fpar[_F_VMAX]
    budget = fpar[_F_SPEED] if method == HEURISTIC else v_max
    kp = fpar[_F_KP]
    noise = fpar[_F_NOISE]
    radius = fpar[_F_RADIUS]
    land_thr = fpar[_F_LAND]
    clearance = fpar[_F_CLEAR]
    look = fpar[_F_LOOK]
    xte_max = fpar[_F_XTE]
    n_wp = route.shape[1] - 1
    s = state[e, 0]
    c = cmd[e, 0]
    energy = 0.0
    viol = 0
    sum_x = 0.0
    x_max = 0.0
    wp = 1
    k = 0
    while k < n_steps and wp <= n_wp:
        t = t0[e] + k * dt
        px = s[0]
        py = s[1]
        pz = s[2]
        ce, cn = current_at(grid, px, py, pz, t)
        pe, pn = sensed_current(method, ce, cn, noise, seed, e, 2 * k)
        a0 = route[e, wp - 1]
        b0 = route[e, wp]
        al, _, tx, ty, tz, ln = leg_geometry(a0[0], a0[1], a0[2], b0[0], b0[1], b0[2],
                                             px, py, pz)
        sl = min(max(al, 0.0) + look, ln)
        lx = a0[0] + sl * tx
        ly = a0[1] + sl * ty
        lz = a0[2] + sl * tz
        ax, ay, az = seek_max(px, py, pz, lx, ly, lz, budget, kp, pe, pn)
        observe(obs, act, e, k, 0, grid, state, lx, ly, lz, pe, pn, math.nan, ax, ay, az)
        set_velocity_cmd(c, ax, ay, az)
        en, code = advance_agent(grid, model, vp, s, c, ce, cn, v_max, dt, land_thr, clearance)
        energy += en
        if code != OK:
            viol += 1
        _, xt, _, _, _, _ = leg_geometry(a0[0], a0[1], a0[2], b0[0], b0[1], b0[2],
                                         s[0], s[1], s[2])
        if wp >= 2:  # just past a waypoint the previous leg is still the route nearby
            z0 = route[e, wp - 2]
            _, xp, _, _, _, _ = leg_geometry(z0[0], z0[1], z0[2], a0[0], a0[1], a0[2],
                                             s[0], s[1], s[2])
            if xp < xt:
                xt = xp
        sum_x += xt
        if xt > x_max:
            x_max = xt
        k += 1
        if (s[0] - b0[0]) ** 2 + (s[1] - b0[1]) ** 2 + (s[2] - b0[2]) ** 2 <= radius * radius:
            wp += 1
    xte = sum_x / k if k > 0 else 0.0
    done = wp > n_wp
    success = done and xte <= xte_max
    res[e, _C_SUCCESS] = 1.0 if success else 0.0
    res[e, _C_T] = k * dt if success else n_steps * dt
    res[e, _C_E] = energy
    res[e, _C_COLL] = 0.0
    res[e, _C_VIOL] = viol
    res[e, _C_XTE] = xte
    res[e, _C_WP] = wp - 1
    res[e, _C_XMAX] = x_max


@njit(parallel=True, cache=True)
def _kernel(grid, vp, ipar, fpar, route, t0, state, cmd, obs, act, res):
    for e in prange(res.shape[0]):
        _episode(grid, vp, ipar, fpar, route, t0, state, cmd, obs, act, res, e)


def rollout(grid, tier: dict, init: dict, method: str, dyn: str, vehicle, seed: int, *,
            record: bool = False) -> dict:
    """Run every episode of ``init`` (from :func:`reset`); see :func:`.g2g.rollout`."""
    need_tier(TASK_ID, tier, "time_limit_s", "wp_radius_m", "xte_max_m", "probe_noise_ms", "dt_s")
    dt = float(tier["dt_s"])
    route = np.ascontiguousarray(init["route"], dtype=np.float64)
    n_ep = route.shape[0]
    v_max = float(vehicle.v_max)
    ipar = np.array([model_id(dyn), method_id(method),
                     episode_steps(tier), int(seed)],
                    dtype=np.int64)
    fpar = np.array([dt, v_max, CRUISE_FRAC * v_max, KP, float(tier["probe_noise_ms"]),
                     float(tier["wp_radius_m"]), DEFAULT_LAND_THRESHOLD, CLEARANCE_M,
                     LOOKAHEAD_M, float(tier["xte_max_m"])])
    state = new_state(n_ep, 1, init["pos0"], init["psi0"])
    cmd = np.zeros((n_ep, 1, CMD_DIM))
    res = np.zeros((n_ep, len(COLUMNS)))
    obs, act = obs_buffers(tier, init, record)
    _kernel(grid, vehicle.params, ipar, fpar, route,
            np.ascontiguousarray(init["t0"], dtype=np.float64), state, cmd, obs, act, res)
    out = rollout_results(res, COLUMNS, obs, act, record)
    out["waypoints_reached"] = out["waypoints_reached"].astype(np.int64)
    return out


# numba keys a cache entry on this file only; drop it when the engine or the task layer
# changes.
fresh_cache(_kernel, __file__)
