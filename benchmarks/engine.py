"""Throughput of the one episode loop per dynamics model (printed figures, not a timed test).

For every dynamics model (kinematic, 3dof, 4dof, 6dof), N = 1 agent (G2G, heuristic) and
N = 10 agents (FT, heuristic, ``n_agents=10``), tier 2, on 1 and 2 numba threads: agent-steps
per second of the fused loop (``Episodes(...).run()``: the task's kernel, ``prange`` over
episodes; agent-steps = steps actually taken x N), on an analytic grid of the ``public``
variant's size (49 x 7 x 150 x 200, tide layers). Next to it, in the same run, the plain
Python/NumPy per-step loop of the same model (:func:`oneocean.engine.reference.reference_run`,
a P-controller toward a goal, timed on fewer steps). First-call compile seconds per task
kernel are measured in a subprocess with an empty numba cache, and the cached load in a second
subprocess sharing that cache (the model id is a run-time int: one kernel per task).

Usage::

    python benchmarks/engine.py            # full run (~3-5 min on 2 cores, plus compiles)
    python benchmarks/engine.py --quick    # smaller, for a smoke test
    python benchmarks/engine.py --json results/benchmarks/engine.json

Wall-clock rates depend on what else runs on the machine; the load average is printed and
the per-CPU-second rate (``process_time``) is reported next to the wall-clock rate.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import textwrap
import time

import numpy as np

GRID_KW = dict(nt=49, nz=7, ny=150, nx=200, dx_m=143.0, dz_m=222.0, max_depth_m=120.0)
CASES = (("G2G", 1), ("FT", 10))  # (task, N): the heuristic of a single- and a multi-agent task
TIER = 2

_COMPILE_PROBE = textwrap.dedent("""
    import json, time
    t0 = time.perf_counter()
    from oneocean.engine import load_grid
    from oneocean.tasks import Cell
    from oneocean.tasks.episodes import Episodes
    from oneocean.testing import make_test_grid
    out = {"import_s": time.perf_counter() - t0}
    g = load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40))
    for task, n in (("G2G", 1), ("FT", 2)):
        t = time.perf_counter()
        c = Cell(g, task, 1, n_agents=n)
        Episodes(c.mod, c.grid, c.params, c.reset(2, 0), "heuristic", "6dof", c.vehicle,
                 0).run(2)
        out[task] = time.perf_counter() - t
    print(json.dumps(out))
