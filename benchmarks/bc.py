"""What behaviour cloning costs: BC episodes next to heuristic episodes, and the training.

For every task at one tier, runs the same episodes with the heuristic and with ``bc`` (the
workflow's trained weights) in the fused loop, warm (numba cache loaded, one warm-up run
first), and prints the wall time and the cost per agent-step of both, side by side. Then it
times the training stage (``oneocean.methods.bc.train.train`` on the workflow's dataset with
the config's settings).

Usage: ``python benchmarks/bc.py [--tier 2] [--episodes 50] [--no-train] [--no-rollouts]
[--dataset PATH] [--baseline OLD_TRAIN_PY]`` from the repository root, after ``snakemake
--cores 2 paper_tables`` (it reads ``results/bc/<region>/<variant>/{dataset.parquet,
weights.npz}`` and the grid export; the training alone needs only the dataset).

``--baseline`` times another implementation of the training beside the current one, on the
same dataset and settings: a ``train.py`` file of ``oneocean.methods.bc`` from another
revision (``git show <rev>:src/oneocean/methods/bc/train.py > /tmp/train_old.py``). Each is
timed after a warm-up on a small part of the dataset (imports, numba compile or cache
load); the table gives the time, the kept epoch, the losses and the weights' hash.
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


def _load_train(path):
    """``train`` of a ``train.py`` file, imported inside ``oneocean.methods.bc`` (its relative
    imports resolve there)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("oneocean.methods.bc._train_baseline",
                                                  path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.train


def _time_training(train, df, settings):
    """Warm-up on the first two episodes of every cell, then the timed fit."""
    import hashlib

    train(df[df["episode"] < 2], **{**settings, "epochs": 1})
    t0 = time.perf_counter()
    _, w, rep = train(df, **settings)
    seconds = time.perf_counter() - t0
    digest = hashlib.sha256(b"".join(w[k].tobytes() for k in ("mu", "sd", "w", "b")))
    return seconds, w, rep, digest.hexdigest()[:12]


def _training(cfg, dataset, baseline) -> None:
    import numpy as np
    import pandas as pd

    from oneocean.methods.bc.train import train

    df = pd.read_parquet(dataset)
    settings = {k: cfg["bc"][k] for k in ("hidden", "epochs", "batch_size", "learning_rate",
                                           "alpha", "val_fraction", "seed")}
    runs = [("current", *_time_training(train, df, settings))]
    if baseline:
        runs.append((f"baseline ({Path(baseline).name})",
                     *_time_training(_load_train(baseline), df, settings)))
    rep = runs[0][3]
    print(f"training: {len(df)} rows ({rep['n_train']} train / {rep['n_val']} val), "
          f"{settings['epochs']} epochs, hidden {settings['hidden']}, 1 thread")
    print(f"{'implementation':28s} {'s':>7s} {'best epoch':>10s} {'best val MSE':>13s} "
          f"{'last train MSE':>15s} {'weights':>13s}")
    for name, seconds, _, r, digest in runs:
        print(f"{name:28s} {seconds:7.1f} {r['best_epoch']:10d} {r['best_val_mse']:13.6f} "
              f"{r['train_mse'][-1]:15.6f} {digest:>13s}")
    if baseline:
        (_, t_cur, w_cur, r_cur, _), (_, t_base, w_base, r_base, _) = runs
        dw = max(float(np.abs(w_cur[k] - w_base[k]).max()) for k in ("w", "b"))
        dv = abs(r_cur["best_val_mse"] - r_base["best_val_mse"]) / r_base["best_val_mse"]
        print(f"current / baseline time {t_cur / t_base:.2f}; max |weight difference| "
              f"{dw:.3g}; best val MSE differs by {100 * dv:.2f} %")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tier", type=int, default=2)
    ap.add_argument("--episodes", type=int, default=50)
    ap.add_argument("--no-train", action="store_true")
    ap.add_argument("--no-rollouts", action="store_true")
    ap.add_argument("--dataset", type=Path, default=None,
                    help="the training's dataset (default: the workflow's)")
    ap.add_argument("--baseline", type=Path, default=None,
                    help="a train.py of another revision to time beside the current one")
    args = ap.parse_args(argv)

    import numba

    from oneocean.config import load_config

    numba.set_num_threads(1)
    cfg = load_config(REPO / "config" / "config.yaml")
    region, variant = cfg["region"]["name"], cfg["rollouts"]["variant"]
    base = REPO / "results" / "bc" / region / variant
    if not args.no_rollouts:
        _rollouts(cfg, base, args.tier, args.episodes)
    if not args.no_train:
        _training(cfg, args.dataset or base / "dataset.parquet", args.baseline)
    return 0


def _rollouts(cfg, base, tier, episodes) -> None:
    from oneocean.engine import load_grid
    from oneocean.tasks.learned import load_weights
    from oneocean.tasks import Cell

    region, variant = cfg["region"]["name"], cfg["rollouts"]["variant"]
    grid = load_grid(REPO / "results" / "exports" / region / variant / "grid.npz")
    net = load_weights(base / "weights.npz")
    seed, dyn = cfg["rollouts"]["seed"], cfg["rollouts"]["dynamics"]
    print(f"{region}/{variant}, tier {tier}, {episodes} episodes, {dyn}, 1 thread")
    print("wall: episode sampling + rollout; ns/agent-step: the rollout alone (the loop's "
          "kernel) over the agent-steps it ran")
    print(f"{'task':5s} {'heuristic s':>12s} {'bc s':>8s} {'heur ns/agent-step':>19s} "
          f"{'bc ns/agent-step':>17s} {'bc/heur':>8s}")
    tot = [0.0, 0.0]
    for task in cfg["rollouts"]["tasks"]:
        cell = Cell(grid, task, tier)
        _timed(cell, "heuristic", 2, seed, dyn, None)     # warm-up (numba cache load)
        _timed(cell, "bc", 2, seed, dyn, net)
        th, rh, sh = _timed(cell, "heuristic", episodes, seed, dyn, None)
        tb, rb, sb = _timed(cell, "bc", episodes, seed, dyn, net)
        tot[0] += th
        tot[1] += tb
        print(f"{task:5s} {th:12.3f} {tb:8.3f} {1e9 * rh / sh:19.0f} {1e9 * rb / sb:17.0f} "
              f"{(rb / sb) / (rh / sh):8.2f}")
    print(f"{'all':5s} {tot[0]:12.3f} {tot[1]:8.3f}")


if __name__ == "__main__":
    sys.exit(main())
