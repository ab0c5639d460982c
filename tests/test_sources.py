"""Source readers on the real fixtures (no network): names, axes, units, dispatch, caching."""

from __future__ import annotations

import json
import shutil
import sys
import types
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

import oneocean.sources as sources
from oneocean.io import sha256_file
from oneocean.sources import (fetch_bathymetry, fetch_currents, open_bathymetry, open_currents,
                              read_bathymetry_file, read_currents_file)
from oneocean.sources import gebco as gebco_source

CURRENTS = "cmems_glo12_currents_P1D_w-1_e10_s50_n55_2025-01-01.nc"
ETOPO = "etopo2022_30s_w2_e3_s51_n53.nc"
GEBCO = "gebco_2020_n56.3_s55.2_w12.2_e13.1.nc"
NORTH_SEA = {"west": 2.0, "east": 3.0, "south": 51.0, "north": 53.0}
ORESUND = {"west": 12.5, "east": 12.8, "south": 55.5, "north": 55.9}
WINDOW = {"start": "2025-01-01T00:00:00", "end": "2025-01-02T00:00:00"}


def assert_canonical_axes(ds: xr.Dataset) -> None:
    for dim in ("longitude", "latitude", "depth", "time"):
        if dim in ds.coords:
            assert np.all(np.diff(ds[dim].values) > np.diff(ds[dim].values).dtype.type(0)), dim
    assert ds["longitude"].attrs["units"] == "degrees_east"
    assert ds["latitude"].attrs["units"] == "degrees_north"
    assert -180 <= ds["longitude"].min() and ds["longitude"].max() <= 180


def assert_margin(values: np.ndarray, lo: float, hi: float) -> None:
    """The bbox edges lie strictly inside the outermost cells (one cell of margin)."""
    assert values[0] < lo <= values[1] and values[-2] <= hi < values[-1], (values, lo, hi)


@pytest.fixture
def north_sea_cfg(base_config, shared_data):
    cfg = base_config
    cfg["region"].update(name="southern_north_sea", bbox=dict(NORTH_SEA), time=dict(WINDOW),
                         max_depth_m=5.0)
    cfg["sources"].update(currents="files", bathymetry="files", tides=False)
    cfg["files"].update(currents=str(shared_data / CURRENTS), bathymetry=str(shared_data / ETOPO))
    return cfg


# ------------------------------------------------------------------ readers on the real files

def test_cmems_currents_file_reads_canonical(shared_data):
    path = shared_data / CURRENTS
    ds = read_currents_file(path)
    assert set(ds.data_vars) == {"u", "v"}
    assert ds["u"].dims == ("time", "depth", "latitude", "longitude")
    assert ds["u"].chunks is not None  # lazy, dask-backed
    assert ds["u"].dtype == np.float32 and ds["u"].attrs["units"] == "m s-1"
    assert ds["u"].attrs["standard_name"] == "eastward_sea_water_velocity"
    assert ds["v"].attrs["standard_name"] == "northward_sea_water_velocity"
    assert ds["time"].dtype == np.dtype("datetime64[ns]")
    assert ds["depth"].attrs["positive"] == "down"
    assert float(ds["depth"][0]) == pytest.approx(0.494, abs=1e-3)
    assert_canonical_axes(ds)
    nan_fraction = float(ds["u"].isel(time=0, depth=0).isnull().mean())
    assert 0.54 < nan_fraction < 0.58  # land: England, France, Benelux, Germany, Denmark
    speed = float(np.hypot(ds["u"], ds["v"]).max())
    assert 0.1 < speed < 5.0
    assert ds.attrs["source"] == "files"
    assert json.loads(ds.attrs["source_files"]) == [{"path": str(path),
                                                     "sha256": sha256_file(path)}]
    assert "uo" not in ds and "lat" not in ds.coords


