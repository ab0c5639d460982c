"""Shared reader machinery: provider files → the canonical vocabulary of contracts.md §1.

One pipeline serves every source kind::

    open (lazy, no data read) → structure (names, axis order, ascending coords; index-only)
      → subset (bbox + one-cell margin, time window, depth; index-only)
      → finalise (dask chunks, units, dtype, CF attributes) → validate

Only the first two steps touch the provider's layout; everything after them sees
``u``/``v``/``u_tide``/``v_tide``/``elevation`` on ``time``/``depth``/``latitude``/``longitude``.
Nothing reads data values until the caller computes or writes the result, and then only the
subset is read.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import struct
import time as _time
from pathlib import Path
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np
import pandas as pd
import xarray as xr

from .. import __version__
from ..errors import DataError, OneOceanError
from ..io import canonical_json, sha256_file
from ..vocab import CF, SOURCE_KINDS

log = logging.getLogger(__name__)

CURRENT_VARS: tuple[str, ...] = ("u", "v")
TIDE_VARS: tuple[str, ...] = ("u_tide", "v_tide")
BATHYMETRY_VARS: tuple[str, ...] = ("elevation",)

#: Canonical dimension order of every variable.
DIMS: dict[str, tuple[str, ...]] = {
    "u": ("time", "depth", "latitude", "longitude"),
    "v": ("time", "depth", "latitude", "longitude"),
    "u_tide": ("time", "latitude", "longitude"),
    "v_tide": ("time", "latitude", "longitude"),
    "elevation": ("latitude", "longitude"),
}

#: CF attributes written on every canonical variable (provider attributes are dropped).
VAR_ATTRS: dict[str, dict[str, str]] = {
    "u": {"standard_name": CF["u"], "long_name": "eastward sea water velocity", "units": "m s-1"},
    "v": {"standard_name": CF["v"], "long_name": "northward sea water velocity", "units": "m s-1"},
    "u_tide": {"standard_name": CF["u_tide"], "long_name": "eastward tidal current",
               "units": "m s-1"},
    "v_tide": {"standard_name": CF["v_tide"], "long_name": "northward tidal current",
               "units": "m s-1"},
    "elevation": {"standard_name": CF["elevation"],
                  "long_name": "elevation above mean sea level (negative = water depth)",
                  "units": "m", "positive": "up"},
}

COORD_ATTRS: dict[str, dict[str, str]] = {
    "longitude": {"standard_name": "longitude", "long_name": "longitude",
                  "units": "degrees_east", "axis": "X"},
    "latitude": {"standard_name": "latitude", "long_name": "latitude",
                 "units": "degrees_north", "axis": "Y"},
    "depth": {"standard_name": "depth", "long_name": "depth below sea surface", "units": "m",
              "positive": "down", "axis": "Z"},
    "time": {"standard_name": "time", "long_name": "time", "axis": "T"},
}

# Provider names, lower case, in order of preference.
COORD_NAMES: dict[str, tuple[str, ...]] = {
    "longitude": ("longitude", "lon", "long", "x", "nav_lon"),
    "latitude": ("latitude", "lat", "y", "nav_lat"),
    "time": ("time", "time_counter", "valid_time", "t"),
    "depth": ("depth", "deptht", "depthu", "depthv", "lev"),
}
VAR_NAMES: dict[str, tuple[str, ...]] = {
    "u": ("u", "uo", "water_u", "ucur", "vozocrtx"),
    "v": ("v", "vo", "water_v", "vcur", "vomecrty"),
    "u_tide": ("u_tide", "utide"),
    "v_tide": ("v_tide", "vtide"),
    "elevation": ("elevation", "z", "band1", "topo", "height", "altitude", "deptho"),
}
VAR_STANDARD_NAMES: dict[str, tuple[str, ...]] = {
    "u": (CF["u"], "sea_water_x_velocity"),
    "v": (CF["v"], "sea_water_y_velocity"),
    "u_tide": (CF["u_tide"],),
    "v_tide": (CF["v_tide"],),
    "elevation": (CF["elevation"], "height_above_reference_ellipsoid", "height", "altitude",
                  "sea_floor_depth_below_geoid", "sea_floor_depth_below_sea_surface"),
}
_DOWNWARD_STANDARD_NAMES = {"sea_floor_depth_below_geoid", "sea_floor_depth_below_sea_surface",
                            "sea_floor_depth"}

_VELOCITY_UNITS = {"m s-1": 1.0, "m/s": 1.0, "m.s-1": 1.0, "m s**-1": 1.0, "meter second-1": 1.0,
                   "meters/second": 1.0, "metre second-1": 1.0, "m sec-1": 1.0, "": 1.0,
                   "cm s-1": 0.01, "cm/s": 0.01, "cm.s-1": 0.01}
_LENGTH_UNITS = {"m": 1.0, "meter": 1.0, "meters": 1.0, "metre": 1.0, "metres": 1.0, "": 1.0}
_EAST_UNITS = {"degrees_east", "degree_east", "degrees_e", "degree_e", "degreese", "degreee"}
_NORTH_UNITS = {"degrees_north", "degree_north", "degrees_n", "degree_n", "degreesn", "degreen"}

#: Provider attribution kept on canonical datasets (data licences ask for it).
_KEPT_PROVIDER_ATTRS = ("credit", "licence", "license", "institution", "references")


# --------------------------------------------------------------------------------------------
# opening
# --------------------------------------------------------------------------------------------

def open_raw(path: str | os.PathLike) -> xr.Dataset:
    """Open a NetCDF or GeoTIFF file lazily, in the provider's own layout.

    Parameters
    ----------
    path : str or os.PathLike
        A NetCDF-3/4 file or a GeoTIFF (``.tif``/``.tiff``).

    Returns
    -------
    xarray.Dataset
        Lazily indexed variables (no data values read).

    Raises
    ------
    DataError
        The file is missing, truncated, corrupt or not a NetCDF/GeoTIFF.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: file not found")
    if path.suffix.lower() in (".tif", ".tiff"):
        return _open_geotiff(path)
    _check_classic_netcdf(path)
    try:
        return xr.open_dataset(path, engine="netcdf4", chunks=None, cache=False)
    except (OSError, ValueError, RuntimeError) as err:
        raise DataError(f"{path}: cannot read as NetCDF (truncated or corrupt file?): "
                        f"{_one_line(err)}") from err


