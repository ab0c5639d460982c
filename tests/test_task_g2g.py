"""G2G (go-to-goal): reset geometry, success rule, energy allocation, metrics, planning through
the field (the heuristic on its forecast, the oracle on the truth, the straight-line crabber),
determinism, tier table."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.engine import status as st
from oneocean.engine.dynamics import P_VMAX
from oneocean.errors import ConfigError, NotApplicable
from oneocean.tasks.routing import power_model
from oneocean.methods.heuristic import g2g as POLICY
from oneocean.tasks import g2g, run_cell
from oneocean.tasks.common import STANDARD
from oneocean.tasks.regime import site_speed
from oneocean.tasks.spawn import path_clear
from oneocean.tasks.tiers import load_task_table
from oneocean.tasks.episodes import Episodes, rollout
from oneocean.testing import uniform_grid
from oneocean.vocab import EVALUATION_SEED
from task_helpers import assert_tier_table_monotone

TIER = {"time_limit_s": 600.0,
        "goal_distance_m": 550.0, "goal_radius_m": 10.0, "dt_s": 1.0}


@pytest.fixture(scope="module")
def calm():
    return E.load_grid(uniform_grid(0.0, 0.0, depth_m=60.0, nx=21, ny=21, dx_m=100.0))


def _run(grid, tier, method, dyn="kinematic", n=6, seed=0, vehicle=None, info=None):
    init = g2g.reset(grid, tier, 1, n, seed)
    return init, rollout(g2g, grid, tier, init, method, dyn, vehicle or E.load_vehicle(), seed,
                         info=info)


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


def test_both_fly_the_transit_at_the_least_energy_speed(calm):
    # No throttle on either method: both plan the same least-energy transit on the task's
    # vehicle (REMUS 100, 2.5 m/s limit): in calm water its maximum-range speed, 1.25 m/s
    # (data/vehicles.yaml power model). Kinematic, given the truth: 540 m / 1.25 m/s = 432
    # steps, E = 432 * 1.25^2, and the energy is the power model's P(1.25) for 432 s.
    veh = E.load_vehicle(load_task_table("G2G")["vehicle"])
    assert veh.v_max == 2.5
    tier = {**TIER, "goal_radius_m": 10.5}
    _, r = _run(calm, tier, "heuristic", vehicle=veh, info="truth")
    assert r["success"].all()
    np.testing.assert_array_equal(r["T_s"], 432.0)
    np.testing.assert_allclose(r["E"], 432 * 1.25 ** 2)
    pw = power_model("remus100")
    np.testing.assert_allclose(r["energy_wh"], 432 * float(pw.power(1.25)) / 3600.0)
    _, ro = _run(calm, tier, "oracle", vehicle=veh)
    for k in ("T_s", "E", "final_error_m", "path_length_m", "energy_wh"):
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
    # full 2.5 m/s; they differ only in what they know: the heuristic's sensors (current
    # estimate, dead-reckoning navigation) vs the true current and position.
    grid = E.load_grid(uniform_grid(1.0, 0.0, depth_m=60.0, nx=41, ny=41, dx_m=100.0))
    veh = E.load_vehicle(load_task_table("G2G")["vehicle"])
    init = g2g.reset(grid, TIER, 1, 12, 0)

    def run(method, info=None):
        return rollout(g2g, grid, TIER, init, method, "6dof", veh, 0, info=info)

    ro = run("oracle")
    assert ro["success"].all()
    # given the truth, the heuristic IS the oracle, bit for bit
    rh0 = run("heuristic", "truth")
    for k in ("success", "T_s", "E", "final_error_m", "min_error_m", "path_length_m"):
        np.testing.assert_array_equal(rh0[k], ro[k], err_msg=k)
    # with its sensors it steers by an estimate: it heads where it THINKS the goal is, off by
    # its dead-reckoning error (~1 % of 550 m): a 2 m goal radius it misses, the oracle not
    tight = {**TIER, "goal_radius_m": 2.0}
    ro = rollout(g2g, grid, tight, init, "oracle", "6dof", veh, 0)
    rh = rollout(g2g, grid, tight, init, "heuristic", "6dof", veh, 0)
    rp = rollout(g2g, grid, tight, init, "heuristic", "6dof", veh, 0, info="true_position")
    assert ro["success"].all() and not rh["success"].all()
    assert rh["T_s"].mean() > ro["T_s"].mean()
    # its navigation is what it lacks: given its true position it arrives like the oracle
    assert rp["success"].all()


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
        assert {"current_ms", "time_limit_s", "energy_reserve", "forecast_lead_h"} <= set(tiers[t])
    # tiers are made by the ocean (absolute current bands, m/s), the mission (distance),
    # the tolerances (the energy reserve) and the forecast's lead, never by a method knob
    assert tiers[3]["current_ms"][0] > tiers[1]["current_ms"][0]
    assert tiers[3]["goal_distance_m"] > tiers[1]["goal_distance_m"]
    assert tiers[3]["energy_reserve"] < tiers[1]["energy_reserve"]
    assert tiers[3]["forecast_lead_h"] > tiers[1]["forecast_lead_h"]
    # at Tier 3 the current is a large fraction of the cruise speed (and at times more)
    assert tiers[3]["current_ms"][0] >= 0.4 * 1.25
    # the transit task flies the torpedo AUV; calibrated on seeds that exclude the
    # evaluation seed
    assert table["vehicle"] == "remus100"
    assert EVALUATION_SEED not in table["calibration"]["seeds"]
    assert table["agents"] == {"default": 1, "range": [1, 1]}
    assert math.isclose(table["dt_s"], 1.0)


# ------------------------------------------------------------------------------ energy, planning

def _jet_grid(jet_ms, half_width_m, n=41, dx=100.0):
    """A land-free 4 km grid, calm except an eastward jet of ``jet_ms`` in |z| <= half_width."""
    g = uniform_grid(0.0, 0.0, depth_m=60.0, nx=n, ny=n, dx_m=dx)
    z = -0.5 * (n - 1) * dx + dx * np.arange(n)
    g["u"][:, :, np.abs(z) <= half_width_m, :] = jet_ms
    return E.load_grid(g)


def _west(d=3000.0):
    """One episode from x = +d/2 to x = -d/2 along z = 0 at 5 m."""
    return {"pos0": np.array([[[0.5 * d, 5.0, 0.0]]]), "goal": np.array([[-0.5 * d, 5.0, 0.0]]),
            "psi0": np.array([[-math.pi / 2]]), "t0": np.zeros(1)}


def test_energy_allocation_is_the_best_plan_plus_the_reserve():
    grid = E.load_grid(uniform_grid(-0.6, 0.2, depth_m=60.0, nx=41, ny=41, dx_m=100.0))
    tier = {**TIER, "goal_distance_m": 3000.0, "time_limit_s": 4000.0, "goal_radius_m": 20.0,
            "energy_reserve": 0.05}
    init = _west()
    P, W = g2g.make(grid, tier, init)
    # E_ref: the least-energy transit on the true field: the straight line at the speed
    # with the least energy per metre (west, with a 0.6 m/s following and 0.2 m/s cross
    # current: ground speed 0.6 + sqrt(u^2 - 0.2^2))
    pw = power_model("remus100")
    per_m = min((pw.hotel_w + pw.k * u ** 3) / (0.6 + math.sqrt(u * u - 0.04))
                for u in np.arange(0.75, 2.51, 0.25))
    np.testing.assert_allclose(W.eref[0], 3000.0 * per_m, rtol=1e-6)   # float32 field
    np.testing.assert_allclose(W.budget[0], 1.05 * W.eref[0])
    veh = E.load_vehicle("remus100")
    # the oracle flies that plan within its allocation (kinematic: to the goal radius)
    r = rollout(g2g, grid, tier, init, "oracle", "kinematic", veh, 0)
    assert r["success"][0] and 0.98 < r["energy_ratio"][0] <= 1.0
    # an allocation it cannot meet: it arrives, over its allocation, and fails
    ep = Episodes(g2g, grid, tier, init, "oracle", "kinematic", veh, 0)
    ep.W.budget[:] = 0.5 * ep.W.eref
    r = ep.run().results()
    assert not r["success"][0] and r["energy_ratio"][0] > 0.98
    assert r["final_error_m"][0] <= 20.0 and r["T_s"][0] == tier["time_limit_s"]
    with pytest.raises(ConfigError, match="energy_reserve"):
        g2g.make(grid, {**tier, "energy_reserve": -0.1}, init)
    # without a reserve there is no allocation (the task's old success rule)
    P, W = g2g.make(grid, {k: v for k, v in tier.items() if k != "energy_reserve"}, init)
    assert np.isinf(W.budget).all()


def test_planner_beats_the_straight_line_crabber_on_a_jet(monkeypatch):
    # a 1.1 m/s head current in a 400 m band along the straight line, calm outside: the
    # planners leave it; the crabber that flies the straight line at its cruise speed
    # crawls at 0.15 m/s over ground and spends its allocation
    grid = _jet_grid(1.1, 200.0)
    # (a 60 m radius: the heuristic navigates by dead reckoning, ~1 % of 3.5 km)
    tier = {**TIER, "goal_distance_m": 3000.0, "time_limit_s": 6000.0, "goal_radius_m": 60.0,
            "energy_reserve": 0.10, "forecast_lead_h": 24.0}
    veh = E.load_vehicle("remus100")
    init = _west()
    ro = rollout(g2g, grid, tier, init, "oracle", "6dof", veh, 0)
    rh = rollout(g2g, grid, tier, init, "heuristic", "6dof", veh, 0)
    assert ro["success"][0] and rh["success"][0]
    # the plan leaves the jet: the oracle's track is longer than the straight line
    assert ro["path_length_m"][0] > 3000.0 + 2 * 150.0
    ep = Episodes(g2g, grid, tier, init, "oracle", "6dof", veh, 0)
    assert np.max(np.abs(ep.H.wps[0, :ep.H.wcount[0], 1])) > 200.0
    # the straight line through the jet costs several times the plan's energy
    monkeypatch.setattr(POLICY, "plan_episode", lambda B, M, e: POLICY.straight_plan(
        M, (B.start[e, 0], B.start[e, 2]), (B.goal[e, 0], B.goal[e, 2]), B.t0[e]))
    rs = rollout(g2g, grid, tier, init, "heuristic", "6dof", veh, 0)
    assert not rs["success"][0] and rs["energy_ratio"][0] >= 1.10
    assert rs["final_error_m"][0] > 1000.0      # still in the jet at the time limit


def test_forecast_planner_spends_more_and_fails_where_the_oracle_succeeds():
    # a uniform 0.9 m/s head current, a 2 % reserve and a 4-day-old forecast: the oracle
    # flies the least-energy speed; the heuristic (given its true position, so that the
    # forecast is the only difference) picks its speed from the forecast
    grid = E.load_grid(uniform_grid(0.9, 0.0, depth_m=60.0, nx=41, ny=41, dx_m=100.0))
    tier = {**TIER, "goal_distance_m": 3000.0, "time_limit_s": 8000.0, "goal_radius_m": 20.0,
            "energy_reserve": 0.02, "forecast_lead_h": 96.0}
    veh = E.load_vehicle("remus100")
    n = 8
    init = {"pos0": np.tile([[[1500.0, 5.0, 0.0]]], (n, 1, 1)),
            "goal": np.tile([[-1500.0, 5.0, 0.0]], (n, 1)),
            "psi0": np.full((n, 1), -math.pi / 2), "t0": np.zeros(n)}
    ro = rollout(g2g, grid, tier, init, "oracle", "kinematic", veh, 0)
    rh = rollout(g2g, grid, tier, init, "heuristic", "kinematic", veh, 0, info="true_position")
    assert ro["success"].all()
    # never less energy than the oracle's least-energy plan (to the goal radius' rounding)
    assert np.all(rh["energy_ratio"] >= ro["energy_ratio"] - 1e-3)
    assert np.mean(rh["energy_ratio"] > ro["energy_ratio"] + 0.01) >= 0.5
    assert not rh["success"].all()
    # given the truth it is the oracle again, bit for bit
    rt = rollout(g2g, grid, tier, init, "heuristic", "kinematic", veh, 0, info="truth")
    for k in ("success", "T_s", "E", "energy_wh", "final_error_m"):
        np.testing.assert_array_equal(rt[k], ro[k], err_msg=k)


def test_a_small_reset_draws_few_candidates_and_keeps_the_same_ones(coast, monkeypatch):
    """The band's candidates are drawn in batches sized to what is still needed: a reset of a
    few episodes draws a few candidates (it drew 32 at a time), and which are kept does not
    depend on it (the first candidates in the band, in the seed's order)."""
    tier = {**TIER, "goal_distance_m": 1500.0, "time_limit_s": 3000.0, "current_ms": [0.0, 5.0]}
    calls = []
    real = g2g.sample_routes

    def counted(grid, rngs, *a, **k):       # candidates drawn: the streams' rows
        calls.extend([1] * rngs.shape[0])
        return real(grid, rngs, *a, **k)

    monkeypatch.setattr(g2g, "sample_routes", counted)
    one = g2g.reset(coast, tier, 1, 1, 4)
    assert len(calls) == 2        # every candidate is in this band: 1.25 x 1, rounded up
    calls.clear()
    many = g2g.reset(coast, tier, 1, 24, 4)
    assert len(calls) == 30
    for k in one:
        np.testing.assert_array_equal(one[k], many[k][:1])
    # a narrow band keeps the same episodes whatever the batch sizes
    narrow = {**tier, "current_ms": [0.5, 0.6]}
    a = g2g.reset(coast, narrow, 1, 2, 4)
    b = g2g.reset(coast, narrow, 1, 6, 4)
    np.testing.assert_array_equal(a["goal"], b["goal"][:2])
    np.testing.assert_array_equal(a["t0"], b["t0"][:2])


def test_a_candidate_that_cannot_be_drawn_fails_the_reset_only_when_the_scan_reaches_it(
        coast, monkeypatch):
    """Candidate c's route that cannot be drawn (NotApplicable) fails every reset that needs
    a candidate at or after c, and no reset that is done before c, whatever the batch sizes."""
    tier = {**TIER, "goal_distance_m": 1500.0, "time_limit_s": 3000.0, "current_ms": [0.0, 5.0]}
    real = g2g.sample_routes
    ref = g2g.reset(coast, tier, 1, 3, 4)

    def flaky(*a, **k):
        routes, failed = real(*a, **k)
        for j in range(routes.shape[0]):
            if k["what"](j).endswith("(candidate 3)"):
                failed[j] = NotApplicable(f"{k['what'](j)}: no valid route")
        return routes, failed

    monkeypatch.setattr(g2g, "sample_routes", flaky)
    for n in (1, 2, 3):   # every candidate is in this band: candidates 0..n-1 are kept
        got = g2g.reset(coast, tier, 1, n, 4)   # n = 3 draws candidate 3 too (4 = 1.25 x 3)
        for k in ref:
            np.testing.assert_array_equal(got[k], ref[k][:n], err_msg=k)
    for n in (4, 5, 24):
        with pytest.raises(NotApplicable, match=r"\(candidate 3\): no valid route"):
            g2g.reset(coast, tier, 1, n, 4)


def test_absolute_current_band(coast):
    tier = {**TIER, "goal_distance_m": 1500.0, "time_limit_s": 3000.0}
    init = g2g.reset(coast, {**tier, "current_ms": [0.5, 0.6]}, 1, 6, 4)
    def line(i, e):
        return np.linspace(i["pos0"][e, 0], i["goal"][e], 5)

    sp = [site_speed(coast, line(init, e), init["t0"][e], 1500.0 / 1.25) for e in range(6)]
    assert all(0.5 <= s <= 0.6 for s in sp)
    # the first candidates in the band, in the seed's order: the same episodes as without it
    plain = g2g.reset(coast, tier, 1, 40, 4)
    ok = [0.5 <= site_speed(coast, line(plain, e), plain["t0"][e], 1200.0) <= 0.6
          for e in range(40)]
    np.testing.assert_array_equal(init["goal"], plain["goal"][np.flatnonzero(ok)[:6]])
    with pytest.raises(NotApplicable, match="0.8-2 m/s"):
        g2g.reset(coast, {**tier, "current_ms": [0.8, 2.0]}, 1, 2, 0)
    with pytest.raises(ConfigError, match="current_ms"):
        g2g.reset(coast, {**tier, "current_ms": [0.6, 0.2]}, 1, 2, 0)
