"""FH (fish herding): reset geometry, fish stay in water, success rule, metrics, determinism
(seeds and threads), tier table; the public view: briefing, the sonar's observation fields,
the team observation and the task's herding cue."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.engine import status as st
from oneocean.engine.dynamics import P_VMAX
from oneocean.errors import ConfigError
from oneocean.models.fish import fish_params, init_school, school_spread, step_school
from oneocean.tasks import fh, run_cell
from oneocean.tasks.episodes import Episodes, rollout
from oneocean.tasks.common import STANDARD
from oneocean.tasks.spawn import path_clear
from oneocean.tasks.tiers import load_task_table, tier_params
from oneocean.tasks.public import COMMON
from oneocean.testing import make_test_grid, uniform_grid
from task_helpers import assert_tier_table_monotone, on_one_thread

TIER = {"current_band": [0.0, 1.0], "time_limit_s": 600.0, "fish_count": 60,
        "zone_distance_m": 100.0, "zone_radius_m": 10.0, "hold_s": 20.0, "dt_s": 1.0}
N = fh.N_AGENTS


@pytest.fixture(scope="module")
def calm():
    return E.load_grid(uniform_grid(0.0, 0.0, depth_m=30.0, nx=21, ny=21, dx_m=100.0))


@pytest.fixture(scope="module")
def coast():
    return E.load_grid(make_test_grid(nt=4, nz=3, ny=30, nx=40, dt_s=3600.0))


def _tier(i):
    return {**tier_params("FH", i), "dt_s": 1.0}


def _roll(grid, tier, init, method="oracle", dyn="kinematic", vehicle=None, seed=0):
    return rollout(fh, grid, tier, init, method, dyn, vehicle or E.load_vehicle(), seed)


def _hand_init(zone, n_fish=60, n_ep=1, ring=40.0):
    """School at the origin, zone centre ``zone`` (x, z), agents on a ring of ``ring`` m."""
    fx, fz, _, _ = init_school(n_fish, (0.0, 0.0), fh.SCHOOL_RADIUS_M, 7)
    a = 2 * np.pi * np.arange(N) / N
    pos = np.stack([ring * np.sin(a), np.full(N, fh.FISH_DEPTH_M), ring * np.cos(a)], axis=1)
    return {"fish0": np.tile(np.stack([fx, fz]), (n_ep, 1, 1)),
            "zone": np.tile(np.asarray(zone, float), (n_ep, 1)),
            "pos0": np.tile(pos, (n_ep, 1, 1)), "psi0": np.zeros((n_ep, N)),
            "t0": np.zeros(n_ep)}


def test_reset_geometry_is_valid(coast):
    tier = _tier(3)
    init = fh.reset(coast, tier, N, 8, seed=2)
    fish, zone, pos0 = init["fish0"], init["zone"], init["pos0"]
    assert fish.shape == (8, 2, tier["fish_count"]) and tier["fish_count"] >= 50
    xyz = np.stack([fish[:, 0].ravel(), np.full(fish[:, 0].size, fh.FISH_DEPTH_M),
                    fish[:, 1].ravel()], axis=1)
    assert np.all(E.feasibility(coast, xyz, 0.5, fh.FISH_CLEARANCE_M) == st.OK)
    centre = fish.mean(axis=2)
    d = np.linalg.norm(zone - centre, axis=1)
    assert np.all(np.abs(d - tier["zone_distance_m"]) < fh.SCHOOL_RADIUS_M)
    for e in range(8):
        a = np.array([centre[e, 0], fh.FISH_DEPTH_M, centre[e, 1]])
        b = np.array([zone[e, 0], fh.FISH_DEPTH_M, zone[e, 1]])
        assert path_clear(coast, a, b, fh.ROUTE_CLEARANCE_M - 0.5)
    assert np.all(E.feasibility(coast, pos0.reshape(-1, 3), 0.5, fh.CLEARANCE_M) == st.OK)
    r = np.linalg.norm(pos0[..., [0, 2]] - centre[:, None], axis=2)
    assert np.all(r > 15.0 + fh.SCHOOL_RADIUS_M)  # the school is not scared at the start
    t_end = init["t0"] + tier["time_limit_s"]
    assert np.all(init["t0"] >= coast.time_s[0]) and np.all(t_end <= coast.time_s[-1])


def test_reset_raises_when_impossible(calm):
    with pytest.raises(ConfigError, match="exactly 8"):
        fh.reset(calm, TIER, 5, 2, 0)
    with pytest.raises(ConfigError, match="< 50"):
        fh.reset(calm, {**TIER, "fish_count": 40}, N, 2, 0)
    shallow = E.load_grid(uniform_grid(0.0, 0.0, depth_m=4.0))  # fish need >= 5 m of water
    with pytest.raises(ConfigError, match="FH"):
        fh.reset(shallow, TIER, N, 2, 0)
    with pytest.raises(ConfigError, match="FH"):  # 5 km to the zone in a 2 km grid
        fh.reset(calm, {**TIER, "zone_distance_m": 5000.0}, N, 2, 0)


def test_fish_never_enter_land():
    # a 1 m/s westward current pushes the school onto a coast 80 m west of it
    g = uniform_grid(-1.0, 0.0, depth_m=30.0, nx=21, ny=21, dx_m=100.0)
    g["land_mask"][:, :10] = 1.0
    g["elevation"][:, :10] = 5.0
    g["valid_mask"][:, :, :10] = 0
    g["u"][:, :, :, :10] = 0.0
    grid = E.load_grid(g)
    n = 60
    fx, fz, vx, vz = init_school(n, (30.0, 0.0), 8.0, 3)
    gx, gz, gvx, gvz, cx, cz = (np.empty(n) for _ in range(6))
    none = np.empty(0)
    p = fish_params()
    # without the rule, the school's own step would put fish on land
    step_school(fx, fz, vx, vz, none, none, np.full(n, -80.0), np.zeros(n), p, 1, 0, 1.0,
                gx, gz, gvx, gvz)
    raw = np.stack([gx, np.full(n, fh.FISH_DEPTH_M), gz], axis=1)
    assert np.any(E.feasibility(grid, raw, 0.5, fh.FISH_CLEARANCE_M) != st.OK)
    scr = np.empty((7, n))
    for k in range(120):
        fh._fish_step(grid, fx, fz, vx, vz, none, none, cx, cz, p, np.uint64(1), k, 0.0, 1.0,
                      0.5, gx, gz, gvx, gvz, scr)
        pts = np.stack([gx, np.full(n, fh.FISH_DEPTH_M), gz], axis=1)
        assert np.all(E.feasibility(grid, pts, 0.5, fh.FISH_CLEARANCE_M) == st.OK)
        fx, fz, vx, vz, gx, gz, gvx, gvz = gx, gz, gvx, gvz, fx, fz, vx, vz
    assert np.all(cx < -0.4)  # the current was sampled at every fish (weaker at the coast)
    assert fx.min() < -40.0  # the school was pushed onto the coast (land for x < -50 m)


@pytest.mark.parametrize("tier", [1, 2, 3])
def test_every_tier_is_solvable_in_calm_water(coast, tier):
    df = run_cell(coast, "FH", tier, "oracle", episodes=3, seed=1, currents=False)
    assert df["success"].all()
    assert (df["final_centroid_distance_m"] <= _tier(tier)["zone_radius_m"]).all()


def test_school_already_in_zone_succeeds_after_hold(calm):
    # zone centred on the school, far enough from the agents not to scare it
    init = _hand_init((0.0, 0.0), ring=60.0)
    tier = {**TIER, "hold_s": 12.0}
    r = _roll(calm, tier, init)
    assert r["success"][0] and r["T_s"][0] == 12.0
    assert r["fraction_inside"][0] > 0.9


def test_do_nothing_fails_with_time_limit(calm):
    veh = E.load_vehicle()
    p = veh.params.copy()
    p[P_VMAX] = 0.0
    still = dataclasses.replace(veh, params=p)
    init = _hand_init((80.0, 0.0), ring=60.0)
    r = _roll(calm, {**TIER, "time_limit_s": 150.0}, init, vehicle=still)
    assert not r["success"][0]
    assert r["T_s"][0] == 150.0
    assert r["E"][0] == 0.0
    assert r["final_centroid_distance_m"][0] > 70.0  # the school stays where it was
    assert r["fraction_inside"][0] == 0.0
    # the same episode with working vehicles herds the school in
    r = _roll(calm, {**TIER, "time_limit_s": 600.0}, init)
    assert r["success"][0] and r["final_centroid_distance_m"][0] <= TIER["zone_radius_m"]


def test_strong_current_away_from_the_zone_defeats_herding():
    # fish swim at most 0.8 m/s: a 1.5 m/s current away from the zone cannot be beaten
    grid = E.load_grid(uniform_grid(-1.5, 0.0, depth_m=30.0, nx=41, ny=21, dx_m=100.0))
    init = _hand_init((80.0, 0.0), ring=60.0)
    for method in ("oracle", "heuristic"):
        r = _roll(grid, {**TIER, "time_limit_s": 200.0}, init, method=method)
        assert not r["success"][0] and r["T_s"][0] == 200.0
        assert r["final_centroid_distance_m"][0] > 150.0


def test_metrics_are_consistent(coast):
    df = run_cell(coast, "FH", 2, "heuristic", episodes=4, seed=3)
    for k in STANDARD + ("primary",) + fh.METRICS:
        assert k in df.columns
    np.testing.assert_array_equal(df["primary"], df["containment_success"])
    np.testing.assert_array_equal(df["containment_success"], df["success"].astype(float))
    lim = _tier(2)["time_limit_s"]
    assert (df.loc[~df.success, "T_s"] == lim).all()
    assert (df.loc[df.success, "T_s"] >= _tier(2)["hold_s"]).all()
    assert (df.loc[df.success, "final_centroid_distance_m"] <= _tier(2)["zone_radius_m"]).all()
    assert df["fraction_inside"].between(0.0, 1.0).all()
    assert df["coll_ratio"].between(0.0, 1.0).all()
    assert (df["E"] > 0).all() and (df["E"] <= N * 2.0 ** 2 * df["T_s"] + 1e-9).all()
    assert (df["school_spread_m"] > 0).all()


def test_near_collision_ratio_counts_close_steps(calm):
    init = _hand_init((0.0, 0.0), ring=60.0)
    tier = {**TIER, "hold_s": 30.0}
    assert _roll(calm, tier, init)["coll_ratio"][0] == 0.0  # agents 46 m apart
    init["pos0"][0] = np.array([[60.0 + 0.25 * i, 2.0, 0.0] for i in range(N)])  # bunched
    assert _roll(calm, tier, init)["coll_ratio"][0] > 0.0


def test_run_cell_deterministic_seeds_and_threads(coast):
    a = run_cell(coast, "FH", 1, "heuristic", episodes=4, seed=5)
    b = run_cell(coast, "FH", 1, "heuristic", episodes=4, seed=5)
    pd.testing.assert_frame_equal(a, b)
    c = run_cell(coast, "FH", 1, "heuristic", episodes=4, seed=6)
    assert not np.array_equal(a["E"].to_numpy(), c["E"].to_numpy())
    d = on_one_thread(run_cell, coast, "FH", 1, "heuristic", episodes=4, seed=5)
    pd.testing.assert_frame_equal(a, d)


def test_tier_table_monotone_and_declared():
    table = load_task_table("FH")
    tiers = table["tiers"]
    assert_tier_table_monotone(table)
    for t in (1, 2, 3):
        assert set(tiers[t]) == set(table["harder"]) == set(fh._TIER_KEYS)
        assert tiers[t]["fish_count"] >= 50
    assert table["agents"] == {"default": 8, "range": [8, 8]}
    assert table["dt_s"] == 1.0


def _sonar_setup(calm, n_fish=80, agent0=(20.0, 0.0), true_target=0):
    """A school at the origin, agent 0 at ``agent0`` (x, z), the others 200 m away."""
    init = _hand_init((80.0, 0.0), n_fish=n_fish)
    init["pos0"][0, :, 0] = 200.0
    init["pos0"][0, :, 2] = 0.0
    init["pos0"][0, 0, 0], init["pos0"][0, 0, 2] = agent0
    P, W = fh.make(calm, TIER, init)
    W.sinfo[0] = (7, true_target, 0)
    state = np.zeros((1, N, 12))
    state[0, :, :3] = init["pos0"][0]
    return P, W, state, init


def test_sonar_sees_the_near_side_of_the_school(calm):
    """Each ROV's reading: the echo centroid, pulled toward the sensor by shadowing, with
    range/bearing noise; nothing beyond the sonar's range; deterministic per ping."""
    P, W, state, init = _sonar_setup(calm)
    assert P.sonar_r == 50.0 and P.ext_len > 0.0
    cx, cz = init["fish0"][0].mean(axis=1)
    dx = []
    for ping in range(200):
        fh.sonar(P, W, state, 0, ping)
        assert W.sfix[0, 0, 0] == 1.0 and not W.sfix[0, 1:, 0].any()   # 200 m: not seen
        dx.append((W.sfix[0, 0, 1], W.sfix[0, 0, 2], W.sfix[0, 0, 3]))
    dx = np.array(dx)
    true_off = cx - 20.0
    bias = dx[:, 0].mean() - true_off
    assert 0.3 < bias < 4.0                   # toward the sensor (+x), a fraction of the school
    assert abs(dx[:, 1].mean() - cz) < 0.3    # no bias across the line of sight
    assert dx[:, 0].std() > 0.05              # the echo fluctuates from ping to ping
    assert 0.0 < dx[:, 2].mean() < fh.SCHOOL_RADIUS_M
    fh.sonar(P, W, state, 0, 5)
    again = W.sfix[0, 0, :].copy()
    fh.sonar(P, W, state, 0, 5)
    np.testing.assert_array_equal(W.sfix[0, 0], again)
    # a method given the target draws nothing (it reads the truth)
    P, W, state, _ = _sonar_setup(calm, true_target=1)
    W.sfix[:] = -1.0
    fh.sonar(P, W, state, 0, 0)
    assert (W.sfix == -1.0).all()


