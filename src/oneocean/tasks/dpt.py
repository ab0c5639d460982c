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
Methods
    Horizontal line-of-sight guidance (lookahead ``LOOKAHEAD_M``, cross-track current fed
    forward first, :func:`~oneocean.tasks.common.seek_max`) with the budget left after a
    depth loop ``w = KZ (y* - y)`` (vertical command first, at most half the budget).
    ``heuristic``: NOISY probed current, throttle cap ``CRUISE_FRAC * v_max``, P depth loop
    on the local target depth only (it lags on slopes by ``slope * ground speed / KZ``).
    ``oracle``: exact current, full ``v_max``, plus feed-forward of the profile slope times
    the along-track ground speed (preview of the planned profile).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..engine.constraints import DEFAULT_LAND_THRESHOLD
from ..engine.dynamics import CMD_DIM, VX, VZ, model_id, new_state
from ..engine._jit import hot_kernel
from ..errors import ConfigError
from .common import (CLEARANCE_M, CRUISE_FRAC, HEURISTIC, MIN_ALTITUDE_M, OK, STANDARD,
                     advance_agent, current_at, episode_generators, episode_steps, fresh_cache,
                     method_id, need_tier, obs_buffers, observe, rollout_results, sample_route,
                     seek_max, sensed_current, set_velocity_cmd, start_times)

TASK_ID = "DPT"
METRICS = ("depth_error_m", "waypoints_reached", "max_depth_error_m", "cross_track_error_m")
COLUMNS = STANDARD + METRICS

#: Shallowest vertex depth of the target profile, m.
PROFILE_MIN_DEPTH_M = 3.0
#: Horizontal line-of-sight lookahead, m.
LOOKAHEAD_M = 20.0
#: Horizontal proportional gain toward the lookahead point, s-1.
KP = 0.5
#: Depth-loop gain, s-1.
KZ = 0.3
#: Largest heading change between consecutive legs, degrees.
MAX_TURN_DEG = 120.0

_I_MODEL, _I_METHOD, _I_STEPS, _I_SEED = range(4)
(_F_DT, _F_VMAX, _F_SPEED, _F_KP, _F_NOISE, _F_RADIUS, _F_LAND, _F_CLEAR, _F_LOOK, _F_KZ,
 _F_TOL) = range(11)
_C = {k: i for i, k in enumerate(COLUMNS)}
_C_SUCCESS, _C_T, _C_E, _C_COLL, _C_VIOL = (_C[k] for k in STANDARD)
_C_DERR, _C_WP, _C_DMAX, _C_XTE = (_C[k] for k in METRICS)


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the route with its depth profile and the start time of every episode.

    Returns
    -------
    dict
        ``route`` (E, W + 1, 3) vertices (x, target depth, z), m; ``pos0`` (E, 1, 3) m (on
        vertex 0); ``psi0`` (E, 1) facing the first leg, rad; ``t0`` (E,) s.
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
    rngs = episode_generators(seed, n_episodes)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    route = np.empty((n_episodes, n_wp + 1, 3))
    for e, rng in enumerate(rngs):
        route[e] = sample_route(grid, rng, n_wp, float(tier["leg_m"]),
                                (PROFILE_MIN_DEPTH_M, PROFILE_MIN_DEPTH_M + span),
                                MIN_ALTITUDE_M, max_turn_rad=math.radians(MAX_TURN_DEG),
                                land_threshold=DEFAULT_LAND_THRESHOLD, vary_depth=True,
                                what=f"task {TASK_ID} reset (episode {e})")
    d = route[:, 1] - route[:, 0]
    psi0 = np.arctan2(d[:, 0], d[:, 2])[:, None]
    return {"route": route, "pos0": route[:, :1].copy(), "psi0": psi0, "t0": t0}


