"""Per-episode metrics and trajectories: columnar files, manifest entries, deterministic bytes."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.errors import ConfigError
from oneocean.io import sha256_file


@pytest.fixture(scope="module")
def batch_and_goals():
    g = E.load_grid(E.make_test_grid())
    pos = E.spawn_positions(g, 5, 12, {"y": (2.0, 8.0)}, min_separation=3.0).reshape(4, 3, 3)
    goals = pos + np.array([30.0, 1.0, 20.0])
    b = E.init_batch(pos, seed=9, episode_ids=np.arange(100, 104), record_every=7,
                     max_steps=60)
    ctrl = E.goal_controller(goals)
    E.run(g, b, ctrl, 40, dynamics="4dof")
    b.alive[2] = 0  # episode 102 ends early
    E.run(g, b, ctrl, 20, dynamics="4dof")
    return b, goals, ctrl


def test_metrics_frame(batch_and_goals):
    b, goals, _ = batch_and_goals
    ok = np.array([True, False, True, False])
    df = E.episode_metrics(b, 1.0, goals=goals, success=ok, t_success=np.array([12.0, 0, 30, 0]),
                           teams=[0, 0, 1], extra={"coverage": np.arange(4) / 4})
    assert df["episode"].tolist() == [100, 101, 102, 103]
    assert df["steps"].tolist() == [60, 60, 40, 60]
    assert df["T_s"].tolist() == [12.0, 60.0, 30.0, 60.0]  # success time, else episode time
    assert (df["seed"] == 9).all()
    np.testing.assert_allclose(df["E"], df["E_team_0"] + df["E_team_1"])
    err = np.linalg.norm(b.positions - goals, axis=2)
    np.testing.assert_allclose(df["final_error_m"], err.mean(axis=1))
    assert list(df.columns[-1:]) == ["coverage"]
    with pytest.raises(ConfigError, match="teams: expected shape"):
        E.episode_metrics(b, 1.0, teams=[0, 1])


def test_parquet_bytes_are_deterministic_and_entry_complete(tmp_path, batch_and_goals):
    b, goals, ctrl = batch_and_goals
    df = E.episode_metrics(b, 1.0, goals=goals)
    meta = {"dynamics": "4dof", "vehicle": E.load_vehicle().spec, "controller": ctrl.describe()}
    e1 = E.write_metrics(df, tmp_path / "a" / "metrics.parquet", meta=meta)
    e2 = E.write_metrics(df.copy(), tmp_path / "b" / "metrics.parquet", meta=meta)
    assert e1["sha256"] == e2["sha256"] == sha256_file(e1["path"])
    assert e1["bytes"] > 0 and e1["rows"] == 4 and e1["kind"] == "episode_metrics"
    assert e1["dynamics"] == "4dof" and e1["vehicle"]["mass_kg"] == 40.0
    back = pd.read_parquet(e1["path"])
    pd.testing.assert_frame_equal(back, df)
    assert not list((tmp_path / "a").glob(".*"))  # no temporary files left behind


def test_trajectories_one_file_long_format(tmp_path, batch_and_goals):
    b, _, _ = batch_and_goals
    entry = E.write_trajectories(b, tmp_path / "traj.parquet", 1.0, meta={"dynamics": "4dof"})
    t = pd.read_parquet(entry["path"])
    # samples every 7 steps at 0, 7, ..., 56; episode 102 stopped at step 40
    k_full, k_short = len(range(0, 61, 7)), len(range(0, 41, 7))
    assert len(t) == entry["rows"] == 3 * (3 * k_full + k_short)
    row = t[(t.episode == 101) & (t.agent == 2) & (t.step == 56)]
    np.testing.assert_allclose(row[["x", "y", "z"]].to_numpy()[0], b.traj[1, 2, 8], rtol=0)
    first = t[t.step == 0].sort_values(["episode", "agent"])
    assert first["x"].notna().all()
    e2 = E.write_trajectories(b, tmp_path / "traj2.parquet", 1.0, meta={"dynamics": "4dof"})
    assert e2["sha256"] == entry["sha256"]
    with pytest.raises(ConfigError, match="recorded no trajectories"):
        E.write_trajectories(E.init_batch(np.zeros((1, 1, 3))), tmp_path / "x.parquet", 1.0)
