"""The canonical 10-task ladder (G2G, SK, RF, DPT, AS, PI, FT, SPC, UPL, FH).

Each task is one module, the environment (see ``docs/tasks_design.md``; ``g2g.py`` is the
template): ``TASK_ID``, ``METRICS`` (``METRICS[0]`` is the primary metric), ``reset(...)``,
``make(...)`` and the hooks of the one episode loop (:mod:`.loop`); its tier table, with its
registry spec, is data in ``oneocean/data/tasks/<ID>.yaml``; its heuristic and oracle are in
:mod:`oneocean.methods.heuristic`. :func:`run_cell` runs one (task, tier, method) cell of
episodes on a grid export and returns one row per episode.

A task module's two scenario functions take the same arguments in every task (documented here
once; a task's docstring says what it samples and builds)::

    reset(grid, tier, n_agents, n_episodes, seed) -> init   the episodes' scenario (dict)
    make(grid, tier, init) -> (P, W)                         the params and work arrays

``grid``: the grid export (:class:`oneocean.engine.grid.Grid`; the ablations' forcing
included); ``tier``: the tier's parameters (its row of ``data/tasks/<ID>.yaml``) plus ``dt_s``;
``n_agents``: agents per episode N (single-agent tasks require 1); ``n_episodes``: episodes E;
``seed``: the run seed (each episode draws from its own reset stream); ``init``: the dict
``reset`` returned.
"""

from __future__ import annotations

import importlib
import math

import numpy as np
import pandas as pd

from ..errors import ConfigError, NotApplicable
from .common import ACT_FIELDS, OBS_FIELDS, STANDARD  # noqa: F401
from .tiers import load_task_table, tier_params  # noqa: F401


def task_module(task_id: str):
    """The module implementing a task.

    Parameters
    ----------
    task_id : str
        Registered task id.

    Returns
    -------
    module
        The module named by the task's spec (``oneocean.registry.task_spec(id).module``).

    Raises
    ------
    ConfigError
        If ``task_id`` is not registered.
    """
    from ..registry import task_spec

    return importlib.import_module(task_spec(task_id).module)


def n_agents_for(task_id: str, n_agents: int | None) -> int:
    """The team size: the table's default, or ``n_agents`` checked against its allowed range.

    Parameters
    ----------
    task_id : str
        Registered task id.
    n_agents : int or None
        Requested team size; None: the task table's ``agents.default``.

    Returns
    -------
    int
        The team size N.

    Raises
    ------
    ConfigError
        ``n_agents`` outside the table's ``agents.range``.
    """
    agents = load_task_table(task_id)["agents"]
    if n_agents is None:
        return int(agents["default"])
    lo, hi = agents["range"]
    if not lo <= n_agents <= hi:
        raise ConfigError(f"task {task_id}: n_agents={n_agents} outside its allowed range "
                          f"[{lo}, {hi}]")
    return int(n_agents)


