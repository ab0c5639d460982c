"""Batched rollouts: constraints, spawning, collisions, energy, controllers, determinism."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from oneocean import engine as E
from oneocean.engine import constraints as C
from oneocean.engine import controllers as K
from oneocean.engine import dynamics as D
from oneocean.engine import status as st
from oneocean.errors import ConfigError


@pytest.fixture(scope="module")
def grid():
    return E.load_grid(E.make_test_grid())


@pytest.fixture(scope="module")
def flat():
    return E.load_grid(E.uniform_grid(0.0, 0.0, depth_m=100.0, nx=21, ny=21, dx_m=100.0))


def _line(n, act):
    return np.tile(np.asarray(act, dtype=float), (n, 1, 1, 1))


@pytest.mark.parametrize("model", ["kinematic", "6dof"])
def test_move_into_land_is_rejected(grid, model):
    zc = 0.0
    x_water = -2450.0  # deep enough for y = 2 + clearance near the coast at x ~ -2790
    b = E.init_batch(np.array([[[x_water, 2.0, zc]]]))
    E.run(grid, b, E.open_loop_controller(_line(800, [-2.0, 0.0, 0.0])), 800, dynamics=model)
    s = b.state[0, 0]
    assert b.violations[0, 0] > 0
    assert b.status[0, 0] in (st.LAND, st.SEAFLOOR)
    assert E.check_move(grid, s[0], s[1], s[2], 0.5, 1.0) == st.OK  # never left the valid set
    np.testing.assert_array_equal(s[D.VX:D.VZ + 1], 0.0)  # velocity zeroed on rejection
    assert C.feasibility(grid, s[None, :3])[0] == st.OK


def test_each_violation_kind_is_coded(flat):
    g = flat
    # seafloor: dive to 100 m depth with 1 m clearance
    b = E.init_batch(np.array([[[0.0, 95.0, 0.0]]]))
    E.run(g, b, E.open_loop_controller(_line(10, [0.0, 1.0, 0.0])), 10, allow_time_clamp=True)
    assert b.status[0, 0] == st.SEAFLOOR and b.violations[0, 0] == 6
    assert b.positions[0, 0, 1] == 99.0
    # outside: drive off the east edge (x_max = 1000)
    b = E.init_batch(np.array([[[995.0, 5.0, 0.0]]]))
    E.run(g, b, E.open_loop_controller(_line(10, [1.0, 0.0, 0.0])), 10, allow_time_clamp=True)
    assert b.status[0, 0] == st.OUTSIDE and b.violations[0, 0] == 5
    assert b.positions[0, 0, 0] == 1000.0


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


def test_collision_steps_counted(flat):
    # two agents approach head on at 1 m/s each from 20 m apart: within r_coll = 2 m from step 9
    pos = np.array([[[-10.0, 5.0, 0.0], [10.0, 5.0, 0.0]]])
    acts = np.zeros((20, 1, 2, 3))
    acts[:, 0, 0, 0] = 1.0
    acts[:, 0, 1, 0] = -1.0
    b = E.init_batch(pos)
    E.run(flat, b, E.open_loop_controller(acts), 20, allow_time_clamp=True)
    # distance after step k (1-based) is 20 - 2k; <= 2 for k >= 9 (agents pass through)
    expect = sum(1 for k in range(1, 21) if abs(20 - 2 * k) <= 2.0)
    assert b.coll_steps[0] == expect
    assert b.min_dist[0] == 0.0
    df = E.episode_metrics(b, 1.0)
    assert df["coll_ratio"].iloc[0] == expect / 20


def test_energy_is_sum_of_clipped_action_squared(flat):
    rng = np.random.default_rng(0)
    acts = rng.normal(0, 2.0, (50, 2, 3, 3))
    b = E.init_batch(np.tile(np.array([0.0, 50.0, 0.0]), (2, 3, 1)) +
                     np.arange(3)[None, :, None] * 10.0)
    E.run(flat, b, E.open_loop_controller(acts), 50, dt=0.5, v_max=1.5, allow_time_clamp=True)
    n = np.linalg.norm(acts, axis=3)
    expect = (np.minimum(n, 1.5) ** 2 * 0.5).sum(axis=0)
    np.testing.assert_allclose(b.energy, expect, rtol=1e-12)
    df = E.episode_metrics(b, 0.5, teams=[0, 1, 1])
    np.testing.assert_allclose(df["E_team_0"], expect[:, 0], rtol=1e-12)
    np.testing.assert_allclose(df["E_team_1"], expect[:, 1:].sum(axis=1), rtol=1e-12)
    np.testing.assert_allclose(df["E"], expect.sum(axis=1), rtol=1e-12)


def test_bad_shapes_are_clear_errors(flat):
    b = E.init_batch(np.zeros((2, 3, 3)) + [0.0, 5.0, 0.0])
    with pytest.raises(ConfigError, match=r"controller actions: expected shape \(4, 2, 3, 3\)"):
        E.run(flat, b, E.open_loop_controller(np.zeros((4, 2, 2, 3))), 4)
    with pytest.raises(ConfigError, match=r"expected shape \(steps, episodes, agents, 3\)"):
        E.open_loop_controller(np.zeros((4, 2, 3)))
    with pytest.raises(ConfigError, match=r"controller goals: expected shape \(2, 3, 4\)"):
        E.run(flat, b, E.goal_controller(np.zeros((2, 2, 3))), 4)
    with pytest.raises(ConfigError, match="positions: expected shape"):
        E.init_batch(np.zeros((2, 3)))
    with pytest.raises(ConfigError, match="dynamics: invalid value 'rov'"):
        E.run(flat, b, E.goal_controller(np.zeros((2, 3, 3))), 4, dynamics="rov")


def test_time_range_is_checked(grid):
    b = E.init_batch(np.array([[[1000.0, 3.0, 0.0]]]), t0=float(grid.time_s[-1]) - 10.0)
    with pytest.raises(ConfigError, match="beyond the grid's time range"):
        E.run(grid, b, E.goal_controller(b.positions.copy()), 100)
    E.run(grid, b, E.goal_controller(b.positions.copy()), 100, allow_time_clamp=True)
    assert b.steps[0] == 100


def test_segments_resume_exactly(grid):
    pos = E.spawn_positions(grid, 2, 6, {"y": (2.0, 8.0)}).reshape(3, 2, 3)
    goals = pos + [40.0, 1.0, -30.0]
    runs = []
    for split in ((100,), (30, 70), (1, 49, 50)):
        b = E.init_batch(pos, seed=5, record_every=10, max_steps=100)
        ctrl = E.goal_controller(goals)
        for n in split:
            E.run(grid, b, ctrl, n, dynamics="6dof", action_noise=0.05)
        runs.append(b)
    for b in runs[1:]:
        np.testing.assert_array_equal(b.state, runs[0].state)
        np.testing.assert_array_equal(b.energy, runs[0].energy)
        np.testing.assert_array_equal(b.traj, runs[0].traj)


def test_action_noise_is_seeded(flat):
    pos = np.zeros((2, 1, 3)) + [0.0, 5.0, 0.0]
    out = []
    for seed in (1, 1, 2):
        b = E.init_batch(pos, seed=seed)
        E.run(flat, b, E.goal_controller(pos), 20, action_noise=0.1, allow_time_clamp=True)
        out.append(b.state.copy())
    np.testing.assert_array_equal(out[0], out[1])
    assert not np.array_equal(out[0], out[2])
    assert not np.array_equal(out[0][0], out[0][1])  # episodes get their own streams


def test_alive_mask_freezes_episodes(flat):
    pos = np.zeros((2, 1, 3)) + [0.0, 5.0, 0.0]
    b = E.init_batch(pos)
    b.alive[1] = 0
    E.run(flat, b, E.goal_controller(pos + [50.0, 0, 0]), 10, allow_time_clamp=True)
    assert b.steps.tolist() == [10, 0]
    np.testing.assert_array_equal(b.positions[1], pos[1])


def test_plan_controller_visits_waypoints_in_order(flat):
    wps = np.array([[[[50.0, 5.0, 0.0], [50.0, 5.0, 50.0], [0.0, 10.0, 50.0], [9.0, 9.0, 9.0]]]])
    b = E.init_batch(np.array([[[0.0, 5.0, 0.0]]]), record_every=1, max_steps=300)
    ctrl = E.plan_controller(wps, plan_len=np.array([[3]]), kp=0.5, wp_radius=2.0)
    E.run(flat, b, ctrl, 300, dynamics="4dof", allow_time_clamp=True)
    assert b.wp_idx[0, 0] == 2  # never beyond plan_len - 1
    np.testing.assert_allclose(b.positions[0, 0], wps[0, 0, 2], atol=0.05)
    traj = b.traj[0, 0].astype(float)
    first = [int(np.argmax(np.linalg.norm(traj - w, axis=1) < 2.5)) for w in wps[0, 0, :3]]
    assert first[0] < first[1] < first[2]


def test_mlp_controller_matches_numpy_forward(grid):
    rng = np.random.default_rng(4)
    sizes = [6 + 2, 16, 8, 3]
    ws = [rng.normal(0, 0.5, (a, b)) for a, b in zip(sizes[:-1], sizes[1:])]
    bs = [rng.normal(0, 0.1, b) for b in sizes[1:]]
    mean, std = rng.normal(0, 1, 8), rng.uniform(0.5, 2.0, 8)
    pos = E.spawn_positions(grid, 3, 4, {"y": (2.0, 8.0)}).reshape(2, 2, 3)
    goals = pos + rng.normal(0, 50, pos.shape)
    feats = rng.normal(0, 1, (2, 2, 2))
    ctrl = E.mlp_controller(ws, bs, goals, mean, std, features=feats, out_scale=0.7)
    b = E.init_batch(pos, t0=50.0)
    E.run(grid, b, ctrl, 1, v_max=100.0)
    sizes_a, flat_w = K.pack_mlp(ws, bs, mean, std)
    for e in range(2):
        for a in range(2):
            p = pos[e, a]
            ce, cn = E.sample_current(grid, *p, 50.0)
            x = np.concatenate([goals[e, a] - p, [ce, cn, p[1]], feats[e, a]])
            act = 0.7 * K.mlp_forward_py(sizes_a, flat_w, x)
            expect = p + (act + [ce, 0.0, cn]) * 1.0
            np.testing.assert_allclose(b.positions[e, a], expect, rtol=0, atol=1e-12)
    with pytest.raises(ConfigError, match="input width 8 != 6 base features"):
        E.mlp_controller(ws, bs, goals, mean, std)


def _state_digest_script(threads: int) -> str:
    return textwrap.dedent(f"""
        import hashlib, numpy as np
        from oneocean import engine as E
        g = E.load_grid(E.make_test_grid())
        pos = E.spawn_positions(g, 11, 24, {{"y": (2.0, 10.0)}}).reshape(8, 3, 3)
        goals = pos + np.array([60.0, 2.0, -40.0])
        h = hashlib.sha256()
        for model in ("kinematic", "6dof"):
            b = E.init_batch(pos, seed=3, t0=600.0, record_every=5, max_steps=80)
            E.run(g, b, E.goal_controller(goals), 80, dynamics=model, action_noise=0.1,
                  threads={threads})
            for a in (b.state, b.energy, b.violations, b.coll_steps, b.min_dist, b.traj):
                h.update(np.ascontiguousarray(a).tobytes())
        print(h.hexdigest())
    """)


def test_same_seed_byte_identical_on_one_and_two_threads():
    env = dict(os.environ, NUMBA_NUM_THREADS="2")
    out = []
    for threads in (1, 2, 2):
        r = subprocess.run([sys.executable, "-c", _state_digest_script(threads)], env=env,
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr[-2000:]
        out.append(r.stdout.strip())
    assert len(out[0]) == 64 and out[0] == out[1] == out[2]


def test_run_honours_thread_count(flat):
    import numba

    before = numba.get_num_threads()
    b = E.init_batch(np.zeros((4, 1, 3)) + [0.0, 5.0, 0.0])
    E.run(flat, b, E.goal_controller(b.positions.copy()), 2, threads=1, allow_time_clamp=True)
    assert numba.get_num_threads() == before
