"""SK (station keeping): reset geometry, hold rule, metrics, determinism, tier table."""

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
from oneocean.tasks import run_cell, sk
from oneocean.tasks.common import load_task_table
from oneocean.tasks.episodes import rollout
from oneocean.testing import make_test_grid, uniform_grid
from task_helpers import assert_tier_table_monotone, on_one_thread

TIER = {"time_limit_s": 400.0, "probe_noise_ms": 0.0,
        "hold_time_s": 200.0, "hold_radius_m": 2.0, "dt_s": 1.0}


def _grid(ce=0.0, cn=0.0, depth=60.0):
    return E.load_grid(uniform_grid(ce, cn, depth_m=depth, nx=21, ny=21, dx_m=100.0))


@pytest.fixture(scope="module")
def coast():
    return E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))


def _run(grid, tier, method, dyn="kinematic", n=4, seed=0, vehicle=None, init=None):
    init = init if init is not None else sk.reset(grid, tier, 1, n, seed)
    return init, rollout(sk, grid, tier, init, method, dyn, vehicle or E.load_vehicle(), seed)


def test_reset_geometry_is_valid(coast):
    init = sk.reset(coast, TIER, 1, 10, seed=1)
    stn = init["station"]
    np.testing.assert_array_equal(init["pos0"][:, 0], stn)
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


def test_oracle_holds_in_calm_water():
    _, r = _run(_grid(), TIER, "oracle", dyn="6dof")
    assert r["success"].all()
    np.testing.assert_array_equal(r["T_s"], TIER["hold_time_s"])  # stops when the hold is done
    np.testing.assert_array_equal(r["hold_s"], TIER["hold_time_s"])
    assert np.all(r["rms_error_m"] < 1e-6) and np.all(r["heading_rms_deg"] < 1e-6)
    np.testing.assert_array_equal(r["E"], 0.0)  # nothing to fight: zero action


def test_methods_differ_in_information_only():
    """No throttle: both methods spend the full v_max. Without probe noise the heuristic IS
    the oracle; against a current of 0.9 v_max both hold exactly, above v_max nobody holds."""
    v_max = E.load_vehicle().v_max
    c = 0.9 * v_max
    g = _grid(c, 0.0)
    _, ro = _run(g, TIER, "oracle")
    _, rh = _run(g, TIER, "heuristic")
    for k in ro:
        np.testing.assert_array_equal(rh[k], ro[k])
    assert ro["success"].all() and np.all(ro["max_error_m"] < 1e-6)
    np.testing.assert_allclose(ro["E"], c ** 2 * TIER["hold_time_s"])
    # pushed downstream at 0.5 m/s for the whole episode
    _, r = _run(_grid(v_max + 0.5, 0.0), TIER, "oracle")
    assert not r["success"].any()
    np.testing.assert_array_equal(r["T_s"], TIER["time_limit_s"])
    np.testing.assert_allclose(r["max_error_m"], 0.5 * TIER["time_limit_s"])
    assert np.all(np.isnan(r["rms_error_m"])) and np.all(np.isnan(r["heading_rms_deg"]))


def test_station_rms_is_over_the_hold_window():
    """Released 4 m off station (kinematic, calm, KP = 0.4, 1.6 m/s < v_max): the distance
    after step k is 4 * 0.6^k, inside the 2 m radius from step 2 on, so the hold window is
    steps 2..201 and rms_error_m = sqrt(mean over it of (4 * 0.6^k)^2); the approach (2.4 m)
    is not in it. final_rms_m (the episode's last H steps) is the same window here."""
    g = _grid()
    init = sk.reset(g, TIER, 1, 1, 0)
    init["pos0"] = init["pos0"] + np.array([4.0, 0.0, 0.0])
    _, r = _run(g, TIER, "oracle", init=init)
    assert r["success"][0] and r["T_s"][0] == 201.0
    d = 4.0 * 0.6 ** np.arange(2, 202)
    want = math.sqrt(np.mean(d ** 2))
    assert r["rms_error_m"][0] == pytest.approx(want, rel=1e-9)
    assert r["final_rms_m"][0] == pytest.approx(want, rel=1e-9)
    assert r["max_error_m"][0] == pytest.approx(2.4)
    # the old definition (every step run) would have counted the approach
    d_all = 4.0 * 0.6 ** np.arange(1, 202)
    assert math.sqrt(np.mean(d_all ** 2)) > 1.5 * want


def test_hold_window_must_be_contiguous():
    # the agent is released 6 m off station (outside 2 m) and must re-enter, then hold 200 s
    g = _grid()
    init = sk.reset(g, TIER, 1, 2, 0)
    init["pos0"] = init["pos0"] + np.array([6.0, 0.0, 0.0])
    _, r = _run(g, TIER, "oracle", init=init)
    assert r["success"].all()
    # kinematic, KP = 0.4: 6 -> 3.6 -> 2.16 -> 1.296 m: inside from step 3, then 200 s
    np.testing.assert_array_equal(r["T_s"], 202.0)
    np.testing.assert_array_equal(r["hold_s"], 200.0)
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
    # never held: no station RMS (NaN); the last hold_time_s (steps 201..400, 0.3 k m off)
    assert np.all(np.isnan(r["rms_error_m"])) and np.all(np.isnan(r["heading_rms_deg"]))
    want = math.sqrt(np.mean((0.3 * np.arange(201, 401)) ** 2))
    np.testing.assert_allclose(r["final_rms_m"], want, rtol=1e-6)  # float32 current


def test_probe_noise_degrades_heuristic_only(coast):
    # the coast's currents at half gain (the run's forcing, not a tier key), 6dof, on the
    # task's own vehicle (the BlueROV2 Heavy, 0.85 m/s)
    half = E.with_forcing(coast, current_gain=0.5)
    rov = E.load_vehicle(load_task_table("SK")["vehicle"])
    tier = {**TIER, "probe_noise_ms": 0.3}
    init = sk.reset(half, tier, 1, 6, 3)
    _, rh = _run(half, tier, "heuristic", dyn="6dof", init=init, vehicle=rov)
    _, ro = _run(half, tier, "oracle", dyn="6dof", init=init, vehicle=rov)
    assert np.all(rh["final_rms_m"] > ro["final_rms_m"])
    held = rh["success"] & ro["success"]
    assert held.any() and np.all(rh["rms_error_m"][held] > ro["rms_error_m"][held])


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
        assert {"current_band", "time_limit_s", "probe_noise_ms"} <= set(tiers[t])
    # station keeping is an ROV's job (a torpedo cannot hover or crab)
    assert table["vehicle"] == "bluerov2_heavy"
    assert table["agents"] == {"default": 1, "range": [1, 1]}
    assert math.isclose(table["dt_s"], 1.0)