class Cell:
    """One (task, tier) on one grid, ready to sample episodes and run them.

    The attribute ``grid`` is what the rollout sees: the run's forcing, or the current
    switched off. Episodes are always sampled on ``grid_reset``, the data as the tier defines
    them (no run forcing), so every forcing ablation replays the same episodes (geometry,
    start times, current regime). ``tier_params`` is the tier's parameters with the
    overrides applied, ``tier_overrides`` the overrides alone; ``params`` adds ``dt_s`` and
    the vehicle's speed limit ``v_max`` (m s-1), which reach the task's ``reset`` / ``make``.
    The scenario, judge and accounting are the same code on both backends
    (:mod:`oneocean.tasks.loop`).

    Parameters
    ----------
    grid : Grid, path-like or None
        The grid export (loaded with :func:`oneocean.engine.load_grid` unless a
        :class:`~oneocean.engine.grid.Grid`); None with a ``scene``: the scene's local grid.
    task : str
        Registered task id.
    tier : int
        Tier of the task's table.
    n_agents : int, optional
        Team size; default the table's (:func:`n_agents_for`).
    currents : bool
        False: the current switched off (g = 0, no tide layers, no synthetic tide).
    vehicle : Vehicle, optional
        The vehicle (:class:`oneocean.engine.dynamics.Vehicle`); default the task table's
        ``vehicle``.
    current_gain : float
        Gain g on the data currents u, v, dimensionless (default 1: the data as they are); a
        tier's own ``current_gain``, if its table has one, multiplies it.
    tide : None, mapping or (A, w, phi)
        Optional synthetic tide term (the c_tide ablation; :func:`oneocean.engine.load_grid`).
    tier_overrides : dict, optional
        ``{key: value}`` replacing tier parameters of the task's tier table (keys of its
        ``harder`` block): the stressor ablations, e.g. Tier 1 with one key at its Tier-3
        value.
    backend : str
        What moves the agents (:data:`oneocean.backends.protocol.BACKENDS`): ``core`` (the
        numba engine) or ``mujoco`` (MuJoCo rigid bodies in ``scene``, which it requires).
    scene : Scene, optional
        A :class:`oneocean.backends.mujoco.scenes.Scene`, on either backend: the tier is then
        the table's ``scene_tiers`` row over its core row (a task without one is not
        applicable in a scene).
    physics_step_s : float, optional
        The scene backend's MuJoCo step, s (default its own).

    Raises
    ------
    ConfigError
        Unknown task, tier, backend or tier override key, a team size outside the table's
        range, or a backend other than ``core`` without a scene.
    NotApplicable
        A scene for a task without ``scene_tiers``.
    """

    def __init__(self, grid, task: str, tier: int, *, n_agents: int | None = None,
                 currents: bool = True, vehicle=None, current_gain: float = 1.0, tide=None,
                 tier_overrides: dict | None = None, backend: str = "core", scene=None,
                 physics_step_s: float | None = None):
        from ..backends.protocol import check_backend
        from ..engine import load_grid, load_vehicle
        from ..engine.grid import Grid, with_forcing

        self.backend = check_backend(backend, "backend")
        if backend != "core" and scene is None:
            raise ConfigError(f"backend {backend!r} needs a scene")
        self.scene = scene
        self.physics_step_s = physics_step_s   # the scene backend's MuJoCo step, s
        if grid is None and scene is not None:
            grid = scene.grid_data
        self.task, self.tier = task, int(tier)
        self.mod = task_module(task)
        table = load_task_table(task)
        self.tier_overrides = checked_tier_overrides(task, table, tier_overrides)
        grid = grid if isinstance(grid, Grid) else load_grid(grid)
        self.vehicle = vehicle if vehicle is not None else load_vehicle(table.get("vehicle"))
        params = {**tier_params(task, self.tier, scene is not None), **self.tier_overrides}
        self.tier_params = params
        self.params = {**params, "dt_s": float(table["dt_s"]), "v_max": self.vehicle.v_max}
        self.n_agents = n_agents_for(task, n_agents)
        tier_gain = float(params.get("current_gain", 1.0))
        self.current_gain = float(current_gain) * tier_gain
        # episodes are drawn on the data as the tier defines them; the run's forcing
        # ablations (g, c_tide, currents off) replay exactly the same episodes
        self.grid_reset = with_forcing(grid, current_gain=tier_gain)
        forced = with_forcing(grid, current_gain=self.current_gain, tide=tide)
        self.grid = forced if currents else forced._replace(gain=0.0, tide_layers=0,
                                                            tide_amp=0.0)
        self.currents = bool(currents)
        self._regimes = {}     # (band, depth) -> (grid, regime): see _regime
        self._regime_sampler = None

    def reset(self, episodes: int, seed: int, shard: tuple[int, int] | None = None) -> dict:
        """The task's episodes of ``seed``: its ``reset`` output.

        Without a ``current_band`` in the tier these are the task's candidates
        ``0 .. episodes-1``. With one, candidates are drawn in order and the first
        ``episodes`` whose episode current (:func:`~.regime.site_speeds` at the candidate's
        ``regime_points``, else its start positions, over ``[t0, t0 + time_limit_s]``) lies in
        the tier's :class:`~.regime.Regime` are kept; ``init["candidate"]`` records which.
        Either way a candidate is kept only where the product defines currents at those
        points. Candidate ``c`` is drawn from its own stream (``SeedSequence([seed, c,
        purpose])``), so it does not depend on how many are drawn.
        A task module may split its ``reset`` in two (SPC and UPL do): ``reset_candidates(grid,
        tier, n_agents, n, seed)`` (per candidate, what this check needs: ``t0`` and
        ``regime_points`` or ``pos0``, plus any arrays its build needs) and
        ``reset_build(grid, tier, n_agents, cand, seed)`` (the ``reset`` dict of the
        candidates ``cand``: the ``reset_candidates`` dict with every per-candidate array
        indexed by the kept candidates, ``cand["candidate"]`` their indices). Then the check
        runs first and only the kept candidates are built; the episodes are ``reset``'s bit
        for bit. Without the split every candidate is built by ``reset``, then checked.

        Parameters
        ----------
        episodes : int
            Episodes of the cell.
        seed : int
            Run seed.
        shard : (int, int), optional
            ``(a, b)``: only the cell's episodes ``a .. b-1``, bit for bit those rows of the
            whole cell's (the check runs for all ``episodes``, the build for the shard).

        Returns
        -------
        dict
            The task's ``reset`` dict of the kept episodes (``episodes`` rows, or ``b - a``
            with a shard), without ``regime_points``, with ``candidate`` (int64) the
            candidate index of each.

        Raises
        ------
        NotApplicable
            The region cannot host the cell (naming it).
        ConfigError
            A bad ``shard`` (:func:`check_shard`).
        """
        rows = slice(None) if shard is None else slice(*check_shard(shard, episodes))
        try:
            return self._reset(int(episodes), int(seed), rows)
        except NotApplicable as exc:
            raise NotApplicable(f"{self.task} tier {self.tier}: {exc}") from None

    def _reset(self, episodes: int, seed: int, rows: slice = slice(None)) -> dict:
        from .spawn import episode_rows

        init, keep, n_cand, regime = self._check(episodes, seed)
        self.regime = regime
        # a task whose batch shares values across its episodes (cell_constants: PI's field
        # shape) computes them on the whole cell, so that a shard's rows equal the cell's
        constants = getattr(self.mod, "cell_constants", None)
        part = keep if constants is not None else keep[rows]
        out = episode_rows(init, part, n_cand)
        if hasattr(self.mod, "reset_candidates") and hasattr(self.mod, "reset_build"):
            out["candidate"] = part.astype(np.int64)
            out = self.mod.reset_build(self.grid_reset, self.params, self.n_agents, out, seed)
        if constants is not None:
            shared = constants(self.params, out)
            out = episode_rows(out, rows, part.size)
            out.update(shared)
        keep = keep[rows]
        out.pop("regime_points", None)
        out["candidate"] = keep.astype(np.int64)
        return out

    def _check(self, episodes: int, seed: int) -> tuple:
        """The candidates of ``seed`` and which of them are the cell's ``episodes``: the
        task's candidate dict (``reset_candidates``, else ``reset``), the kept candidates'
        indices, the number of candidates drawn and the tier's regime (None without a
        ``current_band``)."""
        from ..engine.grid import current_coverage
        from .regime import site_speeds

        band = self.params.get("current_band")
        duration = float(self.params["time_limit_s"])
        n_cand = (episodes if band is None else
                  int(np.ceil(2.0 * episodes / max(float(band[1]) - float(band[0]), 0.05))))
        from .spawn import route_guide

        # a scene with structures draws the routes on them (the scene's part of the scenario)
        guide = None
        if self.scene is not None:
            from ..backends.mujoco.scenes import route_guide as scene_guide
            guide = scene_guide(self.scene)
        split = hasattr(self.mod, "reset_candidates") and hasattr(self.mod, "reset_build")
        draw = self.mod.reset_candidates if split else self.mod.reset
        regime = None
        for _ in range(REGIME_DRAWS):
            with route_guide(guide):
                init = draw(self.grid_reset, self.params, self.n_agents, n_cand, seed)
            pts = np.asarray(init["regime_points"] if "regime_points" in init else
                             init["pos0"], dtype=np.float64)
            # episodes only where the product defines currents (never in water it does not
            # cover, where the engine's current is 0: docs/contracts.md §5)
            ok = (current_coverage(self.grid_reset, pts.reshape(-1, 3)) >= 1.0).reshape(
                n_cand, -1).all(axis=1)
            if band is not None:
                regime = self._regime(float(np.median(pts[..., 1])))
                speed = np.full(n_cand, np.nan)
                speed[ok] = site_speeds(self.grid_reset, pts[ok], init["t0"][ok], duration)
                ok &= (speed >= regime.lo) & (speed <= regime.hi)
            keep = np.flatnonzero(ok)[:episodes]
            if keep.size == episodes:
                break
            n_cand *= 2
        else:
            what = ("in water with currents" if regime is None else
                    f"in the tier's current regime (speed quantiles {band[0]:g}-{band[1]:g} of "
                    f"the region: {regime.lo:.2f}-{regime.hi:.2f} m/s)")
            raise NotApplicable(f"only {keep.size} of {n_cand} candidate episodes lie {what}; "
                                f"{episodes} needed")
        return init, keep, n_cand, regime

    def _regime(self, depth_m: float):
        """:func:`~.regime.current_regime` of this cell's tier at ``depth_m`` on
        ``grid_reset``, computed once per (band, depth) and cell (the cell's
        :class:`~.regime.RegimeSampler` keeps the grid levels' currents between depths)."""
        from .regime import RegimeSampler, current_regime

        key = (repr(self.params.get("current_band")), float(depth_m))
        hit = self._regimes.get(key)
        if hit is None or hit[0] is not self.grid_reset:
            if self._regime_sampler is None or self._regime_sampler.grid is not self.grid_reset:
                self._regime_sampler = RegimeSampler(self.grid_reset)
            hit = self._regimes[key] = (self.grid_reset,
                                        current_regime(self.grid_reset, self.params, depth_m,
                                                       self._regime_sampler))
        return hit[1]

    def episodes(self, init: dict, method: str | None, dynamics: str, seed: int, **kw):
        """The rollout of the episodes ``init`` on this cell's backend.

        Parameters
        ----------
        init : dict
            The episodes (:meth:`reset`).
        method : str or None
            A fused method, ``bc`` (with ``net=``) or None for external actions.
        dynamics : str
            Dynamics model name.
        seed : int
            Run seed.
        **kw
            As :class:`~oneocean.tasks.episodes.Episodes` (``record``, ``net``, ``info``,
            ``fused_plan``, ``e0``).

        Returns
        -------
        Rollout
            A :class:`oneocean.backends.protocol.Rollout`:
            :class:`~oneocean.tasks.episodes.Episodes` on the core backend, the scene
            backend's ``SceneEpisodes`` otherwise.
        """
        if self.backend == "core":
            from .episodes import Episodes

            return Episodes(self.mod, self.grid, self.params, init, method, dynamics,
                            self.vehicle, int(seed), **kw)
        from ..backends.mujoco.episodes import SceneEpisodes

        if self.physics_step_s is not None:
            kw.setdefault("physics_step_s", float(self.physics_step_s))
        return SceneEpisodes(self.mod, self.scene, self.grid, self.params, init, method,
                             dynamics, self.vehicle, int(seed), **kw)

    def run(self, method: str, episodes: int, seed: int, dynamics: str,
            observations: bool = False, net: dict | None = None, info: str | None = None,
            shard: tuple[int, int] | None = None, noise: float = 0.0, expert: bool = False):
        """Sample ``episodes`` episodes of ``seed`` and run them with a fused ``method`` (or
        ``bc`` with its network ``net``).

        Parameters
        ----------
        method : str
            A fused method (``heuristic``, ``oracle``) or a learned one (``bc``).
        episodes : int
            Episodes of the cell.
        seed : int
            Run seed.
        dynamics : str
            Dynamics model name.
        observations : bool
            Also return every agent's per-step observation and action.
        net : dict, optional
            A learned method's network (:func:`oneocean.tasks.learned.load_weights`).
        info : str, optional
            What the method knows instead of its sensors
            (:class:`~oneocean.tasks.episodes.Episodes`).
        shard : (int, int), optional
            ``(a, b)``: only the cell's episodes ``a .. b-1`` (rows ``episode`` a .. b-1),
            each bit for bit its row of the whole cell's table (:meth:`reset`; the episodes'
            random streams are keyed by the cell's episode, ``Episodes(e0=a)``).
        noise : float, optional
            A fused method's teacher noise (``Episodes(noise=...)``; default 0: none).
        expert : bool, optional
            A learned method with the heuristic as its shadow expert
            (``Episodes(expert=...)``; default False).

        Returns
        -------
        DataFrame or tuple
            The cell table (:func:`run_cell`); with ``observations`` ``(df, obs, act)``.

        Raises
        ------
        ConfigError
            Unknown method or bad ``shard``.
        NotApplicable
            The region cannot host the cell.
        """
        from ..registry import method_spec

        method_spec(method)   # an unknown method is a one-line ConfigError
        init = self.reset(episodes, seed, shard)
        e0 = 0 if shard is None else int(shard[0])
        n = int(init["candidate"].shape[0])
        res = self.episodes(init, method, dynamics, seed, record=observations, net=net,
                            info=info, e0=e0, noise=noise, expert=expert).run().results()
        df = cell_frame(self.mod, res, self.tier, method, self.n_agents, dynamics,
                        self.currents, n, seed, e0=e0)
        df.insert(df.columns.get_loc("seed") + 1, "candidate", init["candidate"])
        if observations:
            return df, res["obs"], res["act"]
        return df


