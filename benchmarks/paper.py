"""Wall time of the whole paper: from an empty ``results/`` on 2 cores, then a no-op rerun.

Runs the repository's workflow (``snakemake --cores 2``, the default target: every table,
figure, rollout, BC training and the manifest) in a fresh working directory, so nothing is
reused from ``results/``, and prints:

* the cold wall time (goal < 5 min), with numba's cache empty by default (a fresh machine:
  every task kernel compiles) or warm with ``--warm-numba`` (numba's cache as it is);
* the wall time of a second, no-op run (goal < 5 s: Snakemake only checks the DAG);
* the five slowest jobs (from the workflow's own benchmark files).

Usage: ``python benchmarks/paper.py [--warm-numba] [--keep]`` from the repository root.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _snakemake(workdir: Path, env: dict) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "snakemake", "--snakefile", str(REPO / "Snakefile"),
                    "--directory", str(workdir), "--cores", "2", "--quiet", "all"],
                   check=True, env=env, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--warm-numba", action="store_true",
                    help="keep numba's cache (default: an empty NUMBA_CACHE_DIR, as on a new "
                         "machine)")
    ap.add_argument("--keep", action="store_true", help="keep the working directory")
    args = ap.parse_args(argv)

    import pandas as pd

    work = Path(tempfile.mkdtemp(prefix="oneocean-paper-"))
    env = dict(os.environ)
    if not args.warm_numba:
        env["NUMBA_CACHE_DIR"] = str(work / "numba-cache")
    try:
        cold = _snakemake(work, env)
        noop = _snakemake(work, env)
        jobs = [(str(f.relative_to(work / "results" / "benchmarks")),
                 float(pd.read_csv(f, sep="\t")["s"].iloc[0]))
                for f in (work / "results" / "benchmarks").rglob("*.tsv")]
        n_art = sum(1 for _ in (work / "results").rglob("*") if _.is_file())
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    numba = "warm" if args.warm_numba else "empty"
    print(f"whole paper from an empty results/, 2 cores, numba cache {numba}: {cold:.0f} s "
          f"({cold / 60:.1f} min; goal < 5 min), {n_art} files")
    print(f"no-op rerun: {noop:.1f} s (goal < 5 s)")
    print(f"{len(jobs)} jobs, summed job wall {sum(s for _, s in jobs):.0f} s; slowest:")
    for name, s in sorted(jobs, key=lambda j: -j[1])[:5]:
        print(f"  {s:6.1f} s  {name}")
    if args.keep:
        print(f"working directory kept: {work}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
