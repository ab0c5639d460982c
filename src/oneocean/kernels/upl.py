"""UPL's compiled episode loop: the hooks of :mod:`oneocean.tasks.upl` with its fused policy
:mod:`oneocean.methods.heuristic.upl` (:mod:`oneocean.kernels`)."""

from __future__ import annotations

from numba import njit

from ..engine._jit import hot_kernel
from ..methods.heuristic import upl as POLICY
from ..tasks import upl as TASK
from ..tasks.common import fresh_cache
from ..tasks.loop import noop_report, policy_block, run_block, step_fields, step_kernel
from ..tasks.upl import after_agent, begin, cue, finish, post_step, pre_step, sense


@hot_kernel(nogil=True)
def _kernel(K, io, k_stop, e_lo, e_hi):
    run_block(begin, pre_step, cue, sense, after_agent, post_step, finish, noop_report,
              POLICY.plan, POLICY.act, K, io, k_stop, e_lo, e_hi)


@step_kernel
def _step_fields(A, io, k_stop, e_lo, e_hi):
    """One step of ``_kernel`` on the fields of ``A``, borrowed
    (:func:`~oneocean.tasks.loop.step_fields`)."""
    _kernel(step_fields(A), io, k_stop, e_lo, e_hi)


@njit(cache=True, nogil=True)
def _step_boxed(A, io, k_stop, e_lo, e_hi):
    """One step of ``_kernel`` with its arguments in one
    :class:`~oneocean.tasks.loop.StepArgs`."""
    _step_fields(A, io, k_stop, e_lo, e_hi)


@hot_kernel(nogil=True)
def _policy(C, ks, out, e_lo, e_hi):
    """The fused policy alone, on its context ``C`` (:func:`~oneocean.tasks.loop.policy_block`)."""
    policy_block(POLICY.plan, POLICY.act, C, ks, out, e_lo, e_hi)


fresh_cache(_kernel, __file__, TASK.__file__, POLICY.__file__)