#: Candidate draws (each twice the last) before a tier's current regime is declared not
#: applicable in a region.
REGIME_DRAWS = 3


def run_cell(grid, task: str, tier: int, method: str = "heuristic", episodes: int = 50,
             seed: int = 0, dynamics: str = "6dof", currents: bool = True,
             n_agents: int | None = None, vehicle=None, observations: bool = False,
             current_gain: float = 1.0, tide=None, net: dict | None = None,
             info: str | None = None, tier_overrides: dict | None = None):
    """Run ``episodes`` episodes of one (task, tier, method) cell on the one episode loop,
    batched in one kernel call (a fused method: the task's heuristic or oracle).

    Parameters
    ----------
    grid : Grid
        A loaded grid export (:func:`oneocean.engine.load_grid`).
    task : str
        Registered task id.
    tier : int
        Tier of the task's table.
    method : str
        A fused method (``heuristic``, ``oracle``) or ``bc`` with ``net``.
    episodes : int
        Episodes of the cell.
    seed : int
        Run seed.
    dynamics : str
        Dynamics model name (``kinematic``, ``3dof``, ``4dof``, ``6dof``).
    currents : bool
        False: the currents-off ablation (g = 0, no tides; the same episodes, :class:`Cell`).
    n_agents : int, optional
        Team size; default the task table's.
    vehicle : Vehicle, optional
        The vehicle; default the task table's.
    observations : bool
        Also return every agent's per-step observation and action (for learning methods).
    current_gain : float
        The run's gain g on the data u, v (:class:`Cell`), dimensionless.
    tide : None, mapping or (A, w, phi)
        The run's synthetic tide term (:class:`Cell`).
    net : dict
        Method ``bc`` only: the trained network (:func:`oneocean.tasks.learned.load_weights`).
    info : str
        What the method knows instead of its sensors (:data:`oneocean.sensing.INFO_LEVELS`;
        default: the method's own): the information ablations ``true_current`` and
        ``true_position`` of a non-oracle method.
    tier_overrides : dict
        Tier parameters to replace (:class:`Cell`): ``{key: value}``, keys of the task's tier
        table; an unknown key is a one-line ConfigError.

    Returns
    -------
    df : DataFrame
        One row per episode (:func:`cell_frame`): ``task, tier, method, n_agents, dynamics,
        currents, episode, seed, candidate``, the standard metrics ``success, T_s, E,
        coll_ratio, violations, current_speed_ms``, ``primary`` and the task's metric columns.
    obs : (E, n_steps, N, OBS_DIM) float64
        With ``observations=True`` only (then a tuple ``(df, obs, act)``): every agent's
        observations (:data:`oneocean.tasks.common.OBS_FIELDS`), NaN after an episode ended.
    act : (E, n_steps, N, 3) float64
        With ``observations=True`` only: the actions (``ACT_FIELDS``), m s-1, NaN after an
        episode ended.

    Raises
    ------
    ConfigError
        Unknown task, method, tier override key or information level, a bad team size.
    NotApplicable
        The region cannot host the cell.
    """
    return Cell(grid, task, tier, n_agents=n_agents, currents=currents, vehicle=vehicle,
                current_gain=current_gain, tide=tide,
                tier_overrides=tier_overrides).run(method, episodes, seed, dynamics,
                                                   observations, net, info)


