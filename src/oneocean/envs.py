"""The step API: every task as a Gymnasium vector env and a PettingZoo parallel env.

Both run the same episode loop, task hooks and metrics as the fused rollouts
(:mod:`oneocean.tasks.loop`): a ``step`` writes the agents' actions into the loop's external
action slots and advances every running episode by one step.

Spaces (per agent; ``N`` = team size)
    observation
        ``OBS_DIM`` float64 values, :data:`oneocean.tasks.common.OBS_FIELDS`: the task's goal
        cue (goal point minus the agent's navigation estimate of its position, world m), its
        current estimate (forecast plus filtered in-situ samples, :mod:`oneocean.sensing`,
        m s-1), depth and altitude above the seafloor (m), the pollution
        probe (SPC, PI), the three nearest teammates' horizontal offsets (m). Values the task
        does not define (no field, fewer teammates) are 0 here (NaN in recorded observations).
    action
        3 float64: the desired velocity relative to the water, world frame (x east, y down,
        z north), m s-1, as in the paper; the loop clips its norm to the vehicle's ``v_max``
        (the Box bounds are +-v_max per component). Heading is left to the vehicle.
    reward
        1 on the step an episode ends in success, else 0 (the benchmark scores episodes with
        the task's metrics, which every ended episode reports in ``info``).

Episodes
    ``reset(seed=s)`` starts the same episodes as ``run_cell(..., seed=s)`` (episode ``e`` of
    a vector env is episode ``e`` of the cell), so a policy scored through the step API and a
    fused method see identical scenarios. An episode ends with ``terminated`` (the task's own
    end: success or a terminal failure) or ``truncated`` (the time limit). Autoreset is
    ``DISABLED``: finished sub-envs ignore further actions until ``reset``.
"""

from __future__ import annotations

import numpy as np

import gymnasium as gym
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv

from .tasks import Cell
from .tasks.common import ACT_FIELDS, OBS_DIM, OBS_FIELDS
from .backends.protocol import Rollout


class _Cell(Cell):
    """A :class:`~oneocean.tasks.Cell` that builds externally driven :class:`Episodes`."""

    def __init__(self, task: str, tier: int, grid, *, dynamics: str = "6dof",
                 n_agents: int | None = None, currents: bool = True, vehicle=None,
                 backend: str = "core", scene=None):
        super().__init__(grid, task, tier, n_agents=n_agents, currents=currents,
                         vehicle=vehicle, backend=backend, scene=scene)
        self.dynamics = dynamics
        self.v_max = float(self.vehicle.v_max)

    def batch(self, n_episodes: int, seed: int) -> Rollout:
        """Externally driven episodes ``0 .. n_episodes-1`` of ``seed`` on the backend."""
        return self.episodes(self.reset(n_episodes, seed), None, self.dynamics, seed)

    def obs_space(self, shape) -> spaces.Box:
        return spaces.Box(-np.inf, np.inf, shape=shape, dtype=np.float64)

    def act_space(self, shape) -> spaces.Box:
        return spaces.Box(-self.v_max, self.v_max, shape=shape, dtype=np.float64)


def _clean(obs: np.ndarray) -> np.ndarray:
    return np.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0)


class OceanVectorEnv(VectorEnv):
    """``num_envs`` episodes of one (task, tier) cell advanced together by the fused loop.

    Observation (num_envs, N, OBS_DIM), action (num_envs, N, 3), reward/terminated/truncated
    (num_envs,). ``info`` carries, for sub-envs whose episode ended at this step, every
    result column of the cell table (``success``, ``T_s``, ``E``, ``coll_ratio``,
    ``violations`` and the task's metrics) with Gymnasium's ``_<key>`` masks.

    Parameters
    ----------
    task, tier : the cell; grid : a :class:`~oneocean.engine.grid.Grid` or a grid export path
    (None with ``scene``); num_envs : episodes per batch; dynamics, n_agents, currents,
    vehicle : as ``run_cell``; backend, scene : the execution backend (``core``, or
    ``mujoco`` with a :class:`oneocean.backends.mujoco.scenes.Scene`), as
    :class:`~oneocean.tasks.Cell`.
    """

    metadata = {"autoreset_mode": AutoresetMode.DISABLED, "render_modes": []}

    def __init__(self, task: str, tier: int, grid, num_envs: int = 8, **kw):
        self.cell = _Cell(task, tier, grid, **kw)
        n = self.cell.n_agents
        self.num_envs = int(num_envs)
        self.single_observation_space = self.cell.obs_space((n, OBS_DIM))
        self.single_action_space = self.cell.act_space((n, len(ACT_FIELDS)))
        self.observation_space = self.cell.obs_space((self.num_envs, n, OBS_DIM))
        self.action_space = self.cell.act_space((self.num_envs, n, len(ACT_FIELDS)))
        self.obs_fields = OBS_FIELDS
        self.batch: Rollout | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if options and "reset_mask" in options:
            raise ValueError("OceanVectorEnv: autoreset is DISABLED and partial resets are "
                             "not supported; call reset() for the whole batch")
        super().reset(seed=seed)
        self._seed = int(seed) if seed is not None else int(self.np_random.integers(2**31))
        self.batch = self.cell.batch(self.num_envs, self._seed)
        self.batch.run(0)            # begin every episode (step 0 not taken)
        return _clean(self.batch.observe()), {}

    def step(self, actions):
        b = self.batch
        if b is None:
            raise RuntimeError("OceanVectorEnv: call reset() before step()")
        was_done = b.done.copy()
        b.set_actions(actions)
        live = ~was_done
        k_next = int(b.k[live].max()) + 1 if live.any() else 0
        b.run(k_next)
        ended = b.done & ~was_done
        success = b.res[:, 0] > 0.5
        truncated = ended & (b.k >= b.n_steps) & ~success
        terminated = ended & ~truncated
        reward = (ended & success).astype(np.float64)
        info: dict = {}
        if ended.any():
            for j, col in enumerate(b.columns):
                info[col] = np.where(ended, b.res[:, j], np.nan)
                info["_" + col] = ended.copy()
        return _clean(b.observe()), reward, terminated, truncated, info

    def close(self, **kwargs):
        self.batch = None


