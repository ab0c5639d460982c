"""SK (station keeping): reset geometry (release offset, start time in a changing current),
hold rule, metrics (station-keeping RMS over the window for every episode, hold-window RMS),
the briefing and the cue, determinism, tier table."""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.engine import status as st
from oneocean.engine.dynamics import P_VMAX
from oneocean.errors import ConfigError
from oneocean.tasks import cell_frame, run_cell, sk
from oneocean.tasks.spawn import episode_generators, start_times
from oneocean.tasks.tiers import load_task_table
from oneocean.evaluate import Observation
from oneocean.methods.heuristic import FusedPolicy
from oneocean.tasks.episodes import Episodes, rollout
from oneocean.testing import uniform_grid
from task_helpers import assert_tier_table_monotone, on_one_thread

TIER = {"time_limit_s": 400.0, "hold_time_s": 200.0, "hold_radius_m": 2.0, "dt_s": 1.0}


def _grid(ce=0.0, cn=0.0, depth=60.0):
    return E.load_grid(uniform_grid(ce, cn, depth_m=depth, nx=21, ny=21, dx_m=100.0))


def _run(grid, tier, method, dyn="kinematic", n=4, seed=0, vehicle=None, init=None,
         info=None):
    init = init if init is not None else sk.reset(grid, tier, 1, n, seed)
    return init, rollout(sk, grid, tier, init, method, dyn, vehicle or E.load_vehicle(), seed,
                         info=info)


def test_reset_geometry_is_valid(coast):
    init = sk.reset(coast, TIER, 1, 10, seed=1)
    stn = init["station"]
    np.testing.assert_array_equal(init["pos0"][:, 0], stn)   # no start_offset_m: on station
    np.testing.assert_array_equal(init["regime_points"], np.stack([stn, stn], axis=1))
    assert np.all(E.feasibility(coast, stn, 0.5, sk.MIN_ALTITUDE_M) == st.OK)
    # heading into the local current at the start time
    c = E.sample_currents(coast, stn, init["t0"])
    np.testing.assert_allclose(init["heading"], np.arctan2(-c[:, 0], -c[:, 1]))
    np.testing.assert_array_equal(init["psi0"][:, 0], init["heading"])


def test_reset_raises_when_impossible():
    with pytest.raises(ConfigError, match="SK"):
        sk.reset(_grid(depth=6.0), TIER, 1, 2, 0)
    with pytest.raises(ConfigError, match="hold_time_s"):
        sk.reset(_grid(), {**TIER, "hold_time_s": 500.0}, 1, 2, 0)
    with pytest.raises(ConfigError, match="single-agent"):
        sk.reset(_grid(), TIER, 3, 2, 0)
    with pytest.raises(ConfigError, match="settling allowance"):
        sk.reset(_grid(), {**TIER, "time_limit_s": sk.SETTLE_S, "hold_time_s": 30.0}, 1, 2, 0)
    with pytest.raises(ConfigError, match="start_offset_m"):
        sk.reset(_grid(), {**TIER, "start_offset_m": -1.0}, 1, 2, 0)


def test_release_is_start_offset_m_from_the_station(coast):
    """The vehicle is released start_offset_m (horizontal, random bearing) from the station,
    in valid water at the station's depth, facing the station heading; the station, its
    heading and the start time are those of the on-station episode (the release is drawn
    after them), and everything is deterministic per seed."""
    on = sk.reset(coast, TIER, 1, 12, seed=4)
    off = sk.reset(coast, {**TIER, "start_offset_m": 5.0}, 1, 12, seed=4)
    again = sk.reset(coast, {**TIER, "start_offset_m": 5.0}, 1, 12, seed=4)
    for k in off:
        np.testing.assert_array_equal(off[k], again[k], err_msg=k)
    for k in ("station", "heading", "psi0", "t0"):
        np.testing.assert_array_equal(off[k], on[k], err_msg=k)
    d = off["pos0"][:, 0] - off["station"]
    np.testing.assert_allclose(np.hypot(d[:, 0], d[:, 2]), 5.0, rtol=1e-12)
    np.testing.assert_array_equal(d[:, 1], 0.0)
    assert np.unique(np.round(np.arctan2(d[:, 0], d[:, 2]), 6)).size == 12   # random bearings
    assert np.all(E.feasibility(coast, off["pos0"][:, 0], 0.5, sk.MIN_ALTITUDE_M) == st.OK)
    np.testing.assert_array_equal(off["regime_points"][:, 1], off["pos0"][:, 0])


