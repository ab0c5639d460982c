"""Backend exports of a product: the grid export (contracts §3) and the temporal export (§4).

Both are ``.npz`` files written with :func:`oneocean.io.write_npz_atomic` (byte-deterministic),
or, when the output path ends in ``.zarr`` (config ``exports.format: zarr``), zarr stores of the
same arrays (:func:`oneocean.product.zarrio.write_arrays_zarr`: consolidated, atomic, deterministic);
:func:`oneocean.product.zarrio.read_npz`, hence the engine's ``load_grid`` and the scene backend, read
either. They record the product's path, sha256 and the indices used for the extraction.

Metres mapping: an equirectangular local tangent plane at the centre of the product grid,
``x = (lon - origin_lon) * m_per_deg_lon`` (east), ``z = (lat - origin_lat) * m_per_deg_lat``
(north), with a spherical Earth of radius :data:`EARTH_RADIUS_M`.

Boundaries (one rule for both backends; the engine's ``sample_current*`` give the temporal
export's value at the same point):

* vertical: each node's column holds its deepest valid value below it (a level above the
  shallowest valid one takes that one), :func:`oneocean.engine.grid.hold_levels`; depth is
  linear between the bracketing levels, clamped to the first level above it;
* horizontal: the bilinear weights of the four corners, restricted to corners with currents
  (``current_mask``) and renormalised; the temporal export needs at least half of the weight
  on such corners (the engine fades to 0 below that);
* the tide layers use the same corner weights.
"""

from __future__ import annotations

import json

import numpy as np
import xarray as xr

from ..errors import DataError
from ..io import write_npz_atomic
from .zarrio import is_zarr, open_product, sha256_path, write_arrays_zarr
from ..engine import libm

__all__ = ["export_grid", "export_temporal", "metres_per_degree", "default_point",
           "point_weights", "EARTH_RADIUS_M"]

#: Mean Earth radius (IUGG), m.
EARTH_RADIUS_M = 6371008.8


def metres_per_degree(lat0_deg: float) -> tuple[float, float]:
    """Metres per degree of latitude and of longitude at a latitude (equirectangular, spherical
    Earth of radius :data:`EARTH_RADIUS_M`).

    Parameters
    ----------
    lat0_deg : float
        The latitude, degrees.

    Returns
    -------
    m_per_deg_lat, m_per_deg_lon : float
        Metres per degree of latitude, and of longitude (scaled by ``cos(lat0_deg)``), m.
    """
    m_lat = np.pi * EARTH_RADIUS_M / 180.0
    return float(m_lat), float(m_lat * libm.cos(np.deg2rad(lat0_deg)))


def _spacing(axis: np.ndarray, fallback: float) -> float:
    return float((axis[-1] - axis[0]) / (axis.size - 1)) if axis.size > 1 else float(fallback)


def _time_axis(times: np.ndarray) -> tuple[float, np.ndarray]:
    ns = times.astype("datetime64[ns]").astype(np.int64)
    return float(ns[0]) * 1e-9, (ns - ns[0]).astype(np.float64) * 1e-9


def _source_meta(product_path, ds: xr.Dataset, meta: dict | None) -> dict:
    return {**(meta or {}), "source_path": str(product_path),
            "source_sha256": sha256_path(product_path),
            "region": str(ds.attrs.get("region", (meta or {}).get("region", ""))),
            "variant": str(ds.attrs.get("variant", (meta or {}).get("variant", ""))),
            "source_kind": str(ds.attrs.get("source", "")),
            "config_hash": str(ds.attrs.get("config_hash", ""))}


def _write_export(out_path, arrays: dict) -> None:
    """An export's arrays as ``.npz``, or as a zarr store when ``out_path`` ends in ``.zarr``."""
    if is_zarr(out_path):
        write_arrays_zarr(out_path, arrays)
    else:
        write_npz_atomic(out_path, arrays)


def _open(product_path) -> xr.Dataset:
    """Open a product (NetCDF file or zarr store, by suffix) lazily, with a small HDF5 chunk
    cache for NetCDF (it is read once, step by step)."""
    from .build import netcdf_chunk_cache

    try:
        with netcdf_chunk_cache():
            return open_product(product_path, cache=False)
    except (OSError, ValueError, KeyError) as err:
        raise DataError(f"{product_path}: cannot open the product ({err})") from None


