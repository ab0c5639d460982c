"""Task-kernel throughput, before and after, side by side in one run (printed, not a test).

Agent-steps per second of ``oneocean.tasks.run_cell(grid, task, tier, "heuristic", episodes,
0, "6dof")`` per task on the scene grid of the default region, with ONE numba thread, for the
current checkout ("after") and optionally a baseline checkout ("before"). Each side runs in its
own worker subprocess (``PYTHONPATH`` = that side's ``src``, ``NUMBA_NUM_THREADS=1``, its own
``NUMBA_CACHE_DIR``): a warm-up call compiles (both sides' warm-ups run at once), then the timed
calls alternate before, after, before, after, ... and the best of ``--repeat`` is kept.
Agent-steps = sum over episodes of ``T_s / dt_s * n_agents``.

Usage::

    python benchmarks/tasks_speed.py --baseline-src /tmp/base/src     # all ten tasks
    python benchmarks/tasks_speed.py --baseline-src /tmp/base/src --tasks G2G SK \\
        --episodes 10 --repeat 1                                        # smoke test
    python benchmarks/tasks_speed.py                                    # "after" only

Cold compiles take 60-160 s per task and side; pass ``--cache-dir DIR`` to keep the numba
caches between runs (default: a temporary directory removed at the end). Nothing is written
into the repository. Wall-clock rates depend on machine load: the load average is printed.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_GRID = ROOT / "results" / "exports" / "synthetic_coast" / "scene" / "grid.npz"
TASKS = ("G2G", "SK", "RF", "DPT", "AS", "PI", "FT", "SPC", "UPL", "FH")
TAG = "@@"  # prefix of the worker's protocol lines on stdout (anything else is ignored)

# Worker: argv = grid, task, tier, episodes. Warms up, then one timed call per "run" on stdin.
_WORKER = """
import json, sys, time
import oneocean, oneocean.tasks as T
from oneocean.engine import load_grid
from oneocean.tasks.common import load_task_table
grid_path, task, tier, episodes = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
grid = load_grid(grid_path)
dt = float(load_task_table(task)["dt_s"])
call = lambda: T.run_cell(grid, task, tier, "heuristic", episodes, 0, "6dof")
t0 = time.perf_counter(); call(); warm = time.perf_counter() - t0
print("@@" + json.dumps({"file": oneocean.__file__, "warmup_s": warm}), flush=True)
for line in sys.stdin:
    if line.strip() != "run":
        break
    w0, c0 = time.perf_counter(), time.process_time()
    df = call()
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    steps = float((df["T_s"].to_numpy() / dt * df["n_agents"].to_numpy()).sum())
    print("@@" + json.dumps({"wall_s": wall, "cpu_s": cpu, "agent_steps": steps}), flush=True)
"""


class Worker:
    """One side's long-lived subprocess for one task."""

    def __init__(self, side, src, cache, grid, task, tier, episodes):
        env = dict(os.environ, PYTHONPATH=str(src), NUMBA_NUM_THREADS="1",
                   NUMBA_CACHE_DIR=str(cache))
        self.side, self.task, self.err = side, task, tempfile.TemporaryFile(mode="w+")
        self.proc = subprocess.Popen([sys.executable, "-c", _WORKER, str(grid), task, str(tier),
                                      str(episodes)], env=env, stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=self.err, text=True)

    def read(self) -> dict:
        for line in self.proc.stdout:
            if line.startswith(TAG):
                return json.loads(line[len(TAG):])
        self.err.seek(0)
        raise RuntimeError(f"{self.side} worker for {self.task} died:\n{self.err.read()[-3000:]}")

    def run(self) -> dict:
        print("run", file=self.proc.stdin, flush=True)
        return self.read()

    def close(self, kill=False):
        if self.proc.poll() is None:
            self.proc.kill() if kill else self.proc.stdin.close()
            self.proc.wait()
        self.err.close()


def measure(task, sides, args, cache_root) -> dict:
    """Best-of-repeat timing per side for one task, calls interleaved across sides."""
    workers = {s: Worker(s, src, Path(cache_root) / s, args.grid, task, args.tier, args.episodes)
               for s, src in sides.items()}
    ok = False  # on an error, kill the other side rather than wait for its compile
    try:
        info = {s: w.read() for s, w in workers.items()}  # warm-ups run concurrently
        runs = {s: [] for s in sides}
        for _ in range(args.repeat):
            for s, w in workers.items():
                runs[s].append(w.run())
        ok = True
    finally:
        for w in workers.values():
            w.close(kill=not ok)
    return {s: {**info[s], "agent_steps": r[0]["agent_steps"],
                "rate": max(x["agent_steps"] / x["wall_s"] for x in r),
                "cpu_rate": max(x["agent_steps"] / x["cpu_s"] for x in r)} for s, r in runs.items()}


_STEP_API = r"""
import sys, time, numpy as np
from oneocean.envs import OceanVectorEnv
from oneocean.tasks import Cell
from oneocean.tasks.episodes import Episodes
task, tier, n, grid, steps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], 200
env = OceanVectorEnv(task, tier, grid, num_envs=n, autoreset_mode="disabled")
env.reset(seed=0)
a = np.zeros(env.action_space.shape)
env.step(a)                                   # compile / warm up
env.reset(seed=0)
t = time.perf_counter(); k = 0
while k < steps and not env.batch.done.all():
    env.step(a); k += 1
api = (time.perf_counter() - t) / max(k, 1)
cell = Cell(grid, task, tier)
ep = Episodes(cell.mod, cell.grid, cell.params, cell.reset(n, 0), None, "6dof", cell.vehicle, 0)
ep.run(0)
t = time.perf_counter(); j = 0
while j < k:
    j += 1; ep.run(j)
loop = (time.perf_counter() - t) / max(k, 1)
print(f"{api:.6e} {loop:.6e} {k}")
"""


