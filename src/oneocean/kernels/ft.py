"""FT's compiled episode loop: the hooks of :mod:`oneocean.tasks.ft` with its
fused policy :mod:`oneocean.methods.heuristic.ft` (:mod:`oneocean.kernels`)."""

from __future__ import annotations

from numba import njit

from ..engine._jit import hot_kernel
from ..methods.heuristic import ft as POLICY
from ..tasks import ft as TASK
from ..tasks.common import fresh_cache
from ..tasks.loop import (env_step_in, env_step_out, noop_after_agent, noop_pre_step, observe_next,
                          run_episode, step_fields, step_kernel)
from ..tasks.ft import begin, cue, finish, post_step


@hot_kernel(inline="always")
def _steps(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop):
    run_episode(begin, noop_pre_step, cue, noop_after_agent, post_step, finish, POLICY.plan,
                POLICY.act, grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e,
                k_stop)


@hot_kernel
def _episode(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop):
    _steps(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop)


@njit(cache=True, nogil=True)
def _kernel(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, k_stop, e_lo, e_hi):
    for e in range(e_lo, e_hi):
        _episode(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop)


@hot_kernel(inline="always")
def _observe(grid, LP, P, W, LS, t0, state, nobs, nact, e):
    observe_next(grid, cue, P, W, LP, LS, state, t0, e, nobs, nact)


@hot_kernel(nogil=True)
def _observe_kernel(grid, LP, P, W, LS, t0, state, nobs, nact, e_lo, e_hi):
    for e in range(e_lo, e_hi):
        _observe(grid, LP, P, W, LS, t0, state, nobs, nact, e)


@hot_kernel(nogil=True)
def _step_kernel(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, nobs, nact,
                 io, e_lo, e_hi):
    for e in range(e_lo, e_hi):
        was = env_step_in(LP, LS, ext, io, e)
        _steps(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, -1)
        _observe(grid, LP, P, W, LS, t0, state, nobs, nact, e)
        env_step_out(LP, LS, res, nobs, io, e, was)


@step_kernel
def _step_fields(A, io, e_lo, e_hi):
    """``_step_kernel`` on the fields of ``A``, borrowed
    (:func:`~oneocean.tasks.loop.step_fields`)."""
    grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, nobs, nact = step_fields(A)
    _step_kernel(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, nobs, nact, io,
                 e_lo, e_hi)


@njit(cache=True, nogil=True)
def _step_boxed(A, io, e_lo, e_hi):
    """``_step_kernel`` with its arguments in one :class:`~oneocean.tasks.loop.StepArgs`."""
    _step_fields(A, io, e_lo, e_hi)


fresh_cache(_kernel, __file__, TASK.__file__, POLICY.__file__)
