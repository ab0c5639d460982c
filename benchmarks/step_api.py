"""Step API speed beside the fused kernel on the same task, tier and grid (printed figures).

For each task (default G2G, FT, SPC at tier 2) and each batch size (1, 16, 256, 4096
sub-envs; ``--envs``), in one run:

* ``reset``: the wall time of ``OceanVectorEnv.reset`` (episode sampling and the batch's
  set-up), per sub-env: it draws the candidates of the first pool seed (``--pool`` episodes
  per sub-env: 4, the env's default) and builds the episodes the sub-envs start on (the
  whole pool for a task whose pool is not built in parts); and ``ms/episode``: the time per
  episode of building episodes (what every autoreset costs, amortised: sampling, the task's
  set-up and the first observation); ``whole pool``: the baseline, the same reset building
  all the first pool seed's episodes at once;
* ``step``: env-steps per second of ``step()`` with a fixed action (raw view, velocity
  actions), and the microseconds per ``step()`` call, wall and CPU (the process's CPU
  time: what a loaded machine does not inflate as much);
* ``fused``: agent-steps per second of the task's fused kernel running the heuristic on the
  same episodes (``Cell.run``; the best of three runs of 64 episodes), the speed the step
  API is measured against; ``step API / fused`` is the wall-clock ratio (the step API's
  autoresets, hence their episode sampling, included), ``CPU, no sampling`` the ratio of
  CPU agent-steps/s with the autoresets' pool builds taken out of the step API's time (at
  the same run's cost per episode): the step against the kernel, both without sampling.

One numba thread (``NUMBA_NUM_THREADS=1`` is set here unless given); the first call of each
kind is a warm-up (compilation), not timed. The grid is the default region's (built and
cached on first use: :func:`oneocean.product.defaults.default_grid_path`) unless ``--grid``.

Usage::

    python benchmarks/step_api.py
    python benchmarks/step_api.py --tasks G2G --envs 1 16 --steps 200     # quick look
    python benchmarks/step_api.py --baseline-src /tmp/before/src           # before / after
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")


def _grid(path):
    from oneocean.engine import load_grid

    if path:
        return load_grid(path)
    from oneocean.product.defaults import resolve_grid

    return resolve_grid(None)


def _builder(env) -> str:
    """The env's method that builds the episodes sub-envs draw next: ``_next_pool`` (a pool
    seed's episodes a part at a time), or ``_new_pool`` on checkouts that build whole pools."""
    return "_next_pool" if hasattr(env, "_next_pool") else "_new_pool"


def _build(env):
    """Build the episodes sub-envs would draw next (what an autoreset pays for)."""
    if _builder(env) == "_next_pool":
        return env._next_pool()
    return env._new_pool(env.pool_size)


def _count_built(env) -> list:
    """A counter of the episodes ``env`` builds (pools and parts of pools) from now on."""
    count = [0]
    name = _builder(env)
    build = getattr(env, name)

    def counted(*args):
        pool = build(*args)
        count[0] += pool.n
        return pool

    setattr(env, name, counted)
    return count


def measure(task: str, tier: int, grid, n_envs: int, steps: int, pool: int = 4) -> dict:
    import numpy as np

    from oneocean.envs import OceanVectorEnv

    env = OceanVectorEnv(task, tier, grid, num_envs=n_envs, autoreset_mode="next_step",
                         pool=pool)
    env.reset(seed=0)                                   # warm-up (compile)
    env.step(np.zeros(env.action_space.shape))
    # the baseline: the same reset building the pool seed's episodes at once
    whole = OceanVectorEnv(task, tier, grid, num_envs=n_envs, autoreset_mode="next_step",
                           pool=pool)
    whole._part = whole.pool_size
    whole.reset(seed=0)                                 # warm-up, as for env
    t = time.perf_counter()
    whole.reset(seed=1)
    t_whole = time.perf_counter() - t
    whole.close()
    t = time.perf_counter()
    env.reset(seed=1)
    t_reset = time.perf_counter() - t
    a = np.zeros(env.action_space.shape)
    a[..., 0] = 0.5 * env.v_max
    n_resets = 0
    built = _count_built(env)
    t, c = time.perf_counter(), time.process_time()
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(a)
        n_resets += int((term | trunc).sum())
    t_steps = time.perf_counter() - t
    c_steps = time.process_time() - c
    n_built = built[0]
    # time spent on autoresets: the same run's episode builds (a pool seed's episodes, built
    # as the sub-envs reach them), timed separately
    t = time.perf_counter()
    before = built[0]
    while time.perf_counter() - t < 0.5 or built[0] == before:
        _build(env)
    t_pool = (time.perf_counter() - t) / (built[0] - before)
    # the autoresets' builds inside the timed steps (at the same run's cost per episode)
    sampling = n_built * t_pool
    return {"cpu_us_per_step_no_sampling": 1e6 * max(c_steps - sampling, 0.0) / steps,
            "reset_ms_per_env": 1e3 * t_reset / n_envs,
            "whole_reset_ms_per_env": 1e3 * t_whole / n_envs, "pool_ms_per_env": 1e3 * t_pool,
            "env_steps_s": steps * n_envs / t_steps, "us_per_step": 1e6 * t_steps / steps,
            "cpu_us_per_step": 1e6 * c_steps / steps,
            "agents": env.n_agents, "episodes_ended": n_resets}


