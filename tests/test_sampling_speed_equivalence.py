"""The fast episode-sampling paths give the same values as the plain ones they replace: the
batched reference energies (``routing.mission_costs``) equal one ``plan_mission`` per episode,
the compiled field equals the engine's vectorised samplers, the compiled ``path_clear`` and
start-point draw equal the numpy versions (same points, same random draws)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from oneocean import engine as E
from oneocean.engine import status as st
from oneocean.engine.constraints import spawn_positions
from oneocean.engine.grid import sample_currents, sample_elevation_points, sample_speeds_times
from oneocean.tasks import g2g, rf, routing
from oneocean.tasks.spawn import _spawn_one, path_clear
from oneocean.testing import make_test_grid

G2G_TIER = {"time_limit_s": 3600.0, "goal_distance_m": 1200.0, "goal_radius_m": 10.0,
            "energy_reserve": 0.1, "dt_s": 1.0}
RF_TIER = {"time_limit_s": 3600.0, "n_waypoints": 3, "leg_m": 500.0, "wp_radius_m": 15.0,
           "xte_max_m": 30.0, "energy_reserve": 0.1, "dt_s": 1.0}


def test_g2g_reference_energies_equal_one_plan_per_episode(coast):
    init = g2g.reset(coast, G2G_TIER, 1, 5, seed=2)
    start, goal = init["pos0"][:, 0], init["goal"]
    batch = g2g.reference_energies(coast, G2G_TIER, start, goal, init["t0"])
    one = [g2g.reference_energy(coast, G2G_TIER, start[e, [0, 2]], goal[e, [0, 2]],
                                float(goal[e, 1]), float(init["t0"][e])) for e in range(5)]
    assert np.isfinite(batch).all()
    np.testing.assert_array_equal(batch, np.array(one))
    # and make's allocation is (1 + reserve) x that
    _, W = g2g.make(coast, G2G_TIER, init)
    np.testing.assert_array_equal(W.eref, batch)
    np.testing.assert_array_equal(W.budget, 1.1 * batch)


def test_g2g_reference_off_grid_is_inf(coast):
    start = np.array([[coast.x0 + 500.0, 5.0, coast.z0 + 500.0]] * 2)
    goal = start.copy()
    goal[1, 0] = coast.x_max + 100.0          # off the grid
    goal[0, 0] += 300.0
    e = g2g.reference_energies(coast, G2G_TIER, start, goal, [0.0, 0.0])
    assert math.isinf(e[1])
    assert e[0] == g2g.reference_energy(coast, G2G_TIER, start[0, [0, 2]], goal[0, [0, 2]],
                                        5.0, 0.0)


def test_rf_reference_energies_equal_one_schedule_per_episode(coast):
    init = rf.reset(coast, RF_TIER, 1, 4, seed=1)
    batch = rf.reference_energies(coast, RF_TIER, init["route"], init["t0"])
    one = [rf.reference_energy(coast, RF_TIER, init["route"][e], float(init["t0"][e]))
           for e in range(4)]
    np.testing.assert_array_equal(batch, np.array(one))


def _field_numpy(grid, lat, depth, times, clearance, lt=0.5, lm=0.1):
    """field_from_grid as it was written with the engine's vectorised samplers."""
    xs = lat.x0 + np.arange(lat.nx) * lat.h
    zs = lat.z0 + np.arange(lat.ny) * lat.h
    X, Z = np.meshgrid(xs, zs)
    xz = np.ascontiguousarray(np.column_stack([X.ravel(), Z.ravel()]))
    n = xz.shape[0]
    xyz = np.column_stack([xz[:, 0], np.full(n, float(depth)), xz[:, 1]])
    c = sample_currents(grid, np.tile(xyz, (times.size, 1)), np.repeat(times, n))
    elev = sample_elevation_points(grid, xz, np.empty(n)).reshape(lat.ny, lat.nx)
    land = routing._land_points(grid, xz, np.empty(n)).reshape(lat.ny, lat.nx)
    free = np.minimum(-elev - (float(depth) + float(clearance)), (lt - lm - land) * lat.h)
    return c.reshape(times.size, lat.ny, lat.nx, 2), free


def test_field_from_grid_equals_the_vectorised_samplers(coast):
    pts = np.array([[coast.x0 + 300.0, coast.z0 + 400.0], [coast.x0 + 2100.0, coast.z0 + 2500.0]])
    lat = routing.lattice(coast, pts, 400.0, 75.0)
    times = routing.field_times(coast, 1800.0, 7200.0)
    cur, free = routing.field_from_grid(coast, lat, 4.0, times, 5.0)
    cur0, free0 = _field_numpy(coast, lat, 4.0, times, 5.0)
    np.testing.assert_array_equal(cur, cur0)
    np.testing.assert_array_equal(free, free0)


