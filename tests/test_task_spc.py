"""SPC (surface pollution cleanup): reset geometry, mass budget, success rule, the cleanup
rate over the fixed metric horizon, near-collisions, determinism."""

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
from oneocean.models import pollution as pol
from oneocean.tasks import run_cell, spc
from oneocean.tasks.common import STANDARD, load_task_table
from oneocean.tasks.episodes import Episodes, rollout
from oneocean.testing import make_test_grid, uniform_grid
from task_helpers import assert_tier_table_monotone, on_one_thread

TIER = {"time_limit_s": 400.0, "spill_radius_m": 40.0, "target_fraction": 0.5, "staging_distance_m": 120.0,
        "removal_radius_m": 11.0, "removal_rate_s": 0.1, "kappa_m2s": 1.0, "domain_m": 300.0,
        "aerial_period_s": 20.0, "dt_s": 1.0}


def _grid(ce=0.0, cn=0.0, depth=30.0, n=21):
    return E.load_grid(uniform_grid(ce, cn, depth_m=depth, nx=n, ny=n, dx_m=100.0))


@pytest.fixture(scope="module")
def calm():
    return _grid()


@pytest.fixture(scope="module")
def coast():
    return E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))


#: The task's vehicle (its tier table): the BlueROV2 Heavy, 0.85 m/s.
VEHICLE = E.load_vehicle(load_task_table("SPC")["vehicle"])


def _run(grid, tier, method, n_agents=4, n=4, seed=0, dyn="kinematic", vehicle=None):
    init = spc.reset(grid, tier, n_agents, n, seed)
    return init, rollout(spc, grid, tier, init, method, dyn, vehicle or VEHICLE, seed)


def test_reset_geometry_is_valid(coast):
    init = spc.reset(coast, TIER, 6, 5, seed=3)
    n, half = spc.field_frame(TIER["domain_m"])
    assert init["C0"].shape == (5, 1, n, n) and init["land"].shape == (5, n, n)
    p0 = init["pos0"]
    assert p0.shape == (5, 6, 3)
    np.testing.assert_allclose(p0[..., 1], spc.SURFACE_Y_M)
    codes = E.feasibility(coast, p0.reshape(-1, 3), 0.5, spc.CLEARANCE_M)
    assert np.all(codes == st.OK)
    for e in range(5):
        m = pol.total_mass(init["C0"][e], spc.FIELD_H_M)
        assert math.isclose(m, spc.SPILL_MASS_KG, rel_tol=1e-9)
        assert np.all(init["C0"][e, 0][init["land"][e] != 0] == 0.0)  # no oil on land
        stg = p0[e, :, [0, 2]].T.mean(axis=0)
        d = np.linalg.norm(stg - (init["origin"][e] + half))
        assert abs(d - TIER["staging_distance_m"]) < 1e-6  # staging distance from the centre
        # teammates start apart (>= the staging spacing)
        dd = np.linalg.norm(p0[e, :, None] - p0[e, None], axis=2) + 1e9 * np.eye(6)
        assert dd.min() >= spc.STAGING_SPACING_M - 1e-9
    t_end = init["t0"] + TIER["time_limit_s"]
    assert np.all(init["t0"] >= coast.time_s[0]) and np.all(t_end <= coast.time_s[-1])


def test_staging_is_up_current():
    init = spc.reset(_grid(1.0, 0.0), TIER, 3, 6, 0)  # current toward +x (east)
    half = spc.field_frame(TIER["domain_m"])[1]
    rel = init["pos0"][:, :, 0].mean(axis=1) - (init["origin"][:, 0] + half)
    assert np.all(rel < -TIER["staging_distance_m"] * math.cos(spc.STAGING_SPREAD_RAD) + 1e-6)


def test_reset_raises_when_impossible(calm):
    with pytest.raises(ConfigError, match="n_agents"):
        spc.reset(calm, TIER, 1, 2, 0)
    with pytest.raises(ConfigError, match="n_agents"):
        spc.reset(calm, TIER, 11, 2, 0)
    with pytest.raises(ConfigError, match="SPC"):  # 2 km grid, 5 km staging distance
        spc.reset(calm, {**TIER, "staging_distance_m": 5000.0}, 3, 2, 0)
    with pytest.raises(ConfigError, match="SPC"):  # too shallow for a surface vehicle
        spc.reset(_grid(depth=1.0), TIER, 3, 2, 0)
    with pytest.raises(ConfigError, match="missing"):
        spc.reset(calm, {k: v for k, v in TIER.items() if k != "kappa_m2s"}, 3, 2, 0)


