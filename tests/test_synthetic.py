"""The embedded synthetic source: deterministic, chunk-invariant, realistic coastal structure."""

from __future__ import annotations

import copy
from pathlib import Path

import dask.array  # noqa: F401  (for the warning filter)
import numpy as np
import pytest
import yaml
from scipy import ndimage

from oneocean.product.exports import metres_per_degree
from oneocean.sources.synthetic import (make_bathymetry, make_currents, scene_summary,
                                        synthetic_axes)

CONFIG = Path(__file__).parents[1] / "config" / "config.yaml"


def small_config(**synthetic) -> dict:
    """The default region at 0.004 deg, 12 hourly steps (fast)."""
    with open(CONFIG) as fh:
        cfg = yaml.safe_load(fh)
    cfg["region"]["time"] = {"start": "2025-01-01T00:00:00", "end": "2025-01-01T12:00:00"}
    cfg["synthetic"].update({"resolution_deg": 0.004, **synthetic})
    return cfg


@pytest.fixture(scope="module")
def cfg() -> dict:
    return small_config()


@pytest.fixture(scope="module")
def cur(cfg):
    return make_currents(cfg).compute()


@pytest.fixture(scope="module")
def bat(cfg):
    return make_bathymetry(cfg).compute()


def _same(a, b) -> bool:
    return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)


def test_same_seed_gives_identical_arrays(cfg, cur, bat):
    again = make_currents(copy.deepcopy(cfg)).compute()
    for name in ("u", "v", "u_tide", "v_tide"):
        assert _same(cur[name], again[name]), name
    assert _same(bat["elevation"], make_bathymetry(copy.deepcopy(cfg))["elevation"])


def test_different_seed_gives_different_fields(cfg, cur, bat):
    other = copy.deepcopy(cfg)
    other["synthetic"]["seed"] += 1
    assert not _same(make_bathymetry(other)["elevation"], bat["elevation"])
    assert not _same(make_currents(other)["u"].isel(time=0), cur["u"].isel(time=0))


@pytest.mark.filterwarnings("ignore::dask.array.PerformanceWarning")
def test_chunking_does_not_change_values(cfg, cur, bat):
    chunked = make_currents(cfg, chunks={"time": 5, "latitude": 17, "longitude": 23})
    assert chunked["u"].data.numblocks == (3, 1, 5, 5)
    for name in ("u", "v", "u_tide", "v_tide"):
        assert _same(chunked[name].values, cur[name].values), name
    rows = make_bathymetry(cfg, chunks={"latitude": 10, "longitude": 40})
    assert _same(rows["elevation"].values, bat["elevation"].values)


def test_canonical_schema_and_marking(cfg, cur, bat):
    ax = synthetic_axes(cfg)
    assert cur["u"].dims == ("time", "depth", "latitude", "longitude")
    assert cur["u_tide"].dims == ("time", "latitude", "longitude")
    assert bat["elevation"].dims == ("latitude", "longitude")
    assert cur["u"].dtype == np.float32 and bat["elevation"].dtype == np.float32
    assert cur.sizes["time"] == 13 and cur["time"].dtype == np.dtype("datetime64[ns]")
    for c in ("latitude", "longitude", "depth"):
        assert np.all(np.diff(cur[c].values) > 0), c
    assert cur["longitude"].values[0] == pytest.approx(cfg["region"]["bbox"]["west"])
    assert cur["longitude"].values[-1] == pytest.approx(cfg["region"]["bbox"]["east"])
    np.testing.assert_array_equal(cur["depth"].values, ax["depth"])
    for ds in (cur, bat):
        assert ds.attrs["source"] == "synthetic"
        assert "SYNTHETIC" in ds.attrs["title"]
        assert ds.attrs["source_files"] == "[]"
    assert cur["u"].attrs["standard_name"] == "eastward_sea_water_velocity"
    assert cur["u"].attrs["units"] == "m s-1"


def test_depths_limited_by_region_max_depth():
    cfg = small_config()
    cfg["region"]["max_depth_m"] = 15.0
    assert synthetic_axes(cfg)["depth"].tolist() == [0.5, 5.0, 10.0]


def test_tides_follow_sources_tides_flag():
    cfg = small_config()
    cfg["sources"]["tides"] = False
    assert "u_tide" not in make_currents(cfg)


