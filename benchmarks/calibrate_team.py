"""Calibration table of the cooperative team tasks (UPL, FH) on the default region.

Prints, per task, the success rate of the heuristic and the oracle at Tier 1/2/3 and of the
heuristic at Tier 3 with currents off (the data-grounding ablation), the mean primary and
secondary metrics, the wall time per cell, and whether each calibration target of issue #4
holds: oracle >= 90 % at every tier; heuristic SR non-increasing T1 -> T2 -> T3, about
90-100 / 65-90 / 15-45 %; Tier-3 SR with currents off >= 15 points higher.

Usage::

    python benchmarks/calibrate_team.py [--tasks UPL FH] [--episodes 50] [--seed 0]
        [--grid results/exports/synthetic_coast/scene/grid.npz] [--dynamics 6dof]
        [--set FH.3.zone_radius_m=5 ...]

``--set TASK.TIER.KEY=VALUE`` overrides one tier parameter for this run only (tier-table
sweeps); the printed table then says so. Without it the YAML tier tables are used as-is.
"""

from __future__ import annotations

import argparse
import contextlib
import time
from pathlib import Path

import numpy as np

import oneocean.tasks as tasks
from oneocean.engine import load_grid

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_GRID = ROOT / "results" / "exports" / "synthetic_coast" / "scene" / "grid.npz"
TEAM_TASKS = ("UPL", "FH")
#: (method, tier, currents) of every column of the table.
CELLS = (("heuristic", 1, True), ("heuristic", 2, True), ("heuristic", 3, True),
         ("oracle", 1, True), ("oracle", 2, True), ("oracle", 3, True),
         ("heuristic", 3, False))
#: A secondary metric printed next to the primary one.
SECONDARY = {"UPL": "final_object_depth_m", "FH": "final_centroid_distance_m"}


@contextlib.contextmanager
def overrides(sets: dict):
    """Temporarily override tier parameters seen by :func:`oneocean.tasks.run_cell`."""
    if not sets:
        yield
        return
    orig = tasks.tier_params

    def patched(task_id, tier):
        p = orig(task_id, tier)
        p.update(sets.get((task_id, int(tier)), {}))
        return p

    tasks.tier_params = patched
    try:
        yield
    finally:
        tasks.tier_params = orig


def parse_sets(items) -> dict:
    """``["FH.3.zone_radius_m=5"]`` -> ``{("FH", 3): {"zone_radius_m": 5.0}}``."""
    out: dict = {}
    for it in items or ():
        key, val = it.split("=", 1)
        task, tier, name = key.split(".", 2)
        out.setdefault((task, int(tier)), {})[name] = float(val)
    return out


def calibrate(grid, task_ids, episodes: int, seed: int, dynamics: str, sets=None):
    """Rows ``(task, {cell: (SR, mean primary, mean secondary, seconds)})``."""
    rows = []
    with overrides(sets or {}):
        for task in task_ids:
            cells = {}
            for method, tier, cur in CELLS:
                t = time.perf_counter()
                df = tasks.run_cell(grid, task, tier, method, episodes=episodes, seed=seed,
                                    dynamics=dynamics, currents=cur)
                cells[(method, tier, cur)] = (float(df["success"].mean()),
                                              float(df["primary"].mean()),
                                              float(df[SECONDARY[task]].mean()),
                                              time.perf_counter() - t)
            rows.append((task, cells))
    return rows


def targets(sr) -> list[tuple[str, bool]]:
    """Calibration targets for one task's SR row (order of ``CELLS``)."""
    h1, h2, h3, o1, o2, o3, off = sr
    return [("oracle>=90%", min(o1, o2, o3) >= 0.9),
            ("H non-increasing", h1 >= h2 >= h3),
            ("H-T1 in [90,100]", h1 >= 0.9),
            ("H-T2 in [65,90]", 0.65 <= h2 <= 0.9),
            ("H-T3 in [15,45]", 0.15 <= h3 <= 0.45),
            ("off >= +15p", off - h3 >= 0.15)]


def format_table(rows) -> str:
    head = ("task", "H-T1", "H-T2", "H-T3", "O-T1", "O-T2", "O-T3", "H-T3-off", "dSR-off")
    lines = ["  ".join(f"{h:>8}" for h in head)]
    for task, cells in rows:
        sr = [cells[c][0] for c in CELLS]
        vals = [f"{100 * v:7.0f}%" for v in sr] + [f"{100 * (sr[6] - sr[2]):+7.0f}p"]
        lines.append("  ".join([f"{task:>8}"] + vals))
    lines.append("")
    lines.append("mean primary / secondary metric per cell (same order) and slowest cell time:")
    for task, cells in rows:
        prim = "  ".join(f"{cells[c][1]:8.3g}" for c in CELLS)
        sec = "  ".join(f"{cells[c][2]:8.3g}" for c in CELLS)
        slow = max(cells[c][3] for c in CELLS)
        lines.append(f"{task:>8}  {prim}   {slow:.2f} s")
        lines.append(f"{'':>8}  {sec}   ({SECONDARY[task]})")
    lines.append("")
    for task, cells in rows:
        checks = targets([cells[c][0] for c in CELLS])
        lines.append(f"{task:>8}  " + "  ".join(f"{name}: {'ok' if ok else 'MISS'}"
                                                for name, ok in checks))
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tasks", nargs="+", default=list(TEAM_TASKS))
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--grid", default=str(DEFAULT_GRID))
    ap.add_argument("--dynamics", default="6dof")
    ap.add_argument("--set", nargs="*", default=[], metavar="TASK.TIER.KEY=VALUE")
    a = ap.parse_args(argv)
    grid = load_grid(a.grid)
    sets = parse_sets(a.set)
    # warm-up (compilation or cache load) outside the timed cells
    for task in a.tasks:
        tasks.run_cell(grid, task, 1, "heuristic", episodes=2, seed=a.seed, dynamics=a.dynamics)
    rows = calibrate(grid, a.tasks, a.episodes, a.seed, a.dynamics, sets)
    print(f"grid={a.grid} dynamics={a.dynamics} episodes={a.episodes} seed={a.seed}"
          + (f" overrides={sets}" if sets else ""))
    print(format_table(rows))
    sr = np.array([[c[k][0] for k in CELLS] for _, c in rows])
    if len(rows) > 1:
        print(f"macro: H-T1 {100 * sr[:, 0].mean():.0f}%  H-T2 {100 * sr[:, 1].mean():.0f}%  "
              f"H-T3 {100 * sr[:, 2].mean():.0f}%  min oracle {100 * sr[:, 3:6].min():.0f}%  "
              f"H-T3 currents-off {100 * sr[:, 6].mean():.0f}%")


if __name__ == "__main__":
    main()
