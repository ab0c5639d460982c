"""RF (route following): reset geometry, waypoint/xte/energy success rule, metrics, the speed
schedule planned through the briefing's field (heuristic on its forecast, oracle on the truth,
the constant-speed crabber), the briefing, the task's cue and observation fields, determinism,
tier table."""

from __future__ import annotations

import math

import numba
import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.engine.grid import with_forcing
from oneocean.errors import ConfigError
from oneocean.methods.heuristic import rf as POLICY
from oneocean.tasks import rf, run_cell
from oneocean.tasks import routing
from oneocean.tasks.common import OBS_DIM
from oneocean.tasks.spawn import path_clear
from oneocean.tasks.tiers import load_task_table
from oneocean.tasks.routing import power_model
from oneocean.tasks.episodes import Episodes, rollout
from oneocean.testing import uniform_grid
from task_helpers import assert_tier_table_monotone, on_one_thread

TIER = {"time_limit_s": 900.0, "n_waypoints": 3,
        "leg_m": 250.0, "wp_radius_m": 5.0, "xte_max_m": 3.0, "dt_s": 1.0}


def _grid(ce=0.0, cn=0.0, depth=60.0, n=31):
    return E.load_grid(uniform_grid(ce, cn, depth_m=depth, nx=n, ny=n, dx_m=100.0))


#: The task's vehicle (its tier table): the REMUS 100, 2.5 m/s.
VEHICLE = E.load_vehicle(load_task_table("RF")["vehicle"])


def _run(grid, tier, method, dyn="kinematic", n=4, seed=0, init=None, info=None):
    init = init if init is not None else rf.reset(grid, tier, 1, n, seed)
    return init, rollout(rf, grid, tier, init, method, dyn, VEHICLE, seed, info=info)


def _straight(grid_len=250.0, n_wp=3):
    """A hand-made straight route east along z = 0 at 5 m depth."""
    route = np.zeros((1, n_wp + 1, 3))
    route[0, :, 0] = -400.0 + grid_len * np.arange(n_wp + 1)
    route[0, :, 1] = 5.0
    return {"route": route, "pos0": route[:, :1].copy(), "psi0": np.full((1, 1), math.pi / 2),
            "t0": np.zeros(1)}


def test_reset_geometry_is_valid(coast):
    init = rf.reset(coast, TIER, 1, 8, seed=2)
    r = init["route"]
    assert r.shape == (8, TIER["n_waypoints"] + 1, 3)
    legs = np.diff(r, axis=1)
    np.testing.assert_allclose(np.linalg.norm(legs, axis=2), TIER["leg_m"])
    hd = np.arctan2(legs[..., 0], legs[..., 2])
    turn = np.abs((np.diff(hd, axis=1) + np.pi) % (2 * np.pi) - np.pi)
    assert np.all(turn <= math.radians(rf.MAX_TURN_DEG) + 1e-9)
    for e in range(8):
        assert all(path_clear(coast, a, b, rf.MIN_ALTITUDE_M) for a, b in zip(r[e, :-1], r[e, 1:]))
    np.testing.assert_array_equal(init["pos0"][:, 0], r[:, 0])


def test_reset_raises_when_impossible():
    with pytest.raises(ConfigError, match="RF"):
        rf.reset(_grid(n=11), {**TIER, "leg_m": 3000.0}, 1, 2, 0)
    with pytest.raises(ConfigError, match="n_waypoints"):
        rf.reset(_grid(), {**TIER, "n_waypoints": 0}, 1, 2, 0)
    with pytest.raises(ConfigError, match="missing"):
        rf.reset(_grid(), {k: v for k, v in TIER.items() if k != "leg_m"}, 1, 2, 0)


def test_leg_geometry():
    s, xt, tx, ty, tz, ln = rf.leg_geometry(0.0, 0.0, 0.0, 10.0, 0.0, 0.0, 4.0, 0.0, 3.0)
    assert (s, xt, tx, ty, tz, ln) == (4.0, 3.0, 1.0, 0.0, 0.0, 10.0)
    s, xt, *_ = rf.leg_geometry(0.0, 0.0, 0.0, 10.0, 0.0, 0.0, 13.0, 0.0, 4.0)
    assert s == 13.0 and xt == 5.0  # beyond the end: distance to the segment's end point


def test_oracle_follows_straight_route_exactly():
    init = _straight()
    _, r = _run(_grid(), TIER, "oracle", init=init)
    assert r["success"][0]
    assert r["waypoints_reached"][0] == 3
    assert r["cross_track_error_m"][0] == 0.0 and r["max_cross_track_m"][0] == 0.0
    # kinematic (the task logic, not the vehicle): 750 m in calm water at the REMUS's
    # least-energy speed, its maximum-range speed 1.25 m/s (its limit is 2.5 m/s); the last
    # waypoint counts within 5 m
    assert VEHICLE.v_max == 2.5
    assert r["T_s"][0] == math.ceil((750.0 - 5.0) / 1.25)


