"""The BC training set: the heuristic teacher's (observation, action) pairs.

For every (task, tier) and training seed, :func:`teacher_rows` runs the heuristic on the
cell's episodes of that seed with observations recorded *inside the loop* (the observation
of every agent from its true pre-step state, and the action the teacher requested there:
:func:`oneocean.tasks.common.observe`), never reconstructed from positions afterwards. Rows
are kept every ``stride`` steps while the episode runs; a cell with more than ``max_rows``
rows keeps an evenly spaced subset. Training seeds must differ from the evaluation seed
(:data:`oneocean.vocab.EVALUATION_SEED`; :func:`check_seeds`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...errors import ConfigError, NotApplicable
from ...tasks.common import ACT_FIELDS, OBS_FIELDS

#: Identifying columns of a dataset row, then OBS_FIELDS, ACT_FIELDS and ``v_max_ms``.
KEY_COLUMNS = ("task", "tier", "seed", "episode", "step", "agent")


def check_seeds(seeds, evaluation_seed: int) -> list[int]:
    """``seeds`` as ints; a one-line ``ConfigError`` if empty or if it holds the evaluation
    seed (a network must never be trained on the episodes it is scored on)."""
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ConfigError("bc.train_seeds: at least one training seed is needed")
    if int(evaluation_seed) in seeds:
        raise ConfigError(f"bc.train_seeds: {seeds} contains the evaluation seed "
                          f"{int(evaluation_seed)} (rollouts.seed); training seeds must be "
                          "disjoint from it")
    return seeds


def teacher_rows(cell, seed: int, episodes: int, dynamics: str, stride: int,
                 max_rows: int, info: str | None = None) -> pd.DataFrame:
    """The teacher's rows of one :class:`oneocean.tasks.Cell` and seed (columns
    :data:`KEY_COLUMNS` + OBS_FIELDS + ACT_FIELDS + ``v_max_ms``): what the heuristic saw
    through its sensors (``info``: another information level, for tests)."""
    _, obs, act = cell.run("heuristic", int(episodes), int(seed), dynamics, observations=True,
                           info=info)
    n_ep, n_steps, n_ag, _ = obs.shape
    e, k, i = np.meshgrid(np.arange(n_ep), np.arange(n_steps), np.arange(n_ag), indexing="ij")
    keep = (k % int(stride) == 0) & np.isfinite(act).all(axis=-1)
    idx = np.flatnonzero(keep.ravel())
    if idx.size > max_rows:
        idx = idx[np.linspace(0, idx.size - 1, int(max_rows)).round().astype(np.int64)]
    o = obs.reshape(-1, obs.shape[-1])[idx]
    a = act.reshape(-1, act.shape[-1])[idx]
    df = pd.DataFrame({"task": cell.task, "tier": np.int64(cell.tier),
                       "seed": np.int64(seed), "episode": e.ravel()[idx].astype(np.int64),
                       "step": k.ravel()[idx].astype(np.int64),
                       "agent": i.ravel()[idx].astype(np.int64)})
    for j, name in enumerate(OBS_FIELDS):
        df[name] = o[:, j]
    for j, name in enumerate(ACT_FIELDS):
        df[name] = a[:, j]
    df["v_max_ms"] = float(cell.vehicle.v_max)
    return df


def build_dataset(grid, tasks, tiers, seeds, *, episodes: int, dynamics: str, stride: int,
                  max_rows: int, evaluation_seed: int) -> tuple[pd.DataFrame, list[str]]:
    """Every (task, tier, seed)'s :func:`teacher_rows`, concatenated in that order; and the
    cells the region cannot host (one line each: they contribute no rows)."""
    from ...engine import load_grid
    from ...engine.grid import Grid
    from ...tasks import Cell

    seeds = check_seeds(seeds, evaluation_seed)
    grid = grid if isinstance(grid, Grid) else load_grid(grid)
    parts, skipped = [], []
    for task in tasks:
        for tier in tiers:
            cell = Cell(grid, task, int(tier))
            for seed in seeds:
                try:
                    parts.append(teacher_rows(cell, seed, episodes, dynamics, stride,
                                              max_rows))
                except NotApplicable as exc:
                    skipped.append(f"seed {seed}: {exc}")
    if not parts:
        raise ConfigError("bc dataset: no (task, tier) cell could be hosted: "
                          + "; ".join(skipped))
    return pd.concat(parts, ignore_index=True), skipped


def dataset_to_file(grid_path, out_path, tasks, tiers, seeds, *, episodes: int, dynamics: str,
                    stride: int, max_rows: int, evaluation_seed: int, threads: int = 1) -> dict:
    """:func:`build_dataset` on a grid export, written atomically as Parquet with its record
    (tasks, tiers, seeds, episodes, stride, skipped cells); returns the manifest entry."""
    import numba

    from ...engine import write_metrics

    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    df, skipped = build_dataset(grid_path, tasks, tiers, seeds, episodes=episodes,
                                dynamics=dynamics, stride=stride, max_rows=max_rows,
                                evaluation_seed=evaluation_seed)
    meta = {"stage": "bc_dataset", "tasks": list(tasks), "tiers": [int(t) for t in tiers],
            "seeds": [int(s) for s in seeds], "episodes": int(episodes), "stride": int(stride),
            "max_rows": int(max_rows), "dynamics": dynamics, "teacher": "heuristic",
            "skipped": skipped, "n_rows": int(len(df))}
    return write_metrics(df, out_path, meta=meta)
