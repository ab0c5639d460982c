"""The Strait of Dover narrows (config/regions/dover_strait_narrows.yaml) end to end, offline.

SYNTHETIC DATA IN THE REAL PRODUCTS' SCHEMAS. No machine here reaches Copernicus Marine, so
``copernicusmarine.subset`` is patched: it cuts a synthetic, in-memory copy of the hourly dataset
``cmems_mod_glo_phy_anfc_merged-uv_PT1H-i`` (GLOBAL_ANALYSISFORECAST_PHY_001_024, GLO12) and
writes the subset the way copernicusmarine 2.x writes one. The values are invented (an M2 tidal
stream of about 1 m/s along the strait over a 0.1 m/s residual, a weak Stokes drift); the layout
is the product's:

* dims ``time, depth, latitude, longitude``; one level, ``depth`` = 0.494025 m (float32,
  positive down); GLO12 nodes ``longitude = -180 + k/12``, ``latitude = -80 + k/12`` (float32);
  ``time`` hourly on the hour (instantaneous, "PT1H-i"), float32 "hours since 1950-01-01",
  calendar gregorian;
* variables, all float32 (time, depth, latitude, longitude), units "m s-1", ``_FillValue``
  9.96921e+36 on land: ``uo``/``vo`` (eastward/northward_sea_water_velocity, the model's
  circulation, no tide), ``utide``/``vtide`` (tidal currents), ``vsdx``/``vsdy``
  (sea_surface_wave_stokes_drift_x/y_velocity) and ``utotal``/``vtotal`` = the sum of the three;
* as written by the toolbox: only the requested variables, "outside" coordinate selection,
  coordinate attributes standard_name/long_name/units/unit_long/axis (+ positive), coordinates
  without ``_FillValue``, NetCDF-4 through h5netcdf, no compression (copernicusmarine 2.5's own
  xarray subset and writer give the same file for the same input, attribute order aside);
  global attributes and valid_min/valid_max like the shared real daily GLO12 file's.

The long names, and the standard names of utide/vtide/utotal/vtotal, could not be checked
against a real download offline; the readers select ``uo/vo/utide/vtide`` by name.

The bathymetry is synthetic too (the narrows' two coasts 33 km apart, a 60 m deep channel, the
Varne bank), written in the layout of a real ETOPO 2022 NetCDF (that of the shared real
``etopo2022_30s_w2_e3_s51_n53.nc``: ``z`` float32 m positive up, EGM2008, 30 arc-second cell
centres, ``crs``) and of a GEBCO download-app NetCDF (NETCDF3, ``elevation`` int16, 15
arc-second cell centres, ``node_offset = 1``).
"""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import netCDF4
import numpy as np
import pytest
import xarray as xr

from oneocean.config import load_config
from oneocean.engine import grid as G
from oneocean.errors import DataError
from oneocean.product.exports import export_grid, export_temporal
from oneocean.product.build import build_product
from oneocean.sources import fetch_bathymetry, fetch_currents, open_bathymetry, open_currents
from test_exports import check_engine_matches_temporal
from workflow_helpers import REPO

DATASET = "cmems_mod_glo_phy_anfc_merged-uv_PT1H-i"
REGION = REPO / "config" / "regions" / "dover_strait_narrows.yaml"
BBOX = {"west": 1.2, "east": 2.0, "south": 50.8, "north": 51.2}
T0 = np.datetime64("2025-01-01T00:00:00", "ns")
HOURS = 48                          # the region's window and its scene/public variants
SURFACE = np.float32(0.494025)      # the dataset's one level, m
NC_FILL = np.float32(9.96921e36)    # the NetCDF default float fill, as in the real GLO12 files

# ---------------------------------------------------------------- the synthetic strait
# Centre of the narrows (midway between South Foreland and Cap Gris-Nez) and km per degree.
LON_C, LAT_C = 1.475, 51.005
KM_LON, KM_LAT = 111.32 * np.cos(np.radians(51.0)), 111.2
ACROSS = (-0.44, 0.898)             # unit vector (east, north) toward England
ALONG = (0.898, 0.44)               # unit vector (east, north) toward the North Sea
HALF_WIDTH_KM = 16.7                # South Foreland - Cap Gris-Nez is 33 km
M2_PERIOD_H = 12.4206012
M2_AMPLITUDE = 1.0                  # m/s along the strait at (1.6 E, 51.0 N)
M2_MINOR = 0.1                      # m/s across it (a narrow tidal ellipse)


