"""AS (area scan over 3-D terrain): geometry, sensor footprint, success rule, metrics,
determinism, the briefing and the task's survey cue, planning and the tier table."""

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
from oneocean.methods.heuristic import as_ as pol
from oneocean.tasks import as_, run_cell
from oneocean.methods.steering import seek_max
from oneocean.tasks.common import O_CE, O_CN, O_GX, O_GY, O_GZ, O_X, O_Z, STANDARD
from oneocean.tasks.tiers import load_task_table
from oneocean.tasks.episodes import Episodes, rollout
from oneocean.tasks.public import COMMON
from oneocean.testing import uniform_grid
from task_helpers import assert_tier_table_monotone, on_one_thread

TIER = {"current_band": [0.0, 1.0], "time_limit_s": 900.0, "region_long_m": 160.0, "region_short_m": 80.0, "coverage_threshold": 0.95,
        "max_altitude_m": 20.0, "half_angle_deg": 45.0, "cell_m": 4.0, "seafloor_min_m": 30.0,
        "seafloor_max_m": 150.0, "min_relief_m": 0.0, "dt_s": 1.0}


def _sloped(ce=0.0, cn=0.0, nx=21, ny=21, dx=100.0):
    """Land-free grid, uniform current, seafloor deepening eastward 40 -> 80 m."""
    g = uniform_grid(ce, cn, depth_m=80.0, nx=nx, ny=ny, dx_m=dx)
    x = np.arange(nx) / (nx - 1)
    g["elevation"] = np.tile(-(40.0 + 40.0 * x), (ny, 1)).astype(np.float32)
    return E.load_grid(g)


@pytest.fixture(scope="module")
def calm():
    return _sloped()


def _still(veh=None):
    veh = veh or E.load_vehicle()
    p = veh.params.copy()
    p[P_VMAX] = 0.0
    return dataclasses.replace(veh, params=p)


def test_reset_geometry_is_valid(coast):
    tier = {**TIER, "min_relief_m": 3.0}
    init = as_.reset(coast, tier, 3, 8, seed=2)
    reg, pos0 = init["region"], init["pos0"]
    assert reg.shape == (8, 4) and pos0.shape == (8, 3, 3) and init["t0"].shape == (8,)
    w = reg[:, 2] - reg[:, 0]
    h = reg[:, 3] - reg[:, 1]
    long_ = np.where(init["long_axis"] == 0, w, h)
    short = np.where(init["long_axis"] == 0, h, w)
    np.testing.assert_allclose(long_, tier["region_long_m"])
    np.testing.assert_allclose(short, tier["region_short_m"])
    for e in range(8):
        xs = np.linspace(reg[e, 0], reg[e, 2], 9)
        zs = np.linspace(reg[e, 1], reg[e, 3], 9)
        X, Z = np.meshgrid(xs, zs)
        xz = np.ascontiguousarray(np.stack([X.ravel(), Z.ravel()], 1))
        depth = -np.array([E.sample_elevation(coast, x, z) for x, z in xz])
        land = np.array([E.sample_land(coast, x, z) for x, z in xz])
        assert depth.min() >= tier["seafloor_min_m"] - 1e-6
        assert depth.max() <= tier["seafloor_max_m"] + 1e-6
        assert np.ptp(depth) >= tier["min_relief_m"] - 0.5  # 9 x 9 subsample of the check
        assert land.max() == 0.0
        # agents start near the south-west corner, apart, in feasible water
        assert np.all(np.abs(pos0[e, :, 0] - reg[e, 0] - 0.5 * as_.SPAWN_BOX_M)
                      <= 0.5 * as_.SPAWN_BOX_M)
        assert np.all(np.abs(pos0[e, :, 2] - reg[e, 1] - 0.5 * as_.SPAWN_BOX_M)
                      <= 0.5 * as_.SPAWN_BOX_M)
        d = np.linalg.norm(pos0[e, :, None] - pos0[e, None], axis=-1) + 1e9 * np.eye(3)
        assert d.min() >= as_.SPAWN_SEPARATION_M
    assert np.all(E.feasibility(coast, pos0.reshape(-1, 3), 0.5, as_.CLEARANCE_M) == st.OK)
    assert np.all(init["t0"] + TIER["time_limit_s"] <= coast.time_s[-1])


