"""Each task's compiled episode loop: where a task and its fused methods meet.

A task module (:mod:`oneocean.tasks`) says what the world does -- its scenario, hooks, public
view, judge and accounting -- and a policy module (:mod:`oneocean.methods.heuristic`) says
what the fused heuristic and oracle do from that public view; neither imports the other. The
module ``kernels/<task>.py`` binds the two: it passes the task's hooks and the policy's
``plan`` / ``act`` to the one loop (:func:`oneocean.tasks.loop.run_block`) and exposes

* ``TASK`` and ``POLICY``: the two modules it binds;
* ``_kernel(K, io, k_stop, e_lo, e_hi)``: the loop over a block of episodes ``[e_lo, e_hi)``
  (``hot_kernel(nogil=True)``) on a batch's arguments ``K``
  (:class:`~oneocean.tasks.loop.Batch`), the one compiled copy of the loop, which serves the
  fused cells (``k_stop``: up to a step), the step API (one step and the next observation,
  with its side ``io``, :class:`~oneocean.tasks.loop.EnvIO`) and the scene backend's decide
  and judge phases;
* ``_step_boxed``: one step of ``_kernel`` with its arguments in one
  :class:`~oneocean.tasks.loop.StepArgs` (one object to unbox per call of the step API, not
  every array), through ``_step_fields``, which reads them without counting a reference to
  each array (:func:`~oneocean.tasks.loop.step_fields`);
* ``_policy``: the fused policy alone on its context (:func:`oneocean.tasks.loop.policy_block`),
  for :class:`oneocean.methods.heuristic.FusedPolicy`, the heuristic as an outside policy.

These wrappers are all numba's on-disk cache needs: a kernel is cached only when the hooks
reach the inlined loop as module globals (:mod:`oneocean.tasks.loop`), so each task has one
small file, and :func:`~oneocean.tasks.common.fresh_cache` drops its cache entries when the
task, its policy or a model it inlines changes. A task's spec names its kernel module
(``kernel:`` in its table's ``spec`` block; :func:`kernel_module`); a plugin task may bind
its kernel in its own module (the default).
"""

from __future__ import annotations

import importlib


def kernel_module(task_id: str):
    """The module holding a task's compiled loop.

    Parameters
    ----------
    task_id : str
        Registered task id.

    Returns
    -------
    module
        The module named by the task spec's ``kernel`` (:class:`oneocean.registry.TaskSpec`),
        with ``POLICY``, ``_kernel``, ``_step_boxed`` and ``_policy``.

    Raises
    ------
    ConfigError
        If ``task_id`` is not registered.
    """
    from ..registry import task_spec

    return importlib.import_module(task_spec(task_id).kernel_module)
