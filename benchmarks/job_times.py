"""Where a workflow run's time went: the jobs' own benchmark files, summed per part.

Every rule of the workflow writes ``results/benchmarks/<stage>/<wildcards>.tsv`` (Snakemake's
``benchmark:``: the job's wall seconds, peak memory, CPU time). This sums their wall seconds
into the parts a user waits for:

* ``compile``: the ten ``compile_kernel`` jobs (each task's loop into numba's on-disk cache);
* ``scenes``: the scene backend's cell jobs (MuJoCo);
* ``rollouts``: the core backend's cells (ladder, replicate, currents-off, BC, team sweep,
  information-ablation and stressor cells) and the planning suite's;
* ``rest``: the product, exports, scene builds and media, BC's dataset and training, the
  tables and figures.

Usage::

    python benchmarks/job_times.py                 # results/ of this checkout
    python benchmarks/job_times.py /path/to/results --top 8
    python benchmarks/job_times.py --region synthetic_coast --skip rl   # the paper's jobs

Jobs that write no benchmark file (the LLM planning cells, the manifest) are not counted.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

PARTS = (("compile", ("kernels",)), ("scenes", ("scene_rollouts",)),
         ("rollouts", ("rollouts", "planning")))


def part_of(rel: Path) -> str:
    """The part a benchmark file (path below ``results/benchmarks``) belongs to."""
    for name, stages in PARTS:
        if rel.parts[0] in stages:
            return name
    return "rest"


def job_seconds(path: Path) -> float:
    """The wall seconds a Snakemake benchmark file records (its last row)."""
    with open(path) as fh:
        rows = list(csv.DictReader(fh, delimiter="\t"))
    return float(rows[-1]["s"])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="?", type=Path,
                    default=Path(__file__).resolve().parents[1] / "results")
    ap.add_argument("--top", type=int, default=5, help="also list the slowest jobs")
    ap.add_argument("--region", help="only this region's jobs")
    ap.add_argument("--skip", nargs="*", default=[], help="stages to leave out (e.g. rl)")
    a = ap.parse_args(argv)
    root = a.results / "benchmarks"
    files = sorted(root.rglob("*.tsv"))
    if not files:
        raise SystemExit(f"{root}: no benchmark files (run the workflow first)")
    rels = [f.relative_to(root) for f in files]
    rels = [r for r in rels if r.parts[0] not in a.skip
            and (a.region is None or a.region in r.parts)]
    jobs = [(job_seconds(root / r), r) for r in rels]
    sums: dict[str, float] = {name: 0.0 for name, _ in PARTS}
    sums["rest"] = 0.0
    counts = dict.fromkeys(sums, 0)
    for s, rel in jobs:
        part = part_of(rel)
        sums[part] += s
        counts[part] += 1
    total = sum(sums.values())
    print(f"{'part':10s} {'jobs':>5s} {'job time s':>11s} {'share':>6s}")
    for name, s in sums.items():
        print(f"{name:10s} {counts[name]:5d} {s:11.1f} {100 * s / total:5.0f}%")
    print(f"{'total':10s} {len(jobs):5d} {total:11.1f}")
    for s, rel in sorted(jobs, reverse=True)[:a.top]:
        print(f"  {s:7.1f} s  {rel}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