def _across_along(lon, lat):
    """Cross- and along-channel coordinates (km) of (lon, lat)."""
    x, y = (np.asarray(lon) - LON_C) * KM_LON, (np.asarray(lat) - LAT_C) * KM_LAT
    return ACROSS[0] * x + ACROSS[1] * y, ALONG[0] * x + ALONG[1] * y


def elevation(lon, lat):
    """Synthetic height (m, positive up): a 60 m deep channel, the Varne bank, cliffs."""
    s, r = _across_along(lon, lat)
    q = np.abs(s) / HALF_WIDTH_KM
    varne = 42.0 * np.exp(-((r + 4.0) / 6.0) ** 2 - ((s - 3.8) / 1.5) ** 2)
    return np.where(q < 1.0, -60.0 * (1.0 - q ** 2) + varne,
                    np.minimum(6.0 * (np.abs(s) - HALF_WIDTH_KM), 120.0))


def currents(t_h, lon, lat) -> dict:
    """The synthetic dataset's eight variables (m/s) at hours ``t_h`` after T0. Every field is
    linear in lon and lat at each time, so bilinear regridding reproduces it exactly."""
    t_h, lon, lat = np.broadcast_arrays(*(np.asarray(a, float) for a in (t_h, lon, lat)))
    phase = 2 * np.pi * t_h / M2_PERIOD_H + 0.4
    amp = M2_AMPLITUDE + 0.1 * (lon - 1.6) / 0.4 - 0.05 * (lat - 51.0) / 0.2
    along, across = amp * np.cos(phase), M2_MINOR * np.sin(phase)
    residual = 0.10 + 0.03 * (lon - 1.6) / 0.4 + 0.02 * np.sin(2 * np.pi * t_h / 24.0)
    f = {"uo": residual * ALONG[0] + 0.01 * (lat - 51.0) / 0.2, "vo": residual * ALONG[1],
         "utide": along * ALONG[0] + across * ACROSS[0],
         "vtide": along * ALONG[1] + across * ACROSS[1],
         "vsdx": 0.04 + 0.01 * (lat - 51.0) / 0.2 + 0.01 * np.sin(2 * np.pi * t_h / 24.0),
         "vsdy": np.full(t_h.shape, 0.02)}
    f["utotal"] = f["uo"] + f["utide"] + f["vsdx"]
    f["vtotal"] = f["vo"] + f["vtide"] + f["vsdy"]
    return f


_VARIABLE_ATTRS = {
    "uo": ("eastward_sea_water_velocity", "Eastward Eulerian velocity (Navier-Stokes current)"),
    "vo": ("northward_sea_water_velocity", "Northward Eulerian velocity (Navier-Stokes current)"),
    "utide": ("surface_sea_water_x_velocity_due_to_tide",
              "Eastward tide-induced velocity (Tidal current)"),
    "vtide": ("surface_sea_water_y_velocity_due_to_tide",
              "Northward tide-induced velocity (Tidal current)"),
    "vsdx": ("sea_surface_wave_stokes_drift_x_velocity",
             "Eastward wave-induced velocity (Stokes drift)"),
    "vsdy": ("sea_surface_wave_stokes_drift_y_velocity",
             "Northward wave-induced velocity (Stokes drift)"),
    "utotal": ("surface_sea_water_x_velocity", "Eastward total velocity (Eulerian + Waves + Tide)"),
    "vtotal": ("surface_sea_water_y_velocity",
               "Northward total velocity (Eulerian + Waves + Tide)"),
}