def checked_tier_overrides(task: str, table: dict, overrides) -> dict:
    """``overrides`` as a plain dict after checking every key is a tier parameter of
    ``task``'s tier table (declared in its ``harder`` block).

    Parameters
    ----------
    task : str
        Task id (for the message).
    table : dict
        The task's tier table (:func:`~oneocean.tasks.tiers.load_task_table`).
    overrides : dict or None
        ``{key: value}`` tier parameters to replace.

    Returns
    -------
    dict
        The overrides (empty for None).

    Raises
    ------
    ConfigError
        ``overrides`` not a mapping, or a key not in the ``harder`` block (one line naming
        it and the valid ones).
    """
    if overrides is None:
        return {}
    if not isinstance(overrides, dict):
        raise ConfigError(f"task {task}: tier_overrides must be a mapping of tier parameters "
                          f"to values, got {type(overrides).__name__}")
    valid = list(table["harder"])
    for key in overrides:
        if key not in valid:
            raise ConfigError(f"task {task}: unknown tier parameter {key!r} in tier_overrides; "
                              f"valid: {', '.join(valid)}")
    return dict(overrides)


def cell_frame(mod, res: dict, tier: int, method: str, n_agents: int, dynamics: str,
               currents: bool, episodes: int, seed: int, e0: int = 0) -> pd.DataFrame:
    """The cell table (one row per episode) from a rollout's result columns ``res``: the
    same columns whether a fused method, a planner or a user's policy produced them.

    Parameters
    ----------
    mod : module
        The task module (``TASK_ID``, ``METRICS``).
    res : dict
        One (E,) array per column of ``STANDARD`` and the task's ``METRICS``
        (:meth:`~oneocean.tasks.episodes.Episodes.results`).
    tier : int
        Tier.
    method : str
        Method name.
    n_agents : int
        Team size N.
    dynamics : str
        Dynamics model name.
    currents : bool
        Whether the current was on.
    episodes : int
        Rows E.
    seed : int
        Run seed.
    e0 : int
        The cell's episode of the first row: rows are numbered ``e0 .. e0 + episodes - 1``
        (a shard of a cell).

    Returns
    -------
    DataFrame
        Columns ``task, tier, method, n_agents, dynamics, currents, episode, seed``, the
        standard metrics, ``primary`` (the task's ``METRICS[0]``) and the task's metrics;
        ``attrs`` records the cell.

    Raises
    ------
    RuntimeError
        ``res`` lacks a column.
    """
    task = mod.TASK_ID
    missing = [k for k in STANDARD + tuple(mod.METRICS) if k not in res]
    if missing:
        raise RuntimeError(f"task {task}: rollout did not return {missing}")
    df = pd.DataFrame({"task": task, "tier": np.full(episodes, int(tier), dtype=np.int64),
                       "method": method, "n_agents": np.full(episodes, n_agents, dtype=np.int64),
                       "dynamics": dynamics, "currents": bool(currents),
                       "episode": np.arange(e0, e0 + episodes, dtype=np.int64),
                       "seed": np.full(episodes, seed, dtype=np.int64)})
    for k in STANDARD:
        df[k] = res[k]
    df["primary"] = res[mod.METRICS[0]]
    for k in mod.METRICS:
        df[k] = res[k]
    df.attrs.update(task=task, tier=int(tier), method=method, n_agents=n_agents,
                    dynamics=dynamics, currents=bool(currents), primary=mod.METRICS[0])
    return df


