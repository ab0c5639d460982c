"""G2G — go-to-goal under currents (1 agent).

Objective
    Reach a goal ``goal_distance_m`` metres from the start, at the start's depth, before
    ``time_limit_s``. Start, goal and the straight segment between them are in valid water
    (off land, inside the grid, ``MIN_ALTITUDE_M`` above the seafloor), so every episode is
    solvable without path planning; the difficulty is the current along the way.
Success
    The agent comes within ``goal_radius_m`` of the goal (checked after every step); the
    episode stops there and ``T_s`` is the time to success (the time limit on failure).
Metrics
    ``final_error_m`` (primary: distance to the goal when the episode ends, m),
    ``min_error_m`` (closest approach, m), ``path_length_m`` (ground track length, m).
Methods
    :mod:`oneocean.methods.heuristic.g2g` (both at full speed; heuristic: noisy probe;
    oracle: exact current).

Module layout (the template every task module follows; the contract is
:mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset`` (Python: geometry and start times per episode from
    :func:`~oneocean.tasks.common.episode_generators`); ``Params`` / ``Work`` and ``make``
    (the env's typed scalars and per-episode arrays); the env hooks ``begin``, ``cue``,
    ``post_step``, ``finish`` (``hot_kernel``, no allocation); ``POLICY`` (the task's fused
    heuristic/oracle module); ``_kernel`` and ``_observe_kernel`` (``njit(cache=True,
    nogil=True)``: the one loop over a block of episodes, specialised to these hooks).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from typing import NamedTuple

from ..engine._jit import hot_kernel
from ..engine.constraints import DEFAULT_LAND_THRESHOLD
from ..errors import ConfigError
from ..methods.heuristic import g2g as POLICY
from .common import (DEPTH_RANGE_M, MIN_ALTITUDE_M, STANDARD, episode_generators, fresh_cache,
                     need_tier, sample_route, start_times)
from .loop import noop_after_agent, noop_pre_step, observe_next, run_episode

TASK_ID = "G2G"
METRICS = ("final_error_m", "min_error_m", "path_length_m")
#: Result-matrix columns written by the kernel (standard columns first).
COLUMNS = STANDARD + METRICS

_C_FINAL, _C_MIN, _C_PATH = (len(STANDARD) + i for i in range(len(METRICS)))


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample start, goal and start time of every episode.

    Parameters
    ----------
    grid : Grid
    tier : dict
        Tier parameters (``goal_distance_m``, ``time_limit_s``, ...) plus ``dt_s``.
    n_agents : int
        Must be 1 (single-agent task).
    n_episodes, seed : int

    Returns
    -------
    dict
        ``pos0`` (E, 1, 3) start positions, m; ``goal`` (E, 3) goal positions, m;
        ``psi0`` (E, 1) initial heading (facing the goal), rad; ``t0`` (E,) start times, s.

    Raises
    ------
    ConfigError
        Wrong team size, missing tier keys, or no valid geometry for some episode.
    """
    if int(n_agents) != 1:
        raise ConfigError(f"task {TASK_ID}: single-agent task, got n_agents={n_agents}")
    need_tier(TASK_ID, tier, "goal_distance_m", "time_limit_s")
    rngs = episode_generators(seed, n_episodes)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    pos0 = np.empty((n_episodes, 1, 3))
    goal = np.empty((n_episodes, 3))
    for e, rng in enumerate(rngs):
        route = sample_route(grid, rng, 1, float(tier["goal_distance_m"]), DEPTH_RANGE_M,
                             MIN_ALTITUDE_M, land_threshold=DEFAULT_LAND_THRESHOLD,
                             what=f"task {TASK_ID} reset (episode {e})")
        pos0[e, 0] = route[0]
        goal[e] = route[1]
    d = goal - pos0[:, 0]
    psi0 = np.arctan2(d[:, 0], d[:, 2])[:, None]
    return {"pos0": pos0, "goal": goal, "psi0": psi0, "t0": t0}


class G2GParams(NamedTuple):
    radius: float           # success radius around the goal, m


class G2GWork(NamedTuple):
    goal: np.ndarray        # (E, 3) goal positions, m
    acc: np.ndarray         # (E, 3) distance to the goal, closest approach, path length, m


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`)."""
    need_tier(TASK_ID, tier, "goal_radius_m")
    n_ep = init["goal"].shape[0]
    return (G2GParams(float(tier["goal_radius_m"])),
            G2GWork(np.ascontiguousarray(init["goal"], dtype=np.float64), np.zeros((n_ep, 3))))


@hot_kernel(inline="always")
def _dist(s, g):
    return math.sqrt((s[0] - g[0]) ** 2 + (s[1] - g[1]) ** 2 + (s[2] - g[2]) ** 2)


@hot_kernel(inline="always")
def begin(grid, P, W, state, e):
    d = _dist(state[e, 0], W.goal[e])
    W.acc[e, 0] = d
    W.acc[e, 1] = d
    W.acc[e, 2] = 0.0
    return d <= P.radius


@hot_kernel(inline="always")
def cue(grid, P, W, state, e, k, i):
    return W.goal[e, 0], W.goal[e, 1], W.goal[e, 2], math.nan


@hot_kernel(inline="always")
def post_step(grid, P, W, state, prev, e, k, t):
    s = state[e, 0]
    p = prev[e, 0]
    a = W.acc[e]
    a[2] += math.sqrt((s[0] - p[0]) ** 2 + (s[1] - p[1]) ** 2 + (s[2] - p[2]) ** 2)
    d = _dist(s, W.goal[e])
    a[0] = d
    if d < a[1]:
        a[1] = d
    return d <= P.radius


@hot_kernel(inline="always")
def finish(grid, P, W, state, e, k, row):
    a = W.acc[e]
    row[_C_FINAL] = a[0]
    row[_C_MIN] = a[1]
    row[_C_PATH] = a[2]
    return a[0] <= P.radius


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