def test_reset_raises_when_impossible(calm, coast):
    with pytest.raises(ConfigError, match="AS"):  # seafloor 40-80 m: no 100 m deep region
        as_.reset(calm, {**TIER, "seafloor_min_m": 100.0}, 1, 2, 0)
    with pytest.raises(ConfigError, match="AS"):  # 2 km grid, 5 km region
        as_.reset(calm, {**TIER, "region_long_m": 5000.0}, 1, 2, 0)
    with pytest.raises(ConfigError, match="AS"):  # flat within 160 m: no 30 m of relief
        as_.reset(calm, {**TIER, "min_relief_m": 30.0}, 1, 2, 0)
    with pytest.raises(ConfigError, match="n_agents"):
        as_.reset(calm, TIER, 11, 2, 0)
    with pytest.raises(ConfigError, match="missing"):
        as_.reset(calm, {k: v for k, v in TIER.items() if k != "cell_m"}, 1, 2, 0)
    # a region too small for its seafloor checks: a one-line error naming the key
    with pytest.raises(ConfigError, match=r"region_short_m must be >= 30 m .* got 10"):
        as_.reset(calm, {**TIER, "region_short_m": 10.0}, 1, 2, 0)


@numba.njit
def _mark_all(cov, x, z, r, x_lo, z_lo, cell, ncx, ncz):
    return as_._mark(cov, 0, x, z, r, x_lo, z_lo, cell, ncx, ncz)


def test_footprint_marks_exactly_the_cells_within_radius():
    ncx, ncz, cell = 30, 20, 4.0
    rng = np.random.default_rng(0)
    for _ in range(20):
        x, z, r = rng.uniform(-20, 140), rng.uniform(-20, 100), rng.uniform(0.5, 30)
        cov = np.zeros((1, ncx * ncz), np.uint8)
        n = _mark_all(cov, x, z, r, 0.0, 0.0, cell, ncx, ncz)
        cx = (np.arange(ncx) + 0.5) * cell
        cz = (np.arange(ncz) + 0.5) * cell
        want = ((cx[None, :] - x) ** 2 + (cz[:, None] - z) ** 2 <= r * r).ravel()
        np.testing.assert_array_equal(cov[0].astype(bool), want)
        assert n == want.sum()
        assert _mark_all(cov, x, z, r, 0.0, 0.0, cell, ncx, ncz) == 0  # counted once


def test_hovering_vehicle_covers_its_altitude_footprint_only(calm):
    """A vehicle that cannot move images exactly the cells within alt * tan(half-angle)."""
    tier = {**TIER, "time_limit_s": 30.0}
    init = as_.reset(calm, tier, 1, 4, 1)
    r = rollout(as_, calm, tier, init, "oracle", "kinematic", _still(), 0)
    assert not r["success"].any()
    np.testing.assert_array_equal(r["T_s"], 30.0)  # T on failure = time limit
    np.testing.assert_array_equal(r["E"], 0.0)
    for e in range(4):
        p = init["pos0"][e, 0]
        alt = -E.sample_elevation(calm, p[0], p[2]) - p[1]
        x_lo, z_lo, x_hi, z_hi = init["region"][e]
        nx_, nz_ = round((x_hi - x_lo) / 4.0), round((z_hi - z_lo) / 4.0)
        cx = x_lo + (np.arange(nx_) + 0.5) * 4.0
        cz = z_lo + (np.arange(nz_) + 0.5) * 4.0
        rad = alt * math.tan(math.radians(tier["half_angle_deg"]))
        n = ((cx[None, :] - p[0]) ** 2 + (cz[:, None] - p[2]) ** 2 <= rad * rad).sum()
        assert n > 0
        assert r["coverage_fraction"][e] == pytest.approx(n / (nx_ * nz_))
        assert r["mean_altitude_m"][e] == pytest.approx(alt)
    # above the sensor's maximum altitude nothing is imaged
    r2 = rollout(as_, calm, {**tier, "max_altitude_m": 4.0}, init, "oracle", "kinematic",
                 _still(), 0)
    np.testing.assert_array_equal(r2["coverage_fraction"], 0.0)
    np.testing.assert_array_equal(r2["footprint_loss_frac"], 1.0)