def na_frame(mod, tier: int, method: str, n_agents: int, dynamics: str,
             currents: bool, seed: int) -> pd.DataFrame:
    """The zero-episode cell table of a cell the region cannot host (same columns and
    dtypes as :func:`cell_frame`, with ``candidate``; the reason travels in the file's
    record).

    Parameters
    ----------
    mod : module
        The task module.
    tier : int
        Tier.
    method : str
        Method name.
    n_agents : int
        Team size N.
    dynamics : str
        Dynamics model name.
    currents : bool
        Whether the current was on.
    seed : int
        Run seed.

    Returns
    -------
    DataFrame
        The empty cell table.
    """
    res = {k: np.zeros(0, dtype=bool if k == "success" else np.float64)
           for k in STANDARD + tuple(mod.METRICS)}
    res["violations"] = np.zeros(0, dtype=np.int64)
    df = cell_frame(mod, res, tier, method, n_agents, dynamics, currents, 0, seed)
    df.insert(df.columns.get_loc("seed") + 1, "candidate", np.zeros(0, dtype=np.int64))
    return df


def rollout_to_file(grid_path, out_path, task: str, tier: int, method: str, episodes: int,
                    seed: int, dynamics: str, threads: int = 1, currents: bool = True,
                    current_gain: float = 1.0, tide=None, weights=None,
                    n_agents: int | None = None, info: str | None = None,
                    tier_overrides: dict | None = None, backend: str = "core",
                    scene=None, physics_step_s: float | None = None,
                    shard: tuple[int, int] | None = None) -> dict:
    """Run one cell on a grid export file and write its per-episode Parquet table atomically.

    The file records its configuration (``oneocean.engine.recording.read_metrics_meta``):
    tier parameters (with ``tier_overrides`` applied), vehicle, dynamics, seed, forcing, and
    ``applicable``; an ablation cell also records ``info`` (an information level given
    instead of the method's own sensing, :func:`run_cell`) and ``tier_overrides`` (the tier
    parameters it replaced), so that tables never pool it with the normal cell. A cell the
    region cannot host (:class:`~oneocean.errors.NotApplicable`) is written with zero episodes,
    ``applicable: false`` and the one-line ``reason``; it is never a crash. So is a cell whose
    ``tier_overrides`` the task cannot build with the tier's other parameters (its ``reset``
    or ``make`` rejects the combination, e.g. more leaks than a shorter pipeline holds): it
    also records ``tier_conflict: true``.
    ``weights``: method ``bc``'s weights file (:mod:`oneocean.methods.bc`), recorded by hash.
    ``backend``, ``scene``: the execution backend and the scene (:class:`Cell`; with a scene,
    ``grid_path`` may be None: the scene's own grid); the file records the backend, the scene
    and its metadata (frames, dataset clock, current source). A task that does not run in a
    scene is written as a not-applicable cell.
    ``shard = (a, b)``: only the cell's episodes ``a .. b-1`` (:meth:`Cell.run`); the file
    records ``shard: [a, b]`` beside the whole cell's record, and :func:`merge_shards`
    writes the shards of a cell as the whole cell's file, byte for byte.

    Parameters
    ----------
    grid_path : path-like or None
        The grid export file; None with a ``scene``: the scene's own grid.
    out_path : path-like
        The Parquet file written.
    task : str
        Registered task id.
    tier : int
        Tier.
    method : str
        Method name (a fused method, or ``bc`` with ``weights``).
    episodes : int
        Episodes of the cell.
    seed : int
        Run seed.
    dynamics : str
        Dynamics model name.
    threads : int
        numba threads (clipped to ``[1, NUMBA_NUM_THREADS]``).
    currents : bool
        False: the currents-off ablation.
    current_gain : float
        The run's gain g on the data currents, dimensionless.
    tide : None, mapping or (A, w, phi)
        The run's synthetic tide term.
    weights : path-like, optional
        Method ``bc``'s weights file (:mod:`oneocean.methods.bc`), recorded by hash.
    n_agents : int, optional
        Team size; default the task table's.
    info : str, optional
        An information level given instead of the method's own sensing
        (:data:`oneocean.sensing.INFO_LEVELS`).
    tier_overrides : dict, optional
        Tier parameters to replace (:class:`Cell`).
    backend : str
        The execution backend (:class:`Cell`).
    scene : Scene, optional
        The scene (:class:`Cell`).
    physics_step_s : float, optional
        The scene backend's MuJoCo step, s (recorded; default its own).
    shard : (int, int), optional
        ``(a, b)``: only the cell's episodes ``a .. b-1``.

    Returns
    -------
    dict
        The manifest entry of :func:`oneocean.engine.write_metrics`.

    Raises
    ------
    ConfigError
        A bad cell (:class:`Cell`), an unknown method or information level, ``bc`` without
        ``weights``, a bad ``shard``, or a configuration error of the run without
        ``tier_overrides``.
    """
    import numba

    from ..engine import load_grid, write_metrics

    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    grid = load_grid(grid_path) if grid_path is not None else None
    where = {"backend": backend}
    if shard is not None:
        where["shard"] = list(check_shard(shard, episodes))
    if scene is not None:
        where.update(scene=scene.name, scene_meta=scene_record(scene))
    if backend == "mujoco":
        from ..backends.mujoco.episodes import PHYSICS_STEP_S

        where["physics_step_s"] = float(physics_step_s or PHYSICS_STEP_S)
    try:
        cell = Cell(grid, task, tier, currents=currents, current_gain=current_gain, tide=tide,
                    n_agents=n_agents, tier_overrides=tier_overrides, backend=backend,
                    scene=scene, physics_step_s=physics_step_s)
    except NotApplicable as exc:
        mod = task_module(task)
        n = n_agents_for(task, n_agents)
        df = na_frame(mod, tier, method, n, dynamics, currents, seed)
        return write_metrics(df, out_path, meta={
            "task": task, "tier": int(tier), "method": method, "dynamics": dynamics,
            "n_agents": n, "episodes": int(episodes), "seed": int(seed), **where,
            "applicable": False, "reason": str(exc)})
    meta = {"task": task, "tier": int(tier), "method": method, "dynamics": dynamics,
            "vehicle": cell.vehicle.name, "v_max_ms": cell.vehicle.v_max,
            "n_agents": cell.n_agents, "episodes": int(episodes), "seed": int(seed),
            "current_gain": cell.current_gain, "tide": tide, "currents": bool(currents),
            "tier_params": cell.tier_params, "applicable": True, "reason": "", **where}
    if info is not None:
        meta["info"] = str(info)
    if cell.tier_overrides:
        meta["tier_overrides"] = cell.tier_overrides
    net = None
    if weights is not None:
        from ..io import sha256_file
        from .learned import load_weights

        net = load_weights(weights)
        meta["weights_sha256"] = sha256_file(weights)
    # what could be refused for other reasons than the overrides, checked before the run
    from ..registry import method_spec
    from ..sensing import INFO_LEVELS
    from .episodes import learned_method

    method_spec(method)
    if info is not None and info not in INFO_LEVELS:
        raise ConfigError(f"unknown information level {info!r}; valid: "
                          f"{', '.join(INFO_LEVELS)}")
    if learned_method(method) and net is None:
        raise ConfigError(f"task {task}: method {method!r} needs its trained weights")
    try:
        df = cell.run(method, episodes, seed, dynamics, net=net, info=info, shard=shard)
    except NotApplicable as exc:
        df = na_frame(cell.mod, tier, method, cell.n_agents, dynamics, currents, seed)
        meta.update(applicable=False, reason=str(exc))
    except ConfigError as exc:
        if not cell.tier_overrides:
            raise
        df = na_frame(cell.mod, tier, method, cell.n_agents, dynamics, currents, seed)
        what = ", ".join(f"{k} = {v}" for k, v in cell.tier_overrides.items())
        meta.update(applicable=False, tier_conflict=True,
                    reason=f"{task} tier {int(tier)} with {what}: {exc}")
    return write_metrics(df, out_path, meta=meta)