def _check_classic_netcdf(path: Path) -> None:
    """Raise DataError if a NetCDF-3 file is shorter than its header says.

    netCDF-C silently returns zeros when reading past the end of a truncated classic file,
    so a truncated GEBCO download would otherwise turn into a flat 0 m sea floor.
    """
    with open(path, "rb") as fh:
        head = fh.read(4)
        if len(head) < 4 or head[:3] != b"CDF" or head[3] not in (1, 2):
            return  # NetCDF-4/HDF5 (its library checks the length) or not NetCDF at all
        try:
            expected = _classic_data_end(fh, offset_size=4 * head[3])
        except (struct.error, ValueError) as err:
            raise DataError(f"{path}: truncated or corrupt NetCDF-3 header") from err
    size = path.stat().st_size
    if size < expected:
        raise DataError(f"{path}: truncated NetCDF-3 file ({size} bytes, its header declares "
                        f"{expected})")


_NC_TYPE_SIZE = {1: 1, 2: 1, 3: 2, 4: 4, 5: 4, 6: 8}


def _classic_data_end(fh, offset_size: int) -> int:
    """Byte offset where the data of a classic (CDF-1/CDF-2) file ends, from its header."""
    def i4() -> int:
        return struct.unpack(">i", fh.read(4))[0]

    def name() -> None:
        n = i4()
        fh.read(n + (-n) % 4)

    def attributes() -> None:
        i4()  # NC_ATTRIBUTE tag or ABSENT
        for _ in range(i4()):
            name()
            nc_type, n = i4(), i4()
            nbytes = n * _NC_TYPE_SIZE[nc_type]
            fh.read(nbytes + (-nbytes) % 4)

    numrecs = i4()
    i4()  # NC_DIMENSION tag or ABSENT
    dims = []
    for _ in range(i4()):
        name()
        dims.append(i4())
    attributes()
    i4()  # NC_VARIABLE tag or ABSENT
    fixed_end, records = 0, []  # records: (begin, bytes per record, vsize)
    for _ in range(i4()):
        name()
        dim_ids = [i4() for _ in range(i4())]
        attributes()
        nc_type, vsize = i4(), i4()
        begin = struct.unpack(">i" if offset_size == 4 else ">q", fh.read(offset_size))[0]
        shape = [dims[d] for d in dim_ids]
        nbytes = _NC_TYPE_SIZE[nc_type] * int(np.prod([n for n in shape if n != 0] or [1]))
        if shape and shape[0] == 0:  # record variable
            records.append((begin, nbytes, vsize))
        else:
            fixed_end = max(fixed_end, begin + nbytes)
    if records and numrecs > 0:
        recsize = records[0][1] if len(records) == 1 else sum(r[2] for r in records)
        fixed_end = max(fixed_end, *(b + (numrecs - 1) * recsize + n for b, n, _ in records))
    return fixed_end


def _open_geotiff(path: Path) -> xr.Dataset:
    """Open a single-band geographic GeoTIFF as ``elevation(latitude, longitude)``, lazily.

    Georeferencing comes from the GeoTIFF tags ``ModelPixelScale`` (33550) and
    ``ModelTiepoint`` (33922); ``GTRasterTypeGeoKey`` selects pixel-is-area (default, tie
    point at the pixel corner) or pixel-is-point. ``GDAL_NODATA`` (42113) becomes NaN.
    """
    import dask.array as da
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages.first
            meta = tif.geotiff_metadata or {}  # parsed GeoKeyDirectory, if any
            tags = {code: page.tags[code].value for code in (33550, 33922, 42113)
                    if code in page.tags}
            page_shape, page_dtype = tuple(page.shape), np.dtype(page.dtype)
            data_end = max((o + n for o, n in zip(page.dataoffsets, page.databytecounts)),
                           default=0)
    except (tifffile.TiffFileError, OSError, ValueError, KeyError) as err:
        raise DataError(f"{path}: cannot read as GeoTIFF (truncated or corrupt file?): "
                        f"{_one_line(err)}") from err
    size = path.stat().st_size
    if data_end > size:
        raise DataError(f"{path}: truncated GeoTIFF ({size} bytes, its image data end at "
                        f"byte {data_end})")
    scale, tie, nodata = tags.get(33550), tags.get(33922), tags.get(42113)
    if not scale or not tie or len(tie) < 6:
        raise DataError(f"{path}: GeoTIFF has no ModelPixelScale/ModelTiepoint tags "
                        "(not georeferenced)")
    if int(meta.get("GTModelTypeGeoKey", 2)) == 1:
        raise DataError(f"{path}: projected GeoTIFF; only geographic (lon/lat) grids are "
                        "supported")
    arr = da.from_array(_TiffArray(path, page_shape, page_dtype), chunks="auto",
                        meta=np.empty((0,) * len(page_shape), page_dtype))
    if arr.ndim == 3 and arr.shape[-1] == 1:
        arr = arr[..., 0]  # (y, x, band)
    elif arr.ndim == 3 and arr.shape[0] == 1:
        arr = arr[0]  # (band, y, x)
    if arr.ndim != 2:
        raise DataError(f"{path}: GeoTIFF has shape {tuple(arr.shape)}; expected one band")
    ny, nx = arr.shape
    sx, sy = float(scale[0]), float(scale[1])
    i0, j0, x0, y0 = float(tie[0]), float(tie[1]), float(tie[3]), float(tie[4])
    centre = 0.0 if int(meta.get("GTRasterTypeGeoKey", 1)) == 2 else 0.5
    lon = x0 + (np.arange(nx) - i0 + centre) * sx
    lat = y0 - (np.arange(ny) - j0 + centre) * sy
    if nodata is not None:
        try:
            arr = da.where(arr == float(nodata), np.nan, arr.astype("float32"))
        except ValueError:
            pass  # a non-numeric GDAL_NODATA string: nothing to mask
    return xr.Dataset(
        {"elevation": (("latitude", "longitude"), arr, {"units": "m"})},
        coords={"latitude": ("latitude", lat, {"units": "degrees_north"}),
                "longitude": ("longitude", lon, {"units": "degrees_east"})},
    )