def test_start_time_is_where_the_current_changes(coast):
    """Of START_DRAWS start times, the episode starts where the station's current changes
    most over the episode: never less than at the first draw (the old uniform start), more
    at some; on a grid whose current does not vary in time, the first draw."""
    T = TIER["time_limit_s"]
    init = sk.reset(coast, TIER, 1, 16, seed=5)
    first = start_times(coast, episode_generators(5, 16), T)

    def change(t):
        a = E.sample_currents(coast, init["station"], t)
        b = E.sample_currents(coast, init["station"], t + T)
        return np.hypot(*(b - a).T)

    assert np.all(change(init["t0"]) >= change(first))
    assert np.any(change(init["t0"]) > change(first) + 1e-3)
    g = _grid(0.2, 0.1)
    np.testing.assert_array_equal(sk.reset(g, TIER, 1, 4, 5)["t0"],
                                  start_times(g, episode_generators(5, 4), T))


def test_oracle_holds_in_calm_water():
    _, r = _run(_grid(), TIER, "oracle", dyn="6dof")
    assert r["success"].all()
    np.testing.assert_array_equal(r["T_s"], TIER["hold_time_s"])  # time to the first hold
    # the episode runs on to its time limit (the metric horizon), holding all the way
    np.testing.assert_array_equal(r["hold_s"], TIER["time_limit_s"])
    assert np.all(r["rms_error_m"] < 1e-6) and np.all(r["hold_rms_m"] < 1e-6)
    assert np.all(r["heading_rms_deg"] < 1e-6)
    np.testing.assert_array_equal(r["E"], 0.0)  # nothing to fight: zero action


def test_methods_differ_in_information_only():
    """No throttle: both methods spend the full v_max. Given the truth the heuristic IS the
    oracle; against a current of 0.9 v_max both hold exactly, above v_max nobody holds."""
    v_max = E.load_vehicle().v_max
    c = 0.9 * v_max
    g = _grid(c, 0.0)
    _, ro = _run(g, TIER, "oracle")
    _, rh = _run(g, TIER, "heuristic", info="truth")
    for k in ro:
        np.testing.assert_array_equal(rh[k], ro[k])
    assert ro["success"].all() and np.all(ro["max_error_m"] < 1e-6)
    np.testing.assert_allclose(ro["E"], c ** 2 * TIER["hold_time_s"])
    # pushed downstream at 0.5 m/s for the whole episode
    _, r = _run(_grid(v_max + 0.5, 0.0), TIER, "oracle")
    assert not r["success"].any()
    np.testing.assert_array_equal(r["T_s"], TIER["time_limit_s"])
    np.testing.assert_allclose(r["max_error_m"], 0.5 * TIER["time_limit_s"])
    # never held: no hold window (NaN), but a station-keeping error like every episode:
    # 0.5 k m after step k, over the window (SETTLE_S, T] = steps 61..400
    assert np.all(np.isnan(r["hold_rms_m"])) and np.all(np.isnan(r["heading_rms_deg"]))
    k = np.arange(61, 401)
    np.testing.assert_allclose(r["rms_error_m"], math.sqrt(np.mean((0.5 * k) ** 2)), rtol=1e-9)


def test_station_rms_windows():
    """Released 4 m off station (kinematic, calm, KP = 0.4, 1.6 m/s < v_max): the distance
    after step k is 4 * 0.6^k, inside the 2 m radius from step 2 on. The hold window is steps
    2..201 (hold_rms_m, T_s = 201 s; the approach, 2.4 m, is not in it: the oracle is not
    exact there); the station-keeping window is steps 61..400 (rms_error_m, max_error_m: the
    episode runs on to its time limit), by which time it is on the station; final_rms_m is
    the last H = 200 steps, 201..400."""
    g = _grid()
    init = sk.reset(g, TIER, 1, 1, 0)
    init["pos0"] = init["pos0"] + np.array([4.0, 0.0, 0.0])
    _, r = _run(g, TIER, "oracle", init=init)
    assert r["success"][0] and r["T_s"][0] == 201.0

    def rms(k0, k1):
        return math.sqrt(np.mean((4.0 * 0.6 ** np.arange(k0, k1 + 1)) ** 2))

    assert r["hold_rms_m"][0] == pytest.approx(rms(2, 201), rel=1e-9)
    assert r["hold_rms_m"][0] > 0.1   # released off station: the hold starts on the approach
    # on the station by the end of the settling allowance (within the 1e-9 m at which the
    # steering stops correcting): no station-keeping error
    assert r["rms_error_m"][0] < 1e-9 and r["max_error_m"][0] < 1e-9
    assert r["final_rms_m"][0] < 1e-9


