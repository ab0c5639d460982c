"""A toy task registered from outside the package: what adding an 11th task takes.

TOY ("ascend"): one vehicle starts at depth and must rise to within ``tol_m`` of
``target_depth_m`` before the time limit. Its tier table (with its registry spec) is
``oneocean_toy.yaml`` beside this file; its heuristic is the ``act`` hook below. Importing
this module registers the task (list it under ``plugins:`` in a config).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numba import njit

from oneocean import registry
from oneocean.engine._jit import hot_kernel
from oneocean.engine.constraints import spawn_positions
from oneocean.tasks.common import episode_generators, fresh_cache, start_times
from oneocean.tasks.loop import (N_STANDARD, noop_after_agent, noop_plan, noop_pre_step,
                                 observe_next, run_episode)

registry.register_task(registry.load_task_spec(Path(__file__).with_name("oneocean_toy.yaml")))

TASK_ID = "TOY"
METRICS = ("final_depth_error_m",)


# ------------------------------------------------------------------ the heuristic (its method)
class TOYPolicy(NamedTuple):
    speed: float


class _Policy:
    SENSING = {"heuristic": "sensors", "oracle": "truth"}

    @staticmethod
    def params(method, tier, vehicle):
        return TOYPolicy(float(vehicle.v_max) * (0.5 if method == "heuristic" else 1.0))

    plan = noop_plan


@hot_kernel(inline="always")
def _act(grid, P, W, M, state, e, k, i, t, pe, pn):
    dy = P.target - state[e, i, 1]
    v = min(abs(dy), M.speed)
    return -pe, math.copysign(v, dy), -pn, math.nan


_Policy.act = _act
_Policy.__file__ = __file__
POLICY = _Policy


# ------------------------------------------------------------------ the environment
class TOYParams(NamedTuple):
    target: float
    tol: float


class TOYWork(NamedTuple):
    err: np.ndarray     # (E,) depth error after the last step, m


def reset(grid, tier, n_agents, n_episodes, seed):
    rngs = episode_generators(seed, n_episodes)
    pos0 = np.empty((n_episodes, n_agents, 3))
    for e, rng in enumerate(rngs):
        pos0[e] = spawn_positions(grid, rng, n_agents, {"y": (10.0, 12.0)}, clearance=2.0)
    return {"pos0": pos0, "psi0": np.zeros((n_episodes, n_agents)),
            "t0": start_times(grid, rngs, float(tier["time_limit_s"]))}


def make(grid, tier, init):
    n_ep = init["pos0"].shape[0]
    return (TOYParams(float(tier["target_depth_m"]), float(tier["tol_m"])),
            TOYWork(np.zeros(n_ep)))


@hot_kernel(inline="always")
def begin(grid, P, W, state, e):
    W.err[e] = abs(state[e, 0, 1] - P.target)
    return False


@hot_kernel(inline="always")
def cue(grid, P, W, state, e, k, i):
    return state[e, i, 0], P.target, state[e, i, 2], math.nan


@hot_kernel(inline="always")
def post_step(grid, P, W, state, prev, e, k, t):
    W.err[e] = abs(state[e, 0, 1] - P.target)
    return W.err[e] <= P.tol


@hot_kernel(inline="always")
def finish(grid, P, W, state, e, k, row):
    row[N_STANDARD] = W.err[e]           # the first task metric, after the standard columns
    return W.err[e] <= P.tol


@hot_kernel
def _episode(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop):
    run_episode(begin, noop_pre_step, cue, noop_after_agent, post_step, finish, noop_plan,
                _act, grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop)


@njit(cache=True, nogil=True)
def _kernel(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, k_stop, e_lo, e_hi):
    for e in range(e_lo, e_hi):
        _episode(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop)


@hot_kernel
def _observe(grid, LP, P, W, LS, t0, state, nobs, nact, e):
    observe_next(grid, cue, P, W, LP, LS, state, t0, e, nobs, nact)


@njit(cache=True, nogil=True)
def _observe_kernel(grid, LP, P, W, LS, t0, state, nobs, nact, e_lo, e_hi):
    for e in range(e_lo, e_hi):
        _observe(grid, LP, P, W, LS, t0, state, nobs, nact, e)


fresh_cache(_kernel, __file__)
