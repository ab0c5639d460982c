"""Grid export (contracts §3) and temporal export (contracts §4)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from oneocean.engine import grid as G
from oneocean.errors import DataError
from oneocean.product.exports import (default_point, export_grid, export_temporal, metres_per_degree,
                              point_weights)
from oneocean.io import sha256_file
from oneocean.product.build import build_product
from oneocean.sources import fetch_bathymetry, fetch_currents

CONFIG = Path(__file__).parents[1] / "config" / "config.yaml"
META = {"region": "test_coast", "variant": "scene"}


def small_config() -> dict:
    with open(CONFIG) as fh:
        cfg = yaml.safe_load(fh)
    cfg["region"]["time"] = {"start": "2025-01-01T00:00:00", "end": "2025-01-01T06:00:00"}
    cfg["region"]["max_depth_m"] = 40.0
    cfg["synthetic"].update(resolution_deg=0.004, time_step_hours=1.0,
                            depths_m=[0.5, 10.0, 40.0])
    cfg["variants"]["scene"] = {"extent_fraction": 0.8, "resolution_deg": 0.005, "hours": 6,
                                "max_depth_m": 40.0}
    return cfg


@pytest.fixture(scope="module")
def product(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("exports")
    cfg = small_config()
    fetch_currents(cfg, root / "c.nc", root / "cache")
    fetch_bathymetry(cfg, root / "b.nc", root / "cache")
    build_product(root / "c.nc", root / "b.nc", cfg, "scene", root / "product.nc",
                  root / "metadata.json")
    return root / "product.nc"


@pytest.fixture(scope="module")
def grid(product):
    out = product.parent / "grid.npz"
    export_grid(product, out, META)
    with np.load(out) as z:
        return {k: z[k] for k in z.files}


GRID_SPEC = {  # key: (dtype, ndim)
    "u": ("float32", 4), "v": ("float32", 4), "u_tide": ("float32", 3), "v_tide": ("float32", 3),
    "has_tide": ("int8", 0), "time_s": ("float64", 1), "time0_unix_s": ("float64", 0),
    "depth": ("float64", 1), "lat": ("float64", 1), "lon": ("float64", 1),
    "x0_m": ("float64", 0), "dx_m": ("float64", 0), "z0_m": ("float64", 0),
    "dz_m": ("float64", 0), "origin_lat": ("float64", 0), "origin_lon": ("float64", 0),
    "m_per_deg_lat": ("float64", 0), "m_per_deg_lon": ("float64", 0),
    "elevation": ("float32", 2), "land_mask": ("float32", 2), "valid_mask": ("uint8", 3),
    "current_mask": ("uint8", 2), "meta_json": ("U", 0),
}


def test_grid_keys_dtypes_shapes(grid, product):
    assert set(grid) == set(GRID_SPEC)
    for key, (dtype, ndim) in GRID_SPEC.items():
        assert grid[key].ndim == ndim, key
        if dtype == "U":
            assert grid[key].dtype.kind == "U"
        else:
            assert grid[key].dtype == np.dtype(dtype), key
    with xr.open_dataset(product) as ds:
        nt, nz, ny, nx = (ds.sizes[d] for d in ("time", "depth", "latitude", "longitude"))
        assert grid["u"].shape == (nt, nz, ny, nx) and grid["u_tide"].shape == (nt, ny, nx)
        assert grid["valid_mask"].shape == (nz, ny, nx)
        assert nt == 7 and nz == 3
        valid = ds["valid_mask"].values == 1
        current = valid.any(axis=0)
        np.testing.assert_array_equal(grid["valid_mask"] == 1, valid)
        np.testing.assert_array_equal(grid["current_mask"] == 1, current)
        np.testing.assert_array_equal(grid["current_mask"], ds["current_mask"].values)
        np.testing.assert_array_equal(grid["u"][:, valid], ds["u"].values[:, valid])
        # below a column's deepest valid level: that level's value (hold); no current: 0
        deepest = nz - 1 - np.argmax(valid[::-1], axis=0)                  # (ny, nx)
        held = 0
        for k in range(nz):
            below = current & (k > deepest)
            src = np.take_along_axis(ds["u"].values, deepest[None, None].repeat(nt, 0),
                                     axis=1)[:, 0]
            np.testing.assert_array_equal(grid["u"][:, k][:, below], src[:, below])
            held += int(below.sum())
        assert held > 100                              # the 10 m and 40 m levels hold values
        assert (grid["u"][..., ~current] == 0).all() and (grid["v"][..., ~current] == 0).all()
        assert np.isfinite(grid["u"]).all() and np.isfinite(grid["v"]).all()
        assert np.isfinite(grid["u_tide"]).all() and int(grid["has_tide"]) == 1
        np.testing.assert_array_equal(grid["u_tide"][:, current],
                                      ds["u_tide"].values[:, current])
        assert (grid["u_tide"][:, ~current] == 0).all()
        t = ds["time"].values.astype("datetime64[ns]").astype(np.int64) * 1e-9
        assert grid["time0_unix_s"] == t[0]
        np.testing.assert_array_equal(grid["time_s"], t - t[0])
        np.testing.assert_array_equal(grid["land_mask"], ds["land_mask"].values)
        # land from the bathymetry only
        np.testing.assert_array_equal(grid["land_mask"] == 1, ds["elevation"].values >= 0)
    assert np.all(np.diff(grid["time_s"]) > 0) and np.all(np.diff(grid["depth"]) > 0)


def test_grid_metres_mapping_round_trip(grid):
    lat, lon = grid["lat"], grid["lon"]
    assert grid["origin_lat"] == pytest.approx(0.5 * (lat[0] + lat[-1]))
    assert grid["origin_lon"] == pytest.approx(0.5 * (lon[0] + lon[-1]))
    m_lat, m_lon = metres_per_degree(float(grid["origin_lat"]))
    assert grid["m_per_deg_lat"] == m_lat and grid["m_per_deg_lon"] == m_lon
    assert 111_000 < m_lat < 111_400 and m_lon == pytest.approx(m_lat * np.cos(np.deg2rad(
        float(grid["origin_lat"]))))
    x = grid["x0_m"] + np.arange(lon.size) * grid["dx_m"]
    z = grid["z0_m"] + np.arange(lat.size) * grid["dz_m"]
    np.testing.assert_allclose(grid["origin_lon"] + x / grid["m_per_deg_lon"], lon, atol=1e-9)
    np.testing.assert_allclose(grid["origin_lat"] + z / grid["m_per_deg_lat"], lat, atol=1e-9)
    assert x[0] < 0 < x[-1] and z[0] < 0 < z[-1]
    assert x[0] == pytest.approx(-x[-1]) and z[0] == pytest.approx(-z[-1])
    assert grid["dx_m"] == pytest.approx(0.005 * m_lon)


def test_grid_meta_records_source(grid, product):
    meta = json.loads(str(grid["meta_json"]))
    assert meta["source_path"] == str(product)
    assert meta["source_sha256"] == sha256_file(product)
    assert meta["region"] == "synthetic_coast" and meta["variant"] == "scene"
    assert meta["extraction"]["time_index"] == [0, grid["time_s"].size]
    assert meta["extraction"]["depth_m"] == grid["depth"].tolist()


def test_exports_rerun_byte_identical(product, tmp_path):
    for name in ("a", "b"):
        export_grid(product, tmp_path / f"grid_{name}.npz", META)
        export_temporal(product, tmp_path / f"temporal_{name}.npz", None, None, 5.0, META)
    for kind in ("grid", "temporal"):
        first, second = (tmp_path / f"{kind}_{n}.npz" for n in ("a", "b"))
        assert first.read_bytes() == second.read_bytes()


def _temporal(product, tmp_path, lat, lon, depth):
    out = tmp_path / "t.npz"
    export_temporal(product, out, lat, lon, depth, META)
    with np.load(out) as z:
        return {k: z[k] for k in z.files}


def test_temporal_keys_and_decoded_time(product, tmp_path):
    t = _temporal(product, tmp_path, None, None, 0.5)
    t_default = _temporal(product, tmp_path, None, None, None)   # null = the first level
    assert float(t_default["depth"]) == 0.5
    for k in ("u", "v", "u_tide", "v_tide", "time_s"):
        np.testing.assert_array_equal(t_default[k], t[k])
    assert set(t) == {"time", "time_s", "u", "v", "u_tide", "v_tide", "lat", "lon", "depth",
                      "indices_json", "meta_json"}
    assert t["time"].dtype == np.dtype("datetime64[s]")
    with xr.open_dataset(product) as ds:
        np.testing.assert_array_equal(t["time"], ds["time"].values.astype("datetime64[s]"))
    assert str(t["time"][0]) == "2025-01-01T00:00:00"
    np.testing.assert_array_equal(t["time_s"], np.arange(7) * 3600.0)
    for k in ("u", "v", "u_tide", "v_tide"):
        assert t[k].dtype == np.float64 and t[k].shape == (7,) and np.isfinite(t[k]).all()
    assert t["lat"].shape == () and float(t["depth"]) == 0.5
    idx = json.loads(str(t["indices_json"]))
    assert {"latitude_index", "longitude_index", "depth_index", "time_index"} <= set(idx)
    meta = json.loads(str(t["meta_json"]))
    assert meta["source_sha256"] == sha256_file(product)
    assert meta["point"]["depth_m"] == 0.5


def test_temporal_default_point_is_in_the_wettest_water(product):
    with xr.open_dataset(product) as ds:
        lat, lon = default_point(ds)
        j = int(np.flatnonzero(ds["latitude"].values == lat)[0])
        i = int(np.flatnonzero(ds["longitude"].values == lon)[0])
        assert (ds["valid_mask"].values[:, j, i] == 1).all()


def test_temporal_interpolation(product, tmp_path):
    with xr.open_dataset(product) as ds:
        valid = (ds["valid_mask"].values == 1).all(axis=0)
        block = valid[:-1, :-1] & valid[1:, :-1] & valid[:-1, 1:] & valid[1:, 1:]
        j, i = (int(a[len(a) // 2]) for a in np.nonzero(block))
        lat, lon = ds["latitude"].values, ds["longitude"].values
        u = ds["u"].values.astype(float)
        # At a node and level: exactly the product value.
        t = _temporal(product, tmp_path, lat[j], lon[i], 10.0)
        np.testing.assert_allclose(t["u"], u[:, 1, j, i], rtol=0, atol=1e-12)
        # Cell centre, halfway between levels 0.5 m and 10 m: the mean of eight values.
        t = _temporal(product, tmp_path, 0.5 * (lat[j] + lat[j + 1]),
                      0.5 * (lon[i] + lon[i + 1]), 5.25)
        np.testing.assert_allclose(t["u"], u[:, 0:2, j:j + 2, i:i + 2].mean(axis=(1, 2, 3)),
                                   atol=1e-9)
        # Tide is depth-independent and separate.
        np.testing.assert_allclose(t["u_tide"], ds["u_tide"].values[:, j:j + 2, i:i + 2]
                                   .astype(float).mean(axis=(1, 2)), atol=1e-9)


def test_temporal_point_on_land_outside_or_below_seafloor_raises(product, tmp_path):
    with xr.open_dataset(product) as ds:
        j, i = (int(a[0]) for a in np.nonzero(ds["land_mask"].values == 1))
        lat, lon = float(ds["latitude"][j]), float(ds["longitude"][i])
        north = float(ds["latitude"].max()) + 0.1
    out = tmp_path / "t.npz"
    with pytest.raises(DataError, match="on land"):
        export_temporal(product, out, lat, lon, 0.5, META)
    with pytest.raises(DataError, match="outside"):
        export_temporal(product, out, north, lon, 0.5, META)
    with pytest.raises(DataError, match="below the deepest"):
        export_temporal(product, out, None, None, 500.0, META)
    with xr.open_dataset(product) as ds:
        h = -ds["elevation"].values
        shallow = (ds["current_mask"].values == 1) & (h > 12.0) & (h < 30.0)
        j, i = (int(a[0]) for a in np.nonzero(shallow))
        lat, lon = float(ds["latitude"][j]), float(ds["longitude"][i])
        floor = float(h[j, i])
    with pytest.raises(DataError, match="below the seafloor"):
        export_temporal(product, out, lat, lon, floor + 0.1, META)
    export_temporal(product, out, lat, lon, 0.5, META)                # the surface is fine
    export_temporal(product, out, lat, lon, floor - 0.1, META)        # above the bed: held
    assert list(tmp_path.iterdir()) == [out]


def test_point_weights_boundary_rules():
    """The NaN rule on a 3 x 3 grid: land, water without currents, a shallow column."""
    glat, glon, depth = np.array([0.0, 1.0, 2.0]), np.array([0.0, 1.0, 2.0]), np.array(
        [1.0, 10.0, 20.0])
    land = np.array([[0, 0, 1], [0, 0, 0], [0, 0, 0]])
    valid = np.ones((3, 3, 3), int)
    valid[:, 0, 2] = 0                 # land
    valid[:, 2, 2] = 0                 # water without currents (outside the coverage)
    valid[2, 1, 1] = 0                 # a shallow column: no 20 m level
    elev = np.full((3, 3), -30.0)
    elev[0, 2] = 5.0
    elev[1, 1] = -15.0
    pw = lambda la, lo, d: point_weights(glat, glon, depth, land, valid, la, lo, d,  # noqa
                                         "p", elevation=elev)
    # a cell with one corner without currents: three corners, renormalised (1/3 each here)
    r = pw(1.5, 1.5, 5.0)
    assert sorted((j, i) for j, i, _ in r["corner_weights"]) == [(1, 1), (1, 2), (2, 1)]
    assert [w for *_, w in r["corner_weights"]] == pytest.approx([1 / 3] * 3)
    assert r["tide_weights"] == r["corner_weights"] and r["current_weight"] == 0.75
    # below the shallow column's 10 m level it holds the 10 m value
    r = pw(1.0, 1.0, 14.0)
    assert r["depth_weights"] == {1: pytest.approx(0.6), 2: pytest.approx(0.4)}
    assert r["source_levels"] == {1: [1], 2: [1]}
    with pytest.raises(DataError, match="below the seafloor"):
        pw(1.0, 1.0, 16.0)
    # mostly water without currents: an error naming it (not "land")
    with pytest.raises(DataError, match="no current defined"):
        pw(1.9, 1.9, 5.0)
    with pytest.raises(DataError, match="on land"):
        pw(0.1, 1.9, 5.0)
    # depth: None = the first level; above it = the first level; within the last cell = last
    assert pw(0.5, 0.5, None)["depth_m"] == 1.0
    assert pw(0.5, 0.5, 0.2)["depth_weights"] == {0: 1.0}
    assert pw(0.5, 0.5, 24.9)["depth_weights"] == {2: 1.0}
    with pytest.raises(DataError, match="below the deepest level"):
        pw(0.5, 0.5, 25.1)
    # a single level at d stands for [0, 2d]: CMEMS's 0.494 m takes 0.5 m
    one = point_weights(glat, glon, np.array([0.494]), land, valid[:1], 0.5, 0.5, 0.5, "p")
    assert one["depth_weights"] == {0: 1.0}
    with pytest.raises(DataError, match="below the deepest level"):
        point_weights(glat, glon, np.array([0.494]), land, valid[:1], 0.5, 0.5, 1.0, "p")


def _cell_points(ds, rng):
    """Points (lat, lon, depth) next to land / water without currents, just above the
    seafloor, and in open water, where the temporal export is defined."""
    lat, lon = ds["latitude"].values, ds["longitude"].values
    depth = ds["depth"].values
    cm = ds["current_mask"].values == 1
    h = -ds["elevation"].values.astype(float)
    corners = cm[:-1, :-1].astype(int) + cm[1:, :-1] + cm[:-1, 1:] + cm[1:, 1:]
    pts = []
    for n_def, frac in ((3, (0.5, 0.5)), (2, None), (4, (0.37, 0.61))):
        js, is_ = np.nonzero(corners == n_def)
        for c in rng.choice(js.size, size=min(3, js.size), replace=False):
            j, i = int(js[c]), int(is_[c])
            if frac is None:            # two defined corners: a quarter cell off their edge
                sub = cm[j:j + 2, i:i + 2]
                fy = 0.25 if sub[0].all() else 0.75 if sub[1].all() else 0.5
                fx = 0.25 if sub[:, 0].all() else 0.75 if sub[:, 1].all() else 0.5
                if fy == fx == 0.5:
                    continue            # diagonal pair: exactly half the weight
            else:
                fy, fx = frac
            la = lat[j] + fy * (lat[j + 1] - lat[j])
            lo = lon[i] + fx * (lon[i + 1] - lon[i])
            w = np.array([[(1 - fy) * (1 - fx), (1 - fy) * fx], [fy * (1 - fx), fy * fx]])
            floor = float((w * h[j:j + 2, i:i + 2]).sum())
            if floor <= depth[0] + 0.2:
                continue
            # near the surface, between levels, and 0.1 m above the bed (within the levels)
            bottom = (depth[-1] + 0.4 * (depth[-1] - depth[-2]) if depth.size > 1
                      else 1.9 * depth[0])
            for d in (None, 0.5 * (depth[0] + depth[min(1, depth.size - 1)]),
                      min(floor - 0.1, bottom)):
                if d is None or d < floor - 0.05:
                    pts.append((float(la), float(lo), d))
    return pts


def check_engine_matches_temporal(product, tmp_path, min_points=10):
    """The engine's sample_current_data on the grid export equals the temporal export (u +
    tide at gain 1; g u + tide at gain 2) at points next to land, above the bed, in water."""
    grid_path = tmp_path / "grid_cmp.npz"
    export_grid(product, grid_path, META)
    g1 = G.load_grid(grid_path)
    g2 = G.with_forcing(g1, current_gain=2.0)
    rng = np.random.default_rng(5)
    with xr.open_dataset(product) as ds:
        pts = _cell_points(ds, rng)
    assert len(pts) >= min_points
    kinds = {"next_to_no_current": 0, "above_bed_held": 0}
    for la, lo, d in pts:
        t = _temporal(product, tmp_path, la, lo, d)
        idx = json.loads(str(t["indices_json"]))
        kinds["next_to_no_current"] += idx["current_weight"] < 1.0
        levels = {k: v for k, v in idx["source_levels"].items()}
        kinds["above_bed_held"] += any(int(k) != s for k, v in levels.items() for s in v)
        x, z = G.lonlat_to_world(g1, lo, la)
        y = float(t["depth"])
        for k, ts in enumerate(t["time_s"]):
            for gain, gr in ((1.0, g1), (2.0, g2)):
                ce, cn = G.sample_current_data(gr, float(x), y, float(z), float(ts))
                assert ce == pytest.approx(gain * t["u"][k] + t["u_tide"][k], abs=2e-6)
                assert cn == pytest.approx(gain * t["v"][k] + t["v_tide"][k], abs=2e-6)
    return kinds


def test_engine_sampling_equals_the_temporal_export(product, tmp_path):
    kinds = check_engine_matches_temporal(product, tmp_path)
    assert kinds["next_to_no_current"] >= 3 and kinds["above_bed_held"] >= 3