def test_briefing_holds_the_mission_and_the_forecast_at_the_centre(coast):
    tier = {**TIER, "min_relief_m": 3.0}
    init = as_.reset(coast, tier, 2, 3, 4)
    veh = E.load_vehicle()
    eps = {m: Episodes(as_, coast, tier, init, m, "kinematic", veh, 0)
           for m in ("heuristic", "oracle")}
    for m, ep in eps.items():
        B = ep.B
        assert B._fields == tuple(COMMON) + tuple(as_.BRIEF_FIELDS)
        np.testing.assert_array_equal(B.region, init["region"])
        np.testing.assert_array_equal(B.long_axis, init["long_axis"])
        np.testing.assert_array_equal(B.start, ep.known_state[:, :, :3])   # the start fixes
        assert (B.max_altitude, B.half_angle_deg, B.cell, B.coverage_threshold) == (
            tier["max_altitude_m"], tier["half_angle_deg"], tier["cell_m"],
            tier["coverage_threshold"])
        assert B.survey_alt == as_.SURVEY_ALT_FRAC * tier["max_altitude_m"]
        lines, cnt = as_.survey_plan(init["region"], init["long_axis"], B.line_spacing, 2)
        np.testing.assert_array_equal(B.lines, lines)
        np.testing.assert_array_equal(B.line_count, cnt)
        for e in range(3):
            # the forecast (the truth for the oracle) at the survey depth over the window
            ts, cur, depth = as_.centre_forecast(
                coast, tuple(init["region"][e]), init["t0"][e], tier["time_limit_s"],
                B.survey_alt, None if m == "oracle" else ep.LS.fc, e)
            np.testing.assert_array_equal(B.forecast_times[e], ts)
            np.testing.assert_array_equal(B.forecast_centre[e], cur)
            assert B.forecast_depth[e] == depth
            c = init["region"][e]
            seafloor = -E.sample_elevation(coast, 0.5 * (c[0] + c[2]), 0.5 * (c[1] + c[3]))
            assert depth == pytest.approx(max(seafloor - B.survey_alt, as_.MIN_DEPTH_M))
    h, o = eps["heuristic"].B, eps["oracle"].B
    np.testing.assert_array_equal(o.start, init["pos0"])               # the truth
    assert not np.array_equal(h.start, o.start)                        # a start fix error
    np.testing.assert_allclose(h.start, o.start, atol=5.0)
    np.testing.assert_array_equal(h.start[..., 1], o.start[..., 1])    # depth is measured
    assert not np.array_equal(h.forecast_centre, o.forecast_centre)    # a forecast


def test_survey_plan_is_a_team_lawnmower_along_the_long_axis():
    region = np.array([[0.0, 0.0, 200.0, 100.0], [0.0, 0.0, 100.0, 200.0]])
    lines, cnt = as_.survey_plan(region, [0, 1], 20.0, 2)
    assert cnt.tolist() == [[7, 5], [7, 5]]   # 5 strips: 3 + 2, run-in first
    # episode 0: strips along x at z = 10, 30, 50 (agent 0) and 70, 90 (agent 1), each
    # block a boustrophedon from the low end, led in RUNIN_M before its first strip
    np.testing.assert_allclose(lines[0, 0, :7], [[-20, 10], [0, 10], [200, 10], [200, 30],
                                                 [0, 30], [0, 50], [200, 50]])
    np.testing.assert_allclose(lines[0, 1, :5], [[-20, 70], [0, 70], [200, 70], [200, 90],
                                                 [0, 90]])
    # episode 1: the same along z
    np.testing.assert_allclose(lines[1, :, :, ::-1], lines[0])
    # the task's spacing: 2 a tan(half-angle) (1 - overlap) at the survey altitude
    assert as_.survey_spacing(TIER) == pytest.approx(
        2.0 * 0.75 * 20.0 * math.tan(math.radians(45.0)) * 0.8)


def _cue_point(O, e, i):
    """Agent i's cue in world m (its offset plus the observed position and depth)."""
    from oneocean.tasks.common import O_DEPTH
    o = O[e, i]
    return np.array([o[O_GX] + o[O_X], o[O_GY] + o[O_DEPTH], o[O_GZ] + o[O_Z]])