def test_tier3_spills_lie_in_the_tiers_current_band(coast):
    """Harder tiers put the spill in moving water through the generic current band
    (:class:`oneocean.tasks.Cell`): every kept Tier-3 spill's mean surface current over the
    episode (at the reported spill centre) lies between the tier's speed quantiles of the
    region, the band really removes candidates, and a band the region cannot fill is refused
    as not applicable with a named reason."""
    from oneocean.errors import NotApplicable
    from oneocean.tasks import Cell
    from oneocean.tasks.common import current_regime, site_speed

    cell = Cell(coast, "SPC", 3, n_agents=3)
    band = cell.params["current_band"]
    assert band == load_task_table("SPC")["tiers"][3]["current_band"] and band[0] > 0.0
    init = cell.reset(6, seed=1)
    reg = cell.regime
    assert reg is not None and reg.band == tuple(band) and 0.0 < reg.lo < reg.hi
    # the regime's bounds are the region's own surface-speed quantiles
    assert reg == current_regime(cell.grid_reset, cell.params, spc.SURFACE_Y_M)
    T = cell.params["time_limit_s"]
    for (x, z), t0 in zip(init["report"], init["t0"]):
        s = site_speed(cell.grid_reset, [[x, spc.SURFACE_Y_M, z]], t0, T)
        assert reg.lo <= s <= reg.hi
    # the band selects: some candidates (in seeded order) were skipped
    cand = init["candidate"]
    assert cand.shape == (6,) and np.all(np.diff(cand) > 0) and cand[-1] > 5
    # without the band the first six candidates are kept: spills in slacker water among them
    free = Cell(coast, "SPC", 3, n_agents=3)
    free.params = {k: v for k, v in free.params.items() if k != "current_band"}
    base = free.reset(6, seed=1)
    np.testing.assert_array_equal(base["candidate"], np.arange(6))
    speeds = [site_speed(coast, [[x, spc.SURFACE_Y_M, z]], t0, T)
              for (x, z), t0 in zip(base["report"], base["t0"])]
    assert min(speeds) < reg.lo
    # a band the region cannot fill: not applicable, named
    free.params = {**free.params, "current_band": [0.9999, 1.0]}
    with pytest.raises(NotApplicable, match="SPC tier 3.*current regime"):
        free.reset(6, seed=1)


@pytest.mark.parametrize("method", ["heuristic", "oracle"])
def test_mass_budget_closes(method):
    # strong current: mass escapes through the open sides; removed + escaped + remaining = 1
    grid = _grid(0.8, 0.3)
    _, r = _run(grid, {**TIER, "target_fraction": 0.99, "time_limit_s": 300.0}, method)
    tot = r["cleanup_rate"] + r["escaped_fraction"] + r["remaining_fraction"]
    np.testing.assert_allclose(tot, 1.0, atol=1e-6)
    assert np.all(r["escaped_fraction"] > 0.01) and np.all(r["cleanup_rate"] > 0.01)
    assert not r["success"].any()
    np.testing.assert_array_equal(r["T_s"], 300.0)
    np.testing.assert_array_equal(r["time_to_target_s"], 300.0)


def test_oracle_cleans_calm_water_and_success_rule(calm):
    _, r = _run(calm, TIER, "oracle")
    assert r["success"].all()
    # T is the time to success; the episode ran on to the metric horizon (the time limit),
    # so the cleanup rate is the removal over the whole horizon, beyond the target
    assert np.all(r["T_s"] < TIER["time_limit_s"])
    np.testing.assert_array_equal(r["T_s"], r["time_to_target_s"])
    assert np.all(r["cleanup_rate"] > TIER["target_fraction"] + 0.2)
    # calm water: only diffusion reaches the open sides, 150 m from a 40 m spill (over the
    # whole 400 s horizon: < 1e-3)
    np.testing.assert_allclose(r["escaped_fraction"], 0.0, atol=1e-3)
    np.testing.assert_array_equal(r["violations"], 0)
    # the heuristic (same ROV, same full speed; an aerial map aerial_period_s old, a noisy
    # probe, ring targets before the first map) also succeeds in calm water; with a fresh
    # 20 s map it is about as fast as the oracle (the slick barely moves) ...
    _, rh = _run(calm, TIER, "heuristic")
    assert rh["success"].all()
    assert abs(rh["T_s"].mean() - r["T_s"].mean()) < 0.1 * r["T_s"].mean()
    # ... while a stale map (Tier 2's 90 s) costs it time in every episode and removal at the
    # horizon: the methods differ in information
    _, rs = _run(calm, {**TIER, "aerial_period_s": 90.0}, "heuristic")
    assert rs["success"].all() and np.all(rs["T_s"] > r["T_s"])
    assert rs["cleanup_rate"].mean() < r["cleanup_rate"].mean() - 0.02