def step_api_overhead(args):
    """Seconds per ``step()`` of a batch of ``args.episodes`` envs through the Gymnasium
    vector env (zero actions, tier ``args.tier``, 6dof, one thread) next to the same loop
    advanced one step per call without the API (``Episodes.run(k + 1)``): the difference is
    the API's own overhead (observation, info, checks). Returns ``{task: (api, loop)}``."""
    out = {}
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "NUMBA_NUM_THREADS": "1"}
    for task in args.tasks:
        r = subprocess.run([sys.executable, "-c", _STEP_API, task, str(args.tier),
                            str(args.episodes), str(args.grid)], env=env, capture_output=True,
                           text=True)
        if r.returncode != 0:
            print(f"# step API {task}: FAILED\n{r.stderr[-2000:]}")
            continue
        api, loop, k = r.stdout.split()
        out[task] = (float(api), float(loop))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS, metavar="TASK")
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--repeat", type=int, default=3, help="timed calls per side (best kept)")
    ap.add_argument("--tier", type=int, default=2)
    ap.add_argument("--baseline-src", type=Path, help="src/ dir of the 'before' checkout")
    ap.add_argument("--grid", type=Path, default=DEFAULT_GRID)
    ap.add_argument("--cache-dir", type=Path, help="numba caches (default: a temp dir)")
    args = ap.parse_args(argv)
    args.grid = args.grid.resolve()
    sides = {"after": ROOT / "src"}
    if args.baseline_src:
        sides = {"before": args.baseline_src.resolve(), **sides}
    cache_root = args.cache_dir or Path(tempfile.mkdtemp(prefix="oneocean-speed-"))
    # the parent itself may import numba (step API): keep its cache out of the repo as well
    os.environ.update(NUMBA_NUM_THREADS="1", NUMBA_CACHE_DIR=str(Path(cache_root) / "after"))
    load0 = os.getloadavg()
    print(f"# task throughput: tier {args.tier}, heuristic, 6dof, 1 numba thread, "
          f"{args.episodes} episodes, seed 0, best of {args.repeat}; grid {args.grid}")
    print("# " + "; ".join(f"{s}: {src}" for s, src in sides.items()))
    print(f"# load average at start: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    cols = list(sides)
    hdr = f"{'task':5s}" + "".join(f"{s + ' steps/s':>18s}" for s in cols)
    if len(cols) == 2:
        hdr += f"{'after/before':>14s}  {'verdict':11s}  cpu ratio"
    print(f"{hdr}   (warm-up s)\n" + "-" * (len(hdr) + 14))
    notes, slower = [], []
    try:
        for task in args.tasks:
            try:
                res = measure(task, sides, args, cache_root)
            except RuntimeError as exc:  # e.g. one side broken mid-refactor: go on
                print(f"{task:5s} FAILED: {str(exc).splitlines()[0]}", flush=True)
                notes.append(f"{task} FAILED: {str(exc)[-1500:]}")
                continue
            line = f"{task:5s}" + "".join(f"{res[s]['rate']:18,.0f}" for s in cols)
            if len(cols) == 2:
                ratio = res["after"]["rate"] / res["before"]["rate"]
                slower += [task] if ratio < 0.9 else []
                line += (f"{ratio:14.3f}  {'ok' if ratio >= 0.9 else 'SLOWER >10%':11s}"
                         f"{res['after']['cpu_rate'] / res['before']['cpu_rate']:11.3f}")
                n_b, n_a = (res[s]["agent_steps"] for s in cols)
                if n_b != n_a:
                    notes.append(f"{task}: agent-steps differ (before {n_b:.0f}, after {n_a:.0f})")
            line += "   (" + ", ".join(f"{res[s]['warmup_s']:.0f}" for s in cols) + ")"
            print(line, flush=True)
            for s, src in sides.items():
                if not res[s]["file"].startswith(str(src)):
                    notes.append(f"{task}: {s} side imported {res[s]['file']}, not from {src}")
        over = step_api_overhead(args)
    finally:
        if args.cache_dir is None:
            shutil.rmtree(cache_root, ignore_errors=True)
    load1 = os.getloadavg()
    print(f"# load average at end:   {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    for n in notes:
        print(f"# NOTE {n}")
    if len(cols) == 2:
        print(f"# more than 10 % slower: {', '.join(slower) or 'none'}  (cpu ratio: the same "
              "with agent-steps per CPU-second of the worker, less sensitive to machine load)")
    for task, (api, loop) in (over or {}).items():
        print(f"step API {task}: {api * 1e6:.0f} us per step() of {args.episodes} envs vs "
              f"{loop * 1e6:.0f} us for the same loop step without the API (overhead "
              f"{(api - loop) * 1e6:.0f} us)")
    if over is None:
        print("step API: not available")
    return 0


if __name__ == "__main__":
    sys.exit(main())