def merged_uv_dataset(drop=()) -> xr.Dataset:
    """The service side: the hourly merged-uv dataset around the strait, as the toolbox opens
    it (decoded, float32, encodings of the ARCO store). ``drop``: variables it lacks."""
    lon = (-180.0 + np.arange(2166, 2194) / 12.0).astype(np.float32)       # 0.5 .. 2.75 E
    lat = (-80.0 + np.arange(1563, 1582) / 12.0).astype(np.float32)        # 50.25 .. 51.75 N
    times = T0 + np.arange(-2, HOURS + 3).astype("timedelta64[h]")
    t_h = (times - T0) / np.timedelta64(1, "h")
    fields = currents(t_h[:, None, None], lon[None, None, :].astype(float),
                      lat[None, :, None].astype(float))
    wet = elevation(lon[None, :].astype(float), lat[:, None].astype(float)) < -3.0
    data = {}
    for name, (standard_name, long_name) in _VARIABLE_ATTRS.items():
        if name in drop:
            continue
        values = np.where(wet, fields[name], np.nan).astype(np.float32)[:, None]
        var = xr.Variable(("time", "depth", "latitude", "longitude"), values,
                          {"standard_name": standard_name, "long_name": long_name,
                           "units": "m s-1", "unit_long": "Meters per second",
                           "valid_min": np.float32(-5.0), "valid_max": np.float32(5.0)})
        var.encoding = {"dtype": np.dtype("float32"), "_FillValue": NC_FILL}
        data[name] = var
    ds = xr.Dataset(data, coords={
        "time": ("time", times, {"standard_name": "time", "long_name": "Time", "axis": "T"}),
        "depth": ("depth", np.array([SURFACE]),
                  {"standard_name": "depth", "long_name": "Depth", "units": "m",
                   "unit_long": "Meters", "axis": "Z", "positive": "down"}),
        "latitude": ("latitude", lat, {"standard_name": "latitude", "long_name": "Latitude",
                                       "units": "degrees_north", "unit_long": "Degrees North",
                                       "axis": "Y"}),
        "longitude": ("longitude", lon, {"standard_name": "longitude", "long_name": "Longitude",
                                         "units": "degrees_east", "unit_long": "Degrees East",
                                         "axis": "X"}),
    }, attrs={
        "credit": "E.U. Copernicus Marine Service Information (CMEMS)",
        "producer": "CMEMS - Global Monitoring and Forecasting Centre",
        "references": "http://marine.copernicus.eu",
        "contact": "https://marine.copernicus.eu/contact",
        "Conventions": "CF-1.8", "institution": "Mercator Ocean International",
        "title": "hourly instantaneous surface merged ocean currents (SMOC) from Global Ocean "
                 "Physics Analysis and Forecast (SYNTHETIC test data)",
        "source": "MOI GLO12", "copernicusmarine_version": "2.2.2"})
    ds["time"].encoding = {"units": "hours since 1950-01-01", "calendar": "gregorian",
                           "dtype": np.dtype("float32")}
    return ds


def _outside(values: np.ndarray, lo, hi) -> slice:
    """The toolbox's "outside" selection: from the last node <= lo to the first node >= hi."""
    first = max(int(np.searchsorted(values, lo, side="right")) - 1, 0)
    last = min(int(np.searchsorted(values, hi, side="left")), values.size - 1)
    return slice(first, last + 1)


class MergedUvService:
    """Stands in for ``copernicusmarine.subset`` on the hourly merged-uv dataset: cuts the
    synthetic dataset like the service and writes the file as copernicusmarine 2.x does."""

    def __init__(self, dataset: xr.Dataset):
        self.dataset, self.calls = dataset, []

    def __call__(self, **kw):
        self.calls.append(kw)
        assert kw["dataset_id"] == DATASET and kw["coordinates_selection_method"] == "outside"
        ds = self.dataset[[v for v in kw["variables"] if v in self.dataset]]
        index = {
            "longitude": _outside(ds["longitude"].values, kw["minimum_longitude"],
                                  kw["maximum_longitude"]),
            "latitude": _outside(ds["latitude"].values, kw["minimum_latitude"],
                                 kw["maximum_latitude"]),
            "time": _outside(ds["time"].values, np.datetime64(kw["start_datetime"], "ns"),
                             np.datetime64(kw["end_datetime"], "ns")),
        }
        if "minimum_depth" in kw:
            index["depth"] = _outside(ds["depth"].values, kw["minimum_depth"],
                                      kw["maximum_depth"])
        ds = ds.isel(index)
        ds["time"].attrs["unit_long"] = "Hours Since 1950-01-01"
        for coord in ds.coords:
            ds[coord].encoding["_FillValue"] = None
        out = Path(kw["output_directory"]) / kw["output_filename"]
        ds.to_netcdf(out, mode="w", engine="h5netcdf")


