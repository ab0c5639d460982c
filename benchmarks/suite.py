"""Wall time of the canonical task suite's rollouts on the default region.

Prints the wall time of ``snakemake --cores 2 rollouts`` (the protocol: 10 tasks x 3 tiers x
50 episodes x heuristic and oracle, plus the heuristic's currents-off Tier-3 cells, 6dof) with
compilation cached, and the agent-steps/s it achieved end to end. The ladder itself, with its
intervals and checks on the evaluation seed, is ``benchmarks/ladder.py`` (the workflow's
``results/tables/<region>/ladder.md``).

Usage: ``python benchmarks/suite.py`` (from the repository root; exports are built first if
missing).
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
    wall = _snakemake("rollouts", "--forcerun", "rollout_task", "rollout_task_bc", "rollout_team")
    from oneocean.reporting.cells import read_cell

    # the cells the forced rules rewrote (not the ablation cells of rollout_ablation_<task>)
    files = sorted(f for f in (REPO / "results" / "rollouts" / cfg["region"]["name"]
                               / cfg["rollouts"]["variant"]).rglob("*.parquet")
                   if not read_cell(f)[1]["ablation"])
    cells = pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)
    dt = 1.0
    agent_steps = float((np.ceil(cells["T_s"] / dt) * cells["n_agents"]).sum())
    print(f"snakemake --cores 2 rollouts: {len(files)} cells, {len(cells)} episodes, "
          f"wall {wall:.1f} s (goal < 60 s), {agent_steps:.3g} agent-steps, "
          f"{agent_steps / wall:.3g} agent-steps/s end to end")


def main(argv=None) -> int:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args(argv)
    time_rollouts()
    return 0


if __name__ == "__main__":
    sys.exit(main())
