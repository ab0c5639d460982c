"""PI (pipeline inspection / leak detection): geometry, plume sensing, the public view
(briefing, the mission computer's cue and ``section_done``, the report), estimators, success
rule, metrics, determinism and the tier table."""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.engine import grid as G
from oneocean.engine import status as st
from oneocean.engine.dynamics import P_RTURN, P_VMAX
from oneocean.errors import ConfigError
from oneocean.methods.heuristic import pi as pi_policy
from oneocean.models import pollution as pol
from oneocean.tasks import pi, run_cell
from oneocean.tasks import public
from oneocean.tasks.common import (OBS_DIM, O_CE, O_CN, O_DEPTH, O_GX, O_GY, O_GZ, O_PROBE, O_X,
                                   O_Z, STANDARD)
from oneocean.tasks.tiers import load_task_table
from oneocean.tasks.episodes import Episodes, rollout
from oneocean.tasks.loop import Ctx, EnvCtx
from oneocean.testing import make_test_grid, uniform_grid
from task_helpers import assert_tier_table_monotone, on_one_thread

TIER = {"current_band": [0.0, 1.0], "time_limit_s": 900.0, "pipeline_length_m": 800.0, "n_leaks": 2, "leak_spacing_m": 200.0,
        "leak_rate_kg_s": 0.01, "detect_threshold_kg_m3": 4e-6, "loc_tolerance_m": 15.0,
        "seafloor_min_m": 30.0, "seafloor_max_m": 150.0, "dt_s": 1.0}


def _sloped(ce=0.0, cn=0.0, nx=21, ny=21, dx=100.0):
    """Land-free grid, uniform current, seafloor deepening eastward 40 -> 80 m."""
    g = uniform_grid(ce, cn, depth_m=80.0, nx=nx, ny=ny, dx_m=dx)
    x = np.arange(nx) / (nx - 1)
    g["elevation"] = np.tile(-(40.0 + 40.0 * x), (ny, 1)).astype(np.float32)
    return E.load_grid(g)


@pytest.fixture(scope="module")
def calm():
    return _sloped()


def _still():
    veh = E.load_vehicle()
    p = veh.params.copy()
    p[P_VMAX] = 0.0
    return dataclasses.replace(veh, params=p)


def _view(grid, n_agents=1):
    """A batch of the straight-pipeline episode under the heuristic (nothing run): its public
    view (briefing ``B``, memory ``H``, the report ``C.R``) and the task's ``P`` / ``W``."""
    return Episodes(pi, grid, TIER, _straight_init(grid, n_agents=n_agents), "heuristic",
                    "6dof", E.load_vehicle(), 0)


def _valid(claims):
    """The claims of a report row block (rows with a finite position)."""
    return claims[np.isfinite(claims[:, 0]) & np.isfinite(claims[:, 1])]


def _straight_init(grid, x0=-450.0, x1=450.0, z=0.0, leaks=(-150.0, 150.0), n_agents=1,
                   rate=0.01):
    """A hand-made episode: a straight west-east pipeline, leaks at the given x."""
    poly = np.array([[[x0, z], [0.5 * (x0 + x1), z], [x1, z]]])
    L = x1 - x0
    cuts = np.linspace(0.0, L, n_agents + 1)
    pos0 = np.zeros((1, n_agents, 3))
    for i in range(n_agents):
        x = x0 + cuts[i]
        pos0[0, i] = (x, -E.sample_elevation(grid, x, z) - 10.0, z)
    nl = len(leaks)
    return {"poly": poly, "leaks": np.array([[[x, z] for x in leaks]]),
            "leak_rate": np.full((1, nl), rate), "pos0": pos0, "psi0": np.zeros((1, n_agents)),
            "t0": np.zeros(1), "sections": np.stack([cuts[:-1], cuts[1:]], axis=1)[None]}


def _run(grid, tier, init, method, vehicle, seed=0, info=None):
    """Results and the finished batch (the task's work arrays ``W``: field, mission computer,
    report; the method's memory ``H``)."""
    ep = Episodes(pi, grid, tier, init, method, "6dof", vehicle, seed, info=info).run()
    return ep.results(), ep


