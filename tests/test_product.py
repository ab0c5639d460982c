"""The merged product (contracts §2), its metadata, summary and Fig. 3."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from oneocean import __version__
from oneocean.errors import DataError
from oneocean.reporting.figures import plot_current_field
from oneocean.io import config_hash, dataset_content_hash, sha256_file
from oneocean.product.build import (bilinear_plan, build_product, netcdf_encoding, product_config,
                              regrid_bilinear, summarise_product, write_netcdf_atomic)
from oneocean.sources import fetch_bathymetry, fetch_currents
from oneocean.sources.synthetic import make_bathymetry, make_currents
from oneocean.vocab import CF, VARIANTS

CONFIG = Path(__file__).parents[1] / "config" / "config.yaml"


def small_config() -> dict:
    """Default region at 0.004 deg, 2-hourly over 12 h, three depth levels."""
    with open(CONFIG) as fh:
        cfg = yaml.safe_load(fh)
    cfg["region"]["time"] = {"start": "2025-01-01T00:00:00", "end": "2025-01-01T12:00:00"}
    cfg["region"]["max_depth_m"] = 40.0
    cfg["synthetic"].update(resolution_deg=0.004, time_step_hours=2.0,
                            depths_m=[0.5, 10.0, 40.0])
    cfg["variants"] = {
        "tiny": {"extent_fraction": 0.5, "resolution_deg": 0.008, "hours": 6,
                 "max_depth_m": 10.0},
        "scene": {"extent_fraction": 0.8, "resolution_deg": 0.003, "hours": 8,
                  "max_depth_m": 40.0},
        "public": {"extent_fraction": 1.0, "resolution_deg": 0.004, "hours": 12,
                   "max_depth_m": 40.0},
    }
    return cfg


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """Canonical inputs via the fetch stage, and the three variant products."""
    root = tmp_path_factory.mktemp("product")
    cfg = small_config()
    cur, bat = root / "currents.nc", root / "bathymetry.nc"
    fetch_currents(cfg, cur, root / "cache")
    fetch_bathymetry(cfg, bat, root / "cache")
    for v in VARIANTS:
        build_product(cur, bat, cfg, v, root / v / "product.nc", root / v / "metadata.json")
    return {"root": root, "cfg": cfg, "currents": cur, "bathymetry": bat}


def _open(built, variant):
    return xr.open_dataset(built["root"] / variant / "product.nc")


def _schema(ds):
    return {
        "vars": {n: (v.dims, str(v.dtype), sorted(v.attrs)) for n, v in ds.data_vars.items()},
        "coords": {n: (v.dims, str(v.dtype), sorted(v.attrs)) for n, v in ds.coords.items()},
        "attrs": sorted(ds.attrs),
    }


def test_schema_identical_across_variants_and_per_contract(built):
    schemas = []
    for v in VARIANTS:
        with _open(built, v) as ds:
            schemas.append(_schema(ds))
            assert ds["u"].dims == ("time", "depth", "latitude", "longitude")
            assert ds["u_tide"].dims == ("time", "latitude", "longitude")
            assert ds["elevation"].dims == ("latitude", "longitude")
            assert ds["valid_mask"].dims == ("depth", "latitude", "longitude")
            assert ds["land_mask"].dtype == np.int8 and ds["valid_mask"].dtype == np.int8
            assert ds["u"].dtype == np.float32
            assert ds["time"].dtype == np.dtype("datetime64[ns]")
            for c in ("time", "depth", "latitude", "longitude"):
                assert np.all(np.diff(ds[c].values.astype(np.int64 if c == "time" else float))
                              > 0), c
            assert -180 <= ds["longitude"].min() and ds["longitude"].max() <= 180
            spacing = np.diff(ds["longitude"].values)
            np.testing.assert_allclose(spacing, spacing[0], rtol=1e-6)
    assert schemas[0] == schemas[1] == schemas[2]


def test_cf_attributes(built):
    with _open(built, "scene") as ds:
        assert ds.attrs["Conventions"] == "CF-1.11"
        for name in ("u", "v", "u_tide", "v_tide", "elevation", "land_mask", "valid_mask"):
            assert ds[name].attrs["standard_name"] == CF[name], name
            assert "units" in ds[name].attrs and "long_name" in ds[name].attrs
        assert ds["u"].attrs["units"] == "m s-1"
        assert ds["elevation"].attrs["positive"] == "up"
        assert ds["depth"].attrs["positive"] == "down"
        assert ds["latitude"].attrs["units"] == "degrees_north"
        assert ds["longitude"].attrs["units"] == "degrees_east"
        assert ds["time"].encoding["units"].startswith("seconds since 1970-01-01")
        assert "history" not in ds.attrs


def test_provenance_attributes(built):
    cfg = built["cfg"]
    with _open(built, "tiny") as ds:
        assert ds.attrs["source"] == "synthetic"
        assert "SYNTHETIC" in ds.attrs["title"]
        assert ds.attrs["region"] == cfg["region"]["name"] and ds.attrs["variant"] == "tiny"
        assert ds.attrs["oneocean_version"] == __version__
        assert ds.attrs["config_hash"] == config_hash(product_config(cfg, "tiny"))
        assert json.loads(ds.attrs["config"])["variant"]["resolution_deg"] == 0.008
        assert isinstance(json.loads(ds.attrs["source_files"]), list)
        assert json.loads(ds.attrs["input_files"]) == [str(built["currents"]),
                                                       str(built["bathymetry"])]
        assert int(ds.attrs["has_tide"]) == 1
        assert ds.attrs["synthetic_seed"] == cfg["synthetic"]["seed"]


def test_variant_settings_applied(built):
    cfg = built["cfg"]
    bbox = cfg["region"]["bbox"]
    for v in VARIANTS:
        vc = cfg["variants"][v]
        with _open(built, v) as ds:
            lon, lat = ds["longitude"].values, ds["latitude"].values
            np.testing.assert_allclose(np.diff(lon), vc["resolution_deg"], atol=1e-9)
            width = vc["extent_fraction"] * (bbox["east"] - bbox["west"])
            assert width - vc["resolution_deg"] < lon[-1] - lon[0] <= width + 1e-9
            assert 0.5 * (lon[0] + lon[-1]) == pytest.approx(0.5 * (bbox["west"]
                                                                   + bbox["east"]))
            assert 0.5 * (lat[0] + lat[-1]) == pytest.approx(0.5 * (bbox["south"]
                                                                   + bbox["north"]))
            assert ds.sizes["time"] == vc["hours"] // 2 + 1          # 2-hourly source
            assert ds["depth"].values.max() <= vc["max_depth_m"]


def test_land_mask_from_bathymetry_and_current_mask_from_currents(built):
    with _open(built, "scene") as ds:
        elev = ds["elevation"].values
        np.testing.assert_array_equal(ds["land_mask"].values == 1, elev >= 0)
        assert 0.1 < ds["land_mask"].values.mean() < 0.6
        assert (elev >= 0).any() and (elev < 0).any()
        any_finite = np.isfinite(ds["u"].values).any(axis=(0, 1))
        assert ds["current_mask"].dtype == np.int8
        assert ds["current_mask"].dims == ("latitude", "longitude")
        np.testing.assert_array_equal(ds["current_mask"].values == 1, any_finite)
        np.testing.assert_array_equal(ds["current_mask"].values == 1,
                                      (ds["valid_mask"].values == 1).any(axis=0))
        assert not ((ds["current_mask"] == 1) & (ds["land_mask"] == 1)).any()
        assert ds["current_mask"].attrs["flag_meanings"] == "no_current current_defined"


def test_valid_mask_consistent_with_nans(built):
    with _open(built, "public") as ds:
        valid = ds["valid_mask"].values == 1
        for name in ("u", "v"):
            finite_all = np.isfinite(ds[name].values).all(axis=0)
            any_finite = np.isfinite(ds[name].values).any(axis=0)
            np.testing.assert_array_equal(valid, finite_all)
            np.testing.assert_array_equal(valid, any_finite)       # NaN exactly where invalid
        h = -ds["elevation"].values
        depth = ds["depth"].values[:, None, None]
        assert not (valid & (depth > h[None])).any()                # nothing below the seafloor
        assert not (valid & (ds["land_mask"].values == 1)[None]).any()
        tide_finite = np.isfinite(ds["u_tide"].values).all(axis=0)
        assert not (tide_finite & (ds["land_mask"].values == 1)).any()


def test_currents_and_tide_kept_separate(built):
    """On the public grid the product nodes are source nodes: u equals the source u exactly."""
    src = xr.open_dataset(built["currents"])
    with _open(built, "public") as ds:
        s = src.sel(time=ds["time"], depth=ds["depth"]).sel(
            latitude=ds["latitude"], longitude=ds["longitude"], method="nearest")
        valid = ds["valid_mask"].values == 1
        for name in ("u", "v"):
            np.testing.assert_array_equal(ds[name].values[:, valid], s[name].values[:, valid])
        water = ds["land_mask"].values == 0
        np.testing.assert_array_equal(ds["u_tide"].values[:, water], s["u_tide"].values[:, water])
        assert not np.allclose(ds["u"].values[:, valid], (s["u"] + s["u_tide"]).values[:, valid])
    src.close()


def test_regrid_reproduces_linear_field_and_follows_nan_rule():
    lat, lon = np.linspace(50.0, 50.5, 11), np.linspace(-4.0, -3.0, 21)
    tlat, tlon = np.linspace(50.013, 50.487, 17), np.linspace(-3.99, -3.01, 29)
    field = 0.3 + 2.0 * lon[None, :] - 1.5 * lat[:, None]
    py, px = bilinear_plan(lat, tlat), bilinear_plan(lon, tlon)
    out = regrid_bilinear(field, np.ones(field.shape, bool), py, px)
    np.testing.assert_allclose(out, 0.3 + 2.0 * tlon[None, :] - 1.5 * tlat[:, None],
                               atol=1e-12)
    # One invalid node: targets mostly weighted on it become NaN, others renormalise.
    valid = np.ones(field.shape, bool)
    valid[5, 10] = False
    field2 = np.where(valid, field, np.nan)
    pyy, pxx = bilinear_plan(lat, np.array([lat[5] + 0.01, lat[5] + 0.04])), \
        bilinear_plan(lon, np.array([lon[10] + 0.005, lon[10] + 0.04]))
    res = regrid_bilinear(field2, valid, pyy, pxx)
    assert np.isnan(res[0, 0])                              # 64 % of the weight on the NaN node
    assert np.isfinite(res[1, 1])
    corners = field[5:7, 10:12]
    wy, wx = pyy[2][1], pxx[2][1]
    w = np.array([[(1 - wy) * (1 - wx), (1 - wy) * wx], [wy * (1 - wx), wy * wx]])
    w[0, 0] = 0.0
    assert res[1, 1] == pytest.approx((w * corners).sum() / w.sum())
    with pytest.raises(DataError, match="outside"):
        bilinear_plan(lat, np.array([50.6]))


def test_build_reproduces_linear_currents_exactly(tmp_path):
    cfg = small_config()
    cur = make_currents(cfg).compute()
    lon, lat = cur["longitude"], cur["latitude"]
    lin_u = 0.1 + 2.0 * (lon + 4.4) - 3.0 * (lat - 50.25)
    lin_v = -0.2 + 1.0 * (lat - 50.25) + 0.0 * lon
    for name, lin in (("u", lin_u), ("v", lin_v)):
        plane = lin.transpose("latitude", "longitude").values.astype(np.float32)
        cur[name] = (cur[name].dims, np.broadcast_to(plane, cur[name].shape).copy(),
                     cur[name].attrs)
    bat = make_bathymetry(cfg).compute()
    bat["elevation"][:] = -500.0
    write_netcdf_atomic(cur, tmp_path / "c.nc", netcdf_encoding(cur))
    write_netcdf_atomic(bat, tmp_path / "b.nc", netcdf_encoding(bat))
    cfg["variants"]["scene"].update(extent_fraction=0.77, resolution_deg=0.0031)
    build_product(tmp_path / "c.nc", tmp_path / "b.nc", cfg, "scene", tmp_path / "p.nc",
                  tmp_path / "m.json")
    with xr.open_dataset(tmp_path / "p.nc") as ds:
        assert (ds["valid_mask"] == 1).all()
        assert (ds["land_mask"] == 0).all()
        want_u = 0.1 + 2.0 * (ds["longitude"] + 4.4) - 3.0 * (ds["latitude"] - 50.25)
        want_v = -0.2 + 1.0 * (ds["latitude"] - 50.25) + 0.0 * ds["longitude"]
        np.testing.assert_allclose(ds["u"].values, np.broadcast_to(
            want_u.transpose("latitude", "longitude").values, ds["u"].shape), atol=2e-6)
        np.testing.assert_allclose(ds["v"].values, np.broadcast_to(
            want_v.transpose("latitude", "longitude").values, ds["v"].shape), atol=2e-6)
        np.testing.assert_allclose(ds["elevation"].values, -500.0)
    # A shallower sea floor (15 m) than the currents' levels masks the 40 m level everywhere.
    bat["elevation"][:] = -15.0
    write_netcdf_atomic(bat, tmp_path / "b15.nc", netcdf_encoding(bat))
    build_product(tmp_path / "c.nc", tmp_path / "b15.nc", cfg, "scene", tmp_path / "p15.nc",
                  tmp_path / "m15.json")
    with xr.open_dataset(tmp_path / "p15.nc") as ds:
        assert ds["depth"].values.tolist() == [0.5, 10.0, 40.0]
        assert (ds["valid_mask"][:2] == 1).all() and (ds["valid_mask"][2] == 0).all()
        assert np.isnan(ds["u"][:, 2].values).all() and np.isfinite(ds["u"][:, :2].values).all()


def test_reruns_are_byte_identical(built, tmp_path):
    cfg = built["cfg"]
    a, b = tmp_path / "a.nc", tmp_path / "b.nc"
    build_product(built["currents"], built["bathymetry"], cfg, "tiny", a, tmp_path / "a.json")
    build_product(built["currents"], built["bathymetry"], cfg, "tiny", b, tmp_path / "b.json")
    assert sha256_file(a) == sha256_file(b) == sha256_file(built["root"] / "tiny/product.nc")
    with xr.open_dataset(a) as da_, xr.open_dataset(b) as db_:
        assert dataset_content_hash(da_) == dataset_content_hash(db_)
    ma, mb = (json.loads(p.read_text()) for p in (tmp_path / "a.json", tmp_path / "b.json"))
    ma["product"].pop("path"), mb["product"].pop("path")
    assert ma == mb


def test_metadata_json(built):
    meta = json.loads((built["root"] / "scene" / "metadata.json").read_text())
    path = built["root"] / "scene" / "product.nc"
    assert meta["product"]["sha256"] == sha256_file(path)
    with xr.open_dataset(path) as ds:
        assert meta["product"]["content_hash"] == dataset_content_hash(ds)
        assert meta["grid"]["nt"] == ds.sizes["time"] == meta["time_coverage"]["count"]
        assert meta["grid"]["ny"] == ds.sizes["latitude"]
        assert meta["depth_levels_m"] == ds["depth"].values.tolist()
    assert meta["time_coverage"]["start"] == "2025-01-01T00:00:00"
    assert meta["time_coverage"]["end"] == "2025-01-01T08:00:00"
    assert meta["settings"]["variant"] == built["cfg"]["variants"]["scene"]
    assert meta["source_kinds"] == {"currents": "synthetic", "bathymetry": "synthetic",
                                    "tides": "synthetic"}
    s = meta["summary"]
    assert 0.0 < s["mean_speed_ms"] < s["max_speed_ms"] < 2.0
    assert s["max_total_speed_ms"] > s["max_speed_ms"]
    assert s["max_tide_speed_ms"] > 1.0
    assert 0.4 < s["ocean_fraction"] < 0.9


def test_summarise_product_matches_the_data(built):
    path = built["root"] / "public" / "product.nc"
    s = summarise_product(path)
    with xr.open_dataset(path) as ds:
        u, v = ds["u"].isel(depth=0).values, ds["v"].isel(depth=0).values
        sp = np.hypot(u.astype(float), v.astype(float))
        assert s["mean_speed_ms"] == pytest.approx(np.nanmean(sp))
        assert s["max_speed_ms"] == pytest.approx(np.nanmax(sp))
        tot = np.hypot(u + ds["u_tide"].values, v + ds["v_tide"].values)
        assert s["max_total_speed_ms"] == pytest.approx(np.nanmax(tot), rel=1e-6)
        assert s["ocean_fraction"] == pytest.approx(1.0 - ds["land_mask"].values.mean())
        assert s["current_fraction"] == pytest.approx(ds["current_mask"].values.mean())
        assert 0.0 < s["current_fraction"] <= s["ocean_fraction"]
        assert (s["ny"], s["nx"], s["n_depths"]) == (ds.sizes["latitude"],
                                                     ds.sizes["longitude"], ds.sizes["depth"])
    assert s["extent"]["west"] == pytest.approx(built["cfg"]["region"]["bbox"]["west"])
    assert s["source"] == "synthetic" and s["time_end"] == "2025-01-01T12:00:00"


def _no_leftovers(folder: Path):
    return [p.name for p in folder.iterdir()] if folder.exists() else []


@pytest.mark.parametrize("change, match", [
    (lambda c: c["region"]["time"].update(start="2026-03-01T00:00:00"), "no time step"),
    (lambda c: c["region"].update(bbox={"west": 10.0, "east": 10.4, "south": 50.1,
                                        "north": 50.4}), "outside"),
    (lambda c: c["variants"]["tiny"].update(max_depth_m=0.1), "no depth level"),
])
def test_variant_outside_the_data_raises_and_leaves_nothing(built, tmp_path, change, match):
    cfg = copy.deepcopy(built["cfg"])
    change(cfg)
    out = tmp_path / "out"
    with pytest.raises(DataError, match=match) as err:
        build_product(built["currents"], built["bathymetry"], cfg, "tiny", out / "p.nc",
                      out / "m.json")
    assert "\n" not in str(err.value)
    assert _no_leftovers(out) == []


def test_all_land_raises_and_leaves_nothing(built, tmp_path):
    bat = make_bathymetry(built["cfg"]).compute()
    bat["elevation"][:] = 25.0
    write_netcdf_atomic(bat, tmp_path / "land.nc", netcdf_encoding(bat))
    out = tmp_path / "out"
    with pytest.raises(DataError, match="no valid"):
        build_product(built["currents"], tmp_path / "land.nc", built["cfg"], "tiny",
                      out / "p.nc", out / "m.json")
    assert _no_leftovers(out) == []


def test_figure_png_is_written_byte_identically(built, tmp_path):
    product = built["root"] / "tiny" / "product.nc"
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    plot_current_field(product, a, pitch_deg=25, azimuth_deg=45, depth_m=0.0)
    plot_current_field(product, b, pitch_deg=25, azimuth_deg=45, depth_m=0.0)
    assert a.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert a.stat().st_size > 20_000
    assert a.read_bytes() == b.read_bytes()
    plot_current_field(product, b, pitch_deg=40, azimuth_deg=-60, depth_m=10.0)
    assert a.read_bytes() != b.read_bytes()
    assert b"Software" not in a.read_bytes()[:2000]