def test_school_sensor_table_errors(tmp_path):
    import yaml
    from oneocean.sensing import SENSORS_YAML
    doc = yaml.safe_load(SENSORS_YAML.read_text())
    del doc["perception"]["fh_school"]["extinction_m"]
    p = tmp_path / "sensors.yaml"
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError, match="perception.fh_school.extinction_m"):
        fh.school_sensor(p)
    doc["perception"]["fh_school"]["extinction_m"] = 0.0
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError, match="perception.fh_school.extinction_m"):
        fh.school_sensor(p)


def test_tracker_gains():
    from oneocean.methods.heuristic.fh import tracker_gains
    a, b = tracker_gains(0.02, 0.5, 1.0)
    assert 0.0 < b < a < 1.0
    a2, b2 = tracker_gains(0.2, 0.5, 1.0)   # a faster target: larger gains
    assert a2 > a and b2 > b


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def _uniform(ce, cn):
    return E.load_grid(uniform_grid(ce, cn, depth_m=30.0, nx=21, ny=21, dx_m=100.0))


def test_the_briefing_and_what_the_method_is_given(calm):
    init = _hand_init((80.0, 0.0), ring=60.0)
    for method, flags in (("heuristic", (0, 0)), ("oracle", (1, 1))):
        ep = Episodes(fh, calm, TIER, init, method, "kinematic", E.load_vehicle(), 0)
        B = ep.B
        assert B._fields == tuple(COMMON) + tuple(fh.BRIEF_FIELDS)
        np.testing.assert_array_equal(B.zone, init["zone"])
        np.testing.assert_allclose(B.school0, init["fish0"].mean(axis=2), atol=1e-12)
        assert (B.zone_radius, B.hold_s, B.depth) == (10.0, 20.0, fh.FISH_DEPTH_M)
        assert (B.fish_count, B.school_radius, B.sonar_range) == (60, fh.SCHOOL_RADIUS_M, 50.0)
        assert (B.flee_radius, B.fish_speed) == (15.0, 0.8)
        # brief tells the task's sensing what the method is given
        assert tuple(ep.W.sinfo[0, 1:]) == flags
        np.testing.assert_array_equal(ep.W.fce, 0.0 if method == "oracle" else ep.LS.fc)