def test_runs_to_the_metric_horizon_with_standard_metrics_frozen_at_success(calm):
    """After success the episode runs on to the time limit (the loop's REACHED); T, E,
    violations and coll_ratio are what a run stopped at success reports: running in segments
    up to the success step gives the final E exactly, and later steps add nothing."""
    init = spc.reset(calm, TIER, 4, 3, 0)
    veh = E.load_vehicle()
    whole = Episodes(spc, calm, TIER, init, "oracle", "kinematic", veh, 0).run()
    r = whole.results()
    assert r["success"].all()
    n_steps = int(TIER["time_limit_s"])
    np.testing.assert_array_equal(whole.LS.k, n_steps)          # ran to the horizon
    np.testing.assert_array_equal(whole.LS.k_succ * 1.0, r["T_s"])  # T = time to success
    seg = Episodes(spc, calm, TIER, init, "oracle", "kinematic", veh, 0)
    for e in range(3):
        seg.run(int(whole.LS.k_succ[e]))
        assert seg.LS.energy[e] == r["E"][e] and seg.LS.coll[e] == whole.LS.coll[e]
    seg.run()
    np.testing.assert_array_equal(seg.res, whole.res)           # resumable, bit for bit
    assert np.all(seg.LS.energy == r["E"])


def test_cleanup_rate_is_removed_mass_over_the_fixed_horizon(calm):
    """Hand-checkable: two agents parked on a spill that does not move (calm water, no
    diffusion) remove the fraction f = removal_rate_s dt of every cell within removal_radius_m
    at every step (twice where both footprints cover it), so after K steps
    removed / initial = sum_c C_c (1 - (1 - f)^(m_c K)) / sum_c C_c. Success comes at the
    first step that reaches the target; the cleanup rate is the value at K = the horizon."""
    init = spc.reset(calm, TIER, 2, 1, 0)
    n, half = spc.field_frame(TIER["domain_m"])
    c = init["origin"][0] + half
    init["pos0"][0] = [[c[0] - 3.0, spc.SURFACE_Y_M, c[1]], [c[0] + 3.0, spc.SURFACE_Y_M, c[1]]]
    veh = E.load_vehicle()
    p = veh.params.copy()
    p[P_VMAX] = 0.0
    still = dataclasses.replace(veh, params=p)
    K = 120
    tier = {**TIER, "kappa_m2s": 0.0, "time_limit_s": float(K), "removal_rate_s": 0.02}
    ci = np.arange(n) * spc.FIELD_H_M
    X, Z = np.meshgrid(init["origin"][0, 0] + ci, init["origin"][0, 1] + ci)
    m = sum((np.hypot(X - a[0], Z - a[2]) <= tier["removal_radius_m"]).astype(int)
            for a in init["pos0"][0])
    C0 = init["C0"][0, 0]
    f = tier["removal_rate_s"] * tier["dt_s"]
    frac = lambda k: float(np.sum(C0 * (1.0 - (1.0 - f) ** (m * k))) / C0.sum())  # noqa: E731
    assert 0.1 < frac(K) < 0.9   # (the footprints cover part of the spill)
    target = 0.5 * frac(K)
    k_hit = next(k for k in range(1, K + 1) if frac(k) >= target)
    r = rollout(spc, calm, {**tier, "target_fraction": target}, init, "oracle", "kinematic",
                still, 0)
    assert r["success"][0]
    assert r["T_s"][0] == r["time_to_target_s"][0] == k_hit * tier["dt_s"]
    assert r["cleanup_rate"][0] == pytest.approx(frac(K), rel=1e-9)
    assert r["cleanup_rate"][0] > 1.9 * target            # beyond the target fraction
    assert r["escaped_fraction"][0] == pytest.approx(0.0, abs=1e-12)
    assert r["remaining_fraction"][0] == pytest.approx(1.0 - frac(K), rel=1e-9)
    # the same horizon without a reachable target: the same cleanup rate, no success
    r2 = rollout(spc, calm, {**tier, "target_fraction": 0.99}, init, "oracle", "kinematic",
                 still, 0)
    assert not r2["success"][0] and r2["T_s"][0] == K
    assert r2["cleanup_rate"][0] == r["cleanup_rate"][0]