def fused(task: str, tier: int, grid, n_episodes: int, repeat: int = 3) -> tuple:
    """Agent-steps per second (wall, CPU) of the task's fused kernel with the heuristic on
    ``n_episodes`` episodes: the best of ``repeat`` runs of the same episodes (each run on
    its own fresh rollout), so one slow run on a shared machine does not set the ratio."""
    from oneocean.tasks import Cell

    cell = Cell(grid, task, tier)
    cell.run("heuristic", 2, 0, "6dof")                 # warm-up
    init = cell.reset(n_episodes, 1)
    best, best_cpu = 0.0, 0.0
    for _ in range(max(int(repeat), 1)):
        ep = cell.episodes(init, "heuristic", "6dof", 1)
        t, c = time.perf_counter(), time.process_time()
        ep.run()
        dt, dc = time.perf_counter() - t, time.process_time() - c
        steps = int(ep.k.sum()) * cell.n_agents
        best, best_cpu = max(best, steps / dt), max(best_cpu, steps / dc)
    return best, best_cpu


def _baseline(args, argv) -> None:
    """Run this script's measurements on the checkout ``args.baseline_src`` (rows 'before')."""
    import subprocess
    import tempfile

    rest, skip = [], False
    for a in argv:
        if skip:
            skip = False
        elif a == "--baseline-src":
            skip = True
        elif not a.startswith("--baseline-src="):
            rest.append(a)
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "PYTHONPATH": str(args.baseline_src.resolve()),
               "NUMBA_CACHE_DIR": cache}
        subprocess.run([sys.executable, __file__, *rest, "--side", "before"], env=env,
                       check=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tasks", nargs="+", default=["G2G", "FT", "SPC"])
    p.add_argument("--tier", type=int, default=2)
    p.add_argument("--envs", nargs="+", type=int, default=[1, 16, 256, 4096])
    p.add_argument("--steps", type=int, default=0,
                   help="steps per timing (default: 2000 at 1 env down to 50 at 4096)")
    p.add_argument("--grid", default=None, help="grid export (default: the default region)")
    p.add_argument("--pool", type=int, default=4,
                   help="episodes sampled per sub-env per pool (the env's pool; default 4)")
    p.add_argument("--baseline-src", type=Path,
                   help="src/ dir of a 'before' checkout: the same figures on it first (in a "
                        "subprocess, its own numba cache), rows marked 'before'")
    p.add_argument("--side", default="after", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.baseline_src:
        _baseline(args, argv if argv is not None else sys.argv[1:])
    import oneocean

    grid = _grid(args.grid)
    print(f"# step API vs fused kernel: tier {args.tier}, {os.environ['NUMBA_NUM_THREADS']} "
          f"numba thread(s), {platform.processor() or platform.machine()}, "
          f"python {sys.version.split()[0]}; load average {os.getloadavg()[0]:.2f}; "
          f"{args.side}: {Path(oneocean.__file__).parents[1]}")
    print(f"{'side':6} {'task':5} {'envs':>5} {'reset ms/env':>13} {'whole pool':>11} {'ms/episode':>11} "
          f"{'env-steps/s':>12} {'us/step()':>10} {'cpu us/step()':>13} {'agent-steps/s':>14} {'fused agent-steps/s':>20}"
          f" {'step API / fused':>17} {'CPU, no sampling':>17}")
    for task in args.tasks:
        f, f_cpu = fused(task, args.tier, grid, 64)
        for n in args.envs:
            steps = args.steps or max(50, min(2000, 200000 // n))
            m = measure(task, args.tier, grid, n, steps, args.pool)
            agent_steps = m["env_steps_s"] * m["agents"]
            # CPU agent-steps/s of step() without the autoresets' sampling, over the fused
            # kernel's CPU agent-steps/s (which samples nothing while it runs)
            cpu_ratio = (n * m["agents"] / max(m["cpu_us_per_step_no_sampling"], 1e-9) * 1e6
                         / f_cpu)
            print(f"{args.side:6} {task:5} {n:>5} {m['reset_ms_per_env']:>13.3f} "
                  f"{m['whole_reset_ms_per_env']:>11.3f} {m['pool_ms_per_env']:>11.3f} "
                  f"{m['env_steps_s']:>12,.0f} {m['us_per_step']:>10.1f} {m['cpu_us_per_step']:>13.1f} "
                  f"{agent_steps:>14,.0f} "
                  f"{f:>20,.0f} {agent_steps / f:>17.2f} "
                  f"{cpu_ratio:>17.2f}", flush=True)
    print(f"# load average at end: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
