"""UPL (cooperative lift): reset geometry, the survey's chart, reachability, attach/lift
physics, success rule, the object's perception (sonar fixes, the team's filter, the search),
the public view (briefing, the observation's own fields, the team observation, the task's
cue, which a follower can lift by), metrics, determinism (seeds and threads), tier table."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.engine import status as st
from oneocean.engine.dynamics import P_VMAX
from oneocean.errors import ConfigError, NotApplicable
from oneocean.tasks import run_cell, upl
from oneocean.tasks.common import OBS_DIM, STANDARD
from oneocean.tasks.spawn import path_clear
from oneocean.tasks.tiers import load_task_table, tier_params
from oneocean.tasks.episodes import Episodes, rollout
from oneocean.testing import make_test_grid, uniform_grid
from task_helpers import assert_tier_table_monotone, on_one_thread

TIER = {"time_limit_s": 400.0, "site_depth_m": 40.0,
        "start_distance_m": 60.0, "attach_radius_m": 1.0, "attach_dwell_s": 5.0,
        "detach_radius_m": 2.5, "sink_speed_ms": 0.3, "quorum": 5, "hold_radius_m": 30.0,
        "success_depth_m": 2.5, "survey_std_m": 10.0, "dt_s": 1.0}
N = upl.N_SLOTS
#: The task's vehicle (its tier table): the BlueROV2 Heavy, 0.85 m/s.
VEHICLE = E.load_vehicle(load_task_table("UPL")["vehicle"])


def _flat(floor_m, deepest_m=80.0, ce=0.0):
    """Flat ``floor_m`` seafloor, no land, uniform current; current levels 0 and ``deepest_m``."""
    g = uniform_grid(ce, 0.0, depth_m=floor_m, nx=21, ny=21, dx_m=100.0)
    g["depth"] = np.array([0.0, float(deepest_m)])
    return E.load_grid(g)


@pytest.fixture(scope="module")
def calm():
    """Flat 40 m seafloor, no current, no land."""
    return _flat(40.0)


@pytest.fixture(scope="module")
def coast():
    """Sloping seafloor to 75 m with a coast, currents, tides; deepest level 60 m."""
    return E.load_grid(make_test_grid(nt=4, nz=5, ny=40, nx=50, max_depth_m=60.0))


def _tier(i):
    return {**tier_params("UPL", i), "dt_s": 1.0}


def _at_slots(depth_floor=40.0, n_ep=1, offset=0.0):
    """Hand-made init: object on a flat floor at the origin, agents ``offset`` m above slots."""
    obj = np.array([0.0, depth_floor - upl.OBJ_HALF_HEIGHT_M, 0.0])
    off = upl.slot_offsets(0.3)
    pos = obj + off + np.array([0.0, -offset, 0.0])
    return {"obj0": np.tile(obj, (n_ep, 1)), "slot_off": np.tile(off, (n_ep, 1, 1)),
            "pos0": np.tile(pos, (n_ep, 1, 1)), "psi0": np.zeros((n_ep, N)),
            "t0": np.zeros(n_ep)}


def _roll(grid, tier, init, method="oracle", dyn="kinematic", vehicle=None, seed=0):
    return rollout(upl, grid, tier, init, method, dyn, vehicle or VEHICLE, seed)


def _batch(grid, tier, init, method="heuristic", dyn="kinematic", seed=0, info=None):
    return Episodes(upl, grid, tier, init, method, dyn, VEHICLE, seed, info=info)


def test_reset_geometry_is_valid(coast):
    tier = _tier(2)
    init = upl.reset(coast, tier, N, 10, seed=4)
    obj, off, pos0 = init["obj0"], init["slot_off"], init["pos0"]
    floor = -E.grid.sample_elevation_points(coast, np.ascontiguousarray(obj[:, [0, 2]]),
                                            np.empty(10))
    # the object rests on the seafloor, at a depth the tier asks for and the grid can reach
    np.testing.assert_allclose(obj[:, 1], floor - upl.OBJ_HALF_HEIGHT_M)
    lo = tier["site_depth_m"] - upl.SITE_DEPTH_SPAN_M
    assert np.all((floor >= lo) & (floor <= tier["site_depth_m"]))
    slots = obj[:, None, :] + off
    assert np.all(E.feasibility(coast, slots.reshape(-1, 3), 0.5, upl.CLEARANCE_M) == st.OK)
    # agents start apart (not attached), in valid water, with a clear descent to the site
    assert np.all(E.feasibility(coast, pos0.reshape(-1, 3), 0.5, upl.CLEARANCE_M) == st.OK)
    hd = np.linalg.norm((pos0 - obj[:, None, :])[..., [0, 2]], axis=2)
    assert np.all(hd >= upl.START_RING_FRAC * tier["start_distance_m"] - 1e-9)
    assert np.all(hd <= tier["start_distance_m"] + 1e-9)
    assert np.min(np.linalg.norm(pos0[:, :, None] - pos0[:, None], axis=3)
                  + 1e9 * np.eye(N)) >= upl.START_SEPARATION_M
    assert np.all(np.linalg.norm(pos0 - slots, axis=2) > tier["detach_radius_m"])
    for e in range(10):
        above = [obj[e, 0], obj[e, 1] - upl.SLOT_RISE_M, obj[e, 2]]
        assert all(path_clear(coast, p, above, upl.CLEARANCE_M, spacing_m=5.0) for p in pos0[e])
    t_end = init["t0"] + tier["time_limit_s"]
    assert np.all(init["t0"] >= coast.time_s[0]) and np.all(t_end <= coast.time_s[-1])


def test_reset_raises_when_impossible(calm, coast):
    with pytest.raises(ConfigError, match="exactly 5"):
        upl.reset(calm, TIER, 4, 2, 0)
    with pytest.raises(ConfigError, match="no site"):  # flat 40 m floor, sites must be 45-60 m
        upl.reset(calm, {**TIER, "site_depth_m": 60.0}, N, 2, 0)
    with pytest.raises(ConfigError, match="no site"):  # starts 5 km away: outside the 2 km grid
        upl.reset(calm, {**TIER, "start_distance_m": 5000.0}, N, 2, 0)
    with pytest.raises(NotApplicable, match="no site"):  # coast's seafloor ends at 75 m
        upl.reset(coast, {**TIER, "site_depth_m": 120.0, "start_distance_m": 60.0}, N, 2, 0)
    # below the product's deepest current level (60 m) the engine holds that level's current
    # down to the seafloor: such sites are hosted, not refused
    deep = upl.reset(coast, {**TIER, "site_depth_m": 75.0}, N, 3, 0)
    floor = deep["obj0"][:, 1] + upl.OBJ_HALF_HEIGHT_M
    assert np.all((floor >= 75.0 - upl.SITE_DEPTH_SPAN_M) & (floor <= 75.0))
    assert np.any(floor > coast.depth[-1])
    with pytest.raises(ConfigError, match="missing"):
        upl.reset(calm, {k: v for k, v in TIER.items() if k != "quorum"}, N, 2, 0)


def test_unreachable_success_depth_is_rejected(calm):
    # the reference's flaw: the goal depth could not reach the success depth
    with pytest.raises(ConfigError, match="unreachable"):
        upl.check_reachable({**TIER, "success_depth_m": upl.SLOT_RISE_M - 0.1})
    with pytest.raises(ConfigError, match="unreachable"):
        rollout(upl, calm, {**TIER, "success_depth_m": 1.0}, _at_slots(), "oracle", "kinematic",
                E.load_vehicle(), 0)
    with pytest.raises(ConfigError, match="above the success depth"):
        upl.check_reachable({**TIER, "site_depth_m": 17.0})
    with pytest.raises(ConfigError, match="survey_std_m"):
        upl.check_reachable({**TIER, "survey_std_m": -1.0})
    for i in (1, 2, 3):
        upl.check_reachable(_tier(i))


@pytest.mark.parametrize("tier", [1, 2, 3])
def test_every_tier_is_solvable_in_calm_water(coast, tier):
    # the real tier geometry and rules, currents off: the oracle lifts every object
    df = run_cell(coast, "UPL", tier, "oracle", episodes=4, seed=1, currents=False)
    assert df["success"].all()
    assert (df["final_object_depth_m"] <= _tier(tier)["success_depth_m"]).all()
    assert (df["attach_time_s"] < df["T_s"]).all()


def test_lift_rate_is_team_pull_minus_sink(calm):
    # agents start on their slots: attach after the dwell, then the assembly rises at
    # v_max - sink (kinematic, all five ROVs pulling at v_max = 0.85 m/s)
    assert VEHICLE.v_max == 0.85
    tier = {**TIER, "sink_speed_ms": 0.5, "attach_dwell_s": 3.0}
    r = _roll(calm, tier, _at_slots())
    assert r["success"][0]
    assert r["attach_time_s"][0] == 3.0
    depth0 = 40.0 - upl.OBJ_HALF_HEIGHT_M
    lift_steps = np.ceil((depth0 - tier["success_depth_m"]) / (VEHICLE.v_max - 0.5))
    assert abs(r["T_s"][0] - (3.0 + lift_steps)) <= 1.0
    assert r["final_object_depth_m"][0] <= tier["success_depth_m"]
    assert r["object_drift_m"][0] < 1e-6


def test_too_heavy_object_is_never_lifted(calm):
    tier = {**TIER, "sink_speed_ms": 1.0, "time_limit_s": 60.0}  # sink > v_max = 0.85
    r = _roll(calm, tier, _at_slots())
    assert not r["success"][0]
    assert r["T_s"][0] == 60.0
    assert r["final_object_depth_m"][0] == pytest.approx(40.0 - upl.OBJ_HALF_HEIGHT_M)


def test_object_moves_only_with_the_quorum(calm):
    init = _at_slots()
    init["pos0"][0, 4] += np.array([150.0, -30.0, 0.0])  # one agent far away
    tier = {**TIER, "time_limit_s": 400.0}
    r5 = _roll(calm, {**tier, "quorum": 5}, init)
    r4 = _roll(calm, {**tier, "quorum": 4}, init)
    assert r4["attach_time_s"][0] == tier["attach_dwell_s"]
    assert r5["attach_time_s"][0] > 150.0  # waits for the far agent (>= 150 m at 0.85 m/s)
    assert r4["success"][0] and r5["success"][0]
    assert r4["T_s"][0] < r5["T_s"][0]


def test_do_nothing_fails_with_time_limit(coast):
    veh = E.load_vehicle()
    p = veh.params.copy()
    p[P_VMAX] = 0.0
    still = dataclasses.replace(veh, params=p)
    tier = _tier(1)
    init = upl.reset(coast, tier, N, 3, 0)
    r = _roll(coast, tier, init, vehicle=still)
    assert not r["success"].any()
    np.testing.assert_array_equal(r["T_s"], tier["time_limit_s"])
    np.testing.assert_array_equal(r["attach_time_s"], tier["time_limit_s"])
    np.testing.assert_array_equal(r["E"], 0.0)
    np.testing.assert_allclose(r["final_object_depth_m"], init["obj0"][:, 1])
    np.testing.assert_array_equal(r["lift_success"], 0.0)


def test_metrics_are_consistent(coast):
    df = run_cell(coast, "UPL", 2, "heuristic", episodes=6, seed=2)
    for k in STANDARD + ("primary",) + upl.METRICS:
        assert k in df.columns
    np.testing.assert_array_equal(df["primary"], df["lift_success"])
    np.testing.assert_array_equal(df["lift_success"], df["success"].astype(float))
    lim = _tier(2)["time_limit_s"]
    assert (df.loc[~df.success, "T_s"] == lim).all()
    assert (df.loc[df.success, "T_s"] <= lim).all()
    assert (df["coll_ratio"].between(0.0, 1.0)).all()
    # E = sum ||a||^2 dt over the clipped action: at most N v_max^2 T (the ROV's 0.85 m/s)
    assert (df["E"] > 0).all() and (df["E"] <= N * VEHICLE.v_max ** 2 * df["T_s"] + 1e-9).all()
    ok = df[df.success]
    assert (ok["final_object_depth_m"] <= 2.5).all()
    assert (ok["object_drift_m"] <= _tier(2)["hold_radius_m"]).all()


def test_near_collision_ratio_counts_close_steps(calm):
    # five agents start bunched within 1.6 m of each other, 30 m from the object
    init = _at_slots()
    init["pos0"][0] = np.array([[30.0 + 0.4 * i, 5.0, 0.0] for i in range(N)])
    r = _roll(calm, {**TIER, "time_limit_s": 200.0}, init)
    assert r["coll_ratio"][0] > 0.0
    r0 = _roll(calm, {**TIER, "time_limit_s": 200.0}, _at_slots())
    assert r0["coll_ratio"][0] == 0.0  # slots are 3.5 m apart


def test_run_cell_deterministic_seeds_and_threads(coast):
    a = run_cell(coast, "UPL", 3, "heuristic", episodes=4, seed=5)
    b = run_cell(coast, "UPL", 3, "heuristic", episodes=4, seed=5)
    pd.testing.assert_frame_equal(a, b)
    c = run_cell(coast, "UPL", 3, "heuristic", episodes=4, seed=6)
    assert not np.array_equal(a["E"].to_numpy(), c["E"].to_numpy())
    d = on_one_thread(run_cell, coast, "UPL", 3, "heuristic", episodes=4, seed=5)
    pd.testing.assert_frame_equal(a, d)


def test_tier_table_monotone_and_declared():
    table = load_task_table("UPL")
    tiers = table["tiers"]
    assert_tier_table_monotone(table)
    for t in (1, 2, 3):
        # the current band is the Cell's (region-relative regime), not the task module's
        assert set(tiers[t]) == set(table["harder"]) == set(upl._TIER_KEYS) | {"current_band"}
    # attaching to and lifting an object: the hovering ROV
    assert table["vehicle"] == "bluerov2_heavy"
    assert table["agents"] == {"default": 5, "range": [5, 5]}
    assert table["dt_s"] == 1.0


def test_chart_is_the_site_with_the_survey_error(coast):
    tier = _tier(3)
    init = upl.reset(coast, tier, N, 40, seed=3)
    obj, chart = init["obj0"], init["chart"]
    err = (chart - obj)[:, [0, 2]]
    # horizontal error of the tier's stated size (truncated at 3 sigma), none vertically
    # beyond the charted seafloor's depth at the charted point
    assert np.all(np.abs(err) <= 3.0 * tier["survey_std_m"] + 1e-9)
    assert 0.5 * tier["survey_std_m"] < err.std() < 1.5 * tier["survey_std_m"]
    floor = -E.grid.sample_elevation_points(coast, np.ascontiguousarray(chart[:, [0, 2]]),
                                            np.empty(40))
    wet = floor > upl.OBJ_HALF_HEIGHT_M
    np.testing.assert_allclose(chart[wet, 1], floor[wet] - upl.OBJ_HALF_HEIGHT_M)
    # the chart is drawn after the geometry: the sites and starts do not depend on it
    other = upl.reset(coast, {**tier, "survey_std_m": 0.0}, N, 40, seed=3)
    np.testing.assert_array_equal(other["obj0"], obj)
    np.testing.assert_array_equal(other["pos0"], init["pos0"])
    np.testing.assert_allclose(other["chart"][:, [0, 2]], obj[:, [0, 2]])


def test_object_perception_reads_the_sensor_table(monkeypatch):
    rng, rstd, bstd, cstd, every = upl.object_perception(1.0)
    assert (rng, rstd, cstd, every) == (40.0, 0.1, 0.1, 1)
    assert bstd == pytest.approx(np.radians(1.0))
    assert upl.object_perception(0.5)[4] == 2
    monkeypatch.setattr(upl, "perception", lambda name: {"range_m": 40.0})
    with pytest.raises(ConfigError, match="perception.upl_object.range_std_m"):
        upl.object_perception(1.0)


def test_sonar_fixes_within_range_and_the_oracle_exact(calm):
    # agents 3 m above their slots (in range) and one 150 m away (out of range)
    init = _at_slots(offset=3.0)
    init["pos0"][0, 4] += np.array([150.0, -30.0, 0.0])
    init["chart"] = init["obj0"] + np.array([[6.0, 0.0, -8.0]])
    h = _batch(calm, TIER, init).run(0)   # the first observation: step 0's fixes, fused
    fix = h.W.fix[0]
    assert np.all(fix[:4, 3] == 1.0) and fix[4, 3] == 0.0
    # the measured offsets of the step's start, with the sonar's noise (not exact)
    d = fix[:4, :3] - (init["obj0"][0] - init["pos0"][0, :4])
    assert np.all(np.abs(d) < 1.0) and np.any(d != 0.0)
    assert h.W.odet[0] == 1
    # the team's estimate left the chart for the object
    est = h.W.oest[0, :3]
    assert np.linalg.norm(est - init["obj0"][0]) < 1.0
    o = _batch(calm, TIER, init, method="oracle").run(0)
    assert np.all(o.W.fix[0, :, 3] == 1.0)   # exact, at any range
    np.testing.assert_array_equal(o.W.oest[0, :3], o.W.obj[0])


def test_heuristic_estimate_converges_and_is_not_the_truth(coast):
    tier = _tier(2)
    init = upl.reset(coast, tier, N, 4, seed=2)
    h = _batch(coast, tier, init, dyn="6dof").run(150)
    err = np.linalg.norm(h.W.oest[:, :3] - h.W.obj, axis=1)
    assert np.all(h.W.odet == 1)
    assert np.all(err < 1.0) and np.all(err > 0.0)


def test_search_finds_an_object_far_off_the_chart(calm):
    # the chart 70 m off: beyond the sonar's 40 m from the charted slots; the team searches
    init = _at_slots(offset=3.0)
    init["pos0"][0] += np.array([70.0, -30.0, 0.0])
    init["chart"] = init["obj0"] + np.array([[70.0, 0.0, 0.0]])
    tier = {**TIER, "survey_std_m": 40.0, "time_limit_s": 900.0}
    h = _batch(calm, tier, init).run()
    r = h.results()
    assert h.H.srch[0, 0] == 1.0 and h.W.odet[0] == 1
    assert r["success"][0]
    o = _roll(calm, tier, init)
    assert o["success"][0] and o["T_s"][0] < r["T_s"][0]


def test_briefing_holds_the_mission_and_the_oracle_the_truth(calm):
    init = _at_slots(offset=3.0)
    init["chart"] = init["obj0"] + np.array([[6.0, 0.0, -8.0]])
    h = _batch(calm, TIER, init)
    B = h.B
    assert isinstance(B, upl.UPLBriefing)
    assert B._fields[len(B._fields) - len(upl.BRIEF_FIELDS):] == tuple(upl.BRIEF_FIELDS)
    np.testing.assert_array_equal(B.obj_chart, init["chart"])
    np.testing.assert_array_equal(B.slot_off, init["slot_off"])
    assert (B.quorum, B.attach_radius, B.attach_dwell, B.detach_radius, B.sink_speed,
            B.success_depth, B.hold_radius, B.survey_std) == (5, 1.0, 5.0, 2.5, 0.3, 2.5, 30.0,
                                                              10.0)
    assert B.p_range == upl.object_perception(1.0)[0]
    assert h.W.pcfg[1] == 0
    # the oracle perceives the object exactly: its chart is the truth
    o = _batch(calm, TIER, init, method="oracle")
    np.testing.assert_array_equal(o.B.obj_chart, init["obj0"])
    assert o.W.pcfg[1] == 1
    # the sonar's error stream is the run's (seed, the cell's episodes)
    h.run(1)
    assert h.W.pcfg[0] == 0 and h.W.pcfg[2] == 0
    assert _batch(calm, TIER, init, seed=7).run(1).W.pcfg[0] == 7


def _check_fields(b, e=0):
    """The task's observation fields and team observation of ``b``'s current step."""
    O = b.C.O[e]
    X = b.known_state[e]
    W = b.W
    assert len(upl.OBS_EXTRA) == O.shape[1] - OBS_DIM <= 8
    x = O[:, OBS_DIM:]
    np.testing.assert_array_equal(x[:, 0], W.odet[e])
    np.testing.assert_allclose(x[:, 1:4], W.oest[e, :3] - X[:, :3], atol=1e-9)
    np.testing.assert_array_equal(x[:, 4:7], np.tile(W.oest[e, 3:], (upl.N_SLOTS, 1)))
    np.testing.assert_array_equal(x[:, 7], W.att[e])
    # the team observation: views of the team's estimate
    T = b.C.T
    assert isinstance(T, upl.UPLTeamObs) and set(T._fields) == set(upl.TEAM_FIELDS)
    assert np.shares_memory(T.obj_est, W.oest) and np.shares_memory(T.obj_det, W.odet)
    return O, X


def test_observation_fields_and_the_task_cue(calm):
    # agents 3 m above their slots; the chart 6 m off: the team's estimate leaves it
    init = _at_slots(offset=3.0)
    init["chart"] = init["obj0"] + np.array([[6.0, 0.0, -8.0]])
    h = _batch(calm, TIER, init).run(2)
    O, X = _check_fields(h)
    assert np.all(O[:, OBS_DIM] == 1.0) and np.all(O[:, OBS_DIM + 7] == -1.0)
    est = h.W.oest[0, :3]
    off = init["slot_off"][0]
    # unattached: the cue is the nearest slot on the estimate (here each agent's own)
    goal = X[:, :3] + O[:, :3]
    np.testing.assert_allclose(goal, est + off, atol=1e-9)
    # the oracle on its slots: attached after the dwell (5 s), its own slot, then the lift:
    # the slot at the surface
    o = _batch(calm, TIER, _at_slots(), method="oracle").run(5)
    O, X = _check_fields(o)
    att = o.W.att[0]
    assert np.all(att >= 0)
    np.testing.assert_array_equal(O[:, OBS_DIM + 7], att)
    lift = o.W.oest[0, :3].copy()
    lift[1] = upl.SLOT_RISE_M
    np.testing.assert_allclose(X[:, :3] + O[:, :3], lift + off[att], atol=1e-9)
    assert np.allclose(O[:, 1], -X[:, 1])   # the slots' depth 0
    # one agent attached, the others not: its own slot at the object's depth, the others the
    # nearest free slot (never the held one)
    init = _at_slots()
    init["pos0"][0, 1:] = init["pos0"][0, 0] + np.array([0.0, -2.0, 0.0])
    init["pos0"][0, 1:] += np.arange(1, 5)[:, None] * np.array([0.0, 0.0, 1.0])
    o = _batch(calm, {**TIER, "time_limit_s": 60.0}, init, method="oracle").run(5)
    O, X = _check_fields(o)
    assert o.W.att[0, 0] == 0 and np.all(o.W.att[0, 1:] == -1)
    est = o.W.oest[0, :3]
    goal = X[:, :3] + O[:, :3]
    np.testing.assert_allclose(goal[0], est + off[0], atol=1e-9)
    for i in range(1, 5):
        d = np.linalg.norm(X[i, :3] - (est + off), axis=1)
        d[0] = np.inf
        np.testing.assert_allclose(goal[i], est + off[np.argmin(d)], atol=1e-9)


def test_a_cue_follower_attaches_and_lifts(calm):
    # an outside policy that flies to its cue (P-control, v_max) and nothing else: it
    # attaches (one agent from 25 m away) and lifts the object
    init = _at_slots(offset=3.0)
    init["pos0"][0, 4] += np.array([25.0, -10.0, 0.0])
    init["chart"] = init["obj0"] + np.array([[5.0, 0.0, 5.0]])
    b = _batch(calm, TIER, init, method=None)
    O = b.observe()
    while not b.done.all():
        a = 0.6 * np.nan_to_num(O[..., :3])
        n = np.linalg.norm(a, axis=-1, keepdims=True)
        b.set_actions(a * np.minimum(1.0, VEHICLE.v_max / np.maximum(n, 1e-12)))
        O = b.step_observe()
    r = b.results()
    assert r["success"][0] and r["attach_time_s"][0] < r["T_s"][0]