def _follow(O, v_max):
    """A follower of the cue: seek it at full speed against the observed current."""
    a = np.zeros(O.shape[:2] + (3,))
    for e in range(O.shape[0]):
        for i in range(O.shape[1]):
            o = O[e, i]
            if np.isfinite(o[O_GX]):
                a[e, i] = seek_max(0.0, 0.0, 0.0, o[O_GX], o[O_GY], o[O_GZ], v_max, 0.5,
                                   o[O_CE], o[O_CN])
    return a


@pytest.mark.parametrize("info", ["truth", "sensors"])
def test_the_cue_leads_each_agent_along_its_lines_and_a_follower_covers_the_region(calm,
                                                                                   info):
    """The task's mission computer: the cue starts at each agent's run-in point at the
    survey altitude above the chart and moves along its lines as the agent follows it; a
    policy that only follows the cue covers the region (calm water, short strips)."""
    init = as_.reset(calm, TIER, 2, 3, 1)
    veh = E.load_vehicle()
    ep = Episodes(as_, calm, TIER, init, None, "kinematic", veh, 0, info=info)
    O = ep.observe()
    B = ep.B
    for e in range(3):
        for i in range(2):
            x, z = B.lines[e, i, 0]
            want = [x, -E.sample_elevation(calm, x, z) - B.survey_alt, z]
            np.testing.assert_allclose(_cue_point(O, e, i), want, atol=1e-9)
    np.testing.assert_array_equal(ep.W.lidx, 0)
    seen = set()
    while not ep.done.all():
        ep.set_actions(_follow(O, veh.v_max))
        O = ep.step_observe()
        seen.update(int(w) for w in ep.W.lidx.ravel())
    r = ep.results()
    assert r["success"].all(), r["coverage_fraction"]
    np.testing.assert_array_equal(r["footprint_loss_frac"], 0.0)
    assert seen >= set(range(1, int(B.line_count.min())))   # every leg was cued


def test_both_methods_complete_the_scan_in_calm_water(calm):
    init = as_.reset(calm, TIER, 1, 4, 3)
    for method in ("oracle", "heuristic"):
        r = rollout(as_, calm, TIER, init, method, "6dof", E.load_vehicle(), 0)
        assert r["success"].all(), method
        assert np.all(r["coverage_fraction"] >= TIER["coverage_threshold"])
        assert np.all(r["T_s"] < TIER["time_limit_s"])
        np.testing.assert_array_equal(r["violations"], 0)
        np.testing.assert_array_equal(r["footprint_loss_frac"], 0.0)
        # terrain following: the mean altitude is the method's commanded altitude
        np.testing.assert_allclose(r["mean_altitude_m"],
                                   pol.method_altitude(TIER["max_altitude_m"]), atol=1.5)


def test_torpedo_does_not_orbit_its_first_waypoint(calm):
    """Regression: a REMUS (turns no tighter than 5 m) that reached its first waypoint only
    within 2 m (waypoint_carrot's transit arrival) could orbit it at ~5 m for ever in calm
    water (with ARRIVE_M = 1: 4 of these 32 oracle episodes); the transit now ends within
    ARRIVE_M, wider than the turning diameter, and every scan completes."""
    assert pol.ARRIVE_M > 2.0 * 5.0
    for seed in (3, 4):
        init = as_.reset(calm, TIER, 1, 16, seed)
        for method in ("oracle", "heuristic"):
            r = rollout(as_, calm, TIER, init, method, "6dof", E.load_vehicle(), 0)
            assert r["success"].all(), (seed, method, np.flatnonzero(~r["success"]))


def _sp(info="sensors"):
    from oneocean.sensing import sensing_params
    return sensing_params(info, 1.0)


