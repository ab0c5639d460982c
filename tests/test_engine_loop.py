"""The engine inside the one episode loop: rejected moves, energy, near-collisions, spawning,
determinism across thread counts, and the per-episode Parquet writer.

Agents are driven with external actions (the step API's path) through G2G (one agent) and FT
(several agents) with the tasks' own ends switched off (``task_helpers.external_episodes``).
"""

from __future__ import annotations

import hashlib

import numba
import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.engine import constraints as C
from oneocean.engine import dynamics as D
from oneocean.engine import status as st
from oneocean.errors import ConfigError
from oneocean.io import sha256_file
from oneocean.tasks import Cell, run_cell
from oneocean.tasks.episodes import Episodes
from oneocean.tasks.loop import C_COLL, C_E, C_VIOL
from oneocean.testing import make_test_grid, uniform_grid
from task_helpers import drive, external_episodes


@pytest.fixture(scope="module")
def grid():
    return E.load_grid(make_test_grid())


@pytest.fixture(scope="module")
def flat():
    return E.load_grid(uniform_grid(0.0, 0.0, depth_m=100.0, nx=21, ny=21, dx_m=100.0))


@pytest.mark.parametrize("model", ["kinematic", "3dof", "4dof", "6dof"])
def test_move_into_land_is_rejected(grid, model):
    """Driving west into the coast: every rejected move keeps the position and zeroes the
    velocity, is counted, and the agent never leaves the valid set."""
    x_water = -2450.0  # deep enough for y = 2 + clearance near the coast at x ~ -2790
    ep = external_episodes(grid, [[[x_water, 2.0, 0.0]]], 500, dyn=model)
    ep.set_actions(np.array([[[-2.0, 0.0, 0.0]]]))
    viol, rejected = 0, 0
    for k in range(ep.n_steps):
        before = ep.state[0, 0].copy()
        ep.run(k + 1)
        s = ep.state[0, 0]
        assert C.check_move(grid, s[0], s[1], s[2], 0.5, 1.0) == st.OK
        if ep.LS.viol[0] > viol:
            rejected += 1
            np.testing.assert_array_equal(s[:3], before[:3])           # position kept
            np.testing.assert_array_equal(s[D.U:D.W + 1], 0.0)          # velocity zeroed
            np.testing.assert_array_equal(s[D.VX:D.VZ + 1], 0.0)
        viol = ep.LS.viol[0]
    assert rejected == viol > 0
    assert ep.done.all() and ep.res[0, C_VIOL] == viol
    assert s[0] < x_water - 150.0  # it did get to the coast


def test_each_violation_kind_is_counted(flat):
    # seafloor: dive at 1 m/s from 95 m on a 100 m flat floor with 1 m clearance: 4 moves,
    # then 6 rejections at y = 99
    ep = external_episodes(flat, [[[0.0, 95.0, 0.0]]], 10)
    drive(ep, np.tile([0.0, 1.0, 0.0], (10, 1, 1, 1)))
    assert ep.res[0, C_VIOL] == 6 and ep.state[0, 0, 1] == 99.0
    assert C.check_move(flat, 0.0, 100.0, 0.0, 0.5, 1.0) == st.SEAFLOOR
    # outside: drive off the east edge (x_max = 1000): 5 moves, then 5 rejections
    ep = external_episodes(flat, [[[995.0, 5.0, 0.0]]], 10)
    drive(ep, np.tile([1.0, 0.0, 0.0], (10, 1, 1, 1)))
    assert ep.res[0, C_VIOL] == 5 and ep.state[0, 0, 0] == 1000.0
    assert C.check_move(flat, 1001.0, 5.0, 0.0, 0.5, 1.0) == st.OUTSIDE


def test_energy_is_sum_of_clipped_action_squared(flat):
    rng = np.random.default_rng(0)
    acts = rng.normal(0, 2.0, (50, 2, 3, 3))
    pos = np.tile(np.array([0.0, 50.0, 0.0]), (2, 3, 1)) + np.arange(3)[None, :, None] * 10.0
    veh = D.load_vehicle(overrides={"speed_limit_ms": 1.5})
    ep = external_episodes(flat, pos, 50, dt=0.5, vehicle=veh)
    drive(ep, acts)
    n = np.linalg.norm(acts, axis=3)
    expect = (np.minimum(n, 1.5) ** 2 * 0.5).sum(axis=(0, 2))  # team energy per episode
    np.testing.assert_allclose(ep.res[:, C_E], expect, rtol=1e-12)
    assert ep.res[0, C_E] != ep.res[1, C_E]


