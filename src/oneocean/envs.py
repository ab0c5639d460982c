"""The step API: every task as a Gymnasium env / vector env and a PettingZoo parallel env.

All of them run the same episode loop, task hooks and metrics as the fused rollouts
(:mod:`oneocean.tasks.loop`): a ``step`` writes the agents' actions into the loop's external
action slots and advances every running episode by one step. Success, the metrics and the
paper's tables always use the task's own criteria; the reward is only a training signal.

Spaces (per agent; ``N`` = team size)
    observation, ``obs_mode="raw"`` (default)
        ``D`` float64 values: the common head :data:`oneocean.tasks.common.OBS_FIELDS` (the
        task's cue minus the agent's navigation estimate of its position, world m; its current
        estimate, forecast plus filtered in-situ samples, :mod:`oneocean.sensing`, m s-1;
        depth and altitude above the seafloor, m; the task's probe; the three nearest
        teammates' horizontal offsets, m; the navigation estimate, heading and ground
        velocity; time, energy used, position fixes) then the task's own fields (its
        ``OBS_EXTRA``; docs/policy.md). Values the task does not define (no field, fewer
        teammates) are 0 here (NaN in recorded observations and in ``evaluate``'s
        :class:`~oneocean.evaluate.Observation`).
    observation, ``obs_mode="normalized"``
        :data:`NORM_FIELDS` (:func:`normalize`): the cue as ``g / (|g| + 10 m)`` (a unit
        vector far away, metres / 10 close in) and ``log(1 + |g|) / log(1 + reach)`` with
        ``reach = v_max x time limit`` (the task's range); the current estimate / ``v_max``;
        depth / 100 m (clipped to 5); altitude clipped to 50 m, / 50 m (1 where undefined);
        ``log(1 + probe)``; each teammate's offset / (distance + 10 m); ``v_max`` (m s-1) and
        the fraction of the time limit left; the ground velocity / ``v_max``; then the task's
        own fields as ``sign(x) log(1 + |x|)`` (0 where undefined).
    action, ``action_mode="velocity"`` (default)
        3 float64: the desired velocity relative to the water, world frame (x east, y down,
        z north), m s-1, as in the paper; the loop clips its norm to the vehicle's ``v_max``
        (the Box bounds are +-v_max per component). ``step`` also takes a fourth value per
        agent, the commanded heading (rad from north, NaN: free, the vehicle faces its
        velocity), e.g. station keeping's heading.
    action, ``action_mode="normalized"``
        3 float64 in [-1, 1]: the desired velocity in units of ``v_max``, its norm clipped to 1
        (every bound is reachable: a unit vector along an axis is full speed that way).
    reward, ``reward="sparse"`` (default)
        1 on the step an episode ends in success, else 0.
    reward, ``reward="dense"``
        :func:`dense_reward`, consistent with the task's success rule: progress toward the
        cue as a bounded potential, the energy used against the task's allocation (the
        judge's; else the control effort), a penalty as large as success when the allocation
        is exceeded, small penalties for rejected moves and near-collisions, and 1 on success
        (a successful episode earns more than a failed one).

Episodes and resets
    ``reset(seed=s)`` starts the same episodes as ``run_cell(..., seed=s)``: sub-env ``j``
    runs the cell's episode ``j`` first. An episode ends with ``terminated`` (the task's own
    end: success or a terminal failure) or ``truncated`` (the time limit). Autoreset
    (Gymnasium's ``AutoresetMode``):

    * ``next_step`` (default): the ``step`` after an episode ended resets that sub-env (its
      action is ignored; reward 0) and returns the new episode's first observation;
    * ``same_step``: the step that ends an episode returns the next episode's first
      observation, the final one in ``info["final_obs"]`` (and ``info["final_info"]``);
    * ``disabled``: finished sub-envs ignore further actions until ``reset`` -- what
      evaluation uses (:mod:`oneocean.evaluate`), so episode ``e`` is the cell's episode ``e``.

    New episodes come from a pool per seed (``pool`` episodes per sub-env): the pool of seed
    ``s`` holds the cell's episodes ``0, 1, ...`` of ``s`` and sub-envs draw them in the
    order they finish; a spent pool is followed by one of seed :func:`pool_seed` ``(s, 1)``,
    ``(s, 2)``, ... A pool's candidates are drawn at once, its episodes built ``num_envs`` at
    a time as the sub-envs reach them (the same episodes, bit for bit). A seed whose
    episodes the cell cannot host (a task whose scenario finds no candidate in the tier's
    current regime for it) is skipped for the next pool seed, except with
    ``strict_seed=True`` (evaluation).

    ``info`` carries, for sub-envs whose episode ended at this step, every result column of the
    cell table (``success``, ``T_s``, ``E``, ``coll_ratio``, ``violations`` and the task's
    metrics) and ``is_success``, with Gymnasium's ``_<key>`` masks; and for sub-envs whose
    episode started (every sub-env at ``reset``; autoreset), ``info["briefing"]``: a tuple of
    each sub-env's briefing (the task's ``<ID>Briefing`` of one episode, docs/policy.md; None
    for the others), with its ``_briefing`` mask.
"""

from __future__ import annotations

import copy
import math

import numpy as np

import gymnasium as gym
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv

from .errors import ConfigError, NotApplicable
from .tasks import Cell
from .tasks.common import ACT_FIELDS, O_T, O_VX, O_VZ, OBS_DIM, OBS_FIELDS, N_MATES
from .tasks.spawn import episode_rows
from .tasks.public import briefing_rows
from .tasks.loop import ENV_ENDED, ENV_SUCCESS, ENV_TRUNCATED, FINISHED, NEW, EnvIO
from .backends.protocol import Rollout
from .engine import libm

AUTORESET_MODES = {"next_step": AutoresetMode.NEXT_STEP, "same_step": AutoresetMode.SAME_STEP,
                   "disabled": AutoresetMode.DISABLED}
OBS_MODES = ("raw", "normalized", "dict")
ACTION_MODES = ("velocity", "normalized")
REWARDS = ("sparse", "dense")

#: The normalised observation's fields before the task's own (``obs_mode="normalized"``;
#: see the module docstring); then one ``x_<name>`` per field of the task's ``OBS_EXTRA``.
NORM_FIELDS = (("goal_ux", "goal_uy", "goal_uz", "goal_log_dist", "current_e", "current_n",
                "depth", "altitude", "pollution_log")
               + tuple(f"mate{m + 1}_{c}" for m in range(N_MATES) for c in ("ux", "uz"))
               + ("v_max_ms", "time_left", "vx", "vy", "vz"))