def check_shard(shard, episodes: int) -> tuple[int, int]:
    """``shard`` as ``(a, b)``, the cell's episodes ``a .. b-1``, after checking
    ``0 <= a < b <= episodes``.

    Parameters
    ----------
    shard : pair of int
        ``(first, end)`` episodes.
    episodes : int
        Episodes of the cell.

    Returns
    -------
    (int, int)
        ``(a, b)``.

    Raises
    ------
    ConfigError
        Not a pair of integers, or not a range within ``[0, episodes)`` (one line naming it).
    """
    try:
        a, b = (int(x) for x in shard)
    except (TypeError, ValueError):
        raise ConfigError(f"shard must be a pair (first, end) of episodes, got {shard!r}") from None
    if not 0 <= a < b <= int(episodes):
        raise ConfigError(f"shard {[a, b]} is not a range of episodes within [0, {int(episodes)})")
    return a, b


def shard_ranges(episodes: int, per_shard: int | None) -> list[tuple[int, int]]:
    """The episode ranges of a cell run in shards.

    Parameters
    ----------
    episodes : int
        Episodes of the cell.
    per_shard : int or None
        Episodes per shard (``rollouts.shard_episodes``); None: no sharding.

    Returns
    -------
    list of (int, int)
        ``[(a, b), ...]`` tiling ``0 .. episodes-1`` (the last may be shorter); one range,
        the whole cell, when ``per_shard`` is None or not smaller than ``episodes``.

    Raises
    ------
    ConfigError
        ``per_shard`` below 1.
    """
    n = int(episodes)
    if per_shard is None:
        return [(0, n)]
    k = int(per_shard)
    if k < 1:
        raise ConfigError(f"rollouts.shard_episodes must be at least 1, got {per_shard!r}")
    return [(a, min(a + k, n)) for a in range(0, max(n, 1), k)]