def test_collision_steps_counted(flat):
    # two agents approach head on at 1 m/s each from 20 m apart: within r_coll = 2 m from step 9
    ep = external_episodes(flat, [[[-10.0, 5.0, 0.0], [10.0, 5.0, 0.0]]], 20)
    traj = drive(ep, np.tile([[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]], (20, 1, 1, 1)))
    # distance after step k (1-based) is 20 - 2k; <= 2 for k in 9..11 (agents pass through)
    expect = sum(1 for k in range(1, 21) if abs(20 - 2 * k) <= 2.0)
    assert expect == 3 and ep.LS.coll[0] == expect
    assert ep.res[0, C_COLL] == expect / 20
    np.testing.assert_array_equal(traj[10, 0, :, 0], [0.0, 0.0])
    # the closest pair distance over the episode (3-D, after each step): 0 when they meet
    assert ep.LS.dmin[0] == 0.0
    d = np.linalg.norm(traj[1:, 0, 0] - traj[1:, 0, 1], axis=1)
    assert ep.LS.dmin[0] == d.min()


def test_spawn_is_valid_deterministic_and_fails_loudly(grid):
    pos = E.spawn_positions(grid, 7, 50, {"y": (1.0, 20.0)}, min_separation=10.0)
    assert pos.shape == (50, 3)
    assert np.all(C.feasibility(grid, pos) == st.OK)
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2) + np.eye(50) * 1e9
    assert d.min() >= 10.0
    np.testing.assert_array_equal(pos, E.spawn_positions(grid, 7, 50, {"y": (1.0, 20.0)},
                                                         min_separation=10.0))
    assert not np.array_equal(pos, E.spawn_positions(grid, 8, 50, {"y": (1.0, 20.0)},
                                                     min_separation=10.0))
    alt = E.spawn_positions(grid, 1, 20, {"altitude": (2.0, 5.0)})
    floor = -np.array([E.sample_elevation(grid, x, z) for x, _, z in alt])
    assert np.all((floor - alt[:, 1] >= 2.0 - 1e-9) & (floor - alt[:, 1] <= 5.0 + 1e-9))
    land_box = {"x": (grid.x0, grid.x0 + 100.0), "y": (1.0, 2.0)}
    with pytest.raises(ConfigError, match=r"spawn: found only 0 of 3 valid positions.*land: "):
        E.spawn_positions(grid, 0, 3, land_box, max_candidates=2000)
    with pytest.raises(ConfigError, match="unknown keys"):
        E.spawn_positions(grid, 0, 3, {"depth": (0, 1)})


def test_min_pairwise_distance_matches_brute_force():
    rng = np.random.default_rng(3)
    for n in (1, 2, 5, 10):
        p = rng.normal(0, 10, (n, 16))
        d = np.linalg.norm(p[:, None, :3] - p[None, :, :3], axis=2) + np.diag(np.full(n, np.inf))
        assert E.min_pairwise_distance(p) == pytest.approx(d.min(), rel=1e-14)


def test_same_seed_byte_identical_on_one_and_two_threads():
    """A heuristic cell of a multi-agent task (FT, 4 agents, noisy probe, 6dof): results,
    states and recorded observations do not depend on the thread count."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs NUMBA_NUM_THREADS >= 2")
    coast = E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
    cell = Cell(coast, "FT", 1, n_agents=4)
    init = cell.reset(6, 3)

    def digest(threads):
        prev = numba.get_num_threads()
        numba.set_num_threads(threads)
        try:
            ep = Episodes(cell.mod, cell.grid, cell.params, init, "heuristic", "6dof",
                          cell.vehicle, 3, record=True).run()
        finally:
            numba.set_num_threads(prev)
        h = hashlib.sha256()
        for a in (ep.res, ep.state, ep.obs, ep.act, ep.LS.k):
            h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest(), ep.res

    (d1, r1), (d2, _), (d3, _) = digest(1), digest(2), digest(2)
    assert d1 == d2 == d3
    assert np.isfinite(r1).all() and (r1[:, C_E] > 0).all()


def test_parquet_bytes_are_deterministic_and_entry_complete(tmp_path):
    coast = E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
    df = run_cell(coast, "G2G", 1, "heuristic", episodes=3, seed=4)
    meta = {"dynamics": "6dof", "vehicle": E.load_vehicle().spec}
    e1 = E.write_metrics(df, tmp_path / "a" / "metrics.parquet", meta=meta)
    e2 = E.write_metrics(df.copy(), tmp_path / "b" / "metrics.parquet", meta=meta)
    assert e1["sha256"] == e2["sha256"] == sha256_file(e1["path"])
    assert e1["bytes"] > 0 and e1["rows"] == 3 and e1["kind"] == "episode_metrics"
    assert e1["columns"] == list(df.columns)
    assert e1["dynamics"] == "6dof"
    assert e1["vehicle"]["mass_kg"] == E.load_vehicle().spec["mass_kg"] > 0.0
    pd.testing.assert_frame_equal(pd.read_parquet(e1["path"]), df)
    assert not list((tmp_path / "a").glob(".*"))  # no temporary files left behind
    with pytest.raises(ConfigError, match="clashes with a reserved key"):
        E.write_metrics(df, tmp_path / "c.parquet", meta={"rows": 1})
