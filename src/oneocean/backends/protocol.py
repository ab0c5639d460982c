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
    """E episodes of one task under one method, advanced in segments (see module doc)."""

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
        """Advance every running episode up to step ``k_stop`` (default: its end)."""

    def run_planned(self, planner, every: int) -> "Rollout":
        """Run to the end in segments of ``every`` steps, ``planner(self)`` before each."""

    def set_actions(self, actions) -> None:
        """External actions (E, N, 3) for the next step(s), m s-1, world frame."""

    def observe(self) -> np.ndarray:
        """(E, N, OBS_DIM) every agent's observation before its next step."""

    def results(self) -> dict:
        """Per-episode result columns once every episode ended."""


def check_backend(name: str, where: str = "rollouts.backend") -> str:
    """``name`` if it is a backend, else a one-line ConfigError naming ``where``."""
    from ..errors import ConfigError

    if name not in BACKENDS:
        raise ConfigError(f"{where}: unknown backend {name!r}; backends: {', '.join(BACKENDS)}")
    return name