def test_near_collisions_on_a_head_on_pass(calm):
    """Coll (eq. 4) through the SPC kernel: two vehicles 20 m apart driven head-on at 1 m/s
    each (external actions, kinematic, calm water) are within r_coll = 2 m after steps 9, 10
    and 11 of 30 (distances 2, 0, 2 m): Coll = 3 / 30; the closest distance is 0."""
    init = spc.reset(calm, TIER, 2, 1, 0)
    half = spc.field_frame(TIER["domain_m"])[1]
    c = init["origin"][0] + half + [0.0, 100.0]   # off the spill: nothing to remove
    init["pos0"][0] = [[c[0] - 10.0, spc.SURFACE_Y_M, c[1]],
                       [c[0] + 10.0, spc.SURFACE_Y_M, c[1]]]
    tier = {**TIER, "time_limit_s": 30.0, "target_fraction": 0.99}
    ep = Episodes(spc, calm, tier, init, None, "kinematic", E.load_vehicle(), 0)
    ep.set_actions(np.array([[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]]))
    r = ep.run().results()
    assert r["coll_ratio"][0] == pytest.approx(3.0 / 30.0)
    assert ep.LS.coll[0] == 3 and ep.LS.dmin[0] == pytest.approx(0.0, abs=1e-9)
    # 2.5 m apart at the closest (parallel lanes 2.5 m apart): never
    init["pos0"][0, 1, 2] += 2.5
    ep = Episodes(spc, calm, tier, init, None, "kinematic", E.load_vehicle(), 0)
    ep.set_actions(np.array([[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]]))
    r = ep.run().results()
    assert r["coll_ratio"][0] == 0.0 and ep.LS.dmin[0] == pytest.approx(2.5)


def test_fused_teams_closest_distance_and_coll_agree(coast):
    """The fused teams start on a 6 m lattice and steer away from teammates closer than SEP_M
    (4.5 m), which is why Coll is rare; the loop records every episode's closest pair
    distance up to success (LoopState.dmin) and Coll > 0 exactly when it was <= 2 m."""
    init = spc.reset(coast, TIER, 6, 4, 1)
    for method in ("heuristic", "oracle"):
        ep = Episodes(spc, coast, TIER, init, method, "6dof", VEHICLE, 1).run()
        r = ep.results()
        assert np.all(np.isfinite(ep.LS.dmin)) and np.all(ep.LS.dmin > 0.0)
        assert np.all(ep.LS.dmin < spc.STAGING_SPACING_M)
        np.testing.assert_array_equal(r["coll_ratio"] > 0, ep.LS.dmin <= spc.R_COLL_M)


def test_do_nothing_fails(calm):
    veh = E.load_vehicle()
    p = veh.params.copy()
    p[P_VMAX] = 0.0
    still = dataclasses.replace(veh, params=p)
    _, r = _run(calm, TIER, "oracle", vehicle=still)
    assert not r["success"].any()
    np.testing.assert_array_equal(r["T_s"], TIER["time_limit_s"])
    np.testing.assert_array_equal(r["E"], 0.0)
    # parked 120 m from the centre: only the diffused fringe reaches the footprints or the
    # open sides in 400 s
    assert np.all(r["cleanup_rate"] < 5e-3) and np.all(r["escaped_fraction"] < 5e-3)
    np.testing.assert_allclose(r["remaining_fraction"], 1.0, atol=1e-2)