class _TiffArray:
    """Array-like view of a TIFF's first image that opens the file only for each read.

    ``dask.array.from_array`` calls ``__getitem__`` per chunk; tifffile's zarr store then
    decodes only the strips/tiles that chunk needs, and no file handle outlives the read.
    """

    def __init__(self, path: Path, shape: tuple[int, ...], dtype: np.dtype):
        self.path, self.shape, self.dtype, self.ndim = path, shape, dtype, len(shape)

    def __getitem__(self, key) -> np.ndarray:
        import tifffile
        import zarr

        store = tifffile.imread(self.path, aszarr=True)
        try:
            return np.asarray(zarr.open(store, mode="r")[key])
        finally:
            store.close()


# --------------------------------------------------------------------------------------------
# structure: names, dimension order, ascending axes (index operations only)
# --------------------------------------------------------------------------------------------

def structure(ds: xr.Dataset, name: str, variables: Sequence[str],
              optional: Sequence[str] = ()) -> xr.Dataset:
    """Rename provider coordinates/variables to canonical names and order every axis.

    Parameters
    ----------
    ds : xarray.Dataset
        A provider dataset (lazy).
    name : str
        File name or URL used in error messages.
    variables : sequence of str
        Canonical variables that must be present (e.g. ``("u", "v")``).
    optional : sequence of str, default ()
        Canonical variables kept when present (e.g. ``("u_tide", "v_tide")``).

    Returns
    -------
    xarray.Dataset
        Only the canonical variables, canonical dims in canonical order, depth positive down,
        longitudes in −180..180 and every coordinate strictly ascending (duplicates dropped).
        No values are read except the 1-D coordinates.

    Raises
    ------
    DataError
        A missing coordinate or variable, a curvilinear grid, non-degree or swapped axes, or an
        unexpected dimension.
    """
    ds = _rename_coords(ds, name)
    ds = _select_variables(ds, name, variables, optional)
    _check_swapped(ds, name)
    ds = _fix_depth_sign(ds)
    ds = _wrap_longitude(ds)
    for dim in ("longitude", "latitude", "depth", "time"):
        if dim in ds.dims:
            ds = _ascending(ds, dim, name)
    return _order_dims(ds, name)


def _lookup(ds: xr.Dataset, candidates: Iterable[str]) -> str | None:
    present = {str(k).lower(): str(k) for k in (*ds.coords, *ds.dims)}
    for cand in candidates:
        if cand in present:
            return present[cand]
    return None


def _rename_coords(ds: xr.Dataset, name: str) -> xr.Dataset:
    renames = {}
    for canon, candidates in COORD_NAMES.items():
        found = _lookup(ds, candidates)
        if found is None:
            found = next((str(k) for k, c in ds.coords.items()
                          if c.attrs.get("standard_name") == canon and c.ndim == 1), None)
        if found is None:
            if canon in ("longitude", "latitude"):
                raise DataError(f"{name}: no {canon} coordinate (looked for "
                                f"{', '.join(candidates)})")
            continue
        if found not in ds.variables:
            raise DataError(f"{name}: dimension '{found}' has no coordinate values")
        if ds[found].ndim != 1:
            raise DataError(f"{name}: '{found}' is {ds[found].ndim}-D (curvilinear grid); only "
                            "regular latitude/longitude grids are supported")
        if found != canon:
            renames[found] = canon
    # Free canonical names held by unrelated variables (e.g. a 2-D 'latitude' field).
    clashes = [c for c in renames.values() if c in ds.variables and c not in renames]
    ds = ds.drop_vars(clashes)
    ds = ds.rename(renames)
    for canon in ("longitude", "latitude", "time", "depth"):
        if canon in ds.variables and canon not in ds.dims:
            if ds[canon].ndim == 0:
                ds = ds.expand_dims(canon)  # a scalar coordinate: one time, one level...
            else:
                ds = ds.swap_dims({ds[canon].dims[0]: canon})
    for canon in ("longitude", "latitude"):
        units = str(ds[canon].attrs.get("units", "")).strip().lower()
        if units and not (units.startswith("deg") or "°" in units):
            raise DataError(f"{name}: {canon} has units '{units}'; only geographic "
                            "coordinates in degrees are supported")
    return ds


