"""Grid export loading/validation and the field-sampling kernels (oneocean.engine.grid)."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from oneocean.engine import constraints as C
from oneocean.engine import grid as G
from oneocean.engine import status as st
from oneocean.errors import ConfigError, DataError
from oneocean.io import write_npz_atomic
from oneocean.testing import make_test_grid


@pytest.fixture(scope="module")
def export():
    return make_test_grid()


@pytest.fixture(scope="module")
def grid(export):
    return G.load_grid(export)


def test_test_grid_has_exactly_the_contract_keys(export):
    assert set(export) == set(G.REQUIRED_KEYS)
    assert set(G.OPTIONAL_KEYS) == {"current_mask"}


def test_load_from_npz_path_equals_load_from_dict(tmp_path, export, grid):
    p = tmp_path / "grid.npz"
    write_npz_atomic(p, export)
    g2 = G.load_grid(p)
    for name, a, b in zip(G.Grid._fields, grid, g2):
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=name)
        else:
            assert a == b, name
    assert G.grid_metadata(p)["variant"] == "test"


def test_missing_fields_are_all_named(export):
    d = {k: v for k, v in export.items() if k not in ("u", "dx_m", "valid_mask")}
    with pytest.raises(DataError, match="missing fields: u, dx_m, valid_mask"):
        G.load_grid(d)


def test_nan_current_inside_valid_water_is_an_error(export):
    d = dict(export)
    u = d["u"].copy()
    t, k, j, i = np.argwhere(d["valid_mask"][None].repeat(u.shape[0], 0) == 1)[5]
    u[t, k, j, i] = np.nan
    d["u"] = u
    with pytest.raises(DataError, match="NaN currents inside valid water"):
        G.load_grid(d)


@pytest.mark.parametrize("key", ["elevation", "land_mask", "u_tide"])
def test_nan_in_other_layers_is_an_error(export, key):
    d = dict(export)
    a = d[key].copy()
    a.flat[3] = np.nan
    d[key] = a
    with pytest.raises(DataError, match=key):
        G.load_grid(d)


def test_shape_and_axis_errors(export):
    d = dict(export, elevation=export["elevation"][:-1])
    with pytest.raises(DataError, match="inconsistent shapes.*'elevation'"):
        G.load_grid(d)
    lon = export["lon"].copy()
    lon[3] += 0.3 * (lon[1] - lon[0])
    with pytest.raises(DataError, match="'lon' must have regular spacing"):
        G.load_grid(dict(export, lon=lon))
    with pytest.raises(DataError, match="'time_s' must be strictly ascending"):
        G.load_grid(dict(export, time_s=export["time_s"][::-1].copy()))
    with pytest.raises(DataError, match="'lat' disagrees"):
        G.load_grid(dict(export, z0_m=np.array(float(export["z0_m"]) + 1000.0)))


def test_bad_forcing_config(export):
    with pytest.raises(ConfigError, match="current_gain"):
        G.load_grid(export, current_gain=np.nan)
    with pytest.raises(ConfigError, match="period_s"):
        G.load_grid(export, tide={"amplitude_ms": 0.1})


def _linear_grid():
    """Currents linear in x, z, depth and time on an irregular depth axis (interp is exact)."""
    d = make_test_grid(nt=4, nz=4, ny=6, nx=7, dx_m=50.0, dz_m=70.0, dt_s=600.0,
                         depths=[0.0, 3.0, 10.0, 40.0], has_tide=True, land=False)
    x = float(d["x0_m"]) + 50.0 * np.arange(7)
    z = float(d["z0_m"]) + 70.0 * np.arange(6)
    T, D, Z, X = np.meshgrid(d["time_s"], d["depth"], z, x, indexing="ij")
    d["u"] = (0.1 + 1e-4 * X - 2e-4 * Z + 3e-3 * D + 1e-5 * T).astype(np.float64)
    d["v"] = (-0.2 + 2e-4 * X + 1e-4 * Z - 1e-3 * D + 2e-5 * T).astype(np.float64)
    T3, Z3, X3 = np.meshgrid(d["time_s"], z, x, indexing="ij")
    d["u_tide"] = (0.05 + 1e-4 * X3 + 1e-6 * T3).astype(np.float32)
    d["v_tide"] = (0.02 - 1e-4 * Z3).astype(np.float32)
    d["valid_mask"] = np.ones_like(d["valid_mask"])
    return d


def _exact(x, y, z, t, tide=True):
    u = 0.1 + 1e-4 * x - 2e-4 * z + 3e-3 * y + 1e-5 * t
    v = -0.2 + 2e-4 * x + 1e-4 * z - 1e-3 * y + 2e-5 * t
    if tide:
        u += 0.05 + 1e-4 * x + 1e-6 * t
        v += 0.02 - 1e-4 * z
    return u, v


def test_sampling_is_exact_for_linear_fields_in_4d():
    d = _linear_grid()
    g = G.load_grid(d)
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(g.x0, g.x_max, 200), rng.uniform(0, 40, 200),
                           rng.uniform(g.z0, g.z_max, 200)])
    t = rng.uniform(0, 1800, 200)
    got = G.sample_currents(g, pts, t)
    # the arrays are float32, so exact up to float32 rounding of the node values
    u, v = _exact(pts[:, 0], pts[:, 1], pts[:, 2], t)
    np.testing.assert_allclose(got[:, 0], u, atol=2e-6)
    np.testing.assert_allclose(got[:, 1], v, atol=2e-6)


def test_gain_tide_layers_and_synthetic_tide():
    d = _linear_grid()
    x, y, z, t = 10.0, 5.0, -20.0, 900.0
    base = G.load_grid(d, use_tide_layers=False)
    u0, v0 = G.sample_current(base, x, y, z, t)
    ue, ve = _exact(x, y, z, t, tide=False)
    assert abs(u0 - ue) < 2e-6 and abs(v0 - ve) < 2e-6
    # paper eq. 1: g scales the data currents only, the tide layers are added unscaled
    g2 = G.load_grid(d, current_gain=2.0)
    u2, v2 = G.sample_current(g2, x, y, z, t)
    ut, vt = _exact(x, y, z, t, tide=True)
    assert abs(u2 - (2 * ue + (ut - ue))) < 4e-6 and abs(v2 - (2 * ve + (vt - ve))) < 4e-6
    u1, v1 = G.sample_current(G.load_grid(d), x, y, z, t)
    assert u2 - u1 == pytest.approx(ue, abs=4e-6) and v2 - v1 == pytest.approx(ve, abs=4e-6)
    g0 = G.with_forcing(g2, current_gain=0.0)                   # tide layers only
    assert G.sample_current(g0, x, y, z, t) == pytest.approx((ut - ue, vt - ve), abs=2e-6)
    # tide layers are ignored when the export says it has none
    u3, _ = G.sample_current(G.load_grid(dict(d, has_tide=np.int8(0))), x, y, z, t)
    assert u3 == u0
    amp, period, ph = 0.3, 1000.0, 0.4
    g4 = G.with_forcing(base, tide={"amplitude_ms": amp, "period_s": period, "phase_rad": ph})
    u4, v4 = G.sample_current(g4, x, y, z, t)
    w = 2 * np.pi / period
    assert u4 - u0 == pytest.approx(amp * np.sin(w * t + ph), abs=1e-12)
    assert v4 - v0 == pytest.approx(amp * np.cos(w * t + ph), abs=1e-12)


def test_nodes_and_clamping(grid, export):
    k, t_i, j, i = 2, 3, 17, 23
    x = grid.x0 + i * grid.dx
    z = grid.z0 + j * grid.dz
    ce, cn = G.sample_current(grid._replace(tide_layers=0), x, export["depth"][k], z,
                              export["time_s"][t_i])
    assert ce == pytest.approx(float(export["u"][t_i, k, j, i]), abs=1e-7)
    assert cn == pytest.approx(float(export["v"][t_i, k, j, i]), abs=1e-7)
    # outside the time / depth / horizontal range: the edge value
    g0 = grid._replace(tide_layers=0)
    last = G.sample_current(g0, x, export["depth"][-1], z, export["time_s"][-1])
    assert G.sample_current(g0, x, 1e4, z, 1e9) == last
    first = G.sample_current(g0, x, export["depth"][0], z, 0.0)
    assert G.sample_current(g0, x, -5.0, z, -100.0) == first
    assert G.sample_current(g0, grid.x_max + 500, 3.0, z, 10.0) == \
        G.sample_current(g0, grid.x_max, 3.0, z, 10.0)


def test_axis_lookup_matches_searchsorted():
    rng = np.random.default_rng(1)
    ax = np.cumsum(rng.uniform(0.01, 5.0, 40))
    inv, lut, h = G._axis_lut(ax)
    for v in rng.uniform(ax[0] - 1, ax[-1] + 1, 2000):
        i0, i1, w = G._locate(ax, inv, lut, h, v)
        if v <= ax[0]:
            assert (i0, w) == (0, 0.0)
        elif v >= ax[-1]:
            assert (i1, w) == (ax.size - 1, 1.0)
        else:
            assert i0 == np.searchsorted(ax, v, side="right") - 1
            assert (1 - w) * ax[i0] + w * ax[i1] == pytest.approx(v, rel=1e-12)


def test_elevation_land_and_feasibility(grid):
    # west edge is land, east is deep water (make_test_grid's coast)
    zc = 0.5 * (grid.z0 + grid.z_max)
    assert G.sample_land(grid, grid.x0, zc) == 1.0
    assert G.sample_elevation(grid, grid.x0, zc) > 0
    assert G.sample_land(grid, grid.x_max, zc) == 0.0
    depth = -G.sample_elevation(grid, grid.x_max, zc)
    assert depth > 30
    assert C.check_move(grid, grid.x0, 1.0, zc, 0.5, 1.0) == st.LAND
    assert C.check_move(grid, grid.x_max, depth - 0.5, zc, 0.5, 1.0) == st.SEAFLOOR
    assert C.check_move(grid, grid.x_max, depth - 1.5, zc, 0.5, 1.0) == st.OK
    assert C.check_move(grid, grid.x_max + 1, 1.0, zc, 0.5, 1.0) == st.OUTSIDE
    assert C.check_move(grid, grid.x_max, -0.1, zc, 0.5, 1.0) == st.OUTSIDE  # above the surface
    assert C.check_move(grid, np.nan, 1.0, zc, 0.5, 1.0) == st.NONFINITE


def test_lonlat_roundtrip(grid):
    lon, lat = G.world_to_lonlat(grid, np.array([123.0]), np.array([-456.0]))
    x, z = G.lonlat_to_world(grid, lon, lat)
    assert x[0] == pytest.approx(123.0) and z[0] == pytest.approx(-456.0)


def test_hold_levels():
    valid = np.array([[1, 0, 1, 0], [1, 1, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0]])[:, None, :]
    src = G.hold_levels(valid)[:, 0, :]
    # col 0: valid to 1 m -> held below; col 1: first level missing -> takes level 1;
    # col 2: only the first level; col 3: no current (reads 0, zeroed by fill_columns)
    np.testing.assert_array_equal(src, [[0, 1, 0, 0], [1, 1, 0, 0], [1, 2, 0, 0],
                                        [1, 2, 0, 0]])
    a = np.arange(2 * 4 * 1 * 4, dtype=np.float32).reshape(2, 4, 1, 4) + 1
    f = G.fill_columns(a, valid)
    np.testing.assert_array_equal(f[:, :, 0, 0], a[:, [0, 1, 1, 1], 0, 0])
    np.testing.assert_array_equal(f[:, :, 0, 1], a[:, [1, 1, 2, 2], 0, 1])
    assert (f[:, :, 0, 3] == 0).all()


def _boundary_grid():
    """A 4-level grid with u = 0.4, v = -0.2 wherever defined: a land node, water without
    currents (a 2 x 2 block in the south-east), and a column whose bed is at 32.5 m."""
    d = make_test_grid(nt=2, nz=4, ny=8, nx=8, dx_m=100.0, dz_m=100.0,
                       depths=[0.5, 10.0, 20.0, 40.0], has_tide=True, land=False)
    elev = np.full((8, 8), -60.0, np.float32)
    elev[5, 2] = 3.0                                  # land
    elev[3, 4] = -32.5                                # shallow column: no 40 m level
    valid = np.ones((4, 8, 8), np.uint8)
    valid[:, 5, 2] = 0
    valid[3, 3, 4] = 0
    valid[:, 0:2, 6:8] = 0                            # water without currents
    d.update(elevation=elev, land_mask=(elev >= 0).astype(np.float32), valid_mask=valid)
    shape = d["u"].shape
    d["u"] = np.where(valid[None] == 1, np.full(shape, 0.4, np.float32), 0).astype(np.float32)
    d["v"] = np.where(valid[None] == 1, np.full(shape, -0.2, np.float32), 0).astype(np.float32)
    d["u_tide"] = np.full(d["u_tide"].shape, 0.1, np.float32)
    d["v_tide"] = np.zeros(d["v_tide"].shape, np.float32)
    return d


def test_nan_aware_sampling_next_to_land_above_the_bed_and_without_currents():
    d = _boundary_grid()
    g = G.load_grid(d, use_tide_layers=False)
    node = lambda j, i: (g.x0 + i * g.dx, g.z0 + j * g.dz)  # noqa: E731
    # next to land (node (5, 2)), three defined corners: renormalised while the land node
    # carries less than half of the weight (before: 0.4 * (1 - w_land)), then fading
    x, z = node(5, 2)
    for fx, fz in ((0.5, 0.5), (0.75, 0.4), (-0.5, -0.6), (0.3, -0.5)):
        assert G.sample_current(g, x + fx * g.dx, 3.0, z + fz * g.dz, 0.0) == \
            pytest.approx((0.4, -0.2), abs=1e-7), (fx, fz)
    assert G.sample_current(g, x + 0.25 * g.dx, 3.0, z + 0.25 * g.dz, 0.0) == \
        pytest.approx((0.4 * (1 - 0.75 ** 2) / 0.5, -0.2 * (1 - 0.75 ** 2) / 0.5), abs=1e-7)
    # 2.5 m above a 32.5 m bed: the 20 m value held down (was half of it before)
    x, z = node(3, 4)
    assert G.sample_current(g, x, 30.0, z, 0.0) == pytest.approx((0.4, -0.2), abs=1e-7)
    # water without currents: exactly 0, and it fades linearly below half of the weight
    x, z = node(0, 7)
    assert G.sample_current(g, x, 3.0, z, 0.0) == (0.0, 0.0)
    assert G.current_coverage(g, [[x, z]])[0] == 0.0 and G.sample_land(g, x, z) == 0.0
    x5, z0 = node(0, 5)
    for fx, want in ((0.25, 0.4), (0.5, 0.4), (0.75, 0.2), (0.9, 0.08)):
        got = G.sample_current(g, x5 + fx * g.dx, 3.0, z0, 0.0)[0]
        assert got == pytest.approx(want, abs=1e-7), fx
        assert G.current_coverage(g, [[x5 + fx * g.dx, 0.0, z0]])[0] == pytest.approx(1 - fx)
    # the tide layers share the weights; the gain scales u, v only
    gt = G.load_grid(d, current_gain=3.0)
    x, z = node(5, 2)
    assert G.sample_current(gt, x + 50.0, 3.0, z + 50.0, 0.0) == \
        pytest.approx((3 * 0.4 + 0.1, 3 * -0.2), abs=1e-6)
    assert G.sample_current(gt, *node(0, 7)[:1], 3.0, node(0, 7)[1], 0.0) == (0.0, 0.0)


def test_current_mask_is_carried_and_checked(tmp_path):
    d = _boundary_grid()
    g = G.load_grid(d)
    cm = (d["valid_mask"] == 1).any(axis=0)
    np.testing.assert_array_equal(g.current_mask, cm.astype(np.float32))
    assert g.current_mask.dtype == np.float32 and g.current_mask.shape == (8, 8)
    # an export with the mask and held values loads to the same Grid (idempotent)
    held = dict(d, current_mask=cm.astype(np.uint8), u=G.fill_columns(d["u"], d["valid_mask"]),
                v=G.fill_columns(d["v"], d["valid_mask"]))
    assert held["u"][0, 3, 3, 4] == np.float32(0.4)
    g2 = G.load_grid(held)
    for name, a, b in zip(G.Grid._fields, g, g2):
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=name)
    bad = cm.astype(np.uint8)
    bad[0, 7] = 1
    with pytest.raises(DataError, match="'current_mask' disagrees with any\\(valid_mask\\)"):
        G.load_grid(dict(d, current_mask=bad))
    with pytest.raises(DataError, match="'current_mask' must be numeric"):
        G.load_grid(dict(d, current_mask=bad[:-1]))


def test_spawn_can_keep_away_from_water_without_currents():
    g = G.load_grid(_boundary_grid())
    pos = C.spawn_positions(g, 3, 200, {"y": (1.0, 5.0)}, min_current_defined=1.0)
    assert (G.current_coverage(g, pos) == 1.0).all()
    assert (G.current_coverage(g, C.spawn_positions(g, 3, 200, {"y": (1.0, 5.0)})) < 1).any()
    block = {"x": (g.x0 + 6.2 * g.dx, g.x_max), "z": (g.z0, g.z0 + 0.8 * g.dz), "y": (1, 2)}
    with pytest.raises(ConfigError, match="no current: "):
        C.spawn_positions(g, 0, 1, block, min_current_defined=0.5, max_candidates=500)
    assert C.spawn_positions(g, 0, 1, block).shape == (1, 3)     # water: feasible without it


@pytest.mark.parametrize("which", ["analytic", "boundary"])
def test_speeds_at_every_time_are_hypot_of_the_currents_bit_for_bit(which):
    # the current regime's sampler (points located once, a time of the axis without the
    # other time's terms) gives the bits of hypot(sample_currents), sample by sample: on
    # and off the nodes, off the grid, next to land and water without currents, at the
    # axis's times and between them, with tide layers, a gain and the synthetic tide
    d = make_test_grid() if which == "analytic" else _boundary_grid()
    rng = np.random.default_rng(7)
    for g in (G.load_grid(d), G.load_grid(d, current_gain=1.7, tide=(0.3, 1e-4, 0.4)),
              G.load_grid(d, use_tide_layers=False)):
        ii, jj = np.meshgrid(np.arange(g.nx), np.arange(g.ny))
        nodes = np.column_stack([g.x0 + ii.ravel() * g.dx, np.zeros(ii.size),
                                 g.z0 + jj.ravel() * g.dz])
        loose = np.column_stack([rng.uniform(g.x0 - 300, g.x_max + 300, 500),
                                 np.zeros(500), rng.uniform(g.z0 - 300, g.z_max + 300, 500)])
        times = np.concatenate([np.asarray(g.time_s, np.float64),
                                rng.uniform(g.time_s[0] - 50, g.time_s[-1] + 50, 5)])
        for depth in (0.0, 0.5, 7.3, float(g.depth[-1]), 95.0):
            xyz = np.vstack([nodes, loose])
            xyz[:, 1] = depth
            c = G.sample_currents(g, np.tile(xyz, (times.size, 1)), np.repeat(times, len(xyz)))
            want = np.hypot(c[:, 0], c[:, 1])
            got = G.sample_speeds_times(g, xyz, times)
            assert got.shape == want.shape and (want > 0.0).mean() > 0.5
            np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))


@njit(cache=False)
def _currents_from_parts(g, xyz, tq, times):
    """Each point's parts taken once at time ``tq``'s interval, then the current at every
    time of ``times`` (all in that interval) from them, with the synthetic tide."""
    t0, t1, _ = G.locate_time(g, tq)
    out = np.empty((times.shape[0], xyz.shape[0], 2))
    for n in range(times.shape[0]):
        a0, a1, _ = G.locate_time(g, times[n])
        if a0 != t0 or a1 != t1:
            out[:] = np.nan       # a time outside tq's interval
            return out
    for p in range(xyz.shape[0]):
        q = G.sample_current_parts(g, xyz[p, 0], xyz[p, 1], xyz[p, 2], t0, t1)
        for n in range(times.shape[0]):
            _, _, wt = G.locate_time(g, times[n])
            te, tn = G.synthetic_tide(g, times[n])
            out[n, p, 0] = G.current_from_parts(g, wt, q[0], q[1], q[4], q[5]) + te
            out[n, p, 1] = G.current_from_parts(g, wt, q[2], q[3], q[6], q[7]) + tn
    return out


@pytest.mark.parametrize("which", ["analytic", "boundary"])
def test_currents_from_an_intervals_parts_are_the_samplers_bit_for_bit(which):
    # a field's face centres take their parts once per interval of the time axis and the
    # current at every refresh from them: the sampler's bits at every time of the interval
    # (its ends included), on and off the nodes, off the grid, next to land and water
    # without currents, with and without tide layers, a gain and the synthetic tide
    d = make_test_grid() if which == "analytic" else _boundary_grid()
    rng = np.random.default_rng(11)
    for g in (G.load_grid(d), G.load_grid(d, current_gain=1.7, tide=(0.3, 1e-4, 0.4)),
              G.load_grid(d, use_tide_layers=False)):
        ts = np.asarray(g.time_s, np.float64)
        xyz = np.column_stack([rng.uniform(g.x0 - 300, g.x_max + 300, 400),
                               rng.uniform(0.0, float(g.depth[-1]) + 10.0, 400),
                               rng.uniform(g.z0 - 300, g.z_max + 300, 400)])
        xyz[:50, 0] = g.x0 + rng.integers(0, g.nx, 50) * g.dx       # on the nodes
        xyz[:50, 2] = g.z0 + rng.integers(0, g.ny, 50) * g.dz
        for a, b in zip(ts[:-1], ts[1:]):
            inside = np.concatenate([[a], rng.uniform(a, b, 6)])
            got = _currents_from_parts(g, xyz, float(inside[3]), inside)
            want = G.sample_currents(g, np.tile(xyz, (inside.size, 1)),
                                     np.repeat(inside, len(xyz))).reshape(got.shape)
            assert (np.abs(want) > 0.0).mean() > 0.5
            np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
        # the last time of the axis belongs to the last interval (weight 1)
        got = _currents_from_parts(g, xyz, float(ts[-1]), ts[-1:])
        want = G.sample_currents(g, xyz, np.full(len(xyz), ts[-1])).reshape(got.shape)
        np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
