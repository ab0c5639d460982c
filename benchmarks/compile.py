"""Task-kernel compile time from a cold numba cache, and load time from a warm one (printed).

For each task, in a fresh subprocess with an empty ``NUMBA_CACHE_DIR`` (one per task): (a) the
seconds to ``import oneocean.tasks`` and the task's module, (b) the seconds of the first
``run_cell(grid, task, 2, "heuristic", 2, 0, "6dof")`` (compile + 2 episodes); then, in a second
fresh subprocess sharing that now-warm cache, the same first call (cache load + 2 episodes).
The projection for a fresh clone's first ``snakemake --cores 2 rollouts`` is the sum of the
cold first calls / 2. Each task compiles into its own empty cache, so code shared between task
kernels is compiled once per task (as two concurrent snakemake jobs would, roughly).

Usage::

    python benchmarks/compile.py                                # current checkout, all tasks
    python benchmarks/compile.py --tasks G2G SK                 # a few tasks
    python benchmarks/compile.py --parallel 2                   # two cold compiles at once
    python benchmarks/compile.py --baseline-src /tmp/base/src   # before/after columns
    python benchmarks/compile.py --src /tmp/base/src            # another checkout only
    python benchmarks/compile.py --inline-memo-baseline         # numba's own IR copy vs
                                                                # oneocean's shared memo

Cold compiles take 60-160 s per task; ``--parallel 2`` (as ``snakemake --cores 2``) also
prints the wall time of all the cold compiles of a side. Numba caches go to a temporary
directory; nothing is written into the repository. Timings depend on machine load. Numba's
cache is keyed on the source files' timestamps: measure a tree nobody is editing (or a copy,
e.g. ``git archive HEAD src | tar -x -C /tmp/snap`` then ``--src /tmp/snap/src``), otherwise
a "warm" call recompiles.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_GRID = ROOT / "results" / "exports" / "synthetic_coast" / "scene" / "grid.npz"
TASKS = ("G2G", "SK", "RF", "DPT", "AS", "PI", "FT", "SPC", "UPL", "FH")

# argv = grid, task. Prints one JSON line prefixed "@@".
_PROBE = """
import json, sys, time
t0 = time.perf_counter()
import oneocean, oneocean.tasks as T
T.task_module(sys.argv[2])
t_import = time.perf_counter() - t0
from oneocean.engine import load_grid
grid = load_grid(sys.argv[1])
t1 = time.perf_counter()
T.run_cell(grid, sys.argv[2], 2, "heuristic", 2, 0, "6dof")
t_first = time.perf_counter() - t1
print("@@" + json.dumps({"import_s": t_import, "first_s": t_first, "file": oneocean.__file__}))
"""


def probe(src: Path, cache: Path, grid: Path, task: str, errors: list, env_extra=None):
    """One fresh process; its timings (+ its whole wall time), or None if it failed."""
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(cache),
               NUMBA_NUM_THREADS="1", **(env_extra or {}))
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", _PROBE, str(grid), task], env=env,
                       capture_output=True, text=True)
    wall = time.perf_counter() - t0
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("@@")]
    if r.returncode != 0 or not lines:
        errors.append(f"{src} {task}: exit {r.returncode}\n{r.stderr[-2000:]}")
        return None
    out = json.loads(lines[-1][2:])
    if not out["file"].startswith(str(src)):
        errors.append(f"{src} {task}: imported {out['file']} instead")
    return {**out, "process_s": wall}


def run_side(src: Path, tasks, grid: Path, parallel: int, root: Path, errors: list,
             env_extra=None) -> dict:
    """Cold probes (``parallel`` at a time), then warm probes one at a time."""
    caches = {t: Path(tempfile.mkdtemp(prefix=f"{t}-", dir=root)) for t in tasks}
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=parallel) as ex:
        cold = dict(zip(tasks, ex.map(
            lambda t: probe(src, caches[t], grid, t, errors, env_extra), tasks)))
    wall = time.perf_counter() - t0
    warm = {t: probe(src, caches[t], grid, t, errors, env_extra) if cold[t] else None
            for t in tasks}
    return {"cold": cold, "warm": warm, "wall": wall}


def fmt(x, width=9) -> str:
    return f"{x:{width}.1f}" if x is not None else f"{'FAILED':>{width}s}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS, metavar="TASK")
    ap.add_argument("--src", type=Path, default=ROOT / "src",
                    help="src/ dir of the checkout to measure (default: this one)")
    ap.add_argument("--baseline-src", type=Path, help="also measure this 'before' checkout")
    ap.add_argument("--inline-memo-baseline", action="store_true",
                    help="before = numba's own IR copy in the inliner "
                         "(ONEOCEAN_NUMBA_INLINE_MEMO=0), after = the shared memo "
                         "(oneocean.engine._jit), same checkout")
    ap.add_argument("--parallel", type=int, default=1, help="cold compiles at once")
    ap.add_argument("--grid", type=Path, default=DEFAULT_GRID)
    args = ap.parse_args(argv)

    sides = {"src": args.src.resolve()}
    envs = {"src": None}
    if args.baseline_src:
        sides = {"before": args.baseline_src.resolve(), "after": args.src.resolve()}
        envs = {"before": None, "after": None}
    elif args.inline_memo_baseline:
        sides = {"before": args.src.resolve(), "after": args.src.resolve()}
        envs = {"before": {"ONEOCEAN_NUMBA_INLINE_MEMO": "0"},
                "after": {"ONEOCEAN_NUMBA_INLINE_MEMO": "1"}}
    load0 = os.getloadavg()
    print(f"# task-kernel compile: first run_cell(grid, task, 2, 'heuristic', 2, 0, '6dof'), "
          f"fresh process each, {args.parallel} cold compile(s) at once")
    for s, src in sides.items():
        print(f"# {s}: {src}" + (f" {envs[s]}" if envs[s] else ""))
    print(f"# load average at start: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    errors: list = []
    res = {}
    with tempfile.TemporaryDirectory(prefix="oneocean-compile-") as root:
        for s, src in sides.items():
            res[s] = run_side(src, args.tasks, args.grid.resolve(), args.parallel,
                              Path(tempfile.mkdtemp(prefix=f"{s}-", dir=root)), errors,
                              envs[s])

    cols = list(sides)
    short = {"before": "bef", "after": "aft"} if len(cols) == 2 else {cols[0]: ""}
    groups = (("import", "cold", "import_s"), ("cold", "cold", "first_s"),
              ("warm", "warm", "first_s"))
    hdr = f"{'task':5s}" + "".join(f"{(g + ' ' + short[s]).strip() + ' s':>13s}"
                                   for g, _, _ in groups for s in cols)
    print(hdr + "\n" + "-" * len(hdr))

    def val(s, kind, key, task):
        r = res[s][kind][task]
        return r[key] if r else None

    for task in args.tasks:
        print(f"{task:5s}" + "".join(fmt(val(s, kind, key, task), 13)
                                     for _, kind, key in groups for s in cols))
    totals = {}
    for _, kind, key in groups:
        for s in cols:
            v = [val(s, kind, key, t) for t in args.tasks]
            totals[(s, kind, key)] = None if None in v else sum(v)
    print(f"{'total':5s}" + "".join(fmt(totals[(s, kind, key)], 13)
                                     for _, kind, key in groups for s in cols))
    load1 = os.getloadavg()
    print(f"# load average at end:   {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    for s in cols:
        cold = totals[(s, "cold", "first_s")]
        procs = [r["process_s"] for r in res[s]["cold"].values() if r]
        print(f"# {s}: sum of cold first calls {fmt(cold, 0).strip()} (s) over "
              f"{len(args.tasks)} task(s); cold processes {sum(procs):.1f} s in all; wall of "
              f"all cold compiles at --parallel {args.parallel}: {res[s]['wall']:.1f} s")
        if cold is not None:
            print(f"# {s}: projected first `snakemake --cores 2 rollouts` of a fresh clone "
                  f"~ sum of cold compiles / 2 = {cold / 2:.0f} s ({cold / 120:.1f} min)")
    for e in errors:
        print(f"# ERROR {e}", file=sys.stderr)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
