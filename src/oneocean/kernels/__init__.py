"""Each task's compiled episode loop: where a task and its fused methods meet.

A task module (:mod:`oneocean.tasks`) says what the world does -- its scenario, hooks,
judge and accounting -- and a policy module (:mod:`oneocean.methods.heuristic`) says what
the fused heuristic and oracle do; neither imports the other (a policy reads only the task's
public view: its work arrays, cue and helpers). The module ``kernels/<task>.py`` binds the
two: it passes the task's hooks and the policy's ``plan`` / ``act`` to the one loop
(:func:`oneocean.tasks.loop.run_episode`) and exposes

* ``TASK`` and ``POLICY``: the two modules it binds;
* ``_steps``: an episode's steps (the loop with the hooks bound, ``inline="always"``), and
  ``_episode``, its compiled copy out of line, which ``_kernel`` calls once per episode;
* ``_kernel``: the loop over a block of episodes ``[e_lo, e_hi)``
  (``njit(cache=True, nogil=True)``), which both backends run
  (:class:`oneocean.tasks.episodes.Episodes` fused; the scene backend's
  :class:`oneocean.backends.mujoco.episodes.SteppedEpisodes` in its decide and judge phases);
* ``_observe_kernel``: the next observation of every agent
  (:func:`~oneocean.tasks.loop.observe_next`), for the step API;
* ``_step_kernel``: one step of every running episode of a block, then its agents' next
  observation, in one call (the step, ``_steps``, and the observation, ``_observe``, both
  inlined in its loop over episodes, as in ``_observe_kernel``: an out-of-line call per
  episode would copy the grid's and the loop's arrays, passed by value, at every step; the
  loop is therefore compiled twice per task, once in ``_episode`` and once here), with the step API's side
  of it (``io``, :class:`~oneocean.tasks.loop.EnvIO`: the sub-envs' actions in, their
  observations and end flags out; :meth:`oneocean.tasks.episodes.Episodes.env_step` and
  ``step_observe``), and
  ``_step_boxed``, the same call with its arguments in one
  :class:`~oneocean.tasks.loop.StepArgs` (one object to unbox per call, not every array),
  through ``_step_fields``, which reads them without counting a reference to each array
  (:func:`~oneocean.tasks.loop.step_fields`; ``_step_boxed`` holds the struct); optional: a kernel module without them is stepped by ``_kernel`` and observed by
  ``_observe_kernel``.

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
        with ``POLICY``, ``_kernel`` and ``_observe_kernel``.

    Raises
    ------
    ConfigError
        If ``task_id`` is not registered.
    """
    from ..registry import task_spec

    return importlib.import_module(task_spec(task_id).kernel_module)
