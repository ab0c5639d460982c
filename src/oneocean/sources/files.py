"""Source kind ``files``: local currents / tides / bathymetry files the user already has.

Also home of :func:`attach_tides`, shared with the ``cmems`` source: tides and currents
often come on different time axes (hourly tides, daily-mean currents) and the canonical
currents dataset has one ``time`` coordinate.
"""

from __future__ import annotations

import os
from typing import Mapping

import numpy as np
import xarray as xr

from ..errors import ConfigError, DataError
from . import model
from .base import CURRENT_VARS, TIDE_VARS, VAR_ATTRS, file_records, open_raw, read, to_json


def attach_tides(currents: xr.Dataset, tides: xr.Dataset, name: str) -> xr.Dataset:
    """Put ``u_tide``/``v_tide`` on the coordinates of ``currents``.

    Horizontal: tides are taken as they are when their grid equals the currents' grid (to
    1e-6 degrees), else bilinearly interpolated onto it. Time: when the axes differ, the tide
    times inside the currents' time span become the time axis and ``u``/``v`` are linearly
    interpolated onto them (a single current time is repeated), which
    ``attrs["time_interpolation"]`` records; tides are never interpolated in time.

    Parameters
    ----------
    currents : xarray.Dataset
        Canonical ``u``, ``v`` (time, depth, latitude, longitude).
    tides : xarray.Dataset
        Canonical ``u_tide``, ``v_tide`` (time, latitude, longitude).
    name : str
        The tide file, for error messages.

    Returns
    -------
    xarray.Dataset
        All four variables, float32 m s-1, on one grid, with the currents' attributes.

    Raises
    ------
    DataError
        The tide times do not overlap the currents' times.
    """
    tides = tides[list(TIDE_VARS)]
    same_grid = all(
        currents.sizes[d] == tides.sizes[d]
        and np.allclose(currents[d].values, tides[d].values, rtol=0.0, atol=1e-6)
        for d in ("latitude", "longitude"))
    if same_grid:
        tides = tides.assign_coords(latitude=currents["latitude"],
                                    longitude=currents["longitude"])
    else:
        tides = tides.interp(latitude=currents["latitude"], longitude=currents["longitude"])
    attrs = dict(currents.attrs)
    t_cur, t_tide = currents["time"].values, tides["time"].values
    if not np.array_equal(t_cur, t_tide):
        inside = (t_tide >= t_cur[0]) & (t_tide <= t_cur[-1])
        if not inside.any():
            raise DataError(f"{name}: tide times do not overlap the currents' times "
                            f"({np.datetime_as_string(t_cur[0], 's')}.."
                            f"{np.datetime_as_string(t_cur[-1], 's')})")
        times = t_tide[inside]
        tides = tides.sel(time=times)
        if t_cur.size == 1:
            currents = currents.reindex(time=times, method="nearest")
        else:
            currents = currents.interp(time=times)
        attrs["time_interpolation"] = "u, v linearly interpolated in time onto the tide times"
    merged = {}
    for var_name, var in (*currents[list(CURRENT_VARS)].data_vars.items(),
                          *tides.data_vars.items()):
        var = var.astype("float32")
        var.attrs = dict(VAR_ATTRS[str(var_name)])
        merged[str(var_name)] = var
    out = xr.Dataset(merged, attrs=attrs)
    for dim in out.coords:
        out[dim].attrs = dict(currents[dim].attrs)
    return out


def _required(cfg: Mapping, key: str) -> str:
    value = cfg["files"].get(key)
    if not value:
        raise ConfigError(f"files.{key}: required when sources uses kind 'files'")
    return str(value)


def _has_tides(path: str) -> bool:
    raw = open_raw(path)
    try:
        names = {str(v).lower() for v in raw.data_vars}
        return {"utide", "vtide"} <= names or {"u_tide", "v_tide"} <= names
    finally:
        raw.close()


def currents(cfg: Mapping, cache_dir: str | os.PathLike | None = None) -> xr.Dataset:
    """Canonical currents from ``files.currents`` (tides from ``files.tides`` if enabled).

    When ``sources.tides`` is true and ``files.tides`` is null, the currents file itself
    must carry ``utide``/``vtide`` (or ``u_tide``/``v_tide``). Cut to the region's bbox, time
    window and depth (:func:`~oneocean.sources.base.subset`); tides joined by
    :func:`attach_tides`.

    Parameters
    ----------
    cfg : Mapping
        The validated config (``files``, ``sources.tides``, ``region``).
    cache_dir : str or os.PathLike, optional
        Unused (the source kinds share one signature).

    Returns
    -------
    xarray.Dataset
        Canonical, dask-backed; attrs ``source="files"`` and ``source_files`` (the currents
        file and a separate tide file).

    Raises
    ------
    ConfigError
        ``files.currents`` is not set, or tides are enabled but there is no tide file and the
        currents file has no tide variables.
    DataError
        A file is missing, unreadable or does not cover the region.
    """
    region = cfg["region"]
    path = _required(cfg, "currents")
    if model.detect(path) is not None:
        if cfg["sources"]["tides"]:
            raise ConfigError(f"sources.tides: must be false for model output ({path}): its "
                              "u, v already carry the model's own tide")
        ds, _ = model.read_model(path, region)
        return ds
    ds = read(path, "currents", CURRENT_VARS, bbox=region["bbox"], time=region["time"],
              max_depth=region["max_depth_m"])
    records = file_records([path])
    if cfg["sources"]["tides"]:
        tide_path = cfg["files"].get("tides")
        if not tide_path:
            if not _has_tides(path):
                raise ConfigError(f"files.tides: sources.tides is true but files.tides is "
                                  f"null and {path} has no utide/vtide")
            tide_path = path
        tides = read(tide_path, "currents", TIDE_VARS, bbox=region["bbox"],
                     time=region["time"])
        ds = attach_tides(ds, tides, str(tide_path))
        if str(tide_path) != path:
            records += file_records([tide_path])
    ds.attrs.update(source="files", source_files=to_json(records))
    return ds


def bathymetry(cfg: Mapping, cache_dir: str | os.PathLike | None = None) -> xr.Dataset:
    """Canonical ``elevation`` from ``files.bathymetry`` (NetCDF or GeoTIFF).

    Parameters
    ----------
    cfg : Mapping
        The validated config (``files.bathymetry``, ``region.bbox``).
    cache_dir : str or os.PathLike, optional
        Unused (the source kinds share one signature).

    Returns
    -------
    xarray.Dataset
        Canonical, dask-backed ``elevation`` (m, positive up) cut to the bbox; attrs
        ``source="files"`` and ``source_files``.

    Raises
    ------
    ConfigError
        ``files.bathymetry`` is not set.
    DataError
        The file is missing, unreadable or does not cover the bbox.
    """
    path = _required(cfg, "bathymetry")
    if model.detect(path) is not None:
        _, ds = model.read_model(path, cfg["region"])
        return ds
    ds = read(path, "bathymetry", bbox=cfg["region"]["bbox"])
    ds.attrs.update(source="files", source_files=to_json(file_records([path])))
    return ds