NORM_DIM = len(NORM_FIELDS)
#: Length scales of the normalised view, m.
GOAL_SCALE_M, MATE_SCALE_M, DEPTH_SCALE_M, ALTITUDE_CLIP_M = 10.0, 10.0, 100.0, 50.0
#: Dense reward (:func:`dense_reward`): the weight of the progress potential (over an
#: episode at most this much), of the energy term (over an episode at most this much; against
#: the allocation where the task has one), the penalty per rejected move and per step with a
#: near-collision (each in units of one over the episode's steps), and the penalty at the step
#: a task's energy allocation is exceeded (the judge's failure), as large as success.
PROGRESS_WEIGHT, ENERGY_WEIGHT = 0.5, 0.5
VIOLATION_PENALTY, COLLISION_PENALTY = 1.0, 1.0
ALLOCATION_PENALTY = 1.0
#: Pool seeds tried before a reset gives up on a cell that cannot host episodes.
SEED_TRIES = 16
_NONE = np.zeros(0, dtype=np.int64)


def pool_seed(seed: int, index: int) -> int:
    """The seed of the ``index``-th pool after the first (the first is ``seed`` itself).

    Parameters
    ----------
    seed : int
        The seed given to ``reset``.
    index : int
        Pool index, 0 for the first.

    Returns
    -------
    int
        ``seed`` for index 0, else a non-negative 63-bit seed from
        ``SeedSequence([seed, index])``.
    """
    if index == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0] >> 1)


def _choice(name: str, value: str, valid) -> str:
    if value not in valid:
        raise ConfigError(f"{name}: {value!r} is not one of {', '.join(valid)}")
    return value