def write_etopo(path: Path, west=1.0, east=2.2, south=50.6, north=51.4) -> Path:
    """The synthetic elevation as an ETOPO 2022 30 arc-second NetCDF (the real tile's layout)."""
    step = 1.0 / 120.0
    lon = west + step * (np.arange(round((east - west) / step)) + 0.5)
    lat = south + step * (np.arange(round((north - south) / step)) + 0.5)
    z = elevation(lon[None, :], lat[:, None]).astype(np.float32)
    with netCDF4.Dataset(path, "w", format="NETCDF4") as nc:
        nc.setncatts({
            "GDAL_AREA_OR_POINT": "Area", "node_offset": np.int32(1),
            "GDAL_TIFFTAG_COPYRIGHT": "DOC/NOAA/NESDIS/NCEI > National Centers for "
            "Environmental Information, NESDIS, NOAA, U.S. Department of Commerce",
            "GDAL_TIFFTAG_DATETIME": 20220929123913.0,
            "GDAL_TIFFTAG_IMAGEDESCRIPTION": "Topography-Bathymetry; EGM2008 height",
            "Conventions": "CF-1.5", "GDAL": "GDAL 3.3.2, released 2021/09/01"})
        nc.createDimension("string1", 1)
        nc.createDimension("latitude", lat.size)
        nc.createDimension("longitude", lon.size)
        crs = nc.createVariable("crs", "S1", ("string1",))
        crs.setncatts({
            "grid_mapping_name": "latitude_longitude", "long_name": "CRS definition",
            "longitude_of_prime_meridian": 0.0, "semi_major_axis": 6378137.0,
            "inverse_flattening": 298.257223563,
            "spatial_ref": 'GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,'
                           '298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],'
                           'PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",'
                           '0.0174532925199433,AUTHORITY["EPSG","9122"]],AXIS["Latitude",NORTH],'
                           'AXIS["Longitude",EAST],AUTHORITY["EPSG","4326"]]',
            "GeoTransform": "-180 0.008333333333333333 0 90 0 -0.008333333333333333 "})
        for name, values, units in (("latitude", lat, "degrees_north"),
                                    ("longitude", lon, "degrees_east")):
            v = nc.createVariable(name, "f8", (name,), zlib=True, complevel=5, shuffle=True,
                                  fill_value=np.nan)
            v.setncatts({"standard_name": name, "long_name": name, "units": units})
            v[:] = values
        v = nc.createVariable("z", "f4", ("latitude", "longitude"), zlib=True, complevel=5,
                              shuffle=True, fill_value=np.float32(-99999.0))
        v.setncatts({"long_name": "z", "grid_mapping": "crs", "units": "meters",
                     "positive": "up", "standard_name": "height", "vert_crs_name": "EGM2008",
                     "vert_crs_epsg": "EPSG:3855"})
        v[:] = z
    return path


def write_gebco(path: Path, west=1.1, east=2.1, south=50.7, north=51.3) -> Path:
    """The synthetic elevation as a GEBCO download-app NetCDF (NETCDF3, int16, 15″ centres)."""
    step = 1.0 / 240.0
    lon = west + step * (np.arange(round((east - west) / step)) + 0.5)
    lat = south + step * (np.arange(round((north - south) / step)) + 0.5)
    z = np.round(elevation(lon[None, :], lat[:, None])).astype(np.int16)
    with netCDF4.Dataset(path, "w", format="NETCDF3_CLASSIC") as nc:
        nc.setncatts({"Conventions": "CF-1.6",
                      "title": "The GEBCO_2020 Grid - a continuous terrain model for oceans and "
                               "land at 15 arc-second intervals (SYNTHETIC test data)",
                      "institution": "On behalf of the General Bathymetric Chart of the Oceans "
                                     "(GEBCO), the data are held at the British Oceanographic "
                                     "Data Centre (BODC).",
                      "source": "The GEBCO_2020 Grid is the latest global bathymetric product "
                                "released by the General Bathymetric Chart of the Oceans "
                                "(GEBCO).",
                      "history": "Information on the development of the data set and the "
                                 "source data sets included in the grid can be found in the "
                                 "data set documentation available from https://www.gebco.net",
                      "references": "DOI: 10.5285/a29c5465-b138-234d-e053-6c86abc040b9",
                      "comment": "The data in the GEBCO_2020 Grid should not be used for "
                                 "navigation or any purpose relating to safety at sea.",
                      "node_offset": 1.0})
        nc.createDimension("lat", lat.size)
        nc.createDimension("lon", lon.size)
        for name, values, long, units, axis, sdn in (
                ("lat", lat, "latitude", "degrees_north", "Y",
                 ("ALATZZ01", "Latitude north", "DEGN", "Degrees north")),
                ("lon", lon, "longitude", "degrees_east", "X",
                 ("ALONZZ01", "Longitude east", "DEGE", "Degrees east"))):
            v = nc.createVariable(name, "f8", (name,))
            v.setncatts({"standard_name": long, "long_name": long, "units": units,
                         "axis": axis, "sdn_parameter_urn": f"SDN:P01::{sdn[0]}",
                         "sdn_parameter_name": sdn[1], "sdn_uom_urn": f"SDN:P06::{sdn[2]}",
                         "sdn_uom_name": sdn[3]})
            v[:] = values
        v = nc.createVariable("elevation", "i2", ("lat", "lon"))
        v.setncatts({"standard_name": "height_above_reference_ellipsoid",
                     "long_name": "Elevation relative to sea level", "units": "m",
                     "sdn_parameter_urn": "SDN:P01::BATHHGHT",
                     "sdn_parameter_name": "Sea floor height (above mean sea level) "
                                           "{bathymetric height}",
                     "sdn_uom_urn": "SDN:P06::ULAA", "sdn_uom_name": "Metres"})
        v[:] = z
    return path


