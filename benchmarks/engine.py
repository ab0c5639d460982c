"""Throughput benchmark of the core engine (printed figures, not a timed test).

For every dynamics model, N = 1 and N = 10 agents, 1 and 2 threads: agent-steps per second of
:func:`oneocean.engine.run` with the GOAL controller and full 4-D current sampling (+ tide
layers) on a grid of the ``public`` variant's size (49 x 7 x 150 x 200), next to the plain
Python/NumPy per-step loop of the same model (:mod:`oneocean.engine.reference`, timed on
fewer steps in the same run). First-call compile cost is measured in a subprocess with an
empty numba cache, and the cached load in a second subprocess sharing that cache.

Usage::

    python benchmarks/engine.py            # full run (~3-5 min on 2 cores)
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

_COMPILE_PROBE = textwrap.dedent("""
    import json, time
    t0 = time.perf_counter()
    import numpy as np
    from oneocean import engine as E
    t_import = time.perf_counter() - t0
    g = E.load_grid(E.make_test_grid(nt=3, nz=2, ny=8, nx=9))
    pos = np.zeros((2, 2, 3)) + np.array([0.0, 2.0, 0.0])
    b = E.init_batch(pos)
    t1 = time.perf_counter()
    E.run(g, b, E.goal_controller(pos), 1, dynamics="6dof")
    t_first = time.perf_counter() - t1
    t2 = time.perf_counter()
    E.run(g, b, E.goal_controller(pos), 1, dynamics="kinematic")
    t_second = time.perf_counter() - t2
    print(json.dumps({"import_s": t_import, "first_run_s": t_first, "second_run_s": t_second}))