def _find_variable(ds: xr.Dataset, canon: str) -> str | None:
    data_vars = {str(k).lower(): str(k) for k in ds.data_vars}
    for cand in VAR_NAMES[canon]:
        if cand in data_vars:
            return data_vars[cand]
    for key, var in ds.data_vars.items():
        if var.attrs.get("standard_name") in VAR_STANDARD_NAMES[canon]:
            return str(key)
    return None


def _select_variables(ds: xr.Dataset, name: str, variables: Sequence[str],
                      optional: Sequence[str]) -> xr.Dataset:
    chosen: dict[str, str] = {}
    for canon in (*variables, *optional):
        found = _find_variable(ds, canon)
        if found is None:
            if canon in variables:
                have = ", ".join(map(str, ds.data_vars)) or "none"
                raise DataError(f"{name}: missing variable '{canon}' (looked for "
                                f"{', '.join(VAR_NAMES[canon])}; the file has {have})")
            continue
        chosen[canon] = found
    out = xr.Dataset({canon: ds[src] for canon, src in chosen.items()}, attrs=ds.attrs)
    return out.drop_vars([c for c in out.coords if c not in out.dims])


def _check_swapped(ds: xr.Dataset, name: str) -> None:
    lat, lon = ds["latitude"], ds["longitude"]
    lat_units = str(lat.attrs.get("units", "")).lower()
    lon_units = str(lon.attrs.get("units", "")).lower()
    if (lat_units in _EAST_UNITS or lon_units in _NORTH_UNITS
            or lat.attrs.get("standard_name") == "longitude"
            or lon.attrs.get("standard_name") == "latitude"):
        raise DataError(f"{name}: latitude/longitude look swapped (the latitude axis carries "
                        f"units '{lat_units}', the longitude axis '{lon_units}')")
    lat_vals, lon_vals = np.asarray(lat.values, float), np.asarray(lon.values, float)
    for axis, vals in (("latitude", lat_vals), ("longitude", lon_vals)):
        if vals.size and not np.all(np.isfinite(vals)):
            raise DataError(f"{name}: {axis} coordinate contains NaN or infinite values")
    if lat_vals.size and np.abs(lat_vals).max() > 90.0:
        hint = ("latitude/longitude look swapped" if np.abs(lon_vals).max() <= 90.0
                else "latitude values outside ±90")
        raise DataError(f"{name}: {hint} (latitude spans {lat_vals.min():.6g}.."
                        f"{lat_vals.max():.6g})")
    if lon_vals.size and (lon_vals.min() < -180.0 or lon_vals.max() > 360.0):
        raise DataError(f"{name}: longitude values outside -180..360 (span "
                        f"{lon_vals.min():.6g}..{lon_vals.max():.6g})")


def _fix_depth_sign(ds: xr.Dataset) -> xr.Dataset:
    if "depth" not in ds.dims:
        return ds
    vals = np.asarray(ds["depth"].values, float)
    upward = str(ds["depth"].attrs.get("positive", "")).lower() == "up"
    if upward or (vals.size and vals.max() <= 0.0 and vals.min() < 0.0):
        ds = ds.assign_coords(depth=("depth", -vals, ds["depth"].attrs))
    return ds


def _wrap_longitude(ds: xr.Dataset) -> xr.Dataset:
    vals = np.asarray(ds["longitude"].values, float)
    if vals.size and vals.max() > 180.0:
        wrapped = (vals + 180.0) % 360.0 - 180.0
        ds = ds.assign_coords(longitude=("longitude", wrapped, ds["longitude"].attrs))
    return ds


def _ascending(ds: xr.Dataset, dim: str, name: str) -> xr.Dataset:
    vals = ds[dim].values
    if vals.size < 2:
        return ds
    step = np.diff(vals)
    if np.all(step > step.dtype.type(0)):
        return ds
    if np.all(step < step.dtype.type(0)):
        return ds.isel({dim: slice(None, None, -1)})
    order = np.argsort(vals, kind="stable")
    _, first = np.unique(vals[order], return_index=True)  # drop duplicates (e.g. 0 and 360)
    log.debug("%s: sorting %s (%d duplicate values dropped)", name, dim, vals.size - first.size)
    return ds.isel({dim: order[first]})


def _order_dims(ds: xr.Dataset, name: str) -> xr.Dataset:
    out = {}
    for canon, var in ds.data_vars.items():
        want = DIMS[str(canon)]
        for dim in var.dims:
            if dim not in want:
                if var.sizes[dim] != 1 and not (dim == "depth" and canon in TIDE_VARS):
                    raise DataError(f"{name}: variable '{canon}' has an unexpected dimension "
                                    f"'{dim}' of size {var.sizes[dim]}")
                var = var.isel({dim: 0}, drop=True)  # singleton, or the surface tide level
        if canon in CURRENT_VARS and "depth" not in var.dims:
            var = var.expand_dims(depth=[0.0])  # a surface-only file
        missing = [d for d in want if d not in var.dims]
        if missing:
            raise DataError(f"{name}: variable '{canon}' has no {'/'.join(missing)} dimension "
                            f"(dims {var.dims})")
        out[canon] = var.transpose(*want)
    return xr.Dataset(out, attrs=ds.attrs)


# --------------------------------------------------------------------------------------------
# subsetting (index operations only)
# --------------------------------------------------------------------------------------------

