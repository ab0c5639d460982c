"""SPC (surface pollution cleanup): reset geometry, mass budget, success rule, the cleanup
rate over the fixed metric horizon, near-collisions, determinism; the public view: the
briefing, the aerial survey (the team observation), the task's own cue."""

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
from oneocean.tasks.common import O_CE, O_CN, O_DEPTH, O_GX, O_GY, O_GZ, O_X, O_Z, STANDARD
from oneocean.tasks.tiers import load_task_table
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
    from oneocean.tasks.regime import current_regime, site_speed

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


def _blocks(W, e, nbz, nbx):
    """The aerial map of episode ``e``'s field, by numpy: block masses (kg) and mass
    centroids (m; 0 where empty)."""
    b, h = spc.AERIAL_BLOCK_CELLS, spc.FIELD_H_M
    C = W.C[e, 0]
    nz, nx = C.shape
    pad = np.zeros((nbz * b, nbx * b, 3))
    X, Z = np.meshgrid(W.origin[e, 0] + h * np.arange(nx), W.origin[e, 1] + h * np.arange(nz))
    pos = C > 0.0
    pad[:nz, :nx, 0] = np.where(pos, C, 0.0)
    pad[:nz, :nx, 1] = np.where(pos, C * X, 0.0)
    pad[:nz, :nx, 2] = np.where(pos, C * Z, 0.0)
    s = pad.reshape(nbz, b, nbx, b, 3).sum(axis=(1, 3)).reshape(-1, 3)
    m = s[:, 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        return (m * h * h, np.where(m > 0, s[:, 1] / m, 0.0), np.where(m > 0, s[:, 2] / m, 0.0))


def test_briefing_and_the_aerial_survey_team_observation(calm):
    """The briefing holds the spill report and the survey's schedule and layout; the team
    observation is the task's aerial map: none before the first overflight (one aerial
    period after the start), then a new one every period, kept in between; the oracle (given
    the true target) has the exact map every step from step 0. Each map is the field at its
    step summed over the survey's blocks (masses, mass centroids, the total)."""
    from oneocean.tasks.public import COMMON

    init = spc.reset(calm, TIER, 4, 2, 0)
    ep = Episodes(spc, calm, TIER, init, "heuristic", "kinematic", VEHICLE, 0)
    B, T = ep.B, ep.C.T
    assert isinstance(B, spc.SPCBriefing)
    assert B._fields == tuple(COMMON) + tuple(spc.BRIEF_FIELDS)
    np.testing.assert_array_equal(B.report, init["report"])
    np.testing.assert_array_equal(B.field_origin, init["origin"])
    assert (B.spill_radius, B.depth, B.field_h) == (TIER["spill_radius_m"], spc.SURFACE_Y_M,
                                                     spc.FIELD_H_M)
    assert B.aerial_period_s == TIER["aerial_period_s"] == B.aerial_first_s
    assert (B.removal_radius, B.removal_rate, B.target_fraction) == (
        TIER["removal_radius_m"], TIER["removal_rate_s"], TIER["target_fraction"])
    n = spc.field_frame(TIER["domain_m"])[0]
    nb1 = -(-n // spc.AERIAL_BLOCK_CELLS)
    assert B.block_cells == spc.AERIAL_BLOCK_CELLS and B.map_nbx == B.map_nbz == nb1
    assert isinstance(T, spc.SPCTeamObs) and T._fields == tuple(spc.TEAM_FIELDS)
    assert T.mass.shape == T.x.shape == T.z.shape == (2, nb1 * nb1)
    ep.run(19)   # the observation of step 19: no map yet
    assert np.isnan(T.t_map).all() and (T.mass == 0.0).all() and (T.total == 0.0).all()
    for k in (20, 39, 40):
        ep.run(k)   # the observation of step k (taken before the agents move)
        np.testing.assert_array_equal(T.t_map, init["t0"] + 20.0 * (k // 20))
        if k % 20 == 0:
            for e in range(2):
                m, x, z = _blocks(ep.W, e, nb1, nb1)
                np.testing.assert_allclose(T.mass[e], m, rtol=1e-12, atol=1e-12)
                np.testing.assert_allclose(T.x[e], x, rtol=1e-12)
                np.testing.assert_allclose(T.z[e], z, rtol=1e-12)
                assert T.total[e] == pytest.approx(pol.total_mass(ep.W.C[e], spc.FIELD_H_M),
                                                   rel=1e-12)
                assert T.total[e] == pytest.approx(m.sum(), rel=1e-12)
                assert 0.0 < T.total[e] < spc.SPILL_MASS_KG   # the team removes oil
    # the oracle: the exact map every step, from step 0
    o = Episodes(spc, calm, TIER, init, "oracle", "kinematic", VEHICLE, 0)
    assert o.B.aerial_period_s == TIER["dt_s"] and o.B.aerial_first_s == 0.0
    for k in (0, 1, 7):
        o.run(k)
        np.testing.assert_array_equal(o.C.T.t_map, init["t0"] + k)
        m, _, _ = _blocks(o.W, 0, nb1, nb1)
        np.testing.assert_allclose(o.C.T.mass[0], m, rtol=1e-12, atol=1e-12)


def _cue_reference(pos, mass, x, z, frac):
    """The task's cue assignment, by its documented rule: the blocks of at least ``frac`` of
    the heaviest's mass, heaviest first (lower index on ties), each to the nearest agent
    without one, round after round."""
    q = [b for b in np.argsort(-mass, kind="stable") if mass[b] >= frac * mass.max()]
    free = list(range(len(pos)))
    out = np.empty((len(pos), 2))
    for j in range(len(pos)):
        b = q[j % len(q)]
        d = [(pos[i, 0] - x[b]) ** 2 + (pos[i, 1] - z[b]) ** 2 for i in free]
        i = free.pop(int(np.argmin(d)))
        out[i] = x[b], z[b]
    return out


def test_the_tasks_cue_ring_then_the_mapped_blocks_drifting_with_the_current(coast):
    """The task's own cue (every method gets it): a ring of CUE_RING_FRAC spill radii around
    the spill report before the first map, then at every map each agent's block by the
    documented assignment (its mass centroid); in between it drifts from its time with the
    agent's current estimate of the previous observation. At the operating depth."""
    init = spc.reset(coast, TIER, 6, 2, 1)
    ep = Episodes(spc, coast, TIER, init, "heuristic", "kinematic", VEHICLE, 1, record=True)
    ep.run(20)
    T = ep.C.T
    O20 = ep.C.O.copy()
    snap = [a.copy() for a in T]
    ep.run()
    obs = ep.obs
    n = 6
    ring = spc.CUE_RING_FRAC * TIER["spill_radius_m"]
    a = 2.0 * np.pi * np.arange(n) / n
    for e in range(2):
        cue = lambda k: np.stack([obs[e, k, :, O_GX] + obs[e, k, :, O_X],  # noqa: E731
                                  obs[e, k, :, O_GZ] + obs[e, k, :, O_Z]], 1)
        np.testing.assert_allclose(obs[e, :, :, O_GY] + obs[e, :, :, O_DEPTH], spc.SURFACE_Y_M,
                                   atol=1e-9)
        ring0 = init["report"][e] + ring * np.stack([np.sin(a), np.cos(a)], 1)
        np.testing.assert_allclose(cue(0), ring0, atol=1e-9)
        for k in (1, 7, 19):
            drift = np.stack([obs[e, k - 1, :, O_CE], obs[e, k - 1, :, O_CN]], 1) * k
            np.testing.assert_allclose(cue(k), ring0 + drift, atol=1e-9)
        # the map of step 20: the assignment on the agents' known positions, no drift yet
        pos = O20[e][:, [O_X, O_Z]]
        blocks = _cue_reference(pos, snap[1][e], snap[2][e], snap[3][e], spc.CUE_MASS_FRAC)
        np.testing.assert_array_equal(obs[e, 20][:, [O_X, O_Z]], pos)
        np.testing.assert_allclose(cue(20), blocks, atol=1e-9)
        assert len({tuple(b) for b in blocks}) > 1          # the team is spread
        for k in (21, 33):
            drift = np.stack([obs[e, k - 1, :, O_CE], obs[e, k - 1, :, O_CN]], 1) * (k - 20)
            np.testing.assert_allclose(cue(k), blocks + drift, atol=1e-9)


def test_a_follower_of_the_cue_cleans(coast):
    """A policy that only closes its cue offset through the water (0.5 s-1, capped at
    v_max; the cue drifts with the water) cleans the slick: it reaches the target in the
    episodes the heuristic does, with a cleanup rate near the heuristic's."""
    init = spc.reset(coast, TIER, 6, 4, 2)
    ep = Episodes(spc, coast, TIER, init, None, "kinematic", VEHICLE, 2)
    v = VEHICLE.v_max
    O = ep.observe()
    while not ep.done.all():
        w = 0.5 * np.nan_to_num(O[..., [O_GX, O_GY, O_GZ]])
        nw = np.linalg.norm(w, axis=-1, keepdims=True)
        ep.set_actions(np.where(nw > v, w * v / np.maximum(nw, 1e-12), w))
        O = ep.step_observe()
    r = ep.results()
    h = rollout(spc, coast, TIER, init, "heuristic", "kinematic", VEHICLE, 2)
    assert h["success"].all() and r["success"].all()
    assert np.all(r["cleanup_rate"] > h["cleanup_rate"] - 0.1)


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
