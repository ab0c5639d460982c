"""Bad input → one clear one-line error naming the file and the problem, and no output left."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from oneocean.errors import CredentialsError, DataError
from oneocean.sources import fetch_bathymetry, fetch_currents, open_bathymetry, open_currents

CURRENTS = "cmems_glo12_currents_P1D_w-1_e10_s50_n55_2025-01-01.nc"
SALINITY = "cmems_glo12_salinity_P1D_w-13_e5_s47_n64_2025-09-24.nc"
ETOPO = "etopo2022_30s_w2_e3_s51_n53.nc"
GEBCO = "gebco_2020_n56.3_s55.2_w12.2_e13.1.nc"
NORTH_SEA = {"west": 2.0, "east": 3.0, "south": 51.0, "north": 53.0}


@pytest.fixture
def cfg(base_config, shared_data):
    """The southern North Sea through the ``files`` source, without tides."""
    c = base_config
    c["region"].update(bbox=dict(NORTH_SEA), max_depth_m=5.0,
                       time={"start": "2025-01-01T00:00:00", "end": "2025-01-02T00:00:00"})
    c["sources"].update(currents="files", bathymetry="files", tides=False)
    c["files"].update(currents=str(shared_data / CURRENTS), bathymetry=str(shared_data / ETOPO))
    c["cmems"]["retry_wait_s"] = 0.0
    return c


@pytest.fixture
def north_sea_currents(shared_data) -> xr.Dataset:
    """The CMEMS currents around the southern North Sea bbox, loaded (small)."""
    with xr.open_dataset(shared_data / CURRENTS) as src:
        return src.sel(longitude=slice(1.5, 3.5), latitude=slice(50.5, 53.5)).load()


def fails_cleanly(fetch, cfg, out: Path, error=DataError, names: str | Path | None = None,
                  says: str = "") -> str:
    """Run ``fetch`` expecting ``error``; check the message and that nothing was left behind."""
    with pytest.raises(error) as info:
        fetch(cfg, out, out.parent / "cache")
    message = str(info.value)
    assert "\n" not in message
    if names is not None:
        assert str(names) in message, message
    assert says.lower() in message.lower(), message
    assert not out.exists()
    assert not [p for p in out.parent.iterdir() if p.name.startswith(f".{out.name}")]
    return message


def write(ds: xr.Dataset, path: Path, **kwargs) -> Path:
    ds.to_netcdf(path, **kwargs)
    return path


# ------------------------------------------------------------------ missing variables / files

def test_missing_variable(cfg, tmp_path, north_sea_currents):
    bad = write(north_sea_currents.drop_vars("vo"), tmp_path / "no_vo.nc")
    cfg["files"]["currents"] = str(bad)
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=bad, says="missing variable 'v'")


def test_salinity_file_is_not_currents(cfg, tmp_path, shared_data):
    cfg["files"]["currents"] = str(shared_data / SALINITY)
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=shared_data / SALINITY,
                  says="missing variable 'u' (looked for u, uo")


def test_currents_file_is_not_bathymetry(cfg, tmp_path, shared_data):
    cfg["files"]["bathymetry"] = str(shared_data / CURRENTS)
    fails_cleanly(fetch_bathymetry, cfg, tmp_path / "b.nc", names=shared_data / CURRENTS,
                  says="missing variable 'elevation'")


def test_missing_file(cfg, tmp_path):
    cfg["files"]["currents"] = str(tmp_path / "nowhere.nc")
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=tmp_path / "nowhere.nc",
                  says="file not found")


def test_unsupported_units(cfg, tmp_path, north_sea_currents):
    ds = north_sea_currents.copy()
    ds["uo"].attrs["units"] = "knots"
    bad = write(ds, tmp_path / "knots.nc")
    cfg["files"]["currents"] = str(bad)
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=bad, says="units 'knots'")


# ------------------------------------------------------------------ swapped latitude/longitude

def test_swapped_axes_latitude_beyond_90(cfg, tmp_path):
    """A (lon, lat)-ordered variable whose 'lat' axis holds longitudes 100..120."""
    true_lon, true_lat = np.linspace(100, 120, 6), np.linspace(10, 20, 5)
    ds = xr.Dataset(
        {"uo": (("time", "depth", "lon", "lat"), np.zeros((1, 1, 5, 6), np.float32)),
         "vo": (("time", "depth", "lon", "lat"), np.zeros((1, 1, 5, 6), np.float32))},
        coords={"time": pd.to_datetime(["2025-01-01"]), "depth": [0.5],
                "lat": true_lon, "lon": true_lat})
    bad = write(ds, tmp_path / "swapped.nc")
    cfg["files"]["currents"] = str(bad)
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=bad,
                  says="latitude/longitude look swapped")


def test_swapped_axes_by_attributes(cfg, tmp_path, north_sea_currents):
    """Axis names exchanged: the 'latitude' axis carries units degrees_east."""
    ds = north_sea_currents.rename(latitude="tmp").rename(longitude="latitude").rename(
        tmp="longitude")
    bad = write(ds, tmp_path / "renamed.nc")
    cfg["files"]["currents"] = str(bad)
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=bad,
                  says="latitude/longitude look swapped")


def test_swapped_axes_detected_from_bbox(cfg, tmp_path, shared_data):
    """No attributes to go by: the bbox is covered only with the axes exchanged."""
    with xr.open_dataset(shared_data / ETOPO) as src:
        ds = src[["z"]].load().rename(latitude="lon", longitude="lat")
    for name in ("lat", "lon"):
        ds[name].attrs = {}
    bad = write(ds, tmp_path / "swapped_etopo.nc")
    cfg["files"]["bathymetry"] = str(bad)
    fails_cleanly(fetch_bathymetry, cfg, tmp_path / "b.nc", names=bad,
                  says="latitude/longitude look swapped")


# ------------------------------------------------------------------ coverage

def test_bbox_outside_the_data(cfg, tmp_path, shared_data):
    cfg["region"]["bbox"] = {"west": -150.0, "east": -149.0, "south": 10.0, "north": 11.0}
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=shared_data / CURRENTS,
                  says="is outside the data")
    fails_cleanly(fetch_bathymetry, cfg, tmp_path / "b.nc", names=shared_data / ETOPO,
                  says="is outside the data")


def test_bbox_partly_outside_the_data(cfg, tmp_path, shared_data):
    cfg["region"]["bbox"] = {"west": 2.5, "east": 3.5, "south": 51.0, "north": 52.0}
    fails_cleanly(fetch_bathymetry, cfg, tmp_path / "b.nc", names=shared_data / ETOPO,
                  says="not covered by the data")


def test_time_window_outside_the_data(cfg, tmp_path, shared_data):
    cfg["region"]["time"] = {"start": "2024-06-01T00:00:00", "end": "2024-06-02T00:00:00"}
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=shared_data / CURRENTS,
                  says="time window 2024-06-01T00:00:00..2024-06-02T00:00:00 is outside the data")


def test_time_window_not_covered(cfg, tmp_path, shared_data):
    cfg["region"]["time"] = {"start": "2025-01-01T00:00:00", "end": "2025-01-05T00:00:00"}
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=shared_data / CURRENTS,
                  says="is not covered by the data")


def test_all_nan_currents(cfg, tmp_path, north_sea_currents):
    ds = north_sea_currents.copy()
    ds["uo"][:] = np.nan
    ds["vo"][:] = np.nan
    bad = write(ds, tmp_path / "all_nan.nc")
    cfg["files"]["currents"] = str(bad)
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=bad, says="are all NaN")


def test_all_nan_in_the_requested_subset_only(cfg, tmp_path, north_sea_currents):
    """Valid currents elsewhere do not count: the requested bbox has none."""
    ds = north_sea_currents.copy()
    inside = (ds["longitude"] < 3.2) & (ds["latitude"] < 53.2)
    ds["uo"] = ds["uo"].where(~inside)
    ds["vo"] = ds["vo"].where(~inside)
    assert ds["uo"].notnull().any()
    bad = write(ds, tmp_path / "nan_inside.nc")
    cfg["files"]["currents"] = str(bad)
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=bad, says="all NaN")


# ------------------------------------------------------------------ truncated / corrupt files

def truncated_copy(src: Path, dst: Path) -> Path:
    data = src.read_bytes()
    dst.write_bytes(data[: len(data) // 2])
    return dst


def test_truncated_netcdf4(cfg, tmp_path, shared_data):
    bad = truncated_copy(shared_data / CURRENTS, tmp_path / "half.nc")
    cfg["files"]["currents"] = str(bad)
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=bad, says="truncated")


def test_truncated_netcdf3(cfg, tmp_path, shared_data):
    """netCDF-C would read zeros past the end of a truncated classic file: refuse it."""
    bad = truncated_copy(shared_data / GEBCO, tmp_path / "half_gebco.nc")
    cfg["region"]["bbox"] = {"west": 12.5, "east": 12.8, "south": 55.5, "north": 55.9}
    cfg["files"]["bathymetry"] = str(bad)
    fails_cleanly(fetch_bathymetry, cfg, tmp_path / "b.nc", names=bad, says="truncated")


def test_not_a_netcdf_file(tmp_path):
    bad = tmp_path / "notes.nc"
    bad.write_text("these are not the data you are looking for\n")
    with pytest.raises(DataError, match="notes.nc: cannot read as NetCDF"):
        open_currents(bad)


def test_truncated_geotiff(cfg, tmp_path):
    import tifffile

    good = tmp_path / "good.tif"
    tifffile.imwrite(good, np.zeros((64, 64), np.float32),
                     extratags=[(33550, "d", 3, (0.01, 0.01, 0.0), False),
                                (33922, "d", 6, (0, 0, 0, 2.0, 53.0, 0), False)])
    bad = truncated_copy(good, tmp_path / "half.tif")
    with pytest.raises(DataError, match=f"^{bad}: truncated GeoTIFF"):
        open_bathymetry(bad)


def test_geotiff_without_georeferencing(tmp_path):
    import tifffile

    plain = tmp_path / "plain.tif"
    tifffile.imwrite(plain, np.zeros((4, 4), np.int16))
    with pytest.raises(DataError, match="plain.tif: GeoTIFF has no ModelPixelScale"):
        open_bathymetry(plain)


# ------------------------------------------------------------------ cmems credentials, failures

@pytest.fixture
def no_credentials(monkeypatch, tmp_path):
    """No environment variables and an empty HOME: the toolbox has nothing to go by."""
    for var in ("COPERNICUSMARINE_SERVICE_USERNAME", "COPERNICUSMARINE_SERVICE_PASSWORD",
                "COPERNICUSMARINE_CREDENTIALS_DIRECTORY"):
        monkeypatch.delenv(var, raising=False)
    home = tmp_path / "home"
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    return home


@pytest.fixture
def subset_must_not_run(monkeypatch):
    import copernicusmarine

    def forbidden(**kwargs):
        raise AssertionError("copernicusmarine.subset was called")

    monkeypatch.setattr(copernicusmarine, "subset", forbidden)


def test_no_credentials(cfg, tmp_path, no_credentials, subset_must_not_run):
    cfg["sources"]["currents"] = "cmems"
    message = fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", error=CredentialsError,
                            says="copernicusmarine login")
    assert "COPERNICUSMARINE_SERVICE_USERNAME" in message
    assert not (tmp_path / "cache").exists() or not any((tmp_path / "cache").iterdir())


def test_configured_credentials_file_missing(cfg, tmp_path, no_credentials, subset_must_not_run):
    cfg["sources"]["currents"] = "cmems"
    cfg["cmems"]["credentials_file"] = str(tmp_path / "creds.ini")
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", error=CredentialsError,
                  names=tmp_path / "creds.ini", says="file not found")


def test_download_keeps_failing(cfg, tmp_path, monkeypatch):
    import copernicusmarine

    monkeypatch.setenv("COPERNICUSMARINE_SERVICE_USERNAME", "user")
    monkeypatch.setenv("COPERNICUSMARINE_SERVICE_PASSWORD", "secret")
    calls = []

    def broken(**kwargs):
        calls.append(kwargs)
        (Path(kwargs["output_directory"]) / kwargs["output_filename"]).write_bytes(b"partial")
        raise TimeoutError("read timed out")

    monkeypatch.setattr(copernicusmarine, "subset", broken)
    cfg["sources"]["currents"] = "cmems"
    cfg["cmems"]["retries"] = 2
    fails_cleanly(fetch_currents, cfg, tmp_path / "c.nc", names=cfg["cmems"]["dataset_id"],
                  says="download failed after 2 attempt(s): read timed out")
    assert len(calls) == 2
    assert list((tmp_path / "cache").iterdir()) == []  # no partial download kept