def test_random_routes_oracle_calm(coast):
    # calm water (g = 0 on the coast's currents); the 6dof REMUS 100 turns the route's
    # corners on its >= 5 m turning circle and still keeps its mean cross-track error < 1 m
    calm = with_forcing(coast, current_gain=0.0)
    _, r = _run(calm, TIER, "oracle", dyn="6dof", n=6)
    assert r["success"].all()
    assert np.all(r["cross_track_error_m"] < 1.0)


def test_time_limit_and_xte_bound_are_enforced():
    init = _straight()
    # 300 s at 1.25 m/s: 375 m, the waypoint at 250 m (within 5 m) but not 500 m
    _, r = _run(_grid(), {**TIER, "time_limit_s": 300.0}, "oracle", init=init)
    assert not r["success"][0] and r["waypoints_reached"][0] == 1 and r["T_s"][0] == 300.0
    # all waypoints reached but the mean cross-track error is above a (tiny) bound -> failure
    init2 = _straight()
    init2["pos0"] = init2["pos0"] + np.array([0.0, 0.0, 10.0])  # start 10 m off the route
    _, r = _run(_grid(), {**TIER, "xte_max_m": 0.1}, "oracle", init=init2)
    assert r["waypoints_reached"][0] == 3 and r["cross_track_error_m"][0] > 0.1
    assert not r["success"][0] and r["T_s"][0] == 900.0
    _, r = _run(_grid(), TIER, "oracle", init=init2)
    assert r["success"][0]


def test_cross_current_separates_methods_by_information_only():
    # route east, current 1.5 m/s north (above the 1.25 m/s cruise speed, below v_max = 2.5):
    # the oracle's schedule flies the speed with the least energy per metre among those that
    # keep 0.1 m/s of cross-current headroom and crabs exactly on the route (kinematic: the
    # task's steering, not the hull)
    pw = power_model("remus100")
    speeds = [u for u in np.arange(0.75, 2.51, 0.25) if u - 1.5 >= 0.1 - 1e-12]
    per_m = [(pw.hotel_w + pw.k * u ** 3) / math.sqrt(u * u - 1.5 ** 2) for u in speeds]
    u = speeds[int(np.argmin(per_m))]
    assert u == 2.0
    g = _grid(0.0, 1.5)
    _, ro = _run(g, TIER, "oracle", init=_straight())
    assert ro["success"][0] and ro["cross_track_error_m"][0] < 0.01
    assert ro["T_s"][0] == math.ceil((750.0 - 5.0) / math.sqrt(u * u - 1.5 ** 2))
    # no throttle: given the truth the heuristic is the oracle, bit for bit
    _, rh0 = _run(g, TIER, "heuristic", init=_straight(), info="truth")
    for k in ("success", "T_s", "E", "cross_track_error_m", "max_cross_track_m"):
        np.testing.assert_array_equal(rh0[k], ro[k], err_msg=k)
    # with its sensors it follows the route as its dead reckoning sees it: off the true route
    _, rh = _run(g, TIER, "heuristic", init=_straight())
    assert rh["cross_track_error_m"][0] > 0.3 and rh["max_cross_track_m"][0] > 1.0
    # ... and a tight cross-track bound turns that into a failure the oracle does not have
    tight = {**TIER, "xte_max_m": 0.2}
    _, ro = _run(g, tight, "oracle", init=_straight())
    _, rh = _run(g, tight, "heuristic", init=_straight())
    assert ro["success"][0] and not rh["success"][0]
    # the true position alone gives it back the route: what was left was its current estimate
    _, rp = _run(g, TIER, "heuristic", init=_straight(), info="true_position")
    assert rp["cross_track_error_m"][0] < rh["cross_track_error_m"][0]


def test_determinism_and_threads(coast):
    a = run_cell(coast, "RF", 2, "heuristic", episodes=4, seed=8)
    b = run_cell(coast, "RF", 2, "heuristic", episodes=4, seed=8)
    pd.testing.assert_frame_equal(a, b)
    np.testing.assert_array_equal(a["primary"], a["cross_track_error_m"])
    assert a["waypoints_reached"].dtype == np.int64
    if numba.config.NUMBA_NUM_THREADS >= 2:
        c = on_one_thread(run_cell, coast, "RF", 2, "heuristic", episodes=4, seed=8)
        pd.testing.assert_frame_equal(a, c)