def test_etopo_north_sea_has_land_and_sea(shared_data):
    ds = read_bathymetry_file(shared_data / ETOPO)
    assert list(ds.data_vars) == ["elevation"]
    assert ds["elevation"].dims == ("latitude", "longitude")
    assert ds["elevation"].attrs["units"] == "m" and ds["elevation"].attrs["positive"] == "up"
    assert_canonical_axes(ds)
    z = ds["elevation"].values
    assert (z > 0).mean() > 0.01 and (z < 0).mean() > 0.5  # the French/Belgian coast + the sea
    assert -100 < z.min() < -40 and 0 < z.max() < 100


def test_gebco_download_app_netcdf3(shared_data):
    ds = read_bathymetry_file(shared_data / GEBCO)
    assert ds["elevation"].dtype == np.float32  # int16 on disk
    assert float(ds["elevation"].min()) == -43.0 and float(ds["elevation"].max()) == 185.0
    assert_canonical_axes(ds)
    assert np.allclose(np.diff(ds["latitude"].values), 1 / 240)  # 15 arc-second cells
    assert float(ds["longitude"][0]) == pytest.approx(12.2 + 1 / 480)  # cell centres


def test_open_roundtrip_keeps_canonical_provenance(north_sea_cfg, tmp_path):
    out = tmp_path / "currents.nc"
    fetch_currents(north_sea_cfg, out, tmp_path / "cache")
    ds = open_currents(out)
    assert ds.attrs["source"] == "files" and ds["u"].chunks is not None
    again = tmp_path / "again.nc"
    north_sea_cfg["files"]["currents"] = str(out)
    fetch_currents(north_sea_cfg, again, tmp_path / "cache")
    assert json.loads(open_currents(again).attrs["source_files"])[0]["path"] == str(out)
    xr.testing.assert_equal(open_currents(again)[["u", "v"]], ds[["u", "v"]])


# ------------------------------------------------------------------ the files source

def test_files_source_north_sea(north_sea_cfg, tmp_path, shared_data):
    cur, bathy = tmp_path / "currents.nc", tmp_path / "bathymetry.nc"
    fetch_currents(north_sea_cfg, cur, tmp_path / "cache")
    fetch_bathymetry(north_sea_cfg, bathy, tmp_path / "cache")
    c, b = open_currents(cur), open_bathymetry(bathy)
    assert_margin(c["longitude"].values, 2.0, 3.0)
    assert_margin(c["latitude"].values, 51.0, 53.0)
    depth = c["depth"].values
    assert depth.size == 5 and depth[-2] <= 5.0 < depth[-1]  # first level deeper kept
    assert list(c["time"].values) == list(pd.to_datetime(["2025-01-01", "2025-01-02"]))
    assert c.attrs["Conventions"] == "CF-1.11" and c.attrs["source"] == "files"
    assert json.loads(b.attrs["source_files"])[0]["sha256"] == sha256_file(shared_data / ETOPO)
    # ETOPO land lies where CMEMS has no currents: interpolate elevation at the CMEMS nodes
    z = b["elevation"].interp(latitude=c["latitude"], longitude=c["longitude"]).values
    dry = c["u"].isel(time=0, depth=0).isnull().values
    inside = np.isfinite(z)
    assert dry[inside].any() and (~dry[inside]).any()
    assert np.nanmean(z[dry & inside]) > np.nanmean(z[~dry & inside]) + 10.0


def test_etopo_source(north_sea_cfg, tmp_path, shared_data):
    north_sea_cfg["sources"]["bathymetry"] = "etopo"
    north_sea_cfg["etopo"]["path"] = str(shared_data / ETOPO)
    out = tmp_path / "b.nc"
    fetch_bathymetry(north_sea_cfg, out, tmp_path / "cache")
    ds = open_bathymetry(out)
    assert ds.attrs["source"] == "etopo"
    assert ds["longitude"].values[0] < 2.005 and ds["longitude"].values[-1] > 2.995


# ------------------------------------------------------------------ cmems with subset patched

class FakeSubset:
    """Stands in for ``copernicusmarine.subset``: copies a prepared file to the output path."""

    def __init__(self, files: dict[str, Path]):
        self.files, self.calls = files, []

    def __call__(self, **kwargs):
        self.calls.append(kwargs)
        shutil.copyfile(self.files[kwargs["dataset_id"]],
                        Path(kwargs["output_directory"]) / kwargs["output_filename"])