# ---------------------------------------------------------------- the region, built once

def narrows_config(etopo: Path) -> dict:
    """The region's config as a user runs it, with ``etopo.path`` pointing at ``etopo``."""
    return load_config(REPO / "config" / "config.yaml", REGION,
                       overrides={"etopo": {"path": str(etopo)},
                                  "cmems": {"retry_wait_s": 0.0}})


def fetch_with(service: MergedUvService, cfg: dict, root: Path,
               monkeypatch: pytest.MonkeyPatch) -> Path:
    import copernicusmarine

    monkeypatch.setenv("COPERNICUSMARINE_SERVICE_USERNAME", "user")
    monkeypatch.setenv("COPERNICUSMARINE_SERVICE_PASSWORD", "secret")
    monkeypatch.setattr(copernicusmarine, "subset", service)
    out = root / "currents.nc"
    fetch_currents(cfg, out, root / "download")
    return out


@pytest.fixture(scope="module")
def narrows(tmp_path_factory):
    root = tmp_path_factory.mktemp("dover_strait_narrows")
    cfg = narrows_config(write_etopo(root / "etopo2022_30s_narrows.nc"))
    service = MergedUvService(merged_uv_dataset())
    with pytest.MonkeyPatch.context() as mp:
        cur = fetch_with(service, cfg, root, mp)
    bat = root / "bathymetry.nc"
    fetch_bathymetry(cfg, bat, root / "download")
    product = root / "product.nc"
    build_product(cur, bat, cfg, "public", product, root / "metadata.json")
    return SimpleNamespace(root=root, cfg=cfg, service=service, currents=cur, bathymetry=bat,
                           product=product, meta=json.loads((root / "metadata.json").read_text()))


def _names(path: Path) -> set[str]:
    with netCDF4.Dataset(path) as nc:
        return set(nc.variables)


def _hours(times) -> np.ndarray:
    return (np.asarray(times, "datetime64[ns]") - T0) / np.timedelta64(1, "h")


# ---------------------------------------------------------------- tests

def test_both_requests_go_to_the_hourly_merged_uv_dataset(narrows):
    cur_call, tide_call = narrows.service.calls
    window = {"start_datetime": "2025-01-01T00:00:00", "end_datetime": "2025-01-03T00:00:00"}
    bbox = {"minimum_longitude": BBOX["west"], "maximum_longitude": BBOX["east"],
            "minimum_latitude": BBOX["south"], "maximum_latitude": BBOX["north"]}
    assert narrows.cfg["region"]["bbox"] == BBOX
    for call in (cur_call, tide_call):
        assert call["dataset_id"] == DATASET
        assert {k: call[k] for k in {**window, **bbox}} == {**window, **bbox}
    assert cur_call["variables"] == ["uo", "vo"]
    assert (cur_call["minimum_depth"], cur_call["maximum_depth"]) == (0.0, 1.0)
    assert tide_call["variables"] == ["utide", "vtide"] and "maximum_depth" not in tide_call
    # the downloads hold exactly what was asked for, in the product's layout
    downloads = sorted((narrows.root / "download").glob(f"cmems-{DATASET}-*.nc"))
    assert len(downloads) == 2
    with netCDF4.Dataset(downloads[0]) as a, netCDF4.Dataset(downloads[1]) as b:
        names = {frozenset(a.variables), frozenset(b.variables)}
        assert names == {frozenset({"time", "depth", "latitude", "longitude", "uo", "vo"}),
                         frozenset({"time", "depth", "latitude", "longitude", "utide", "vtide"})}
        var = a["uo"] if "uo" in a.variables else a["utide"]
        assert var.dimensions == ("time", "depth", "latitude", "longitude")
        assert var.dtype == np.float32 and var.getncattr("_FillValue") == NC_FILL
        assert a["time"].units == "hours since 1950-01-01" and a["time"].dtype == np.float32
        assert a["depth"][:].tolist() == [SURFACE] and "_FillValue" not in a["depth"].ncattrs()
    ds = open_currents(narrows.currents)
    assert ds.attrs["source"] == "cmems"
    assert ds.attrs["dataset_id"] == ds.attrs["tide_dataset_id"] == DATASET
    assert "time_interpolation" not in ds.attrs       # same hourly times: nothing interpolated
    assert set(ds.data_vars) == {"u", "v", "u_tide", "v_tide"}