def export_grid(product_path, out_path, meta: dict | None = None) -> None:
    """Write the core backend's grid export (contracts §3): every time and depth of the product.

    Currents are boundary-ready for the engine: at a node with currents, a level without one
    holds the column's deepest valid value (:func:`oneocean.engine.grid.hold_levels`); nodes
    without currents (``current_mask == 0``: land, or water the currents do not cover) are 0,
    tide layers included.

    Parameters
    ----------
    product_path : path
        A product, NetCDF file or zarr store (contracts §2).
    out_path : path
        Output ``.npz`` (or a zarr store of the same arrays when it ends in ``.zarr``); ``u, v``
        (nt, nz, ny, nx) float32 m s-1, held below the deepest valid level, zero where
        ``current_mask == 0``; ``u_tide, v_tide`` (nt, ny, nx) float32, zero where
        ``current_mask == 0`` or without tide; axes, ``elevation`` (ny, nx) float32 m,
        ``land_mask`` (ny, nx) float32, ``valid_mask`` (nz, ny, nx) uint8, ``current_mask``
        (ny, nx) uint8, the lat/lon <-> metres mapping and ``meta_json`` (see contracts §3).
    meta : dict, optional
        Extra fields for ``meta_json`` (e.g. region, variant).

    Raises
    ------
    DataError
        The product cannot be opened.
    """
    from ..engine.grid import fill_columns

    with _open(product_path) as ds:
        lat = ds["latitude"].values.astype(np.float64)
        lon = ds["longitude"].values.astype(np.float64)
        depth = ds["depth"].values.astype(np.float64)
        times = ds["time"].values
        valid = ds["valid_mask"].values.astype(np.uint8)
        land = ds["land_mask"].values.astype(np.float32)
        elev = ds["elevation"].values.astype(np.float32)
        current = valid.any(axis=0)
        nt, nz, ny, nx = times.size, depth.size, lat.size, lon.size
        u = np.zeros((nt, nz, ny, nx), np.float32)
        v = np.zeros_like(u)
        ut = np.zeros((nt, ny, nx), np.float32)
        vt = np.zeros_like(ut)
        has_tide = int(ds.attrs.get("has_tide", 0)) == 1 and "u_tide" in ds
        keep = valid.astype(bool)
        for k in range(nt):                       # one time step in memory at a time
            u[k] = fill_columns(np.where(keep, ds["u"][k].values, 0.0).astype(np.float32),
                                keep)
            v[k] = fill_columns(np.where(keep, ds["v"][k].values, 0.0).astype(np.float32),
                                keep)
            if has_tide:
                ut[k] = np.where(current, np.nan_to_num(ds["u_tide"][k].values), 0.0)
                vt[k] = np.where(current, np.nan_to_num(ds["v_tide"][k].values), 0.0)
        res = float(ds.attrs.get("resolution_deg", np.nan))
        info = _source_meta(product_path, ds, meta)
    origin_lat, origin_lon = 0.5 * (lat[0] + lat[-1]), 0.5 * (lon[0] + lon[-1])
    m_lat, m_lon = metres_per_degree(origin_lat)
    t0, time_s = _time_axis(times)
    info["extraction"] = {"time_index": [0, nt], "depth_index": [0, nz],
                          "latitude_index": [0, ny], "longitude_index": [0, nx],
                          "time_first": str(times[0])[:19], "time_last": str(times[-1])[:19],
                          "depth_m": depth.tolist()}
    arrays = {
        "u": u, "v": v, "u_tide": ut, "v_tide": vt,
        "has_tide": np.array(1 if has_tide else 0, np.int8),
        "time_s": time_s, "time0_unix_s": np.array(t0, np.float64),
        "depth": depth, "lat": lat, "lon": lon,
        "x0_m": np.array((lon[0] - origin_lon) * m_lon),
        "dx_m": np.array(_spacing(lon, res) * m_lon),
        "z0_m": np.array((lat[0] - origin_lat) * m_lat),
        "dz_m": np.array(_spacing(lat, res) * m_lat),
        "origin_lat": np.array(origin_lat), "origin_lon": np.array(origin_lon),
        "m_per_deg_lat": np.array(m_lat), "m_per_deg_lon": np.array(m_lon),
        "elevation": elev, "land_mask": land, "valid_mask": valid,
        "current_mask": current.astype(np.uint8),
        "meta_json": np.array(json.dumps(info, sort_keys=True)),
    }
    _write_export(out_path, arrays)