def test_both_methods_orient_the_strips_across_a_strong_current():
    # 2 m/s eastward (REMUS v_max = 2.5 m/s) along regions whose long axis runs east: strips
    # with and against it (0.5 m/s upstream) take longer than strips across it (crabbing at
    # 1.5 m/s). One planner for both methods: the oracle on the true current, the heuristic on
    # its forecast (gain, direction and bias errors do not flip a 2 m/s current), so both fly
    # their strips along z (north); the heuristic's strips are longer and its area wider by
    # its navigation margins.
    grid = _sloped(ce=2.0)
    init = as_.reset(grid, TIER, 1, 12, 5)
    keep = np.flatnonzero(init["long_axis"] == 0)[:4]
    assert keep.size == 4
    init = {k: (v[keep] if isinstance(v, np.ndarray) and v.shape[:1] == (12,) else v)
            for k, v in init.items()}
    veh = E.load_vehicle()
    runs = {}
    for method in ("oracle", "heuristic"):
        ep = Episodes(as_, grid, TIER, init, method, "6dof", veh, 0)
        runs[method] = ep
        for e in range(4):
            w = ep.H.wps[e, 0, 1:ep.H.wcount[e, 0]]
            assert np.allclose(w[0::2, 0], w[1::2, 0]), method   # strips along z
    reg = init["region"]
    o, h = runs["oracle"].H, runs["heuristic"].H
    for e in range(4):
        wo = o.wps[e, 0, 1:o.wcount[e, 0]]
        wh = h.wps[e, 0, 1:h.wcount[e, 0]]
        # the oracle's strips span the region exactly; the heuristic's reach past both ends
        np.testing.assert_allclose([wo[:, 1].min(), wo[:, 1].max()], reg[e, [1, 3]])
        assert wh[:, 1].min() < reg[e, 1] - 0.5 and wh[:, 1].max() > reg[e, 3] + 0.5
        assert wh[:, 0].min() < wo[:, 0].min() and wh[:, 0].max() > wo[:, 0].max()
    ro = runs["oracle"].run().results()
    rh = runs["heuristic"].run().results()
    assert ro["success"].all() and rh["success"].all()


def test_scan_axis_orients_strips_across_the_current():
    box = (0.0, 0.0, 200.0, 100.0)
    assert pol.scan_axis(np.array([[1.2, 0.0]]), box, 2.0, 20.0) == 1  # strips along z
    assert pol.scan_axis(np.array([[0.0, 1.2]]), box, 2.0, 20.0) == 0  # strips along x
    # no current: the long axis (fewer strips and cross legs)
    assert pol.scan_axis(np.zeros((1, 2)), box, 2.0, 20.0) == 0
    assert pol.scan_axis(np.zeros((1, 2)), (0.0, 0.0, 100.0, 200.0), 2.0, 20.0) == 1
    # the predicted time: 5 strips of 200 m at 2 m/s and 4 cross legs of 20 m; or 10 of 100 m
    t = pol.scan_times(np.zeros((1, 2)), box, 2.0, 20.0)
    assert t[0] == pytest.approx(5 * 100.0 + 4 * 10.0)
    assert t[1] == pytest.approx(10 * 50.0 + 9 * 10.0)


def _scan_times_python(cur, box, v, spacing, n_agents):
    """scan_times' formula sample by sample in plain Python floats (its reference)."""
    def along(ce, cn, ux, uz):
        c_par = ce * ux + cn * uz
        q2 = ce * ce + cn * cn - c_par * c_par
        return 0.0 if q2 >= v * v else max(0.0, c_par + math.sqrt(v * v - q2))

    x_lo, z_lo, x_hi, z_hi = box
    out = []
    for axis, (L, W) in enumerate(((x_hi - x_lo, z_hi - z_lo), (z_hi - z_lo, x_hi - x_lo))):
        ux, uz = (1.0, 0.0) if axis == 0 else (0.0, 1.0)
        n = max(1, int(math.ceil(W / spacing - 1e-9)), int(n_agents))
        tot = 0.0
        for ce, cn in cur.tolist():
            strips = 0.5 * L * (1.0 / max(along(ce, cn, ux, uz), 1e-3)
                                + 1.0 / max(along(ce, cn, -ux, -uz), 1e-3))
            cross = W / n / max(along(ce, cn, uz, ux), 1e-3)
            tot += n * strips + (n - 1) * cross
        out.append(tot / max(1, len(cur)))
    return out