def test_station_rms_counts_every_episode():
    """One episode holds on the station (RMS 0); the other is released 100 m off with a
    0.2 m/s speed budget (kinematic, calm: 100 - 0.2 k m after step k) and never arrives.
    Its station-keeping RMS over steps 61..400 is in the cell's primary column and mean; its
    hold-window RMS is NaN (the paper's Station RMS counts failures; hold_rms_m cannot)."""
    g = _grid()
    veh = E.load_vehicle()
    p = veh.params.copy()
    p[P_VMAX] = 0.2
    slow = dataclasses.replace(veh, params=p)
    init = sk.reset(g, TIER, 1, 2, 0)
    centre = np.array([0.5 * (g.x0 + g.x_max), 20.0, 0.5 * (g.z0 + g.z_max)])
    init["station"][:] = centre
    init["pos0"][:, 0] = centre
    init["pos0"][1, 0, 0] += 100.0
    _, r = _run(g, TIER, "oracle", init=init, vehicle=slow)
    np.testing.assert_array_equal(r["success"], [True, False])
    fail = math.sqrt(np.mean((100.0 - 0.2 * np.arange(61, 401)) ** 2))
    np.testing.assert_allclose(r["rms_error_m"], [0.0, fail], rtol=1e-9, atol=1e-12)
    assert r["hold_rms_m"][0] == 0.0 and np.isnan(r["hold_rms_m"][1])
    df = cell_frame(sk, r, 1, "oracle", 1, "kinematic", True, 2, 0)
    np.testing.assert_array_equal(df["primary"], df["rms_error_m"])
    assert df["primary"].mean() == pytest.approx(fail / 2, rel=1e-9)


def test_hold_window_must_be_contiguous():
    # the agent is released 6 m off station (outside 2 m) and must re-enter, then hold 200 s
    g = _grid()
    init = sk.reset(g, TIER, 1, 2, 0)
    init["pos0"] = init["pos0"] + np.array([6.0, 0.0, 0.0])
    _, r = _run(g, TIER, "oracle", init=init)
    assert r["success"].all()
    # kinematic, KP = 0.4: 6 -> 3.6 -> 2.16 -> 1.296 m: inside from step 3, then 200 s
    np.testing.assert_array_equal(r["T_s"], 202.0)
    np.testing.assert_array_equal(r["hold_s"], 398.0)   # and on to the time limit
    # a hold window longer than the remaining time fails
    tier = {**TIER, "hold_time_s": 400.0}
    _, r = _run(g, tier, "oracle", init=init)
    assert not r["success"].any() and np.all(r["hold_s"] == 398.0)


def test_do_nothing_drifts_off_and_fails():
    veh = E.load_vehicle()
    p = veh.params.copy()
    p[P_VMAX] = 0.0
    _, r = _run(_grid(0.3, 0.0), TIER, "oracle", vehicle=dataclasses.replace(veh, params=p))
    assert not r["success"].any()
    np.testing.assert_array_equal(r["E"], 0.0)
    np.testing.assert_array_equal(r["hold_s"], 6.0)  # 1.8 m after 6 steps, 2.1 m after 7
    np.testing.assert_allclose(r["max_error_m"], 0.3 * TIER["time_limit_s"])
    # never held: no hold-window RMS (NaN); the station-keeping RMS over steps 61..400 and
    # the last hold_time_s (steps 201..400) of a vehicle 0.3 k m off after step k
    assert np.all(np.isnan(r["hold_rms_m"])) and np.all(np.isnan(r["heading_rms_deg"]))
    want = math.sqrt(np.mean((0.3 * np.arange(61, 401)) ** 2))
    np.testing.assert_allclose(r["rms_error_m"], want, rtol=1e-6)  # float32 current
    want = math.sqrt(np.mean((0.3 * np.arange(201, 401)) ** 2))
    np.testing.assert_allclose(r["final_rms_m"], want, rtol=1e-6)


