"""The rollout protocol every execution backend implements.

A *rollout* is a batch of ``E`` episodes of one task (``N`` agents each) under one method,
advanced in resumable segments. The workflow, :func:`oneocean.tasks.run_cell`, the step API
(:mod:`oneocean.envs`), ``oneocean evaluate`` and the LLM planner use only this surface, so
they run unchanged on every backend:

* ``core`` -- :class:`oneocean.tasks.episodes.Episodes`: the numba engine; each agent's step
  is :func:`oneocean.engine.step.advance_agent` inside the task's fused kernel.
* ``mujoco`` -- :class:`oneocean.backends.mujoco.episodes.SceneEpisodes`: MuJoCo rigid bodies
  in a scene; the same kernel decides (phase ``DECIDE``) and judges (phase ``JUDGE``) each
  step around MuJoCo's physics (:mod:`oneocean.tasks.loop`).

What is shared, whatever the backend: the task's scenario (its ``reset``: episode sampling),
its judge (the observation cue, ``post_step`` success and termination, ``finish`` metrics),
the loop's standard accounting (energy proxy, violations, near-collisions, ``T``, the
``REACHED`` latch) and the method's sensing and policy. A backend supplies only physics.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

#: Execution backends (config ``rollouts.backend``).
BACKENDS = ("core", "mujoco")


@runtime_checkable
class Rollout(Protocol):
    """E episodes of one task under one method, advanced in segments (see module doc).

    Attributes
    ----------
    n_episodes : int
        Number of episodes E.
    n_agents : int
        Number of agents per episode N.
    n_steps : int
        Steps per episode at most (the time limit over ``dt``).
    dt : float
        Control step, s.
    columns : tuple of str
        The per-episode result columns.
    P : tuple
        The task's parameters (its public view, e.g. for a planner).
    W : tuple
        The task's per-episode work arrays (plan tokens a planner writes).
    """

    n_episodes: int
    n_agents: int
    n_steps: int
    dt: float
    columns: tuple
    P: tuple            # the task's parameters (its public view, e.g. for a planner)
    W: tuple            # the task's per-episode work arrays (plan tokens a planner writes)

    @property
    def k(self) -> np.ndarray:
        """(E,) steps taken by each episode."""

    @property
    def done(self) -> np.ndarray:
        """(E,) bool: the episode has ended."""

    @property
    def known_state(self) -> np.ndarray:
        """(E, N, STATE_DIM) the agents' state as the method knows it."""

    def run(self, k_stop: int | None = None) -> "Rollout":
        """Advance every running episode up to step ``k_stop``.

        Parameters
        ----------
        k_stop : int, optional
            Step to stop at; default: each episode's end. A negative value advances each episode
            by ``-k_stop`` steps from where it is.

        Returns
        -------
        Rollout
            ``self``.
        """

    def run_planned(self, planner, every: int) -> "Rollout":
        """Run to the end in segments of ``every`` steps, ``planner(self)`` before each.

        Parameters
        ----------
        planner : callable
            ``planner(rollout)``: reads the batch and writes plan tokens into ``W``.
        every : int
            Segment length, steps (>= 1).

        Returns
        -------
        Rollout
            ``self``.
        """

    def set_actions(self, actions) -> None:
        """Set the external actions for the next step(s).

        Parameters
        ----------
        actions : array_like
            (E, N, 3) desired velocity relative to the water, world frame (x east, y down,
            z north), m s-1; clipped to ``v_max`` by the loop.
        """

    def observe(self) -> np.ndarray:
        """Every agent's observation before its next step.

        Returns
        -------
        (E, N, OBS_DIM) float64
            The observations.
        """

    def results(self) -> dict:
        """Per-episode result columns once every episode ended.

        Returns
        -------
        dict
            Column name to (E,) array.
        """


def check_backend(name: str, where: str = "rollouts.backend") -> str:
    """Validate an execution backend name.

    Parameters
    ----------
    name : str
        Backend name, one of :data:`BACKENDS`.
    where : str, default "rollouts.backend"
        Config key named in the error message.

    Returns
    -------
    str
        ``name``.

    Raises
    ------
    ConfigError
        If ``name`` is not a backend (one line naming ``where``).
    """
    from ..errors import ConfigError

    if name not in BACKENDS:
        raise ConfigError(f"{where}: unknown backend {name!r}; backends: {', '.join(BACKENDS)}")
    return name