class OceanEnv(gym.Env):
    """Single-episode view of :class:`OceanVectorEnv` (``num_envs = 1``): observation
    (N, OBS_DIM), action (N, 3). For ``check_env`` and single-env code."""

    metadata = {"render_modes": []}

    def __init__(self, task: str, tier: int, grid, **kw):
        self.venv = OceanVectorEnv(task, tier, grid, num_envs=1, **kw)
        self.observation_space = self.venv.single_observation_space
        self.action_space = self.venv.single_action_space

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        s = seed if seed is not None else int(self.np_random.integers(2**31))
        obs, _ = self.venv.reset(seed=int(s))
        return obs[0], {}

    def step(self, action):
        obs, r, term, trunc, info = self.venv.step(np.asarray(action)[None])
        one = {k: (v[0] if isinstance(v, np.ndarray) else v) for k, v in info.items()
               if not k.startswith("_")}
        return obs[0], float(r[0]), bool(term[0]), bool(trunc[0]), one


def parallel_env(task: str, tier: int, grid, **kw):
    """A PettingZoo ``ParallelEnv`` of one episode of a (multi-agent) task; agents are
    ``vehicle_0 .. vehicle_{N-1}``, each with an ``OBS_DIM`` observation and a 3-vector
    action (see the module docstring)."""
    from pettingzoo import ParallelEnv

    class OceanParallelEnv(ParallelEnv):
        metadata = {"name": f"oneocean_{task.lower()}_t{int(tier)}", "render_modes": []}

        def __init__(self):
            self.venv = OceanVectorEnv(task, tier, grid, num_envs=1, **kw)
            n = self.venv.cell.n_agents
            self.possible_agents = [f"vehicle_{i}" for i in range(n)]
            self.agents = []
            self._obs_space = self.venv.cell.obs_space((OBS_DIM,))
            self._act_space = self.venv.cell.act_space((len(ACT_FIELDS),))
            self.render_mode = None

        def observation_space(self, agent):
            return self._obs_space

        def action_space(self, agent):
            return self._act_space

        def reset(self, seed=None, options=None):
            s = int(seed) if seed is not None else int(np.random.SeedSequence().entropy % 2**31)
            obs, _ = self.venv.reset(seed=s)
            self.agents = list(self.possible_agents)
            return ({a: obs[0, i] for i, a in enumerate(self.agents)},
                    {a: {} for a in self.agents})

        def step(self, actions):
            n = len(self.possible_agents)
            a = np.zeros((1, n, len(ACT_FIELDS)))
            for i, name in enumerate(self.possible_agents):
                if name in actions:
                    a[0, i] = actions[name]
            obs, r, term, trunc, info = self.venv.step(a)
            metrics = {k: float(v[0]) for k, v in info.items() if not k.startswith("_")}
            agents = list(self.agents)
            out = ({x: obs[0, self.possible_agents.index(x)] for x in agents},
                   {x: float(r[0]) for x in agents},
                   {x: bool(term[0]) for x in agents},
                   {x: bool(trunc[0]) for x in agents},
                   {x: dict(metrics) for x in agents})
            if term[0] or trunc[0]:
                self.agents = []
            return out

        def render(self):
            return None

        def close(self):
            self.venv.close()

    return OceanParallelEnv()
