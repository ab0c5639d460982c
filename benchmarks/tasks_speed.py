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

    python benchmarks/tasks_speed.py --breakdown-only --tasks PI SPC \
        --episodes 20 --repeat 2                                        # where the time goes

Cold compiles take 60-160 s per task and side; pass ``--cache-dir DIR`` to keep the numba
caches between runs (default: a temporary directory removed at the end). Nothing is written
into the repository. Wall-clock rates depend on machine load: the load average and the CPU
model are printed.

Breakdown (``--breakdown``: after the timed runs; ``--breakdown-only``: instead of them;
each side given, so it works without ``--baseline-src``). Where an agent-step's CPU time
(``time.process_time``, one thread) goes, per task, in the worker of each side, in
``--repeat`` rounds that alternate between the sides as the timed runs do (a drift of the
machine's speed then reaches both sides alike); each figure is its best over the rounds:

1. *The cell*, as ``run_cell`` runs it, once per round: episode sampling (``Cell`` +
   ``reset`` + ``make`` + the policy's ``prepare``, i.e. building the ``Episodes``) timed
   apart from the loop (``Episodes.run()``); both divided by the *executed* agent-steps
   (loop iterations x agents, ``sum(LS.k) N``; the table above counts ``T_s / dt N``, which
   differs where an episode stops early on failure or runs on past success).
2. *A recording* of the same episodes, advanced one step at a time (``run(k)``,
   ``run(k + 1)``: resumable, so the trajectories are the cell's own) at every
   ``stride``-th step (``stride`` keeps at most 200k agent-steps): each agent's state before
   and after the step, its executed command, the step's time and the sensor state.
3. *Each component alone*, in a small jitted loop (``breakdown_replay``, generated into the
   cache folder) replaying exactly the calls the loop makes on the recorded arguments, in
   the loop's order (episode by episode), best of 3 per round: **dynamics**
   (``engine.step.advance_agent``), **current** (``tasks.common.current_at`` at every agent:
   the grid sampling plus the tide), **sensing** (``sensing.kernels``: ``nav_fill`` twice,
   ``current_estimate`` and ``nav_update`` per agent, as the loop calls them; the random
   draws use the record index as the episode key: same arithmetic, other numbers) and
   **pairs** (the near-collision check ``min_pairwise_distance``, once per step); each
   divided by the replayed agent-steps.
4. **hooks+acct** = loop - dynamics - current - sensing - pairs: the task's and the policy's
   hooks (``begin`` .. ``finish``, ``plan``, ``act``; e.g. a plume field's transport, a fish
   school, a sonar) and the loop's own accounting (energy, status, observation bookkeeping).

A component alone runs without the rest of the step around it (warmer branch predictors,
other cache contents), so its replay may be a little faster or slower than inside the loop;
where the hooks are nearly free, ``hooks+acct`` can come out slightly negative (a few
tenths of a us): read it as ~0. The sampling column is per executed agent-step of the
loop, so ``+sampl /s`` is the throughput of ``run_cell`` as a whole.
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
grid_path, task, tier, episodes = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
grid = load_grid(grid_path)
dt = float(T.load_task_table(task)["dt_s"])
call = lambda: T.run_cell(grid, task, tier, "heuristic", episodes, 0, "6dof")
t0 = time.perf_counter(); call(); warm = time.perf_counter() - t0
print("@@" + json.dumps({"file": oneocean.__file__, "warmup_s": warm}), flush=True)
for line in sys.stdin:
    if line.strip() == "breakdown":
        import breakdown_replay as BR
        print("@@" + json.dumps(BR.breakdown(grid, task, tier, episodes, 1)), flush=True)
        continue
    if line.strip() != "run":
        break
    w0, c0 = time.perf_counter(), time.process_time()
    df = call()
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    steps = float((df["T_s"].to_numpy() / dt * df["n_agents"].to_numpy()).sum())
    print("@@" + json.dumps({"wall_s": wall, "cpu_s": cpu, "agent_steps": steps}), flush=True)
"""


_REPLAY = '''"""Replay kernels of benchmarks/tasks_speed.py --breakdown (generated; {stamp})."""
import time

import numpy as np
from numba import njit

from oneocean.engine.constraints import min_pairwise_distance
from oneocean.engine.step import advance_agent
from oneocean.sensing.kernels import current_estimate, nav_fill, nav_update
from oneocean.tasks.common import current_at

_JIT = dict(cache=True, nogil=True, error_model="numpy")


@njit(**_JIT)
def rep_current(grid, S0, T, CE, CN):
    """current_at at every recorded agent-step (the loop's decide_agent)."""
    acc = 0.0
    for r in range(S0.shape[0]):
        t = T[r]
        for i in range(S0.shape[1]):
            ce, cn = current_at(grid, S0[r, i, 0], S0[r, i, 1], S0[r, i, 2], t)
            CE[r, i] = ce
            CN[r, i] = cn
            acc += ce
    return acc


@njit(**_JIT)
def rep_dynamics(grid, model, vp, S, C, CE, CN, v_max, dt, land, clearance):
    """advance_agent on every recorded pre-step state with its executed command."""
    acc = 0.0
    for r in range(S.shape[0]):
        for i in range(S.shape[1]):
            en, code = advance_agent(grid, model, vp, S[r, i], C[r, i], CE[r, i], CN[r, i],
                                     v_max, dt, land, clearance)
            acc += en + code
    return acc


@njit(**_JIT)
def rep_sensing(SP, seed, S0, S1, K, CE, CN, CB, FC, NAVC, NERR, NAV, dt):
    """The loop's sensing calls of every recorded step: nav_fill of every agent (known_state),
    current_estimate + nav_fill per agent (decide_agent / account_agent), nav_update per
    agent (end_step); record r stands for its episode (same arithmetic, other random draws)."""
    acc = 0.0
    n = S0.shape[1]
    for r in range(S0.shape[0]):
        k = K[r]
        if SP.true_position == 0:
            for i in range(n):
                nav_fill(S0, NERR, NAV, r, i)
        for i in range(n):
            pe, pn = current_estimate(SP, seed, CB, FC, r, k, i, n, CE[r, i], CN[r, i], 1)
            acc += pe + pn
            if SP.true_position == 0:
                nav_fill(S1, NERR, NAV, r, i)
        for i in range(n):
            nav_update(SP, seed, NAVC, NERR, S1, S0, r, k, i, n, dt)
        acc += NAV[r, 0, 0] + NERR[r, 0, 0]
    return acc


@njit(**_JIT)
def rep_pairs(S1):
    """The near-collision check (min_pairwise_distance) after every recorded step."""
    acc = 0.0
    for r in range(S1.shape[0]):
        acc += min_pairwise_distance(S1[r])
    return acc


def _best(fn, args, fresh, repeat):
    """Min CPU time of ``fn(*args)`` over ``repeat`` calls (after a compile/warm-up call);
    ``fresh()`` gives the mutable arguments anew before each call (untimed)."""
    fn(*args, *fresh())
    best = np.inf
    for _ in range(max(repeat, 3)):
        a = fresh()
        c0 = time.process_time()
        fn(*args, *a)
        best = min(best, time.process_time() - c0)
    return best


_RECORDED = {}


def _record(cell, init, stride):
    """The cell's episodes advanced step by step (every stride-th step): states before and
    after, executed commands, sensor state, in the loop's order; and the Episodes."""
    ep = cell.episodes(init, "heuristic", "6dof", 0)
    LP, LS = ep.LP, ep.LS
    rec = {key: [] for key in ("S0", "S1", "C", "T", "K", "E", "CB", "FC", "NAVC", "NERR")}
    k = 0
    while k < ep.n_steps and not ep.done.all():
        ep.run(k)
        live = (~ep.done) & (LS.k == k)
        S0, CB, NERR = ep.state.copy(), LS.cb.copy(), LS.nerr.copy()
        ep.run(k + 1)
        live &= LS.k == k + 1
        idx = np.flatnonzero(live)
        if idx.size:
            rec["S0"].append(S0[idx]); rec["S1"].append(ep.state[idx].copy())
            rec["C"].append(ep.cmd[idx].copy()); rec["T"].append(ep.t0[idx] + k * LP.dt)
            rec["K"].append(np.full(idx.size, k, np.int64)); rec["CB"].append(CB[idx])
            rec["E"].append(idx)
            rec["FC"].append(LS.fc[idx].copy()); rec["NAVC"].append(LS.navc[idx].copy())
            rec["NERR"].append(NERR[idx])
        k += stride
    # replay in the loop's order (episode by episode, step by step): the grid data an
    # episode touches stays in cache as it does in the loop
    order = np.lexsort((np.concatenate(rec["K"]), np.concatenate(rec["E"])))
    R = {key: np.ascontiguousarray(np.concatenate(v)[order]) for key, v in rec.items()}
    return R, ep


def breakdown(grid, task, tier, episodes, repeat, max_records=200_000):
    import oneocean.tasks as T

    # 1. the cell as run_cell runs it: sampling (Cell + reset + make + prepare), then the loop
    samp, loop = np.inf, np.inf
    for _ in range(max(repeat, 1)):
        c0 = time.process_time()
        cell = T.Cell(grid, task, tier)
        init = cell.reset(episodes, 0)
        ep = cell.episodes(init, "heuristic", "6dof", 0)
        c1 = time.process_time()
        ep.run()
        c2 = time.process_time()
        samp, loop = min(samp, c1 - c0), min(loop, c2 - c1)
    n_ag = ep.n_agents
    steps = int(ep.LS.k.sum()) * n_ag      # executed agent-steps (loop iterations x agents)
    # 2. the recording of the same episodes (made once per worker: every round replays it)
    stride = max(1, -(-steps // max_records))
    key = (task, tier, episodes, stride)
    if key not in _RECORDED:
        _RECORDED[key] = _record(cell, init, stride)
    R, ep = _RECORDED[key]
    LP = ep.LP
    n_rec = R["S0"].shape[0] * n_ag
    CE, CN = np.zeros(R["S0"].shape[:2]), np.zeros(R["S0"].shape[:2])
    # 3. each component alone on the recorded calls
    t_cur = _best(rep_current, (grid, R["S0"], R["T"], CE, CN), lambda: (), repeat)
    vp = ep.vehicle.params
    t_dyn = _best(rep_dynamics, (grid, LP.model, vp),
                  lambda: (R["S0"].copy(), R["C"].copy(), CE, CN, LP.v_max, LP.dt,
                           LP.land_thr, LP.clearance), repeat)
    t_sen = _best(rep_sensing, (LP.sens, LP.seed, R["S0"], R["S1"], R["K"], CE, CN),
                  lambda: (R["CB"].copy(), R["FC"], R["NAVC"], R["NERR"].copy(),
                           np.zeros_like(R["S0"]), LP.dt), repeat)
    t_pair = (_best(rep_pairs, (R["S1"],), lambda: (), repeat) if n_ag > 1 else 0.0)
    us = 1e6
    return {"agents": n_ag, "agent_steps": steps, "records": n_rec, "stride": stride,
            "loop_us": loop / steps * us, "sampling_us": samp / steps * us,
            "dynamics_us": t_dyn / n_rec * us, "current_us": t_cur / n_rec * us,
            "sensing_us": t_sen / n_rec * us, "pairs_us": t_pair / n_rec * us}
'''


def replay_dir(src, cache) -> Path:
    """A folder holding the replay module (``breakdown_replay``) for the checkout ``src``,
    named by a fingerprint of the sources it inlines, so a kept numba cache is never stale."""
    import hashlib

    pkg = Path(src) / "oneocean"
    h = hashlib.sha1(_REPLAY.encode())
    for f in sorted([*(pkg / "engine").glob("*.py"), pkg / "sensing" / "kernels.py",
                     pkg / "tasks" / "common.py"]):
        h.update(f.read_bytes() if f.exists() else b"")
    stamp = h.hexdigest()[:16]
    d = Path(cache) / f"replay-{stamp}"
    if not (d / "breakdown_replay.py").exists():
        d.mkdir(parents=True, exist_ok=True)
        (d / "breakdown_replay.py").write_text(_REPLAY.replace("{stamp}", stamp))
    return d


class Worker:
    """One side's long-lived subprocess for one task."""

    def __init__(self, side, src, cache, grid, task, tier, episodes):
        path = os.pathsep.join([str(src), str(replay_dir(src, cache))])
        env = dict(os.environ, PYTHONPATH=path, NUMBA_NUM_THREADS="1",
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

    def run(self, what="run") -> dict:
        print(what, file=self.proc.stdin, flush=True)
        return self.read()

    def close(self, kill=False):
        if self.proc.poll() is None:
            self.proc.kill() if kill else self.proc.stdin.close()
            self.proc.wait()
        self.err.close()


def _best_parts(best: dict | None, new: dict) -> dict:
    """The breakdown of two rounds of the same cell: every time (``*_us``) the smaller, the
    counts (which a round does not change) as they are."""
    if best is None:
        return new
    return {k: (min(v, new[k]) if k.endswith("_us") else v) for k, v in best.items()}


def measure(task, sides, args, cache_root) -> dict:
    """Best-of-repeat timing per side for one task, calls interleaved across sides."""
    workers = {s: Worker(s, src, Path(cache_root) / s, args.grid, task, args.tier, args.episodes)
               for s, src in sides.items()}
    ok = False  # on an error, kill the other side rather than wait for its compile
    try:
        info = {s: w.read() for s, w in workers.items()}  # warm-ups run concurrently
        runs = {s: [] for s in sides}
        for _ in range(args.repeat if args.runs else 0):
            for s, w in workers.items():
                runs[s].append(w.run())
        # the breakdown in rounds alternating across sides, as the timed runs are: a drift
        # of the machine's speed then reaches both sides alike
        parts = {}
        for _ in range(max(args.repeat, 1) if args.breakdown else 0):
            for s, w in workers.items():
                parts[s] = _best_parts(parts.get(s), w.run("breakdown"))
        ok = True
    finally:
        for w in workers.values():
            w.close(kill=not ok)
    return {s: {**info[s], "breakdown": parts.get(s),
                **({"agent_steps": r[0]["agent_steps"],
                    "rate": max(x["agent_steps"] / x["wall_s"] for x in r),
                    "cpu_rate": max(x["agent_steps"] / x["cpu_s"] for x in r)} if r else {})}
            for s, r in runs.items()}


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


def cpu_model() -> str:
    """The CPU model name (``/proc/cpuinfo``; the platform's processor string elsewhere)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform

    return platform.processor() or "unknown"


#: Breakdown columns: (key of the worker's answer, header), microseconds per agent-step.
PARTS = (("sampling_us", "sampling"), ("dynamics_us", "dynamics"), ("current_us", "current"),
         ("sensing_us", "sensing"), ("pairs_us", "pairs"), ("rest_us", "hooks+acct"),
         ("loop_us", "loop"))


def breakdown_table(rows) -> list[str]:
    """The breakdown lines of ``rows`` ``[(task, side, answer)]`` (see :data:`PARTS`)."""
    hdr = (f"{'task':5s} {'side':6s} {'N':>3s} {'agent-steps':>11s} {'loop /s':>10s} "
           f"{'+sampl /s':>10s} | " + " ".join(f"{h:>10s}" for _, h in PARTS) + "   (us/step)")
    out = [hdr, "-" * len(hdr)]
    for task, side, b in rows:
        b = dict(b)
        b["rest_us"] = b["loop_us"] - sum(b[k] for k in ("dynamics_us", "current_us",
                                                         "sensing_us", "pairs_us"))
        out.append(f"{task:5s} {side:6s} {b['agents']:3d} {b['agent_steps']:11,d} "
                   f"{1e6 / b['loop_us']:10,.0f} "
                   f"{1e6 / (b['loop_us'] + b['sampling_us']):10,.0f} | "
                   + " ".join(f"{b[k]:10.3f}" for k, _ in PARTS))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS, metavar="TASK")
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--repeat", type=int, default=3, help="timed calls per side (best kept)")
    ap.add_argument("--tier", type=int, default=2)
    ap.add_argument("--baseline-src", type=Path, help="src/ dir of the 'before' checkout")
    ap.add_argument("--grid", type=Path, help="grid export (default: the default region's "
                    "scene grid, results/exports/... if built, else the package cache's)")
    ap.add_argument("--cache-dir", type=Path, help="numba caches (default: a temp dir)")
    ap.add_argument("--breakdown", action="store_true",
                    help="also print where an agent-step's time goes (per side)")
    ap.add_argument("--breakdown-only", action="store_true",
                    help="only the breakdown (no side-by-side runs, no step-API overhead)")
    args = ap.parse_args(argv)
    args.breakdown = args.breakdown or args.breakdown_only
    args.runs = not args.breakdown_only
    if args.grid is None:
        args.grid = DEFAULT_GRID
        if not args.grid.exists():
            from oneocean.product.defaults import default_grid_path

            args.grid = default_grid_path("scene")
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
    print(f"# CPU: {cpu_model()}, {os.cpu_count()} logical cores")
    print(f"# load average at start: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    cols = list(sides)
    hdr = f"{'task':5s}" + "".join(f"{s + ' steps/s':>18s}" for s in cols)
    if len(cols) == 2:
        hdr += f"{'after/before':>14s}  {'verdict':11s}  cpu ratio"
    if args.runs:
        print(f"{hdr}   (warm-up s)\n" + "-" * (len(hdr) + 14))
    else:
        print("\n".join(breakdown_table([])))
    notes, slower, parts, over = [], [], [], None
    try:
        for task in args.tasks:
            try:
                res = measure(task, sides, args, cache_root)
            except RuntimeError as exc:  # e.g. one side broken mid-refactor: go on
                print(f"{task:5s} FAILED: {str(exc).splitlines()[0]}", flush=True)
                notes.append(f"{task} FAILED: {str(exc)[-1500:]}")
                continue
            parts += [(task, s, res[s]["breakdown"]) for s in cols if res[s]["breakdown"]]
            for s, src in sides.items():
                if not res[s]["file"].startswith(str(src)):
                    notes.append(f"{task}: {s} side imported {res[s]['file']}, not from {src}")
            if not args.runs:
                print("\n".join(breakdown_table(parts[-len(cols):])[2:]), flush=True)
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
        if args.runs:
            over = step_api_overhead(args)
    finally:
        if args.cache_dir is None:
            shutil.rmtree(cache_root, ignore_errors=True)
    load1 = os.getloadavg()
    print(f"# load average at end:   {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    for n in notes:
        print(f"# NOTE {n}")
    if len(cols) == 2 and args.runs:
        print(f"# more than 10 % slower: {', '.join(slower) or 'none'}  (cpu ratio: the same "
              "with agent-steps per CPU-second of the worker, less sensitive to machine load)")
    for task, (api, loop) in (over or {}).items():
        print(f"step API {task}: {api * 1e6:.0f} us per step() of {args.episodes} envs vs "
              f"{loop * 1e6:.0f} us for the same loop step without the API (overhead "
              f"{(api - loop) * 1e6:.0f} us)")
    if over is None and args.runs:
        print("step API: not available")
    if parts:
        print("\n# breakdown: CPU time per executed agent-step (us); loop /s and +sampl /s are "
              "executed agent-steps per CPU-second of the loop alone and with the episode "
              "sampling; hooks+acct = loop - dynamics - current - sensing - pairs "
              "(method: module docstring)")
        print("\n".join(breakdown_table(parts)))
    return 0

if __name__ == "__main__":
    sys.exit(main())