#: The default point keeps this far from the grid's edges when it can (m): a scene's square
#: (``scenes.list[].size_m``, 600 m by default) around it must fit inside the grid, which on
#: a few-km coastal domain the wettest column nearest the centre may not allow.
EDGE_MARGIN_M = 500.0


def default_point(ds: xr.Dataset) -> tuple[float, float]:
    """A default point in water: the node of a wettest column closest to the domain centre.

    A wettest column has the most valid depth levels; the distance is measured in metres, ties
    go to the lowest flat index. Only columns at least :data:`EDGE_MARGIN_M` from every edge of
    the grid compete (all columns if none of those is wet).

    Parameters
    ----------
    ds : xr.Dataset
        A product (its ``latitude``, ``longitude`` and ``valid_mask``).

    Returns
    -------
    lat, lon : float
        The node, degrees.

    Raises
    ------
    DataError
        The product has no valid water column.
    """
    lat, lon = ds["latitude"].values, ds["longitude"].values
    count = ds["valid_mask"].values.astype(np.int64).sum(axis=0)
    if count.max() == 0:
        raise DataError("product has no valid water column")
    lat0, lon0 = 0.5 * (lat[0] + lat[-1]), 0.5 * (lon[0] + lon[-1])
    m_lat, m_lon = metres_per_degree(lat0)
    d2 = ((lat[:, None] - lat0) * m_lat) ** 2 + ((lon[None, :] - lon0) * m_lon) ** 2
    y_m = (lat - lat[0]) * m_lat
    x_m = (lon - lon[0]) * m_lon
    inner = ((np.minimum(y_m, y_m[-1] - y_m)[:, None] >= EDGE_MARGIN_M)
             & (np.minimum(x_m, x_m[-1] - x_m)[None, :] >= EDGE_MARGIN_M))
    if not (inner & (count > 0)).any():
        inner = np.ones_like(inner)
    wettest = inner & (count == count[inner].max())
    d2 = np.where(wettest, d2, np.inf)
    j, i = np.unravel_index(int(np.argmin(d2)), d2.shape)
    return float(lat[j]), float(lon[i])


def _bracket(axis: np.ndarray, x: float) -> tuple[int, int, float]:
    """Bracketing indices and weight of ``x`` on an ascending axis (clamped to its ends)."""
    if axis.size == 1:
        return 0, 0, 0.0
    i0 = int(np.clip(np.searchsorted(axis, x, side="right") - 1, 0, axis.size - 2))
    w = float(np.clip((x - axis[i0]) / (axis[i0 + 1] - axis[i0]), 0.0, 1.0))
    return i0, i0 + 1, w


def _cell_bottom(depth: np.ndarray) -> float:
    """Bottom of the deepest level's cell: half the last spacing below it (a single level at
    ``d`` stands for the layer [0, 2 d])."""
    return float(depth[-1] + (0.5 * (depth[-1] - depth[-2]) if depth.size > 1 else depth[0]))