def shard_episodes_for(minutes: float, seconds_per_episode: float, n_cells: int) -> int:
    """Episodes per shard so that a shard job of ``n_cells`` cells stays within ``minutes``.

    Parameters
    ----------
    minutes : float
        The runtime budget of one shard job (``rollouts.shard_minutes``), min.
    seconds_per_episode : float
        Measured cost of one episode of one cell of the task, s (the workflow's
        ``workflow/resources/rollout_seconds.yaml``).
    n_cells : int
        Cells a shard job runs (every non-learned cell of the task).

    Returns
    -------
    int
        ``floor(60 * minutes / (n_cells * seconds_per_episode))``, at least 1.
    """
    if not minutes > 0:
        raise ConfigError(f"rollouts.shard_minutes must be positive, got {minutes!r}")
    cost = max(float(seconds_per_episode), 1e-9) * max(int(n_cells), 1)
    return max(1, int(math.floor(60.0 * float(minutes) / cost)))


def merge_shards(shard_paths, out_path) -> dict:
    """Write the cell file ``out_path`` from the files of its shards (:func:`rollout_to_file`
    with ``shard``), the same bytes as the whole cell's file: their rows in episode order and
    their common record without ``shard``.

    Parameters
    ----------
    shard_paths : iterable of path-like
        The shard files, in any order.
    out_path : path-like
        The cell file written.

    Returns
    -------
    dict
        The manifest entry of :func:`oneocean.engine.write_metrics`.

    Raises
    ------
    ConfigError
        No shards, a file that is not a shard, shards of different cells (records differ
        but for ``shard``) or shards that do not tile the cell's episodes
        ``0 .. episodes-1`` (one line naming the file).
    """
    import pyarrow.parquet as pq

    from ..engine import read_metrics_meta, write_metrics

    parts = []
    for path in shard_paths:
        meta = read_metrics_meta(path)
        if "shard" not in meta:
            raise ConfigError(f"{path}: not a shard of a cell (its record has no shard)")
        parts.append((tuple(meta.pop("shard")), meta, path))
    if not parts:
        raise ConfigError(f"{out_path}: no shards to merge")
    parts.sort(key=lambda p: p[0])
    meta, end = parts[0][1], 0
    for (a, b), m, path in parts:
        if m != meta:
            raise ConfigError(f"{path}: a shard of another cell than {parts[0][2]} (records differ)")
        if a != end:
            raise ConfigError(f"{path}: shard [{a}, {b}) does not start at episode {end}")
        end = b
    if end != int(meta["episodes"]):
        raise ConfigError(f"{parts[-1][2]}: shards end at episode {end}, the cell has "
                          f"{meta['episodes']}")
    frames = [pq.read_table(path).to_pandas() for _, _, path in parts]
    df = pd.concat(frames, ignore_index=True) if len(frames) > 1 else frames[0]
    df.attrs = dict(frames[0].attrs)
    return write_metrics(df, out_path, meta=meta)