def test_hand_made_success_threshold(calm):
    # agents parked on the spill centre (v_max = 0): the removal alone decides success
    init = spc.reset(calm, TIER, 2, 1, 0)
    half = spc.field_frame(TIER["domain_m"])[1]
    c = init["origin"][0] + half
    init["pos0"][0] = [[c[0] - 3.0, spc.SURFACE_Y_M, c[1]], [c[0] + 3.0, spc.SURFACE_Y_M, c[1]]]
    veh = E.load_vehicle()
    p = veh.params.copy()
    p[P_VMAX] = 0.0
    still = dataclasses.replace(veh, params=p)
    tier = {**TIER, "kappa_m2s": 0.0, "time_limit_s": 50.0}
    r = rollout(spc, calm, tier, init, "oracle", "kinematic", still, 0)
    got = r["cleanup_rate"][0]
    assert 0.0 < got < 1.0 and not r["success"][0]
    assert r["coll_ratio"][0] == 0.0  # 6 m apart
    r2 = rollout(spc, calm, {**tier, "target_fraction": got * 0.9}, init, "oracle", "kinematic",
                 still, 0)
    assert r2["success"][0] and r2["T_s"][0] < 50.0
    # parked 1 m apart: every step is a near collision
    init["pos0"][0, 1, 0] = c[0] - 2.0
    r3 = rollout(spc, calm, tier, init, "oracle", "kinematic", still, 0)
    assert r3["coll_ratio"][0] == 1.0


def test_run_cell_deterministic_threads_and_columns(coast):
    a = run_cell(coast, "SPC", 2, "heuristic", episodes=3, seed=5, n_agents=4)
    b = run_cell(coast, "SPC", 2, "heuristic", episodes=3, seed=5, n_agents=4)
    pd.testing.assert_frame_equal(a, b)
    c = on_one_thread(run_cell, coast, "SPC", 2, "heuristic", episodes=3, seed=5, n_agents=4)
    pd.testing.assert_frame_equal(a, c)
    d = run_cell(coast, "SPC", 2, "heuristic", episodes=3, seed=6, n_agents=4)
    assert not np.array_equal(a["cleanup_rate"].to_numpy(), d["cleanup_rate"].to_numpy())
    for k in STANDARD + ("primary",) + spc.METRICS:
        assert k in a.columns
    np.testing.assert_array_equal(a["primary"], a["cleanup_rate"])


def test_tier_table_monotone_and_declared():
    table = load_task_table("SPC")
    tiers = table["tiers"]
    assert_tier_table_monotone(table)
    for t in (1, 2, 3):
        # the current band is the Cell's (region-relative regime), not the task module's
        assert set(tiers[t]) == set(table["harder"]) == set(spc._TIER_KEYS) | {"current_band"}
    # cleanup inside a drifting slick: the hovering, crabbing ROV
    assert table["vehicle"] == "bluerov2_heavy"
    assert table["agents"] == {"default": 10, "range": [2, 10]}
    assert math.isclose(table["dt_s"], 1.0)


def test_face_refresh_equals_the_current_at_the_faces_across_intervals():
    # the faces keep their current over one interval of the time axis in parts: every
    # refresh, forward, backward and across the axis's times, gives the sampler's bits
    g = E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0),
                    tide=(0.2, 1e-4, 0.3))
    nz, nx, h, y = 7, 9, 20.0, 0.5
    x0, z0 = 0.5 * (g.x0 + g.x_max), 0.5 * (g.z0 + g.z_max)      # open water
    uf, vf = np.zeros((nz, nx + 1)), np.zeros((nz + 1, nx))
    key = np.full(2, -1, np.int64)
    part = np.zeros((nz * (nx + 1) + (nz + 1) * nx, 4))
    jx, ix = np.meshgrid(np.arange(nz), np.arange(nx + 1), indexing="ij")
    jz, iz = np.meshgrid(np.arange(nz + 1), np.arange(nx), indexing="ij")
    xf = np.column_stack([x0 + (ix.ravel() - 0.5) * h, np.full(ix.size, y), z0 + jx.ravel() * h])
    zf = np.column_stack([x0 + iz.ravel() * h, np.full(iz.size, y), z0 + (jz.ravel() - 0.5) * h])
    for t in (100.0, 3000.0, 3600.0, 3601.0, 9000.0, 500.0, 14400.0, 20000.0, 7200.0):
        spc._refresh_faces(g, uf, vf, x0, z0, h, y, key, part, t)
        want_u = E.sample_currents(g, xf, np.full(len(xf), t))[:, 0].reshape(uf.shape)
        want_v = E.sample_currents(g, zf, np.full(len(zf), t))[:, 1].reshape(vf.shape)
        assert (part[:, :2] != 0.0).all()           # the data's currents, not only the tide
        np.testing.assert_array_equal(uf.view(np.int64), want_u.view(np.int64))
        np.testing.assert_array_equal(vf.view(np.int64), want_v.view(np.int64))