@pytest.fixture
def cmems_cfg(north_sea_cfg, monkeypatch):
    monkeypatch.setenv("COPERNICUSMARINE_SERVICE_USERNAME", "user")
    monkeypatch.setenv("COPERNICUSMARINE_SERVICE_PASSWORD", "secret")
    north_sea_cfg["sources"]["currents"] = "cmems"
    north_sea_cfg["cmems"]["retry_wait_s"] = 0.0
    return north_sea_cfg


def test_cmems_request_and_cache(cmems_cfg, tmp_path, shared_data, monkeypatch):
    import copernicusmarine

    fake = FakeSubset({cmems_cfg["cmems"]["dataset_id"]: shared_data / CURRENTS})
    monkeypatch.setattr(copernicusmarine, "subset", fake)
    cache = tmp_path / "cache"
    fetch_currents(cmems_cfg, tmp_path / "a.nc", cache)
    assert len(fake.calls) == 1
    call = fake.calls[0]
    expected = {
        "dataset_id": "cmems_mod_glo_phy-cur_anfc_0.083deg_P1D-m", "dataset_version": None,
        "variables": ["uo", "vo"],
        "minimum_longitude": 2.0, "maximum_longitude": 3.0,
        "minimum_latitude": 51.0, "maximum_latitude": 53.0,
        "start_datetime": "2025-01-01T00:00:00", "end_datetime": "2025-01-02T00:00:00",
        "minimum_depth": 0.0, "maximum_depth": 5.0, "coordinates_selection_method": "outside",
    }
    assert {k: call[k] for k in expected} == expected
    assert call["overwrite"] is True and "skip_existing" not in call
    assert Path(call["output_directory"]) == cache and call["output_filename"].endswith(".nc")
    assert "credentials_file" not in call  # environment variables are used
    assert list(cache.glob(".*")) == []  # the temporary name was renamed

    ds = open_currents(tmp_path / "a.nc")
    assert ds.attrs["source"] == "cmems"
    assert json.loads(ds.attrs["request"]) == expected
    assert ds.attrs["dataset_id"] == expected["dataset_id"]
    assert ds.attrs["dataset_version"] == "default"
    assert ds.attrs["toolbox_version"] == copernicusmarine.__version__
    [record] = json.loads(ds.attrs["source_files"])
    assert Path(record["path"]).parent == cache
    assert record["sha256"] == sha256_file(shared_data / CURRENTS)
    assert_margin(ds["longitude"].values, 2.0, 3.0)
    assert ds["depth"].size == 5 and "u_tide" not in ds

    fetch_currents(cmems_cfg, tmp_path / "b.nc", cache)  # rerun: served from the cache
    assert len(fake.calls) == 1
    cmems_cfg["region"]["max_depth_m"] = 3.0  # a different request downloads again
    fetch_currents(cmems_cfg, tmp_path / "c.nc", cache)
    assert len(fake.calls) == 2 and fake.calls[1]["maximum_depth"] == 3.0


def _hourly_tides(shared_data: Path, path: Path) -> Path:
    """A toolbox-like hourly tide file (``utide``/``vtide``, one depth) on the GLO12 grid."""
    src = xr.open_dataset(shared_data / CURRENTS)
    times = pd.date_range("2025-01-01", "2025-01-02", freq="1h")
    phase = np.cos(2 * np.pi * np.arange(times.size) / 12.42)[:, None, None, None]
    surface = src[["uo", "vo"]].isel(time=[0], depth=[0])
    ds = xr.Dataset(
        {"utide": (("time", "depth", "latitude", "longitude"), phase * surface["uo"].values,
                   {"units": "m s-1"}),
         "vtide": (("time", "depth", "latitude", "longitude"), phase * surface["vo"].values,
                   {"units": "m s-1"})},
        coords={"time": times, "depth": surface["depth"].values,
                "latitude": src["latitude"].values, "longitude": src["longitude"].values})
    ds.to_netcdf(path)
    return path