def test_the_sonar_fields_and_the_team_fix():
    """Each agent's reading (offset of the echo centroid from its navigation estimate,
    extent; NaN beyond the sonar's range), the team's fix (the readings placed at the agents'
    positions, averaged), no velocity, the forecast of the current at the fix."""
    grid = _uniform(0.2, -0.1)
    init = _hand_init((80.0, 0.0), ring=40.0)
    init["pos0"][0, 0] = (200.0, fh.FISH_DEPTH_M, 0.0)      # out of the sonar's range
    ep = Episodes(fh, grid, TIER, init, None, "kinematic", E.load_vehicle(), 0)
    O = ep.observe()[0]
    X = ep.known_state[0]
    W, T = ep.W, ep.C.T
    assert O.shape[1] == fh.OBS_DIM + len(fh.OBS_EXTRA) == fh.O_SSPREAD + 1
    assert O[0, fh.O_SEEN] == 0.0 and np.isnan(O[0, fh.O_SDX:]).all()
    assert (O[1:, fh.O_SEEN] == 1.0).all()
    for j, c in ((fh.O_SDX, 1), (fh.O_SDZ, 2), (fh.O_SSPREAD, 3)):
        np.testing.assert_array_equal(O[1:, j], W.sfix[0, 1:, c])
    placed = X[1:, [0, 2]] + O[1:, [fh.O_SDX, fh.O_SDZ]]
    np.testing.assert_allclose(T.fix[0, :2], placed.mean(axis=0), atol=1e-9)
    np.testing.assert_allclose(T.fix[0, 2], O[1:, fh.O_SSPREAD].mean(), atol=1e-12)
    true = W.school[0, :2]
    assert 0.0 < np.hypot(*(T.fix[0, :2] - true)) < 2.0   # the echo centroid: near the truth
    assert 0.0 < T.fix[0, 2] < fh.SCHOOL_RADIUS_M
    assert np.isnan(T.vel).all()
    g, c, s, be, bn = ep.LS.fc[0]
    np.testing.assert_allclose(T.cur[0], (g * (c * 0.2 - s * 0.1) + be,
                                          g * (-c * 0.1 - s * 0.2) + bn), atol=1e-9)
    # given the target: the true centroid's offset and spread at any range, its velocity;
    # given the true current: the current at the school
    ep = Episodes(fh, grid, TIER, init, None, "kinematic", E.load_vehicle(), 0, info="truth")
    for k in range(3):
        O = ep.observe()[0] if k == 0 else ep.step_observe()[0].copy()
        X, W, T = ep.state[0], ep.W, ep.C.T
        F = W.fish[0, W.fcur[0]]
        assert (O[:, fh.O_SEEN] == 1.0).all()
        np.testing.assert_allclose(X[:, 0] + O[:, fh.O_SDX], W.school[0, 0], atol=1e-9)
        np.testing.assert_allclose(X[:, 2] + O[:, fh.O_SDZ], W.school[0, 1], atol=1e-9)
        np.testing.assert_array_equal(O[:, fh.O_SSPREAD], school_spread(F[0], F[1]))
        np.testing.assert_array_equal(T.fix[0], (*W.school[0, :2], school_spread(F[0], F[1])))
        np.testing.assert_array_equal(T.vel[0], W.school[0, 2:4])
        np.testing.assert_allclose(T.cur[0], (0.2, -0.1), atol=1e-12)
    assert np.any(T.vel[0] != 0.0)


