"""DPT (depth-profile tracking): profile geometry, success rule, metrics, the briefing, the
task's cue and the heuristic's own leg pointer, determinism."""

from __future__ import annotations

import math

import numba
import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.errors import ConfigError
from oneocean.methods.heuristic import dpt as pol_dpt
from oneocean.tasks import dpt, run_cell
from oneocean.tasks.spawn import path_clear
from oneocean.tasks.tiers import load_task_table
from oneocean.tasks.episodes import Episodes, rollout
from oneocean.testing import uniform_grid
from task_helpers import assert_tier_table_monotone, on_one_thread

TIER = {"time_limit_s": 900.0, "n_waypoints": 3,
        "leg_m": 250.0, "wp_radius_m": 5.0, "depth_span_m": 30.0, "depth_tol_m": 0.5,
        "dt_s": 1.0}


def _grid(ce=0.0, cn=0.0, depth=80.0, n=31):
    return E.load_grid(uniform_grid(ce, cn, depth_m=depth, nx=n, ny=n, dx_m=100.0))


#: The task's vehicle (its tier table): the REMUS 100, 2.5 m/s, dives by pitching.
VEHICLE = E.load_vehicle(load_task_table("DPT")["vehicle"])


def _run(grid, tier, method, dyn="kinematic", n=4, seed=0, init=None):
    init = init if init is not None else dpt.reset(grid, tier, 1, n, seed)
    return init, rollout(dpt, grid, tier, init, method, dyn, VEHICLE, seed)


def _ramp(d0=5.0, d1=30.0):
    """Straight route east with a depth ramp d0 -> d1 on the first leg, then level."""
    route = np.array([[[-400.0, d0, 0.0], [-150.0, d1, 0.0], [100.0, d1, 0.0]]])
    return {"route": route, "pos0": route[:, :1].copy(), "psi0": np.full((1, 1), math.pi / 2),
            "t0": np.zeros(1)}


def test_reset_profile_is_above_seafloor(coast):
    init = dpt.reset(coast, TIER, 1, 8, seed=4)
    r = init["route"]
    lo = dpt.PROFILE_MIN_DEPTH_M
    assert np.all((r[..., 1] >= lo) & (r[..., 1] <= lo + TIER["depth_span_m"]))
    h = np.diff(r[..., [0, 2]], axis=1)
    np.testing.assert_allclose(np.linalg.norm(h, axis=2), TIER["leg_m"])
    for e in range(8):  # every straight 3-D leg keeps the clearance above the seafloor
        assert all(path_clear(coast, a, b, dpt.MIN_ALTITUDE_M) for a, b in zip(r[e, :-1], r[e, 1:]))
    assert np.ptp(r[..., 1]) > 1.0  # the profile really varies


def test_reset_raises_when_impossible():
    with pytest.raises(ConfigError, match="DPT"):  # seafloor at 8 m: no room for 3-33 m + 5 m
        dpt.reset(_grid(depth=8.0), TIER, 1, 2, 0)
    with pytest.raises(ConfigError, match="depth_span_m"):
        dpt.reset(_grid(), {**TIER, "depth_span_m": -1.0}, 1, 2, 0)


def test_profile_at():
    s, ln, tx, tz, y, slope, xt = dpt.profile_at(0.0, 10.0, 0.0, 100.0, 30.0, 0.0, 25.0, 4.0)
    assert (s, ln, tx, tz, xt) == (25.0, 100.0, 1.0, 0.0, 4.0)
    assert y == 15.0 and slope == 0.2
    *_, y, _, _ = dpt.profile_at(0.0, 10.0, 0.0, 100.0, 30.0, 0.0, 130.0, 0.0)
    assert y == 30.0  # clamped to the leg


def test_profile_preview_tracks_the_ramp(monkeypatch):
    # 6dof REMUS 100 (pitching to change depth) on a 0.1 ramp (25 m over 250 m), no current.
    # Both methods feed the profile's slope forward (the mission gives them the profile).
    init = _ramp()
    _, ro = _run(_grid(), TIER, "oracle", dyn="6dof", init=init)
    _, rh = _run(_grid(), TIER, "heuristic", dyn="6dof", init=_ramp())
    assert ro["success"][0] and ro["waypoints_reached"][0] == 2
    assert rh["success"][0] and rh["waypoints_reached"][0] == 2
    # without the preview a P depth loop lags on the 0.1 slope at the full 2.5 m/s:
    # ~0.1 * 2.5 / KZ = 0.83 m; it flies the whole route but its RMS depth error exceeds the
    # 0.5 m tolerance, while the slope feed-forward stays well inside
    params = pol_dpt.params
    monkeypatch.setattr(pol_dpt, "params",
                        lambda method, B: params(method, B)._replace(preview=0))
    _, rn = _run(_grid(), TIER, "oracle", dyn="6dof", init=_ramp())
    assert rn["waypoints_reached"][0] == 2
    assert 0.5 < rn["max_depth_error_m"][0] < 1.5
    assert rn["depth_error_m"][0] > TIER["depth_tol_m"] and not rn["success"][0]
    assert ro["depth_error_m"][0] < 0.25 * rn["depth_error_m"][0]