def test_cmems_tides_second_subset(cmems_cfg, tmp_path, shared_data, monkeypatch):
    import copernicusmarine

    c = cmems_cfg["cmems"]
    fake = FakeSubset({c["dataset_id"]: shared_data / CURRENTS,
                       c["tide_dataset_id"]: _hourly_tides(shared_data, tmp_path / "t.nc")})
    monkeypatch.setattr(copernicusmarine, "subset", fake)
    cmems_cfg["sources"]["tides"] = True
    fetch_currents(cmems_cfg, tmp_path / "a.nc", tmp_path / "cache")
    tide_call = fake.calls[1]
    assert tide_call["dataset_id"] == c["tide_dataset_id"]
    assert tide_call["variables"] == ["utide", "vtide"] and "maximum_depth" not in tide_call
    ds = open_currents(tmp_path / "a.nc")
    assert ds["u_tide"].dims == ("time", "latitude", "longitude")
    assert ds["time"].size == 25  # hourly
    assert json.loads(ds.attrs["tide_request"])["dataset_id"] == c["tide_dataset_id"]
    plain = read_currents_file(shared_data / CURRENTS).sel(
        latitude=ds["latitude"], longitude=ds["longitude"], depth=ds["depth"])
    np.testing.assert_allclose(ds["u"].isel(time=0), plain["u"].isel(time=0), atol=1e-6,
                               equal_nan=True)
    np.testing.assert_allclose(ds["u"].isel(time=-1), plain["u"].isel(time=1), atol=1e-6,
                               equal_nan=True)
    mid = 0.5 * (plain["u"].isel(time=0) + plain["u"].isel(time=1))
    np.testing.assert_allclose(ds["u"].isel(time=12), mid, atol=1e-6, equal_nan=True)
    assert float(np.abs(ds["u_tide"]).max()) > 0.05