def subset(ds: xr.Dataset, name: str, bbox: Mapping[str, float],
           time: Mapping[str, str] | None = None,
           max_depth: float | None = None) -> xr.Dataset:
    """Cut a structured dataset to a bbox (one extra cell each side), time window and depth.

    Parameters
    ----------
    ds : xarray.Dataset
        The output of :func:`structure` (ascending coordinates).
    name : str
        File name used in error messages.
    bbox : Mapping[str, float]
        ``west``, ``east``, ``south``, ``north``, degrees.
    time : Mapping[str, str], optional
        ``start``, ``end``: ISO 8601 (UTC); the times bracketing the window (last one <=
        start, first one >= end) are kept. None: every time.
    max_depth : float, optional
        m, positive down: the levels <= ``max_depth`` plus the first deeper one are kept.
        None: every level.

    Returns
    -------
    xarray.Dataset
        The subset (index operations only, nothing read).

    Raises
    ------
    DataError
        The bbox or time window lies outside, or is not covered by, the data.
    """
    lon, lat = ds["longitude"].values, ds["latitude"].values
    west, east = float(bbox["west"]), float(bbox["east"])
    south, north = float(bbox["south"]), float(bbox["north"])
    lon_state, lat_state = _coverage(lon, west, east), _coverage(lat, south, north)
    if lon_state != "covered" or lat_state != "covered":
        what = "outside" if "outside" in (lon_state, lat_state) else "not covered by"
        swapped = (_coverage(lon, south, north) == "covered"
                   and _coverage(lat, west, east) == "covered")
        hint = "; latitude/longitude look swapped" if swapped else ""
        raise DataError(f"{name}: bbox lon {west:g}..{east:g}, lat {south:g}..{north:g} is "
                        f"{what} the data (lon {lon.min():.6g}..{lon.max():.6g}, lat "
                        f"{lat.min():.6g}..{lat.max():.6g}){hint}")
    index = {"longitude": _margin_slice(lon, west, east),
             "latitude": _margin_slice(lat, south, north)}
    if time is not None and "time" in ds.dims:
        index["time"] = _time_slice(ds["time"].values, time, name)
    if max_depth is not None and "depth" in ds.dims:
        deeper = int(np.searchsorted(ds["depth"].values, float(max_depth), side="right"))
        index["depth"] = slice(0, deeper + 1)
    return ds.isel(index)


def _coverage(vals: np.ndarray, lo: float, hi: float) -> str:
    """'covered', 'partial' or 'outside', with a tolerance of one grid step."""
    step = float(np.median(np.diff(vals))) if vals.size > 1 else 0.0
    tol = step * (1.0 + 1e-6)
    first, last = float(vals[0]), float(vals[-1])
    if hi < first - tol or lo > last + tol:
        return "outside"
    if lo < first - tol or hi > last + tol:
        return "partial"
    return "covered"


def _margin_slice(vals: np.ndarray, lo: float, hi: float) -> slice:
    start = max(int(np.searchsorted(vals, lo, side="left")) - 1, 0)
    stop = min(int(np.searchsorted(vals, hi, side="right")) + 1, vals.size)
    return slice(start, stop)


def parse_time(value: str | np.datetime64 | pd.Timestamp) -> np.datetime64:
    """ISO 8601 string → naive UTC ``datetime64[ns]``.

    Parameters
    ----------
    value : str, numpy.datetime64 or pandas.Timestamp
        A time; with a time zone it is converted to UTC, without one it is taken as UTC.

    Returns
    -------
    numpy.datetime64
        The time, ns precision, without a time zone.
    """
    ts = pd.Timestamp(value)
    if ts.tzinfo is not None:
        ts = ts.tz_convert("UTC").tz_localize(None)
    return np.datetime64(ts.to_datetime64(), "ns")


def _time_slice(times: np.ndarray, window: Mapping[str, str], name: str) -> slice:
    start, end = parse_time(window["start"]), parse_time(window["end"])
    times = times.astype("datetime64[ns]")
    span = f"{np.datetime_as_string(times[0], 's')}..{np.datetime_as_string(times[-1], 's')}"
    asked = f"{np.datetime_as_string(start, 's')}..{np.datetime_as_string(end, 's')}"
    if end < times[0] or start > times[-1]:
        raise DataError(f"{name}: time window {asked} is outside the data (times {span})")
    if start < times[0] or end > times[-1]:
        raise DataError(f"{name}: time window {asked} is not covered by the data (times {span})")
    first = int(np.searchsorted(times, start, side="right")) - 1
    last = int(np.searchsorted(times, end, side="left"))
    return slice(max(first, 0), min(last, times.size - 1) + 1)


# --------------------------------------------------------------------------------------------
# finalise: dask chunks, units, dtypes, attributes
# --------------------------------------------------------------------------------------------

