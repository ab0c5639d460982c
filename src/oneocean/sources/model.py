"""Coastal model output → canonical currents and bathymetry on a regular grid.

Three layouts, detected from the file (:func:`detect`):

``regular``
    A model on a regular lon/lat grid with its own depth and land mask (MOHID-like): ``u``/``v``
    (time[, layer], lat, lon), ``bathymetry`` (positive down), ``mask``.
``curvilinear``
    ROMS: ``lon_rho``/``lat_rho`` (2-D), staggered ``u`` on ``lon_u``/``lat_u`` and ``v`` on
    ``lon_v``/``lat_v``, ``angle``, ``mask_rho``, ``h``, ``zeta``, s-levels (``s_rho``,
    ``Cs_r``, ``hc``, ``Vtransform``).
``unstructured``
    FVCOM (``nv`` connectivity, ``u``/``v`` on elements, ``h``/``zeta``/``siglay`` on nodes) and
    UGRID meshes (a ``cf_role: mesh_topology`` variable, e.g. SCHISM or D-Flow FM output).

Horizontal regridding onto the product's regular grid uses xugrid's cell tree
(:meth:`xugrid.Ugrid2d.locate_points`, :meth:`xugrid.Ugrid2d.compute_barycentric_weights`):
node-located fields (ROMS rho points, FVCOM ``h``/``zeta``/``siglay``) are interpolated linearly
inside the mesh triangles (ROMS quads are split into two triangles); element-located FVCOM
``u``/``v`` keep their per-element value (FVCOM's own finite-volume representation). Vertical:
each model layer's depth below the surface is computed per column (sigma: ``-sigma*(h+zeta)``;
ROMS: ``zeta - z``), then currents are linearly interpolated onto :data:`DEPTH_LEVELS_M`
(the top layer's value up to the surface, the bottom layer's down to the sea floor, NaN below
``h``). A depth-averaged (2-D) model is uniform in depth, which the dataset attributes say.

Every assumption about the provider is checked and recorded in the attribute
``model_notes`` (JSON list), which the product copies.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Mapping

import numpy as np
import xarray as xr

from ..engine import libm
from ..errors import DataError
from .base import VAR_ATTRS, _VELOCITY_UNITS, file_records, open_raw, read, to_json

LAYOUTS: tuple[str, ...] = ("regular", "curvilinear", "unstructured")

#: Canonical depth levels (m below the surface) the model layers are interpolated onto.
DEPTH_LEVELS_M: tuple[float, ...] = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0,
                                     20.0, 25.0, 30.0, 40.0, 50.0, 60.0, 80.0, 100.0, 150.0,
                                     200.0, 300.0, 500.0)

#: Above this speed (m/s) a velocity without a units attribute is not taken as m s-1.
MAX_PLAUSIBLE_SPEED = 5.0

#: Elevation written on model land and outside the model's mesh/grid (m, positive up): the
#: model gives no land height; any value >= 0 marks land in the product (land_mask).
LAND_ELEVATION_M = 1.0

#: Fill values some providers leave in place of NaN (depths, velocities).
_FILL_THRESHOLD = 9000.0

TIDE_NOTE = ("the model's own tidal flow is part of u, v (hourly model output); no separate "
             "or synthetic tide is added")

_MODEL_CACHE: dict = {}


# --------------------------------------------------------------------------------------------
# detection
# --------------------------------------------------------------------------------------------

def detect(path: str | os.PathLike) -> str | None:
    """The model layout of ``path`` (one of :data:`LAYOUTS`), or None for a gridded product.

    Parameters
    ----------
    path : str or os.PathLike
        A NetCDF file.

    Returns
    -------
    str or None
        ``"unstructured"`` (FVCOM ``nv`` or a UGRID ``mesh_topology``), ``"curvilinear"``
        (ROMS ``lon_rho``), ``"regular"`` (1-D lon/lat with a ``mask`` and a positive-down
        ``bathymetry``/``h``/``depth`` variable beside ``u``/``v``), else None.
    """
    if Path(path).suffix.lower() in (".tif", ".tiff"):
        return None
    raw = open_raw(path)
    try:
        return _layout(raw)
    finally:
        raw.close()


def _layout(raw: xr.Dataset) -> str | None:
    names = {str(k).lower() for k in raw.variables}
    if "nv" in names and ("lonc" in names or "nele" in raw.dims):
        return "unstructured"
    if any(v.attrs.get("cf_role") == "mesh_topology" for v in raw.variables.values()):
        return "unstructured"
    if "lon_rho" in names and "lat_rho" in names:
        return "curvilinear"
    if "mask" in names and {"u", "v"} <= names and ({"bathymetry", "h"} & names):
        return "regular"
    return None


# --------------------------------------------------------------------------------------------
# the reader
# --------------------------------------------------------------------------------------------

def read_model(path: str | os.PathLike, region: Mapping) -> tuple[xr.Dataset, xr.Dataset]:
    """Canonical currents and bathymetry of a coastal model file, cut to ``region``.

    Parameters
    ----------
    path : str or os.PathLike
        The model output (layout from :func:`detect`).
    region : Mapping
        ``bbox`` (west, east, south, north), ``time`` (start, end) and ``max_depth_m``.

    Returns
    -------
    currents : xarray.Dataset
        Canonical ``u``, ``v`` (time, depth, latitude, longitude) float32 m s-1, NaN on land and
        below the sea floor; attrs ``source="files"``, ``source_files``, ``model_layout``,
        ``model_notes`` (JSON list of the checked assumptions), ``tide_in_currents``.
    bathymetry : xarray.Dataset
        Canonical ``elevation`` (latitude, longitude) m, positive up: ``-h`` in the water,
        :data:`LAND_ELEVATION_M` on the model's land and outside its mesh.

    Raises
    ------
    DataError
        One line naming the file and the variable: a missing variable or coordinate, the bbox
        outside the model, implausible unit-less velocities, a mask that contradicts the NaNs.
    """
    path = str(path)
    st = os.stat(path) if os.path.exists(path) else None
    key = (path, st.st_mtime_ns if st else 0, json.dumps(dict(region), sort_keys=True,
                                                         default=str))
    if key in _MODEL_CACHE:
        cur, bat = _MODEL_CACHE[key]
        return cur.copy(), bat.copy()
    raw = open_raw(path)
    try:
        layout = _layout(raw)
        if layout is None:
            raise DataError(f"{path}: not a recognised model layout (no FVCOM 'nv', UGRID "
                            "mesh_topology, ROMS 'lon_rho' or regular grid with 'mask')")
        reader = {"regular": _regular, "curvilinear": _curvilinear,
                  "unstructured": _unstructured}[layout]
        fields, notes = reader(raw, path, region)
    finally:
        raw.close()
    cur, bat = _canonical(fields, notes, path, layout, region)
    _MODEL_CACHE.clear()
    _MODEL_CACHE[key] = (cur, bat)
    return cur.copy(), bat.copy()


def _canonical(f: dict, notes: list, path: str, layout: str,
               region: Mapping) -> tuple[xr.Dataset, xr.Dataset]:
    """Model fields on the regular grid → canonical datasets through :func:`base.read`."""
    lat, lon, times = f["latitude"], f["longitude"], f["time"]
    land = f["land"]
    h = np.where(land, np.nan, f["h"])
    levels = _levels(float(region.get("max_depth_m", DEPTH_LEVELS_M[-1])))
    u, v = (_to_levels(f[n], f.get("layer_depth"), h, levels) for n in ("u", "v"))
    u[:, :, land] = np.nan
    v[:, :, land] = np.nan
    speed = np.hypot(u, v)
    if not np.isfinite(speed).any():
        raise DataError(f"{path}: u/v have no finite value in the region")
    elev = np.where(land, LAND_ELEVATION_M, -h)
    if not np.isfinite(elev).all():
        raise DataError(f"{path}: {f['h_name']}: no depth at {int((~np.isfinite(elev)).sum())} "
                        "water points of the grid")
    notes = list(notes) + [
        f"elevation = -{f['h_name']} (model depth, positive down) in the water; model land and "
        f"points outside the model's grid/mesh get elevation +{LAND_ELEVATION_M:g} m (land)",
        TIDE_NOTE,
    ]
    attrs = {"units": "m s-1"}
    ds = xr.Dataset(
        {"u": (("time", "depth", "latitude", "longitude"), u.astype(np.float32), attrs),
         "v": (("time", "depth", "latitude", "longitude"), v.astype(np.float32), attrs)},
        coords={"time": ("time", times), "depth": ("depth", levels, {"positive": "down"}),
                "latitude": ("latitude", lat, {"units": "degrees_north"}),
                "longitude": ("longitude", lon, {"units": "degrees_east"})})
    bds = xr.Dataset({"elevation": (("latitude", "longitude"), elev.astype(np.float32),
                                    {"units": "m", "positive": "up"})},
                     coords={"latitude": ("latitude", lat, {"units": "degrees_north"}),
                             "longitude": ("longitude", lon, {"units": "degrees_east"})})
    bbox, tw = region["bbox"], region.get("time")
    cur = read(ds, "currents", ("u", "v"), name=path, bbox=bbox, time=tw,
               max_depth=region.get("max_depth_m"))
    bat = read(bds, "bathymetry", name=path, bbox=bbox)
    common = {"source": "files", "source_files": to_json(file_records([path])),
              "model_layout": layout, "model_notes": json.dumps(notes)}
    cur.attrs.update(common, tide_in_currents=TIDE_NOTE)
    bat.attrs.update(common)
    return cur, bat


def _levels(max_depth: float) -> np.ndarray:
    lv = np.asarray(DEPTH_LEVELS_M, float)
    deeper = np.flatnonzero(lv > max_depth)
    return lv[: (deeper[0] + 1) if deeper.size else lv.size]


def _to_levels(field: np.ndarray, layer_depth: np.ndarray | None, h: np.ndarray,
               levels: np.ndarray) -> np.ndarray:
    """(nt, nl, ny, nx) model layers → (nt, nz, ny, nx) on ``levels`` (m below the surface).

    ``layer_depth`` (nt, nl, ny, nx) increasing with the layer index; None for a 2-D model
    (``field`` (nt, 1, ny, nx), uniform in depth). NaN below ``h`` (ny, nx).
    """
    nt, nl, ny, nx = field.shape
    if layer_depth is None or nl == 1:
        out = np.repeat(field[:, :1], levels.size, axis=1)
    else:
        d = np.asarray(layer_depth, float)
        out = np.empty((nt, levels.size, ny, nx))
        for i, z in enumerate(levels):
            k = (d < z).sum(axis=1)                       # layers above z: 0..nl
            lo = np.clip(k - 1, 0, nl - 1)[:, None]
            hi = np.clip(k, 0, nl - 1)[:, None]
            d0, d1 = (np.take_along_axis(d, ix, 1)[:, 0] for ix in (lo, hi))
            f0, f1 = (np.take_along_axis(field, ix, 1)[:, 0] for ix in (lo, hi))
            with np.errstate(invalid="ignore", divide="ignore"):
                w = np.where(d1 > d0, (z - d0) / (d1 - d0), 0.0)
            out[:, i] = f0 + np.clip(w, 0.0, 1.0) * (f1 - f0)
    out[:, levels[:, None, None] > h[None] + 1e-9] = np.nan
    return out


# --------------------------------------------------------------------------------------------
# shared checks
# --------------------------------------------------------------------------------------------

def _var(raw: xr.Dataset, path: str, *names: str, what: str | None = None) -> xr.DataArray:
    lower = {str(k).lower(): str(k) for k in raw.variables}
    for n in names:
        if n.lower() in lower:
            return raw[lower[n.lower()]]
    raise DataError(f"{path}: missing variable '{what or names[0]}' (looked for "
                    f"{', '.join(names)})")


def _velocity(var: xr.DataArray, path: str, notes: list) -> np.ndarray:
    """Values in m s-1; a missing units attribute is accepted only for plausible magnitudes."""
    vals = np.asarray(var.values, float)
    vals[np.abs(vals) > _FILL_THRESHOLD] = np.nan
    units = var.attrs.get("units")
    top = float(np.nanmax(np.abs(vals))) if np.isfinite(vals).any() else 0.0
    if units is None:
        if top > MAX_PLAUSIBLE_SPEED:
            raise DataError(f"{path}: {var.name}: no units attribute and |{var.name}| reaches "
                            f"{top:.3g}, implausible for m s-1 (limit {MAX_PLAUSIBLE_SPEED:g})")
        notes.append(f"{var.name}: no units attribute; taken as m s-1 because |{var.name}| <= "
                     f"{top:.3g} (plausible, limit {MAX_PLAUSIBLE_SPEED:g} m/s)")
        return vals
    key = " ".join(str(units).strip().lower().replace("meters", "m").replace("meter", "m")
                   .split())
    scale = _VELOCITY_UNITS.get(key, _VELOCITY_UNITS.get(str(units).strip().lower()))
    if scale is None:
        raise DataError(f"{path}: {var.name}: unsupported velocity units {units!r}")
    vals = vals * scale
    if np.nanmax(np.abs(vals), initial=0.0) > 2 * MAX_PLAUSIBLE_SPEED:
        raise DataError(f"{path}: {var.name}: |{var.name}| reaches "
                        f"{np.nanmax(np.abs(vals)):.3g} m s-1, implausible")
    return vals


def _times(raw: xr.Dataset, path: str, names: tuple, notes: list) -> tuple[str, np.ndarray]:
    for n in names:
        if n in raw.variables and np.issubdtype(raw[n].dtype, np.datetime64):
            t = raw[n].values.astype("datetime64[ns]")
            break
    else:
        raise DataError(f"{path}: missing coordinate 'time' (looked for {', '.join(names)})")
    minute = np.timedelta64(60, "s")
    rounded = ((t + minute // 2).astype("datetime64[m]")).astype("datetime64[ns]")
    shift = np.abs(t - rounded).max()
    if shift > np.timedelta64(0, "ns"):
        if shift >= np.timedelta64(30, "s"):
            raise DataError(f"{path}: {n}: times are not on whole minutes")
        notes.append(f"{n}: times rounded to the nearest minute (largest shift "
                     f"{shift / np.timedelta64(1, 's'):.1f} s, the file's float time encoding)")
    return n, rounded


def _target_axes(region: Mapping, lon_all: np.ndarray, lat_all: np.ndarray, res: float,
                 path: str) -> tuple[np.ndarray, np.ndarray]:
    """Regular axes at ``res`` covering the bbox plus two cells, inside the model's extent."""
    bb = region["bbox"]
    lo_x, hi_x = float(np.nanmin(lon_all)), float(np.nanmax(lon_all))
    lo_y, hi_y = float(np.nanmin(lat_all)), float(np.nanmax(lat_all))
    if bb["east"] <= lo_x or bb["west"] >= hi_x or bb["north"] <= lo_y or bb["south"] >= hi_y:
        raise DataError(f"{path}: the region bbox {bb['west']}..{bb['east']} E, "
                        f"{bb['south']}..{bb['north']} N lies outside the model's extent "
                        f"{lo_x:.4f}..{hi_x:.4f} E, {lo_y:.4f}..{hi_y:.4f} N")
    x = np.arange(bb["west"] - 2 * res, bb["east"] + 2.5 * res, res)
    y = np.arange(bb["south"] - 2 * res, bb["north"] + 2.5 * res, res)
    return np.round(x, 10), np.round(y, 10)


