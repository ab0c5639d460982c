"""The scene backend's rollout: the task's kernel decides and judges, MuJoCo moves.

:class:`SceneEpisodes` is an :class:`oneocean.tasks.episodes.Episodes` (same construction,
same task parameters and work arrays, same sensing, same ``observe`` and ``results``) whose
``run`` replaces the core's physics. Each step ``k`` of every running episode:

1. the task's kernel in phase ``DECIDE`` (:mod:`oneocean.tasks.loop`): the task's
   ``pre_step``, the method's ``plan`` and per-agent action (or the external action of the
   step API), the observation record, the executed action clipped to ``v_max`` with its
   energy proxy, and the true current at every agent (the scene's currents: its local grid,
   :mod:`.scenes`);
2. :meth:`oneocean.backends.mujoco.physics.ScenePhysics.step`: MuJoCo advances every vehicle
   by ``dt`` under its command and the current at it, writes the new states back in the
   core's convention and reports each move's status (``OK`` or ``CONTACT``); a vehicle that
   is then where the core would reject the move (on land, which includes the scene's boundary
   band, or off the grid) gets the core's code: a violation, the move not undone;
3. the task's kernel in phase ``JUDGE``: the standard accounting (energy, violations =
   contacts here, near-collisions, ``T``, the ``REACHED`` latch), the task's ``post_step``
   judge, navigation, and at the end its ``finish`` metrics.

Agents decide together and move together (the core moves them one after the other within a
step: a teammate acting later sees the earlier one's new position).
"""

from __future__ import annotations

import numpy as np

from ...tasks.episodes import Episodes
from ...engine.constraints import DEFAULT_LAND_THRESHOLD, feasibility
from ...engine.status import OK
from ...tasks.loop import DECIDE, FINISHED, JUDGE

#: MuJoCo's integration step in the scene backend, s (the task's control step ``dt_s`` is
#: held over ``dt_s / PHYSICS_STEP_S`` of them).
PHYSICS_STEP_S = 0.02


