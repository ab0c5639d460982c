"""Benchmark and ladder checks of the canonical task suite on the default region.

Prints
1. the wall time of ``snakemake --cores 2 rollouts`` (the paper protocol: 10 tasks x 3 tiers x
   50 episodes, heuristic, 6dof) with compilation cached (goal < 60 s), and the agent-steps/s
   it achieved;
2. the ladder checks of issue #4, computed in-process with :func:`oneocean.tasks.run_cell`:
   oracle >= 90 % in every (task, tier); heuristic SR non-increasing T1 -> T2 -> T3 per task;
   Tier-2 heuristic macro SR in [60, 95] %; Tier-3 macro < 50 %; switching currents off raises
   the Tier-3 heuristic macro SR by >= 15 points.

Usage: ``python benchmarks/suite.py [--episodes 50] [--skip-snakemake] [--tasks G2G SK ...]``
(run from the repository root; the default region's exports are built first if missing).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]


def _snakemake(target: str, *extra) -> float:
    """Wall time (s) of ``snakemake --cores 2 <target> <extra>`` in the repository."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "snakemake", target, "--cores", "2", *extra,
                    "--quiet", "all"], cwd=REPO, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def time_rollouts() -> None:
    from oneocean.config import load_config

    cfg = load_config(REPO / "config" / "config.yaml")
    _snakemake("exports")
    _snakemake("rollouts")  # warm numba's cache (compiles only if the code changed)
    wall = _snakemake("rollouts", "--forcerun", "rollout_cell")
    files = sorted((REPO / "results" / "rollouts" / cfg["region"]["name"]
                    / cfg["rollouts"]["variant"]).rglob("*.parquet"))
    cells = pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)
    dt = 1.0
    agent_steps = float((np.ceil(cells["T_s"] / dt) * cells["n_agents"]).sum())
    print(f"snakemake --cores 2 rollouts: {len(files)} cells, {len(cells)} episodes, "
          f"wall {wall:.1f} s (goal < 60 s), {agent_steps:.3g} agent-steps, "
          f"{agent_steps / wall:.3g} agent-steps/s end to end")


def ladder_checks(tasks, episodes: int, seed: int, dynamics: str) -> bool:
    from calibrate import run_cells  # benchmarks/calibrate.py, beside this script

    from oneocean.config import load_config
    from oneocean.engine import load_grid

    cfg = load_config(REPO / "config" / "config.yaml")
    grid_path = (REPO / "results" / "exports" / cfg["region"]["name"]
                 / cfg["rollouts"]["variant"] / "grid.npz")
    grid = load_grid(grid_path)
    cells = [(method, tier, currents) for tier in (1, 2, 3)
             for method, currents in (("heuristic", True), ("oracle", True), ("heuristic", False))]
    t0 = time.perf_counter()
    out = run_cells(grid, tasks, cells, episodes, seed, dynamics)
    wall = time.perf_counter() - t0
    rows = [{"task": task, "tier": tier, "col": f"{method}{'' if cur else '_off'}",
             "sr": 100.0 * info[(method, tier, cur)]["sr"]}
            for task, info in out for method, tier, cur in cells]
    tab = pd.DataFrame(rows).pivot_table(index="task", columns=["col", "tier"], values="sr")
    tab = tab.loc[[t for t in tasks]]
    with pd.option_context("display.width", 200, "display.precision", 1):
        print(tab)
    heur = tab["heuristic"]
    ok = True

    def check(name, passed, detail):
        nonlocal ok
        ok &= bool(passed)
        print(f"[{'PASS' if passed else 'FAIL'}] {name}: {detail}")

    worst = tab["oracle"].min().min()
    check("oracle >= 90 % in every (task, tier)", worst >= 90.0,
          f"lowest oracle SR {worst:.0f} %")
    mono = [t for t in tasks if not (heur.loc[t, 1] >= heur.loc[t, 2] >= heur.loc[t, 3])]
    check("heuristic SR non-increasing T1 -> T2 -> T3", not mono,
          f"violations: {mono or 'none'}")
    m2, m3 = heur[2].mean(), heur[3].mean()
    check("Tier-2 heuristic macro SR in [60, 95] %", 60.0 <= m2 <= 95.0, f"{m2:.1f} %")
    check("Tier-3 heuristic macro SR < 50 %", m3 < 50.0, f"{m3:.1f} %")
    off3 = tab["heuristic_off"][3].mean()
    check("currents off shifts Tier-3 heuristic macro SR by >= 15 points",
          abs(off3 - m3) >= 15.0, f"{m3:.1f} % with currents, {off3:.1f} % without")
    print(f"ladder checks: {len(tasks) * 9} cells x {episodes} episodes in {wall:.1f} s")
    return ok


def main(argv=None) -> int:
    from oneocean.vocab import TASK_IDS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--dynamics", default="6dof")
    ap.add_argument("--tasks", nargs="+", default=list(TASK_IDS))
    ap.add_argument("--skip-snakemake", action="store_true",
                    help="only the in-process ladder checks")
    args = ap.parse_args(argv)
    if not args.skip_snakemake:
        time_rollouts()
    ok = ladder_checks(args.tasks, args.episodes, args.seed, args.dynamics)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