def test_product_currents_are_circulation_plus_tide(narrows):
    """At product nodes inside fully wet GLO12 cells, u + u_tide is the dataset's uo + utide,
    i.e. utotal minus the Stokes drift, and u alone is the circulation."""
    with open_currents(narrows.currents) as glo:
        glon, glat = glo["longitude"].values, glo["latitude"].values
        wet = np.isfinite(glo["u"].isel(time=0, depth=0).values)
    with xr.open_dataset(narrows.product) as p:
        lat, lon = p["latitude"].values, p["longitude"].values
        j = np.searchsorted(glat, lat) - 1
        i = np.searchsorted(glon, lon) - 1
        inside = (j >= 0)[:, None] & (i >= 0)[None, :]
        j, i = np.clip(j, 0, glat.size - 2), np.clip(i, 0, glon.size - 2)
        corners = (wet[j][:, i] & wet[j + 1][:, i] & wet[j][:, i + 1] & wet[j + 1][:, i + 1])
        sample = inside & corners & (p["valid_mask"].values[0] == 1)
        assert sample.sum() > 1000 and (p["land_mask"].values == 1).any()
        jj, ii = np.nonzero(sample)
        pick = np.random.default_rng(3).choice(jj.size, 60, replace=False)
        jj, ii = jj[pick], ii[pick]
        t_h = _hours(p["time"].values)
        expect = currents(t_h[:, None], lon[ii][None, :], lat[jj][None, :])
        u, v = p["u"].values[:, 0, jj, ii], p["v"].values[:, 0, jj, ii]
        ut, vt = p["u_tide"].values[:, jj, ii], p["v_tide"].values[:, jj, ii]
    np.testing.assert_allclose(u + ut, expect["uo"] + expect["utide"], atol=2e-6)
    np.testing.assert_allclose(v + vt, expect["vo"] + expect["vtide"], atol=2e-6)
    np.testing.assert_allclose(u + ut, expect["utotal"] - expect["vsdx"], atol=2e-6)
    np.testing.assert_allclose(u, expect["uo"], atol=2e-6)        # circulation, no tide
    np.testing.assert_allclose(vt, expect["vtide"], atol=2e-6)    # the tide layer
    assert np.abs(u + ut - expect["utotal"]).min() > 0.01         # no Stokes drift added


def test_time_axis_is_hourly_and_speeds_reach_the_m2_amplitude(narrows):
    with xr.open_dataset(narrows.product) as p:
        times = p["time"].values
        assert p.attrs["has_tide"] == 1 and p.attrs["source_tides"] == "cmems"
        assert p["depth"].values.tolist() == [pytest.approx(float(SURFACE), abs=1e-6)]
    assert times.size == HOURS + 1 and times[0] == T0
    assert (np.diff(times) == np.timedelta64(1, "h")).all()
    s = narrows.meta["summary"]
    assert s["n_times"] == HOURS + 1 and s["has_tide"] is True
    # the M2 stream (0.85-1.15 m/s over the extent) is what the speeds show, not the residual
    assert 0.95 * 0.85 < s["max_tide_speed_ms"] < 1.2
    assert s["max_speed_ms"] < 0.2 and s["mean_speed_ms"] < 0.15
    assert s["max_total_speed_ms"] > 1.0