def finalise(ds: xr.Dataset, name: str) -> xr.Dataset:
    """Chunk with dask, convert units and dtypes, and set canonical CF attributes.

    Velocities become float32 m s-1 (cm s-1 converted), elevation float32 m positive up (int16
    and positive-down depths are converted), ``time`` datetime64[ns], lon/lat/depth float64.
    Chunks: one time step and level, ``"auto"`` horizontally.

    Parameters
    ----------
    ds : xarray.Dataset
        A structured (and possibly subset) dataset.
    name : str
        File name used in error messages.

    Returns
    -------
    xarray.Dataset
        The canonical dataset, dask-backed, with ``ds``'s global attributes.

    Raises
    ------
    DataError
        A variable has unsupported units, or the time coordinate is not decodable.
    """
    chunks = {d: ("auto" if d in ("latitude", "longitude") else 1) for d in ds.dims}
    ds = ds.chunk(chunks)
    out = {}
    for canon, var in ds.data_vars.items():
        canon = str(canon)
        units = str(var.attrs.get("units", "")).strip().lower()
        if canon == "elevation":
            factor = _LENGTH_UNITS.get(units)
            downward = (str(var.attrs.get("positive", "")).lower() == "down"
                        or var.attrs.get("standard_name") in _DOWNWARD_STANDARD_NAMES)
            factor = None if factor is None else (-factor if downward else factor)
        else:
            factor = _VELOCITY_UNITS.get(units)
        if factor is None:
            raise DataError(f"{name}: variable '{canon}' has unsupported units '{units}'")
        data = var.astype("float32")
        if factor != 1.0:
            data = data * np.float32(factor)
        data.attrs = dict(VAR_ATTRS[canon])
        data.encoding = {}
        out[canon] = data
    result = xr.Dataset(out, attrs=ds.attrs)
    return set_coord_attrs(result, name)


def set_coord_attrs(ds: xr.Dataset, name: str) -> xr.Dataset:
    """Canonical dtypes and CF attributes on the coordinates (values unchanged).

    Parameters
    ----------
    ds : xarray.Dataset
        A dataset with canonical coordinate names.
    name : str
        File name used in error messages.

    Returns
    -------
    xarray.Dataset
        A copy with float64 ``longitude``, ``latitude``, ``depth``, datetime64[ns] ``time``,
        their :data:`COORD_ATTRS` and no encoding.

    Raises
    ------
    DataError
        The time coordinate is not a decoded date.
    """
    coords = {}
    for dim in ("longitude", "latitude", "depth"):
        if dim in ds.coords:
            coords[dim] = (dim, np.asarray(ds[dim].values, dtype="float64"), COORD_ATTRS[dim])
    if "time" in ds.coords:
        tvals = ds["time"].values
        if not np.issubdtype(tvals.dtype, np.datetime64):
            raise DataError(f"{name}: time coordinate is not a decodable date (dtype "
                            f"{tvals.dtype}, units {ds['time'].attrs.get('units')!r})")
        coords["time"] = ("time", tvals.astype("datetime64[ns]"), COORD_ATTRS["time"])
    ds = ds.assign_coords(coords)
    for dim in coords:
        ds[dim].encoding = {}
    return ds


def require_data(ds: xr.Dataset, name: str, variables: Sequence[str], where: str) -> None:
    """Raise DataError if every value of ``variables`` is NaN (computes over the subset).

    Parameters
    ----------
    ds : xarray.Dataset
        A (subset) canonical dataset.
    name : str
        File name used in error messages.
    variables : sequence of str
        The variables to check; those missing from ``ds`` are skipped.
    where : str
        Ends the error message, e.g. ``"in the requested bbox"``.

    Raises
    ------
    DataError
        Every value of every present variable is NaN.
    """
    present = [v for v in variables if v in ds]
    if not present:
        return
    import dask

    flags = dask.compute(*[ds[v].notnull().any() for v in present])
    if not any(bool(f) for f in flags):
        raise DataError(f"{name}: {'/'.join(present)} are all NaN {where}")


# --------------------------------------------------------------------------------------------
# provenance attributes
# --------------------------------------------------------------------------------------------

def to_json(obj) -> str:
    """Compact, key-sorted JSON for NetCDF attributes.

    Parameters
    ----------
    obj : object
        JSON-serialisable data (numpy scalars, arrays and paths allowed, see
        :func:`oneocean.io.canonical_json`).

    Returns
    -------
    str
        One line of JSON.
    """
    return json.dumps(json.loads(canonical_json(obj)), sort_keys=True, separators=(", ", ": "))


def file_records(paths: Iterable[str | os.PathLike]) -> list[dict[str, str]]:
    """Path and sha256 of each file, in order (hashes memoised per path, mtime and size).

    Parameters
    ----------
    paths : iterable of str or os.PathLike
        Existing files.

    Returns
    -------
    list of dict
        ``{"path": str, "sha256": hex str}`` per file.
    """
    records = []
    for p in paths:
        st = os.stat(p)
        records.append({"path": str(p), "sha256": _sha256(str(p), st.st_mtime_ns, st.st_size)})
    return records


@functools.lru_cache(maxsize=256)
def _sha256(path: str, mtime_ns: int, size: int) -> str:
    return sha256_file(path)


def is_canonical(attrs: Mapping) -> bool:
    """Whether ``attrs`` are those of a file written by :func:`write_canonical`.

    Parameters
    ----------
    attrs : Mapping
        A dataset's global attributes.

    Returns
    -------
    bool
        True when ``source`` is a known source kind and ``source_files`` is present.
    """
    return attrs.get("source") in SOURCE_KINDS and "source_files" in attrs


def provenance_attrs(attrs: Mapping, path: str | os.PathLike | None) -> dict:
    """Global attributes of a freshly read dataset.

    A canonical file keeps its own provenance; a provider file gets ``source="files"``,
    its path and sha256, and keeps only its attribution attributes (credit, licence, ...).

    Parameters
    ----------
    attrs : Mapping
        The raw dataset's global attributes.
    path : str or os.PathLike or None
        The file read; None for an opened (remote) dataset (no file record).

    Returns
    -------
    dict
        The attributes.
    """
    if is_canonical(attrs):
        return dict(attrs)
    out = {k: attrs[k] for k in _KEPT_PROVIDER_ATTRS if k in attrs}
    out["source"] = "files"
    out["source_files"] = to_json(file_records([path]) if path is not None else [])
    return out


