"""The grid export (contracts §3) as a numba-friendly :class:`Grid`, and its sampling kernels.

World frame: x east, y depth (positive down), z north, all in metres; time ``t`` in seconds
since ``time0_unix_s`` (the export's ``time_s`` axis). Currents are sampled bilinearly in
(x, z) and linearly in depth and time with O(1) index arithmetic: the horizontal axes are
regular; depth and time may be irregular and are located through a precomputed lookup table
whose bins are no wider than the smallest spacing (at most one correction step). Outside an
axis the sample is clamped to the edge value.

The disturbance of the task contract (paper eq. 1) is::

    c(x, y, z, t) = g [u, 0, v] + [u_tide, 0, v_tide] + A [sin(w t + phi), 0, cos(w t + phi)]

the gain ``g`` scaling the data currents only; the product's real tide layers are included
only when the export has them (``has_tide``) and the synthetic tide term (amplitude ``A``,
angular frequency ``w``, phase ``phi``) only when asked for (robustness ablations).

Boundaries (the same rule as the temporal export, :func:`oneocean.product.exports.point_weights`):

* a node's column with currents at one level or more (``current_mask == 1``) holds its deepest
  valid value below it (down to the seafloor and beyond; a level above the shallowest valid
  one takes that one), done once by :func:`load_grid` (:func:`hold_levels`);
* horizontally only current-defined nodes count: the bilinear weights of the four corners are
  renormalised by their current-defined share ``s = sum w_k m_k`` when ``s >= 1/2``; below
  that the value fades linearly to 0 (divided by 1/2 instead of ``s``), so the current is
  continuous and exactly 0 in water where the product has no current at all (e.g. outside
  a CMEMS subset polygon, or water shallower than the first level). Tide layers use the same
  weights. :func:`current_defined` (the bilinear ``current_mask``) flags such water.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Mapping, NamedTuple

import numpy as np
from numba import njit

from ..errors import ConfigError, DataError
from ..product.zarrio import read_npz
from ._jit import hot_kernel

#: Keys of the grid export, contracts §3 (order = documentation order).
REQUIRED_KEYS = (
    "u", "v", "u_tide", "v_tide", "has_tide", "time_s", "time0_unix_s", "depth", "lat", "lon",
    "x0_m", "dx_m", "z0_m", "dz_m", "origin_lat", "origin_lon", "m_per_deg_lat",
    "m_per_deg_lon", "elevation", "land_mask", "valid_mask", "meta_json",
)
#: Keys of the grid export that an export (e.g. an analytic test grid) may lack;
#: :func:`load_grid` derives them (``current_mask = any(valid_mask)``).
OPTIONAL_KEYS = ("current_mask",)

#: Minimum current-defined share of the bilinear weight for a renormalised value (the same
#: threshold as the product's regridding and the temporal export).
MIN_CURRENT_WEIGHT = 0.5

_LUT_MAX = 1 << 16


class Grid(NamedTuple):
    """A loaded grid export: arrays and scalars only, passable to ``@njit`` functions.

    Attributes
    ----------
    uv : (nt, nz, ny, nx, 2) float32
        Eastward / northward current (u, v interleaved for cache locality), m s-1; levels
        without a current hold the column's deepest valid value (:func:`hold_levels`); 0 where
        ``current_mask == 0``.
    uv_tide : (nt, ny, nx, 2) float32
        Tidal current, m s-1 (zeros when the export has none, or where ``current_mask == 0``).
    elevation : (ny, nx) float32
        Bathymetric elevation, m, positive up.
    land : (ny, nx) float32
        Land mask, 1 = land, 0 = water (from the bathymetry).
    valid : (nz, ny, nx) uint8
        1 = the product defines a current at this level and node.
    current_mask : (ny, nx) float32
        1 = currents defined at the node (at one level or more), 0 = land or water without
        currents (sampled as 0; see :func:`current_defined`).
    cell_full : (ny, nx) uint8
        1 where the cell with lower-left node (j, i) has currents at all four corners (the
        sampling kernel's fast path: there the weights are plain bilinear); derived.
    time_s, time_inv : (nt,) float64
        Time axis (s since ``time0_unix_s``) and inverse spacings (s-1, last entry 0).
    time_lut : (nlut,) int64
        Lookup table locating a time in O(1): ``lut[int((t - time_s[0]) * inv_h)]``.
    time_lut_inv_h : float
        Inverse bin width of ``time_lut``, s-1.
    depth, depth_inv, depth_lut, depth_lut_inv_h
        Same for the depth axis (m, positive down).
    x0, dx, inv_dx, x_max : float
        Regular east axis ``x = x0 + i dx``, m (``inv_dx`` in m-1; ``x_max`` the last node).
    nx : int
        Number of nodes along x.
    z0, dz, inv_dz, z_max : float
        Regular north axis ``z = z0 + j dz``, m (``inv_dz`` in m-1; ``z_max`` the last node).
    ny : int
        Number of nodes along z.
    gain : float
        Current gain g applied to the data currents u, v (not to the tide layers or the
        synthetic tide term).
    tide_layers : int
        1 if the real tide layers are added.
    tide_amp, tide_omega, tide_phase : float
        Synthetic tide term A (m s-1), w (rad s-1), phi (rad); A = 0 disables it.
    time0_unix_s : float
        Start of the time axis, s since the Unix epoch.
    origin_lat, origin_lon : float
        Latitude and longitude of the world origin, degrees.
    m_per_deg_lat, m_per_deg_lon : float
        Metres per degree of latitude and longitude (equirectangular georeference, contracts §3).
    """

    uv: np.ndarray
    uv_tide: np.ndarray
    elevation: np.ndarray
    land: np.ndarray
    valid: np.ndarray
    current_mask: np.ndarray
    cell_full: np.ndarray
    time_s: np.ndarray
    time_inv: np.ndarray
    time_lut: np.ndarray
    time_lut_inv_h: float
    depth: np.ndarray
    depth_inv: np.ndarray
    depth_lut: np.ndarray
    depth_lut_inv_h: float
    x0: float
    dx: float
    inv_dx: float
    x_max: float
    nx: int
    z0: float
    dz: float
    inv_dz: float
    z_max: float
    ny: int
    gain: float
    tide_layers: int
    tide_amp: float
    tide_omega: float
    tide_phase: float
    time0_unix_s: float
    origin_lat: float
    origin_lon: float
    m_per_deg_lat: float
    m_per_deg_lon: float


# ----------------------------------------------------------------------------- loading


def _axis_lut(ax: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Inverse spacings, lookup table and its inverse bin width for an ascending axis."""
    n = ax.shape[0]
    inv = np.zeros(n, dtype=np.float64)
    if n == 1:
        return inv, np.zeros(1, dtype=np.int64), 0.0
    d = np.diff(ax)
    inv[:-1] = 1.0 / d
    span = float(ax[-1] - ax[0])
    nb = int(min(np.ceil(span / float(d.min())), _LUT_MAX)) + 1
    h = span / (nb - 1) if nb > 1 else span
    edges = ax[0] + h * np.arange(nb)
    lut = np.clip(np.searchsorted(ax, edges, side="right") - 1, 0, n - 2).astype(np.int64)
    return inv, lut, 1.0 / h


def hold_levels(valid: np.ndarray) -> np.ndarray:
    """Source level of every (level, node) under the hold rule.

    A valid level reads itself; an invalid one reads the nearest valid level above it (so the
    deepest valid value is held down to the bottom of the column), or, above the shallowest
    valid level, that level. Columns without any valid level read level 0 (their values are
    zeroed by the callers).

    Parameters
    ----------
    valid : (nz, ny, nx) bool or int
        1 = the product defines a current at this level and node.

    Returns
    -------
    (nz, ny, nx) int64
        Level index each (level, node) reads.
    """
    ok = np.asarray(valid).astype(bool)
    nz = ok.shape[0]
    k = np.arange(nz).reshape((nz,) + (1,) * (ok.ndim - 1))
    above = np.maximum.accumulate(np.where(ok, k, -1), axis=0)
    below = np.minimum.accumulate(np.where(ok, k, nz)[::-1], axis=0)[::-1]
    src = np.where(above >= 0, above, below)
    return np.where(src < nz, src, 0).astype(np.int64)


def fill_columns(a: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Hold every column of ``a`` by :func:`hold_levels` of ``valid``.

    Parameters
    ----------
    a : (..., nz, ny, nx) ndarray
        Field with levels on the third-last axis.
    valid : (nz, ny, nx) bool or int
        1 = the product defines a value at this level and node.

    Returns
    -------
    (..., nz, ny, nx) ndarray
        A new array of ``a``'s dtype: each level holds its source level's value, zeroed where
        the column has no valid level.
    """
    ok = np.asarray(valid).astype(bool)
    src = hold_levels(ok).reshape((1,) * (a.ndim - 3) + ok.shape)
    out = np.take_along_axis(np.asarray(a), src, axis=a.ndim - 3)
    out[..., ~ok.any(axis=0)] = 0
    return out


def _cell_full(cmask: np.ndarray) -> np.ndarray:
    """(ny, nx) uint8: 1 where the cell (j..j+1, i..i+1) has currents at all four corners (the
    sampling kernel's fast path; the last row and column are 0)."""
    full = np.zeros(cmask.shape, np.uint8)
    full[:-1, :-1] = cmask[:-1, :-1] & cmask[1:, :-1] & cmask[:-1, 1:] & cmask[1:, 1:]
    return full


def _as_mapping(src) -> tuple[Mapping, str]:
    if isinstance(src, Mapping):
        return src, "grid export (in-memory)"
    return read_npz(src, "grid export"), str(Path(os.fspath(src)))


def _parse_tide(tide) -> tuple[float, float, float]:
    """Synthetic tide spec -> (A m s-1, w rad s-1, phi rad)."""
    if tide is None:
        return 0.0, 0.0, 0.0
    if isinstance(tide, Mapping):
        unknown = set(tide) - {"amplitude_ms", "period_s", "omega_rad_s", "phase_rad"}
        if unknown:
            raise ConfigError(f"tide: unknown keys {sorted(unknown)}; expected amplitude_ms, "
                              "period_s or omega_rad_s, phase_rad")
        if "amplitude_ms" not in tide:
            raise ConfigError("tide: missing key 'amplitude_ms'")
        amp = float(tide["amplitude_ms"])
        if ("period_s" in tide) == ("omega_rad_s" in tide):
            raise ConfigError("tide: give exactly one of 'period_s' or 'omega_rad_s'")
        if "period_s" in tide:
            period = float(tide["period_s"])
            if not period > 0:
                raise ConfigError(f"tide.period_s: must be > 0, got {period}")
            omega = 2.0 * np.pi / period
        else:
            omega = float(tide["omega_rad_s"])
        phase = float(tide.get("phase_rad", 0.0))
    else:
        try:
            amp, omega, phase = (float(v) for v in tide)
        except (TypeError, ValueError) as exc:
            raise ConfigError("tide: expected None, a mapping or (amplitude_ms, omega_rad_s, "
                              f"phase_rad), got {tide!r}") from exc
    if not (np.isfinite(amp) and np.isfinite(omega) and np.isfinite(phase)) or amp < 0:
        raise ConfigError(f"tide: amplitude must be finite and >= 0, omega/phase finite; "
                          f"got A={amp}, omega={omega}, phase={phase}")
    return amp, omega, phase


def load_grid(src, current_gain: float = 1.0, tide=None, use_tide_layers: bool = True) -> Grid:
    """Load and validate a grid export (contracts §3).

    Parameters
    ----------
    src : path-like or mapping
        A ``grid.npz`` (or ``grid.zarr`` store) written by the export stage, or an in-memory
        mapping with the same keys (e.g. :func:`oneocean.testing.make_test_grid`);
        ``current_mask`` is optional (derived from ``valid_mask``; checked against it when
        present). Currents at invalid levels may be 0 or already held (the export's layout):
        they are re-derived from the valid levels.
    current_gain : float, default 1.0
        Gain g on the data currents u, v (not on the tide layers), dimensionless.
    tide : None, mapping or (A, w, phi)
        Optional synthetic tide term: ``{"amplitude_ms": A, "period_s": P, "phase_rad": phi}``
        (or ``"omega_rad_s": w`` instead of ``"period_s"``); A in m s-1, P in s, w in
        rad s-1, phi in rad (default 0).
    use_tide_layers : bool, default True
        Add the export's tide layers when it has them (``has_tide == 1``).

    Returns
    -------
    Grid
        The loaded grid.

    Raises
    ------
    DataError
        Missing fields (all named), inconsistent shapes, irregular lat/lon, non-ascending axes,
        NaN currents inside valid water, NaN elevation or land mask, a ``current_mask`` that
        disagrees with ``valid_mask``.
    ConfigError
        Bad ``current_gain`` or ``tide``.
    """
    d, name = _as_mapping(src)
    missing = [k for k in REQUIRED_KEYS if k not in d]
    if missing:
        raise DataError(f"{name}: missing fields: {', '.join(missing)}")
    g = float(current_gain)
    if not np.isfinite(g):
        raise ConfigError(f"current_gain: must be finite, got {current_gain!r}")
    amp, omega, phase = _parse_tide(tide)

    def arr(key, ndim, dtype):
        a = np.asarray(d[key])
        if a.ndim != ndim:
            raise DataError(f"{name}: field '{key}' must be {ndim}-D, got shape {a.shape}")
        if a.dtype.kind not in "fiub":
            raise DataError(f"{name}: field '{key}' must be numeric, got dtype {a.dtype}")
        return np.ascontiguousarray(a, dtype=dtype)

    def scalar(key):
        a = np.asarray(d[key])
        if a.size != 1 or a.dtype.kind not in "fiub":
            raise DataError(f"{name}: field '{key}' must be a numeric scalar, got {a!r}")
        v = float(a.reshape(()))
        if not np.isfinite(v):
            raise DataError(f"{name}: field '{key}' is not finite ({v})")
        return v

    u = arr("u", 4, np.float32)
    v = arr("v", 4, np.float32)
    nt, nz, ny, nx = u.shape
    if v.shape != u.shape:
        raise DataError(f"{name}: 'v' shape {v.shape} != 'u' shape {u.shape}")
    expect = {"u_tide": (nt, ny, nx), "v_tide": (nt, ny, nx), "time_s": (nt,), "depth": (nz,),
              "lat": (ny,), "lon": (nx,), "elevation": (ny, nx), "land_mask": (ny, nx),
              "valid_mask": (nz, ny, nx)}
    shapes = {k: np.shape(d[k]) for k in expect}
    bad = [f"'{k}' {shapes[k]} (expected {s})" for k, s in expect.items() if shapes[k] != s]
    if bad:
        raise DataError(f"{name}: inconsistent shapes with u {u.shape}: {'; '.join(bad)}")
    if nx < 2 or ny < 2:
        raise DataError(f"{name}: need at least 2 x 2 horizontal grid nodes, got ny={ny}, nx={nx}")
    u_t = arr("u_tide", 3, np.float32)
    v_t = arr("v_tide", 3, np.float32)
    time_s = arr("time_s", 1, np.float64)
    depth = arr("depth", 1, np.float64)
    lat = arr("lat", 1, np.float64)
    lon = arr("lon", 1, np.float64)
    elev = arr("elevation", 2, np.float32)
    land = arr("land_mask", 2, np.float32)
    valid = arr("valid_mask", 3, np.uint8)
    if np.any(valid > 1):
        raise DataError(f"{name}: field 'valid_mask' must be 0 or 1")
    cmask = (valid == 1).any(axis=0)
    if "current_mask" in d:
        given = np.asarray(d["current_mask"])
        if given.shape != (ny, nx) or given.dtype.kind not in "fiub":
            raise DataError(f"{name}: field 'current_mask' must be numeric ({ny}, {nx}), got "
                            f"{given.dtype} {given.shape}")
        if not np.array_equal(given != 0, cmask):
            raise DataError(f"{name}: field 'current_mask' disagrees with any(valid_mask) at "
                            f"{int(((given != 0) != cmask).sum())} nodes")
    has_tide = int(scalar("has_tide"))
    sc = {k: scalar(k) for k in ("time0_unix_s", "x0_m", "dx_m", "z0_m", "dz_m", "origin_lat",
                                 "origin_lon", "m_per_deg_lat", "m_per_deg_lon")}

    for key, ax in (("time_s", time_s), ("depth", depth), ("lat", lat), ("lon", lon)):
        if not np.all(np.isfinite(ax)):
            raise DataError(f"{name}: field '{key}' has non-finite values")
        if ax.size > 1 and not np.all(np.diff(ax) > 0):
            raise DataError(f"{name}: field '{key}' must be strictly ascending")
    if depth[0] < 0:
        raise DataError(f"{name}: field 'depth' must be >= 0 (positive down), got {depth[0]}")
    for key, ax in (("lat", lat), ("lon", lon)):
        dd = np.diff(ax)
        if np.max(np.abs(dd - dd.mean())) > 1e-6 * abs(dd.mean()) + 1e-12:
            raise DataError(f"{name}: field '{key}' must have regular spacing")
    for key in ("dx_m", "dz_m", "m_per_deg_lat", "m_per_deg_lon"):
        if not sc[key] > 0:
            raise DataError(f"{name}: field '{key}' must be > 0, got {sc[key]}")
    # georeference consistency: lon/lat of the nodes vs the world axes
    x_nodes = sc["x0_m"] + sc["dx_m"] * np.arange(nx)
    z_nodes = sc["z0_m"] + sc["dz_m"] * np.arange(ny)
    lon_w = sc["origin_lon"] + x_nodes / sc["m_per_deg_lon"]
    lat_w = sc["origin_lat"] + z_nodes / sc["m_per_deg_lat"]
    if np.max(np.abs(lon_w - lon)) > 0.01 * abs(lon[1] - lon[0]):
        raise DataError(f"{name}: 'lon' disagrees with origin_lon + (x0_m + i*dx_m)/m_per_deg_lon")
    if np.max(np.abs(lat_w - lat)) > 0.01 * abs(lat[1] - lat[0]):
        raise DataError(f"{name}: 'lat' disagrees with origin_lat + (z0_m + j*dz_m)/m_per_deg_lat")

    # NaN policy: currents must be finite in valid water (an error names where), and the
    # contract says 0 elsewhere; bathymetry and land mask must be finite everywhere.
    for key, a in (("u", u), ("v", v)):
        bad = ~np.isfinite(a)
        if bad.any():
            in_water = bad & (valid[None] == 1)
            if in_water.any():
                idx = tuple(int(i) for i in np.argwhere(in_water)[0])
                raise DataError(f"{name}: NaN currents inside valid water: '{key}' has "
                                f"{int(in_water.sum())} non-finite values where valid_mask == 1 "
                                f"(first at (t, depth, lat, lon) index {idx})")
            raise DataError(f"{name}: '{key}' has {int(bad.sum())} non-finite values where "
                            "valid_mask == 0 (contracts §3: must be 0 there)")
    for key, a in (("u_tide", u_t), ("v_tide", v_t), ("elevation", elev), ("land_mask", land)):
        nbad = int((~np.isfinite(a)).sum())
        if nbad:
            raise DataError(f"{name}: field '{key}' has {nbad} non-finite values")
    if np.any((land < 0) | (land > 1)):
        raise DataError(f"{name}: field 'land_mask' must be in [0, 1]")
    if has_tide not in (0, 1):
        raise DataError(f"{name}: field 'has_tide' must be 0 or 1, got {has_tide}")

    # boundaries: hold each column's deepest valid value below it; 0 without currents (one
    # time step at a time: no full-size temporaries)
    uv = np.empty((nt, nz, ny, nx, 2), dtype=np.float32)
    src_k = hold_levels(valid)
    for ti in range(nt):
        for c, a in ((0, u), (1, v)):
            f = np.take_along_axis(a[ti], src_k, axis=0)
            f[:, ~cmask] = 0
            uv[ti, ..., c] = f
    tide_on = int(has_tide == 1 and use_tide_layers)
    uv_tide = np.zeros((nt, ny, nx, 2), dtype=np.float32)
    if tide_on:
        uv_tide[..., 0] = np.where(cmask, u_t, 0.0)
        uv_tide[..., 1] = np.where(cmask, v_t, 0.0)
    t_inv, t_lut, t_lut_h = _axis_lut(time_s)
    d_inv, d_lut, d_lut_h = _axis_lut(depth)
    dx, dz = sc["dx_m"], sc["dz_m"]
    return Grid(
        uv=uv, uv_tide=uv_tide, elevation=elev, land=land, valid=valid,
        current_mask=cmask.astype(np.float32), cell_full=_cell_full(cmask),
        time_s=time_s, time_inv=t_inv, time_lut=t_lut, time_lut_inv_h=float(t_lut_h),
        depth=depth, depth_inv=d_inv, depth_lut=d_lut, depth_lut_inv_h=float(d_lut_h),
        x0=sc["x0_m"], dx=dx, inv_dx=1.0 / dx, x_max=sc["x0_m"] + (nx - 1) * dx, nx=int(nx),
        z0=sc["z0_m"], dz=dz, inv_dz=1.0 / dz, z_max=sc["z0_m"] + (ny - 1) * dz, ny=int(ny),
        gain=g, tide_layers=tide_on, tide_amp=amp, tide_omega=omega, tide_phase=phase,
        time0_unix_s=sc["time0_unix_s"], origin_lat=sc["origin_lat"],
        origin_lon=sc["origin_lon"], m_per_deg_lat=sc["m_per_deg_lat"],
        m_per_deg_lon=sc["m_per_deg_lon"],
    )


def grid_metadata(src) -> dict:
    """The export's ``meta_json`` as a dict (source path/sha256, variant, region, ...).

    Parameters
    ----------
    src : path-like or mapping
        A grid export file or an in-memory mapping with its keys (as for :func:`load_grid`).

    Returns
    -------
    dict
        The decoded metadata.

    Raises
    ------
    DataError
        If ``meta_json`` is missing or not valid JSON.
    """
    d, name = _as_mapping(src)
    if "meta_json" not in d:
        raise DataError(f"{name}: missing fields: meta_json")
    try:
        return json.loads(str(np.asarray(d["meta_json"]).reshape(())))
    except json.JSONDecodeError as exc:
        raise DataError(f"{name}: field 'meta_json' is not valid JSON ({exc})") from exc


def with_forcing(grid: Grid, current_gain: float | None = None, tide=None) -> Grid:
    """A copy of ``grid`` sharing its arrays, with a different gain and/or synthetic tide.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    current_gain : float, optional
        Gain g on the data currents, dimensionless; default: keep ``grid.gain``.
    tide : None, mapping or (A, w, phi)
        Synthetic tide term as for :func:`load_grid`; ``None`` (default) sets none, replacing
        any the grid had.

    Returns
    -------
    Grid
        The grid with the new forcing.

    Raises
    ------
    ConfigError
        Bad ``current_gain`` or ``tide``.
    """
    amp, omega, phase = _parse_tide(tide)
    g = grid.gain if current_gain is None else float(current_gain)
    if not np.isfinite(g):
        raise ConfigError(f"current_gain: must be finite, got {current_gain!r}")
    return grid._replace(gain=g, tide_amp=amp, tide_omega=omega, tide_phase=phase)


def world_to_lonlat(grid: Grid, x, z):
    """World metres to longitude and latitude (equirectangular, contracts §3).

    Parameters
    ----------
    grid : Grid
        The loaded grid export (its georeference).
    x, z : array_like
        World coordinates east and north, m.

    Returns
    -------
    lon, lat : ndarray
        Longitude and latitude, degrees, shaped like ``x`` and ``z``.
    """
    return (grid.origin_lon + np.asarray(x) / grid.m_per_deg_lon,
            grid.origin_lat + np.asarray(z) / grid.m_per_deg_lat)


def lonlat_to_world(grid: Grid, lon, lat):
    """Longitude and latitude to world metres (equirectangular, contracts §3).

    Parameters
    ----------
    grid : Grid
        The loaded grid export (its georeference).
    lon, lat : array_like
        Longitude and latitude, degrees.

    Returns
    -------
    x, z : ndarray
        World coordinates east and north, m.
    """
    return ((np.asarray(lon) - grid.origin_lon) * grid.m_per_deg_lon,
            (np.asarray(lat) - grid.origin_lat) * grid.m_per_deg_lat)


def grid_extent(grid: Grid) -> tuple[float, float, float, float]:
    """The horizontal extent of the grid nodes.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.

    Returns
    -------
    tuple of float
        ``(x_min, x_max, z_min, z_max)``, m.
    """
    return grid.x0, grid.x_max, grid.z0, grid.z_max


# ----------------------------------------------------------------------------- kernels


@hot_kernel(inline="always")
def _locate(ax, inv, lut, lut_inv_h, v):
    """(i0, i1, w) with ``v ~ (1 - w) ax[i0] + w ax[i1]``; clamped outside the axis."""
    n = ax.shape[0]
    if n == 1:
        return 0, 0, 0.0
    if v <= ax[0]:
        return 0, 1, 0.0
    if v >= ax[n - 1]:
        return n - 2, n - 1, 1.0
    b = int((v - ax[0]) * lut_inv_h)
    if b >= lut.shape[0]:
        b = lut.shape[0] - 1
    i = lut[b]
    while i < n - 2 and ax[i + 1] <= v:
        i += 1
    return i, i + 1, (v - ax[i]) * inv[i]


@hot_kernel(inline="always")
def _hcell(grid, x, z):
    """Horizontal cell (i, j) and weights (wx, wz) for world (x, z); clamped at the edges."""
    fx = (x - grid.x0) * grid.inv_dx
    fz = (z - grid.z0) * grid.inv_dz
    nx1 = grid.nx - 1
    ny1 = grid.ny - 1
    if fx < 0.0:
        fx = 0.0
    elif fx > nx1:
        fx = float(nx1)
    if fz < 0.0:
        fz = 0.0
    elif fz > ny1:
        fz = float(ny1)
    i = int(fx)
    j = int(fz)
    if i > nx1 - 1:
        i = nx1 - 1
    if j > ny1 - 1:
        j = ny1 - 1
    return i, j, fx - i, fz - j


@hot_kernel(inline="always")
def locate_time(grid, t):
    """Locate a time on the grid's time axis (clamped outside it).

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    t : float
        Time, s since ``time0_unix_s``.

    Returns
    -------
    tuple
        ``(i0, i1, w)``: neighbouring indices (int) and weight (float, 0..1) of ``i1``.
    """
    return _locate(grid.time_s, grid.time_inv, grid.time_lut, grid.time_lut_inv_h, t)


@hot_kernel(inline="always")
def sample_current_data(grid, x, y, z, t):
    """Data part of the current, ``(g u + u_tide, g v + v_tide)``, without the synthetic tide term.

    Bilinear in (x, z) over current-defined nodes (renormalised, see the module docstring),
    linear in depth ``y`` and time ``t`` (held columns), clamped at the edges.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    x, y, z : float
        World position (east, depth positive down, north), m.
    t : float
        Time, s since ``time0_unix_s``.

    Returns
    -------
    tuple of float
        ``(ce, cn)``: current east and north, m s-1.
    """
    t0, t1, wt = locate_time(grid, t)
    return sample_current_at(grid, x, y, z, t0, t1, wt)


@hot_kernel(inline="always")
def sample_current_at(grid, x, y, z, t0, t1, wt):
    """:func:`sample_current_data` with the time already located (:func:`locate_time`).

    For loops that sample many agents at one time.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    x, y, z : float
        World position (east, depth positive down, north), m.
    t0, t1 : int
        Neighbouring time indices from :func:`locate_time`.
    wt : float
        Weight of ``t1``, 0..1.

    Returns
    -------
    tuple of float
        ``(ce, cn)``: current east and north, m s-1, without the synthetic tide term.
    """
    i, j, k0, k1, wk, a00, a10, a01, a11 = point_cell(grid, x, y, z)
    return _blend(grid, t0, t1, wt, i, j, k0, k1, wk, a00, a10, a01, a11)


@hot_kernel(inline="always")
def point_cell(grid, x, y, z):
    """A point's place in the grid: the time-independent part of :func:`sample_current_at`.

    For fixed points sampled at many times (:func:`time_slab` at each time of the axis).

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    x, y, z : float
        World position (east, depth positive down, north), m.

    Returns
    -------
    tuple
        ``(i, j, k0, k1, wk, a00, a10, a01, a11)``: horizontal cell (int), depth levels
        (int) and the weight of ``k1``, and the bilinear weights (renormalised next to
        nodes without currents).
    """
    i, j, wx, wz = _hcell(grid, x, z)
    k0, k1, wk = _locate(grid.depth, grid.depth_inv, grid.depth_lut, grid.depth_lut_inv_h, y)
    a00 = (1.0 - wx) * (1.0 - wz)
    a10 = wx * (1.0 - wz)
    a01 = (1.0 - wx) * wz
    a11 = wx * wz
    # next to nodes without currents (their arrays are 0): renormalise by the defined share
    # of the weight (>= 1/2), fade to 0 below it; inside the coverage nothing changes
    if grid.cell_full[j, i] == 0:
        m = grid.current_mask
        r = 1.0 / max((a00 * m[j, i] + a10 * m[j, i + 1])
                      + (a01 * m[j + 1, i] + a11 * m[j + 1, i + 1]), MIN_CURRENT_WEIGHT)
        a00 *= r
        a10 *= r
        a01 *= r
        a11 *= r
    return i, j, k0, k1, wk, a00, a10, a01, a11


@hot_kernel(inline="always")
def time_slab(grid, ti, i, j, k0, k1, wk, a00, a10, a01, a11):
    """A located point's data current at one time of the axis, before the gain.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    ti : int
        Index into the time axis.
    i, j, k0, k1, wk, a00, a10, a01, a11
        The point's place (:func:`point_cell`).

    Returns
    -------
    tuple of float
        ``(u, v, ut, vt)``: east and north (linear in depth) and the tide layers' (0 without
        them), m s-1: what :func:`current_from_parts` blends between two times.
    """
    u0, v0 = _slab(grid.uv, ti, k0, j, i, a00, a10, a01, a11)
    u1, v1 = _slab(grid.uv, ti, k1, j, i, a00, a10, a01, a11)
    wk0 = 1.0 - wk
    ut = vt = 0.0
    if grid.tide_layers == 1:
        ut, vt = _slab2(grid.uv_tide, ti, j, i, a00, a10, a01, a11)
    return wk0 * u0 + wk * u1, wk0 * v0 + wk * v1, ut, vt


@hot_kernel(inline="always")
def _parts(grid, t0, t1, i, j, k0, k1, wk, a00, a10, a01, a11):
    """The time-interval part of :func:`_blend`: a point's data current at the interval's
    two times, each linear in depth, and its tide layers there: ``(u0, u1, v0, v1, ut0, ut1,
    vt0, vt1)`` (the tide's 0 without tide layers)."""
    u0, v0, ut0, vt0 = time_slab(grid, t0, i, j, k0, k1, wk, a00, a10, a01, a11)
    u1, v1, ut1, vt1 = time_slab(grid, t1, i, j, k0, k1, wk, a00, a10, a01, a11)
    return u0, u1, v0, v1, ut0, ut1, vt0, vt1


@hot_kernel(inline="always")
def current_from_parts(grid, wt, u0, u1, ut0, ut1):
    """One component of the data current at a time of an interval, from the point's parts
    there (:func:`sample_current_parts`).

    Parameters
    ----------
    grid : Grid
        The loaded grid export (the one the parts were sampled on).
    wt : float
        Weight of the interval's later time (:func:`locate_time`).
    u0, u1, ut0, ut1 : float
        The component's parts (``u0, u1, ut0, ut1`` or ``v0, v1, vt0, vt1``).

    Returns
    -------
    float
        The component, m s-1, without the synthetic tide term: the bits of
        :func:`sample_current_at` at the same time.
    """
    ue = grid.gain * ((1.0 - wt) * u0 + wt * u1)
    if grid.tide_layers == 1:
        ue += (1.0 - wt) * ut0 + wt * ut1
    return ue


@hot_kernel(inline="always")
def _blend(grid, t0, t1, wt, i, j, k0, k1, wk, a00, a10, a01, a11):
    """The data current ``(ce, cn)`` of a point located by :func:`point_cell` at the time
    located by :func:`locate_time`."""
    u0, u1, v0, v1, ut0, ut1, vt0, vt1 = _parts(grid, t0, t1, i, j, k0, k1, wk, a00, a10,
                                                a01, a11)
    return (current_from_parts(grid, wt, u0, u1, ut0, ut1),
            current_from_parts(grid, wt, v0, v1, vt0, vt1))


@hot_kernel(inline="always")
def sample_current_parts(grid, x, y, z, t0, t1):
    """A point's data current over one interval of the time axis, in parts.

    For fixed points sampled at many times of one interval (a field's face centres): the
    current at any time of the interval is then :func:`current_from_parts` of these parts,
    per component, the bits of :func:`sample_current_at`, without locating the point or
    reading the grid again.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    x, y, z : float
        World position (east, depth positive down, north), m.
    t0, t1 : int
        The interval's time indices (:func:`locate_time`).

    Returns
    -------
    tuple of float
        ``(u0, u1, v0, v1, ut0, ut1, vt0, vt1)``: east and north at ``t0`` and ``t1``
        (linear in depth, before the gain), and the tide layers' (0 without them), m s-1.
    """
    i, j, k0, k1, wk, a00, a10, a01, a11 = point_cell(grid, x, y, z)
    return _parts(grid, t0, t1, i, j, k0, k1, wk, a00, a10, a01, a11)


@hot_kernel(inline="always")
def synthetic_tide(grid, t):
    """Synthetic tide term ``A [sin(w t + phi), cos(w t + phi)]`` (east, north).

    Parameters
    ----------
    grid : Grid
        The loaded grid export (its ``tide_amp``, ``tide_omega``, ``tide_phase``).
    t : float
        Time, s since ``time0_unix_s``.

    Returns
    -------
    tuple of float
        ``(te, tn)``, m s-1; ``(0, 0)`` when ``tide_amp == 0``.
    """
    if grid.tide_amp == 0.0:
        return 0.0, 0.0
    ph = grid.tide_omega * t + grid.tide_phase
    return grid.tide_amp * math.sin(ph), grid.tide_amp * math.cos(ph)


@hot_kernel(inline="always")
def sample_current(grid, x, y, z, t):
    """Current at a world position and time.

    ``g (u, v) + (u_tide, v_tide) + A (sin, cos)(w t + phi)``: bilinear in (x, z) over
    current-defined nodes (renormalised; fades to 0 where less than half of the weight is
    defined), linear in depth ``y`` (each column holding its deepest valid value below it) and
    time, clamped outside the grid. The vertical component of the current is zero. (Loops
    over many agents at one time may call :func:`sample_current_data` per agent and
    :func:`synthetic_tide` once.)

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    x, y, z : float
        World position (east, depth positive down, north), m.
    t : float
        Time, s since ``time0_unix_s``.

    Returns
    -------
    tuple of float
        ``(ce, cn)``: current east and north, m s-1.
    """
    ce, cn = sample_current_data(grid, x, y, z, t)
    te, tn = synthetic_tide(grid, t)
    return ce + te, cn + tn


@hot_kernel(inline="always")
def _slab(uv, ti, ki, j, i, a00, a10, a01, a11):
    return ((a00 * uv[ti, ki, j, i, 0] + a10 * uv[ti, ki, j, i + 1, 0])
            + (a01 * uv[ti, ki, j + 1, i, 0] + a11 * uv[ti, ki, j + 1, i + 1, 0]),
            (a00 * uv[ti, ki, j, i, 1] + a10 * uv[ti, ki, j, i + 1, 1])
            + (a01 * uv[ti, ki, j + 1, i, 1] + a11 * uv[ti, ki, j + 1, i + 1, 1]))


@hot_kernel(inline="always")
def _slab2(tt, ti, j, i, a00, a10, a01, a11):
    return ((a00 * tt[ti, j, i, 0] + a10 * tt[ti, j, i + 1, 0])
            + (a01 * tt[ti, j + 1, i, 0] + a11 * tt[ti, j + 1, i + 1, 0]),
            (a00 * tt[ti, j, i, 1] + a10 * tt[ti, j, i + 1, 1])
            + (a01 * tt[ti, j + 1, i, 1] + a11 * tt[ti, j + 1, i + 1, 1]))


@hot_kernel(inline="always")
def _bilinear2d(a, i, j, wx, wz):
    return ((1.0 - wz) * ((1.0 - wx) * a[j, i] + wx * a[j, i + 1])
            + wz * ((1.0 - wx) * a[j + 1, i] + wx * a[j + 1, i + 1]))


@hot_kernel(inline="always")
def sample_elevation(grid, x, z):
    """Bathymetric elevation at (x, z), bilinear, clamped at the edges.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    x, z : float
        World position east and north, m.

    Returns
    -------
    float
        Elevation h(x, z), m, positive up.
    """
    i, j, wx, wz = _hcell(grid, x, z)
    return _bilinear2d(grid.elevation, i, j, wx, wz)


@hot_kernel(inline="always")
def sample_land(grid, x, z):
    """Land mask at (x, z), bilinear, clamped at the edges.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    x, z : float
        World position east and north, m.

    Returns
    -------
    float
        Land mask m_land(x, z) in [0, 1] (1 = land).
    """
    i, j, wx, wz = _hcell(grid, x, z)
    return _bilinear2d(grid.land, i, j, wx, wz)


@hot_kernel(inline="always")
def current_defined(grid, x, z):
    """Share of the bilinear weight at (x, z) on nodes with currents (``current_mask``).

    1 = fully inside the currents' coverage; < 0.5 = the sampled current fades toward 0 (water
    without currents, e.g. outside a CMEMS subset polygon, or land). Clamped at the edges.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    x, z : float
        World position east and north, m.

    Returns
    -------
    float
        The share, 0..1.
    """
    i, j, wx, wz = _hcell(grid, x, z)
    return _bilinear2d(grid.current_mask, i, j, wx, wz)


@hot_kernel
def current_defined_points(grid, xz, out):
    """Vectorised :func:`current_defined`.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    xz : (n, 2) float64
        Points ``[x, z]``, m.
    out : (n,) float64
        Output array, written in place.

    Returns
    -------
    (n,) float64
        ``out``.
    """
    for n in range(xz.shape[0]):
        out[n] = current_defined(grid, xz[n, 0], xz[n, 1])
    return out


def current_coverage(grid: Grid, xz) -> np.ndarray:
    """:func:`current_defined` at many points.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    xz : array_like
        Points, (n, 2) ``[x, z]`` or (n, 3) ``[x, y, z]``, m.

    Returns
    -------
    (n,) float64
        Share of the bilinear weight on nodes with currents, 0..1.
    """
    xz = np.atleast_2d(np.asarray(xz, dtype=np.float64))
    if xz.shape[1] == 3:
        xz = xz[:, [0, 2]]
    xz = np.ascontiguousarray(xz)
    return current_defined_points(grid, xz, np.empty(xz.shape[0]))


@hot_kernel
def sample_current_points(grid, xyz, t, out):
    """Vectorised :func:`sample_current`.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    xyz : (n, 3) float64
        Points ``[x, y, z]``, m.
    t : (n,) float64
        Times, s since ``time0_unix_s``.
    out : (n, 2) float64
        Output array, written in place.

    Returns
    -------
    (n, 2) float64
        ``out``: ``[ce, cn]``, m s-1.
    """
    for n in range(xyz.shape[0]):
        ce, cn = sample_current(grid, xyz[n, 0], xyz[n, 1], xyz[n, 2], t[n])
        out[n, 0] = ce
        out[n, 1] = cn
    return out


@hot_kernel
def _point_weights(grid, xyz, cells, weights):
    """:func:`point_cell` of every point: ``cells`` (P, 4) int64 ``i, j, k0, k1`` and
    ``weights`` (P, 5) ``a00, a10, a01, a11, wk``, written in place."""
    for p in range(xyz.shape[0]):
        i, j, k0, k1, wk, a00, a10, a01, a11 = point_cell(grid, xyz[p, 0], xyz[p, 1],
                                                            xyz[p, 2])
        cells[p, 0] = i
        cells[p, 1] = j
        cells[p, 2] = k0
        cells[p, 3] = k1
        weights[p, 0] = a00
        weights[p, 1] = a10
        weights[p, 2] = a01
        weights[p, 3] = a11
        weights[p, 4] = wk


@hot_kernel
def _speeds_times(grid, cells, weights, times, out):
    """:func:`sample_speeds_times`'s loop: :func:`_blend` of each point located by
    :func:`_point_weights`, then ``hypot`` of the current with the synthetic tide; at a time
    of the axis (weight 0 or 1) only that time's slabs."""
    n_p = cells.shape[0]
    g = grid.gain
    for n in range(times.shape[0]):
        t = times[n]
        t0, t1, wt = locate_time(grid, t)
        te, tn = synthetic_tide(grid, t)
        single = t0 if wt == 0.0 else (t1 if wt == 1.0 else -1)
        for p in range(n_p):
            i = cells[p, 0]
            j = cells[p, 1]
            k0 = cells[p, 2]
            k1 = cells[p, 3]
            a00 = weights[p, 0]
            a10 = weights[p, 1]
            a01 = weights[p, 2]
            a11 = weights[p, 3]
            wk = weights[p, 4]
            if single >= 0:
                # a time on the axis: the other time's terms are (+-)0 (finite data), which
                # changes no speed's bits (at most a zero's sign, which hypot drops)
                u, v, ut, vt = time_slab(grid, single, i, j, k0, k1, wk, a00, a10, a01, a11)
                ue = g * u
                vn = g * v
                if grid.tide_layers == 1:
                    ue += ut
                    vn += vt
            else:
                ue, vn = _blend(grid, t0, t1, wt, i, j, k0, k1, wk, a00, a10, a01, a11)
            out[n * n_p + p] = math.hypot(ue + te, vn + tn)
    return out


def sample_speeds_times(grid: Grid, xyz, times) -> np.ndarray:
    """Current speed at every point at every time, time-major.

    ``hypot`` of :func:`sample_currents` at every (time, point) pair, the same bits (the C
    library's ``hypot``, as NumPy's), with each point's cell, levels and weights located
    once instead of once per time: for the current regime's quantiles (hundreds of
    thousands of samples).

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    xyz : (P, 3) array_like
        Points ``[x, y, z]``, m.
    times : (T,) array_like
        Times, s since ``time0_unix_s``.

    Returns
    -------
    (T * P,) float64
        Speeds, m s-1: entry ``n * P + p`` is point ``p`` at time ``n``.
    """
    xyz = np.ascontiguousarray(np.atleast_2d(xyz), dtype=np.float64)
    times = np.ascontiguousarray(np.atleast_1d(times), dtype=np.float64)
    cells = np.empty((xyz.shape[0], 4), dtype=np.int64)
    weights = np.empty((xyz.shape[0], 5))
    _point_weights(grid, xyz, cells, weights)
    return _speeds_times(grid, cells, weights, times, np.empty(times.size * xyz.shape[0]))


@hot_kernel
def level_currents(grid, cells, weights, k, out):
    """The data current of depth level ``k`` at located points, at every time of the axis.

    The bilinear part of :func:`time_slab` on one level (before the gain, without the tide
    layers): with the points' levels cached, :func:`speeds_from_levels` gives
    :func:`sample_speeds_times` at any depth between two levels without reading the grid.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    cells, weights : (P, 4) int64, (P, 5) float64
        The points' places (:func:`point_cell`; the depth columns are not read).
    k : int
        Depth level.
    out : (T, P, 2) float64
        Output, ``T`` the grid's times, written in place.

    Returns
    -------
    bool
        True when every time of the axis locates on itself (:func:`locate_time`'s weight 0
        or 1 at that index): the condition under which :func:`speeds_from_levels` equals
        :func:`sample_speeds_times` over ``grid.time_s``.
    """
    n_p = cells.shape[0]
    exact = True
    for n in range(grid.time_s.shape[0]):
        t0, t1, wt = locate_time(grid, grid.time_s[n])
        if not ((wt == 0.0 and t0 == n) or (wt == 1.0 and t1 == n)):
            exact = False
        for p in range(n_p):
            u, v = _slab(grid.uv, n, k, cells[p, 1], cells[p, 0], weights[p, 0],
                         weights[p, 1], weights[p, 2], weights[p, 3])
            out[n, p, 0] = u
            out[n, p, 1] = v
    return exact


@hot_kernel
def tide_layer_currents(grid, cells, weights, out):
    """:func:`level_currents` of the grid's tide layers (``uv_tide``; only with
    ``tide_layers == 1``).

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    cells, weights : (P, 4) int64, (P, 5) float64
        The points' places (:func:`point_cell`).
    out : (T, P, 2) float64
        Output, written in place.
    """
    for n in range(grid.time_s.shape[0]):
        for p in range(cells.shape[0]):
            u, v = _slab2(grid.uv_tide, n, cells[p, 1], cells[p, 0], weights[p, 0],
                          weights[p, 1], weights[p, 2], weights[p, 3])
            out[n, p, 0] = u
            out[n, p, 1] = v


@hot_kernel(inline="always")
def _level_sample(grid, c0, c1, ct, wk, n, p, te, tn):
    """The current of :func:`speeds_from_levels` at time ``n`` and point ``p``, before the
    ``hypot``: ``(east, north)``, m s-1."""
    wk0 = 1.0 - wk
    ue = grid.gain * (wk0 * c0[n, p, 0] + wk * c1[n, p, 0])
    vn = grid.gain * (wk0 * c0[n, p, 1] + wk * c1[n, p, 1])
    if grid.tide_layers == 1:
        ue += ct[n, p, 0]
        vn += ct[n, p, 1]
    return ue + te, vn + tn


@hot_kernel
def speeds_from_levels(grid, c0, c1, ct, wk, out):
    """:func:`sample_speeds_times` over the grid's times from the points' currents on the
    two levels around their depth, the same bits.

    Parameters
    ----------
    grid : Grid
        The loaded grid export (its gain, tide layers and synthetic tide are applied here).
    c0, c1 : (T, P, 2) float64
        :func:`level_currents` of the levels ``k0`` and ``k1`` of the depth.
    ct : (T, P, 2) float64
        :func:`tide_layer_currents` (not read without tide layers).
    wk : float
        The weight of ``k1`` at the depth (:func:`point_cell`).
    out : (T * P,) float64
        Speeds, m s-1, time-major, written in place.

    Returns
    -------
    (T * P,) float64
        ``out``.
    """
    n_p = c0.shape[1]
    for n in range(c0.shape[0]):
        te, tn = synthetic_tide(grid, grid.time_s[n])
        for p in range(n_p):
            ce, cn = _level_sample(grid, c0, c1, ct, wk, n, p, te, tn)
            out[n * n_p + p] = math.hypot(ce, cn)
    return out


#: Bins of :func:`order_stats_from_levels`'s histogram of squared speeds.
ORDER_BINS = 4096
#: Relative and absolute margins around a bin in squared speed, beyond which a sample's order
#: against the bin's is certain: far above the rounding of ``u*u + v*v`` (3 roundings) and of
#: ``hypot`` (under one ulp).
ORDER_REL = 1e-12
ORDER_ABS = 1e-290
#: Most samples :func:`order_stats_from_levels` takes the ``hypot`` of per rank.
ORDER_MAX_CANDIDATES = 1 << 16


@hot_kernel(inline="always")
def _order_bin(v, lo, scale, nb):
    """:func:`order_stats_from_levels`'s bin of squared speed ``v`` (monotone in ``v``; 0 at
    and below ``lo``, ``nb - 1`` at and above the top)."""
    return min(int((v - lo) * scale), nb - 1) if v > lo else 0


@njit(cache=True)
def order_stats_from_levels(grid, c0, c1, ct, wk, ranks, s2, out):
    """Order statistics of :func:`speeds_from_levels`'s speeds without the ``hypot`` of
    every sample, the same values.

    The squared speed ``s = u*u + v*v`` of every sample is binned; for each rank, the bin
    that holds it in the order of ``s``, widened by ``ORDER_REL`` and ``ORDER_ABS`` each
    side, is the only place where the order of ``s`` and that of ``hypot`` can differ: its
    samples' ``hypot`` are sorted and the rank's value read there, checked to be a sample
    of the bin itself (then every sample below the widened bin has a smaller speed and
    every sample above it a larger one, whatever the rounding).

    Parameters
    ----------
    grid, c0, c1, ct, wk
        As for :func:`speeds_from_levels`.
    ranks : (R,) int64
        0-based ranks in ascending order of speed, each in ``[0, T * P)``.
    s2 : (T * P,) float64
        Work array (the squared speeds).
    out : (R,) float64
        The speeds at the ranks, m s-1, written in place.

    Returns
    -------
    bool
        False when the values could not be certified (non-finite samples, all squared
        speeds equal, too many samples around a rank, a rank read outside its bin): then
        ``out`` is not set and the caller sorts the speeds themselves.
    """
    n_t = c0.shape[0]
    n_p = c0.shape[1]
    size = n_t * n_p
    lo = math.inf
    hi = -math.inf
    for n in range(n_t):
        te, tn = synthetic_tide(grid, grid.time_s[n])
        for p in range(n_p):
            ce, cn = _level_sample(grid, c0, c1, ct, wk, n, p, te, tn)
            v = ce * ce + cn * cn
            if not math.isfinite(v):
                return False
            s2[n * n_p + p] = v
            lo = min(lo, v)
            hi = max(hi, v)
    if not hi > lo:
        return False
    nb = ORDER_BINS
    scale = nb / (hi - lo)
    count = np.zeros(nb, np.int64)
    bmin = np.full(nb, math.inf)
    bmax = np.full(nb, -math.inf)
    for q in range(size):
        v = s2[q]
        b = _order_bin(v, lo, scale, nb)
        count[b] += 1
        bmin[b] = min(bmin[b], v)
        bmax[b] = max(bmax[b], v)
    n_r = ranks.shape[0]
    rbin = np.empty(n_r, np.int64)
    w_lo = np.empty(n_r)
    w_hi = np.empty(n_r)
    for r in range(n_r):
        b = 0
        below = 0
        while below + count[b] <= ranks[r]:
            below += count[b]
            b += 1
        rbin[r] = b
        w_lo[r] = bmin[b] * (1.0 - ORDER_REL) - ORDER_ABS
        w_hi[r] = bmax[b] * (1.0 + ORDER_REL) + ORDER_ABS
    # one pass: the samples below each rank's widened bin counted, those in it gathered.
    # The binning is monotone in s, so a sample whose bin lies below that of w_lo[r] is below
    # w_lo[r], one whose bin lies above that of w_hi[r] is above w_hi[r]: the first are
    # counted from the histogram and only the samples of the bins between are compared
    n_below = np.zeros(n_r, np.int64)
    n_cand = np.zeros(n_r, np.int64)
    idx = np.empty((n_r, ORDER_MAX_CANDIDATES), np.int64)
    near = np.zeros(nb, np.uint8)
    b_lo = np.empty(n_r, np.int64)
    for r in range(n_r):
        b_lo[r] = _order_bin(w_lo[r], lo, scale, nb)
        b_hi = _order_bin(w_hi[r], lo, scale, nb)
        for b in range(b_lo[r]):
            n_below[r] += count[b]
        for b in range(b_lo[r], b_hi + 1):
            near[b] = 1
    for q in range(size):
        v = s2[q]
        b = _order_bin(v, lo, scale, nb)
        if near[b] == 0:
            continue
        for r in range(n_r):
            if v < w_lo[r]:
                if b >= b_lo[r]:            # not counted from the histogram
                    n_below[r] += 1
            elif v <= w_hi[r]:
                c = n_cand[r]
                if c == ORDER_MAX_CANDIDATES:
                    return False
                idx[r, c] = q
                n_cand[r] = c + 1
    for r in range(n_r):
        nc = n_cand[r]
        speed = np.empty(nc)
        for c in range(nc):
            n = idx[r, c] // n_p
            p = idx[r, c] - n * n_p
            te, tn = synthetic_tide(grid, grid.time_s[n])
            ce, cn = _level_sample(grid, c0, c1, ct, wk, n, p, te, tn)
            speed[c] = math.hypot(ce, cn)
        order = np.argsort(speed, kind="mergesort")
        m = ranks[r] - n_below[r]
        if m < 0 or m >= nc:
            return False
        v = s2[idx[r, order[m]]]
        if _order_bin(v, lo, scale, nb) != rbin[r]:
            return False
        out[r] = speed[order[m]]
    return True


@hot_kernel
def sample_elevation_points(grid, xz, out):
    """Vectorised :func:`sample_elevation`.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    xz : (n, 2) float64
        Points ``[x, z]``, m.
    out : (n,) float64
        Output array, written in place.

    Returns
    -------
    (n,) float64
        ``out``: elevation, m, positive up.
    """
    for n in range(xz.shape[0]):
        out[n] = sample_elevation(grid, xz[n, 0], xz[n, 1])
    return out


def sample_currents(grid: Grid, xyz, t) -> np.ndarray:
    """Currents at many points and times.

    Parameters
    ----------
    grid : Grid
        The loaded grid export.
    xyz : array_like
        (n, 3) points ``[x, y, z]``, m.
    t : float or array_like
        Time(s), s since ``time0_unix_s``; a scalar or (n,).

    Returns
    -------
    (n, 2) float64
        ``[ce, cn]``, m s-1.
    """
    xyz = np.ascontiguousarray(np.atleast_2d(xyz), dtype=np.float64)
    t = np.ascontiguousarray(np.broadcast_to(np.asarray(t, dtype=np.float64), (xyz.shape[0],)))
    return sample_current_points(grid, xyz, t, np.empty((xyz.shape[0], 2)))
