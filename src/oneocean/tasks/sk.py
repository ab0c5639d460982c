"""SK — station keeping under currents (1 agent).

Objective
    Hold position at a station (valid water, ``DEPTH_RANGE_M`` deep, ``MIN_ALTITUDE_M`` above
    the seafloor) and the station heading. The agent starts at rest on the station facing the
    station heading, which is set into the local current at the start time, as a dynamic-
    positioning operator would (random when the current is below ``CALM_MS``).
Success
    The agent stays within ``hold_radius_m`` of the station for ``hold_time_s`` CONTIGUOUS
    seconds before ``time_limit_s`` (it may be pushed out and recover: the window restarts).
    The episode stops at success; ``T_s`` is the end of the first complete hold window.
Metrics
    ``rms_error_m`` (primary: RMS distance to the station over the steps run, m),
    ``heading_rms_deg`` (RMS heading error over the steps run, deg), ``max_error_m``
    (largest distance, m), ``hold_s`` (longest contiguous in-radius time, s).
Methods
    ``heuristic``: P-control to the station plus feed-forward of the NOISY probed current with
    the cruise throttle cap ``|a| <= CRUISE_FRAC * v_max`` (:func:`~.common.seek_max`), heading
    commanded to the station heading. It cannot hold against a current above its cruise
    speed, and the probe noise shakes it.
    ``oracle``: the same controller with the exact current and the full ``v_max``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..engine.constraints import DEFAULT_LAND_THRESHOLD
from ..engine.dynamics import CMD_DIM, PSI, model_id, new_state, wrap_angle
from ..engine._jit import hot_kernel
from ..engine.grid import sample_currents
from ..errors import ConfigError
from .common import (CLEARANCE_M, CRUISE_FRAC, DEPTH_RANGE_M, HEURISTIC, MIN_ALTITUDE_M, OK,
                     STANDARD, advance_agent, current_at, episode_generators, episode_steps,
                     fresh_cache, method_id, need_tier, obs_buffers, observe, rollout_results,
                     sample_route, seek_max, sensed_current, start_times)

TASK_ID = "SK"
METRICS = ("rms_error_m", "heading_rms_deg", "max_error_m", "hold_s")
COLUMNS = STANDARD + METRICS

#: Proportional position gain, s-1 (ground-speed request = KP * error, plus feed-forward).
KP = 0.4
#: Below this current speed (m s-1) at the start the station heading is drawn at random.
CALM_MS = 0.05

_I_MODEL, _I_METHOD, _I_STEPS, _I_SEED, _I_HOLD = range(5)
_F_DT, _F_VMAX, _F_SPEED, _F_KP, _F_NOISE, _F_RADIUS, _F_LAND, _F_CLEAR = range(8)
_C = {k: i for i, k in enumerate(COLUMNS)}
_C_SUCCESS, _C_T, _C_E, _C_COLL, _C_VIOL = (_C[k] for k in STANDARD)
_C_RMS, _C_HDG, _C_MAX, _C_HOLD = (_C[k] for k in METRICS)


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the station, its heading and the start time of every episode.

    Returns
    -------
    dict
        ``pos0`` (E, 1, 3) start = station, m; ``station`` (E, 3) m; ``psi0`` (E, 1) and
        ``heading`` (E,) station heading, rad (compass); ``t0`` (E,) start times, s.
    """
    if int(n_agents) != 1:
        raise ConfigError(f"task {TASK_ID}: single-agent task, got n_agents={n_agents}")
    need_tier(TASK_ID, tier, "time_limit_s", "hold_time_s")
    if float(tier["hold_time_s"]) > float(tier["time_limit_s"]):
        raise ConfigError(f"task {TASK_ID}: hold_time_s={tier['hold_time_s']} exceeds "
                          f"time_limit_s={tier['time_limit_s']}")
    rngs = episode_generators(seed, n_episodes)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    station = np.empty((n_episodes, 3))
    psi_rand = np.empty(n_episodes)
    for e, rng in enumerate(rngs):
        station[e] = sample_route(grid, rng, 0, 0.0, DEPTH_RANGE_M, MIN_ALTITUDE_M,
                                  land_threshold=DEFAULT_LAND_THRESHOLD,
                                  what=f"task {TASK_ID} reset (episode {e})")[0]
        psi_rand[e] = rng.uniform(-math.pi, math.pi)
    c = sample_currents(grid, station, t0)
    calm = np.hypot(c[:, 0], c[:, 1]) < CALM_MS
    heading = np.where(calm, psi_rand, np.arctan2(-c[:, 0], -c[:, 1]))
    return {"pos0": station[:, None, :].copy(), "station": station, "psi0": heading[:, None],
            "heading": heading, "t0": t0}


