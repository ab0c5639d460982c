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
Metrics (distances are 3-D, sampled after every step; ``H = ceil(hold_time_s / dt)``)
    ``rms_error_m`` (primary: the station-keeping RMS position error *while holding*: the RMS
    distance to the station over the hold window, the ``H`` steps of the first complete hold,
    so at most ``hold_radius_m``; NaN for an episode that never completed a hold: it never
    held station, and its count is the failures, ``1 - SR``, of the cell),
    ``heading_rms_deg`` (RMS heading error over the same hold window, deg; NaN likewise),
    ``max_error_m`` (largest distance over the episode, m), ``hold_s`` (longest contiguous
    in-radius time, s), ``final_rms_m`` (RMS distance over the episode's last ``H`` steps,
    all of them if fewer: defined for every episode; equal to ``rms_error_m`` on success,
    where the episode ends with the hold window; on failure the error over the last
    ``hold_time_s`` before the time limit, m).
Methods
    :mod:`oneocean.methods.heuristic.sk` (P-control plus current feed-forward with the full
    ``v_max``, heading commanded to the station heading; heuristic: noisy probe; oracle: exact
    current).

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset``; ``SKParams`` / ``SKWork`` and ``make``; the env hooks
    ``begin``, ``cue``, ``post_step``, ``finish``; ``POLICY``; ``_kernel`` and
    ``_observe_kernel``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..engine.constraints import DEFAULT_LAND_THRESHOLD
from ..engine.dynamics import PSI, wrap_angle
from ..engine._jit import hot_kernel
from ..engine.grid import sample_currents
from ..errors import ConfigError
from ..methods.heuristic import sk as POLICY
from .common import (DEPTH_RANGE_M, MIN_ALTITUDE_M, STANDARD, episode_generators, fresh_cache,
                     need_tier, sample_route, start_times)
from .loop import noop_after_agent, noop_pre_step, observe_next, run_episode

TASK_ID = "SK"
METRICS = ("rms_error_m", "heading_rms_deg", "max_error_m", "hold_s", "final_rms_m")
COLUMNS = STANDARD + METRICS

#: Below this current speed (m s-1) at the start the station heading is drawn at random.
CALM_MS = 0.05

_C_RMS, _C_HDG, _C_MAX, _C_HOLD, _C_FIN = (len(STANDARD) + i for i in range(len(METRICS)))


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


class SKParams(NamedTuple):
    radius: float           # hold radius around the station, m
    hold_steps: int         # contiguous in-radius steps needed (ceil(hold_time_s / dt))
    dt: float               # step, s


class SKWork(NamedTuple):
    station: np.ndarray     # (E, 3) station positions, m
    heading: np.ndarray     # (E,) station heading, rad (compass)
    acc: np.ndarray         # (E, 3) over the current in-radius run: sums of squared distance
                            # and squared heading error; max distance over the episode
    cnt: np.ndarray         # (E, 3) int64 current in-radius run, longest run, success flag
    ring: np.ndarray        # (E, H) squared distance of the last H steps (step k at k % H)


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`)."""
    need_tier(TASK_ID, tier, "hold_time_s", "hold_radius_m")
    dt = float(tier["dt_s"])
    n_ep = init["station"].shape[0]
    hold = max(1, int(math.ceil(float(tier["hold_time_s"]) / dt - 1e-9)))
    return (SKParams(float(tier["hold_radius_m"]), hold, dt),
            SKWork(np.ascontiguousarray(init["station"], dtype=np.float64),
                   np.ascontiguousarray(init["heading"], dtype=np.float64),
                   np.zeros((n_ep, 3)), np.zeros((n_ep, 3), np.int64), np.zeros((n_ep, hold))))


@hot_kernel(inline="always")
def begin(grid, P, W, state, e):
    W.acc[e, 0] = 0.0
    W.acc[e, 1] = 0.0
    W.acc[e, 2] = 0.0
    W.cnt[e, 0] = 0
    W.cnt[e, 1] = 0
    W.cnt[e, 2] = 0
    return False


@hot_kernel(inline="always")
def cue(grid, P, W, state, e, k, i):
    return W.station[e, 0], W.station[e, 1], W.station[e, 2], math.nan


@hot_kernel(inline="always")
def post_step(grid, P, W, state, prev, e, k, t):
    """Distance and heading error after the step: the in-radius run and its sums (the hold
    window when it completes), the episode's largest distance, the last H steps' ring."""
    s = state[e, 0]
    g = W.station[e]
    a = W.acc[e]
    c = W.cnt[e]
    d = math.sqrt((s[0] - g[0]) ** 2 + (s[1] - g[1]) ** 2 + (s[2] - g[2]) ** 2)
    h = wrap_angle(s[PSI] - W.heading[e])
    W.ring[e, k % W.ring.shape[1]] = d * d
    if d > a[2]:
        a[2] = d
    if d <= P.radius:
        c[0] += 1
        a[0] += d * d
        a[1] += h * h
        if c[0] > c[1]:
            c[1] = c[0]
        if c[0] >= P.hold_steps:
            c[2] = 1
    else:
        c[0] = 0
        a[0] = 0.0
        a[1] = 0.0
    return c[2] != 0


@hot_kernel(inline="always")
def finish(grid, P, W, state, e, k, row):
    """On success the episode ends with the hold window (the run's last ``hold_steps``
    steps): its RMS distance and heading error; NaN if no hold was completed."""
    a = W.acc[e]
    held = W.cnt[e, 2] != 0
    if held:
        row[_C_RMS] = math.sqrt(a[0] / P.hold_steps)
        row[_C_HDG] = math.degrees(math.sqrt(a[1] / P.hold_steps))
    else:
        row[_C_RMS] = math.nan
        row[_C_HDG] = math.nan
    row[_C_MAX] = a[2]
    row[_C_HOLD] = W.cnt[e, 1] * P.dt
    H = W.ring.shape[1]
    n = k if k < H else H
    ss = 0.0
    for j in range(n):
        ss += W.ring[e, j]
    row[_C_FIN] = math.sqrt(ss / n) if n > 0 else math.nan
    return held


# the one loop specialised to this task's hooks (see oneocean.tasks.loop for why two levels)
@hot_kernel
def _episode(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop):
    run_episode(begin, noop_pre_step, cue, noop_after_agent, post_step, finish, POLICY.plan,
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