def point_weights(glat: np.ndarray, glon: np.ndarray, depth: np.ndarray, land: np.ndarray,
                  valid: np.ndarray, lat: float, lon: float, depth_m: float | None,
                  where: str = "product", elevation: np.ndarray | None = None) -> dict:
    """Interpolation indices and weights of a point on a product grid (the engine's rule).

    Horizontal: the bilinear weights of the four corners, restricted to corners with currents
    (``current_mask = any(valid)``) and renormalised; at least half of the weight must be on
    such corners. Vertical: linear between the bracketing levels (a depth above the first level
    takes the first level; one below the deepest level but within its cell takes the deepest
    level), each corner's column holding its deepest valid value below it
    (:func:`oneocean.engine.grid.hold_levels`). The tide layers use the same corner weights.

    Parameters
    ----------
    glat, glon : (ny,), (nx,) float64
        The grid axes, ascending, degrees.
    depth : (nz,) float64
        The levels, ascending, m, positive down.
    land : (ny, nx) int
        1 = land (from the bathymetry).
    valid : (nz, ny, nx) int
        1 = valid current.
    lat, lon : float
        The point (degrees).
    depth_m : float or None
        Depth (m, positive down); None = the first level.
    where : str, default "product"
        Names the product in error messages.
    elevation : (ny, nx) float, optional
        Bathymetry (m, positive up): the depth must not lie below its bilinear seafloor.

    Returns
    -------
    dict
        ``latitude_index``/``longitude_index``/``depth_index`` [lo, hi] and their ``*_weight``
        (of hi); ``depth_m`` (the depth used); ``depth_weights`` {k: w}; ``corner_weights``
        [(j, i, w)] over the corners with currents (summing to 1); ``source_levels``
        {k: [ks per corner]} (the product level each corner reads at level k);
        ``tide_weights`` (= ``corner_weights``); ``current_weight`` (the defined share).

    Raises
    ------
    DataError
        Outside the grid or below the deepest level's cell, on land (more than half of the
        bilinear weight on land nodes), without currents (less than half of it on nodes with
        currents: outside the currents' coverage) or below the seafloor.
    """
    eps = 1e-9
    if not (glat[0] - eps <= lat <= glat[-1] + eps and glon[0] - eps <= lon <= glon[-1] + eps):
        raise DataError(f"{where}: point ({lat}, {lon}) is outside the product grid "
                        f"lat [{glat[0]}, {glat[-1]}], lon [{glon[0]}, {glon[-1]}]")
    depth_m = float(depth[0]) if depth_m is None else float(depth_m)
    if not np.isfinite(depth_m) or depth_m > _cell_bottom(depth) + eps:
        raise DataError(f"{where}: depth {depth_m} m is below the deepest level {depth[-1]} m "
                        f"(its cell ends at {_cell_bottom(depth):.6g} m)")
    j0, j1, wy = _bracket(glat, lat)
    i0, i1, wx = _bracket(glon, lon)
    k0, k1, wz = _bracket(depth, min(max(depth_m, depth[0]), depth[-1]))
    corners = [(j0, i0, (1 - wy) * (1 - wx)), (j0, i1, (1 - wy) * wx),
               (j1, i0, wy * (1 - wx)), (j1, i1, wy * wx)]
    water_weight = sum(w for j, i, w in corners if land[j, i] == 0)
    if water_weight < 0.5:
        raise DataError(f"{where}: point ({lat}, {lon}) is on land")
    if elevation is not None:
        floor = -sum(w * float(elevation[j, i]) for j, i, w in corners)
        if depth_m > floor + eps:
            raise DataError(f"{where}: depth {depth_m} m at ({lat}, {lon}) is below the "
                            f"seafloor ({floor:.6g} m)")
    ok = np.asarray(valid).astype(bool)
    current = ok.any(axis=0)
    defined = [(j, i, w) for j, i, w in corners if current[j, i] and w > 0.0]
    total = sum(w for _, _, w in defined)
    if total < 0.5 - 1e-12:
        raise DataError(f"{where}: no current defined at ({lat}, {lon}) (only "
                        f"{total:.3f} of the bilinear weight on nodes with currents: outside "
                        "the currents' coverage or next to land)")
    weights = [(j, i, w / total) for j, i, w in defined]
    zw = {k0: 1.0 - wz, k1: wz} if k1 != k0 else {k0: 1.0}
    zw = {k: w for k, w in zw.items() if w > 0.0}
    held = {}
    for j, i, _ in weights:
        col = hold_column(ok[:, j, i])
        for k in zw:
            held.setdefault(k, []).append(int(col[k]))
    return {"latitude_index": [j0, j1], "latitude_weight": wy,
            "longitude_index": [i0, i1], "longitude_weight": wx,
            "depth_index": [k0, k1], "depth_weight": wz, "depth_m": depth_m,
            "depth_weights": zw, "corner_weights": weights, "source_levels": held,
            "current_weight": total, "tide_weights": weights}


def hold_column(valid_column: np.ndarray) -> np.ndarray:
    """:func:`oneocean.engine.grid.hold_levels` of one column.

    Parameters
    ----------
    valid_column : (nz,) bool or int
        1 = the product defines a current at this level.

    Returns
    -------
    (nz,) int64
        The level each level reads (a column without a valid level reads level 0).
    """
    from ..engine.grid import hold_levels

    return hold_levels(np.asarray(valid_column).reshape(-1, 1, 1))[:, 0, 0]