def test_tier_table_monotone_and_declared():
    table = load_task_table("RF")
    tiers = table["tiers"]
    assert_tier_table_monotone(table)
    for t in (1, 2, 3):
        assert set(tiers[t]) == set(table["harder"])
        assert {"current_ms", "time_limit_s", "energy_reserve", "forecast_lead_h"} <= set(tiers[t])
    assert tiers[3]["current_ms"][0] > tiers[1]["current_ms"][0]
    assert (tiers[3]["n_waypoints"] * tiers[3]["leg_m"] > tiers[1]["n_waypoints"]
            * tiers[1]["leg_m"])
    assert tiers[3]["energy_reserve"] < tiers[1]["energy_reserve"]
    assert tiers[3]["forecast_lead_h"] > tiers[1]["forecast_lead_h"]
    assert table["vehicle"] == "remus100"
    assert table["agents"] == {"default": 1, "range": [1, 1]}


# ------------------------------------------------------------------------------ energy, planning

def _east(n_ep=1, leg=900.0, n_wp=2):
    init = _straight(leg, n_wp)
    return {k: np.repeat(v, n_ep, axis=0) for k, v in init.items()}


def test_speed_schedule_beats_the_constant_speed_crabber(monkeypatch):
    # a 1.0 m/s head current along an east-going route: the schedule flies faster than
    # cruise (least energy per metre against the current); the crabber at its cruise speed
    # makes 0.25 m/s over ground and spends twice the energy
    g = _grid(-1.0, 0.0)
    tier = {**TIER, "time_limit_s": 12000.0, "wp_radius_m": 10.0, "xte_max_m": 5.0,
            "energy_reserve": 0.10, "forecast_lead_h": 24.0}
    init = _east()
    _, ro = _run(g, tier, "oracle", init=init)
    assert ro["success"][0] and ro["energy_ratio"][0] <= 1.0
    ep = Episodes(rf, g, tier, init, "oracle", "kinematic", VEHICLE, 0)
    assert np.all(ep.H.wspd[0, :ep.H.wcount[0] - 1] > 1.25)
    monkeypatch.setattr(POLICY, "plan_episode", POLICY.straight_plan)
    _, rs = _run(g, tier, "heuristic", init=init, info="truth")
    assert not rs["success"][0] and rs["energy_ratio"][0] >= 1.5


def test_forecast_schedule_spends_more_than_the_oracles():
    # a uniform 0.9 m/s head current, a 4-day-old forecast: given its true position (the
    # forecast is the only difference) the heuristic's schedule never spends less than the
    # oracle's and fails a 2 % reserve where the oracle succeeds
    g = _grid(-0.9, 0.0)
    tier = {**TIER, "time_limit_s": 12000.0, "wp_radius_m": 10.0, "xte_max_m": 5.0,
            "energy_reserve": 0.02, "forecast_lead_h": 96.0}
    init = _east(8)
    _, ro = _run(g, tier, "oracle", init=init)
    _, rh = _run(g, tier, "heuristic", init=init, info="true_position")
    assert ro["success"].all()
    assert np.all(rh["energy_ratio"] >= ro["energy_ratio"] - 1e-3)
    assert np.mean(rh["energy_ratio"] > ro["energy_ratio"] + 0.01) >= 0.5
    assert not rh["success"].all()
    _, rt = _run(g, tier, "heuristic", init=init, info="truth")
    for k in ("success", "T_s", "E", "energy_wh", "cross_track_error_m"):
        np.testing.assert_array_equal(rt[k], ro[k], err_msg=k)


def test_energy_allocation_is_the_best_schedule_plus_the_reserve():
    g = _grid(-0.5, 0.3)
    tier = {**TIER, "time_limit_s": 6000.0, "energy_reserve": 0.05}
    init = _east()
    P, W = rf.make(g, tier, init)
    pw = power_model("remus100")
    # east into a 0.5 m/s head and 0.3 m/s cross current: ground speed sqrt(u^2 - 0.09) - 0.5
    per_m = min((pw.hotel_w + pw.k * u ** 3) / (math.sqrt(u * u - 0.09) - 0.5)
                for u in np.arange(0.75, 2.51, 0.25) if u - 0.3 >= 0.1)
    np.testing.assert_allclose(W.eref[0], 1800.0 * per_m, rtol=1e-6)   # float32 field
    np.testing.assert_allclose(W.budget[0], 1.05 * W.eref[0])
    # an allocation it cannot meet: every waypoint, over the allocation: failure
    ep = Episodes(rf, g, tier, init, "oracle", "kinematic", VEHICLE, 0)
    ep.W.budget[:] = 0.5 * ep.W.eref
    r = ep.run().results()
    assert not r["success"][0] and r["waypoints_reached"][0] == 2
    assert r["energy_ratio"][0] > 0.95 and r["T_s"][0] == tier["time_limit_s"]


