"""The BC training set: the heuristic teacher's (observation, action) pairs.

For every (task, tier) and training seed, :func:`teacher_rows` runs the heuristic on the
cell's episodes of that seed with observations recorded *inside the loop* (the public
observation every agent got at the step's start -- :data:`oneocean.tasks.common.OBS_FIELDS`
then the task's own fields, as ``extra1 ..`` -- and the action the teacher requested there),
never reconstructed from positions afterwards; ``t_lim_s`` is the briefing's time limit. Rows
are kept every ``stride`` steps while the episode runs; a cell with more than ``max_rows``
rows keeps an evenly spaced subset. Training seeds must differ from the evaluation seed
(:data:`oneocean.vocab.EVALUATION_SEED`; :func:`check_seeds`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...errors import ConfigError, NotApplicable
from ...tasks.common import ACT_FIELDS, OBS_DIM, OBS_FIELDS
from ...tasks.learned import N_EXTRA

#: The dataset's columns of the task's own observation fields (NaN after the task's last).
EXTRA_FIELDS = tuple(f"extra{j + 1}" for j in range(N_EXTRA))

#: Identifying columns of a dataset row, then OBS_FIELDS, EXTRA_FIELDS, ACT_FIELDS,
#: ``v_max_ms`` and ``t_lim_s``.
KEY_COLUMNS = ("task", "tier", "seed", "episode", "step", "agent")


def check_seeds(seeds, evaluation_seed: int) -> list[int]:
    """The training seeds, checked against the evaluation seed.

    A network must never be trained on the episodes it is scored on.

    Parameters
    ----------
    seeds : iterable of int
        Training seeds (``bc.train_seeds``).
    evaluation_seed : int
        The evaluation seed (``rollouts.seed``; :data:`oneocean.vocab.EVALUATION_SEED`).

    Returns
    -------
    list of int
        ``seeds`` as ints.

    Raises
    ------
    ConfigError
        One line, if ``seeds`` is empty or holds the evaluation seed.
    """
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ConfigError("bc.train_seeds: at least one training seed is needed")
    if int(evaluation_seed) in seeds:
        raise ConfigError(f"bc.train_seeds: {seeds} contains the evaluation seed "
                          f"{int(evaluation_seed)} (rollouts.seed); training seeds must be "
                          "disjoint from it")
    return seeds


def teacher_rows(cell, seed: int, episodes: int, dynamics: str, stride: int,
                 max_rows: int, info: str | None = None, noise: float = 0.0) -> pd.DataFrame:
    """The teacher's rows of one cell and seed: what the heuristic saw through its sensors.

    Runs the heuristic on the cell's ``episodes`` episodes of ``seed`` with the observations
    recorded inside the loop; keeps every ``stride``-th step of every agent while its episode
    runs (finite action), at most ``max_rows`` rows (an evenly spaced subset).

    Parameters
    ----------
    cell : Cell
        The (task, tier) cell (:class:`oneocean.tasks.Cell`).
    seed : int
        Training seed of the episodes.
    episodes : int
        Episodes of the cell.
    dynamics : str
        Dynamics model (:data:`oneocean.vocab.DYNAMICS`: ``"kinematic"``, ``"3dof"``,
        ``"4dof"``, ``"6dof"``).
    stride : int
        Keep the steps ``k`` with ``k % stride == 0``.
    max_rows : int
        Most rows kept.
    info : str, optional
        Another information level than the heuristic's sensors (for tests;
        :class:`~oneocean.tasks.episodes.Episodes`).
    noise : float, optional
        The teacher's execution noise in units of ``v_max`` (DART: the executed action is
        disturbed, the recorded one is the teacher's; the demonstrations then show how it
        recovers from the errors a clone makes; default 0: none).

    Returns
    -------
    DataFrame
        Columns :data:`KEY_COLUMNS`, the observation fields
        (:data:`oneocean.tasks.common.OBS_FIELDS`), the teacher's action
        (:data:`~oneocean.tasks.common.ACT_FIELDS`, world m s-1 through the water) and the
        vehicle's ``v_max_ms`` (m s-1).

    Raises
    ------
    NotApplicable
        If the region cannot host the cell (:meth:`oneocean.tasks.Cell.reset`).
    """
    _, obs, act = cell.run("heuristic", int(episodes), int(seed), dynamics, observations=True,
                           info=info, noise=float(noise))
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
    for j, name in enumerate(EXTRA_FIELDS):
        df[name] = o[:, OBS_DIM + j] if OBS_DIM + j < o.shape[1] else np.nan
    for j, name in enumerate(ACT_FIELDS):
        df[name] = a[:, j]
    df["v_max_ms"] = float(cell.vehicle.v_max)
    df["t_lim_s"] = float(cell.params["time_limit_s"])
    return df


def build_dataset(grid, tasks, tiers, seeds, *, episodes: int, dynamics: str, stride: int,
                  max_rows: int, evaluation_seed: int,
                  noise: float = 0.0) -> tuple[pd.DataFrame, list[str]]:
    """Every (task, tier, seed)'s :func:`teacher_rows`, concatenated in that order.

    Parameters
    ----------
    grid : Grid or path
        The grid export (:class:`oneocean.engine.grid.Grid`) or its file.
    tasks : iterable of str
        Task ids.
    tiers : iterable of int
        Tiers.
    seeds : iterable of int
        Training seeds (:func:`check_seeds`).
    episodes : int
        Episodes per cell and seed.
    dynamics : str
        Dynamics model (:data:`oneocean.vocab.DYNAMICS`).
    stride : int
        Step stride of the kept rows.
    max_rows : int
        Most rows per cell and seed.
    evaluation_seed : int
        The evaluation seed, which ``seeds`` must not hold.
    noise : float, optional
        The teacher's execution noise (:func:`teacher_rows`; default 0: none).

    Returns
    -------
    df : DataFrame
        The rows (:func:`teacher_rows`), with a fresh index.
    skipped : list of str
        One line per (cell, seed) the region cannot host (no rows from it).

    Raises
    ------
    ConfigError
        Bad seeds (:func:`check_seeds`), or no cell could be hosted.
    """
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
                                              max_rows, noise=noise))
                except NotApplicable as exc:
                    skipped.append(f"seed {seed}: {exc}")
    if not parts:
        raise ConfigError("bc dataset: no (task, tier) cell could be hosted: "
                          + "; ".join(skipped))
    return pd.concat(parts, ignore_index=True), skipped


def dataset_to_file(grid_path, out_path, tasks, tiers, seeds, *, episodes: int, dynamics: str,
                    stride: int, max_rows: int, evaluation_seed: int, noise: float = 0.0,
                    threads: int = 1) -> dict:
    """:func:`build_dataset` on a grid export file, written atomically as Parquet with its record.

    The record holds the tasks, tiers, seeds, episodes, stride, row cap, dynamics, teacher,
    skipped cells and row count.

    Parameters
    ----------
    grid_path : path
        The grid export file.
    out_path : path
        The Parquet file to write.
    tasks, tiers, seeds : iterable
        As :func:`build_dataset`.
    episodes, dynamics, stride, max_rows, evaluation_seed, noise
        As :func:`build_dataset`.
    threads : int, optional
        Numba threads (default 1; at most numba's thread count).

    Returns
    -------
    dict
        The manifest entry (:func:`oneocean.engine.write_metrics`).
    """
    import numba

    from ...engine import write_metrics

    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    df, skipped = build_dataset(grid_path, tasks, tiers, seeds, episodes=episodes,
                                dynamics=dynamics, stride=stride, max_rows=max_rows,
                                evaluation_seed=evaluation_seed, noise=noise)
    meta = {"stage": "bc_dataset", "tasks": list(tasks), "tiers": [int(t) for t in tiers],
            "seeds": [int(s) for s in seeds], "episodes": int(episodes), "stride": int(stride),
            "max_rows": int(max_rows), "dynamics": dynamics, "teacher": "heuristic",
            "noise": float(noise),
            "skipped": skipped, "n_rows": int(len(df))}
    return write_metrics(df, out_path, meta=meta)