def test_cmems_uses_toolbox_credentials_file(cmems_cfg, tmp_path, shared_data, monkeypatch):
    import copernicusmarine

    for var in ("COPERNICUSMARINE_SERVICE_USERNAME", "COPERNICUSMARINE_SERVICE_PASSWORD",
                "COPERNICUSMARINE_CREDENTIALS_DIRECTORY"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    creds = tmp_path / ".copernicusmarine" / ".copernicusmarine-credentials"
    creds.parent.mkdir()
    creds.write_text("W2NyZWRlbnRpYWxzXQ==\n")
    fake = FakeSubset({cmems_cfg["cmems"]["dataset_id"]: shared_data / CURRENTS})
    monkeypatch.setattr(copernicusmarine, "subset", fake)
    fetch_currents(cmems_cfg, tmp_path / "a.nc", tmp_path / "cache")
    assert Path(fake.calls[0]["credentials_file"]) == creds


def test_cmems_retries_then_succeeds(cmems_cfg, tmp_path, shared_data, monkeypatch):
    import copernicusmarine

    fake = FakeSubset({cmems_cfg["cmems"]["dataset_id"]: shared_data / CURRENTS})

    def flaky(**kwargs):
        if not fake.calls:
            fake.calls.append(kwargs)
            (Path(kwargs["output_directory"]) / kwargs["output_filename"]).write_bytes(b"part")
            raise ConnectionError("connection reset")
        fake(**kwargs)

    monkeypatch.setattr(copernicusmarine, "subset", flaky)
    fetch_currents(cmems_cfg, tmp_path / "a.nc", tmp_path / "cache")
    assert len(fake.calls) == 2
    assert open_currents(tmp_path / "a.nc").attrs["source"] == "cmems"


# ------------------------------------------------------------------ gebco: remote and GeoTIFF

def test_gebco_remote_subset_is_cached(base_config, tmp_path, shared_data, monkeypatch):
    calls = []

    def fake_open(url):
        calls.append(url)
        return xr.open_dataset(shared_data / GEBCO)

    monkeypatch.setattr(gebco_source, "open_remote", fake_open)
    cfg = base_config
    cfg["region"]["bbox"] = dict(ORESUND)
    cfg["sources"]["bathymetry"] = "gebco"
    cfg["gebco"]["url"] = "https://example.org/erddap/griddap/GEBCO_2020"
    fetch_bathymetry(cfg, tmp_path / "a.nc", tmp_path / "cache")
    fetch_bathymetry(cfg, tmp_path / "b.nc", tmp_path / "cache")
    assert calls == [cfg["gebco"]["url"]]
    ds = open_bathymetry(tmp_path / "b.nc")
    assert ds.attrs["source"] == "gebco"
    assert json.loads(ds.attrs["request"])["url"] == cfg["gebco"]["url"]
    assert_margin(ds["longitude"].values, 12.5, 12.8)
    assert_margin(ds["latitude"].values, 55.5, 55.9)
    full = read_bathymetry_file(shared_data / GEBCO).sel(latitude=ds["latitude"],
                                                         longitude=ds["longitude"])
    np.testing.assert_array_equal(ds["elevation"].values, full["elevation"].values)


def write_geotiff(path: Path, data: np.ndarray, west: float, north: float, step: float,
                  nodata: float | None = None) -> Path:
    """A north-up, pixel-is-area geographic GeoTIFF with ModelPixelScale/ModelTiepoint tags."""
    import tifffile

    tags = [(33550, "d", 3, (step, step, 0.0), False),
            (33922, "d", 6, (0.0, 0.0, 0.0, west, north, 0.0), False),
            # GeoKeyDirectory: GTModelType=geographic(2), GTRasterType=PixelIsArea(1)
            (34735, "H", 12, (1, 1, 0, 2, 1024, 0, 1, 2, 1025, 0, 1, 1), False)]
    if nodata is not None:
        tags.append((42113, "s", 0, f"{nodata:g}", False))
    tifffile.imwrite(path, data, extratags=tags)
    return path


def test_geotiff_georeferencing(tmp_path, base_config):
    step = 1 / 240
    data = np.arange(12, dtype=np.int16).reshape(3, 4) - 6  # row 0 = northernmost
    data[2, 3] = -32767
    path = write_geotiff(tmp_path / "gebco.tif", data, west=12.0, north=56.0, step=step,
                         nodata=-32767)
    ds = read_bathymetry_file(path)
    np.testing.assert_allclose(ds["latitude"], 56.0 - step * np.array([2.5, 1.5, 0.5]))
    np.testing.assert_allclose(ds["longitude"], 12.0 + step * np.array([0.5, 1.5, 2.5, 3.5]))
    z = ds["elevation"].values
    assert np.isnan(z[0, 3])  # nodata, now in the southern (first) row
    np.testing.assert_array_equal(z[::-1][:2], data[:2].astype(np.float32))

    cfg = base_config
    cfg["region"]["bbox"] = {"west": 12.005, "east": 12.012, "south": 55.989, "north": 55.996}
    cfg["sources"]["bathymetry"] = "gebco"
    cfg["gebco"]["path"] = str(path)
    fetch_bathymetry(cfg, tmp_path / "b.nc", tmp_path / "cache")
    assert open_bathymetry(tmp_path / "b.nc").attrs["source"] == "gebco"


# ------------------------------------------------------------------ silent normalisation

@pytest.fixture
def plain_currents(shared_data, tmp_path) -> Path:
    """A small plain CMEMS-layout file straddling the prime meridian."""
    src = xr.open_dataset(shared_data / CURRENTS)
    small = src.sel(longitude=slice(-1.0, 1.5), latitude=slice(50.0, 51.0)).isel(depth=[0, 1])
    path = tmp_path / "plain.nc"
    small.to_netcdf(path)
    return path


def _variant(plain: Path, out: Path, change, encoding=None) -> Path:
    with xr.open_dataset(plain) as src:
        ds = change(src.load())
    ds.to_netcdf(out, encoding=encoding)
    return out


@pytest.mark.parametrize("variant", ["lon360", "descending", "scale_factor", "names_order",
                                     "depth_up"])
def test_normalisation_matches_plain(plain_currents, tmp_path, variant):
    def lon360(ds):
        return ds.assign_coords(longitude=ds["longitude"].astype("float64") % 360).sortby(
            "longitude")

    def descending(ds):
        return ds.isel(latitude=slice(None, None, -1), longitude=slice(None, None, -1),
                       depth=slice(None, None, -1))

    def names_order(ds):
        ds = ds.rename(latitude="lat", longitude="lon")
        return ds.transpose("time", "depth", "lon", "lat")

    def depth_up(ds):
        return ds.assign_coords(depth=("depth", -ds["depth"].values, {"positive": "up"}))

    changes = {"lon360": lon360, "descending": descending, "scale_factor": lambda ds: ds,
               "names_order": names_order, "depth_up": depth_up}
    encoding = None
    if variant == "scale_factor":
        packed = {"dtype": "int16", "scale_factor": 0.001, "add_offset": 0.0,
                  "_FillValue": np.int16(-32767)}
        encoding = {"uo": packed, "vo": packed}
    path = _variant(plain_currents, tmp_path / f"{variant}.nc", changes[variant], encoding)
    if variant == "lon360":
        assert xr.open_dataset(path)["longitude"].max() > 358  # really 0..360 on disk
    plain, other = read_currents_file(plain_currents), read_currents_file(path)
    for dim in ("time", "depth", "latitude", "longitude"):
        if dim == "time":
            np.testing.assert_array_equal(other[dim], plain[dim])
        else:
            np.testing.assert_allclose(other[dim], plain[dim], atol=1e-6)
    atol = 0.0005 if variant == "scale_factor" else 0.0
    for var in ("u", "v"):
        assert other[var].dims == plain[var].dims and other[var].dtype == np.float32
        np.testing.assert_allclose(other[var].values, plain[var].values, atol=atol,
                                   equal_nan=True)
    assert np.isnan(plain["u"].values).any()  # the comparison covers land too


def test_gebco_with_y_x_names_and_descending_rows(shared_data, tmp_path):
    with xr.open_dataset(shared_data / GEBCO) as src:
        flipped = src.load().isel(lat=slice(None, None, -1)).rename(lat="y", lon="x")
    path = tmp_path / "flipped.nc"
    flipped.to_netcdf(path, format="NETCDF3_CLASSIC")
    a, b = read_bathymetry_file(shared_data / GEBCO), read_bathymetry_file(path)
    np.testing.assert_array_equal(b["latitude"], a["latitude"])
    np.testing.assert_array_equal(b["elevation"].values, a["elevation"].values)


# ------------------------------------------------------------------ synthetic dispatch

def test_synthetic_dispatch(base_config, tmp_path, monkeypatch):
    times = pd.date_range("2025-01-01", periods=3, freq="1h")
    lat, lon = np.linspace(50.1, 50.4, 4), np.linspace(-4.6, -4.2, 5)
    shape3, shape4 = (3, 4, 5), (3, 2, 4, 5)
    attrs = sources.base.VAR_ATTRS

    def make_currents(cfg):
        return xr.Dataset(
            {name: (sources.base.DIMS[name], np.full(shape4 if name in "uv" else shape3, 0.1,
                                                     np.float32), attrs[name])
             for name in ("u", "v", "u_tide", "v_tide")},
            coords={"time": times, "depth": [0.5, 5.0], "latitude": lat, "longitude": lon},
        ).chunk()

    fake = types.ModuleType("oneocean.sources.synthetic")
    fake.make_currents = make_currents
    monkeypatch.setitem(sys.modules, "oneocean.sources.synthetic", fake)
    base_config["sources"]["tides"] = False
    fetch_currents(base_config, tmp_path / "c.nc", tmp_path / "cache")
    ds = open_currents(tmp_path / "c.nc")
    assert ds.attrs["source"] == "synthetic" and json.loads(ds.attrs["source_files"]) == []
    assert "u_tide" not in ds