class SteppedEpisodes(Episodes):
    """Episodes whose agents another physics moves.

    ``trace=True`` keeps every step's true state of every episode (:meth:`traced`) for media.

    Parameters
    ----------
    mod, grid, tier, init, method, dyn, vehicle, seed
        As for :class:`~oneocean.tasks.episodes.Episodes`.
    physics : object
        The physics, with ``reset(state)`` and ``step(state, cmd, current, live) -> codes``
        as :class:`oneocean.backends.mujoco.physics.ScenePhysics`.
    trace : bool, default False
        Keep every step's true state (:meth:`traced`).
    **kw
        Further keywords of :class:`~oneocean.tasks.episodes.Episodes` (``record``, ``info``,
        ...).
    """

    backend = "stepped"

    def __init__(self, mod, grid, tier: dict, init: dict, method, dyn: str, vehicle,
                 seed: int, *, physics, trace: bool = False, **kw):
        super().__init__(mod, grid, tier, init, method, dyn, vehicle, seed, **kw)
        self.physics = physics
        self.physics.reset(self.state)
        self._decide = self.LP._replace(phase=DECIDE)
        self._judge = self.LP._replace(phase=JUDGE)
        self.trace = [self.state.copy()] if trace else None

    #: No fused step API call: the step API steps these episodes through :meth:`step_observe`.
    env_step = None

    def step_observe(self, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """Advance every running episode by one step (this backend's physics).

        Parameters
        ----------
        lo, hi : int
            Unused (every running episode steps).

        Returns
        -------
        (E, N, D) float64
            The next observation ``C.O``.
        """
        self.run(-1)
        return self.C.O

    def _phase(self, LP, k_stop: int) -> None:
        self.kern._kernel(self._args()._replace(LP=LP), self._no_io, int(k_stop), 0,
                          self.n_episodes)

    def run(self, k_stop: int | None = None) -> "SteppedEpisodes":
        """Advance every running episode up to step ``k_stop``, one step at a time.

        Each step: decide (the task's kernel), move (the physics), judge (the kernel).

        Parameters
        ----------
        k_stop : int, optional
            Step to stop at; default: each episode's end. A negative value advances each episode
            by ``-k_stop`` steps from where it is.

        Returns
        -------
        SteppedEpisodes
            ``self``.
        """
        k_stop = self.n_steps if k_stop is None else int(k_stop)
        LS = self.LS
        if k_stop < 0:
            for _ in range(-k_stop):
                live = (LS.status != FINISHED) & (LS.k < self.n_steps)
                if not live.any():
                    break
                self._step(live, -1)
            return self
        while True:
            live = (LS.status != FINISHED) & (LS.k < min(k_stop, self.n_steps))
            if not live.any():
                return self
            self._step(live, k_stop)

    def _step(self, live: np.ndarray, k_stop: int) -> None:
        """One step of the ``live`` episodes: decide, move, judge."""
        LS = self.LS
        self._phase(self._decide, k_stop)
        moving = live & (LS.status != FINISHED)   # a task's begin may end an episode
        codes = self.physics.step(self.state, self.cmd, LS.cw, live=moving)
        codes = np.where(codes != OK, codes, self._feasibility())
        LS.code[moving] = codes[moving]
        self._phase(self._judge, k_stop)
        if self.trace is not None:
            self.trace.append(self.state.copy())

    def _feasibility(self) -> np.ndarray:
        """(E, N) the core's feasibility code of every agent's new position on the grid
        (:func:`oneocean.engine.constraints.feasibility`: land, which includes a scene's
        boundary band and surfacing structures, the grid's extent; no seafloor clearance:
        the physics resolves the seafloor). The core rejects such a move; here the physics
        is authoritative and the code only counts a violation."""
        xyz = self.state[..., :3].reshape(-1, 3).copy()
        np.maximum(xyz[:, 1], 0.0, out=xyz[:, 1])   # at the surface is not off the grid
        return feasibility(self.grid, xyz, DEFAULT_LAND_THRESHOLD, 0.0).reshape(
            self.state.shape[:2])

    def traced(self) -> np.ndarray:
        """The true states kept with ``trace=True``.

        Returns
        -------
        (steps + 1, E, N, STATE_DIM) float64
            The start state and the state after every step taken.

        Raises
        ------
        RuntimeError
            If the batch was built without ``trace=True``.
        """
        if self.trace is None:
            raise RuntimeError(f"{type(self).__name__}: built without trace=True")
        return np.stack(self.trace)


class SceneEpisodes(SteppedEpisodes):
    """E episodes of one task in a MuJoCo scene.

    Parameters
    ----------
    mod : module
        The task module, as for :class:`~oneocean.tasks.episodes.Episodes`.
    scene : Scene
        The scene (:class:`oneocean.backends.mujoco.scenes.Scene`).
    grid : Grid
        The scene's local grid, ``scene.grid_data`` loaded (:func:`oneocean.engine.load_grid`).
    tier, init, method, dyn, vehicle, seed
        As for :class:`~oneocean.tasks.episodes.Episodes`.
    physics_step_s : float, default 0.02
        MuJoCo's step, s (:data:`PHYSICS_STEP_S`); ``tier["dt_s"]`` must be a whole number of
        them.
    **kw
        Further keywords of :class:`SteppedEpisodes` (``trace``) and of
        :class:`~oneocean.tasks.episodes.Episodes`.
    """

    backend = "mujoco"

    def __init__(self, mod, scene, grid, tier: dict, init: dict, method, dyn: str, vehicle,
                 seed: int, *, physics_step_s: float = PHYSICS_STEP_S, **kw):
        from .physics import ScenePhysics

        n_ep, n_ag = np.asarray(init["pos0"]).shape[:2]
        physics = ScenePhysics(scene, vehicle, n_ep, n_ag, dt=float(tier["dt_s"]),
                               timestep=float(physics_step_s))
        self.scene = scene
        super().__init__(mod, grid, tier, init, method, dyn, vehicle, seed, physics=physics,
                         **kw)
