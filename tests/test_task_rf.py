"""RF (route following): reset geometry, waypoint/xte success rule, metrics, determinism."""

from __future__ import annotations

import math

import numba
import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.engine.grid import with_forcing
from oneocean.errors import ConfigError
from oneocean.tasks import rf, run_cell
from oneocean.tasks.common import load_task_table, path_clear
from oneocean.tasks.episodes import rollout
from oneocean.testing import make_test_grid, uniform_grid
from task_helpers import assert_tier_table_monotone, on_one_thread

TIER = {"time_limit_s": 900.0, "probe_noise_ms": 0.0, "n_waypoints": 3,
        "leg_m": 250.0, "wp_radius_m": 5.0, "xte_max_m": 3.0, "dt_s": 1.0}


def _grid(ce=0.0, cn=0.0, depth=60.0, n=31):
    return E.load_grid(uniform_grid(ce, cn, depth_m=depth, nx=n, ny=n, dx_m=100.0))


@pytest.fixture(scope="module")
def coast():
    return E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))


#: The task's vehicle (its tier table): the REMUS 100, 2.5 m/s.
VEHICLE = E.load_vehicle(load_task_table("RF")["vehicle"])


def _run(grid, tier, method, dyn="kinematic", n=4, seed=0, init=None):
    init = init if init is not None else rf.reset(grid, tier, 1, n, seed)
    return init, rollout(rf, grid, tier, init, method, dyn, VEHICLE, seed)


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
    # kinematic (the task logic, not the vehicle): 750 m at the REMUS's 2.5 m/s; the last
    # waypoint counts within 5 m
    assert VEHICLE.v_max == 2.5
    assert r["T_s"][0] == math.ceil((750.0 - 5.0) / 2.5)


def test_random_routes_oracle_calm(coast):
    # calm water (g = 0 on the coast's currents); the 6dof REMUS 100 turns the route's
    # corners on its >= 5 m turning circle and still keeps its mean cross-track error < 1 m
    calm = with_forcing(coast, current_gain=0.0)
    _, r = _run(calm, TIER, "oracle", dyn="6dof", n=6)
    assert r["success"].all()
    assert np.all(r["cross_track_error_m"] < 1.0)


def test_time_limit_and_xte_bound_are_enforced():
    init = _straight()
    # 200 s at 2.5 m/s: 500 m, waypoints at 250 and 500 m (within 5 m) but not 750 m
    _, r = _run(_grid(), {**TIER, "time_limit_s": 200.0}, "oracle", init=init)
    assert not r["success"][0] and r["waypoints_reached"][0] == 2 and r["T_s"][0] == 200.0
    # all waypoints reached but the mean cross-track error is above a (tiny) bound -> failure
    init2 = _straight()
    init2["pos0"] = init2["pos0"] + np.array([0.0, 0.0, 10.0])  # start 10 m off the route
    _, r = _run(_grid(), {**TIER, "xte_max_m": 0.1}, "oracle", init=init2)
    assert r["waypoints_reached"][0] == 3 and r["cross_track_error_m"][0] > 0.1
    assert not r["success"][0] and r["T_s"][0] == 900.0
    _, r = _run(_grid(), TIER, "oracle", init=init2)
    assert r["success"][0]


def test_cross_current_separates_methods_by_information_only():
    # route east, current 1.5 m/s north (< v_max = 2.5): the oracle crabs exactly on the route
    # at ground speed sqrt(2.5^2 - 1.5^2) = 2 m/s (kinematic: the task's steering, not the hull)
    g = _grid(0.0, 1.5)
    _, ro = _run(g, TIER, "oracle", init=_straight())
    assert ro["success"][0] and ro["cross_track_error_m"][0] < 0.01
    assert ro["T_s"][0] == math.ceil((750.0 - 5.0) / 2.0)
    # no throttle: with probe noise 0 the heuristic is the oracle, bit for bit
    _, rh0 = _run(g, {**TIER, "probe_noise_ms": 0.0}, "heuristic", init=_straight())
    for k in ("success", "T_s", "E", "cross_track_error_m", "max_cross_track_m"):
        np.testing.assert_array_equal(rh0[k], ro[k], err_msg=k)
    # with a noisy probe it mis-crabs every step: off the route and slower
    _, rh = _run(g, {**TIER, "probe_noise_ms": 0.5}, "heuristic", init=_straight())
    assert rh["cross_track_error_m"][0] > 0.3 and rh["max_cross_track_m"][0] > 1.0
    assert rh["T_s"][0] > ro["T_s"][0]
    # ... and a tight cross-track bound turns that into a failure the oracle does not have
    tight = {**TIER, "xte_max_m": 0.2}
    _, ro = _run(g, {**tight, "probe_noise_ms": 0.5}, "oracle", init=_straight())
    _, rh = _run(g, {**tight, "probe_noise_ms": 0.5}, "heuristic", init=_straight())
    assert ro["success"][0] and not rh["success"][0]


def test_determinism_and_threads(coast):
    a = run_cell(coast, "RF", 3, "heuristic", episodes=4, seed=8)
    b = run_cell(coast, "RF", 3, "heuristic", episodes=4, seed=8)
    pd.testing.assert_frame_equal(a, b)
    np.testing.assert_array_equal(a["primary"], a["cross_track_error_m"])
    assert a["waypoints_reached"].dtype == np.int64
    if numba.config.NUMBA_NUM_THREADS >= 2:
        c = on_one_thread(run_cell, coast, "RF", 3, "heuristic", episodes=4, seed=8)
        pd.testing.assert_frame_equal(a, c)


def test_tier_table_monotone_and_declared():
    table = load_task_table("RF")
    tiers = table["tiers"]
    assert_tier_table_monotone(table)
    for t in (1, 2, 3):
        assert set(tiers[t]) == set(table["harder"])
        assert {"current_band", "time_limit_s", "probe_noise_ms"} <= set(tiers[t])
    assert table["vehicle"] == "remus100"
    assert table["agents"] == {"default": 1, "range": [1, 1]}
