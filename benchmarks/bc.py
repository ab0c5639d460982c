"""What behaviour cloning costs: BC episodes next to heuristic episodes, and the training.

For every task at one tier, runs the same episodes with the heuristic and with ``bc`` (the
workflow's trained weights) in the fused loop, warm (numba cache loaded, one warm-up run
first), and prints the wall time and the cost per agent-step of both, side by side. Then it
times the training stage (``oneocean.methods.bc.train.train`` on the workflow's dataset with
the config's settings).

Usage: ``python benchmarks/bc.py [--tier 2] [--episodes 50] [--no-train]`` from the
repository root, after ``snakemake --cores 2 paper_tables`` (it reads
``results/bc/<region>/<variant>/{dataset.parquet,weights.npz}`` and the grid export).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _timed(cell, method, episodes, seed, dyn, net):
    """Wall time of one cell (episode sampling + the batched rollout) and the agent-steps it
    actually ran (every episode's own step count, early stops included)."""
    from oneocean.tasks.episodes import Episodes

    t0 = time.perf_counter()
    init = cell.reset(episodes, seed)
    ep = Episodes(cell.mod, cell.grid, cell.params, init, method, dyn, cell.vehicle, seed,
                  net=net)
    t1 = time.perf_counter()
    ep.run()
    t2 = time.perf_counter()
    return t2 - t0, t2 - t1, float(ep.k.sum() * ep.n_agents)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tier", type=int, default=2)
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--no-train", action="store_true")
    args = ap.parse_args(argv)

    import numba
    import pandas as pd

    from oneocean.config import load_config
    from oneocean.engine import load_grid
    from oneocean.methods.bc import load_weights
    from oneocean.tasks import Cell

    numba.set_num_threads(1)
    cfg = load_config(REPO / "config" / "config.yaml")
    region, variant = cfg["region"]["name"], cfg["rollouts"]["variant"]
    base = REPO / "results" / "bc" / region / variant
    grid = load_grid(REPO / "results" / "exports" / region / variant / "grid.npz")
    net = load_weights(base / "weights.npz")
    seed, dyn = cfg["rollouts"]["seed"], cfg["rollouts"]["dynamics"]
    print(f"{region}/{variant}, tier {args.tier}, {args.episodes} episodes, {dyn}, 1 thread")
    print("wall: episode sampling + rollout; ns/agent-step: the rollout alone (the loop's "
          "kernel) over the agent-steps it ran")
    print(f"{'task':5s} {'heuristic s':>12s} {'bc s':>8s} {'heur ns/agent-step':>19s} "
          f"{'bc ns/agent-step':>17s} {'bc/heur':>8s}")
    tot = [0.0, 0.0]
    for task in cfg["rollouts"]["tasks"]:
        cell = Cell(grid, task, args.tier)
        _timed(cell, "heuristic", 2, seed, dyn, None)     # warm-up (numba cache load)
        _timed(cell, "bc", 2, seed, dyn, net)
        th, rh, sh = _timed(cell, "heuristic", args.episodes, seed, dyn, None)
        tb, rb, sb = _timed(cell, "bc", args.episodes, seed, dyn, net)
        tot[0] += th
        tot[1] += tb
        print(f"{task:5s} {th:12.3f} {tb:8.3f} {1e9 * rh / sh:19.0f} {1e9 * rb / sb:17.0f} "
              f"{(rb / sb) / (rh / sh):8.2f}")
    print(f"{'all':5s} {tot[0]:12.3f} {tot[1]:8.3f}")
    if not args.no_train:
        from oneocean.methods.bc.train import train

        df = pd.read_parquet(base / "dataset.parquet")
        settings = {k: cfg["bc"][k] for k in ("hidden", "epochs", "batch_size", "learning_rate",
                                               "alpha", "val_fraction", "seed")}
        t0 = time.perf_counter()
        _, _, rep = train(df, **settings)
        print(f"training: {len(df)} rows ({rep['n_train']} train / {rep['n_val']} val), "
              f"{settings['epochs']} epochs, hidden {settings['hidden']}: "
              f"{time.perf_counter() - t0:.1f} s; best epoch {rep['best_epoch']}, "
              f"val MSE {rep['best_val_mse']:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