def test_sensors_degrade_the_heuristic_and_truth_restores_the_oracle(coast):
    # the coast's currents at half gain (the run's forcing, not a tier key), 6dof, on the
    # task's own vehicle (the BlueROV2 Heavy, 0.85 m/s, USBL-aided navigation)
    half = E.with_forcing(coast, current_gain=0.5)
    rov = E.load_vehicle(load_task_table("SK")["vehicle"])
    tier = TIER
    init = sk.reset(half, tier, 1, 6, 3)
    _, rh = _run(half, tier, "heuristic", dyn="6dof", init=init, vehicle=rov)
    _, ro = _run(half, tier, "oracle", dyn="6dof", init=init, vehicle=rov)
    _, rt = _run(half, tier, "heuristic", dyn="6dof", init=init, vehicle=rov, info="truth")
    for k in ("success", "final_rms_m", "max_error_m"):
        np.testing.assert_array_equal(rt[k], ro[k], err_msg=k)
    assert np.all(rh["final_rms_m"] > ro["final_rms_m"])
    assert np.all(rh["rms_error_m"] > ro["rms_error_m"])
    held = rh["success"] & ro["success"]
    assert held.any() and np.all(rh["hold_rms_m"][held] > ro["hold_rms_m"][held])


def test_determinism_and_threads(coast):
    a = run_cell(coast, "SK", 3, "heuristic", episodes=6, seed=2)
    b = run_cell(coast, "SK", 3, "heuristic", episodes=6, seed=2)
    pd.testing.assert_frame_equal(a, b)
    np.testing.assert_array_equal(a["primary"], a["rms_error_m"])
    if numba.config.NUMBA_NUM_THREADS >= 2:
        c = on_one_thread(run_cell, coast, "SK", 3, "heuristic", episodes=6, seed=2)
        pd.testing.assert_frame_equal(a, c)


def test_tier_table_monotone_and_declared():
    table = load_task_table("SK")
    tiers = table["tiers"]
    assert_tier_table_monotone(table)
    for t in (1, 2, 3):
        assert set(tiers[t]) == set(table["harder"])
        assert tiers[t]["hold_time_s"] <= tiers[t]["time_limit_s"]
        assert {"current_band", "time_limit_s", "start_offset_m"} <= set(tiers[t])
        assert tiers[t]["time_limit_s"] > sk.SETTLE_S
    # harder tiers release the vehicle farther off station, in faster water, with tighter
    # tolerances (radius, hold time) and less time
    assert tiers[1]["start_offset_m"] < tiers[3]["start_offset_m"]
    assert tiers[1]["hold_radius_m"] > tiers[3]["hold_radius_m"]
    assert tiers[1]["hold_time_s"] < tiers[3]["hold_time_s"]
    # the registry names the primary first: the station-keeping RMS over every episode
    assert [m["name"] for m in table["spec"]["metrics"]] == list(sk.METRICS)
    # station keeping is an ROV's job (a torpedo cannot hover or crab)
    assert table["vehicle"] == "bluerov2_heavy"
    assert table["agents"] == {"default": 1, "range": [1, 1]}
    assert math.isclose(table["dt_s"], 1.0)


def test_briefing_cue_and_the_commanded_heading():
    # the briefing holds the station, its heading and the tolerances; the cue is the station;
    # the policy commands the briefing's station heading
    g = _grid(0.3, -0.1)
    tier = {**TIER, "start_offset_m": 3.0}
    init = sk.reset(g, tier, 1, 3, 0)
    ep = Episodes(sk, g, tier, init, "heuristic", "kinematic", E.load_vehicle(), 0)
    B = ep.B
    np.testing.assert_array_equal(B.station, init["station"])
    np.testing.assert_array_equal(B.heading, init["heading"])
    assert (B.radius, B.hold_s, B.settle_s) == (TIER["hold_radius_m"], TIER["hold_time_s"],
                                                sk.SETTLE_S)
    assert sk.OBS_EXTRA == ()
    O = ep.observe()
    np.testing.assert_allclose(ep.known_state[:, 0, :3] + O[:, 0, :3], init["station"],
                               atol=1e-9)
    d = np.linalg.norm(O[:, 0, :3], axis=1)
    assert np.all(np.abs(d - 3.0) < 2.0)   # released 3 m off, known to a few decimetres
    pol = FusedPolicy("SK")
    pol.reset(B)
    a = pol.act(Observation(O, (), np.zeros(0)))
    np.testing.assert_array_equal(a[:, 0, 3], init["heading"])