def test_scan_times_are_the_python_formula_bit_for_bit():
    """The compiled scan times equal the per-sample formula in Python floats, to the bit,
    also where a leg cannot be flown (cross current above the speed: 1e-3 m/s)."""
    rng = np.random.default_rng(11)
    for trial in range(300):
        cur = rng.normal(0.0, [0.2, 1.0, 3.0][trial % 3], (int(rng.integers(1, 25)), 2))
        x0, z0 = rng.normal(0.0, 400.0, 2)
        box = (x0, z0, x0 + rng.uniform(1.0, 900.0), z0 + rng.uniform(1.0, 900.0))
        args = (float(rng.choice([0.5, 1.5, 2.5])), float(rng.uniform(4.0, 60.0)),
                int(rng.integers(1, 7)))
        got = pol.scan_times(cur, box, *args)
        want = _scan_times_python(cur, box, *args)
        assert np.array_equal(np.array(got).view(np.int64), np.array(want).view(np.int64))


def test_navigation_sigma_and_margins_from_the_sensor_table():
    SP = _sp()
    fix, psi, sf, vn = 0.5, math.radians(0.5), 0.003, 0.005   # data/sensors.yaml
    # 1000 m east of the fix: across-track (north) error from the heading bias, along-track
    # (east) from the scale factor; the velocity noise's random walk over t s
    assert pol.nav_sigma(SP, 1000.0, 0.0, 0.0, 1.0, 0.0) == pytest.approx(
        math.hypot(fix, psi * 1000.0))
    assert pol.nav_sigma(SP, 1000.0, 0.0, 1.0, 0.0, 0.0) == pytest.approx(
        math.hypot(fix, sf * 1000.0))
    assert pol.nav_sigma(SP, 0.0, 0.0, 1.0, 0.0, 400.0) == pytest.approx(
        math.sqrt(fix ** 2 + vn ** 2 * 400.0))
    assert pol.nav_sigma(_sp("truth"), 1000.0, 0.0, 0.0, 1.0, 900.0) == 0.0
    assert pol.nav_sigma(_sp("true_current"), 1000.0, 0.0, 0.0, 1.0, 0.0) > 8.0
    # margins of a 1000 x 100 m region, start fix at its south-west corner: the long (north
    # and south) sides' margins are NAV_K sigma of the heading bias over 1000 m, the near
    # (west) side's only the fix and the heading bias over the width
    m = pol.nav_margins(SP, (0.0, 0.0, 1000.0, 100.0), [[0.0, 0.0]], 0.0)
    k = pol.NAV_K
    assert m[1] == pytest.approx(k * math.hypot(fix, psi * 1000.0))            # south
    assert m[3] == pytest.approx(k * math.sqrt(fix ** 2 + (sf * 100.0) ** 2
                                               + (psi * 1000.0) ** 2))         # north
    assert m[0] == pytest.approx(k * math.hypot(fix, psi * 100.0))             # west
    assert m[2] == pytest.approx(k * math.sqrt(fix ** 2 + (sf * 1000.0) ** 2
                                               + (psi * 100.0) ** 2))          # east
    assert 17.0 < m[3] < 18.0 and m[0] < 2.5
    assert pol.nav_margins(_sp("truth"), (0.0, 0.0, 1000.0, 100.0), [[0.0, 0.0]],
                           900.0) == (0.0, 0.0, 0.0, 0.0)
    assert pol.margin_bound(SP, 900.0, [(0.0, 0.0, 1000.0, 100.0)]) >= max(m)
    assert pol.margin_bound(_sp("truth"), 900.0, [(0.0, 0.0, 1000.0, 100.0)]) == 0.0


def _briefs(grid, tier, init):
    """The heuristic's and the oracle's briefings of ``init``."""
    return {m: Episodes(as_, grid, tier, init, m, "kinematic", E.load_vehicle(), 0).B
            for m in ("heuristic", "oracle")}