@hot_kernel(inline="always")
def profile_at(ax_, ay_, az_, bx, by, bz, px, pz):
    """Horizontal projection of (px, pz) on leg a->b.

    Returns (along-track s m, horizontal leg length m, unit horizontal tangent (tx, tz),
    target depth at the clamped projection m, profile slope dy/ds, cross-track distance m).
    """
    lx = bx - ax_
    lz = bz - az_
    ln = math.sqrt(lx * lx + lz * lz)
    if ln <= 1e-12:
        return 0.0, 0.0, 0.0, 0.0, by, 0.0, math.sqrt((px - bx) ** 2 + (pz - bz) ** 2)
    tx = lx / ln
    tz = lz / ln
    s = (px - ax_) * tx + (pz - az_) * tz
    f = min(max(s / ln, 0.0), 1.0)
    qx = ax_ + f * lx - px
    qz = az_ + f * lz - pz
    return s, ln, tx, tz, ay_ + f * (by - ay_), (by - ay_) / ln, math.sqrt(qx * qx + qz * qz)


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
    kz = fpar[_F_KZ]
    n_wp = route.shape[1] - 1
    s = state[e, 0]
    c = cmd[e, 0]
    energy = 0.0
    viol = 0
    sum_d2 = 0.0
    d_max = 0.0
    sum_x = 0.0
    wp = 1
    k = 0
    while k < n_steps and wp <= n_wp:
        t = t0[e] + k * dt
        px = s[0]
        py = s[1]
        pz = s[2]
        ce, cn = current_at(grid, px, py, pz, t)
        pe, pn = sensed_current(method, ce, cn, noise, seed, e, 2 * k)
        a0x = route[e, wp - 1, 0]
        a0y = route[e, wp - 1, 1]
        a0z = route[e, wp - 1, 2]
        b0x = route[e, wp, 0]
        b0y = route[e, wp, 1]
        b0z = route[e, wp, 2]
        sh, ln, tx, tz, ytgt, slope, _ = profile_at(a0x, a0y, a0z, b0x, b0y, b0z, px, pz)
        # depth loop first (at most half the budget), then horizontal LOS with the rest
        w = kz * (ytgt - py)
        if method != HEURISTIC and 0.0 <= sh <= ln:
            w += slope * (s[VX] * tx + s[VZ] * tz)
        wlim = 0.5 * budget
        w = min(max(w, -wlim), wlim)
        bh = math.sqrt(budget * budget - w * w)
        sl = min(max(sh, 0.0) + look, ln)
        ax, _, az = seek_max(px, 0.0, pz, a0x + sl * tx, 0.0, a0z + sl * tz, bh, kp, pe, pn)
        observe(obs, act, e, k, 0, grid, state, a0x + sl * tx, ytgt, a0z + sl * tz, pe, pn,
                math.nan, ax, w, az)
        set_velocity_cmd(c, ax, w, az)
        en, code = advance_agent(grid, model, vp, s, c, ce, cn, v_max, dt, land_thr, clearance)
        energy += en
        if code != OK:
            viol += 1
        _, _, _, _, ytgt, _, xt = profile_at(a0x, a0y, a0z, b0x, b0y, b0z, s[0], s[2])
        de = s[1] - ytgt
        sum_d2 += de * de
        if abs(de) > d_max:
            d_max = abs(de)
        sum_x += xt
        k += 1
        if (s[0] - b0x) ** 2 + (s[2] - b0z) ** 2 <= radius * radius:
            wp += 1
    kk = k if k > 0 else 1
    rms = math.sqrt(sum_d2 / kk)
    success = wp > n_wp and rms <= fpar[_F_TOL]
    res[e, _C_SUCCESS] = 1.0 if success else 0.0
    res[e, _C_T] = k * dt if success else n_steps * dt
    res[e, _C_E] = energy
    res[e, _C_COLL] = 0.0
    res[e, _C_VIOL] = viol
    res[e, _C_DERR] = rms
    res[e, _C_WP] = wp - 1
    res[e, _C_DMAX] = d_max
    res[e, _C_XTE] = sum_x / kk


@njit(parallel=True, cache=True)
def _kernel(grid, vp, ipar, fpar, route, t0, state, cmd, obs, act, res):
    for e in prange(res.shape[0]):
        _episode(grid, vp, ipar, fpar, route, t0, state, cmd, obs, act, res, e)


def rollout(grid, tier: dict, init: dict, method: str, dyn: str, vehicle, seed: int, *,
            record: bool = False) -> dict:
    """Run every episode of ``init`` (from :func:`reset`); see :func:`.g2g.rollout`."""
    need_tier(TASK_ID, tier, "time_limit_s", "wp_radius_m", "depth_tol_m", "probe_noise_ms",
              "dt_s")
    dt = float(tier["dt_s"])
    route = np.ascontiguousarray(init["route"], dtype=np.float64)
    n_ep = route.shape[0]
    v_max = float(vehicle.v_max)
    ipar = np.array([model_id(dyn), method_id(method),
                     episode_steps(tier), int(seed)],
                    dtype=np.int64)
    fpar = np.array([dt, v_max, CRUISE_FRAC * v_max, KP, float(tier["probe_noise_ms"]),
                     float(tier["wp_radius_m"]), DEFAULT_LAND_THRESHOLD, CLEARANCE_M,
                     LOOKAHEAD_M, KZ, float(tier["depth_tol_m"])])
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