def test_reset_geometry_is_valid(coast):
    init = pi.reset(coast, TIER, 2, 6, seed=4)
    poly, leaks = init["poly"], init["leaks"]
    assert leaks.shape == (6, 2, 2) and init["pos0"].shape == (6, 2, 3)
    for e in range(6):
        L = pi._arc(poly[e])[-1]
        assert L == pytest.approx(TIER["pipeline_length_m"])
        pts = pi._densify(poly[e], 10.0)
        depth = -np.array([E.sample_elevation(coast, x, z) for x, z in pts])
        land = np.array([E.sample_land(coast, x, z) for x, z in pts])
        assert depth.min() >= TIER["seafloor_min_m"] and depth.max() <= TIER["seafloor_max_m"]
        assert land.max() == 0.0
        # turns bounded
        d = np.diff(poly[e], axis=0)
        hd = np.arctan2(d[:, 0], d[:, 1])
        turn = np.abs((np.diff(hd) + np.pi) % (2 * np.pi) - np.pi)
        assert np.all(turn <= math.radians(pi.MAX_TURN_DEG) + 1e-9)
        # leaks lie on the pipeline, apart, inside the arc window
        s_leak = []
        for q in range(2):
            dist = np.min(np.linalg.norm(pts - leaks[e, q], axis=1))
            assert dist < 5.0
            k = np.argmin(np.linalg.norm(pts - leaks[e, q], axis=1))
            s_leak.append(pi._arc(pts)[k])
        assert abs(s_leak[1] - s_leak[0]) >= TIER["leak_spacing_m"] - 10.0
        assert min(s_leak) >= pi.LEAK_ARC_FRAC * L - 10.0
        assert max(s_leak) <= (1 - pi.LEAK_ARC_FRAC) * L + 10.0
        np.testing.assert_allclose(init["sections"][e], [[0.0, L / 2], [L / 2, L]])
        for i in range(2):
            start = pi.point_at(poly[e], init["sections"][e, i, 0])
            assert np.all(np.abs(init["pos0"][e, i, [0, 2]] - start) <= 0.5 * pi.SPAWN_BOX_M)
    assert np.all(init["leak_rate"] >= 0.5 * TIER["leak_rate_kg_s"])
    assert np.all(init["leak_rate"] <= TIER["leak_rate_kg_s"])
    codes = E.feasibility(coast, init["pos0"].reshape(-1, 3), 0.5, pi.CLEARANCE_M)
    assert np.all(codes == st.OK)


def test_field_frame_and_land_mask(coast):
    poly = np.array([[-2500.0, 0.0], [-2000.0, 300.0], [-1500.0, 0.0]])
    o, ax_, s0, n0, nx, nz = pi.field_frame(poly, 20.0, 80.0)
    np.testing.assert_allclose(ax_, [1.0, 0.0])
    assert nx * 20.0 >= 1000.0 + 160.0 and nz * 20.0 >= 300.0 + 160.0
    frame = np.array([o[0], o[1], ax_[0], ax_[1], s0, n0])
    land = pi._field_land(coast, frame, nx, nz, 20.0)
    xs = o[0] + s0 + 20.0 * np.arange(nx)
    zs = o[1] + n0 + 20.0 * np.arange(nz)
    want = np.array([[E.sample_land(coast, x, z) >= 0.5 for x in xs] for z in zs])
    np.testing.assert_array_equal(land.astype(bool), want)
    assert 0 < land.sum() < land.size  # the test grid's coast crosses this field


def test_reset_raises_when_impossible(calm):
    with pytest.raises(ConfigError, match="PI"):  # 5 km pipeline on a 2 km grid
        pi.reset(calm, {**TIER, "pipeline_length_m": 5000.0}, 1, 2, 0)
    with pytest.raises(ConfigError, match="PI"):  # seafloor 40-80 m
        pi.reset(calm, {**TIER, "seafloor_max_m": 35.0}, 1, 2, 0)
    with pytest.raises(ConfigError, match="leaks"):  # 5 leaks 300 m apart on 800 m
        pi.reset(calm, {**TIER, "n_leaks": 5, "leak_spacing_m": 300.0}, 1, 2, 0)
    with pytest.raises(ConfigError, match="n_agents"):
        pi.reset(calm, TIER, 11, 2, 0)
    with pytest.raises(ConfigError, match="missing"):
        pi.reset(calm, {k: v for k, v in TIER.items() if k != "n_leaks"}, 1, 2, 0)


@numba.njit
def _estimates(reads, n, b, peak):
    buf = reads[0, 0]
    return (np.array(pi_policy.peak_estimate(buf, n)),
            np.array(pi_policy.onset_estimate(buf, n, b, peak)))


