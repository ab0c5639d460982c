"""The sensor models every non-oracle method shares (oneocean.sensing): values a user relies
on -- the filter's residual, dead-reckoning drift per distance, fixes, truth for the oracle,
and the step API's observation equal to what the loop then senses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from oneocean import engine as E
from oneocean.errors import ConfigError
from oneocean.sensing import (INFO_LEVELS, kalman_gain, nav_aid, sensing_params, sensor_table)
from oneocean.sensing.kernels import current_estimate, init_sensing, nav_update
from oneocean.tasks import Cell
from oneocean.tasks.episodes import Episodes
from oneocean.testing import make_test_grid


def test_kalman_gain_is_the_steady_state():
    q, r = 0.01 ** 2, 0.05 ** 2
    k = kalman_gain(0.01, 0.05, 1.0)
    m = k * r / (1.0 - k)                       # the prior variance behind the gain
    assert math.isclose(m * m, q * m + q * r, rel_tol=1e-12)
    assert kalman_gain(0.01, 0.0, 1.0) == 1.0 and kalman_gain(0.0, 0.05, 1.0) == 0.0
    assert 0.17 < k < 0.19


def test_sensor_table_and_levels():
    t = sensor_table()
    assert t["current"]["in_situ"]["noise_std_ms"] == 0.05
    sp = sensing_params("sensors", 1.0)
    assert (sp.true_current, sp.true_position) == (0, 0)
    assert (sensing_params("truth", 1.0).true_current,
            sensing_params("truth", 1.0).true_position) == (1, 1)
    assert sensing_params("true_current", 1.0)[:2] == (1, 0)
    assert sensing_params("true_position", 1.0)[:3] == (0, 1, 0)
    assert sensing_params("true_target", 1.0)[:3] == (0, 0, 1)
    assert sensing_params("truth", 1.0)[:3] == (1, 1, 1)
    assert sensing_params("sensors", 1.0)[:3] == (0, 0, 0)
    assert set(INFO_LEVELS) == {"sensors", "true_current", "true_position", "true_target",
                                "truth"}
    with pytest.raises(ConfigError, match="unknown information level 'psychic'"):
        sensing_params("psychic", 1.0)
    aid = nav_aid({"navigation": {"aid": "usbl", "period_s": 5}})
    assert aid == ("usbl", 5.0)
    sp = sensing_params("sensors", 1.0, aid)
    assert sp.fix_every == 5 and sp.fix_std == 0.5 and 0.0 < sp.fix_gain < 1.0
    with pytest.raises(ConfigError, match="navigation.aid 'gps' is not a sensor aid"):
        nav_aid({"navigation": {"aid": "gps", "period_s": 5}}, "T.yaml")


def test_forecast_error_grows_with_lead():
    base = sensing_params("sensors", 1.0)
    assert sensing_params("sensors", 1.0, lead_h=24.0) == base       # the reference lead
    a0 = sensing_params("sensors", 1.0, lead_h=0.0)                  # the analysis: half
    a72 = sensing_params("sensors", 1.0, lead_h=72.0)                # 0.5 + 0.5 * 3 = 2x
    for k in ("fc_gain_std", "fc_dir_std", "fc_bias_std"):
        assert math.isclose(getattr(a0, k), 0.5 * getattr(base, k))
        assert math.isclose(getattr(a72, k), 2.0 * getattr(base, k))
    assert a72.meas_std == base.meas_std and a72.start_fix_std == base.start_fix_std
    with pytest.raises(ConfigError, match="forecast_lead_h must be >= 0"):
        sensing_params("sensors", 1.0, lead_h=-1.0)


def test_bad_sensor_table_is_one_line(tmp_path):
    good = (sensor_table.__globals__["SENSORS_YAML"]).read_text()
    f = tmp_path / "sensors.yaml"
    f.write_text(good.replace("noise_std_ms: 0.05", "noise_std_ms: -1"))
    with pytest.raises(ConfigError) as exc:
        sensing_params("sensors", 1.0, path=f)
    msg = str(exc.value)
    assert "\n" not in msg and str(f) in msg and "current.in_situ.noise_std_ms" in msg
    f.write_text(good.replace("gnss_std_m:", "gnss_sdt_m:"))
    with pytest.raises(ConfigError, match="gnss_std_m"):
        sensing_params("sensors", 1.0, path=f)


def _arrays(n_ep, n_ag, depth=5.0):
    state = E.new_state(n_ep, n_ag, np.tile([0.0, depth, 0.0], (n_ep, n_ag, 1)), 0.0)
    return (state, np.zeros((n_ep, 5)), np.zeros((n_ep, n_ag, 2)), np.zeros((n_ep, n_ag, 3)),
            np.zeros((n_ep, n_ag, 2)))


def test_current_estimate_converges_to_the_filter_residual():
    sp = sensing_params("sensors", 1.0)
    state, fc, cb, navc, nerr = _arrays(200, 1)
    init_sensing(sp, 7, state, fc, cb, navc, nerr)
    ce, cn = 0.6, -0.3
    first, late = [], []
    for e in range(200):
        for k in range(400):
            pe, pn = current_estimate(sp, 7, cb, fc, e, k, 0, 1, ce, cn, 1)
            if k == 0:
                first.append(math.hypot(pe - ce, pn - cn))
            elif k >= 100:
                late.append(pe - ce)
    # the forecast alone is off by its error model (gain 20 %, 15 deg, 0.05 m/s bias) ...
    assert 0.05 < np.mean(first) < 0.3
    # ... the filtered estimate by the in-situ noise through the gain: sigma sqrt(K / (2 - K))
    k = sp.kf_gain
    want = 0.05 * math.sqrt(k / (2.0 - k))
    assert abs(np.mean(late)) < 0.2 * want
    assert 0.8 * want < np.std(late) < 1.2 * want
    # the truth for a method given the true current; an uncommitted estimate changes nothing
    tc = sensing_params("true_current", 1.0)
    assert current_estimate(tc, 7, cb, fc, 0, 5, 0, 1, ce, cn, 1) == (ce, cn)
    before = cb.copy()
    current_estimate(sp, 7, cb, fc, 3, 999, 0, 1, ce, cn, 0)
    np.testing.assert_array_equal(cb, before)


def test_dead_reckoning_drifts_with_distance_and_fixes_bound_it():
    sp = sensing_params("sensors", 1.0)
    n_ep = 400
    state, fc, cb, navc, nerr = _arrays(n_ep, 1)
    init_sensing(sp, 3, state, fc, cb, navc, nerr)
    start = nerr.copy()
    prev = state[:, :, :3].copy()
    for k in range(1000):                      # 1 km east at 1 m/s, 5 m deep
        prev[:] = state[:, :, :3]
        state[:, :, 0] += 1.0
        for e in range(n_ep):
            nav_update(sp, 3, navc, nerr, state, prev, e, k, 0, 1, 1.0)
    drift = np.hypot(*(nerr - start)[:, 0].T)
    # heading bias 0.5 deg and scale factor 0.3 %: ~0.9 % of the distance (1 sigma each)
    assert 4.0 < np.sqrt(np.mean(drift ** 2)) < 14.0
    # exactly the scale-factor and heading-bias rotation of the track, plus tiny DVL noise
    g, c, s = navc[:, 0, 0], navc[:, 0, 1], navc[:, 0, 2]
    want = np.column_stack([(g * c - 1.0) * 1000.0, -g * s * 1000.0])
    assert np.max(np.abs((nerr - start)[:, 0] - want)) < 0.6
    # an acoustic fix every 5 s keeps the error at the fix filter's level
    aided = sensing_params("sensors", 1.0, ("usbl", 5.0))
    state, fc, cb, navc, nerr = _arrays(n_ep, 1)
    init_sensing(aided, 3, state, fc, cb, navc, nerr)
    for k in range(1000):
        prev[:] = state[:, :, :3]
        state[:, :, 0] += 1.0
        for e in range(n_ep):
            nav_update(aided, 3, navc, nerr, state, prev, e, k, 0, 1, 1.0)
    assert np.sqrt(np.mean(np.hypot(*nerr[:, 0].T) ** 2)) < 1.0
    # at the surface a GNSS fix every step (1 m per axis, truncated at 3 sigma)
    state, fc, cb, navc, nerr = _arrays(n_ep, 1, depth=0.0)
    init_sensing(sp, 3, state, fc, cb, navc, nerr)
    prev[:] = state[:, :, :3]
    for e in range(n_ep):
        nav_update(sp, 3, navc, nerr, state, prev, e, 0, 0, 1, 1.0)
    assert np.all(np.abs(nerr) <= 3.0) and 0.8 < np.std(nerr) < 1.2


@pytest.fixture(scope="module")
def coast():
    return E.load_grid(make_test_grid(nt=5, nz=5, ny=40, nx=50, max_depth_m=60.0))


@pytest.mark.parametrize("task, cols", [("G2G", slice(0, 7)), ("FT", slice(3, 7))])
def test_step_api_observation_is_what_the_loop_senses(coast, task, cols):
    """Episodes.observe() before step k equals the observation the loop records at step k
    (the filter's update is computed, not stored, between segments). FT's goal cue is its
    slot around the virtual centre its plan moves at the start of the step, so only the
    sensed columns (current, depth, altitude) are compared there."""
    cell = Cell(coast, task, 1)
    init = cell.reset(2, 4)
    rec = Episodes(cell.mod, cell.grid, cell.params, init, "heuristic", "6dof", cell.vehicle,
                   4, record=True).run()
    seg = Episodes(cell.mod, cell.grid, cell.params, cell.reset(2, 4), "heuristic", "6dof",
                   cell.vehicle, 4)
    seg.run(0)
    for k in range(0, 40, 7):
        seg.run(k)
        o = seg.observe()
        np.testing.assert_array_equal(o[:, :, cols], rec.obs[:, k, :, cols])
    # and stepping in segments is the uninterrupted run
    seg.run()
    np.testing.assert_array_equal(seg.res, rec.res)


def test_polar_fix_measures_range_and_bearing_with_bounded_noise():
    from oneocean.sensing.kernels import TRUNC, polar_fix

    # no noise: the offset itself; zero offset: zero
    assert polar_fix(7, 0, 0, 3.0, 4.0, 0.0, 0.0) == pytest.approx((3.0, 4.0), abs=1e-12)
    assert polar_fix(7, 0, 0, 0.0, 0.0, 0.1, 0.01) == (0.0, 0.0)
    # with noise: the measured range within TRUNC sigma, the bearing within TRUNC sigma, and
    # the same draw for the same (seed, episode, counter)
    rs, bs = 0.1, math.radians(1.0)
    errs_r, errs_b = [], []
    for c in range(0, 400, 2):
        mx, mz = polar_fix(7, 3, c, 30.0, 40.0, rs, bs)
        assert (mx, mz) == polar_fix(7, 3, c, 30.0, 40.0, rs, bs)
        errs_r.append(math.hypot(mx, mz) - 50.0)
        errs_b.append(math.atan2(mx, mz) - math.atan2(30.0, 40.0))
    assert max(map(abs, errs_r)) <= TRUNC * rs + 1e-9
    assert max(map(abs, errs_b)) <= TRUNC * bs + 1e-9
    assert 0.07 < np.std(errs_r) < 0.13 and 0.7 < math.degrees(np.std(errs_b)) < 1.3