""")


def compile_cost() -> dict:
    """Cold compile (empty cache) and warm cached load, each in a fresh process."""
    out = {}
    with tempfile.TemporaryDirectory(prefix="oneocean-nbcache-") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("cold", "cached"):
            r = subprocess.run([sys.executable, "-c", _COMPILE_PROBE], env=env,
                               capture_output=True, text=True, timeout=900)
            if r.returncode != 0:
                raise RuntimeError(f"compile probe failed:\n{r.stderr[-3000:]}")
            out[label] = json.loads(r.stdout.strip().splitlines()[-1])
    return out


def _setup(E, grid, n_agents: int, n_episodes: int, steps: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    region = {"x": (grid.x0 + 0.35 * (grid.x_max - grid.x0), grid.x_max - 1000.0),
              "z": (grid.z0 + 1000.0, grid.z_max - 1000.0), "y": (2.0, 20.0)}
    pos = E.spawn_positions(grid, rng, n_episodes * n_agents, region)
    pos = pos.reshape(n_episodes, n_agents, 3)
    goals = pos + rng.normal(0.0, 300.0, pos.shape)
    goals[..., 1] = pos[..., 1]
    t_hi = float(grid.time_s[-1]) - steps - 1.0
    t0 = rng.uniform(0.0, t_hi, n_episodes)
    return pos, goals, t0


def engine_rate(E, grid, model: str, n_agents: int, threads: int, agents_total: int,
                steps: int, repeats: int) -> dict:
    n_ep = max(agents_total // n_agents, threads)
    pos, goals, t0 = _setup(E, grid, n_agents, n_ep, steps)
    ctrl = E.goal_controller(goals, kp=0.05)
    warm = E.init_batch(pos, t0=t0)
    E.run(grid, warm, ctrl, 2, dynamics=model, threads=threads)  # compile / load
    best_wall, best_cpu = np.inf, np.inf
    viol = 0
    for _ in range(repeats):
        b = E.init_batch(pos, t0=t0)
        w0, c0 = time.perf_counter(), time.process_time()
        E.run(grid, b, ctrl, steps, dynamics=model, threads=threads)
        best_wall = min(best_wall, time.perf_counter() - w0)
        best_cpu = min(best_cpu, time.process_time() - c0)
        viol = int(b.violations.sum())
    n = n_ep * n_agents * steps
    return {"model": model, "agents": n_agents, "threads": threads, "episodes": n_ep,
            "steps": steps, "agent_steps": n, "wall_s": best_wall, "cpu_s": best_cpu,
            "rate_wall": n / best_wall, "rate_per_cpu_s": n / best_cpu,
            "rate_per_core_wall": n / best_wall / threads, "violations": viol}


def reference_rate(E, grid, model: str, n_agents: int, steps: int) -> dict:
    from oneocean.engine.reference import reference_run

    pos, goals, t0 = _setup(E, grid, n_agents, 1, steps, seed=1)
    w0 = time.perf_counter()
    reference_run(grid, pos, goals, steps, dynamics=model, kp=0.05, t0=float(t0[0]))
    wall = time.perf_counter() - w0
    n = n_agents * steps
    return {"model": model, "agents": n_agents, "agent_steps": n, "wall_s": wall,
            "rate_wall": n / wall}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer agent-steps (smoke test)")
    ap.add_argument("--no-compile-probe", action="store_true",
                    help="skip the cold/cached compile subprocesses")
    ap.add_argument("--json", help="also write the results to this JSON file")
    args = ap.parse_args(argv)

    load0 = os.getloadavg()
    comp = None if args.no_compile_probe else compile_cost()

    import numba

    from oneocean import engine as E
    from oneocean.io import write_json_atomic
    from oneocean.vocab import DYNAMICS

    t = time.perf_counter()
    grid = E.load_grid(E.make_test_grid(**GRID_KW))
    t_grid = time.perf_counter() - t
    max_threads = numba.config.NUMBA_NUM_THREADS
    threads_list = [1, 2] if max_threads >= 2 else [1]
    agents_total = 1000 if args.quick else 2000
    repeats = 2 if args.quick else 3
    steps = {"kinematic": 500 if args.quick else 2000}
    ref_steps = {"kinematic": 200 if args.quick else 600}
    for m in DYNAMICS[1:]:
        steps[m] = 100 if args.quick else 400
        ref_steps[m] = 10 if args.quick else 40

    print(f"# OneOcean core engine benchmark  ({platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} CPUs, numba {numba.__version__}, NUMBA_NUM_THREADS={max_threads})")
    print(f"# grid {tuple(grid.uv.shape[:4])} (nt, nz, ny, nx) + tide layers, "
          f"{grid.uv.nbytes / 1e6:.0f} MB of currents, loaded in {t_grid:.2f} s")
    print(f"# load average before: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    if comp:
        c, w = comp["cold"], comp["cached"]
        print(f"# compile (empty cache, fresh process): import {c['import_s']:.2f} s, first run "
              f"{c['first_run_s']:.2f} s (all models: one kernel; model id is a runtime int)")
        print(f"# cached  (second process, warm cache): import {w['import_s']:.2f} s, first run "
              f"{w['first_run_s']:.2f} s")
    print()
    hdr = (f"{'model':10s} {'N':>3s} {'thr':>3s} {'agent-steps':>12s} {'wall s':>7s} "
           f"{'M/s wall':>9s} {'M/s/core':>9s} {'M/s/CPU-s':>9s} {'ref k/s':>8s} "
           f"{'speed-up':>9s}")
    print(hdr)
    print("-" * len(hdr))
    rows, refs = [], []
    for model in DYNAMICS:
        for n_ag in (1, 10):
            ref = reference_rate(E, grid, model, n_ag, ref_steps[model])
            refs.append(ref)
            for th in threads_list:
                r = engine_rate(E, grid, model, n_ag, th, agents_total, steps[model], repeats)
                r["reference_rate_wall"] = ref["rate_wall"]
                r["speedup_vs_reference_per_core"] = r["rate_per_core_wall"] / ref["rate_wall"]
                rows.append(r)
                print(f"{model:10s} {n_ag:3d} {th:3d} {r['agent_steps']:12d} {r['wall_s']:7.3f} "
                      f"{r['rate_wall'] / 1e6:9.2f} {r['rate_per_core_wall'] / 1e6:9.2f} "
                      f"{r['rate_per_cpu_s'] / 1e6:9.2f} {ref['rate_wall'] / 1e3:8.2f} "
                      f"{r['speedup_vs_reference_per_core']:9.0f}x", flush=True)
    load1 = os.getloadavg()
    print()
    print(f"# load average after: {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    print("# M/s/core = wall rate / threads; M/s/CPU-s = agent-steps per CPU-second of this "
          "process (insensitive to other load); speed-up = engine per core / reference loop")
    for model, goal in (("kinematic", 10e6), ("6dof", 2e6)):
        sel = [r for r in rows if r["model"] == model]
        best_wall = max(r["rate_per_core_wall"] for r in sel)
        best_cpu = max(r["rate_per_cpu_s"] for r in sel)
        print(f"# goal {model}: >= {goal / 1e6:.0f} M agent-steps/s/core -> best "
              f"{best_wall / 1e6:.2f} M per core (wall), {best_cpu / 1e6:.2f} M per CPU-second")
    if args.json:
        write_json_atomic(args.json, {"compile": comp, "rows": rows, "reference": refs,
                                      "load_before": load0, "load_after": load1,
                                      "grid_shape": list(grid.uv.shape[:4]),
                                      "numba": numba.__version__})
    return 0


if __name__ == "__main__":
    sys.exit(main())