def test_estimators_on_a_hand_made_along_current_plume():
    # readings every 2 m along x through a plume advected +x (downstream = +x) from a source
    # at x = 0: background 3 (an upstream leak's plume), an upstream edge smeared over one
    # 20 m cell, the peak 30 m downstream (accumulation), a slow decay after
    x = np.arange(-50.0, 51.0, 2.0)
    s = np.interp(x, [-20.0, 0.0, 30.0], [0.0, 0.64, 1.0], left=0.0, right=np.nan)
    s = np.where(np.isnan(s), np.exp(-(x - 30.0) / 200.0), s)
    r = 3.0 + 10.0 * s
    reads = np.zeros((1, 1, x.size, 4))
    reads[0, 0, :, 0] = x
    reads[0, 0, :, 2] = r
    reads[0, 0, :, 3] = x - x[0]  # downstream coordinate
    peak, onset = _estimates(reads, x.size, r.min(), r.max())
    assert peak[0] == pytest.approx(30.0)  # the peak sits downstream of the source
    assert abs(onset[0]) < 5.0  # the upstream edge is at the source
    # a cross-current plume (downstream coordinate constant): the onset estimator is the
    # weighted centre of the peak
    reads[0, 0, :, 3] = 0.0
    reads[0, 0, :, 2] = np.exp(-0.5 * ((x - 6.0) / 8.0) ** 2)
    r = reads[0, 0, :, 2]
    peak, onset = _estimates(reads, x.size, r.min(), r.max())
    assert peak[0] == pytest.approx(6.0) and onset[0] == pytest.approx(6.0, abs=0.5)


def test_match_claims_hand_cases():
    """The metric on hand-made reports: one-to-one matching within the gate, localisation
    within the tolerance, every unmatched claim a false claim."""
    leaks = [[0.0, 0.0], [300.0, 0.0]]
    sc = lambda c: pi.score_claims(c, leaks, tol=15.0)  # noqa: E731
    # perfect report
    r = sc([[3.0, 4.0], [300.0, -6.0]])
    assert r["success"] and r["inspection_score"] == 1.0 and r["detection_rate"] == 1.0
    assert r["false_claims"] == 0 and r["localisation_error_m"] == pytest.approx(5.5)
    # the same truth, one claim moved 20 m off (> 15 m tolerance, < 50 m gate): detected,
    # not localised
    r = sc([[3.0, 4.0], [300.0, 20.0]])
    assert not r["success"] and r["detected"] == 2 and r["localised"] == 1
    assert r["inspection_score"] == 0.5 and r["localisation_error_m"] == pytest.approx(12.5)
    # moved 60 m off (> the 50 m gate): a false claim, the leak missed
    r = sc([[3.0, 4.0], [300.0, 60.0]])
    assert r["detected"] == 1 and r["false_claims"] == 1
    assert r["inspection_score"] == pytest.approx(1.0 / 3.0)
    assert r["localisation_error_m"] == pytest.approx(5.0)
    # a claim far from every leak is a false claim (the two true ones still localised)
    r = sc([[3.0, 4.0], [300.0, -6.0], [150.0, 0.0]])
    assert r["false_claims"] == 1 and r["localised"] == 2 and not r["success"]
    assert r["inspection_score"] == pytest.approx(2.0 / 3.0)
    # two claims on one leak: one-to-one, the closer one matches, the other is false
    r = sc([[10.0, 0.0], [2.0, 0.0], [300.0, 0.0]])
    assert r["localisation_error_m"] == pytest.approx(1.0)   # (2 + 0) / 2
    assert r["false_claims"] == 1 and r["detected"] == 2
    # claiming everywhere does not pay: a claim every 10 m along 0..300 m
    r = sc([[x, 0.0] for x in np.arange(0.0, 301.0, 10.0)])
    assert r["localised"] == 2 and r["false_claims"] == 29
    assert r["inspection_score"] == pytest.approx(2.0 / 31.0)
    # no claims (non-finite ones are ignored)
    r = sc([[np.nan, np.nan]])
    assert r["detected"] == 0 and r["false_claims"] == 0 and r["inspection_score"] == 0.0
    assert math.isnan(r["localisation_error_m"])
    r = sc(np.zeros((0, 2)))
    assert r["inspection_score"] == 0.0 and not r["success"]


@numba.njit
def _feed(H, R, xs, rs, fe, thr, estimator):
    for m in range(xs.size):
        pi_policy.detect(H, R, 0, 0, xs[m], 0.0, rs[m], fe, 0.0, thr, estimator)


def test_event_detector_on_a_hand_made_series(calm):
    """Readings along x (a current along +x, so downstream = +x): two plumes carried along
    the pipe, the second on top of the first's decaying tail, make two events and two claims
    (peak estimator: the plume peaks, 30 m downstream; onset estimator: the sources). Small
    wiggles under the detection threshold make none."""
    thr = 1.0
    x = np.arange(-100.0, 500.0, 2.0)

    def plume(x0):
        s = np.interp(x, [x0 - 20.0, x0, x0 + 30.0], [0.0, 6.4, 10.0], left=0.0, right=np.nan)
        return np.where(np.isnan(s), 10.0 * np.exp(-(x - x0 - 30.0) / 200.0), s)

    r = plume(0.0) + plume(250.0)
    for est, want in ((pi_policy.PEAK, (30.0, 280.0)), (pi_policy.ONSET, (0.0, 250.0))):
        ep = _view(calm)
        H, R = ep.H, ep.C.R
        _feed(H, R, x, r, 0.5, thr, est)
        n = H.nclaim[0]
        assert n == 2, est
        np.testing.assert_allclose(R[0, :n, 0], want, atol=6.0)
        np.testing.assert_allclose(R[0, :n, 1], 0.0)
        assert np.all(np.isnan(R[0, n:]))        # the report is compact
    ep = _view(calm)
    _feed(ep.H, ep.C.R, x, 0.4 + 0.3 * np.sin(x / 7.0), 0.5, thr, pi_policy.PEAK)
    assert ep.H.nclaim[0] == 0 and np.all(np.isnan(ep.C.R))