# --------------------------------------------------------------------------------------------
# the reader
# --------------------------------------------------------------------------------------------

def read(source: str | os.PathLike | xr.Dataset, kind: str,
         variables: Sequence[str] | None = None, *, name: str | None = None,
         bbox: Mapping[str, float] | None = None, time: Mapping[str, str] | None = None,
         max_depth: float | None = None) -> xr.Dataset:
    """Read a provider or canonical file (or an opened dataset) into the canonical vocabulary.

    Parameters
    ----------
    source : str, os.PathLike or xarray.Dataset
        A file path, or an already opened (remote) dataset.
    kind : str
        ``"currents"`` or ``"bathymetry"``.
    variables : sequence of str, optional
        Canonical variables required (only these are kept, and the kind's other variables
        need not be present); default ``("u", "v")`` plus ``u_tide``/``v_tide`` when present
        for currents, ``("elevation",)`` for bathymetry.
    name : str, optional
        Label for error messages; default the path (``"dataset"`` for a dataset).
    bbox, time, max_depth : optional
        The subset, see :func:`subset`; ``time`` and ``max_depth`` apply only with a ``bbox``,
        which also requires some non-NaN data in it.

    Returns
    -------
    xarray.Dataset
        Canonical and dask-backed; ``attrs`` carry ``source`` and ``source_files``.

    Raises
    ------
    DataError
        The file is missing, unreadable or not convertible, or the subset has no data.
    ValueError
        ``kind`` is neither ``"currents"`` nor ``"bathymetry"``.
    """
    if isinstance(source, xr.Dataset):
        raw, path = source, None
        name = name or "dataset"
    else:
        path = Path(source)
        name = name or str(path)
        raw = open_raw(path)
    if kind == "currents":
        required, optional = (tuple(variables), ()) if variables else (CURRENT_VARS, TIDE_VARS)
    elif kind == "bathymetry":
        required, optional = tuple(variables or BATHYMETRY_VARS), ()
    else:
        raise ValueError(f"kind must be 'currents' or 'bathymetry', not {kind!r}")
    try:
        ds = structure(raw, name, required, optional)
        if bbox is not None:
            ds = subset(ds, name, bbox, time, max_depth)
        ds = finalise(ds, name)
        ds.attrs = provenance_attrs(raw.attrs, path)
        validate(ds, name, kind, partial=bool(variables))
        if bbox is not None:
            where = "in the requested bbox" + (" and time window" if time else "")
            require_data(ds, name, required, where)
    except OneOceanError:
        raw.close()
        raise
    except (OSError, RuntimeError) as err:
        raw.close()
        raise DataError(f"{name}: read failed (truncated or corrupt file?): "
                        f"{_one_line(err)}") from err
    return ds


# --------------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------------

def validate(ds: xr.Dataset, name: str, kind: str, partial: bool = False) -> xr.Dataset:
    """Check that ``ds`` follows contracts.md §1; return it unchanged.

    Parameters
    ----------
    ds : xarray.Dataset
        The dataset to check (not computed; only coordinates and attributes are inspected).
    name : str
        Label for error messages.
    kind : str
        ``"currents"`` or ``"bathymetry"``.
    partial : bool, default False
        If True, do not require the kind's full variable set (e.g. tides only).

    Returns
    -------
    xarray.Dataset
        ``ds`` itself.

    Raises
    ------
    DataError
        Naming ``name`` and the first violation found.
    """
    required = {"currents": CURRENT_VARS, "bathymetry": BATHYMETRY_VARS}[kind]
    problems = []
    if not partial:
        problems += [f"missing variable '{v}'" for v in required if v not in ds.data_vars]
    for var_name, var in ds.data_vars.items():
        want = DIMS.get(str(var_name))
        if want is None:
            problems.append(f"unexpected variable '{var_name}'")
        elif var.dims != want:
            problems.append(f"'{var_name}' has dims {var.dims}, expected {want}")
        elif var.attrs.get("units") != VAR_ATTRS[str(var_name)]["units"]:
            problems.append(f"'{var_name}' has units {var.attrs.get('units')!r}")
    for dim in ("longitude", "latitude", "depth", "time"):
        if dim not in ds.coords:
            if dim in ("longitude", "latitude") or (kind == "currents" and dim != "depth"):
                problems.append(f"missing coordinate '{dim}'")
            continue
        vals = ds[dim].values
        if vals.ndim != 1:
            problems.append(f"'{dim}' is not 1-D")
        elif vals.size > 1 and not np.all(np.diff(vals) > np.diff(vals).dtype.type(0)):
            problems.append(f"'{dim}' is not strictly ascending")
    if "longitude" in ds.coords and ds["longitude"].size:
        lon = ds["longitude"].values
        if lon.min() < -180.0 or lon.max() > 180.0:
            problems.append("longitude outside -180..180")
    if "latitude" in ds.coords and ds["latitude"].size:
        lat = ds["latitude"].values
        if lat.min() < -90.0 or lat.max() > 90.0:
            problems.append("latitude outside -90..90")
    if "depth" in ds.coords and ds["depth"].size and ds["depth"].values.min() < 0.0:
        problems.append("depth is not positive down")
    if "time" in ds.coords and ds["time"].dtype != np.dtype("datetime64[ns]"):
        problems.append(f"time has dtype {ds['time'].dtype}, expected datetime64[ns]")
    if problems:
        raise DataError(f"{name}: not a canonical {kind} dataset: {'; '.join(problems)}")
    return ds


