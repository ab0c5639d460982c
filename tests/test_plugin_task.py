"""Adding a task from outside the package: one module + its tier YAML (+ its heuristic),
registered by a plugin, runs through run_cell, the step API, the workflow's rollout rule and
the success table (tests/plugins/oneocean_toy.py)."""

from __future__ import annotations

import copy
import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean import registry
from oneocean.testing import make_test_grid

PLUGINS = Path(__file__).with_name("plugins")


@pytest.fixture
def toy(monkeypatch):
    monkeypatch.syspath_prepend(str(PLUGINS))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(PLUGINS)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    import oneocean_toy

    registry.register_task(registry.load_task_spec(PLUGINS / "oneocean_toy.yaml"))
    yield oneocean_toy
    registry.unregister_task("TOY")


def test_toy_task_runs_through_run_cell_and_the_step_api(toy):
    from oneocean.evaluate import evaluate
    from oneocean.tasks import run_cell

    assert "TOY" in registry.task_ids() and registry.task_spec("TOY").primary == \
        "final_depth_error_m"
    grid = E.load_grid(make_test_grid(nt=3, nz=3, ny=30, nx=40, max_depth_m=60.0))
    h = run_cell(grid, "TOY", 1, "heuristic", episodes=4, seed=0)
    assert h["success"].all() and (h["final_depth_error_m"] <= 0.5).all()
    assert (h["task"] == "TOY").all() and (h["primary"] == h["final_depth_error_m"]).all()
    # the table's current band picks the episodes (candidates recorded); the vehicle is the
    # table's (generic_auv, 2 m/s). Tier 3 (8 s to rise 9-11 m): the toy heuristic's
    # half-speed climb (1 m/s: 8 m) cannot make it, the oracle's 2 m/s can
    h3 = run_cell(grid, "TOY", 3, "heuristic", episodes=4, seed=0, dynamics="kinematic")
    o3 = run_cell(grid, "TOY", 3, "oracle", episodes=4, seed=0, dynamics="kinematic")
    assert not h3["success"].any() and o3["success"].all()
    # the task's own metric is its column (not a standard one): above the tolerance where
    # the climb falls short, within it where it succeeds
    assert (h3["final_depth_error_m"] > 0.5).all() and (o3["final_depth_error_m"] <= 0.5).all()
    assert (h["final_depth_error_m"] > 0).all()
    np.testing.assert_array_equal(h3["candidate"], o3["candidate"])
    assert np.all(np.diff(h3["candidate"]) > 0)
    from oneocean.tasks import Cell
    assert Cell(grid, "TOY", 3).vehicle.name == "generic_auv"
    # a user's policy through the step API: climb straight up at 1 m/s
    up = evaluate(lambda obs: np.broadcast_to([0.0, -1.0, 0.0], obs.shape[:2] + (3,)),
                  "TOY", 1, grid, episodes=4, seed=0)
    assert up["success"].all()
    np.testing.assert_array_equal(up["episode"], h["episode"])


@pytest.mark.slow
def test_toy_task_runs_through_the_workflow_and_the_table(toy, tmp_path):
    from workflow_helpers import SMALL_CONFIG, run_workflow

    cfg = copy.deepcopy(SMALL_CONFIG)
    cfg["plugins"] = ["oneocean_toy"]
    cfg["rollouts"].update(tasks=["G2G", "TOY"], tiers=[1])
    run_workflow(tmp_path, targets=("paper_tables",), config=cfg)
    region = cfg["region"]["name"]
    df = pd.read_parquet(tmp_path / f"results/rollouts/{region}/public/TOY/tier1/heuristic.parquet")
    assert len(df) == cfg["rollouts"]["episodes"] and (df["task"] == "TOY").all()
    tex = (tmp_path / f"results/tables/{cfg['region']['name']}/task_success_by_tier.tex").read_text()
    assert "TOY" in tex and "G2G" in tex