def test_readings_are_placed_where_the_method_believes_it_is(calm):
    """The sensor reads at the vehicle's true position, but the method is handed the value
    only (the observation's probe, kg m-3): the event it opens, and the claim it files, sit
    at its navigation estimate (the observation's position, never the truth); the
    observation's probe (``cue``) is the latest reading (``W.sense``), whatever state the cue
    is given."""
    ep = _view(calm)
    P, W, B, M, H, R = ep.P, ep.W, ep.B, ep.M, ep.H, ep.C.R
    assert W.sense.shape == (1, 1)
    H.widx[0, 0] = 1
    O = np.full((1, 1, ep.obs_dim), np.nan)
    C = Ctx(B, O, (), M, H, R)

    def believed(x, z, reading):
        O[0, 0, O_X], O[0, 0, O_Z] = x, z
        O[0, 0, O_DEPTH] = -E.sample_elevation(calm, x, z) - M.alt
        O[0, 0, O_CE:O_CN + 1] = 0.0
        O[0, 0, O_PROBE] = reading

    believed(-120.0, 3.0, 0.0)                 # background: the trough
    pi_policy.act(C, 0, 4, 0)
    assert H.ev_on[0, 0] == 0 and H.nclaim[0] == 0
    believed(-118.0, 7.0, 10.0 * B.thr)        # a plume
    pi_policy.act(C, 0, 5, 0)
    assert H.ev_on[0, 0] == 1 and H.nclaim[0] == 1
    assert tuple(H.ev_pos[0, 0, :2]) == (-118.0, 7.0)
    assert tuple(R[0, 0, :2]) == (-118.0, 7.0)
    assert R is W.claims                       # the report the judge reads
    W.sense[0, 0] = 10.0 * P.thr
    for x in (-118.0, 300.0):
        s = np.zeros((1, 1, E.STATE_DIM))
        s[0, 0, 0] = x
        ctx = EnvCtx(calm, P, W, s, s, np.zeros((1, 1, OBS_DIM)), s[..., :3].copy(),
                     np.zeros((1, 1), np.int64), np.zeros((1, 1)), np.zeros(1), 1.0)
        assert pi.cue(ctx, 0, 5, 0)[3] == 10.0 * P.thr


