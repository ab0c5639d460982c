"""G2G (go-to-goal): reset geometry, success rule, metrics, determinism, tier table."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.engine import status as st
from oneocean.engine.dynamics import P_VMAX
from oneocean.errors import ConfigError
from oneocean.tasks import g2g, run_cell
from oneocean.tasks.common import STANDARD, load_task_table, path_clear
from oneocean.tasks.episodes import rollout
from oneocean.testing import make_test_grid, uniform_grid
from oneocean.vocab import EVALUATION_SEED
from task_helpers import assert_tier_table_monotone

TIER = {"time_limit_s": 600.0, "probe_noise_ms": 0.1,
        "goal_distance_m": 550.0, "goal_radius_m": 10.0, "dt_s": 1.0}


@pytest.fixture(scope="module")
def calm():
    return E.load_grid(uniform_grid(0.0, 0.0, depth_m=60.0, nx=21, ny=21, dx_m=100.0))


@pytest.fixture(scope="module")
def coast():
    return E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))


def _run(grid, tier, method, dyn="kinematic", n=6, seed=0, vehicle=None):
    init = g2g.reset(grid, tier, 1, n, seed)
    return init, rollout(g2g, grid, tier, init, method, dyn, vehicle or E.load_vehicle(), seed)


def test_reset_geometry_is_valid(coast):
    init = g2g.reset(coast, TIER, 1, 12, seed=3)
    p0, goal = init["pos0"][:, 0], init["goal"]
    assert p0.shape == (12, 3) and goal.shape == (12, 3)
    np.testing.assert_allclose(np.linalg.norm(goal - p0, axis=1), TIER["goal_distance_m"])
    np.testing.assert_allclose(p0[:, 1], goal[:, 1])  # same depth
    lo, hi = g2g.DEPTH_RANGE_M
    assert np.all((p0[:, 1] >= lo) & (p0[:, 1] <= hi))
    codes = E.feasibility(coast, np.vstack([p0, goal]), 0.5, g2g.MIN_ALTITUDE_M)
    assert np.all(codes == st.OK)
    assert all(path_clear(coast, a, b, g2g.MIN_ALTITUDE_M) for a, b in zip(p0, goal))
    t_end = init["t0"] + TIER["time_limit_s"]
    assert np.all(init["t0"] >= coast.time_s[0]) and np.all(t_end <= coast.time_s[-1])
    # facing the goal
    d = goal - p0
    np.testing.assert_allclose(init["psi0"][:, 0], np.arctan2(d[:, 0], d[:, 2]))


def test_reset_raises_when_impossible(calm):
    with pytest.raises(ConfigError, match="G2G"):  # 2 km grid, 5 km goal distance
        g2g.reset(calm, {**TIER, "goal_distance_m": 5000.0}, 1, 2, 0)
    shallow = E.load_grid(uniform_grid(0.0, 0.0, depth_m=8.0))
    with pytest.raises(ConfigError, match="G2G"):  # cannot keep 5 m altitude at 2-10 m depth
        g2g.reset(shallow, TIER, 1, 2, 0)
    with pytest.raises(ConfigError, match="single-agent"):
        g2g.reset(calm, TIER, 2, 2, 0)


def test_oracle_reaches_goal_in_calm_water_exactly(calm):
    # The task's success rule and metrics, not the vehicle: the kinematic model on the
    # generic test vehicle (v_max = 2 m/s, no turning circle). No current: 2 m per step at
    # full speed; within 10.5 m of 550 m after 270 steps.
    veh = E.load_vehicle("generic_auv")
    assert veh.v_max == 2.0
    _, r = _run(calm, {**TIER, "goal_radius_m": 10.5}, "oracle", vehicle=veh)
    assert r["success"].all()
    np.testing.assert_array_equal(r["T_s"], 270.0)
    np.testing.assert_allclose(r["E"], 270 * 2.0 ** 2)  # E = sum ||a||^2 dt
    np.testing.assert_allclose(r["final_error_m"], 10.0, atol=1e-6)
    np.testing.assert_allclose(r["path_length_m"], 540.0)
    np.testing.assert_array_equal(r["coll_ratio"], 0.0)
    np.testing.assert_array_equal(r["violations"], 0)


def test_heuristic_flies_at_full_speed_like_the_oracle(calm):
    # No throttle: the heuristic gets the task vehicle's full speed too (REMUS 100, 2.5 m/s).
    # Kinematic, no current, noise off: 540 m / 2.5 m/s = 216 steps, E = 216 * 2.5^2.
    veh = E.load_vehicle(load_task_table("G2G")["vehicle"])
    assert veh.v_max == 2.5
    tier = {**TIER, "probe_noise_ms": 0.0, "goal_radius_m": 10.5}
    _, r = _run(calm, tier, "heuristic", vehicle=veh)
    assert r["success"].all()
    np.testing.assert_array_equal(r["T_s"], 216.0)
    np.testing.assert_allclose(r["E"], 216 * 2.5 ** 2)
    _, ro = _run(calm, tier, "oracle", vehicle=veh)
    for k in ("T_s", "E", "final_error_m", "path_length_m"):
        np.testing.assert_array_equal(r[k], ro[k])


def test_do_nothing_fails_with_time_limit(calm):
    veh = E.load_vehicle()
    p = veh.params.copy()
    p[P_VMAX] = 0.0
    still = dataclasses.replace(veh, params=p)
    init, r = _run(calm, TIER, "oracle", vehicle=still)
    assert not r["success"].any()
    np.testing.assert_array_equal(r["T_s"], TIER["time_limit_s"])  # T on failure = limit
    np.testing.assert_array_equal(r["E"], 0.0)
    np.testing.assert_allclose(r["final_error_m"], TIER["goal_distance_m"])


def test_current_stronger_than_vmax_defeats_both_methods():
    # goal 500 m upstream of a uniform 3 m/s current (> v_max = 2.5 m/s of the REMUS 100):
    # unreachable
    grid = E.load_grid(uniform_grid(-3.0, 0.0, depth_m=60.0, nx=41, ny=41, dx_m=100.0))
    init = {"pos0": np.array([[[0.0, 5.0, 0.0]]]), "goal": np.array([[500.0, 5.0, 0.0]]),
            "psi0": np.array([[math.pi / 2]]), "t0": np.zeros(1)}
    tier = {**TIER, "time_limit_s": 200.0}
    for method in ("oracle", "heuristic"):
        r = rollout(g2g, grid, tier, init, method, "6dof", E.load_vehicle(), 0)
        assert not r["success"][0]
        assert r["T_s"][0] == 200.0
        assert r["final_error_m"][0] > 500.0  # pushed away
    # the same goal downstream is reached
    init["goal"] = np.array([[-500.0, 5.0, 0.0]])
    r = rollout(g2g, grid, tier, init, "heuristic", "6dof", E.load_vehicle(), 0)
    assert r["success"][0] and r["T_s"][0] < 200.0


def test_heuristic_differs_from_oracle_only_in_information():
    # 1 m/s head current everywhere, 6dof REMUS 100 (the task's vehicle). Both methods get the
    # full 2.5 m/s; they differ only in what they sense: the heuristic's noisy probe vs the
    # exact current.
    grid = E.load_grid(uniform_grid(1.0, 0.0, depth_m=60.0, nx=41, ny=41, dx_m=100.0))
    veh = E.load_vehicle(load_task_table("G2G")["vehicle"])
    init = g2g.reset(grid, TIER, 1, 12, 0)

    def run(method, noise):
        tier = {**TIER, "probe_noise_ms": noise}
        return rollout(g2g, grid, tier, init, method, "6dof", veh, 0)

    ro = run("oracle", 0.5)
    assert ro["success"].all()
    # probe noise 0: the heuristic IS the oracle, bit for bit
    rh0 = run("heuristic", 0.0)
    for k in ("success", "T_s", "E", "final_error_m", "min_error_m", "path_length_m"):
        np.testing.assert_array_equal(rh0[k], ro[k], err_msg=k)
    # with probe noise the heuristic's feed-forward is wrong every step: a longer, slower,
    # costlier track than the oracle's on the same episodes
    rh = run("heuristic", 0.5)
    assert rh["success"].all()
    assert rh["path_length_m"].mean() > ro["path_length_m"].mean() + 0.5
    assert rh["T_s"].mean() > ro["T_s"].mean()
    assert rh["E"].mean() > ro["E"].mean()


def test_run_cell_deterministic_and_columns(coast):
    a = run_cell(coast, "G2G", 2, "heuristic", episodes=6, seed=5)
    b = run_cell(coast, "G2G", 2, "heuristic", episodes=6, seed=5)
    pd.testing.assert_frame_equal(a, b)
    c = run_cell(coast, "G2G", 2, "heuristic", episodes=6, seed=6)
    assert not np.array_equal(a["final_error_m"].to_numpy(), c["final_error_m"].to_numpy())
    for k in STANDARD + ("primary",) + g2g.METRICS:
        assert k in a.columns
    np.testing.assert_array_equal(a["primary"], a["final_error_m"])


def test_tier_table_monotone_and_declared():
    table = load_task_table("G2G")
    tiers = table["tiers"]
    assert_tier_table_monotone(table)
    for t in (1, 2, 3):
        assert set(tiers[t]) == set(table["harder"])
        assert {"current_band", "time_limit_s", "probe_noise_ms"} <= set(tiers[t])
    # the region-relative current regime: Tier 3 is the region's fastest third
    assert tiers[3]["current_band"] == [0.67, 1.0]
    # the transit task flies the torpedo AUV; calibrated on seeds that exclude the
    # evaluation seed
    assert table["vehicle"] == "remus100"
    assert EVALUATION_SEED not in table["calibration"]["seeds"]
    assert table["agents"] == {"default": 1, "range": [1, 1]}
    assert math.isclose(table["dt_s"], 1.0)