""")


def compile_cost() -> dict:
    """Cold compile (empty cache) and cached load, each in a fresh process."""
    out = {}
    with tempfile.TemporaryDirectory(prefix="oneocean-nbcache-") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("cold", "cached"):
            r = subprocess.run([sys.executable, "-c", _COMPILE_PROBE], env=env,
                               capture_output=True, text=True, timeout=1800)
            if r.returncode != 0:
                raise RuntimeError(f"compile probe failed:\n{r.stderr[-3000:]}")
            out[label] = json.loads(r.stdout.strip().splitlines()[-1])
    return out


def loop_rate(cell, init, model: str, threads: int, repeats: int) -> dict:
    """Best-of-``repeats`` agent-steps/s of the fused loop over the episodes ``init``."""
    import numba

    from oneocean.tasks.episodes import Episodes

    def batch():
        return Episodes(cell.mod, cell.grid, cell.params, init, "heuristic", model,
                        cell.vehicle, 0)

    prev = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        batch().run(2)  # compile or load from the cache
        best_wall, best_cpu, n = np.inf, np.inf, 0
        for _ in range(repeats):
            ep = batch()
            w0, c0 = time.perf_counter(), time.process_time()
            ep.run()
            best_wall = min(best_wall, time.perf_counter() - w0)
            best_cpu = min(best_cpu, time.process_time() - c0)
            n = int(ep.k.sum()) * ep.n_agents
            success = float(ep.res[:, 0].mean())
    finally:
        numba.set_num_threads(prev)
    return {"task": cell.task, "model": model, "agents": cell.n_agents, "threads": threads,
            "episodes": ep.n_episodes, "agent_steps": n, "wall_s": best_wall, "cpu_s": best_cpu,
            "rate_wall": n / best_wall, "rate_per_cpu_s": n / best_cpu,
            "rate_per_core_wall": n / best_wall / threads, "success": success}


def reference_rate(E, grid, model: str, n_agents: int, steps: int) -> dict:
    """Agent-steps/s of the plain NumPy per-step loop (one episode of ``n_agents``)."""
    from oneocean.engine.reference import reference_run

    rng = np.random.default_rng(1)
    region = {"x": (grid.x0 + 0.35 * (grid.x_max - grid.x0), grid.x_max - 1000.0),
              "z": (grid.z0 + 1000.0, grid.z_max - 1000.0), "y": (2.0, 20.0)}
    pos = E.spawn_positions(grid, rng, n_agents, region).reshape(1, n_agents, 3)
    goals = pos + rng.normal(0.0, 300.0, pos.shape)
    goals[..., 1] = pos[..., 1]
    t0 = float(rng.uniform(0.0, float(grid.time_s[-1]) - steps - 1.0))
    w0 = time.perf_counter()
    reference_run(grid, pos, goals, steps, dynamics=model, kp=0.05, t0=t0)
    wall = time.perf_counter() - w0
    n = n_agents * steps
    return {"model": model, "agents": n_agents, "agent_steps": n, "wall_s": wall,
            "rate_wall": n / wall}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer episodes (smoke test)")
    ap.add_argument("--no-compile-probe", action="store_true",
                    help="skip the cold/cached compile subprocesses")
    ap.add_argument("--json", help="also write the results to this JSON file")
    args = ap.parse_args(argv)

    load0 = os.getloadavg()
    comp = None if args.no_compile_probe else compile_cost()

    import numba

    from oneocean import engine as E
    from oneocean.io import write_json_atomic
    from oneocean.tasks import Cell
    from oneocean.testing import make_test_grid
    from oneocean.vocab import DYNAMICS

    t = time.perf_counter()
    grid = E.load_grid(make_test_grid(**GRID_KW))
    t_grid = time.perf_counter() - t
    max_threads = numba.config.NUMBA_NUM_THREADS
    threads_list = [1, 2] if max_threads >= 2 else [1]
    agents_total = 100 if args.quick else 2000     # agents per batch (episodes x N)
    repeats = 1 if args.quick else 3
    ref_steps = {m: (10 if args.quick else 40) for m in DYNAMICS}
    ref_steps["kinematic"] = 100 if args.quick else 400

    cpu = platform.processor() or platform.machine()
    print(f"# OneOcean engine benchmark: the one episode loop  ({cpu}, {os.cpu_count()} CPUs, "
          f"numba {numba.__version__}, NUMBA_NUM_THREADS={max_threads})")
    print(f"# grid {tuple(grid.uv.shape[:4])} (nt, nz, ny, nx) + tide layers, "
          f"{grid.uv.nbytes / 1e6:.0f} MB of currents, loaded in {t_grid:.2f} s; tier {TIER}, "
          "heuristic")
    print(f"# load average before: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    if comp:
        c, w = comp["cold"], comp["cached"]
        for task, _ in CASES:
            print(f"# {task} kernel, first call: {c[task]:.1f} s compiling (empty cache, fresh "
                  f"process), {w[task]:.2f} s loading from the cache (second process)")
        print(f"# import: {c['import_s']:.2f} s cold, {w['import_s']:.2f} s cached")
    print()
    hdr = (f"{'model':10s} {'task':4s} {'N':>3s} {'thr':>3s} {'agent-steps':>12s} "
           f"{'wall s':>7s} {'M/s wall':>9s} {'M/s/core':>9s} {'M/s/CPU-s':>9s} "
           f"{'ref k/s':>8s} {'speed-up':>9s}")
    print(hdr)
    print("-" * len(hdr))
    rows, refs = [], []
    cells = {task: Cell(grid, task, TIER, n_agents=n) for task, n in CASES}
    inits = {task: cells[task].reset(max(agents_total // n, max(threads_list)), 0)
             for task, n in CASES}
    for model in DYNAMICS:
        for task, n_ag in CASES:
            ref = reference_rate(E, grid, model, n_ag, ref_steps[model])
            refs.append(ref)
            for th in threads_list:
                r = loop_rate(cells[task], inits[task], model, th, repeats)
                r["reference_rate_wall"] = ref["rate_wall"]
                r["speedup_vs_reference_per_core"] = r["rate_per_core_wall"] / ref["rate_wall"]
                rows.append(r)
                print(f"{model:10s} {task:4s} {n_ag:3d} {th:3d} {r['agent_steps']:12d} "
                      f"{r['wall_s']:7.3f} {r['rate_wall'] / 1e6:9.2f} "
                      f"{r['rate_per_core_wall'] / 1e6:9.2f} {r['rate_per_cpu_s'] / 1e6:9.2f} "
                      f"{ref['rate_wall'] / 1e3:8.2f} "
                      f"{r['speedup_vs_reference_per_core']:9.0f}x", flush=True)
    load1 = os.getloadavg()
    print()
    print(f"# load average after: {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    print("# M/s/core = wall rate / threads; M/s/CPU-s = agent-steps per CPU-second of this "
          "process (insensitive to other load); ref = plain NumPy per-step loop of the same "
          "model and N (a P-controller, no task physics); speed-up = loop per core / ref")
    if args.json:
        write_json_atomic(args.json, {"compile": comp, "rows": rows, "reference": refs,
                                      "load_before": load0, "load_after": load1,
                                      "grid_shape": list(grid.uv.shape[:4]), "tier": TIER,
                                      "numba": numba.__version__})
    return 0


if __name__ == "__main__":
    sys.exit(main())