def test_briefing_is_the_mission_and_the_plan_is_the_methods(calm):
    """The briefing: the common fields in order, then the task's own (the pipeline chart,
    the sections, the mission computer's routes, the sensor's and the scoring's constants);
    every E-leading array a copy. The heuristic's survey plan (its memory) is built from the
    chart and the sections: with its overlap the task's route."""
    ep = _view(calm, n_agents=2)
    B, init = ep.B, _straight_init(calm, n_agents=2)
    assert B._fields == tuple(public.COMMON) + tuple(pi.BRIEF_FIELDS)
    np.testing.assert_array_equal(B.pipeline, init["poly"])
    np.testing.assert_array_equal(B.sections, init["sections"])
    assert B.thr == TIER["detect_threshold_kg_m3"] and B.loc_tol == TIER["loc_tolerance_m"]
    assert B.gate == pi.DETECT_GATE_M and B.max_claims == pi.MAX_CLAIMS
    assert B.cue_alt == pi.CUE_ALT_M and B.plume_scale == pi.PLUME_SCALE_M
    assert not np.shares_memory(B.route, ep.W.route)
    # agent 0 from the pipeline's start, agent 1 from ROUTE_OVERLAP_M before its section
    # (x = 0 on the straight west-east pipeline), both to their section's end
    assert list(B.route_n[0]) == [2, 3]
    np.testing.assert_allclose(B.route[0, 0], [[-450.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    np.testing.assert_allclose(B.route[0, 1], [[-pi.ROUTE_OVERLAP_M, 0.0], [0.0, 0.0],
                                               [450.0, 0.0]])
    assert pi_policy.OVERLAP_M == B.route_overlap
    np.testing.assert_array_equal(ep.H.wps, B.route)
    np.testing.assert_array_equal(ep.H.wcount, B.route_n)
    sub = public.briefing_rows(B, [0])
    assert sub.route.shape == B.route.shape and sub.thr == B.thr


def test_cue_is_the_mission_computers_carrot_and_section_done(calm):
    """The task's own cue (every method): the carrot along the agent's route at the
    inspection altitude over the charted seafloor, from a pointer the task advances on the
    navigation estimate; ``section_done`` turns 1 past the route's end and the report is
    final (the episode ends) once every agent's is. The fused heuristic flies the same
    carrot. A policy that only follows the cue inspects its section: it ends the episode
    before the time limit, its report (here the true leaks, written in place) scored."""
    init = _straight_init(calm, n_agents=2)
    veh = E.load_vehicle()
    ep = Episodes(pi, calm, TIER, init, "heuristic", "6dof", veh, 0, record=True).run()
    r = ep.results()
    k_end = int(ep.k[0])
    assert r["success"][0] and k_end < ep.n_steps
    obs = ep.obs[0, :k_end]
    done = obs[:, :, OBS_DIM]
    assert pi.OBS_EXTRA == ("section_done",)
    assert set(np.unique(done)) == {0.0, 1.0}
    assert np.all(np.diff(done, axis=0) >= 0)            # latched
    assert np.all(done[-1] == 1.0) and not np.all(done[-2] == 1.0)
    gx = obs[:, :, O_GX] + obs[:, :, O_X]
    gy = obs[:, :, O_GY] + obs[:, :, O_DEPTH]
    gz = obs[:, :, O_GZ] + obs[:, :, O_Z]
    # on the pipeline (z = 0), at the inspection altitude over the charted seafloor
    np.testing.assert_allclose(gz, 0.0, atol=1e-9)
    floor = -np.array([[E.sample_elevation(calm, x, 0.0) for x in row] for row in gx])
    np.testing.assert_allclose(gy, floor - pi.CUE_ALT_M, atol=1e-6)
    # the heuristic's last carrot is the task's last cue (holding at the section's end)
    np.testing.assert_array_equal(ep.H.tgt[0], ep.W.tgt[0])
    np.testing.assert_allclose(gx[-1], [0.0, 450.0], atol=1e-6)
    # a cue follower (no method of its own: seek the cue at v_max)
    ext = Episodes(pi, calm, TIER, init, None, "6dof", veh, 0)
    O = ext.observe()
    ext.C.R[0, :2, :2] = init["leaks"][0]
    while not ext.done.all():
        d = O[:, :, O_GX:O_GZ + 1]
        n = np.linalg.norm(d, axis=2, keepdims=True)
        ext.set_actions(veh.v_max * d / np.maximum(n, 1e-9))
        O = ext.step_observe().copy()
    rf = ext.results()
    assert ext.k[0] < ext.n_steps and np.all(O[0, :, OBS_DIM] == 1.0)
    assert rf["success"][0] and rf["T_s"][0] < TIER["time_limit_s"]


def test_the_payloads_event_log_and_the_reference_report(calm):
    """The team observation logs every run of readings at or above the threshold at its
    peak (for every method); a policy that follows the cue and copies the log into its report
    (the task's reference rule, which behaviour cloning files by) localises every leak."""
    init = _straight_init(calm, n_agents=1)
    veh = E.load_vehicle()
    ext = Episodes(pi, calm, TIER, init, None, "6dof", veh, 0, record=True)
    O = ext.observe()
    assert ext.C.T._fields == tuple(pi.TEAM_FIELDS) and ext.C.T.n_events[0] == 0
    assert np.isnan(ext.C.T.events).all()
    k = 0
    while not ext.done.all():
        d = O[:, :, O_GX:O_GZ + 1]
        n = np.linalg.norm(d, axis=2, keepdims=True)
        ext.set_actions(veh.v_max * d / np.maximum(n, 1e-9))
        pi.reference_report.py_func(ext.C, 0, k)
        O = ext.step_observe().copy()
        k += 1
    r = ext.results()
    n_ev = int(ext.C.T.n_events[0])
    events = ext.C.T.events[0, :n_ev]
    assert n_ev >= 2 and np.isnan(ext.C.T.events[0, n_ev:]).all()
    assert (events[:, 2] >= TIER["detect_threshold_kg_m3"]).all()      # the runs' peaks
    # every event's peak is a recorded reading, where the vehicle knew it was then
    probe = ext.obs[0, :, 0, O_PROBE]
    for x, z, peak in events:
        j = np.flatnonzero(probe == peak)
        assert j.size and np.isclose(ext.obs[0, j[0], 0, O_X], x)
    np.testing.assert_array_equal(ext.C.R[0, :n_ev], events)
    assert r["success"][0] and r["detection_rate"][0] == 1.0


def test_calm_water_both_methods_localise_every_leak(calm):
    init = _straight_init(calm)
    for method in ("oracle", "heuristic"):
        r, ep = _run(calm, TIER, init, method, E.load_vehicle())
        assert r["success"][0], method
        assert r["inspection_score"][0] == 1.0 and r["detection_rate"][0] == 1.0
        assert r["localisation_error_m"][0] < 10.0
        assert r["violations"][0] == 0
        # T = the time the section was finished (< the time limit): ~900 m of pipeline at
        # most at v_max (both methods have the full speed budget)
        assert 900.0 / E.load_vehicle().v_max < r["T_s"][0] < TIER["time_limit_s"]
        # the field only holds emitted tracer (no mass is created)
        emitted = init["leak_rate"].sum() * (pi.SPINUP_S + r["T_s"][0] + 3.0)
        assert 0.0 < pol.total_mass(ep.W.C[0], pi.FIELD_H_M) <= emitted * (1 + 1e-9)


def test_torpedo_start_off_the_section_start_still_surveys(calm):
    """A torpedo AUV (turn radius >= 5 m) starting beside the section start, heading away
    from the pipeline, cannot close on the start point within a few metres (it would orbit
    it for ever); the transit ends within ARRIVE_M and the survey runs."""
    veh = E.load_vehicle()
    for dz, psi in ((6.0, 0.0), (-7.0, 0.0), (4.0, math.pi)):
        init = _straight_init(calm)
        init["pos0"][0, 0, 2] += dz
        init["psi0"][0, 0] = psi
        r, ep = _run(calm, TIER, init, "oracle", veh)
        assert r["success"][0], (dz, psi)
        assert ep.W.done[0, 0] == 1 and ep.H.done[0, 0] == 1 and r["T_s"][0] < 600.0
    assert pi_policy.ARRIVE_M > 2.0 * veh.params[P_RTURN]   # beyond the turning circle


@numba.njit
def _end_section(H, R, x, z):
    pi_policy.close_event(H, R, 0, 0, x, z, True)


def test_event_reopened_on_the_tail_of_a_plume_keeps_its_own_claim(calm):
    """An event that opens on the decaying tail of the previous leak's plume, within MERGE_M
    of its claim, and climbs to a second leak further on files its own claim (the merge is
    decided on the event's final estimate); an event re-opened on the same plume merges into
    the first one's claim and the report stays compact."""
    thr = 1.0
    x = np.arange(-100.0, 500.0, 2.0)
    # leak at 0: peak 25 at 0, decays to a trough of 3 at 40 m; then a slow rise to a
    # second leak's peak 20 at 220 m (the event opens ~42 m from the first claim)
    r = np.interp(x, [-40.0, 0.0, 40.0, 220.0, 260.0, 500.0], [0.0, 25.0, 3.0, 20.0, 0.0, 0.0])
    ep = _view(calm)
    H, R = ep.H, ep.C.R
    _feed(H, R, x, r, 0.0, thr, pi_policy.PEAK)
    n = H.nclaim[0]
    assert n == 2
    np.testing.assert_allclose(np.sort(R[0, :n, 0]), [0.0, 220.0], atol=3.0)
    # one plume seen as two events (a dip in the readings): one claim, at the stronger peak
    r = np.interp(x, [-40.0, 0.0, 10.0, 20.0, 30.0, 70.0], [0.0, 12.0, 5.0, 14.0, 0.0, 0.0])
    ep = _view(calm)
    H, R = ep.H, ep.C.R
    _feed(H, R, x, r, 0.0, thr, pi_policy.PEAK)
    assert H.nclaim[0] == 1
    assert R[0, 0, 0] == pytest.approx(20.0, abs=2.0)
    assert np.all(np.isnan(R[0, 1:]))
    # a plume still rising where the section ends: its source lies beyond (a teammate's
    # section); the claim is withdrawn, a complete event's is kept
    for x_end, want in ((50.0, 0), (160.0, 1)):
        xs = x[x <= x_end]
        r = np.interp(xs, [-100.0, 0.0, 60.0, 120.0], [0.0, 0.0, 10.0, 0.0])
        ep = _view(calm)
        H, R = ep.H, ep.C.R
        _feed(H, R, xs, r, 0.0, thr, pi_policy.ONSET)
        if H.ev_on[0, 0]:
            _end_section(H, R, xs[-1], 0.0)
        assert H.nclaim[0] == want and len(_valid(R[0])) == want, x_end


def test_failure_modes_do_nothing_and_high_threshold(calm):
    init = _straight_init(calm)
    r = rollout(pi, calm, TIER, init, "oracle", "6dof", _still(), 0)
    assert not r["success"][0]
    assert r["T_s"][0] == TIER["time_limit_s"]  # T on failure = the time limit
    assert r["E"][0] == 0.0 and r["inspection_score"][0] == 0.0
    assert math.isnan(r["localisation_error_m"][0])  # nothing detected
    r = rollout(pi, calm, {**TIER, "detect_threshold_kg_m3": 1.0}, init, "oracle", "6dof",
                E.load_vehicle(), 0)
    assert not r["success"][0] and r["detection_rate"][0] == 0.0
    assert r["T_s"][0] == TIER["time_limit_s"]


def test_along_pipe_current_biases_the_peak_not_the_onset(monkeypatch):
    grid = _sloped(ce=0.6)  # plumes run east along the pipeline
    init = _straight_init(grid)
    tier = {**TIER, "loc_tolerance_m": 12.0}
    ro, _ = _run(grid, tier, init, "oracle", E.load_vehicle())
    # given the truth, the heuristic is the oracle (onset estimator, same altitude)
    rt, _ = _run(grid, tier, init, "heuristic", E.load_vehicle(), info="truth")
    for k in pi.METRICS:
        np.testing.assert_array_equal(rt[k], ro[k], err_msg=k)
    # the same method claiming each event's peak instead of its onset
    peak = Episodes(pi, grid, tier, init, "oracle", "6dof", E.load_vehicle(), 0).M._replace(
        estimator=pi_policy.PEAK)
    monkeypatch.setattr(pi_policy, "params", lambda method, B: peak)
    rh, eh = _run(grid, tier, init, "oracle", E.load_vehicle())
    assert ro["success"][0] and ro["localisation_error_m"][0] < 12.0
    assert rh["detection_rate"][0] == 1.0 and rh["false_claims"][0] == 0
    # the peak claims lie east (downstream) of the leaks
    claims = _valid(eh.C.R[0])[:, :2]
    assert claims.shape == (2, 2) and eh.H.nclaim[0] == 2
    for leak in init["leaks"][0]:
        c = claims[np.argmin(np.linalg.norm(claims - leak, axis=1))]
        assert c[0] > leak[0] + 5.0
    assert rh["localisation_error_m"][0] > ro["localisation_error_m"][0]


def test_score_comes_from_the_claims_through_the_loop(calm):
    """Through the real loop: the score is the method's claims matched to the truth. The
    fused method's claims do not depend on the true leak positions (moving them in ``W``
    after the plumes were made leaves the claims bit-identical: only the score changes), and
    a report written from Python (an outside method, into the batch's report ``C.R``) is
    scored as filed."""
    init = _straight_init(calm)
    veh = E.load_vehicle()
    a = Episodes(pi, calm, TIER, init, "heuristic", "6dof", veh, 0).run()
    ra = a.results()
    n = a.H.nclaim[0]
    claims = a.C.R[0, :n, :2].copy()
    assert np.all(np.isnan(a.C.R[0, n:]))
    assert ra["success"][0] and n == 2
    want = pi.score_claims(claims, init["leaks"][0], TIER["loc_tolerance_m"])
    for k in pi.METRICS:
        np.testing.assert_allclose(ra[k][0], want[k])
    # the truth the score sees moved 1 km (the field, made from leak_loc, is unchanged)
    b = Episodes(pi, calm, TIER, init, "heuristic", "6dof", veh, 0)
    b.W.leaks[...] += 1000.0
    rb = b.run().results()
    np.testing.assert_array_equal(b.C.R[0, :n, :2], claims)
    assert rb["inspection_score"][0] == 0.0 and rb["false_claims"][0] == 2
    assert not rb["success"][0] and math.isnan(rb["localisation_error_m"][0])
    # external method: truth fixed, the claims it files decide the score
    leaks = init["leaks"][0]
    tier = {**TIER, "time_limit_s": 20.0}

    def external(report, rows=None):
        ep = Episodes(pi, calm, tier, init, None, "6dof", veh, 0).run(5)
        ep.C.R[0, np.arange(len(report)) if rows is None else rows, :2] = report
        return ep.run().results()

    r = external(leaks + [[3.0, 4.0], [0.0, -5.0]])
    assert r["success"][0] and r["inspection_score"][0] == 1.0
    assert r["localisation_error_m"][0] == pytest.approx(5.0)
    r = external(leaks + [[3.0, 4.0], [0.0, 20.0]])   # one claim moved past the tolerance
    assert not r["success"][0] and r["inspection_score"][0] == 0.5
    assert r["localisation_error_m"][0] == pytest.approx(12.5)
    r = external(np.vstack([leaks, [[0.0, 400.0]]]))   # a claim far from every leak
    assert r["false_claims"][0] == 1 and r["inspection_score"][0] == pytest.approx(2.0 / 3.0)
    assert not r["success"][0]
    r = external(leaks, rows=[pi.MAX_CLAIMS - 1, 7])    # any rows; the NaN rows are none
    assert r["success"][0] and r["false_claims"][0] == 0


def test_team_inspects_faster(calm):
    r1 = rollout(pi, calm, TIER, _straight_init(calm), "oracle", "6dof", E.load_vehicle(), 0)
    r2 = rollout(pi, calm, TIER, _straight_init(calm, n_agents=2), "oracle", "6dof",
                 E.load_vehicle(), 0)
    assert r1["success"][0] and r2["success"][0]
    assert r2["T_s"][0] < 0.7 * r1["T_s"][0]
    assert r1["coll_ratio"][0] == 0.0 and r2["coll_ratio"][0] == 0.0  # 450 m apart


def test_run_cell_deterministic_and_thread_independent(coast):
    a = run_cell(coast, "PI", 1, "heuristic", episodes=3, seed=2)
    b = run_cell(coast, "PI", 1, "heuristic", episodes=3, seed=2)
    pd.testing.assert_frame_equal(a, b)
    for k in STANDARD + ("primary",) + pi.METRICS:
        assert k in a.columns
    np.testing.assert_array_equal(a["primary"], a["inspection_score"])
    c = run_cell(coast, "PI", 1, "heuristic", episodes=3, seed=3)
    assert not np.array_equal(a["E"].to_numpy(), c["E"].to_numpy())
    if numba.config.NUMBA_NUM_THREADS >= 2:
        d = on_one_thread(run_cell, coast, "PI", 1, "heuristic", episodes=3, seed=2)
        pd.testing.assert_frame_equal(a, d)


def test_tier_table_monotone_and_declared():
    table = load_task_table("PI")
    tiers = table["tiers"]
    assert_tier_table_monotone(table)
    varied = [k for k in table["harder"] if len({repr(tiers[t][k]) for t in (1, 2, 3)}) > 1]
    assert len(varied) >= 5
    for t in (1, 2, 3):
        assert set(tiers[t]) == set(table["harder"]) == set(pi._TIER_KEYS)
        assert tiers[t]["loc_tolerance_m"] >= 0.75 * pi.FIELD_H_M
    assert table["agents"] == {"default": 1, "range": [1, 10]}
    assert math.isclose(table["dt_s"], 1.0)


def test_face_refresh_equals_the_current_at_the_faces_across_intervals():
    # the faces keep their near-bottom current over one interval of the time axis in
    # parts: every refresh, forward, backward and across the axis's times, gives the
    # sampler's bits in the field's axes
    g = E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0),
                    tide=(0.2, 1e-4, 0.3))
    nz, nx, h = 6, 11, 20.0
    ang = 0.6
    frame = np.array([[0.5 * (g.x0 + g.x_max), 0.5 * (g.z0 + g.z_max), math.cos(ang),
                       math.sin(ang), -40.0, -50.0]])
    uf, vf = np.zeros((1, nz, nx + 1)), np.zeros((1, nz + 1, nx))
    key = np.full((1, 2), -1, np.int64)
    part = np.zeros((1, nz * (nx + 1) + (nz + 1) * nx, 8))
    ox, oz, ca, sa, s0, n0 = frame[0]

    def faces(s, n):
        x = ox + s * ca - n * sa
        z = oz + s * sa + n * ca
        y = np.maximum(-G.sample_elevation_points(g, np.column_stack([x, z]),
                                                  np.empty(x.size)) - pi.NEAR_BOTTOM_M, 0.5)
        return np.column_stack([x, y, z])

    jx, fx = np.meshgrid(np.arange(nz), np.arange(nx + 1), indexing="ij")
    fz, iz = np.meshgrid(np.arange(nz + 1), np.arange(nx), indexing="ij")
    xf = faces(s0 + (fx.ravel() - 0.5) * h, n0 + jx.ravel() * h)
    zf = faces(s0 + iz.ravel() * h, n0 + (fz.ravel() - 0.5) * h)
    for t in (100.0, 3000.0, 3600.0, 3601.0, 9000.0, 500.0, 14400.0, 20000.0, 7200.0):
        pi._refresh_faces(g, frame, uf, vf, 0, nx, nz, h, key, part, t)
        assert (part[0, :, :4] != 0.0).all()     # the data's currents, not only the tide
        cu = E.sample_currents(g, xf, np.full(len(xf), t))
        cv = E.sample_currents(g, zf, np.full(len(zf), t))
        want_u = (cu[:, 0] * ca + cu[:, 1] * sa).reshape(nz, nx + 1)
        want_v = (-cv[:, 0] * sa + cv[:, 1] * ca).reshape(nz + 1, nx)
        np.testing.assert_array_equal(uf[0].view(np.int64), want_u.view(np.int64))
        np.testing.assert_array_equal(vf[0].view(np.int64), want_v.view(np.int64))