# ------------------------------------------------------------------------------ public view

def test_briefing_is_the_route_and_the_field_the_method_is_given():
    # the route, its tolerances and the field at its depth around its vertices: the truth
    # for the oracle, the forecast (the episode's forecast error on the truth) for the
    # heuristic; the plan is made from the briefing alone
    g = _grid(-0.5, 0.3)
    tier = {**TIER, "time_limit_s": 6000.0, "energy_reserve": 0.05, "forecast_lead_h": 48.0}
    init = _east(2)
    eo = Episodes(rf, g, tier, init, "oracle", "kinematic", VEHICLE, 0)
    eh = Episodes(rf, g, tier, init, "heuristic", "kinematic", VEHICLE, 0)
    for ep in (eo, eh):
        B = ep.B
        np.testing.assert_array_equal(B.route, init["route"])
        assert B.radius == TIER["wp_radius_m"] and B.xte_max == TIER["xte_max_m"]
        np.testing.assert_array_equal(B.energy_allocation, ep.W.budget)
        assert np.isfinite(B.energy_allocation).all()
    pts = init["route"][0][:, [0, 2]]
    truth = routing.mission_field(g, pts, 5.0, 0.0, tier["time_limit_s"], fixed=True)
    fc = routing.mission_field(g, pts, 5.0, 0.0, tier["time_limit_s"], fixed=True,
                               fc=eh.LS.fc, e=1)
    for got, want in ((routing.unpack_field(eo.B, 0), truth),
                      (routing.unpack_field(eh.B, 1), fc)):
        for k in ("cur", "times", "free"):
            np.testing.assert_array_equal(getattr(got, k), getattr(want, k), err_msg=k)
        assert (got.x0, got.z0, got.h) == (want.x0, want.z0, want.h)
    assert not np.array_equal(routing.unpack_field(eh.B, 1).cur, truth.cur)
    # the method's plan: the schedule on its briefing's field, in its memory
    for ep in (eo, eh):
        H = POLICY.memory(ep.B, ep.M)
        POLICY.prepare(ep.B, ep.M, H)
        for a, b in zip(H, ep.H):
            np.testing.assert_array_equal(a, b)
        r = routing.plan_on_field(routing.unpack_field(ep.B, 0), pts, 0.0, VEHICLE.v_max,
                                  power_model("remus100"), fixed=True)
        np.testing.assert_array_equal(ep.H.wspd[0, :ep.H.wcount[0] - 1], r.speed)


def test_cue_and_energy_fields():
    # the cue: the route point CUE_LOOKAHEAD_M ahead of the known projection on the mission
    # computer's leg; the task's own fields: the energy used (J) and its share of the allocation
    g = _grid(-0.5, 0.3)
    tier = {**TIER, "time_limit_s": 6000.0, "energy_reserve": 0.05}
    init = _east()
    ep = Episodes(rf, g, tier, init, "oracle", "kinematic", VEHICLE, 0)
    assert rf.OBS_EXTRA == ("energy_j", "energy_frac")
    O = ep.observe()
    assert O.shape == (1, 1, OBS_DIM + 2)
    np.testing.assert_array_equal(O[0, 0, :3], [rf.CUE_LOOKAHEAD_M, 0.0, 0.0])
    np.testing.assert_array_equal(O[0, 0, OBS_DIM:], [0.0, 0.0])
    ep.run(100)
    O = ep.C.O
    used = ep.W.acc[0, 2]
    assert used > 0.0
    assert O[0, 0, OBS_DIM] == used and O[0, 0, OBS_DIM + 1] == used / ep.W.budget[0]
    # the cue is on the route (z = 0, 5 m deep), CUE_LOOKAHEAD_M ahead of the projection
    X = ep.known_state[0, 0, :3]
    cue = X + O[0, 0, :3]
    np.testing.assert_allclose(cue, [X[0] + rf.CUE_LOOKAHEAD_M, 5.0, 0.0], atol=1e-9)
    r = ep.run().results()
    O = ep.C.O   # the final state's: the whole episode's energy
    assert O[0, 0, OBS_DIM] == pytest.approx(r["energy_wh"][0] * 3600.0, rel=1e-12)
    # past the route as far as the vehicle knows: the cue is the last waypoint
    np.testing.assert_allclose(ep.known_state[0, 0, :3] + O[0, 0, :3], init["route"][0, -1],
                               atol=1e-9)
    # without a reserve there is no allocation: the share is 0
    ep = Episodes(rf, g, TIER, init, "oracle", "kinematic", VEHICLE, 0)
    ep.run(50)
    assert ep.C.O[0, 0, OBS_DIM] > 0.0 and ep.C.O[0, 0, OBS_DIM + 1] == 0.0
