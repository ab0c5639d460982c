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

from ..errors import ConfigError
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

    ``grid_reset`` carries the tier's forcing (``current_gain``); ``grid`` is what the
    rollout sees: the same, or with the current switched off (``currents=False``, tides
    dropped: the ablation). Episodes are always sampled on ``grid_reset``, so the ablation
    replays the same episodes (geometry, start times).
    """

    def __init__(self, grid, task: str, tier: int, *, n_agents: int | None = None,
                 currents: bool = True, vehicle=None):
        from ..engine import load_grid, load_vehicle
        from ..engine.grid import Grid, with_forcing

        self.task, self.tier = task, int(tier)
        self.mod = task_module(task)
        grid = grid if isinstance(grid, Grid) else load_grid(grid)
        params = tier_params(task, self.tier)
        self.params = {**params, "dt_s": float(load_task_table(task)["dt_s"])}
        self.n_agents = n_agents_for(task, n_agents)
        self.grid_reset = with_forcing(grid,
                                       current_gain=float(params.get("current_gain", 1.0)))
        self.grid = self.grid_reset if currents else self.grid_reset._replace(
            gain=0.0, tide_layers=0, tide_amp=0.0)
        self.currents = bool(currents)
        self.vehicle = vehicle if vehicle is not None else load_vehicle()

    def reset(self, episodes: int, seed: int) -> dict:
        """The task's episodes ``0 .. episodes-1`` of ``seed`` (its ``reset`` output)."""
        return self.mod.reset(self.grid_reset, self.params, self.n_agents, int(episodes),
                              int(seed))


def run_cell(grid, task: str, tier: int, method: str = "heuristic", episodes: int = 50,
             seed: int = 0, dynamics: str = "6dof", currents: bool = True,
             n_agents: int | None = None, vehicle=None, observations: bool = False):
    """Run ``episodes`` episodes of one (task, tier, method) cell on the one episode loop,
    batched in one kernel call (a fused method: the task's heuristic or oracle).

    Parameters
    ----------
    grid : Grid
        A loaded grid export (:func:`oneocean.engine.load_grid`); the tier's ``current_gain``
        is applied here (``currents=False`` sets it to 0 and drops tides in the rollout: the
        ablation; ``reset`` always sees the tier's forcing, so both replay the same episodes).
    observations : bool
        Also return every agent's per-step observation and action (for learning methods).

    Returns
    -------
    DataFrame, one row per episode: ``episode, seed, success, T_s, E, coll_ratio,
    violations, primary`` and the task's metric columns. With ``observations=True`` a tuple
    ``(df, obs, act)``: ``obs`` (E, n_steps, N, len(OBS_FIELDS)) and ``act``
    (E, n_steps, N, 3) float64 (:data:`oneocean.tasks.common.OBS_FIELDS`, ``ACT_FIELDS``),
    NaN after an episode ended.
    """
    cell = Cell(grid, task, tier, n_agents=n_agents, currents=currents, vehicle=vehicle)
    from ..registry import method_spec
    from .episodes import rollout

    method_spec(method)   # an unknown method is a one-line ConfigError
    mod, n = cell.mod, cell.n_agents
    init = cell.reset(episodes, seed)
    res = rollout(mod, cell.grid, cell.params, init, method, dynamics, cell.vehicle, int(seed),
                  record=observations)
    df = cell_frame(mod, res, tier, method, n, dynamics, currents, episodes, seed)
    if observations:
        return df, res["obs"], res["act"]
    return df


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


def rollout_to_file(grid_path, out_path, task: str, tier: int, method: str, episodes: int,
                    seed: int, dynamics: str, threads: int = 1, currents: bool = True) -> dict:
    """Run one cell on a grid export file and write its per-episode Parquet table atomically.

    Returns the manifest entry of :func:`oneocean.engine.write_metrics`.
    """
    import numba

    from ..engine import load_grid, load_vehicle, write_metrics

    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    grid = load_grid(grid_path)
    vehicle = load_vehicle()
    df = run_cell(grid, task, tier, method, episodes, seed, dynamics, currents=currents,
                  vehicle=vehicle)
    return write_metrics(df, out_path, meta={"dynamics": dynamics, "vehicle": vehicle.name,
                                             "tier_params": tier_params(task, int(tier))})