def _slog(x):
    """``sign(x) log(1 + |x|)``, non-finite values as 0."""
    x = np.nan_to_num(np.asarray(x, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    return np.sign(x) * libm.log1p(np.abs(x))


def normalize(obs: np.ndarray, v_max: float, reach: float, t_lim: float) -> np.ndarray:
    """The normalised view of raw observations (the module docstring gives the fields).

    Parameters
    ----------
    obs : (..., N, D) array_like
        Raw observations (:data:`oneocean.tasks.common.OBS_FIELDS`, then the task's own
        fields), NaN for undefined values.
    v_max : float
        The vehicle's speed limit, m s-1.
    reach : float
        The task's range, m (``v_max`` x the time limit).
    t_lim : float
        The time limit, s (the fraction left is from the observation's time).

    Returns
    -------
    (..., N, NORM_DIM + D - OBS_DIM) float64
        The normalised observations (:data:`NORM_FIELDS`, then the task's fields as
        ``sign(x) log(1 + |x|)``), finite.
    """
    o = np.asarray(obs, dtype=np.float64)
    n_x = o.shape[-1] - OBS_DIM
    out = np.zeros(o.shape[:-1] + (NORM_DIM + n_x,))
    g = np.nan_to_num(o[..., 0:3])
    d = np.sqrt((g * g).sum(-1))
    out[..., 0:3] = g / (d + GOAL_SCALE_M)[..., None]
    out[..., 3] = libm.log1p(d) / math.log1p(max(reach, 1.0))
    out[..., 4:6] = np.nan_to_num(o[..., 3:5]) / v_max
    out[..., 6] = np.clip(np.nan_to_num(o[..., 5]) / DEPTH_SCALE_M, 0.0, 5.0)
    alt = o[..., 6]
    out[..., 7] = np.where(np.isfinite(alt), np.clip(alt, 0.0, ALTITUDE_CLIP_M), ALTITUDE_CLIP_M)
    out[..., 7] /= ALTITUDE_CLIP_M
    p = o[..., 7]
    out[..., 8] = np.where(np.isfinite(p), libm.log1p(np.maximum(p, 0.0)), 0.0)
    for m in range(N_MATES):
        dx, dz = o[..., 8 + 2 * m], o[..., 9 + 2 * m]
        ok = np.isfinite(dx) & np.isfinite(dz)
        dm = np.sqrt(np.where(ok, dx * dx + dz * dz, 0.0)) + MATE_SCALE_M
        out[..., 9 + 2 * m] = np.where(ok, dx / dm, 0.0)
        out[..., 10 + 2 * m] = np.where(ok, dz / dm, 0.0)
    out[..., 15] = v_max
    out[..., 16] = np.clip(1.0 - np.nan_to_num(o[..., O_T]) / float(t_lim), 0.0, 1.0)
    out[..., 17:20] = np.clip(np.nan_to_num(o[..., O_VX:O_VZ + 1]) / v_max, -2.0, 2.0)
    out[..., NORM_DIM:] = np.clip(_slog(o[..., OBS_DIM:]), -20.0, 20.0)
    return out


def dense_reward(d0, d_prev, d_now, new_viol, new_coll, success, over, new_energy, scale,
                 n_steps: int, max_step: float):
    """The opt-in dense reward of one step per sub-env: consistent with the task's success
    rule, so that a policy maximising it does not fail the task.

    Progress toward the cue as a potential: ``PROGRESS_WEIGHT`` x the team's mean decrease
    of the distance to its cues over the step, each agent's in units of its distance at the
    episode's start (at least 1 m; an agent whose cue jumped by more than ``2 max_step + 1 m``
    -- a new waypoint, slot or target -- or is undefined counts 0 that step): over an
    episode at most ``PROGRESS_WEIGHT`` while the cue stays. The energy used: ``ENERGY_WEIGHT`` x
    its increment over ``scale`` (the task's energy allocation in J where it has one, so that
    the progress per energy decides the speed as the judge's allocation does; else the team's
    energy proxy at full speed over the time limit): over an episode at most ``ENERGY_WEIGHT``
    within the allocation. ``ALLOCATION_PENALTY`` at the step the allocation is exceeded (the
    judge fails the episode from then on), ``VIOLATION_PENALTY`` per rejected move and
    ``COLLISION_PENALTY`` per step with a near-collision, both over ``n_steps``, and 1 on
    success. A successful episode therefore earns more than a failed one.

    Parameters
    ----------
    d0 : (E, N) float64
        Each agent's distance to its cue at the episode's start, m.
    d_prev, d_now : (E, N) float64
        Each agent's distance to its cue before and after the step, m (NaN: undefined).
    new_viol : (E,) int
        Rejected moves of the step.
    new_coll : (E,) int
        Steps with a near-collision counted at this step (0 or 1).
    success : (E,) bool
        The episode ended in success at this step.
    over : (E,) bool
        The episode's energy allocation was exceeded at this step.
    new_energy : (E,) float64
        The energy of the step: J against an allocation, else the energy proxy (m2 s-1).
    scale : (E,) float64
        The allocation (J), else the energy proxy at full speed over the time limit.
    n_steps : int
        The episode's steps (its time limit).
    max_step : float
        The longest move through the water in a step, m (``v_max dt``).

    Returns
    -------
    (E,) float64
        The reward of each sub-env.
    """
    delta = d_prev - d_now
    ref = np.maximum(np.nan_to_num(d0, nan=1.0), 1.0)
    jump = ~np.isfinite(delta) | (np.abs(delta) > 2.0 * max_step + 1.0)
    step = np.where(jump, 0.0, delta / ref)
    return (PROGRESS_WEIGHT * step.mean(-1)
            - ENERGY_WEIGHT * np.asarray(new_energy, dtype=np.float64) / scale
            - ALLOCATION_PENALTY * np.asarray(over, dtype=np.float64)
            - (VIOLATION_PENALTY * new_viol + COLLISION_PENALTY * (new_coll > 0)) / n_steps
            + success.astype(np.float64))


def _step_observe(batch: Rollout, lo: int, hi: int) -> np.ndarray:
    """One step of every running episode of ``batch`` (all within ``lo .. hi-1``) and the
    next observation (E, N, OBS_DIM), rows ``lo .. hi-1`` valid: the backend's fused
    ``step_observe`` where it has one (the core), else ``run(-1)`` and ``observe``."""
    fused = getattr(batch, "step_observe", None)
    if fused is not None:
        return fused(lo, hi)
    batch.run(-1)
    return batch.observe()


def _cue_distance(raw: np.ndarray) -> np.ndarray:
    """(..., N) distance to the goal cue of raw observations, m (NaN where undefined)."""
    g = raw[..., 0:3]
    return np.sqrt((g * g).sum(-1))


class _Cell(Cell):
    """A :class:`~oneocean.tasks.Cell` that builds externally driven episodes."""

    def __init__(self, task: str, tier: int, grid, *, dynamics: str = "6dof",
                 n_agents: int | None = None, currents: bool = True, vehicle=None,
                 current_gain: float = 1.0, tide=None, backend: str = "core", scene=None,
                 info: str | None = None):
        if scene is None:
            from .product.defaults import resolve_grid

            grid = resolve_grid(grid)      # None: the default region's grid
        super().__init__(grid, task, tier, n_agents=n_agents, currents=currents,
                         vehicle=vehicle, current_gain=current_gain, tide=tide,
                         backend=backend, scene=scene)
        if info is not None:
            from .sensing import INFO_LEVELS

            _choice("info", info, INFO_LEVELS)
        self.info = info            # what the policy is given (None: the sensor models)
        self.dynamics = dynamics
        self.v_max = float(self.vehicle.v_max)
        self._checked = None       # (episodes, seed, check): the last seed's candidates
        self._whole = None         # (episodes, seed, reset): the last seed's whole reset dict

    @property
    def chunked(self) -> bool:
        """Whether a pool may be built a part at a time (:meth:`batch` with ``rows``): on the
        core backend (a part's rows are those of the whole pool; a task with cell-wide values,
        ``cell_constants``, takes them from the whole pool's reset, kept once per seed)."""
        return self.backend == "core"

    def _check(self, episodes: int, seed: int) -> tuple:
        # one seed's pool is built a part at a time: its candidates are drawn and judged once
        if self._checked is None or self._checked[:2] != (episodes, seed):
            self._checked = (episodes, seed, super()._check(episodes, seed))
        return self._checked[2]

    def _reset(self, episodes: int, seed: int, rows: slice = slice(None)) -> dict:
        # a task whose episodes share cell-wide values (cell_constants: PI's field shape)
        # builds the whole pool's reset dict once per seed; a part is a copy of its rows
        if rows == slice(None) or not hasattr(self.mod, "cell_constants"):
            return super()._reset(episodes, seed, rows)
        if self._whole is None or self._whole[:2] != (episodes, seed):
            self._whole = (episodes, seed, super()._reset(episodes, seed))
        return episode_rows(self._whole[2], np.arange(episodes)[rows], episodes)

    def batch(self, n_episodes: int, seed: int, rows: tuple[int, int] | None = None) -> Rollout:
        """Externally driven episodes ``0 .. n_episodes-1`` of ``seed`` on the backend, or
        with ``rows = (a, b)`` its episodes ``a .. b-1`` only, bit for bit (the cell's
        shards: :meth:`~oneocean.tasks.Cell.reset`, ``Episodes(e0=a)``)."""
        return self.episodes(self.reset(n_episodes, seed, rows), None, self.dynamics, seed,
                             e0=0 if rows is None else int(rows[0]), info=self.info)


class _Pool:
    """Pre-sampled episodes that sub-envs draw in order: the pool seed's episodes ``a ..
    b-1`` (``rows``; all ``n_seed`` of them without), every one parked (the loop skips it)
    until drawn, then begun."""

    def __init__(self, cell: _Cell, n_seed: int, seed: int, park: bool,
                 rows: tuple[int, int] | None = None):
        self.batch = cell.batch(n_seed, seed, rows)
        self.seed = seed
        self.rows = (0, n_seed) if rows is None else (int(rows[0]), int(rows[1]))
        self.n_seed = n_seed
        self.n = self.rows[1] - self.rows[0]
        self.drawn = 0
        self.live = 0                      # drawn episodes still owned by a sub-env
        if park:
            self.batch.LS.status[:] = FINISHED

    def draw(self, k: int) -> np.ndarray:
        """Draw the next ``k`` (at most what is left) parked episodes and begin them."""
        e = np.arange(self.drawn, min(self.n, self.drawn + k))
        self.drawn += e.size
        self.batch.LS.status[e] = NEW
        self.live += e.size
        return e


class OceanVectorEnv(VectorEnv):
    """``num_envs`` episodes of one (task, tier) cell advanced together by the task's loop.

    Observation (num_envs, N, D), action (num_envs, N, 3), reward/terminated/truncated
    (num_envs,); see the module docstring for the modes.

    Parameters
    ----------
    task : str
        Registered task id.
    tier : int
        Tier of the task's table.
    grid : Grid, mapping, path-like or None
        A :class:`~oneocean.engine.grid.Grid`, a grid export path, a region config, or None:
        the default region's grid (:func:`oneocean.product.defaults.resolve_grid`; ignored with
        ``scene``).
    num_envs : int
        Sub-envs (at least 1).
    autoreset_mode : str or AutoresetMode
        ``next_step`` (default), ``same_step`` or ``disabled`` (or Gymnasium's
        ``AutoresetMode``).
    obs_mode : str
        ``raw`` (default) or ``normalized``.
    action_mode : str
        ``velocity`` (default, m s-1) or ``normalized`` (units of ``v_max``).
    reward : str
        ``sparse`` (default) or ``dense``.
    pool : int
        Episodes per sub-env in each pool seed's pool (autoreset modes), built ``num_envs``
        at a time.
    render_mode : str, optional
        None or ``rgb_array`` (a top-down view of sub-env 0: :meth:`render`).
    strict_seed : bool
        A seed whose episodes the cell cannot host raises ``NotApplicable`` (evaluation:
        :func:`oneocean.evaluate.evaluate`) instead of moving on to the next pool seed.
    **kw
        ``dynamics`` (default ``6dof``), ``n_agents``, ``currents``, ``vehicle``,
        ``current_gain``, ``tide``: as :func:`~oneocean.tasks.run_cell` (the run's forcing:
        gain on the data currents, a synthetic tide term; episodes are the same under any
        forcing); ``backend``, ``scene``: the execution backend (``core``, or ``mujoco``
        with a :class:`oneocean.backends.mujoco.scenes.Scene`).
    info : str, optional
        What the policy is given instead of the sensor models
        (:data:`oneocean.sensing.INFO_LEVELS`; None: the sensor models, as every method;
        ``truth``: what the oracle is given).

    Raises
    ------
    ConfigError
        An unknown mode, ``num_envs`` below 1, or a bad cell (:class:`oneocean.tasks.Cell`).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": ["rgb_array"]}

    def __init__(self, task: str, tier: int, grid=None, num_envs: int = 8, *,
                 autoreset_mode="next_step", obs_mode: str = "raw",
                 action_mode: str = "velocity", reward: str = "sparse", pool: int = 4,
                 render_mode: str | None = None, strict_seed: bool = False,
                 info: str | None = None, **kw):
        if isinstance(autoreset_mode, AutoresetMode):
            autoreset_mode = {v: k for k, v in AUTORESET_MODES.items()}[autoreset_mode]
        self.autoreset = _choice("autoreset_mode", autoreset_mode, tuple(AUTORESET_MODES))
        self.obs_mode = _choice("obs_mode", obs_mode, OBS_MODES)
        self.action_mode = _choice("action_mode", action_mode, ACTION_MODES)
        self.reward_mode = _choice("reward", reward, REWARDS)
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"render_mode: {render_mode!r} is not one of None, rgb_array")
        self.render_mode = render_mode
        self.strict_seed = bool(strict_seed)
        self.metadata = {**self.metadata, "autoreset_mode": AUTORESET_MODES[self.autoreset]}
        self.cell = _Cell(task, tier, grid, info=info, **kw)
        self.task, self.tier = task, int(tier)
        self._view = "raw" if self.obs_mode == "dict" else self.obs_mode   # the agents' part
        self.obs_dim = OBS_DIM + len(getattr(self.cell.mod, "OBS_EXTRA", ()))
        n = self.cell.n_agents
        self.n_agents = n
        self.num_envs = int(num_envs)
        if self.num_envs < 1:
            raise ConfigError(f"num_envs: must be >= 1, got {num_envs}")
        self.pool_size = self.num_envs * max(1, int(pool))
        # episodes built at a time: a reset builds what the sub-envs start on
        self._part = self.num_envs if self.cell.chunked else self.pool_size
        p = self.cell.params
        self.v_max = self.cell.v_max
        self.dt = float(p["dt_s"])
        self.t_lim = float(p["time_limit_s"])
        self.reach = self.v_max * self.t_lim
        extra = tuple(getattr(self.cell.mod, "OBS_EXTRA", ()))
        self._energy_col = OBS_DIM + extra.index("energy_j") if "energy_j" in extra else None
        self.single_observation_space = self._obs_space((n,))
        self.single_action_space = self._act_space((n,))
        self.observation_space = self._obs_space((self.num_envs, n))
        self.action_space = self._act_space((self.num_envs, n))
        self.obs_fields = (OBS_FIELDS + tuple(getattr(self.cell.mod, "OBS_EXTRA", ()))
                           if self._view == "raw" else NORM_FIELDS)
        self._act_shape = (self.num_envs, n, len(ACT_FIELDS))
        self._obs_shape = (self.num_envs, n, self.obs_dim)
        self._flags = np.zeros(self.num_envs, dtype=np.int64)
        # the raw view leaves the compiled step ready (undefined values 0) unless the dense
        # reward needs the undefined cues
        self._clean = int(self._view == "raw" and self.reward_mode == "sparse")
        self._normalized = int(self.action_mode == "normalized")
        self._pools: list[_Pool] = []
        self._tail: _Pool | None = None      # the pool built last
        self._seed = None

    # ------------------------------------------------------------------ spaces
    def _obs_space(self, lead) -> spaces.Space:
        if self.obs_mode == "dict":
            parts = {"agents": spaces.Box(-np.inf, np.inf, shape=tuple(lead) + (self.obs_dim,),
                                          dtype=np.float64)}
            for name, shape in self._team_shapes().items():
                parts[name] = spaces.Box(-np.inf, np.inf, shape=tuple(lead[:-1]) + shape,
                                         dtype=np.float64)
            return spaces.Dict(parts)
        if self._view == "raw":
            return spaces.Box(-np.inf, np.inf, shape=tuple(lead) + (self.obs_dim,),
                              dtype=np.float64)
        n_x = self.obs_dim - OBS_DIM
        lo = np.array([-1, -1, -1, 0, -10, -10, 0, 0, 0] + [-1] * (2 * N_MATES)
                      + [0, 0, -2, -2, -2] + [-20] * n_x, float)
        hi = np.array([1, 1, 1, 10, 10, 10, 5, 1, 50] + [1] * (2 * N_MATES)
                      + [10, 1, 2, 2, 2] + [20] * n_x, float)
        return spaces.Box(np.broadcast_to(lo, tuple(lead) + lo.shape).copy(),
                          np.broadcast_to(hi, tuple(lead) + hi.shape).copy(), dtype=np.float64)

    def _act_space(self, lead) -> spaces.Box:
        b = self.v_max if self.action_mode == "velocity" else 1.0
        return spaces.Box(-b, b, shape=tuple(lead) + (len(ACT_FIELDS),), dtype=np.float64)

    # ------------------------------------------------------------------ pools
    def _new_pool(self, n: int, part: int | None = None) -> _Pool:
        """The next pool seed's ``n`` episodes (its first ``part`` of them only, built on their
        own, with ``part``). A seed whose episodes the cell cannot host (the task's scenario
        finds no valid candidate: ``NotApplicable``) is followed by the next pool seed, up to
        :data:`SEED_TRIES` of them, unless ``strict_seed`` (evaluation)."""
        rows = None if part is None or part >= n else (0, int(part))
        for attempt in range(1 if self.strict_seed else SEED_TRIES):
            try:
                pool = _Pool(self.cell, n, pool_seed(self._seed, self._n_pools),
                             park=self.autoreset != "disabled", rows=rows)
            except NotApplicable:
                self._n_pools += 1
                if self.strict_seed or attempt == SEED_TRIES - 1:
                    raise
                continue
            self._n_pools += 1
            return self._keep(pool)
        raise AssertionError("unreachable")  # pragma: no cover

    def _keep(self, pool: _Pool) -> _Pool:
        """Record ``pool`` as the pool built last, the one sub-envs draw from next."""
        self._pools.append(pool)
        self._tail = pool
        return pool

    def _next_pool(self) -> _Pool:
        """The episodes sub-envs draw next: the current pool seed's next ``num_envs``
        (:attr:`_Cell.chunked`; else all of its episodes at once), or the next pool seed's
        first. The order of the episodes is the same either way; a part is built when the
        sub-envs reach it."""
        tail = self._tail
        if tail is None or tail.rows[1] >= tail.n_seed:
            return self._new_pool(self.pool_size, self._part)
        a = tail.rows[1]
        return self._keep(_Pool(self.cell, tail.n_seed, tail.seed, park=True,
                                rows=(a, min(a + self._part, tail.n_seed))))

    def _draw(self, envs: np.ndarray) -> None:
        """Give every sub-env in ``envs`` its next episode (in sub-env order) and begin it."""
        envs = np.asarray(envs, dtype=np.int64)
        done = 0
        while done < envs.size:
            pool = self._pools[-1] if self._pools else None
            if pool is None or pool.drawn >= pool.n:
                pool = self._next_pool()
            e = pool.draw(envs.size - done)
            for j, ej in zip(envs[done:done + e.size], e):
                self._owner[j] = pool
                self._ep[j] = ej
            done += e.size
            self._group_cache = None
            pool.batch.run(0)              # begin the drawn episodes (step 0 not taken)
        self._viol_prev[envs] = 0
        self._coll_prev[envs] = 0

    def _release(self, envs) -> None:
        for j in envs:
            self._owner[j].live -= 1
        self._pools = [p for p in self._pools if p.live > 0 or p.drawn < p.n]

    def _groups(self):
        """(pool, sub-env rows, episode rows, lo, hi, rows) per pool that owns sub-envs
        (cached until the ownership changes): ``lo .. hi-1`` spans the pool's owned episodes
        (every running episode of the pool), ``rows`` (pool size,) the sub-env of each of
        the pool's episodes (-1: none)."""
        if self._group_cache is None:
            by = {}
            for j, p in enumerate(self._owner):
                by.setdefault(id(p), (p, []))[1].append(j)
            groups = []
            for p, js in by.values():
                js = np.array(js)
                eps = self._ep[js]
                lo, hi = int(eps.min()), int(eps.max()) + 1
                rows = np.full(p.n, -1, dtype=np.int64)
                rows[eps] = js
                groups.append((p, js, eps, lo, hi, rows))
            self._group_cache = groups
        return self._group_cache

    def _gather(self, what: str) -> np.ndarray:
        """Per sub-env rows of a batch attribute (``k``, ``done``, ``res``, ``viol``,
        ``coll``, ``energy``)."""
        groups = self._groups()
        out = None
        for pool, js, eps, _, _, _ in groups:
            b = pool.batch
            src = (b.res if what == "res" else
                   getattr(b.LS, "status" if what == "done" else what))
            if len(groups) == 1:
                out = src[eps]
                break
            if out is None:
                out = np.empty((self.num_envs,) + src.shape[1:], dtype=src.dtype)
            out[js] = src[eps]
        return out == FINISHED if what == "done" else out

    def _raw_obs(self, envs=None) -> np.ndarray:
        """Raw observations (len(envs), N, OBS_DIM) of sub-envs ``envs`` (default all)."""
        want = np.arange(self.num_envs) if envs is None else np.asarray(envs)
        out = np.empty((self.num_envs, self.n_agents, self.obs_dim))
        mask = np.zeros(self.num_envs, dtype=bool)
        mask[want] = True
        for pool, js, eps, _, _, _ in self._groups():
            sel = mask[js]
            if not sel.any():
                continue
            e = eps[sel]
            o = pool.batch.observe(int(e.min()), int(e.max()) + 1)
            out[js[sel]] = o[e]
        return out if envs is None else out[want]

    def _obs(self, raw: np.ndarray, envs=None, inplace: bool = False) -> np.ndarray:
        """The observation of raw observations ``raw`` of sub-envs ``envs`` (default all) in
        the env's view (``inplace``: the raw view may overwrite ``raw``)."""
        if self._view == "raw":
            out = raw if inplace else raw.copy()
            out[~np.isfinite(out)] = 0.0
            return out
        return normalize(raw, self.v_max, self.reach, self.t_lim)

    def _team_shapes(self) -> dict:
        """The task's team observation fields and their shapes per sub-env (``obs_mode =
        "dict"``), read off a batch of one episode (the shapes are the cell's)."""
        if not hasattr(self, "_team_shape_cache"):
            shapes = {}
            if getattr(self.cell.mod, "team_obs", None) is not None:
                T = self.cell.batch(1, 0).C.T
                shapes = {k: tuple(v.shape[1:]) for k, v in T._asdict().items()}
            self._team_shape_cache = shapes
        return self._team_shape_cache

    def _present(self, obs):
        """The observation as the env gives it: the agents' view, or with ``obs_mode="dict"``
        a dict of it (``agents``) and the task's team observation of every sub-env (undefined
        values 0)."""
        if self.obs_mode != "dict":
            return obs
        out = {"agents": obs}
        shapes = self._team_shapes()
        for name, shape in shapes.items():
            out[name] = np.zeros((self.num_envs,) + shape)
        if shapes:
            for pool, js, eps, _, _, _ in self._groups():
                T = pool.batch.C.T
                for name in shapes:
                    out[name][js] = np.nan_to_num(getattr(T, name)[eps])
        return out

    @property
    def batch(self) -> Rollout | None:
        """With autoreset disabled: the rollout of the cell's episodes ``0 .. num_envs-1``
        (:class:`oneocean.backends.protocol.Rollout`; its ``results()`` once all ended)."""
        if self.autoreset != "disabled" or not self._pools:
            return None
        return self._pools[0].batch

    @property
    def cell_steps(self) -> int:
        """Steps of an episode (the time limit over ``dt``; 0 before :meth:`reset`)."""
        return self._pools[0].batch.n_steps if self._pools else 0

    # ------------------------------------------------------------------ API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start every sub-env on a fresh episode (sub-env ``j`` on the cell's episode ``j``
        of ``seed``).

        Parameters
        ----------
        seed : int, optional
            The cell's seed; None: drawn from the env's generator.
        options : dict, optional
            Unused; a ``reset_mask`` (a partial reset) is refused.

        Returns
        -------
        obs : (num_envs, N, D) float64
            The first observations.
        info : dict
            Empty.

        Raises
        ------
        ValueError
            ``options`` with a ``reset_mask``.
        NotApplicable
            With ``strict_seed``, a seed whose episodes the cell cannot host (else after
            :data:`SEED_TRIES` pool seeds).
        """
        if options and "reset_mask" in options:
            raise ValueError("OceanVectorEnv: partial resets are made by autoreset; call "
                             "reset() for the whole batch")
        super().reset(seed=seed)
        self._seed = int(seed) if seed is not None else int(self.np_random.integers(2**31))
        self._pools, self._n_pools, self._tail = [], 0, None
        self._group_cache = None
        self._owner: list[_Pool | None] = [None] * self.num_envs
        self._ep = np.zeros(self.num_envs, dtype=np.int64)
        self._pending = np.zeros(self.num_envs, dtype=bool)
        self._n_pending = 0
        self._d0 = np.full((self.num_envs, self.n_agents), np.nan)
        self._d_prev = np.full((self.num_envs, self.n_agents), np.nan)
        self._viol_prev = np.zeros(self.num_envs, dtype=np.int64)
        self._coll_prev = np.zeros(self.num_envs, dtype=np.int64)
        self._energy_prev = np.zeros(self.num_envs)
        self._scale = np.ones(self.num_envs)
        self._alloc = np.zeros(self.num_envs, dtype=bool)
        self._over = np.zeros(self.num_envs, dtype=bool)
        if self.autoreset == "disabled":
            pool = self._new_pool(self.num_envs)
            pool.drawn = pool.live = self.num_envs
            self._owner = [pool] * self.num_envs
            self._ep = np.arange(self.num_envs)
            pool.batch.run(0)
        else:
            self._draw(np.arange(self.num_envs))
        raw = self._raw_obs()
        self._start_rewards(np.arange(self.num_envs), raw)
        return (self._present(self._obs(raw)),
                self._briefings(np.arange(self.num_envs), {}))

    def _start_rewards(self, envs, raw) -> None:
        """The dense reward's references of sub-envs ``envs`` whose episodes start, from their
        first raw observations ``raw`` (rows of those sub-envs) and briefings."""
        envs = np.asarray(envs, dtype=np.int64)
        d = _cue_distance(raw)
        self._d0[envs] = d
        self._d_prev[envs] = d
        self._energy_prev[envs] = 0.0
        self._over[envs] = False
        proxy = self.n_agents * self.v_max * self.v_max * self.t_lim
        for j in envs:
            alloc = float(self._owner[j].batch.B.energy_allocation[int(self._ep[j])])
            self._alloc[j] = self._energy_col is not None and math.isfinite(alloc)
            self._scale[j] = alloc if self._alloc[j] else proxy

    def _energy(self, raw) -> np.ndarray:
        """Each sub-env's energy used so far in the dense reward's measure: the task's own
        ``energy_j`` (summed over the team) where the episode has an allocation, else the
        team's energy proxy E."""
        proxy = self._gather("energy")
        if self._energy_col is None or not self._alloc.any():
            return proxy
        j_used = np.nansum(raw[..., self._energy_col], axis=-1)
        return np.where(self._alloc, j_used, proxy)

    def _briefings(self, envs, info: dict) -> dict:
        """``info["briefing"]`` (and its mask) for the sub-envs ``envs`` whose episode
        just started: each one's briefing, one episode."""
        out = [None] * self.num_envs
        mask = np.zeros(self.num_envs, dtype=bool)
        for j in np.asarray(envs, dtype=np.int64):
            b = self._owner[j].batch
            # the user keeps it: a copy of every array (the chart's too), none shared
            out[j] = copy.deepcopy(briefing_rows(b.B, [int(self._ep[j])]))
            mask[j] = True
        info["briefing"] = tuple(out)
        info["_briefing"] = mask
        return info

    def _checked_actions(self, actions) -> np.ndarray:
        """``actions`` as a contiguous float64 array of the action shape, else a one-line
        ConfigError naming both shapes."""
        a = np.ascontiguousarray(actions, dtype=np.float64)
        if a.shape != self._act_shape and a.shape != self._act_shape[:2] + (4,):
            raise ConfigError(f"actions: expected shape {self._act_shape} (or a heading "
                              f"column: {self._act_shape[:2] + (4,)}), got {a.shape}")
        return a

    def _to_velocity(self, actions) -> np.ndarray:
        a = self._checked_actions(actions)
        if self.action_mode == "normalized":
            v = a[..., :3]
            norm = np.sqrt((v * v).sum(-1, keepdims=True))
            a = a.copy()
            a[..., :3] = self.v_max * v / np.maximum(norm, 1.0)
        return a

    def step(self, actions):
        """Advance every running sub-env by one step.

        Parameters
        ----------
        actions : (num_envs, N, 3) array_like
            Each agent's action (``action_mode``: velocity relative to the water, world
            frame, m s-1, or units of ``v_max``).

        Returns
        -------
        obs : (num_envs, N, D) float64
            The next observations (autoreset: see the module docstring).
        reward : (num_envs,) float64
            The step's reward (``reward`` mode).
        terminated : (num_envs,) bool
            The episode ended by the task (success or a terminal failure).
        truncated : (num_envs,) bool
            The episode ended at the time limit without success.
        info : dict
            For sub-envs whose episode ended: the cell table's result columns and
            ``is_success``, with Gymnasium's ``_<key>`` masks (``final_obs`` /
            ``final_info`` with ``same_step``).

        Raises
        ------
        RuntimeError
            Before :meth:`reset`.
        ConfigError
            ``actions`` of another shape.
        """
        if not self._pools:
            raise RuntimeError("OceanVectorEnv: call reset() before step()")
        n = self.num_envs
        # NEXT_STEP: these reset, not step
        reset_now = np.flatnonzero(self._pending) if self._n_pending else _NONE
        # one compiled call per pool: the step of every running episode, then every agent's
        # next observation (a finished episode -- NEXT_STEP's pending ones included -- is
        # not stepped, so its action row is never read)
        groups = self._groups()
        fast = self._fused_env_step(actions, groups)
        if fast is not None:
            raw, flags = fast
            if not np.count_nonzero(flags):            # no episode ended at this step
                ended = None
            else:
                ended = (flags & ENV_ENDED) != 0
                success = (flags & ENV_SUCCESS) != 0
                truncated = (flags & ENV_TRUNCATED) != 0
        else:
            raw, ended = self._step_groups(self._to_velocity(actions), groups)
            if ended is not None:
                res = self._gather("res")
                success = ended & (res[:, 0] > 0.5)
                truncated = ended & ~success & (self._gather("k") >= self.cell_steps)
        info: dict = {}
        if ended is None:
            terminated = np.zeros(n, dtype=bool)
            truncated = np.zeros(n, dtype=bool)
            success = None
        else:
            terminated = ended & ~truncated
            res = self._gather("res")
            cols = self._owner[int(np.flatnonzero(ended)[0])].batch.columns
            for c, col in enumerate(cols):
                info[col] = np.where(ended, res[:, c], np.nan)
                info["_" + col] = ended.copy()
            info["is_success"] = success.copy()
            info["_is_success"] = ended.copy()
        if self.reward_mode == "sparse":
            reward = np.zeros(n) if success is None else success.astype(np.float64)
        else:
            d_now = _cue_distance(raw)
            viol, coll = self._gather("viol"), self._gather("coll")
            energy = self._energy(raw)
            over = self._alloc & ~self._over & (energy > self._scale)
            reward = dense_reward(self._d0, self._d_prev, d_now, viol - self._viol_prev,
                                  coll - self._coll_prev,
                                  np.zeros(n, dtype=bool) if success is None else success,
                                  over, energy - self._energy_prev, self._scale,
                                  self.cell_steps, self.v_max * self.dt)
            self._viol_prev, self._coll_prev = viol, coll
            self._energy_prev = energy
            self._over |= over
            self._d_prev = d_now
        if reset_now.size:
            reward[reset_now] = 0.0
        obs = raw if (fast is not None and self._clean) else self._obs(raw, inplace=True)
        if self.autoreset == "next_step":
            if reset_now.size:
                self._replace_episodes(reset_now, obs)
                terminated[reset_now] = truncated[reset_now] = False
            if ended is None:
                if self._n_pending:
                    self._pending[:] = False
                    self._n_pending = 0
            else:
                self._pending = ended
                self._n_pending = int(ended.sum())
        elif self.autoreset == "same_step" and ended is not None:
            idx = np.flatnonzero(ended)
            info["final_obs"] = self._present(obs.copy())
            info["_final_obs"] = ended.copy()
            info["final_info"] = {k: v for k, v in info.items()
                                  if k not in ("final_obs", "_final_obs")}
            info["_final_info"] = ended.copy()
            self._replace_episodes(idx, obs)
        if self.autoreset == "next_step" and reset_now.size:
            self._briefings(reset_now, info)
        elif self.autoreset == "same_step" and ended is not None:
            self._briefings(np.flatnonzero(ended), info)
        return self._present(obs), reward, terminated, truncated, info

    def _fused_env_step(self, actions, groups):
        """The step of every sub-env (each pool's running episodes) with the actions
        written, the raw observations (non-finite values already 0 where ``_clean``) and
        the end flags (``ENV_*``) in one compiled call per pool; None (nothing done) where a
        pool's backend has no such call."""
        if len(groups) == 1:
            if getattr(groups[0][0].batch, "env_step", None) is None:
                return None
        elif not all(hasattr(g[0].batch, "env_step") for g in groups):
            return None
        a = self._checked_actions(actions)
        out = np.empty(self._obs_shape)
        for pool, _, _, lo, hi, rows in groups:
            if not pool.batch.env_step(EnvIO(a, out, self._flags, rows, self._normalized,
                                             self._clean), lo, hi):
                return None       # a kernel module without the fused step (every pool's)
        return out, self._flags

    def _step_groups(self, a: np.ndarray, groups):
        """The step of every pool's running episodes (``a`` velocities per sub-env): raw
        observations and the sub-envs whose episode ended at this step (None: none). The
        path of backends without a fused step (the scene backend's pools); the core
        backend's pools take :meth:`_fused_env_step`."""
        n = self.num_envs
        raw = np.empty((n, self.n_agents, self.obs_dim))
        was_done = np.empty(n, dtype=bool)
        done = np.empty(n, dtype=bool)
        for pool, js, eps, lo, hi, _ in groups:
            b = pool.batch
            st = b.LS.status
            was_done[js] = st[eps] == FINISHED
            b.set_actions(a[js], eps)
            raw[js] = _step_observe(b, lo, hi)[eps]
            done[js] = st[eps] == FINISHED
        ended = done & ~was_done
        return raw, (ended if ended.any() else None)

    def _replace_episodes(self, envs: np.ndarray, obs: np.ndarray) -> None:
        """Autoreset: give sub-envs ``envs`` their next episodes and write those episodes'
        first observations into ``obs``."""
        self._release(envs)
        self._draw(envs)
        fresh = self._raw_obs(envs)
        obs[envs] = self._obs(fresh, envs)
        self._start_rewards(envs, fresh)

    def render(self):
        """A top-down RGB view of sub-env 0: the current speed near the surface at the
        episode's time, land, the agents and their goal cues.

        Returns
        -------
        (H, W, 3) uint8 or None
            The image (:func:`oneocean.reporting.render.topdown_rgb`, north up); None unless
            ``render_mode="rgb_array"`` and the env was reset.
        """
        if self.render_mode != "rgb_array" or not self._pools:
            return None
        from .reporting.render import topdown_rgb

        b = self._owner[0].batch
        e = int(self._ep[0])
        raw = self._raw_obs(np.array([0]))[0]
        return topdown_rgb(self.cell.grid, b.state[e], raw[:, 0:3],
                           float(b.t0[e] + b.k[e] * self.dt))

    def close(self, **kwargs):
        """Drop the episode pools.

        Parameters
        ----------
        **kwargs
            Ignored (Gymnasium's signature).
        """
        self._pools, self._tail = [], None
        self._group_cache = None