def scene_record(scene) -> dict:
    """What a cell file records about the scene it ran in.

    Parameters
    ----------
    scene : Scene
        The scene (:class:`oneocean.backends.mujoco.scenes.Scene`).

    Returns
    -------
    dict
        ``name``, ``kind`` and stand-in ``label``; ``frames``, the frame mapping; the current
        source ``currents``; the dataset ``clock`` (``start_s``: dataset time of scene time
        0, s since the product's time0; ``rate``: dataset seconds per simulated second); the
        ``anchor`` (lat, lon), degrees.
    """
    return {"name": scene.name, "kind": scene.kind, "label": scene.label,
            "frames": "core: x east, y down, z north; MuJoCo: x east, y north, z up",
            "currents": scene.currents,
            "clock": {"start_s": float(scene.clock[0]), "rate": float(scene.clock[1])},
            "anchor": [float(a) for a in scene.anchor]}


def compile_kernel(grid_path, out_path, task: str, tiers, dynamics: str) -> dict:
    """Compile ``task``'s episode kernel into numba's on-disk cache, once, before its cells run.

    Runs one episode of every tier in ``tiers`` with the heuristic on the grid export
    ``grid_path`` (the cells' own grid, so the argument types are exactly the cells'); a tier
    the region cannot host is noted, never an error. Every later process that runs the task
    (its rollout cells, the BC dataset, the planning cells) loads the kernel from the cache
    instead of compiling it again, so a cold run compiles each task kernel once rather than
    once per concurrently starting job. Writes (atomically) and returns the kernel record
    ``{task, dynamics, numba, tiers, not_applicable}``; no timings, so the record's bytes
    depend only on the configuration.

    Parameters
    ----------
    grid_path : path-like
        The grid export file.
    out_path : path-like
        The JSON kernel record written.
    task : str
        Registered task id.
    tiers : iterable of int
        Tiers to run one episode of.
    dynamics : str
        Dynamics model name.

    Returns
    -------
    dict
        The kernel record: ``tiers`` the tiers run, ``not_applicable`` ``{tier: reason}``.
    """
    import numba

    from ..engine import load_grid
    from ..io import write_json_atomic

    grid = load_grid(grid_path)
    done, na = [], {}
    for tier in tiers:
        try:
            Cell(grid, task, int(tier)).run("heuristic", 1, 0, dynamics)
            done.append(int(tier))
        except NotApplicable as exc:
            na[str(int(tier))] = str(exc)
    rec = {"task": task, "dynamics": dynamics, "numba": numba.__version__, "tiers": done,
           "not_applicable": na}
    write_json_atomic(out_path, rec)
    return rec
