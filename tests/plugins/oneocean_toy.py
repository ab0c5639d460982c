"""A toy task registered from outside the package: what adding an 11th task takes.

TOY ("ascend"): one vehicle starts at depth and must rise to within ``tol_m`` of
``target_depth_m`` before the time limit. Its tier table (with its registry spec) is
``oneocean_toy.yaml`` beside this file; its briefing is the common fields plus the target
depth and tolerance; its heuristic is the ``act`` hook below, a policy of the briefing and
the observation. Importing this module registers the task (list it under ``plugins:`` in a
config).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from oneocean import registry
from oneocean.engine._jit import hot_kernel
from oneocean.engine.constraints import spawn_positions
from oneocean.tasks.common import O_CE, O_CN, O_DEPTH, fresh_cache
from oneocean.tasks.spawn import episode_generators, start_times
from oneocean.tasks.loop import (N_STANDARD, noop_after_agent, noop_plan, noop_pre_step,
                                 noop_report, noop_sense, policy_block, run_block)
from oneocean.tasks.public import common_brief

registry.register_task(registry.load_task_spec(Path(__file__).with_name("oneocean_toy.yaml")))

TASK_ID = "TOY"
METRICS = ("final_depth_error_m",)


# ------------------------------------------------------------------ the heuristic (its method)
class TOYPolicy(NamedTuple):
    speed: float


class _Policy:
    SENSING = {"heuristic": "sensors", "oracle": "truth"}

    @staticmethod
    def params(method, B):
        return TOYPolicy(float(B.v_max) * (0.5 if method == "heuristic" else 1.0))

    @staticmethod
    def memory(B, M):
        return (np.zeros(B.t0.shape[0]),)

    plan = noop_plan


@hot_kernel(inline="always")
def _act(C, e, k, i):
    o = C.O[e, i]
    dy = C.B.target - o[O_DEPTH]
    v = min(abs(dy), C.M.speed)
    return -o[O_CE], math.copysign(v, dy), -o[O_CN], math.nan


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


class TOYBriefing(NamedTuple):
    t0: np.ndarray
    t_lim: float
    dt: float
    n_agents: int
    v_max: float
    guidance: int
    hotel_w: float
    pk: float
    energy_allocation: np.ndarray
    sens: tuple
    chart: tuple
    target: float       # the target depth, m
    tol: float          # success: within this of it, m


def brief(P, W, init, m):
    return TOYBriefing(**common_brief(m), target=P.target, tol=P.tol)


@hot_kernel(inline="always")
def begin(ctx, e):
    ctx.W.err[e] = abs(ctx.state[e, 0, 1] - ctx.P.target)
    return False


@hot_kernel(inline="always")
def cue(ctx, e, k, i):
    X = ctx.X                            # the agents' states as the method knows them
    return X[e, i, 0], ctx.P.target, X[e, i, 2], math.nan


@hot_kernel(inline="always")
def post_step(ctx, e, k):
    ctx.W.err[e] = abs(ctx.state[e, 0, 1] - ctx.P.target)
    return ctx.W.err[e] <= ctx.P.tol


@hot_kernel(inline="always")
def finish(ctx, e, k):
    ctx.res[e, N_STANDARD] = ctx.W.err[e]   # the first task metric, after the standard columns
    return ctx.W.err[e] <= ctx.P.tol


@hot_kernel(nogil=True)
def _kernel(K, io, k_stop, e_lo, e_hi):
    run_block(begin, noop_pre_step, cue, noop_sense, noop_after_agent, post_step, finish,
              noop_report, noop_plan, _act, K, io, k_stop, e_lo, e_hi)


@hot_kernel(nogil=True)
def _policy(C, ks, out, e_lo, e_hi):
    policy_block(noop_plan, _act, C, ks, out, e_lo, e_hi)


fresh_cache(_kernel, __file__)