def _row(obs, j: int, i: int | None = None):
    """Sub-env ``j``'s observation (agent ``i``'s, if given) of a vector env's observation:
    an array, or a dict (``obs_mode="dict"``: the agents' part indexed, the team's by
    sub-env)."""
    if isinstance(obs, dict):
        return {k: (v[j] if k != "agents" or i is None else v[j, i]) for k, v in obs.items()}
    return obs[j] if i is None else obs[j, i]


class OceanEnv(gym.Env):
    """Single-episode view of :class:`OceanVectorEnv` (``num_envs = 1``, autoreset
    disabled): observation (N, D), action (N, 3).

    Parameters
    ----------
    task : str
        Registered task id.
    tier : int
        Tier of the task's table.
    grid : Grid, mapping, path-like or None
        As :class:`OceanVectorEnv`.
    render_mode : str, optional
        None or ``rgb_array``.
    **kw
        As :class:`OceanVectorEnv` (``autoreset_mode`` is ignored).
    """

    metadata = {"render_modes": ["rgb_array"]}

    def __init__(self, task: str, tier: int, grid=None, *, render_mode: str | None = None,
                 **kw):
        kw.pop("autoreset_mode", None)
        self.venv = OceanVectorEnv(task, tier, grid, num_envs=1, autoreset_mode="disabled",
                                   render_mode=render_mode, **kw)
        self.render_mode = render_mode
        self.observation_space = self.venv.single_observation_space
        self.action_space = self.venv.single_action_space

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start a fresh episode: the cell's episode 0 of ``seed``.

        Parameters
        ----------
        seed : int, optional
            The cell's seed; None: drawn from the env's generator.
        options : dict, optional
            Unused.

        Returns
        -------
        obs : (N, D) float64
            The first observation.
        info : dict
            Empty.
        """
        super().reset(seed=seed)
        s = seed if seed is not None else int(self.np_random.integers(2**31))
        obs, info = self.venv.reset(seed=int(s))
        return _row(obs, 0), {"briefing": info["briefing"][0]}

    def step(self, action):
        """Advance the episode by one step.

        Parameters
        ----------
        action : (N, 3) array_like
            Each agent's action (as :meth:`OceanVectorEnv.step`).

        Returns
        -------
        obs : (N, D) float64
            The next observation.
        reward : float
            The step's reward.
        terminated : bool
            The episode ended by the task.
        truncated : bool
            The episode ended at the time limit.
        info : dict
            When the episode ended: the result columns and ``is_success``.
        """
        obs, r, term, trunc, info = self.venv.step(np.asarray(action)[None])
        one = {k: (v[0] if isinstance(v, np.ndarray) else v) for k, v in info.items()
               if not k.startswith("_")}
        if "is_success" in one:
            one["is_success"] = bool(one["is_success"])
        return _row(obs, 0), float(r[0]), bool(term[0]), bool(trunc[0]), one

    def render(self):
        """The vector env's :meth:`~OceanVectorEnv.render`.

        Returns
        -------
        (H, W, 3) uint8 or None
            The top-down view, or None unless ``render_mode="rgb_array"``.
        """
        return self.venv.render()


def parallel_env(task: str, tier: int, grid=None, **kw):
    """A PettingZoo ``ParallelEnv`` of one episode of a (multi-agent) task.

    Agents are ``vehicle_0 .. vehicle_{N-1}``, each with one agent's observation and a
    3-vector action (see the module docstring); an agent missing from a step's actions acts
    ``(0, 0, 0)``. Every agent gets the team's reward, end flags and result columns.

    Parameters
    ----------
    task : str
        Registered task id.
    tier : int
        Tier of the task's table.
    grid : Grid, mapping, path-like or None
        As :class:`OceanVectorEnv`.
    **kw
        As :class:`OceanVectorEnv`: the modes, the backend (``autoreset_mode`` is ignored).

    Returns
    -------
    ParallelEnv
        The env (requires ``pettingzoo``).
    """
    from pettingzoo import ParallelEnv

    class OceanParallelEnv(ParallelEnv):
        metadata = {"name": f"oneocean_{task.lower()}_t{int(tier)}",
                    "render_modes": ["rgb_array"]}

        def __init__(self):
            kw.pop("autoreset_mode", None)
            self.venv = OceanVectorEnv(task, tier, grid, num_envs=1, autoreset_mode="disabled",
                                       **kw)
            n = self.venv.n_agents
            self.possible_agents = [f"vehicle_{i}" for i in range(n)]
            self.agents = []
            self._obs_space = self.venv._obs_space(())
            self._act_space = self.venv._act_space(())
            self.render_mode = self.venv.render_mode

        def observation_space(self, agent):
            return self._obs_space

        def action_space(self, agent):
            return self._act_space

        def reset(self, seed=None, options=None):
            s = int(seed) if seed is not None else int(np.random.SeedSequence().entropy % 2**31)
            obs, info = self.venv.reset(seed=s)
            self.agents = list(self.possible_agents)
            return ({a: _row(obs, 0, i) for i, a in enumerate(self.agents)},
                    {a: {"briefing": info["briefing"][0]} for a in self.agents})

        def step(self, actions):
            n = len(self.possible_agents)
            a = np.zeros((1, n, len(ACT_FIELDS)))
            for i, name in enumerate(self.possible_agents):
                if name in actions:
                    a[0, i] = actions[name]
            obs, r, term, trunc, info = self.venv.step(a)
            metrics = {k: (bool(v[0]) if k == "is_success" else float(v[0]))
                       for k, v in info.items() if not k.startswith("_")}
            agents = list(self.agents)
            out = ({x: _row(obs, 0, self.possible_agents.index(x)) for x in agents},
                   {x: float(r[0]) for x in agents},
                   {x: bool(term[0]) for x in agents},
                   {x: bool(trunc[0]) for x in agents},
                   {x: dict(metrics) for x in agents})
            if term[0] or trunc[0]:
                self.agents = []
            return out

        def render(self):
            return self.venv.render()

        def close(self):
            self.venv.close()

    return OceanParallelEnv()
