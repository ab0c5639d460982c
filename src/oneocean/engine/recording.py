"""Per-episode metrics and subsampled trajectories as columnar files (one file per cell).

Both writers go through :func:`oneocean.io.atomic_path` and return a manifest entry
``{path, sha256, bytes, kind, rows, columns, ...meta}``. Parquet bytes depend only on the data
(pyarrow writes no timestamps; the ``created_by`` string is the library version), which the
tests check.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Mapping

from typing import TYPE_CHECKING

import numpy as np

from ..errors import ConfigError
from ..io import atomic_path, sha256_file
from .rollout import Batch

if TYPE_CHECKING:  # pandas / pyarrow are imported lazily (they cost ~0.6 s per process)
    import pandas as pd
    import pyarrow as pa

_PARQUET_OPTS = dict(compression="zstd", use_dictionary=False, write_statistics=False)


def episode_metrics(batch: Batch, dt: float, *, teams=None, goals=None, success=None,
                    t_success=None, extra: Mapping[str, np.ndarray] | None = None) -> pd.DataFrame:
    """One row per episode with the standard metrics of the task contract.

    Parameters
    ----------
    batch : Batch
    dt : float
        Step, s.
    teams : (A,) ints, optional
        Team id of each agent (default: all agents in team 0); adds ``E_team_<id>`` columns.
    goals : (E, A, 3) array, optional
        Goal positions (m) for ``final_error_m`` (mean over agents) and ``final_error_max_m``.
    success : (E,) bool, optional
        Task success; with ``t_success`` (E,) s, ``T_s`` is the time to success on success and
        the episode time otherwise (so it is always defined).
    extra : mapping of (E,) arrays, optional
        Task-specific columns appended as given.

    Returns
    -------
    pandas.DataFrame
        Columns: episode, seed, n_agents, steps, T_s, [success], E, E_team_<k>..., violations,
        coll_steps, coll_ratio, min_pair_dist_m, final_error_m, final_error_max_m, [extra...].
    """
    import pandas as pd

    e, a = batch.n_episodes, batch.n_agents
    steps = batch.steps.astype(np.int64)
    t_ep = steps * float(dt)
    cols: dict[str, np.ndarray] = {
        "episode": batch.episode_ids.astype(np.int64),
        "seed": np.full(e, batch.seed, dtype=np.int64),
        "n_agents": np.full(e, a, dtype=np.int64),
        "steps": steps,
    }
    if success is not None:
        ok = np.asarray(success, dtype=bool)
        if ok.shape != (e,):
            raise ConfigError(f"success: expected shape ({e},), got {ok.shape}")
        ts = t_ep if t_success is None else np.asarray(t_success, dtype=np.float64)
        if ts.shape != (e,):
            raise ConfigError(f"t_success: expected shape ({e},), got {ts.shape}")
        cols["T_s"] = np.where(ok, ts, t_ep)
        cols["success"] = ok
    else:
        cols["T_s"] = t_ep
    cols["E"] = batch.energy.sum(axis=1)
    team = np.zeros(a, dtype=np.int64) if teams is None else np.asarray(teams, dtype=np.int64)
    if team.shape != (a,):
        raise ConfigError(f"teams: expected shape ({a},), got {team.shape}")
    for k in np.unique(team):
        cols[f"E_team_{int(k)}"] = batch.energy[:, team == k].sum(axis=1)
    cols["violations"] = batch.violations.sum(axis=1).astype(np.int64)
    cols["coll_steps"] = batch.coll_steps.astype(np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        cols["coll_ratio"] = np.where(steps > 0, batch.coll_steps / np.maximum(steps, 1), 0.0)
    cols["min_pair_dist_m"] = batch.min_dist.astype(np.float64)
    if goals is not None:
        g = np.asarray(goals, dtype=np.float64)[..., :3]
        if g.shape != (e, a, 3):
            raise ConfigError(f"goals: expected shape ({e}, {a}, 3), got {g.shape}")
        err = np.linalg.norm(batch.positions - g, axis=2)
        cols["final_error_m"] = err.mean(axis=1)
        cols["final_error_max_m"] = err.max(axis=1)
    else:
        cols["final_error_m"] = np.full(e, np.nan)
        cols["final_error_max_m"] = np.full(e, np.nan)
    for k, v in (extra or {}).items():
        v = np.asarray(v)
        if v.shape != (e,):
            raise ConfigError(f"extra column '{k}': expected shape ({e},), got {v.shape}")
        cols[k] = v
    return pd.DataFrame(cols)


def _write_table(table: pa.Table, path: Path) -> None:
    import pyarrow.parquet as pq

    with atomic_path(path, suffix=".parquet") as tmp:
        pq.write_table(table, tmp, **_PARQUET_OPTS)


def _entry(path: Path, kind: str, table: pa.Table, meta: Mapping | None) -> dict:
    entry = {"path": os.fspath(path), "kind": kind, "sha256": sha256_file(path),
             "bytes": path.stat().st_size, "rows": table.num_rows,
             "columns": list(table.column_names)}
    for k, v in (meta or {}).items():
        if k in entry:
            raise ConfigError(f"manifest meta key '{k}' clashes with a reserved key")
        entry[k] = v
    return entry


def write_metrics(df: pd.DataFrame, path, *, meta: Mapping | None = None) -> dict:
    """Write per-episode metrics to Parquet atomically; return the manifest entry.

    ``meta`` (JSON-able; e.g. ``{"dynamics": "6dof", "vehicle": vehicle.spec, "dt_s": 1.0,
    "controller": ctrl.describe()}``) is copied into the entry.
    """
    import pyarrow as pa

    path = Path(path)
    table = pa.Table.from_pandas(df, preserve_index=False)
    _write_table(table, path)
    return _entry(path, "episode_metrics", table, meta)


def write_trajectories(batch: Batch, path, dt: float, *, meta: Mapping | None = None) -> dict:
    """Write the recorded trajectories as ONE long-format Parquet file; return the entry.

    Columns: episode (int64), agent (int16), step (int64), t_s (float64, since the episode
    start), x, y, z (float32, m). Samples not reached by an episode are omitted.
    """
    import pyarrow as pa

    path = Path(path)
    traj = batch.recorded()
    if traj.shape[2] == 0:
        raise ConfigError("write_trajectories: the batch recorded no trajectories "
                          "(init_batch(record_every=..., max_steps=...))")
    e, a, k, _ = traj.shape
    every = batch.record_every
    step = np.arange(k, dtype=np.int64) * every
    reached = step[None, :] <= batch.steps[:, None]  # (E, K)
    ep = np.broadcast_to(batch.episode_ids[:, None, None], (e, a, k))
    ag = np.broadcast_to(np.arange(a, dtype=np.int16)[None, :, None], (e, a, k))
    st = np.broadcast_to(step[None, None, :], (e, a, k))
    keep = np.broadcast_to(reached[:, None, :], (e, a, k))
    table = pa.table({
        "episode": pa.array(ep[keep].astype(np.int64)),
        "agent": pa.array(ag[keep]),
        "step": pa.array(st[keep]),
        "t_s": pa.array(st[keep] * float(dt)),
        "x": pa.array(traj[..., 0][keep]),
        "y": pa.array(traj[..., 1][keep]),
        "z": pa.array(traj[..., 2][keep]),
    })
    _write_table(table, path)
    m = {"record_every": int(every), **(meta or {})}
    return _entry(path, "trajectories", table, m)