def test_field_from_grid_is_the_point_sampler_bit_for_bit_at_any_times():
    """The field (each node located once, each time slab read once and shared by the two
    intervals it bounds) holds ``sample_currents``' bits, signed zeros included: with the
    tide layers and a synthetic tide, at the axis' times, between and outside them, in any
    order, next to land."""
    from oneocean.engine.grid import with_forcing

    g = with_forcing(E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0)),
                     tide=(0.3, 1.4e-4, 0.7))
    assert g.tide_layers == 1 and g.tide_amp == 0.3
    pts = np.array([[g.x0 + 50.0, g.z0 + 400.0], [g.x0 + 2100.0, g.z0 + 2500.0]])
    lat = routing.lattice(g, pts, 600.0, 75.0)
    times = np.concatenate([np.asarray(g.time_s, dtype=np.float64),
                            [-600.0, 1234.5, 7200.0, 7777.0, 3600.0, 1e6, 14400.0]])
    cur, free = routing.field_from_grid(g, lat, 4.0, times, 5.0)
    cur0, free0 = _field_numpy(g, lat, 4.0, times, 5.0)
    assert np.array_equal(cur.view(np.int64), cur0.view(np.int64))
    assert np.array_equal(free, free0)
    assert (free <= 0.0).any() and (free > 0.0).any()     # land and water in the lattice
    assert np.abs(cur).max() > 0.1


def test_current_times_equal_the_per_sample_sampler():
    """``sample_speeds_times`` (each point located once, the time and the tide once per time,
    used for a tier's current regime) equals ``hypot`` of ``sample_currents`` on every
    (time, point) pair, bit for bit: between and outside the grid's times, with a synthetic
    tide, next to land."""
    from oneocean.engine.grid import with_forcing

    g = with_forcing(E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0)),
                     tide=(0.3, 1.4e-4, 0.7))
    assert g.tide_amp == 0.3
    rng = np.random.default_rng(5)
    xyz = np.column_stack([rng.uniform(g.x0 - 50.0, g.x_max + 50.0, 300),
                           rng.uniform(0.0, 40.0, 300),
                           rng.uniform(g.z0 - 50.0, g.z_max + 50.0, 300)])
    times = np.concatenate([np.asarray(g.time_s[:3], dtype=np.float64),
                            [-600.0, 1234.5, 7777.0, 1e6]])
    got = sample_speeds_times(g, xyz, times)
    c = sample_currents(g, np.tile(xyz, (times.size, 1)), np.repeat(times, 300))
    want = np.hypot(c[:, 0], c[:, 1])
    assert np.array_equal(got.view(np.int64), want.view(np.int64))
    assert np.abs(got).max() > 0.1


def test_path_clear_equals_the_linspace_check(coast):
    rng = np.random.default_rng(4)
    for _ in range(200):
        p0 = np.array([rng.uniform(coast.x0, coast.x_max), rng.uniform(0.0, 20.0),
                       rng.uniform(coast.z0, coast.z_max)])
        p1 = p0 + rng.normal(0.0, 400.0, 3) * np.array([1.0, 0.01, 1.0])
        n = max(2, int(math.ceil(float(np.linalg.norm(p1 - p0)) / 20.0)) + 1)
        w = np.linspace(0.0, 1.0, n)[:, None]
        want = bool(np.all(E.feasibility(coast, p0 + w * (p1 - p0), 0.5, 5.0) == st.OK))
        assert path_clear(coast, p0, p1, 5.0, 0.5, spacing_m=20.0) == want


def test_spawn_one_draws_as_spawn_positions(coast):
    for seed in range(20):
        a = np.random.default_rng(seed)
        b = np.random.default_rng(seed)
        y = a.uniform(2.0, 10.0)
        assert b.uniform(2.0, 10.0) == y
        p = _spawn_one(coast, a, y, 0.5, 5.0)
        q = spawn_positions(coast, b, 1, {"y": (y, y)}, land_threshold=0.5, clearance=5.0,
                            max_candidates=4096)[0]
        np.testing.assert_array_equal(p, q)
        assert a.random() == b.random()       # the streams moved alike


def test_spawn_one_failure_is_spawn_positions_error(coast):
    from oneocean.errors import ConfigError

    a = np.random.default_rng(0)
    b = np.random.default_rng(0)
    with pytest.raises(ConfigError) as ea:
        _spawn_one(coast, a, 5.0, 0.5, 1e4)          # no water 10 km deep
    with pytest.raises(ConfigError) as eb:
        spawn_positions(coast, b, 1, {"y": (5.0, 5.0)}, land_threshold=0.5, clearance=1e4,
                        max_candidates=4096)
    assert str(ea.value) == str(eb.value)
    assert a.random() == b.random()


