"""Grid export (contracts §3) and temporal export (contracts §4)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from oneocean.errors import DataError
from oneocean.exports import default_point, export_grid, export_temporal, metres_per_degree
from oneocean.io import sha256_file
from oneocean.product import build_product
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
    "meta_json": ("U", 0),
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
        np.testing.assert_array_equal(grid["valid_mask"] == 1, valid)
        np.testing.assert_array_equal(grid["u"][:, valid], ds["u"].values[:, valid])
        assert (grid["u"][:, ~valid] == 0).all() and (grid["v"][:, ~valid] == 0).all()
        assert np.isfinite(grid["u_tide"]).all() and int(grid["has_tide"]) == 1
        water = ds["land_mask"].values == 0
        np.testing.assert_array_equal(grid["u_tide"][:, water], ds["u_tide"].values[:, water])
        t = ds["time"].values.astype("datetime64[ns]").astype(np.int64) * 1e-9
        assert grid["time0_unix_s"] == t[0]
        np.testing.assert_array_equal(grid["time_s"], t - t[0])
        np.testing.assert_array_equal(grid["land_mask"], ds["land_mask"].values)
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
        shallow = (ds["valid_mask"].values[0] == 1) & (ds["valid_mask"].values[-1] == 0)
        j, i = (int(a[0]) for a in np.nonzero(shallow))
        lat, lon = float(ds["latitude"][j]), float(ds["longitude"][i])
        bottom = float(ds["depth"][-1])
    with pytest.raises(DataError, match="below the seafloor"):
        export_temporal(product, out, lat, lon, bottom, META)
    export_temporal(product, out, lat, lon, 0.5, META)                # the surface is fine
    assert list(tmp_path.iterdir()) == [out]
