"""The canonical 10-task ladder (G2G, SK, RF, DPT, AS, PI, FT, SPC, UPL, FH).

Each task is one module, the environment (see ``docs/tasks_design.md``; ``g2g.py`` is the
template): ``TASK_ID``, ``METRICS`` (``METRICS[0]`` is the primary metric), ``reset(...)``,
``make(...)`` and the hooks of the one episode loop (:mod:`.loop`); its tier table, with its
registry spec, is data in ``oneocean/data/tasks/<ID>.yaml``; its heuristic and oracle are in
:mod:`oneocean.methods.heuristic`. :func:`run_cell` runs one (task, tier, method) cell of
episodes on a grid export and returns one row per episode.
"""

from __future__ import annotations

import importlib

import numpy as np
import pandas as pd

from ..errors import ConfigError, NotApplicable
from .common import ACT_FIELDS, OBS_FIELDS, STANDARD, load_task_table, tier_params  # noqa: F401


def task_module(task_id: str):
    """The module implementing ``task_id`` (``oneocean.registry.task_spec(id).module``)."""
    from ..registry import task_spec

    return importlib.import_module(task_spec(task_id).module)


def n_agents_for(task_id: str, n_agents: int | None) -> int:
    """The team size: the table's default, or ``n_agents`` checked against its allowed range."""
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

    ``grid`` is what the rollout sees: the run's forcing (``current_gain`` g on the data u, v,
    default 1: the data as they are; an optional synthetic tide term ``tide``: the c_tide
    ablation; a tier's own ``current_gain``, if its table has one, multiplies g), or the
    current switched off (``currents=False``: g = 0, no tide layers, no synthetic tide).
    Episodes are always sampled on ``grid_reset``, the data as the tier defines them (no
    run forcing), so every forcing ablation replays the same episodes (geometry, start
    times, current regime).
    The vehicle is the task table's ``vehicle`` unless one is given; its speed limit reaches
    ``reset``/``make`` as ``params["v_max"]``.
    ``tier_overrides`` (``{key: value}``) replaces tier parameters of the task's tier table
    (keys of its ``harder`` block; an unknown key is a one-line ConfigError naming it): the
    stressor ablations, e.g. Tier 1 with one key at its Tier-3 value. ``tier_params`` is the
    tier's parameters with the overrides applied, ``tier_overrides`` the overrides alone.
    ``backend`` (:data:`oneocean.backends.protocol.BACKENDS`) says what moves the agents:
    ``core`` (the numba engine) or ``mujoco`` (MuJoCo rigid bodies in ``scene``, which it
    requires). With a ``scene`` (a :class:`oneocean.backends.mujoco.scenes.Scene`), on
    either backend, ``grid`` is the scene's local grid when None and the tier is the table's
    ``scene_tiers`` row over its core row (a task without one is not applicable in a scene).
    The scenario, judge and accounting are the same code on both backends
    (:mod:`oneocean.tasks.loop`).
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

    def reset(self, episodes: int, seed: int) -> dict:
        """The task's episodes of ``seed`` (its ``reset`` output, ``episodes`` rows).

        Without a ``current_band`` in the tier these are the task's candidates
        ``0 .. episodes-1``. With one, candidates are drawn in order and the first
        ``episodes`` whose episode current (:func:`~.common.site_speeds` at the candidate's
        ``regime_points``, else its start positions, over ``[t0, t0 + time_limit_s]``) lies in
        the tier's :class:`~.common.Regime` are kept; ``init["candidate"]`` records which.
        Either way a candidate is kept only where the product defines currents at those
        points. Candidate ``c`` is drawn from its own stream (``SeedSequence([seed, c,
        purpose])``), so it does not depend on how many are drawn.
        A task module may split its ``reset`` in two (SPC does): ``reset_candidates(grid,
        tier, n_agents, n, seed)`` (per candidate, what this check needs: ``t0`` and
        ``regime_points`` or ``pos0``, plus any arrays its build needs) and
        ``reset_build(grid, tier, n_agents, cand, seed)`` (the ``reset`` dict of the
        candidates ``cand``: the ``reset_candidates`` dict with every per-candidate array
        indexed by the kept candidates, ``cand["candidate"]`` their indices). Then the check
        runs first and only the kept candidates are built; the episodes are ``reset``'s bit
        for bit. Without the split every candidate is built by ``reset``, then checked.
        Raises :class:`~oneocean.errors.NotApplicable` (naming the cell) when the region
        cannot host it."""
        try:
            return self._reset(int(episodes), int(seed))
        except NotApplicable as exc:
            raise NotApplicable(f"{self.task} tier {self.tier}: {exc}") from None

    def _reset(self, episodes: int, seed: int) -> dict:
        from ..engine.grid import current_coverage
        from .common import site_speeds

        band = self.params.get("current_band")
        duration = float(self.params["time_limit_s"])
        n_cand = (episodes if band is None else
                  int(np.ceil(2.0 * episodes / max(float(band[1]) - float(band[0]), 0.05))))
        split = hasattr(self.mod, "reset_candidates") and hasattr(self.mod, "reset_build")
        draw = self.mod.reset_candidates if split else self.mod.reset
        regime = None
        for _ in range(REGIME_DRAWS):
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
        self.regime = regime
        out = {k: (v[keep] if isinstance(v, np.ndarray) and v.ndim and v.shape[0] == n_cand
                   else v) for k, v in init.items()}
        if split:
            out["candidate"] = keep.astype(np.int64)
            out = self.mod.reset_build(self.grid_reset, self.params, self.n_agents, out, seed)
        out.pop("regime_points", None)
        out["candidate"] = keep.astype(np.int64)
        return out

    def _regime(self, depth_m: float):
        """:func:`~.common.current_regime` of this cell's tier at ``depth_m`` on
        ``grid_reset``, computed once per (band, depth) and cell."""
        from .common import current_regime

        key = (repr(self.params.get("current_band")), float(depth_m))
        cache = self.__dict__.setdefault("_regimes", {})
        hit = cache.get(key)
        if hit is None or hit[0] is not self.grid_reset:
            hit = cache[key] = (self.grid_reset,
                                current_regime(self.grid_reset, self.params, depth_m))
        return hit[1]

    def episodes(self, init: dict, method: str | None, dynamics: str, seed: int, **kw):
        """The rollout (:class:`oneocean.backends.protocol.Rollout`) of the episodes ``init``
        (:meth:`reset`) on this cell's backend: ``method`` a fused method, ``bc`` (with
        ``net=``) or None for external actions; ``kw`` as
        :class:`~oneocean.tasks.episodes.Episodes` (``record``, ``net``, ``info``,
        ``fused_plan``)."""
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
            observations: bool = False, net: dict | None = None, info: str | None = None):
        """Sample ``episodes`` episodes of ``seed`` and run them with a fused ``method`` (or
        ``bc`` with its network ``net``; ``info``: what it knows instead of its sensors,
        :class:`~oneocean.tasks.episodes.Episodes`); the cell table (see :func:`run_cell`)."""
        from ..registry import method_spec

        method_spec(method)   # an unknown method is a one-line ConfigError
        init = self.reset(episodes, seed)
        res = self.episodes(init, method, dynamics, seed, record=observations, net=net,
                            info=info).run().results()
        df = cell_frame(self.mod, res, self.tier, method, self.n_agents, dynamics,
                        self.currents, episodes, seed)
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
    currents : bool
        False: the currents-off ablation (g = 0, no tides; the same episodes, :class:`Cell`).
    observations : bool
        Also return every agent's per-step observation and action (for learning methods).
    current_gain, tide
        The run's forcing (:class:`Cell`): g on the data u, v and the synthetic tide term.
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
    DataFrame, one row per episode: ``episode, seed, candidate, success, T_s, E, coll_ratio,
    violations, primary`` and the task's metric columns. With ``observations=True`` a tuple
    ``(df, obs, act)``: ``obs`` (E, n_steps, N, len(OBS_FIELDS)) and ``act``
    (E, n_steps, N, 3) float64 (:data:`oneocean.tasks.common.OBS_FIELDS`, ``ACT_FIELDS``),
    NaN after an episode ended.
    """
    return Cell(grid, task, tier, n_agents=n_agents, currents=currents, vehicle=vehicle,
                current_gain=current_gain, tide=tide,
                tier_overrides=tier_overrides).run(method, episodes, seed, dynamics,
                                                   observations, net, info)


def checked_tier_overrides(task: str, table: dict, overrides) -> dict:
    """``overrides`` as a plain dict after checking every key is a tier parameter of
    ``task``'s tier table (declared in its ``harder`` block); else a one-line ConfigError
    naming the key and the valid ones."""
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
               currents: bool, episodes: int, seed: int) -> pd.DataFrame:
    """The cell table (one row per episode) from a rollout's result columns ``res``: the
    same columns whether a fused method, a planner or a user's policy produced them."""
    task = mod.TASK_ID
    missing = [k for k in STANDARD + tuple(mod.METRICS) if k not in res]
    if missing:
        raise RuntimeError(f"task {task}: rollout did not return {missing}")
    df = pd.DataFrame({"task": task, "tier": np.full(episodes, int(tier), dtype=np.int64),
                       "method": method, "n_agents": np.full(episodes, n_agents, dtype=np.int64),
                       "dynamics": dynamics, "currents": bool(currents),
                       "episode": np.arange(episodes, dtype=np.int64),
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
    dtypes as :func:`cell_frame`; the reason travels in the file's record)."""
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
                    scene=None, physics_step_s: float | None = None) -> dict:
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
    Returns the manifest entry of :func:`oneocean.engine.write_metrics`.
    """
    import numba

    from ..engine import load_grid, write_metrics

    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    grid = load_grid(grid_path) if grid_path is not None else None
    where = {"backend": backend}
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
        df = cell.run(method, episodes, seed, dynamics, net=net, info=info)
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


def scene_record(scene) -> dict:
    """What a cell file records about the scene it ran in: name, kind and stand-in label,
    the frame mapping, the current source and the dataset clock (``start_s``: dataset time
    of scene time 0, s since the product's time0; ``rate``: dataset seconds per simulated
    second)."""
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