@pytest.mark.parametrize("has_tide", [True, False])
def test_regime_sampler_equals_sampling_the_grid_at_each_depth(has_tide, monkeypatch):
    """The current regime's samples from the levels a ``RegimeSampler`` keeps equal
    ``sample_speeds_times`` of the same nodes at each depth, bit for bit: on a level, between
    levels, above the shallowest and below the deepest, with a gain and a synthetic tide,
    with and without tide layers, one sampler reused over the depths (and its levels
    bounded); its quantiles (from certified order statistics, without sorting the speeds)
    equal ``np.quantile`` of them, and so do ``current_regime``'s and the path without kept
    levels."""
    from oneocean.engine.grid import order_stats_from_levels, with_forcing
    from oneocean.tasks import regime

    g = with_forcing(E.load_grid(make_test_grid(nt=7, nz=4, ny=30, nx=40, dt_s=1800.0,
                                                has_tide=has_tide)),
                     current_gain=1.3, tide=(0.25, 1.4e-4, 0.4))
    assert g.tide_layers == (1 if has_tide else 0)
    sampler = regime.RegimeSampler(g)
    depths = [float(g.depth[1]), 0.1, 3.3, 3.3, 11.7, float(g.depth[-1]), 500.0, 0.5 * (
        float(g.depth[1]) + float(g.depth[2]))]
    tier = {"current_band": [0.33, 0.83]}
    wants = []
    for d in depths:
        k, x, z = sampler.nodes(d)
        assert k == int(np.argmin(np.abs(np.asarray(g.depth) - d)))
        xyz = np.column_stack([x, np.full(x.size, d), z])
        want = sample_speeds_times(g, xyz, np.asarray(g.time_s, dtype=np.float64))
        got = sampler.speeds(d)
        assert got.shape == (len(g.time_s) * x.size,) and np.abs(got).max() > 0.1
        assert np.array_equal(got.view(np.int64), want.view(np.int64)), d
        wants.append(want)
        qs = [0.0, 0.15, 0.25, 1.0 / 3.0, 0.5, 0.55, 0.83, 1.0]
        assert sampler.quantiles(d, qs) == tuple(np.quantile(want, qs).tolist()), d
        _, c0, c1, ct, wk = sampler._parts(d)          # certified, not the sorting fallback
        ranks = np.array([0, want.size // 3, want.size - 1])
        vals = np.empty(3)
        assert order_stats_from_levels(g, c0, c1, ct, wk, ranks, np.empty(want.size), vals)
        np.testing.assert_array_equal(vals, np.sort(want)[ranks])
        assert len(sampler._levels) <= regime.REGIME_LEVELS_KEPT
        assert (regime.current_regime(g, tier, d, sampler)
                == regime.current_regime(g, tier, d))
    monkeypatch.setattr(regime, "REGIME_LEVEL_BYTES", 0)      # nothing kept: the grid's path
    fresh = regime.RegimeSampler(g)
    for d, want in zip(depths[:3], wants):
        assert np.array_equal(fresh.speeds(d).view(np.int64), want.view(np.int64))
    assert not fresh._levels


@pytest.mark.parametrize("step", [None, 1e-3, 0.05])
def test_order_stats_with_ties_and_many_ranks_are_the_sorted_speeds(step):
    """The order statistics at many ranks (both ends, neighbours, the middle) are those of
    the sorted speeds, also where currents quantised to ``step`` m/s make many samples tie
    (full bins, ranks sharing a bin, samples counted below a rank from the histogram)."""
    from oneocean.engine.grid import order_stats_from_levels, speeds_from_levels
    from oneocean.tasks import regime

    g = E.load_grid(make_test_grid(nt=6, nz=3, ny=30, nx=40, dt_s=3600.0))
    _, c0, c1, ct, wk = regime.RegimeSampler(g)._parts(2.7)
    if step is not None:
        c0, c1 = np.round(c0 / step) * step, np.round(c1 / step) * step
    want = np.sort(speeds_from_levels(g, c0, c1, ct, wk, np.empty(c0.shape[0] * c0.shape[1])))
    n = want.size
    ranks = np.unique(np.array([0, 1, 2, n // 7, n // 3, n // 2, n // 2 + 1, n - 2, n - 1]))
    vals = np.empty(ranks.size)
    assert order_stats_from_levels(g, c0, c1, ct, wk, ranks, np.empty(n), vals)
    assert np.array_equal(vals.view(np.int64), want[ranks].view(np.int64))


def test_regime_quantiles_of_a_calm_grid_fall_back_to_sorting_the_speeds():
    """Where every sample has the same squared speed (no current, no tide) the order
    statistics cannot be binned: the quantiles are ``np.quantile`` of the speeds, 0."""
    from oneocean.engine.grid import with_forcing
    from oneocean.tasks.regime import RegimeSampler, current_regime

    g = with_forcing(E.load_grid(make_test_grid(nt=3, nz=3, ny=20, nx=30, has_tide=False)),
                     current_gain=0.0)
    assert RegimeSampler(g).quantiles(4.0, [0.2, 0.9]) == (0.0, 0.0)
    r = current_regime(g, {"current_band": [0.5, 1.0]}, 4.0)
    assert (r.lo, r.hi) == (0.0, math.inf)
