"""Calibration table of the scene tiers (``scene_tiers`` of RF, G2G, SK, FT) in every scene.

Builds the scenes of ``config/config.yaml`` (``scenes.list``) from the default region's
exports, then prints per scene, task and tier the success rate of the heuristic on the
CALIBRATION seeds (each tier table's ``calibration.seeds``; the evaluation seed is refused),
on the MuJoCo backend and, for the compare scene, on the core with the same episodes.
``--set TASK.TIER.KEY=VALUE`` overrides a scene tier parameter for this run (sweeps).

Usage::

    python benchmarks/calibrate_scenes.py [--tasks RF G2G] [--episodes 10] [--scenes dam]
        [--set RF.3.xte_max_m=2.5]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from calibrate import calibration_seeds, overrides, parse_sets  # noqa: E402 (same folder)

ROOT = Path(__file__).resolve().parents[1]
EXPORTS = ROOT / "results" / "exports" / "synthetic_coast" / "scene"


def main(argv=None) -> None:
    from oneocean.backends.mujoco.scenes import build_scene
    from oneocean.product.zarrio import read_npz
    from oneocean.tasks import Cell
    from oneocean.tasks.tiers import scene_tasks

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", nargs="+", default=list(scene_tasks()))
    ap.add_argument("--tiers", nargs="+", type=int, default=[1, 2, 3])
    ap.add_argument("--scenes", nargs="+", default=None)
    ap.add_argument("--episodes", type=int, default=10, help="per seed")
    ap.add_argument("--seeds", nargs="+", type=int, default=None)
    ap.add_argument("--set", action="append", default=[], metavar="TASK.TIER.KEY=VALUE")
    a = ap.parse_args(argv)
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["scenes"]
    seeds = calibration_seeds(a.tasks, a.seeds)
    grid = read_npz(EXPORTS / "grid.npz", "grid export")
    temporal = read_npz(EXPORTS / "temporal.npz", "temporal export")
    rows = []
    t_all = time.time()
    with overrides(parse_sets(a.set)):
        for spec in cfg["list"]:
            if a.scenes and spec["name"] not in a.scenes:
                continue
            scene = build_scene(spec, grid, temporal)
            backends = ("mujoco", "core") if spec["name"] == cfg["compare"] else ("mujoco",)
            for task in a.tasks:
                for tier in a.tiers:
                    for backend in backends:
                        cell = Cell(None, task, tier, backend=backend, scene=scene)
                        dfs = [cell.run("heuristic", a.episodes, s, "6dof") for s in seeds]
                        df = pd.concat(dfs)
                        rows.append({"scene": spec["name"], "task": task, "tier": tier,
                                     "backend": backend,
                                     "SR": 100.0 * df["success"].mean(),
                                     "primary": df["primary"].mean(),
                                     "T_s": df["T_s"].mean(), "viol": df["violations"].mean(),
                                     "cur": df["current_speed_ms"].mean()})
                        print(pd.DataFrame([rows[-1]]).to_string(header=len(rows) == 1,
                                                                  index=False,
                                                                  float_format="%.2f"),
                              flush=True)
    print(f"# seeds {seeds}, {a.episodes} episodes each; {time.time() - t_all:.0f} s")


if __name__ == "__main__":
    main()