def _wrap(lon: np.ndarray) -> np.ndarray:
    lon = np.asarray(lon, float)
    return np.where(lon > 180.0, lon - 360.0, lon)


def _node_interp(grid, values: np.ndarray, fi: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Linear (barycentric) interpolation of node values (..., n_node) at located points.

    NaN-aware: the valid weight is renormalised when >= 0.5, else NaN; NaN outside the mesh.
    """
    inside = fi >= 0
    conn = grid.face_node_connectivity[np.where(inside, fi, 0)]   # (np, 3)
    vals = values[..., conn]                                      # (..., np, 3)
    ok = np.isfinite(vals) & (conn >= 0)
    ww = np.where(ok, w, 0.0)
    sw = ww.sum(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(ok, vals, 0.0).__mul__(ww).sum(-1) / sw
    return np.where(inside & (sw >= 0.5 - 1e-12), out, np.nan)


# --------------------------------------------------------------------------------------------
# regular (MOHID-like)
# --------------------------------------------------------------------------------------------

def _regular(raw: xr.Dataset, path: str, region: Mapping) -> tuple[dict, list]:
    notes: list = []
    u_var, v_var = _var(raw, path, "u"), _var(raw, path, "v")
    h_var = _var(raw, path, "bathymetry", "h", what="bathymetry")
    m_var = _var(raw, path, "mask")
    lon_name = next((n for n in ("lon", "longitude", "x") if n in raw.variables), None)
    lat_name = next((n for n in ("lat", "latitude", "y") if n in raw.variables), None)
    if lon_name is None or lat_name is None:
        raise DataError(f"{path}: u: no lon/lat coordinates (looked for lon, longitude, x / "
                        "lat, latitude, y)")
    lon, lat = _wrap(raw[lon_name].values), np.asarray(raw[lat_name].values, float)
    _, times = _times(raw, path, ("time", "Time", "time_counter"), notes)
    if u_var.dims[-2:] != (lat_name, lon_name):
        raise DataError(f"{path}: u: dims {u_var.dims} do not end in ({lat_name}, {lon_name})")
    u, v = _velocity(u_var, path, notes), _velocity(v_var, path, notes)
    if u.ndim == 3:
        u, v, layer_depth = u[:, None], v[:, None], None
        notes.append("u, v: depth-averaged (2-D) model: currents uniform from the surface to "
                     "the sea floor")
    else:
        raise DataError(f"{path}: u: {u.ndim}-D; only 2-D (time, lat, lon) regular model output "
                        "is supported")
    h = np.asarray(h_var.values, float)
    fill = h_var.attrs.get("_FillValue", h_var.encoding.get("_FillValue"))
    bad = np.abs(h) > _FILL_THRESHOLD
    if fill is not None:
        bad |= h == float(fill)
    h[bad] = np.nan
    positive = str(h_var.attrs.get("positive", "")).lower()
    down = positive == "down" or (positive != "up" and (
        h_var.attrs.get("standard_name", "").startswith("sea_floor_depth")
        or "below" in str(h_var.attrs.get("long_name", "")).lower()))
    if not down:
        raise DataError(f"{path}: {h_var.name}: cannot tell its sign (no positive='down', no "
                        "sea_floor_depth standard_name, no 'below' in long_name)")
    claimed = h_var.attrs.get("minimum")
    notes.append(f"{h_var.name}: depth positive down (standard_name "
                 f"{h_var.attrs.get('standard_name', '-')}); values beyond ±{_FILL_THRESHOLD:g}"
                 f" treated as fill" + (f" (attrs claim minimum {claimed})"
                                        if claimed is not None else "")
                 + f"; actual range {np.nanmin(h):.3g}..{np.nanmax(h):.3g} m")
    land = _regular_mask(m_var, u, path, notes)
    water_no_h = ~land & ~np.isfinite(h)
    if water_no_h.any():
        raise DataError(f"{path}: {h_var.name}: NaN/fill at {int(water_no_h.sum())} water cells "
                        f"of '{m_var.name}'")
    ys = np.argsort(lat)
    xs = np.argsort(lon)
    fields = {"latitude": lat[ys], "longitude": lon[xs], "time": times,
              "u": u[..., ys, :][..., xs], "v": v[..., ys, :][..., xs],
              "layer_depth": layer_depth, "h": h[ys][:, xs], "land": land[ys][:, xs],
              "h_name": str(h_var.name)}
    return fields, notes


def _regular_mask(m_var: xr.DataArray, u: np.ndarray, path: str, notes: list) -> np.ndarray:
    """Land (bool) from the mask, its meaning from its attributes, checked against u's NaNs."""
    m = np.asarray(m_var.values, float)
    if not np.isin(m[np.isfinite(m)], (0.0, 1.0)).all():
        raise DataError(f"{path}: {m_var.name}: values other than 0 and 1")
    text = " ".join(str(m_var.attrs.get(k, "")) for k in ("standard_name", "long_name")).lower()
    u_nan = ~np.isfinite(u).any(axis=(0, 1))
    if "land" in text:
        one_is_land, why = True, "1 = land (its standard/long name: land_binary_mask, CF)"
    elif any(w in text for w in ("water", "sea", "wet", "ocean")):
        one_is_land, why = False, "1 = water (its name)"
    else:
        raise DataError(f"{path}: {m_var.name}: cannot tell whether 1 means land or water (no "
                        "standard_name/long_name)")
    land = (m == 1.0) if one_is_land else (m == 0.0)
    disagree = int((land != u_nan).sum())
    if disagree > 0.01 * land.size:
        inverse = int((~land != u_nan).sum())
        hint = (" (the flags look inverted)" if inverse < disagree else "")
        raise DataError(f"{path}: {m_var.name}: {why} contradicts the NaNs of u at {disagree} of "
                        f"{land.size} cells{hint}")
    notes.append(f"{m_var.name}: {why}; agrees with the NaNs of u at {land.size - disagree} of "
                 f"{land.size} cells ({int(land.sum())} land)")
    return land | u_nan


# --------------------------------------------------------------------------------------------
# curvilinear (ROMS)
# --------------------------------------------------------------------------------------------

def _rho_average(a: np.ndarray, axis: int, n: int) -> np.ndarray:
    """Staggered u (axis=-1) or v (axis=-2) → rho points (NaN-aware mean, edges copied)."""
    a = np.moveaxis(a, axis, -1)
    out = np.empty(a.shape[:-1] + (n,))
    with np.errstate(invalid="ignore"):
        mid = np.nanmean(np.stack([a[..., :-1], a[..., 1:]]), axis=0)
    out[..., 1:-1] = mid
    out[..., 0], out[..., -1] = a[..., 0], a[..., -1]
    return np.moveaxis(out, -1, axis)


def _quad_mesh(lon: np.ndarray, lat: np.ndarray):
    """xugrid mesh whose nodes are the (ny, nx) points, two triangles per quad."""
    import xugrid as xu

    ny, nx = lon.shape
    idx = np.arange(ny * nx).reshape(ny, nx)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = np.concatenate([np.c_[a, b, c], np.c_[a, c, d]])
    return xu.Ugrid2d(lon.ravel(), lat.ravel(), -1, faces)


def _curvilinear(raw: xr.Dataset, path: str, region: Mapping) -> tuple[dict, list]:
    notes: list = ["grid: ROMS curvilinear (rho points as mesh nodes, linear in each triangle)"]
    lon = _wrap(_var(raw, path, "lon_rho").values)
    lat = np.asarray(_var(raw, path, "lat_rho").values, float)
    if lon.ndim != 2:
        raise DataError(f"{path}: lon_rho: {lon.ndim}-D, expected 2-D (eta_rho, xi_rho)")
    ny, nx = lon.shape
    u_var, v_var = _var(raw, path, "u"), _var(raw, path, "v")
    for var, want in ((u_var, (ny, nx - 1)), (v_var, (ny - 1, nx))):
        if tuple(var.shape[-2:]) != want:
            raise DataError(f"{path}: {var.name}: horizontal shape {tuple(var.shape[-2:])}, "
                            f"expected {want} (ROMS staggering)")
    h = np.asarray(_var(raw, path, "h").values, float)
    h[np.abs(h) > _FILL_THRESHOLD] = np.nan
    angle = (np.asarray(raw["angle"].values, float) if "angle" in raw.variables
             else np.zeros_like(lon))
    if "angle" not in raw.variables:
        notes.append("angle: absent, grid taken as aligned with east/north")
    mask = (np.asarray(raw["mask_rho"].values, float) if "mask_rho" in raw.variables
            else np.isfinite(h).astype(float))
    tname, times = _times(raw, path, ("ocean_time", "time"), notes)
    u, v = _velocity(u_var, path, notes), _velocity(v_var, path, notes)
    if u.ndim == 3:
        u, v = u[:, None], v[:, None]
    ur, vr = _rho_average(u, -1, nx), _rho_average(v, -2, ny)
    ca, sa = libm.cos(angle), libm.sin(angle)
    ue, vn = ur * ca - vr * sa, ur * sa + vr * ca
    land = mask == 0
    ue[..., land], vn[..., land] = np.nan, np.nan
    notes.append("u, v: averaged from the u/v points to the rho points, rotated by 'angle' to "
                 "east/north; ROMS writes 0 on land, so mask_rho == 0 is NaN")
    zeta = (np.asarray(raw["zeta"].values, float) if "zeta" in raw.variables
            else np.zeros((times.size, ny, nx)))
    zeta[np.abs(zeta) > _FILL_THRESHOLD] = np.nan
    zeta = np.where(np.isfinite(zeta), zeta, 0.0)
    layer_depth = None
    if ue.shape[1] > 1:
        s = np.asarray(_var(raw, path, "s_rho").values, float)
        cs = np.asarray(_var(raw, path, "Cs_r").values, float)
        hc = float(_var(raw, path, "hc").values)
        vt = int(_var(raw, path, "Vtransform").values) if "Vtransform" in raw.variables else 1
        hh = np.where(np.isfinite(h), h, 0.0)[None, None]
        zz = zeta[:, None]
        sc, cc = s[None, :, None, None], cs[None, :, None, None]
        if vt == 1:
            z0 = hc * sc + (hh - hc) * cc
            z = z0 + zz * (1.0 + z0 / np.where(hh > 0, hh, 1.0))
        elif vt == 2:
            z0 = (hc * sc + hh * cc) / (hc + hh)
            z = zz + (zz + hh) * z0
        else:
            raise DataError(f"{path}: Vtransform: {vt} not supported (1 or 2)")
        layer_depth = zz - z                           # m below the surface, (nt, nl, ny, nx)
        order = np.argsort(layer_depth[0, :, ny // 2, nx // 2])
        ue, vn, layer_depth = ue[:, order], vn[:, order], layer_depth[:, order]
        notes.append(f"vertical: ROMS s-levels, Vtransform {vt}, depth of each rho level = "
                     "zeta - z(s_rho, Cs_r, hc, h, zeta), linear onto the depth levels")
    else:
        notes.append("u, v: depth-averaged (2-D): uniform from the surface to the sea floor")
    res = float(np.nanmedian(np.hypot(np.diff(lon, axis=1), np.diff(lat, axis=1))))
    x, y = _target_axes(region, lon, lat, res, path)
    grid = _quad_mesh(lon, lat)
    X, Y = np.meshgrid(x, y)
    fi, w = grid.compute_barycentric_weights(np.c_[X.ravel(), Y.ravel()])
    shape = (y.size, x.size)
    interp = lambda a: _node_interp(grid, a.reshape(a.shape[:-2] + (-1,)), fi, w)  # noqa: E731
    wet = interp(np.where(land, np.nan, 1.0)).reshape(shape)
    hi = interp(np.where(land, np.nan, h)).reshape(shape)
    tgt_land = ~np.isfinite(wet) | ~np.isfinite(hi)
    fields = {"latitude": y, "longitude": x, "time": times,
              "u": interp(ue).reshape(ue.shape[:2] + shape),
              "v": interp(vn).reshape(vn.shape[:2] + shape),
              "layer_depth": (None if layer_depth is None else
                              interp(layer_depth).reshape(layer_depth.shape[:2] + shape)),
              "h": hi, "land": tgt_land, "h_name": "h"}
    notes.append(f"regridded to a regular {res:.5g} deg grid (the median rho spacing)")
    return fields, notes


# --------------------------------------------------------------------------------------------
# unstructured (FVCOM, UGRID)
# --------------------------------------------------------------------------------------------

def _unstructured(raw: xr.Dataset, path: str, region: Mapping) -> tuple[dict, list]:
    import xugrid as xu

    notes: list = []
    if "nv" in raw.variables:
        lon = _wrap(_var(raw, path, "lon").values)
        lat = np.asarray(_var(raw, path, "lat").values, float)
        nv = np.asarray(raw["nv"].values)
        if nv.shape[0] == 3 and nv.shape[-1] != 3:
            nv = nv.T
        base = 1 if nv.min() == 1 else 0
        grid = xu.Ugrid2d(lon, lat, -1, nv.astype(np.int64) - base)
        face_dim, node_dim = raw["nv"].dims[-1 if raw["nv"].shape[0] == 3 else 0], "node"
        notes.append("grid: FVCOM triangular mesh (nv, 1-based) of "
                     f"{grid.n_node} nodes and {grid.n_face} elements")
        h_name = "h"
    else:
        uds = xu.UgridDataset(raw)
        grid = uds.grid
        lon, lat = grid.node_x, grid.node_y
        face_dim, node_dim = grid.face_dimension, grid.node_dimension
        notes.append(f"grid: UGRID mesh of {grid.n_node} nodes and {grid.n_face} faces")
        h_name = next((n for n in ("h", "depth", "mesh2d_node_z", "bathymetry")
                       if n in raw.variables), "h")
    u_var = _var(raw, path, "u", "mesh2d_ucx", "uo")
    v_var = _var(raw, path, "v", "mesh2d_ucy", "vo")
    h = np.asarray(_var(raw, path, h_name, what="h").values, float)
    h[np.abs(h) > _FILL_THRESHOLD] = np.nan
    if str(raw[h_name].attrs.get("positive", "down")).lower() == "up":
        h = -h
    tname, times = _times(raw, path, ("time", "Times"), notes)
    u, v = _velocity(u_var, path, notes), _velocity(v_var, path, notes)
    loc = "face" if face_dim in u_var.dims else ("node" if node_dim in u_var.dims else None)
    if loc is None:
        raise DataError(f"{path}: u: dims {u_var.dims} name neither the mesh's elements "
                        f"({face_dim}) nor its nodes ({node_dim})")
    if "wet_cells" in raw.variables and loc == "face":
        dry = np.asarray(raw["wet_cells"].values) == 0
        if dry.any():
            u = np.where(dry[:, None], np.nan, u) if u.ndim == 3 else np.where(dry, np.nan, u)
            v = np.where(dry[:, None], np.nan, v) if v.ndim == 3 else np.where(dry, np.nan, v)
            notes.append(f"wet_cells: {int(dry.sum())} dry element-times set to NaN")
    if u.ndim == 2:
        u, v = u[:, None], v[:, None]
    zeta = (np.asarray(raw["zeta"].values, float) if "zeta" in raw.variables
            else np.zeros((times.size, grid.n_node)))
    zeta = np.where(np.isfinite(zeta) & (np.abs(zeta) < _FILL_THRESHOLD), zeta, 0.0)
    e = grid.edge_node_connectivity
    res = 0.5 * float(np.median(np.hypot(lon[e[:, 0]] - lon[e[:, 1]],
                                         lat[e[:, 0]] - lat[e[:, 1]])))
    x, y = _target_axes(region, lon, lat, res, path)
    X, Y = np.meshgrid(x, y)
    pts = np.c_[X.ravel(), Y.ravel()]
    fi, w = grid.compute_barycentric_weights(pts)
    shape = (y.size, x.size)
    hi = _node_interp(grid, h, fi, w).reshape(shape)
    if loc == "face":
        face = grid.locate_points(pts)
        inside = face >= 0
        take = lambda a: np.where(inside, a[..., np.where(inside, face, 0)],  # noqa: E731
                                  np.nan).reshape(a.shape[:-1] + shape)
        ut, vt = take(u), take(v)
        notes.append("u, v: FVCOM element values kept per element (piecewise constant, the "
                     "model's finite-volume representation), located with xugrid's cell tree")
    else:
        ut = _node_interp(grid, u, fi, w).reshape(u.shape[:-1] + shape)
        vt = _node_interp(grid, v, fi, w).reshape(v.shape[:-1] + shape)
        notes.append("u, v: node values, linear inside each mesh face")
    layer_depth = None
    if ut.shape[1] > 1:
        sig_name = next((n for n in ("siglay", "sigma", "mesh2d_layer_sigma") if n in
                         raw.variables), None)
        if sig_name is None:
            raise DataError(f"{path}: siglay: u has {ut.shape[1]} layers but no sigma "
                            "coordinate (looked for siglay, sigma, mesh2d_layer_sigma)")
        sig = np.asarray(raw[sig_name].values, float)
        if sig.ndim == 1:
            sig = np.repeat(sig[:, None], grid.n_node, axis=1)
        sig_t = _node_interp(grid, sig, fi, w).reshape((sig.shape[0],) + shape)
        zt = _node_interp(grid, zeta, fi, w).reshape((times.size,) + shape)
        total = np.where(np.isfinite(hi), hi, 0.0)[None] + np.where(np.isfinite(zt), zt, 0.0)
        layer_depth = -sig_t[None] * total[:, None]
        order = np.argsort(np.nanmean(-sig, axis=1))
        ut, vt, layer_depth = ut[:, order], vt[:, order], layer_depth[:, order]
        notes.append(f"vertical: {sig.shape[0]} sigma layers ({sig_name}), depth below the "
                     "surface = -sigma * (h + zeta) per column, linear onto the depth levels")
    else:
        notes.append("u, v: depth-averaged (2-D): uniform from the surface to the sea floor")
    land = ~np.isfinite(hi) | (fi.reshape(shape) < 0)
    notes.append(f"regridded to a regular {res:.5g} deg grid (half the median mesh edge); "
                 f"{100 * land.mean():.0f} % of it lies outside the mesh and is land "
                 "(no model data)")
    return ({"latitude": y, "longitude": x, "time": times, "u": ut, "v": vt,
             "layer_depth": layer_depth, "h": hi, "land": land, "h_name": h_name}, notes)


__all__ = ["DEPTH_LEVELS_M", "LAND_ELEVATION_M", "LAYOUTS", "detect", "read_model"]