@hot_kernel
def _episode(grid, vp, ipar, fpar, station, heading, t0, state, cmd, obs, act, res, e):
    """Run episode ``e`` (serial) and write row ``e`` of ``res`` (see ``COLUMNS``)."""
    model = ipar[_I_MODEL]
    method = ipar[_I_METHOD]
    n_steps = ipar[_I_STEPS]
    seed = ipar[_I_SEED]
    hold_steps = ipar[_I_HOLD]
    dt = fpar[_F_DT]
    v_max = fpar[_F_VMAX]
    budget = fpar[_F_SPEED] if method == HEURISTIC else v_max
    kp = fpar[_F_KP]
    noise = fpar[_F_NOISE]
    radius = fpar[_F_RADIUS]
    land_thr = fpar[_F_LAND]
    clearance = fpar[_F_CLEAR]
    s = state[e, 0]
    c = cmd[e, 0]
    gx = station[e, 0]
    gy = station[e, 1]
    gz = station[e, 2]
    psi_t = heading[e]
    energy = 0.0
    viol = 0
    sum_d2 = 0.0
    sum_h2 = 0.0
    d_max = 0.0
    run = 0
    best = 0
    success = False
    k = 0
    while k < n_steps and not success:
        t = t0[e] + k * dt
        px = s[0]
        py = s[1]
        pz = s[2]
        ce, cn = current_at(grid, px, py, pz, t)
        pe, pn = sensed_current(method, ce, cn, noise, seed, e, 2 * k)
        ax, ay, az = seek_max(px, py, pz, gx, gy, gz, budget, kp, pe, pn)
        observe(obs, act, e, k, 0, grid, state, gx, gy, gz, pe, pn, math.nan, ax, ay, az)
        c[0] = ax
        c[1] = ay
        c[2] = az
        c[3] = psi_t
        c[4] = 1.0
        en, code = advance_agent(grid, model, vp, s, c, ce, cn, v_max, dt, land_thr, clearance)
        energy += en
        if code != OK:
            viol += 1
        d = math.sqrt((s[0] - gx) ** 2 + (s[1] - gy) ** 2 + (s[2] - gz) ** 2)
        h = wrap_angle(s[PSI] - psi_t)
        sum_d2 += d * d
        sum_h2 += h * h
        if d > d_max:
            d_max = d
        k += 1
        if d <= radius:
            run += 1
            if run > best:
                best = run
            if run >= hold_steps:
                success = True
        else:
            run = 0
    kk = k if k > 0 else 1
    res[e, _C_SUCCESS] = 1.0 if success else 0.0
    res[e, _C_T] = k * dt if success else n_steps * dt
    res[e, _C_E] = energy
    res[e, _C_COLL] = 0.0
    res[e, _C_VIOL] = viol
    res[e, _C_RMS] = math.sqrt(sum_d2 / kk)
    res[e, _C_HDG] = math.degrees(math.sqrt(sum_h2 / kk))
    res[e, _C_MAX] = d_max
    res[e, _C_HOLD] = best * dt


@njit(parallel=True, cache=True)
def _kernel(grid, vp, ipar, fpar, station, heading, t0, state, cmd, obs, act, res):
    for e in prange(res.shape[0]):
        _episode(grid, vp, ipar, fpar, station, heading, t0, state, cmd, obs, act, res, e)


def rollout(grid, tier: dict, init: dict, method: str, dyn: str, vehicle, seed: int, *,
            record: bool = False) -> dict:
    """Run every episode of ``init`` (from :func:`reset`); see :func:`.g2g.rollout`.

    Returns
    -------
    dict of (E,) arrays: ``STANDARD`` columns and ``METRICS``.
    """
    need_tier(TASK_ID, tier, "time_limit_s", "hold_time_s", "hold_radius_m", "probe_noise_ms",
              "dt_s")
    dt = float(tier["dt_s"])
    n_ep = init["station"].shape[0]
    v_max = float(vehicle.v_max)
    ipar = np.array([model_id(dyn), method_id(method),
                     episode_steps(tier), int(seed),
                     int(math.ceil(float(tier["hold_time_s"]) / dt - 1e-9))], dtype=np.int64)
    fpar = np.array([dt, v_max, CRUISE_FRAC * v_max, KP, float(tier["probe_noise_ms"]),
                     float(tier["hold_radius_m"]), DEFAULT_LAND_THRESHOLD, CLEARANCE_M])
    state = new_state(n_ep, 1, init["pos0"], init["psi0"])
    cmd = np.zeros((n_ep, 1, CMD_DIM))
    res = np.zeros((n_ep, len(COLUMNS)))
    obs, act = obs_buffers(tier, init, record)
    _kernel(grid, vehicle.params, ipar, fpar, np.ascontiguousarray(init["station"]),
            np.ascontiguousarray(init["heading"], dtype=np.float64),
            np.ascontiguousarray(init["t0"], dtype=np.float64), state, cmd, obs, act, res)
    return rollout_results(res, COLUMNS, obs, act, record)


# numba keys a cache entry on this file only; drop it when the engine or the task layer
# changes.
fresh_cache(_kernel, __file__)