def test_planner_narrows_its_margin_to_fit_the_time_limit(calm):
    B = _briefs(calm, TIER, as_.reset(calm, TIER, 1, 2, 0))
    M = pol.params("heuristic", B["heuristic"])
    assert M == pol.params("oracle", B["oracle"])   # information only
    box = (300.0, 300.0, 1300.0, 400.0)
    starts = np.array([[310.0, 310.0]])
    SP = _sp()
    full = pol.nav_margins(SP, box, starts, 4000.0)

    def cur(duration):   # still water
        return as_.centre_forecast(calm, box, 0.0, duration, M.alt)[1]

    wps, cnt, t_full = pol.plan_episode(M, box, cur(4000.0), 4000.0, 1, starts, SP)
    w = wps[0, 1:cnt[0]]
    # ample time: the whole NAV_K margin, strips along x (the long axis in still water)
    np.testing.assert_allclose([w[:, 0].min(), w[:, 0].max()],
                               [box[0] - full[0], box[2] + full[2]])
    assert t_full <= 4000.0
    # too little time for any margin: the region itself, as the oracle plans it
    wps0, cnt0, t0_ = pol.plan_episode(M, box, cur(600.0), 600.0, 1, starts, SP)
    wpo, cnto, _ = pol.plan_episode(M, box, cur(600.0), 600.0, 1, starts, _sp("truth"))
    np.testing.assert_array_equal(wps0, wpo)
    np.testing.assert_allclose([wpo[0, 1:, 0].min(), wpo[0, 1:, 0].max()], [box[0], box[2]])
    # in between: a narrower margin whose predicted scan fits
    lim = 0.5 * (t_full + t0_) / (1.0 - pol.TIME_RESERVE)
    wpm, cntm, t_mid = pol.plan_episode(M, box, cur(lim), lim, 1, starts, SP)
    assert t_mid <= (1.0 - pol.TIME_RESERVE) * lim
    assert box[0] - full[0] < wpm[0, 1:cntm[0], 0].min() < box[0]


def test_dead_reckoning_drift_opens_holidays_the_margins_close(monkeypatch):
    """A long narrow survey in still water: the oracle (true position) covers the region;
    the heuristic flying the same plan without margins (NAV_K = 0) on its dead-reckoned
    position leaves holidays at the far edges in some episodes; with its margins it covers
    the region as the oracle does, in more time."""
    grid = _sloped(nx=31, ny=31)
    tier = {**TIER, "region_long_m": 1000.0, "region_short_m": 96.0, "time_limit_s": 5000.0,
            "coverage_threshold": 1.0}
    init = as_.reset(grid, tier, 1, 8, 2)
    veh = E.load_vehicle()
    ro = rollout(as_, grid, tier, init, "oracle", "kinematic", veh, 0)
    rh = rollout(as_, grid, tier, init, "heuristic", "kinematic", veh, 0)
    monkeypatch.setattr(pol, "NAV_K", 0.0)
    r0 = rollout(as_, grid, tier, init, "heuristic", "kinematic", veh, 0)
    assert ro["coverage_fraction"].min() >= 0.999
    assert rh["coverage_fraction"].min() >= 0.999
    assert r0["coverage_fraction"].min() < 0.99          # drift: holidays
    assert np.mean(rh["T_s"]) > np.mean(ro["T_s"])       # the margins cost time


def test_plan_splits_strips_between_agents():
    wps, cnt = pol.plan_lawnmower((0.0, 0.0, 200.0, 100.0), 0, 20.0, 2)
    assert list(cnt) == [6, 4]  # 5 strips: 3 + 2, two waypoints per strip
    offs = sorted({round(w[1], 6) for i in range(2) for w in wps[i, :cnt[i]]})
    np.testing.assert_allclose(offs, [10.0, 30.0, 50.0, 70.0, 90.0])
    np.testing.assert_allclose(wps[0, :2, 0], [0.0, 200.0])  # boustrophedon
    np.testing.assert_allclose(wps[0, 2:4, 0], [200.0, 0.0])
    # more agents than strips of the nominal spacing: narrower strips, one per agent
    wps, cnt = pol.plan_lawnmower((0.0, 0.0, 200.0, 100.0), 0, 60.0, 4)  # 2 nominal strips
    assert list(cnt) == [2, 2, 2, 2]
    np.testing.assert_allclose(wps[:, 0, 1], [12.5, 37.5, 62.5, 87.5])  # z offsets
    np.testing.assert_allclose(wps[:, :2, 0], [[0.0, 200.0]] * 4)  # along x, same end


