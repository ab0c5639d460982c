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

The loop runs with one vehicle of ``data/vehicles.yaml`` (``--vehicle``, default: the file's
default). ``--step`` adds the rigid-body step alone (:func:`oneocean.engine.dynamics.step_agent`
in a jitted loop, 1000 agents x 300 steps of 1 s in a uniform current, commands changing every
30 steps) for every vehicle and model, in nanoseconds per agent-step; with
``--baseline-dynamics OLD.py --baseline-vehicles OLD.yaml`` the same loop also times an older
copy of ``dynamics.py`` (imported as a module of ``oneocean.engine``) in the same process, so
the two are measured under the same load.

Usage::

    python benchmarks/engine.py            # full run (~3-5 min on 2 cores, plus compiles)
    python benchmarks/engine.py --quick    # smaller, for a smoke test
    python benchmarks/engine.py --json results/benchmarks/engine.json
    python benchmarks/engine.py --step --no-loop --baseline-dynamics /tmp/dynamics_old.py \
        --baseline-vehicles /tmp/vehicles_old.yaml

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


def reference_rate(E, grid, model: str, n_agents: int, steps: int, vehicle=None) -> dict:
    """Agent-steps/s of the plain NumPy per-step loop (one episode of ``n_agents``; it runs
    the holonomic controller on ``vehicle``'s parameters and substeps: a timing reference)."""
    from oneocean.engine.reference import reference_run

    rng = np.random.default_rng(1)
    region = {"x": (grid.x0 + 0.35 * (grid.x_max - grid.x0), grid.x_max - 1000.0),
              "z": (grid.z0 + 1000.0, grid.z_max - 1000.0), "y": (2.0, 20.0)}
    pos = E.spawn_positions(grid, rng, n_agents, region).reshape(1, n_agents, 3)
    goals = pos + rng.normal(0.0, 300.0, pos.shape)
    goals[..., 1] = pos[..., 1]
    t0 = float(rng.uniform(0.0, float(grid.time_s[-1]) - steps - 1.0))
    w0 = time.perf_counter()
    reference_run(grid, pos, goals, steps, dynamics=model, kp=0.05, t0=t0, vehicle=vehicle)
    wall = time.perf_counter() - w0
    n = n_agents * steps
    return {"model": model, "agents": n_agents, "agent_steps": n, "wall_s": wall,
            "rate_wall": n / wall}