def test_land_shelf_slope_deep_water_canyon_and_island(cfg, bat):
    elev = bat["elevation"].values
    land = elev >= 0
    assert 0.10 < land.mean() < 0.60
    depth = -elev[~land]
    assert ((depth > 20) & (depth < 150)).mean() > 0.15            # shelf
    assert ((depth > 150) & (depth < 1000)).any()                    # slope
    assert (depth > 1000).mean() > 0.05                              # deep water
    labels, n = ndimage.label(land)
    assert n >= 2
    border = set(np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0],
                                           labels[:, -1]]))) - {0}
    islands = [k for k in range(1, n + 1) if k not in border]
    assert islands, "no island (land not connected to the box edge)"
    s = scene_summary(cfg)
    j = int(np.argmin(np.abs(bat["latitude"].values - s["island_lat"])))
    i = int(np.argmin(np.abs(bat["longitude"].values - s["island_lon"])))
    assert labels[j, i] in islands
    # The canyon: mid-shelf, markedly deeper than the shelf either side.
    lat_row = s["coast_lat_at_canyon"] - 0.2 * (cfg["region"]["bbox"]["north"]
                                                 - cfg["region"]["bbox"]["south"])
    row = -elev[int(np.argmin(np.abs(bat["latitude"].values - lat_row)))]
    ic = int(np.argmin(np.abs(bat["longitude"].values - s["canyon_lon"])))
    window = row[max(ic - 3, 0):ic + 4]
    assert window.max() > np.median(row) + 100.0


def test_currents_nan_on_land_and_below_seafloor(cur, bat):
    h = -bat["elevation"].values
    for k, z in enumerate(cur["depth"].values):
        finite = np.isfinite(cur["u"].isel(depth=k).values)
        np.testing.assert_array_equal(finite, np.broadcast_to(z <= h, finite.shape))
        assert np.array_equal(finite, np.isfinite(cur["v"].isel(depth=k).values))
    tide_finite = np.isfinite(cur["u_tide"].values)
    np.testing.assert_array_equal(tide_finite, np.broadcast_to(h > 0, tide_finite.shape))


def test_tidal_speed_reaches_auv_speed_and_stays_bounded(cur):
    speed = np.hypot(cur["u_tide"], cur["v_tide"]).values
    assert np.nanmax(speed) > 1.0
    assert np.nanmax(speed) < 1.6
    # Shallow water has stronger tides than deep water.
    assert np.nanmax(speed[0, :10]) < 0.5 * np.nanmax(speed[0])     # southern (deep) rows
    # Semidiurnal ellipses: the speed changes within a quarter period (major -> minor axis).
    assert np.nanmean(np.abs(speed[0] - speed[3])) > 0.1


def test_currents_vary_in_time_and_decay_with_depth(cur):
    u, v = cur["u"].values, cur["v"].values
    wet_all = np.isfinite(u).all(axis=(0, 1))                       # columns deep enough
    speed = np.hypot(u, v)[:, :, wet_all]                           # (nt, nz, ncol)
    profile = speed.mean(axis=(0, 2))
    assert np.all(np.diff(profile) < 0), profile
    assert profile[-1] < 0.8 * profile[0]
    diff = np.nanmean(np.abs(u[0] - u[-1]))
    assert diff > 0.02


def test_mean_and_eddy_flow_is_divergence_free():
    cfg = small_config(resolution_deg=0.001, depths_m=[0.5])
    cfg["region"]["time"]["end"] = cfg["region"]["time"]["start"]
    cfg["sources"]["tides"] = False
    ds = make_currents(cfg).isel(time=0, depth=0).compute()
    u, v = ds["u"].values.astype(float), ds["v"].values.astype(float)
    m_lat, m_lon = metres_per_degree(0.5 * (cfg["region"]["bbox"]["south"]
                                            + cfg["region"]["bbox"]["north"]))
    dx, dy = 0.001 * m_lon, 0.001 * m_lat
    dudx = (u[1:-1, 2:] - u[1:-1, :-2]) / (2 * dx)
    dvdy = (v[2:, 1:-1] - v[:-2, 1:-1]) / (2 * dy)
    dvdx = (v[1:-1, 2:] - v[1:-1, :-2]) / (2 * dx)
    dudy = (u[2:, 1:-1] - u[:-2, 1:-1]) / (2 * dy)
    div, vort = dudx + dvdy, dvdx - dudy
    ok = np.isfinite(div) & np.isfinite(vort)
    assert ok.mean() > 0.5
    assert np.median(np.abs(div[ok])) < 0.05 * np.median(np.abs(vort[ok]))
    assert np.median(np.abs(div[ok])) < 0.05 * np.median(np.abs(dudx[ok]) + np.abs(dvdy[ok]))