def test_team_blocks_overlap_by_the_seam():
    # 2 agents, 100 m wide, 20 m spacing, a 10 m seam: the width unrolls to 110 m, 6 strips
    # at (k + 1/2) 110 / 6, the second agent's block shifted back by 10 m
    wps, cnt = pol.plan_lawnmower((0.0, 0.0, 200.0, 100.0), 0, 20.0, 2, seam=10.0)
    assert list(cnt) == [6, 6]
    u = (np.arange(6) + 0.5) * 110.0 / 6
    np.testing.assert_allclose(wps[0, 0:6:2, 1], u[:3])
    np.testing.assert_allclose(wps[1, 0:6:2, 1], u[3:] - 10.0)
    assert wps[1, 0, 1] - wps[0, 4, 1] == pytest.approx(110.0 / 6 - 10.0)
    assert wps[1, 4, 1] == pytest.approx(100.0 - 110.0 / 12)   # symmetric at the far edge
    # the seam of two dead-reckoning vehicles: sqrt(2) NAV_K sigma across the strips at the
    # far corner; none for one vehicle or given the true position
    box = (0.0, 0.0, 1000.0, 100.0)
    two = [[0.0, 0.0], [5.0, 0.0]]
    sig = pol.nav_sigma(_sp(), 1000.0, 100.0, 0.0, 1.0, 0.0)
    assert pol.team_seam(_sp(), box, two, 0.0, 0) == pytest.approx(
        pol.NAV_K * math.sqrt(2.0) * sig)
    assert pol.team_seam(_sp(), box, two[:1], 0.0, 0) == 0.0
    assert pol.team_seam(_sp("truth"), box, two, 0.0, 0) == 0.0


def test_team_scans_faster_and_coll_ratio(calm):
    init1 = as_.reset(calm, TIER, 1, 3, 4)
    init3 = as_.reset(calm, TIER, 3, 3, 4)
    r1 = rollout(as_, calm, TIER, init1, "oracle", "kinematic", E.load_vehicle(), 0)
    r3 = rollout(as_, calm, TIER, init3, "oracle", "kinematic", E.load_vehicle(), 0)
    assert r1["success"].all() and r3["success"].all()
    assert np.all(r3["T_s"] < r1["T_s"])
    np.testing.assert_array_equal(r1["coll_ratio"], 0.0)
    assert np.all((r3["coll_ratio"] >= 0.0) & (r3["coll_ratio"] <= 1.0))
    # two vehicles that cannot move, 1.5 m apart: near-collision at every step
    init = {**init3, "pos0": init3["pos0"][:, :2].copy(), "psi0": init3["psi0"][:, :2].copy()}
    init["pos0"][:, 1] = init["pos0"][:, 0] + np.array([1.5, 0.0, 0.0])
    r = rollout(as_, calm, {**TIER, "time_limit_s": 20.0}, init, "oracle", "kinematic",
                _still(), 0)
    np.testing.assert_array_equal(r["coll_ratio"], 1.0)


def test_run_cell_deterministic_and_thread_independent(coast):
    a = run_cell(coast, "AS", 2, "heuristic", episodes=3, seed=7, n_agents=2)
    b = run_cell(coast, "AS", 2, "heuristic", episodes=3, seed=7, n_agents=2)
    pd.testing.assert_frame_equal(a, b)
    for k in STANDARD + ("primary",) + as_.METRICS:
        assert k in a.columns
    np.testing.assert_array_equal(a["primary"], a["coverage_fraction"])
    c = run_cell(coast, "AS", 2, "heuristic", episodes=3, seed=8, n_agents=2)
    assert not np.array_equal(a["coverage_fraction"].to_numpy(),
                              c["coverage_fraction"].to_numpy())
    if numba.config.NUMBA_NUM_THREADS >= 2:
        d = on_one_thread(run_cell, coast, "AS", 2, "heuristic", episodes=3, seed=7, n_agents=2)
        pd.testing.assert_frame_equal(a, d)


def test_tier_table_monotone_and_declared():
    table = load_task_table("AS")
    tiers = table["tiers"]
    assert_tier_table_monotone(table)
    varied = [k for k in table["harder"] if len({repr(tiers[t][k]) for t in (1, 2, 3)}) > 1]
    assert len(varied) >= 5  # several stressors, never a single knob
    for t in (1, 2, 3):
        assert set(tiers[t]) == set(table["harder"]) == set(as_._TIER_KEYS)
    assert table["agents"] == {"default": 1, "range": [1, 10]}
    assert math.isclose(table["dt_s"], 1.0)
