"""Refactor check: per-episode results of every (task, tier, method, currents) cell.

``python benchmarks/equivalence.py --out before.parquet`` runs every cell (10 tasks x 3 tiers x
{heuristic, oracle} x currents {on, off}, 50 episodes, seed 0, 6dof, scene variant of the
default region) and writes all per-episode rows to one Parquet file;
``--compare before.parquet`` runs the same cells and prints, per cell, whether every
per-episode value is bit-identical to the saved file (exit status 1 if any cell differs).
Run it against an older commit with ``PYTHONPATH=<old checkout>/src`` to capture "before".
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_GRID = ROOT / "results" / "exports" / "synthetic_coast" / "scene" / "grid.npz"
KEYS = ["task", "tier", "method", "currents", "episode"]


def run_all(grid_path, tasks_ids, episodes: int, seed: int, methods, dynamics: str):
    import oneocean.tasks as tasks
    from oneocean.engine import load_grid, load_vehicle
    from oneocean.errors import NotApplicable

    grid = load_grid(grid_path)
    veh = load_vehicle()
    frames = []
    for task in tasks_ids:
        t0 = time.perf_counter()
        for tier in (1, 2, 3):
            for method in methods:
                for currents in (True, False):
                    try:
                        df = tasks.run_cell(grid, task, tier, method, episodes, seed, dynamics,
                                            currents=currents, vehicle=veh)
                    except NotApplicable as exc:   # the region cannot serve this cell
                        print(f"{task} T{tier} {method} currents={currents}: not applicable "
                              f"({exc})", file=sys.stderr, flush=True)
                        continue
                    frames.append(df)
        print(f"{task}: {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
    return pd.concat(frames, ignore_index=True)


def compare(new: pd.DataFrame, old: pd.DataFrame) -> int:
    bad = 0
    for key, g_new in new.groupby(["task", "tier", "method", "currents"], sort=False):
        m = (old.task == key[0]) & (old.tier == key[1]) & (old.method == key[2]) & \
            (old.currents == key[3])
        g_old = old[m].dropna(axis=1, how="all")   # other tasks' metric columns
        cols = [c for c in g_old.columns if c in g_new.columns]
        missing = sorted(set(g_old.columns) - set(g_new.columns))
        a = g_new[cols].reset_index(drop=True)
        b = g_old[cols].reset_index(drop=True)
        same = len(a) == len(b) and not missing
        diff_cols = []
        if same:
            for c in cols:
                va, vb = a[c].to_numpy(), b[c].to_numpy()
                if va.dtype.kind == "f" and vb.dtype.kind == "f":
                    eq = np.array_equal(va.view(np.int64), vb.astype(np.float64).view(np.int64))
                else:
                    eq = np.array_equal(va, vb)
                if not eq:
                    diff_cols.append(c)
        ok = same and not diff_cols
        bad += not ok
        print(f"{key[0]:>4} T{key[1]} {key[2]:<9} currents={'on ' if key[3] else 'off'} "
              f"{'identical' if ok else 'DIFFERS ' + ','.join(diff_cols + missing)}")
    return bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", default=str(DEFAULT_GRID))
    ap.add_argument("--tasks", nargs="*", default=None)
    ap.add_argument("--methods", nargs="*", default=["heuristic", "oracle"])
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--dynamics", default="6dof")
    ap.add_argument("--out")
    ap.add_argument("--compare")
    a = ap.parse_args(argv)
    from oneocean.vocab import TASK_IDS

    df = run_all(a.grid, a.tasks or TASK_IDS, a.episodes, a.seed, a.methods, a.dynamics)
    if a.out:
        df.to_parquet(a.out)
        print(f"wrote {len(df)} rows to {a.out}")
    if a.compare:
        old = pd.read_parquet(a.compare)
        bad = compare(df, old)
        print(f"{bad} cell(s) differ" if bad else "all cells identical")
        return 1 if bad else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