def _load_module(path: str):
    """Import a copy of an engine module as ``oneocean.engine._bench_<stem>`` (its relative
    imports resolve in ``oneocean.engine``; the name is stable, so numba's cache of the copy
    stays valid between runs)."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location(
        f"oneocean.engine._bench_{Path(path).stem}", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def _step_driver(step_agent):
    """A jitted loop over agents and steps calling ``step_agent`` (one per dynamics module)."""
    from numba import njit

    @njit(cache=False)
    def drive(model, vp, states, cmds, ce, cn, dt, steps, period):
        n = states.shape[0]
        for k in range(steps):
            j = k // period
            for i in range(n):
                step_agent(model, vp, states[i], cmds[(i + j) % cmds.shape[0]], ce, cn, dt)

    return drive


def step_rates(modules: dict, n_agents: int = 1000, steps: int = 300,
               repeats: int = 5) -> dict:
    """ns per agent-step of ``step_agent`` for each (label: (dynamics module, {name: vehicle}))
    entry, vehicle and model. Repeats are interleaved across modules and the minimum CPU time
    (``process_time``) is kept, so a busy machine biases all entries alike."""
    rng = np.random.default_rng(0)
    ang = rng.uniform(-np.pi, np.pi, 64)
    frac = rng.uniform(0.3, 1.0, 64)
    dive = rng.uniform(-0.2, 0.2, 64)
    jobs = []
    for label, (dyn, vehicles) in modules.items():
        drive = _step_driver(dyn.step_agent)
        for vname, veh in vehicles.items():
            vmax = veh.v_max
            cmds = np.zeros((64, dyn.CMD_DIM))
            cmds[:, 0] = frac * vmax * np.sin(ang)
            cmds[:, 1] = dive * vmax
            cmds[:, 2] = frac * vmax * np.cos(ang)
            cmds[:, 3] = np.nan
            cmds[:, 4] = 1.0
            for model in ("kinematic", "3dof", "4dof", "6dof"):
                mid = dyn.model_id(model)
                s0 = dyn.new_state(1, n_agents,
                                   np.zeros((1, n_agents, 3)) + [0.0, 50.0, 0.0])[0]
                drive(mid, veh.params, s0.copy(), cmds, 0.3, -0.2, 1.0, 2, 30)  # compile
                jobs.append([label, vname, model, veh.substeps(1.0), drive, mid, veh.params,
                             s0, cmds, np.inf])
    for _ in range(repeats):
        for job in jobs:
            drive, mid, vp, s0, cmds = job[4:9]
            s = s0.copy()
            t0 = time.process_time()
            drive(mid, vp, s, cmds, 0.3, -0.2, 1.0, steps, 30)
            job[9] = min(job[9], time.process_time() - t0)
            assert np.all(np.isfinite(s))
    out = {}
    for label, vname, model, sub, *_, best in jobs:
        out.setdefault(label, []).append({
            "vehicle": vname, "model": model, "substeps": sub,
            "ns_per_agent_step": best / (n_agents * steps) * 1e9})
    return out


def print_step_rates(label: str, rows: list[dict]) -> None:
    print(f"# rigid-body step alone ({label}): CPU ns per agent-step (dt = 1 s; best of 5)")
    print(f"{'vehicle':16s} {'substeps':>8s} {'kinematic':>10s} {'3dof':>8s} {'4dof':>8s} "
          f"{'6dof':>8s}")
    by = {}
    for r in rows:
        by.setdefault(r["vehicle"], {})[r["model"]] = r
    for v, m in by.items():
        sub = next(iter(m.values()))["substeps"]
        print(f"{v:16s} {sub:8d} " + " ".join(
            f"{m[k]['ns_per_agent_step']:{10 if k == 'kinematic' else 8}.1f}"
            for k in ("kinematic", "3dof", "4dof", "6dof")), flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer episodes (smoke test)")
    ap.add_argument("--no-compile-probe", action="store_true",
                    help="skip the cold/cached compile subprocesses")
    ap.add_argument("--vehicle", default=None,
                    help="vehicle of data/vehicles.yaml for the episode loop (default: the "
                         "file's default)")
    ap.add_argument("--step", action="store_true",
                    help="also time the rigid-body step alone for every vehicle and model")
    ap.add_argument("--no-loop", action="store_true", help="skip the episode-loop table")
    ap.add_argument("--baseline-dynamics", help="an older dynamics.py to time next to the "
                    "current one (with --step)")
    ap.add_argument("--baseline-vehicles", help="the vehicles.yaml of that older dynamics.py")
    ap.add_argument("--json", help="also write the results to this JSON file")
    args = ap.parse_args(argv)

    load0 = os.getloadavg()
    comp = None if (args.no_compile_probe or args.no_loop) else compile_cost()

    steps_out = {}
    if args.step:
        from oneocean.engine import dynamics as dyn

        modules = {}
        if args.baseline_dynamics:
            import yaml

            old = _load_module(args.baseline_dynamics)
            with open(args.baseline_vehicles) as f:
                names = tuple(yaml.safe_load(f)["vehicles"])
            modules[f"baseline {args.baseline_dynamics}"] = (old, {
                v: old.load_vehicle(v, path=args.baseline_vehicles) for v in names})
        modules["current dynamics.py"] = (dyn, {v: dyn.load_vehicle(v)
                                                for v in dyn.vehicle_names()})
        steps_out = step_rates(modules)
        for label, rows in steps_out.items():
            print_step_rates(label, rows)
        print()
        if args.no_loop:
            if args.json:
                from oneocean.io import write_json_atomic

                write_json_atomic(args.json, {"step": steps_out, "load_before": load0,
                                              "load_after": os.getloadavg()})
            return 0

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
    from oneocean.engine import load_vehicle

    vehicle = load_vehicle(args.vehicle)
    print(f"# vehicle: {vehicle.name} (v_max {vehicle.v_max} m/s, "
          f"{vehicle.substeps(1.0)} substeps per 1 s step)")
    cells = {task: Cell(grid, task, TIER, n_agents=n, vehicle=vehicle) for task, n in CASES}
    inits = {task: cells[task].reset(max(agents_total // n, max(threads_list)), 0)
             for task, n in CASES}
    for model in DYNAMICS:
        for task, n_ag in CASES:
            ref = reference_rate(E, grid, model, n_ag, ref_steps[model], vehicle)
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
                                      "vehicle": vehicle.name, "step": steps_out,
                                      "load_before": load0, "load_after": load1,
                                      "grid_shape": list(grid.uv.shape[:4]), "tier": TIER,
                                      "numba": numba.__version__})
    return 0


if __name__ == "__main__":
    sys.exit(main())
