"""Scene backend speed beside the core on the same task, scene and episodes (printed figures).

For route following (RF, one REMUS per episode) with 1 and 8 episodes in flight, and
formation transit (FT) with one episode of 8 REMUS, both backends run the heuristic on the
same scene's local grid with the same scene tiers and seed (so the same scenarios): the core
(numba; one thread) and MuJoCo (:class:`oneocean.backends.mujoco.episodes.SceneEpisodes`:
the task's kernel decides and judges every step, MuJoCo moves the vehicles; one thread).
Printed per case: simulated seconds per wall second of the batch (the real-time factor: a
batch of 8 vehicles at 100x advances 100 simulated seconds every wall second), vehicle-seconds
per wall second, and the core's figures. Control and judging are included; the first call
(numba compile, MuJoCo model compile) is a warm-up, not timed.

The scene is built from the default region's exports (``results/exports/synthetic_coast/
scene/{grid,temporal}.npz``: ``snakemake --cores 2 exports`` makes them) with the config's
first ``scenes.list`` entry of kind ``open_water`` (or ``--scene NAME``).

Usage::

    NUMBA_NUM_THREADS=1 python benchmarks/scene.py
    NUMBA_NUM_THREADS=1 python benchmarks/scene.py --episodes 2 --repeat 1   # smoke test
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXPORTS = ROOT / "results" / "exports" / "synthetic_coast" / "scene"


def _scene(name: str | None):
    import yaml

    from oneocean.backends.mujoco.scenes import build_scene
    from oneocean.product.zarrio import read_npz

    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["scenes"]["list"]
    spec = next(s for s in cfg if (s["name"] == name if name else s["kind"] == "open_water"))
    for f in ("grid.npz", "temporal.npz"):
        if not (EXPORTS / f).exists():
            sys.exit(f"{EXPORTS / f} not found: run `snakemake --cores 2 exports` first")
    return build_scene(spec, read_npz(EXPORTS / "grid.npz", "grid export"),
                       read_npz(EXPORTS / "temporal.npz", "temporal export"))


def _time(cell, init, backend_kw, seed, repeat):
    best = None
    for _ in range(repeat):
        ep = cell.episodes(init, "heuristic", "6dof", seed, **backend_kw)
        w0 = time.perf_counter()
        ep.run()
        wall = time.perf_counter() - w0
        best = wall if best is None else min(best, wall)
    k = ep.k.astype(float)
    return best, float(k.max()) * cell.params["dt_s"], float(k.sum()) * cell.params["dt_s"] * cell.n_agents


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=None, help="scene name in config scenes.list")
    ap.add_argument("--tier", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=2, help="timed runs per case (best kept)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--physics-step", type=float, default=None, help="MuJoCo step, s")
    args = ap.parse_args(argv)

    import numba

    from oneocean.tasks import Cell

    numba.set_num_threads(1)
    scene = _scene(args.scene)
    print(f"# scene backend speed: scene {scene.name} ({scene.label}), tier {args.tier}, "
          f"heuristic, seed {args.seed}, best of {args.repeat}; one numba thread, MuJoCo "
          f"serial")
    print(f"# machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
          f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    cases = (("RF", 1, 1), ("RF", 8, 1), ("FT", 1, 8))
    print(f"{'case':<22}{'backend':<9}{'wall s':>9}{'sim s':>8}{'x real time':>13}"
          f"{'veh-s / s':>12}")
    for task, n_ep, n_ag in cases:
        kw = {"physics_step_s": args.physics_step} if args.physics_step else {}
        mj = Cell(None, task, args.tier, backend="mujoco", scene=scene,
                  n_agents=None if task == "RF" else n_ag, **kw)
        core = Cell(None, task, args.tier, backend="core", scene=scene,
                    n_agents=None if task == "RF" else n_ag)
        init = core.reset(n_ep, args.seed)
        for cell, name in ((core, "core"), (mj, "mujoco")):
            _time(cell, init, {}, args.seed, 1)          # warm-up (compiles)
            wall, sim, veh = _time(cell, init, {}, args.seed, args.repeat)
            label = f"{task} {n_ep} ep x {n_ag} veh"
            print(f"{label:<22}{name:<9}{wall:>9.3f}{sim:>8.0f}{sim / wall:>13.1f}"
                  f"{veh / wall:>12.1f}")
    print("# x real time: simulated seconds of the batch per wall second; veh-s / s: "
          "vehicle-seconds simulated per wall second")


if __name__ == "__main__":
    main()