def test_the_cue_is_the_tasks_herding_station(calm):
    """Every agent's cue: a station on the arc behind the school's team fix, opposite the
    zone, CUE_STANDOFF_M plus the school's extent out, at most CUE_STEP_DEG of arc from the
    agent's own bearing -- the task's own, the same for every method."""
    init = _hand_init((80.0, 30.0), ring=40.0)
    ep = Episodes(fh, calm, TIER, init, None, "kinematic", E.load_vehicle(), 0)
    O = ep.observe()[0]
    X = ep.known_state[0]
    fix = ep.C.T.fix[0]
    np.testing.assert_allclose(O[:, 1], fh.FISH_DEPTH_M - X[:, 1], atol=1e-12)
    st = X[:, [0, 2]] + O[:, [0, 2]] - fix[:2]
    np.testing.assert_allclose(np.hypot(st[:, 0], st[:, 1]), fh.CUE_STANDOFF_M + fix[2],
                               atol=1e-9)
    zone = init["zone"][0] - fix[:2]
    th = np.arctan2(-zone[0], -zone[1])                       # behind the school
    a = _wrap(np.arctan2(st[:, 0], st[:, 1]) - th)
    own = _wrap(np.arctan2(X[:, 0] - fix[0], X[:, 2] - fix[1]) - th)
    assert np.all(np.abs(_wrap(a - own)) <= np.radians(fh.CUE_STEP_DEG) + 1e-9)
    slot = np.radians(fh.CUE_ARC_DEG) * (np.argsort(np.argsort(own)) / (N - 1) - 0.5)
    np.testing.assert_allclose(a, np.where(np.abs(slot - own) <= np.radians(fh.CUE_STEP_DEG),
                                           slot, a), atol=1e-9)
    # the task's own cue: the fused heuristic's observation is the same
    fz = Episodes(fh, calm, TIER, init, "heuristic", "kinematic", E.load_vehicle(), 0,
                  record=True).run()
    np.testing.assert_array_equal(fz.obs[0, 0], ep.observe()[0])


@pytest.mark.parametrize("current", [(0.0, 0.0), (0.2, 0.1)])
def test_a_follower_of_the_cue_herds_the_school_in(current):
    # the task's cue alone herds the school: seek the station (gain 0.5 s-1, capped at
    # v_max), cancel the known current
    grid = _uniform(*current)
    veh = E.load_vehicle()
    ep = Episodes(fh, grid, TIER, _hand_init((80.0, 0.0), ring=60.0), None, "kinematic", veh,
                  0)
    O = ep.observe()
    while not ep.done.all():
        g = O[..., 0:3]
        d = np.linalg.norm(g, axis=-1, keepdims=True)
        a = g / np.maximum(d, 1e-9) * np.minimum(veh.v_max, 0.5 * d)
        a[..., 0] -= O[..., 3]
        a[..., 2] -= O[..., 4]
        ep.set_actions(a)
        O = ep.step_observe()
    r = ep.results()
    assert r["success"][0] and r["final_centroid_distance_m"][0] <= TIER["zone_radius_m"]