def test_grid_and_temporal_exports_carry_the_tides(narrows, tmp_path):
    lat, lon = 50.97, 1.55                                  # mid-channel, south of the Varne
    t = tmp_path / "temporal.npz"
    export_temporal(narrows.product, t, lat, lon)
    with np.load(t) as z:
        time_s, u, v, ut, vt = (z[k] for k in ("time_s", "u", "v", "u_tide", "v_tide"))
    assert time_s.size == HOURS + 1 and np.allclose(np.diff(time_s), 3600.0, atol=1e-6)
    expect = currents(time_s / 3600.0, lon, lat)
    np.testing.assert_allclose(ut, expect["utide"], atol=2e-6)
    np.testing.assert_allclose(vt, expect["vtide"], atol=2e-6)
    np.testing.assert_allclose(u, expect["uo"], atol=2e-6)
    along = ut * ALONG[0] + vt * ALONG[1]
    assert 0.9 < np.abs(along).max() < 1.1                  # the M2 amplitude at this point
    assert 7 <= np.count_nonzero(np.diff(np.sign(along))) <= 8   # 48 h / 12.42 h, twice each
    speed = np.hypot(u + ut, v + vt)
    assert speed.max() > 0.95 and speed.min() < 0.4         # full flood/ebb and slack water

    g = tmp_path / "grid.npz"
    export_grid(narrows.product, g, {"region": "dover_strait_narrows", "variant": "public"})
    with np.load(g) as z:
        assert int(z["has_tide"]) == 1 and z["u_tide"].shape[0] == HOURS + 1
        assert np.abs(z["u_tide"]).max() > 0.8
        assert np.allclose(np.diff(z["time_s"]), 3600.0, atol=1e-6)
    grid = G.load_grid(g)
    x, zz = G.lonlat_to_world(grid, lon, lat)
    for k in (0, 7, 30):
        for depth in (float(SURFACE), 20.0):                # the surface level, held below
            ce, cn = G.sample_current_data(grid, float(x), depth, float(zz), float(time_s[k]))
            assert ce == pytest.approx(expect["uo"][k] + expect["utide"][k], abs=2e-6)
            assert cn == pytest.approx(expect["vo"][k] + expect["vtide"][k], abs=2e-6)
    check_engine_matches_temporal(narrows.product, tmp_path, min_points=5)


@pytest.mark.parametrize("missing", ["vtide", "utide"])
def test_tide_variable_missing_is_one_line_error(missing, tmp_path, monkeypatch):
    """A tide download without one of its variables stops the fetch with one line naming the
    downloaded file and the variable; no currents file is written."""
    cfg = narrows_config(tmp_path / "unused_etopo.nc")
    service = MergedUvService(merged_uv_dataset(drop=(missing,)))
    with pytest.raises(DataError) as info:
        fetch_with(service, cfg, tmp_path, monkeypatch)
    message = str(info.value)
    [tide_file] = [f for f in (tmp_path / "download").glob("*.nc") if "uo" not in _names(f)]
    assert "\n" not in message
    assert message.startswith(f"{tide_file}: missing variable "), message
    canonical = missing.replace("tide", "_tide")
    assert f"'{canonical}'" in message and f"{missing}" in message, message
    assert not (tmp_path / "currents.nc").exists()


def test_gebco_download_app_bathymetry_for_the_narrows(narrows, tmp_path):
    gebco = write_gebco(tmp_path / "gebco_2020_n51.3_s50.7_w1.1_e2.1.nc")
    cfg = narrows_config(tmp_path / "unused_etopo.nc")
    cfg["sources"]["bathymetry"] = "gebco"
    cfg["gebco"]["path"] = str(gebco)
    bat = tmp_path / "bathymetry.nc"
    fetch_bathymetry(cfg, bat, tmp_path / "download")
    b = open_bathymetry(bat)
    assert b.attrs["source"] == "gebco" and b["elevation"].dtype == np.float32
    z = b["elevation"].sel(latitude=slice(50.8, 51.2), longitude=slice(1.2, 2.0)).values
    assert (z > 0).any() and (z < -50).any()                # both coasts and the deep channel
    product = tmp_path / "product.nc"
    build_product(narrows.currents, bat, cfg, "scene", product, tmp_path / "metadata.json")
    with xr.open_dataset(product) as p:
        land = p["land_mask"].values == 1
        assert p.attrs["source_bathymetry"] == "gebco" and p.attrs["has_tide"] == 1
        assert land[-1, 0] and land[0, -1] and not land[land.shape[0] // 2,
                                                       land.shape[1] // 2]