def export_temporal(product_path, out_path, lat: float | None, lon: float | None,
                    depth_m: float | None = None, meta: dict | None = None) -> None:
    """Write the scene backend's temporal export (contracts §4): a current time series at a point.

    Interpolation as in :func:`point_weights` (the engine's rule: the grid export sampled by
    ``oneocean.engine.sample_current_data`` with gain 1 gives ``u + u_tide`` at the same point).

    Parameters
    ----------
    product_path : path
        A product, NetCDF file or zarr store (contracts §2).
    out_path : path
        Output ``.npz`` (or a zarr store of the same arrays when it ends in ``.zarr``) with
        ``time`` datetime64[s] (nt,), ``time_s``, ``u, v, u_tide, v_tide`` float64 (nt,) m s-1,
        ``lat, lon, depth`` float64 (), ``indices_json``, ``meta_json``.
    lat, lon : float or None
        Point (degrees); None for :func:`default_point`.
    depth_m : float or None
        Depth (m, positive down); None = the product's first level (works for surface-only
        products). A depth above the first level takes the first level; one below the deepest
        level but within its cell (half the last spacing; [0, 2 d] for a single level d) takes
        the deepest level.
    meta : dict, optional
        Extra fields for ``meta_json``.

    Raises
    ------
    DataError
        The product cannot be opened or has no valid water column, or the point lies outside
        the grid or below the deepest level's cell, on land, outside the currents' coverage, or
        below the seafloor.
    """
    with _open(product_path) as ds:
        glat, glon = ds["latitude"].values, ds["longitude"].values
        depth = ds["depth"].values.astype(float)
        if lat is None or lon is None:
            lat, lon = default_point(ds)
        lat, lon = float(lat), float(lon)
        requested = None if depth_m is None else float(depth_m)
        pw = point_weights(glat, glon, depth, ds["land_mask"].values, ds["valid_mask"].values,
                           lat, lon, requested, str(product_path),
                           elevation=ds["elevation"].values.astype(np.float64))
        depth_m = pw["depth_m"]
        zw, weights, held = pw["depth_weights"], pw["corner_weights"], pw["source_levels"]
        j0, i0 = pw["latitude_index"][0], pw["longitude_index"][0]
        j1, i1 = pw["latitude_index"][1], pw["longitude_index"][1]
        times = ds["time"].values
        nt = times.size
        klo = min(min(v) for v in held.values())
        khi = max(max(v) for v in held.values())
        box = {"depth": slice(klo, khi + 1), "latitude": slice(j0, j1 + 1),
               "longitude": slice(i0, i1 + 1)}
        ub = ds["u"].isel(box).values.astype(np.float64)      # (nt, levels, <=2, <=2)
        vb = ds["v"].isel(box).values.astype(np.float64)
        u, v = np.zeros(nt), np.zeros(nt)
        for k, wk in zw.items():
            for (j, i, w), ks in zip(weights, held[k]):
                u += wk * w * ub[:, ks - klo, j - j0, i - i0]
                v += wk * w * vb[:, ks - klo, j - j0, i - i0]
        ut, vt = np.zeros(nt), np.zeros(nt)
        has_tide = int(ds.attrs.get("has_tide", 0)) == 1 and "u_tide" in ds
        if has_tide:
            tbox = {"latitude": box["latitude"], "longitude": box["longitude"]}
            utb = np.nan_to_num(ds["u_tide"].isel(tbox).values.astype(np.float64))
            vtb = np.nan_to_num(ds["v_tide"].isel(tbox).values.astype(np.float64))
            for j, i, w in pw["tide_weights"]:
                ut += w * utb[:, j - j0, i - i0]
                vt += w * vtb[:, j - j0, i - i0]
        info = _source_meta(product_path, ds, meta)
    if not (np.isfinite(u).all() and np.isfinite(v).all()):
        raise DataError(f"{product_path}: NaN current at a valid node near ({lat}, {lon})")
    _, time_s = _time_axis(times)
    indices = {**pw, "time_index": [0, nt], "has_tide": has_tide}
    arrays = {
        "time": times.astype("datetime64[s]"), "time_s": time_s,
        "u": u, "v": v, "u_tide": ut, "v_tide": vt,
        "lat": np.array(lat), "lon": np.array(lon), "depth": np.array(depth_m),
        "indices_json": np.array(json.dumps(indices, sort_keys=True)),
        "meta_json": np.array(json.dumps({**info, "point": {"lat": lat, "lon": lon,
                                                             "depth_m": depth_m,
                                                             "depth_m_requested": requested}},
                                         sort_keys=True)),
    }
    _write_export(out_path, arrays)
