"""The task ladder on the evaluation seed, for the default region and the real southern North
Sea region, in one run, with 95 % intervals and the protocol's checks.

    python benchmarks/ladder.py [--cores 2] [--regions synthetic_coast southern_north_sea_files]

Each region's ladder is the workflow's own target ``results/tables/<region>/ladder.md``
(``snakemake --cores N results/tables/<region>/ladder.md [--configfile ...]``): heuristic and
oracle rollouts of every (task, tier) and the heuristic's currents-off Tier-3 cells, on
``rollouts.seed`` (held out from every tier table's ``calibration.seeds``). The real region is
built from ``../shared/data`` through the ``files`` source (``config/regions/
southern_north_sea_files.yaml``); a cell it cannot host is shown as n/a with its reason. Prints
each table and the wall time of each region's run (cold if its results are absent).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = {
    "synthetic_coast": None,
    "southern_north_sea_files": ROOT / "config" / "regions" / "southern_north_sea_files.yaml",
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--regions", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))
    args = ap.parse_args(argv)
    status = 0
    for region in args.regions:
        target = f"results/tables/{region}/ladder.md"
        cmd = ["snakemake", "--cores", str(args.cores), target, "--quiet", "rules"]
        if CONFIGS[region] is not None:
            cmd += ["--configfile", str(CONFIGS[region])]
        t = time.perf_counter()
        rc = subprocess.run(cmd, cwd=ROOT).returncode
        wall = time.perf_counter() - t
        print(f"\n## {region}  (snakemake {target}: {wall:.0f} s wall, exit {rc})\n")
        if rc != 0:
            status = rc
            continue
        print((ROOT / target).read_text())
    return status


if __name__ == "__main__":
    sys.exit(main())