# --------------------------------------------------------------------------------------------
# writing and download caching
# --------------------------------------------------------------------------------------------

def write_canonical(ds: xr.Dataset, out_path: str | os.PathLike, kind: str) -> None:
    """Validate ``ds`` and write it as one CF NetCDF4 file, atomically.

    Data are streamed chunk by chunk from the (lazy) sources, zlib level 4. On any failure no
    file is left at ``out_path``; read errors become a DataError naming the source files.

    Parameters
    ----------
    ds : xarray.Dataset
        A canonical dataset (:func:`read`); its attributes are kept, ``Conventions`` and
        ``oneocean_version`` added unless present.
    out_path : str or os.PathLike
        The NetCDF file to create or replace.
    kind : str
        ``"currents"`` or ``"bathymetry"``.

    Raises
    ------
    DataError
        ``ds`` is not canonical (:func:`validate`), or reading or writing failed.
    """
    validate(ds, str(out_path), kind)
    ds = ds.copy()
    ds.attrs = {"Conventions": "CF-1.11", "oneocean_version": __version__, **ds.attrs}
    from ..product.ncio import netcdf_encoding, write_netcdf_atomic

    try:
        # Streamed one time block at a time in a fixed order: the file's bytes do not depend
        # on dask's thread scheduling.
        write_netcdf_atomic(ds, out_path, netcdf_encoding(ds, zlib=True, complevel=4))
    except (OSError, RuntimeError) as err:
        sources = ", ".join(r["path"] for r in json.loads(ds.attrs.get("source_files", "[]")))
        raise DataError(f"{sources or out_path}: failed while writing {out_path}: "
                        f"{_one_line(err)}") from err


def _disk_chunks(shape: tuple[int, ...], tile: int = 512) -> tuple[int, ...]:
    """HDF5 chunks: one horizontal tile (<= ``tile`` x ``tile``) per time step and level."""
    return (*(1 for _ in shape[:-2]), *(max(min(n, tile), 1) for n in shape[-2:]))


def request_key(request: Mapping) -> str:
    """First 16 hex digits of the sha256 of the request's canonical JSON.

    Parameters
    ----------
    request : Mapping
        A JSON-serialisable request.

    Returns
    -------
    str
        16 hex digits.
    """
    return hashlib.sha256(canonical_json(dict(request)).encode()).hexdigest()[:16]


def cached_download(cache_dir: str | os.PathLike, prefix: str, request: Mapping,
                    download: Callable[[Path], None], *, retries: int = 3,
                    retry_wait_s: float = 5.0, label: str = "download",
                    before_download: Callable[[], None] | None = None) -> Path:
    """Return ``cache_dir/{prefix}-{key}.nc`` for ``request``, downloading it if needed.

    Parameters
    ----------
    cache_dir : str or os.PathLike
        Folder of completed downloads (created if missing).
    prefix : str
        File name prefix (e.g. the dataset id).
    request : Mapping
        JSON-serialisable request; its hash (:func:`request_key`) keys the cache file.
    download : callable
        ``download(part)`` writes the data to the temporary path ``part``
        (``.{name}.part.nc`` in ``cache_dir``), which is renamed onto the cache file only once
        complete.
    retries : int, default 3
        Attempts before giving up (at least one is made).
    retry_wait_s : float, default 5.0
        Wait between attempts, s.
    label : str, default "download"
        What is downloaded, for messages.
    before_download : callable, optional
        Called (without arguments) once before the first attempt (e.g. a credentials check);
        not called when the cache already holds the file.

    Returns
    -------
    pathlib.Path
        The cache file, ``cache_dir/{prefix}-{key}.nc``.

    Raises
    ------
    DataError
        All attempts failed. OneOcean errors raised by ``download`` are not retried.
    """
    final = Path(cache_dir) / f"{prefix}-{request_key(request)}.nc"
    if final.is_file():
        log.info("%s: using cached %s", label, final)
        return final
    if before_download is not None:
        before_download()
    final.parent.mkdir(parents=True, exist_ok=True)
    part = final.with_name(f".{final.stem}.part.nc")
    last: BaseException | None = None
    retries = max(int(retries), 1)
    for attempt in range(1, retries + 1):
        try:
            part.unlink(missing_ok=True)
            download(part)
            if not part.is_file():
                raise OSError(f"the download did not produce {part}")
            os.replace(part, final)
            return final
        except OneOceanError:
            part.unlink(missing_ok=True)
            raise
        except Exception as err:  # network and service errors of any library: retry
            part.unlink(missing_ok=True)
            last = err
            log.warning("%s: attempt %d/%d failed: %s", label, attempt, retries, err)
            if attempt < retries:
                _time.sleep(float(retry_wait_s))
    raise DataError(f"{label}: download failed after {retries} attempt(s): {_one_line(last)}")


def _one_line(err: BaseException | None) -> str:
    return " ".join(str(err).split()) or type(err).__name__


__all__ = [
    "BATHYMETRY_VARS", "COORD_ATTRS", "CURRENT_VARS", "DIMS", "TIDE_VARS", "VAR_ATTRS",
    "cached_download", "file_records", "finalise", "is_canonical", "open_raw", "parse_time",
    "read", "request_key", "require_data", "set_coord_attrs", "structure", "subset", "to_json",
    "validate", "write_canonical",
]