def test_depth_tolerance_is_part_of_success():
    init = _ramp()
    _, r = _run(_grid(), {**TIER, "depth_tol_m": 0.01}, "heuristic", dyn="6dof", init=init)
    assert r["waypoints_reached"][0] == 2 and r["depth_error_m"][0] > 0.01
    assert not r["success"][0] and r["T_s"][0] == TIER["time_limit_s"]


def test_route_incomplete_fails():
    init = _ramp()
    # 80 s at 2.5 m/s: 200 m, short of the first waypoint (250 m, 5 m radius)
    _, r = _run(_grid(), {**TIER, "time_limit_s": 80.0}, "oracle", init=init)
    assert not r["success"][0] and r["waypoints_reached"][0] == 0 and r["T_s"][0] == 80.0


def test_random_episodes_oracle_calm(coast):
    _, r0 = _run(E.with_forcing(coast, current_gain=0.0), TIER, "oracle", dyn="6dof", n=6)
    assert r0["success"].all() and np.all(r0["depth_error_m"] < 0.1)
    np.testing.assert_array_equal(r0["violations"], 0)


def test_determinism_and_threads(coast):
    a = run_cell(coast, "DPT", 3, "heuristic", episodes=4, seed=1)
    b = run_cell(coast, "DPT", 3, "heuristic", episodes=4, seed=1)
    pd.testing.assert_frame_equal(a, b)
    np.testing.assert_array_equal(a["primary"], a["depth_error_m"])
    if numba.config.NUMBA_NUM_THREADS >= 2:
        c = on_one_thread(run_cell, coast, "DPT", 3, "heuristic", episodes=4, seed=1)
        pd.testing.assert_frame_equal(a, c)


def test_tier_table_monotone_and_declared():
    table = load_task_table("DPT")
    tiers = table["tiers"]
    assert_tier_table_monotone(table)
    for t in (1, 2, 3):
        assert set(tiers[t]) == set(table["harder"])
        assert {"current_band", "time_limit_s"} <= set(tiers[t])
    assert table["vehicle"] == "remus100"
    assert table["agents"] == {"default": 1, "range": [1, 1]}


def test_briefing_cue_and_the_heuristics_own_leg_pointer():
    # the briefing: the route with its profile and the tolerances
    init = _ramp()
    ep = Episodes(dpt, _grid(), TIER, init, "oracle", "6dof", VEHICLE, 0)
    np.testing.assert_array_equal(ep.B.route, init["route"])
    assert ep.B.radius == TIER["wp_radius_m"] and ep.B.depth_tol == TIER["depth_tol_m"]
    assert dpt.OBS_EXTRA == ()
    # the cue: CUE_LOOKAHEAD_M along the first leg from the known projection, at the target
    # depth (the profile at the projection: 5 m + 25 m over the first 250 m)
    O = ep.observe()
    np.testing.assert_allclose(O[0, 0, :3], [dpt.CUE_LOOKAHEAD_M, 0.0, 0.0], atol=1e-12)
    ep.run(40)
    X = ep.known_state[0, 0, :3]
    s = X[0] + 400.0
    assert 20.0 < s < 230.0
    np.testing.assert_allclose(X + ep.C.O[0, 0, :3],
                               [X[0] + dpt.CUE_LOOKAHEAD_M, 5.0 + 0.1 * s, 0.0], atol=1e-9)
    r = ep.run().results()
    assert r["success"][0] and r["waypoints_reached"][0] == 2
    # the task's mission computer advanced its pointer on the final state too (the route
    # done: the cue is the last waypoint); the method's own pointer, advanced in its act on
    # the observations of the steps it acted on, stopped at the last leg
    assert ep.W.nwp[0] == 3 and ep.H.nwp[0] == 2
    np.testing.assert_allclose(ep.known_state[0, 0, :3] + ep.C.O[0, 0, :3],
                               init["route"][0, -1], atol=1e-9)
