"""The embedded default source: a deterministic synthetic coastal ocean (``source="synthetic"``).

Everything is an analytic, element-wise function of (longitude, latitude, time, depth) plus a
handful of random parameters drawn once from ``cfg["synthetic"]["seed"]``. Fields are built
lazily with :func:`dask.array.blockwise`, one block per time chunk, so a multi-GB source is never
materialised, and the chunking cannot change a single value.

Layout (box coordinates ``X = (lon - west) / (east - west)``, ``Y = (lat - south) /
(north - south)``, both in [0, 1], so any bounding box gets the same coastal scene scaled to it):

* land in the north behind an irregular coastline ``Y = Yc(X)`` (a random Fourier series);
* a continental shelf deepening to ~130 m, a slope (tanh) down to ~1600 m in the south;
* a meandering submarine canyon cutting the shelf (up to +250 m deeper than the shelf);
* a small island on the shelf (a Gaussian seamount piercing the surface);
* currents = an along-shore mean flow (coast on the right, i.e. westward) following the smoothed
  coastline plus drifting Gaussian eddies, both from streamfunctions (divergence-free on the
  local tangent plane), surface-intensified (e-folding 200 m and 70 m), slowly modulated in time;
* barotropic M2 (12.42 h) and S2 (12.00 h) tidal ellipses aligned with the coast, amplified in
  shallow water by ``clip(sqrt(80 m / h), 0.15, 1.25)``; spring tide at the window start.

Currents are NaN on land and at depth levels deeper than the local water depth; tides are NaN on
land.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import dask.array as da
import numpy as np
import xarray as xr

from ..errors import ConfigError
from ..product.exports import metres_per_degree
from ..io import canonical_json, config_hash
from ..vocab import CF
from ..engine import libm

__all__ = ["make_currents", "make_bathymetry", "synthetic_axes", "write_synthetic",
           "scene_summary", "M2_PERIOD_H", "S2_PERIOD_H"]

M2_PERIOD_H = 12.4206012
S2_PERIOD_H = 12.0

# Shape of the scene (box units of Y unless stated; depths in m).
_COAST_MEAN = 0.72          # mean coastline position (fraction of the box height)
_COAST_MODES = 16           # Fourier modes of the coastline; the first _COAST_LOW steer the flow
_COAST_LOW = 2
_SHELF_H, _SHELF_E = 140.0, 0.12           # shelf depth scale and e-folding distance
_DEEP_H, _SLOPE_D, _SLOPE_W = 1500.0, 0.45, 0.06
_LAND_H, _LAND_E = 150.0, 0.10
_CANYON_DEPTH, _CANYON_W = 250.0, 0.03
_ISLAND_R, _ISLAND_OFFSHORE, _ISLAND_TOP = 0.05, 0.17, 40.0
_N_EDDIES = 10
_MEAN_DECAY_M, _EDDY_DECAY_M = 200.0, 70.0
_TIDE_H_REF, _TIDE_FMIN, _TIDE_FMAX = 80.0, 0.15, 1.25

# Purposes of the seed streams (SeedSequence([seed, 0, purpose])).
_P_COAST, _P_ROUGH, _P_FEATURES, _P_EDDIES, _P_TIDES = 1, 2, 3, 4, 5


@dataclass(frozen=True)
class _Scene:
    """Random parameters of the scene (small arrays of scalars), drawn once per seed."""

    west: float
    east: float
    south: float
    north: float
    lx_m: float
    ly_m: float
    coast_amp: np.ndarray
    coast_phase: np.ndarray
    rough_kx: np.ndarray
    rough_ky: np.ndarray
    rough_amp: np.ndarray
    rough_phase: np.ndarray
    canyon_x: float
    canyon_phase: float
    island_x: float
    island_y: float
    island_h: float
    eddy_x0: np.ndarray
    eddy_y0: np.ndarray
    eddy_r: np.ndarray
    eddy_psi: np.ndarray
    eddy_cx: np.ndarray
    eddy_cy: np.ndarray
    eddy_mod_period: np.ndarray
    eddy_mod_phase: np.ndarray
    mean_speed: float
    mean_mod_phase: float
    m2_amp: float
    s2_amp: float
    tide_phase: float
    s2_offset: float


def _rng(seed: int, purpose: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(seed), 0, purpose]))


def _scene(cfg: dict) -> _Scene:
    """Draw the scene parameters from ``cfg["synthetic"]["seed"]`` (pure function of cfg)."""
    syn, bbox = cfg["synthetic"], cfg["region"]["bbox"]
    west, east, south, north = (float(bbox[k]) for k in ("west", "east", "south", "north"))
    m_lat, m_lon = metres_per_degree(0.5 * (south + north))
    lx, ly = (east - west) * m_lon, (north - south) * m_lat
    seed = syn["seed"]

    r = _rng(seed, _P_COAST)
    k = np.arange(1, _COAST_MODES + 1)
    coast_amp = 0.045 * k ** -1.1 * r.uniform(0.5, 1.0, k.size)
    coast_phase = r.uniform(0, 2 * np.pi, k.size)

    r = _rng(seed, _P_ROUGH)
    n_rough = 24
    rough_kx = r.integers(-9, 10, n_rough).astype(float)
    rough_ky = r.integers(1, 10, n_rough).astype(float)
    rough_amp = 5.0 * r.uniform(0.3, 1.0, n_rough) / np.hypot(rough_kx, rough_ky) ** 0.5
    rough_phase = r.uniform(0, 2 * np.pi, n_rough)

    r = _rng(seed, _P_FEATURES)
    canyon_x = r.uniform(0.22, 0.38)
    canyon_phase = r.uniform(0, 2 * np.pi)
    island_x = r.uniform(0.62, 0.80)
    island_y = float(_coastline(np.array([island_x]), coast_amp, coast_phase)[0][0]
                     - _ISLAND_OFFSHORE)
    island_h = float(_shelf_depth(np.array(_ISLAND_OFFSHORE))) + _ISLAND_TOP

    r = _rng(seed, _P_EDDIES)
    n = _N_EDDIES
    scale = np.sqrt(lx * ly)
    eddy_r = r.uniform(0.04, 0.12, n) * scale
    vmax = float(syn["eddy_speed_ms"]) * r.uniform(0.5, 1.0, n)
    sign = np.where(r.random(n) < 0.5, -1.0, 1.0)
    eddy_psi = sign * vmax * eddy_r * libm.exp(0.5) / np.sqrt(2.0)
    eddy_x0 = r.uniform(0.0, 1.0, n) * lx
    eddy_y0 = r.uniform(0.05, 0.55, n) * ly
    eddy_cx = -0.3 * float(syn["mean_speed_ms"]) + r.normal(0.0, 0.03, n)
    eddy_cy = r.normal(0.0, 0.02, n)
    eddy_mod_period = r.uniform(1.0, 4.0, n) * 86400.0
    eddy_mod_phase = r.uniform(0, 2 * np.pi, n)
    mean_mod_phase = r.uniform(0, 2 * np.pi)

    r = _rng(seed, _P_TIDES)
    tide_phase = r.uniform(-0.3, 0.3)
    s2_offset = r.uniform(-0.3, 0.3)

    return _Scene(west, east, south, north, float(lx), float(ly), coast_amp, coast_phase,
                  rough_kx, rough_ky, rough_amp, rough_phase, float(canyon_x),
                  float(canyon_phase), float(island_x), island_y, island_h, eddy_x0, eddy_y0,
                  eddy_r, eddy_psi, eddy_cx, eddy_cy, eddy_mod_period, eddy_mod_phase,
                  float(syn["mean_speed_ms"]), float(mean_mod_phase),
                  float(syn["m2_amplitude_ms"]), float(syn["s2_amplitude_ms"]),
                  float(tide_phase), float(s2_offset))


# --- element-wise scene functions (box coordinates X, Y; arrays broadcast) -----------------

def _coastline(X, amp, phase, n_modes=None):
    """Coastline ``Yc(X)`` and its slope ``dYc/dX`` (box units), first ``n_modes`` modes."""
    yc = np.full_like(X, _COAST_MEAN, dtype=float)
    dyc = np.zeros_like(X, dtype=float)
    for i in range(amp.size if n_modes is None else n_modes):
        k = 2.0 * np.pi * (i + 1)
        yc = yc + amp[i] * libm.sin(k * X + phase[i])
        dyc = dyc + amp[i] * k * libm.cos(k * X + phase[i])
    return yc, dyc


def _smoothstep(s):
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def _shelf_depth(d):
    """Water depth (m) of the undisturbed shelf/slope profile at offshore distance ``d`` >= 0."""
    deep = 0.5 * (1.0 + libm.tanh((d - _SLOPE_D) / _SLOPE_W))
    deep0 = 0.5 * (1.0 + libm.tanh(-_SLOPE_D / _SLOPE_W))
    return _SHELF_H * (1.0 - libm.exp(-d / _SHELF_E)) + _DEEP_H * (deep - deep0)


def _elevation(s: _Scene, X, Y):
    """Elevation (m, positive up) at box coordinates ``X, Y`` (broadcast arrays)."""
    yc, _ = _coastline(X, s.coast_amp, s.coast_phase)
    d = yc - Y                                               # offshore distance, box units
    sea = d >= 0.0
    ds = np.where(sea, d, 0.0)
    dl = np.where(sea, 0.0, d)
    elev = np.where(sea, -_shelf_depth(ds), _LAND_H * (1.0 - libm.exp(dl / _LAND_E)))
    rough = np.zeros(np.broadcast(X, Y).shape)
    for i in range(s.rough_amp.size):        # sin(a + b) expanded: transcendental only in 1-D
        ax_, ay_ = 2.0 * np.pi * s.rough_kx[i] * X, 2.0 * np.pi * s.rough_ky[i] * Y
        rough = rough + s.rough_amp[i] * (libm.sin(ax_) * libm.cos(ay_ + s.rough_phase[i])
                                          + libm.cos(ax_) * libm.sin(ay_ + s.rough_phase[i]))
    taper = np.clip(np.abs(d) / 0.04, 0.0, 1.0) * np.where(sea, 1.0, 3.0)
    elev = elev + rough * taper
    aspect = s.lx_m / s.ly_m
    # Canyon: a meandering Gaussian trough across the shelf, fading into the deep plain.
    xc = s.canyon_x + 0.03 * libm.sin(2.0 * np.pi * 1.5 * Y + s.canyon_phase)
    across = libm.exp(-(((X - xc) * aspect) / _CANYON_W) ** 2)
    along = _smoothstep((ds - 0.04) / 0.20) * (1.0 - 0.6 * _smoothstep((ds - 0.35) / 0.30))
    elev = elev - _CANYON_DEPTH * along * across
    # Island: a Gaussian seamount on the shelf whose top is _ISLAND_TOP above the sea surface.
    r2 = ((X - s.island_x) * aspect) ** 2 + (Y - s.island_y) ** 2
    return elev + s.island_h * libm.exp(-r2 / _ISLAND_R ** 2)


def _box(s: _Scene, lat, lon):
    """Box coordinates (Y[:, None], X[None, :]) of latitude (ny,) and longitude (nx,)."""
    Y = ((np.asarray(lat, float) - s.south) / (s.north - s.south))[:, None]
    X = ((np.asarray(lon, float) - s.west) / (s.east - s.west))[None, :]
    return Y, X


def _surface_flow(s: _Scene, X, Y, t):
    """Mean flow and eddies at the surface, (u, v) in m s-1 each (mean, eddy) at time ``t`` (s).

    Both derive from streamfunctions on the local tangent plane (x = X * lx_m, y = Y * ly_m),
    so ``du/dx + dv/dy = 0`` analytically.
    """
    # Mean flow: psi = -U ly G(Yc_low(X) - Y), coast on the right (westward along the shore).
    yc, dyc = _coastline(X, s.coast_amp, s.coast_phase, _COAST_LOW)
    d = yc - Y
    gprime = 0.5 + 0.7 * libm.exp(-((d - 0.3) / 0.12) ** 2)
    speed = -s.mean_speed * (1.0 + 0.25 * libm.sin(2.0 * np.pi * t / (2.7 * 86400.0)
                                                  + s.mean_mod_phase))
    um = speed * gprime
    vm = speed * gprime * dyc * (s.ly_m / s.lx_m)
    um, vm = np.broadcast_to(um, d.shape), np.broadcast_to(vm, d.shape)
    # Eddies: Gaussian streamfunctions psi_i exp(-r^2 / R_i^2), drifting, periodic in x.
    x, y = X * s.lx_m, Y * s.ly_m
    ue = np.zeros(np.broadcast(x, y).shape)
    ve = np.zeros_like(ue)
    for i in range(s.eddy_r.size):
        xi = s.eddy_x0[i] + s.eddy_cx[i] * t
        yi = s.eddy_y0[i] + s.eddy_cy[i] * t
        dx = np.mod(x - xi + 0.5 * s.lx_m, s.lx_m) - 0.5 * s.lx_m
        dy = y - yi
        r2 = 1.0 / s.eddy_r[i] ** 2
        amp = s.eddy_psi[i] * (1.0 + 0.3 * libm.sin(2.0 * np.pi * t / s.eddy_mod_period[i]
                                                  + s.eddy_mod_phase[i]))
        g = 2.0 * amp * r2 * libm.exp(-(dx * dx + dy * dy) * r2)
        ue = ue + g * dy
        ve = ve - g * dx
    return um, vm, ue, ve


def _tide(s: _Scene, X, Y, elev, t):
    """Barotropic M2 + S2 tidal current (u, v) in m s-1 at time ``t`` (s since window start)."""
    h = np.maximum(-elev, 1.0)
    factor = np.clip(np.sqrt(_TIDE_H_REF / h), _TIDE_FMIN, _TIDE_FMAX)
    yc, dyc = _coastline(X, s.coast_amp, s.coast_phase, _COAST_LOW)
    theta = libm.arctan(dyc * s.ly_m / s.lx_m)                # major axis along the coast
    eps = 0.15 + 0.2 * _smoothstep((yc - Y) / 0.6)          # minor/major, anticlockwise
    phase = s.tide_phase + 2.0 * np.pi * 0.1 * X            # alongshore-propagating tide
    u = np.zeros(np.broadcast(X, Y).shape)
    v = np.zeros_like(u)
    for amp, period_h, offset in ((s.m2_amp, M2_PERIOD_H, 0.0),
                                  (s.s2_amp, S2_PERIOD_H, s.s2_offset)):
        arg = 2.0 * np.pi * t / (period_h * 3600.0) - phase - offset
        major = amp * factor * libm.cos(arg)
        minor = amp * factor * eps * libm.sin(arg)
        u = u + major * libm.cos(theta) - minor * libm.sin(theta)
        v = v + major * libm.sin(theta) + minor * libm.cos(theta)
    return u, v


# --- dask blocks -----------------------------------------------------------------------------

def _currents_block(t, lat, lon, *, scene: _Scene, depth: np.ndarray):
    """Block of stacked (u, v): (2, nt, nz, ny, nx) float32, m s-1, NaN on land/below seafloor."""
    Y, X = _box(scene, lat, lon)
    elev = _elevation(scene, X, Y)
    ok = (depth[:, None, None] <= -elev[None])              # (nz, ny, nx)
    fm = libm.exp(-depth / _MEAN_DECAY_M)[:, None, None]
    fe = libm.exp(-depth / _EDDY_DECAY_M)[:, None, None]
    out = np.empty((2, t.size, depth.size, lat.size, lon.size), np.float32)
    for k, tk in enumerate(t):
        um, vm, ue, ve = _surface_flow(scene, X, Y, float(tk))
        out[0, k] = np.where(ok, um[None] * fm + ue[None] * fe, np.nan)
        out[1, k] = np.where(ok, vm[None] * fm + ve[None] * fe, np.nan)
    return out


def _tide_block(t, lat, lon, *, scene: _Scene):
    """Block of stacked (u_tide, v_tide): (2, nt, ny, nx) float32, m s-1, NaN on land."""
    Y, X = _box(scene, lat, lon)
    elev = _elevation(scene, X, Y)
    land = elev >= 0.0
    out = np.empty((2, t.size, lat.size, lon.size), np.float32)
    for k, tk in enumerate(t):
        u, v = _tide(scene, X, Y, elev, float(tk))
        out[0, k] = np.where(land, np.nan, u)
        out[1, k] = np.where(land, np.nan, v)
    return out


def _elevation_block(lat, lon, *, scene: _Scene):
    """Block of elevation: (ny, nx) float32, m, positive up."""
    Y, X = _box(scene, lat, lon)
    return _elevation(scene, X, Y).astype(np.float32)


# --- public API ------------------------------------------------------------------------------

def synthetic_axes(cfg: dict) -> dict:
    """Coordinate axes of the synthetic source.

    Parameters
    ----------
    cfg : dict
        The validated config (``region`` bbox, time and max_depth_m; ``synthetic``
        resolution_deg, time_step_hours and depths_m).

    Returns
    -------
    dict
        ``longitude`` (nx,) and ``latitude`` (ny,) float64 degrees, ascending, from the west
        (south) edge of the region bbox every ``synthetic.resolution_deg`` up to the east
        (north) edge; ``time`` (nt,) datetime64[ns] every ``time_step_hours`` from
        ``region.time.start`` up to its end; ``depth`` (nz,) float64 m, ascending, the
        ``synthetic.depths_m`` not deeper than ``region.max_depth_m``.

    Raises
    ------
    ConfigError
        A non-positive resolution, an empty time axis, or no depth level.
    """
    syn, reg = cfg["synthetic"], cfg["region"]
    bbox, res = reg["bbox"], float(syn["resolution_deg"])
    if res <= 0:
        raise ConfigError(f"synthetic.resolution_deg: must be > 0, got {res}")

    def axis(lo, hi):
        n = int(np.floor((hi - lo) / res + 1e-9)) + 1
        return np.round(np.linspace(lo, lo + (n - 1) * res, n), 10)

    start = np.datetime64(str(reg["time"]["start"]).replace("Z", ""), "ns")
    end = np.datetime64(str(reg["time"]["end"]).replace("Z", ""), "ns")
    step = np.timedelta64(int(round(float(syn["time_step_hours"]) * 3600e9)), "ns")
    if end < start or step <= np.timedelta64(0, "ns"):
        raise ConfigError("region.time / synthetic.time_step_hours: empty time axis")
    nt = int((end - start) // step) + 1
    depth = np.array([d for d in syn["depths_m"] if d <= float(reg["max_depth_m"])], float)
    if depth.size == 0:
        raise ConfigError("synthetic.depths_m: no level within region.max_depth_m")
    return {"longitude": axis(float(bbox["west"]), float(bbox["east"])),
            "latitude": axis(float(bbox["south"]), float(bbox["north"])),
            "time": start + step * np.arange(nt), "depth": np.sort(depth)}


def _attrs(cfg: dict, what: str) -> dict:
    syn = {k: cfg["synthetic"][k] for k in sorted(cfg["synthetic"])}
    return {
        "Conventions": "CF-1.11",
        "title": f"SYNTHETIC coastal ocean {what} (OneOcean embedded default; not real data)",
        "source": "synthetic",
        "source_files": "[]",
        "synthetic_seed": int(cfg["synthetic"]["seed"]),
        "synthetic_config": canonical_json({"synthetic": syn, "region": cfg["region"]}).strip(),
        "synthetic_config_hash": config_hash({"synthetic": syn, "region": cfg["region"]}),
        "comment": ("Analytic scene: irregular coastline, shelf, slope and deep water, a "
                    "submarine canyon and an island; mean along-shore flow plus drifting eddies "
                    "(streamfunction, surface-intensified); M2/S2 tidal ellipses amplified in "
                    "shallow water."),
    }


def _coords(ax: dict, with_depth: bool = True, with_time: bool = True) -> dict:
    coords = {
        "latitude": ("latitude", ax["latitude"], {"standard_name": "latitude",
                                                  "units": "degrees_north", "axis": "Y"}),
        "longitude": ("longitude", ax["longitude"], {"standard_name": "longitude",
                                                     "units": "degrees_east", "axis": "X"}),
    }
    if with_time:
        coords["time"] = ("time", ax["time"], {"standard_name": "time", "axis": "T"})
    if with_depth:
        coords["depth"] = ("depth", ax["depth"], {"standard_name": "depth", "units": "m",
                                                  "positive": "down", "axis": "Z"})
    return coords


def _velocity_attrs(name: str) -> dict:
    what = "eastward" if name.startswith("u") else "northward"
    tide = " due to tides" if name.endswith("_tide") else ""
    return {"standard_name": CF[name], "long_name": f"{what} sea water velocity{tide}",
            "units": "m s-1"}


def make_currents(cfg: dict, chunks: dict | None = None) -> xr.Dataset:
    """Synthetic currents (and tides) on the region, lazily as dask arrays.

    Parameters
    ----------
    cfg : dict
        Validated config; uses ``region`` (bbox, time, max_depth_m), ``synthetic`` and
        ``sources.tides``.
    chunks : dict, optional
        Chunk sizes for ``time``, ``latitude``, ``longitude`` (default: 1 time step, whole
        horizontal plane). Values do not depend on the chunking.

    Returns
    -------
    xarray.Dataset
        ``u``, ``v`` : (time, depth, latitude, longitude) float32, m s-1, NaN on land and below
        the seafloor; ``u_tide``, ``v_tide`` : (time, latitude, longitude) float32, m s-1, NaN on
        land (only when ``sources.tides`` is true). ``attrs["source"] == "synthetic"``.

    Raises
    ------
    ConfigError
        The axes cannot be built (:func:`synthetic_axes`).
    """
    ax = synthetic_axes(cfg)
    scene = _scene(cfg)
    chunks = {"time": 1, "latitude": -1, "longitude": -1, **(chunks or {})}
    t0 = ax["time"][0]
    t_s = ((ax["time"] - t0) / np.timedelta64(1, "ns")).astype(float) * 1e-9
    t = da.from_array(t_s, chunks=chunks["time"])
    lat = da.from_array(ax["latitude"], chunks=chunks["latitude"])
    lon = da.from_array(ax["longitude"], chunks=chunks["longitude"])
    uv = da.blockwise(partial(_currents_block, scene=scene, depth=ax["depth"]), "ctzyx",
                      t, "t", lat, "y", lon, "x", new_axes={"c": 2, "z": ax["depth"].size},
                      dtype=np.float32, meta=np.empty((0,) * 5, np.float32))
    dims = ("time", "depth", "latitude", "longitude")
    data = {"u": (dims, uv[0], _velocity_attrs("u")), "v": (dims, uv[1], _velocity_attrs("v"))}
    if cfg.get("sources", {}).get("tides", True):
        tide = da.blockwise(partial(_tide_block, scene=scene), "ctyx", t, "t", lat, "y",
                            lon, "x", new_axes={"c": 2}, dtype=np.float32,
                            meta=np.empty((0,) * 4, np.float32))
        tdims = ("time", "latitude", "longitude")
        data["u_tide"] = (tdims, tide[0], _velocity_attrs("u_tide"))
        data["v_tide"] = (tdims, tide[1], _velocity_attrs("v_tide"))
    return xr.Dataset(data, coords=_coords(ax), attrs=_attrs(cfg, "currents"))


def make_bathymetry(cfg: dict, chunks: dict | None = None) -> xr.Dataset:
    """Synthetic bathymetry/topography on the same grid as :func:`make_currents`.

    Parameters
    ----------
    cfg : dict
        The validated config; uses ``region`` and ``synthetic``.
    chunks : dict, optional
        Chunk sizes for ``latitude``, ``longitude`` (default: the whole plane). Values do not
        depend on the chunking.

    Returns
    -------
    xarray.Dataset
        ``elevation`` : (latitude, longitude) float32, m, positive up (negative = water depth),
        lazily as a dask array; ``attrs["source"] == "synthetic"``.
    """
    ax = synthetic_axes(cfg)
    scene = _scene(cfg)
    chunks = {"latitude": -1, "longitude": -1, **(chunks or {})}
    lat = da.from_array(ax["latitude"], chunks=chunks["latitude"])
    lon = da.from_array(ax["longitude"], chunks=chunks["longitude"])
    elev = da.blockwise(partial(_elevation_block, scene=scene), "yx", lat, "y", lon, "x",
                        dtype=np.float32, meta=np.empty((0, 0), np.float32))
    attrs = {"standard_name": CF["elevation"], "long_name": "height above mean sea level",
             "units": "m", "positive": "up"}
    return xr.Dataset({"elevation": (("latitude", "longitude"), elev, attrs)},
                      coords=_coords(ax, with_depth=False, with_time=False),
                      attrs=_attrs(cfg, "bathymetry"))


def write_synthetic(cfg: dict, currents_path, bathymetry_path, *, zlib: bool = False,
                    time_chunk: int = 4) -> None:
    """Write :func:`make_currents` / :func:`make_bathymetry` as canonical NetCDFs, atomically.

    Computed and written ``time_chunk`` time steps at a time (memory ~ that many 3-D fields per
    variable) with a deterministic layout (byte-identical reruns).

    Parameters
    ----------
    cfg : dict
        The validated config (see :func:`make_currents`).
    currents_path : str or os.PathLike
        The currents NetCDF to write.
    bathymetry_path : str or os.PathLike or None
        The bathymetry NetCDF to write; None: the currents only.
    zlib : bool, default False
        Compress the data variables (level 1).
    time_chunk : int, default 4
        Time steps computed and written at a time.
    """
    from ..product.build import netcdf_encoding, write_netcdf_atomic

    cur = make_currents(cfg, chunks={"time": int(time_chunk)})
    write_netcdf_atomic(cur, currents_path, netcdf_encoding(cur, zlib=zlib))
    if bathymetry_path is not None:
        bat = make_bathymetry(cfg)
        write_netcdf_atomic(bat, bathymetry_path, netcdf_encoding(bat, zlib=zlib))


def scene_summary(cfg: dict) -> dict:
    """Where the island and canyon are, and the size of the box.

    Parameters
    ----------
    cfg : dict
        The validated config (``region.bbox``, ``synthetic``).

    Returns
    -------
    dict
        ``island_lon``, ``island_lat`` (the island's centre), ``canyon_lon`` (the canyon's
        mean axis) and ``coast_lat_at_canyon``, degrees; ``extent_m`` [lx, ly], the box's
        east-west and north-south size, m.
    """
    s = _scene(cfg)
    lon = s.west + s.island_x * (s.east - s.west)
    lat = s.south + s.island_y * (s.north - s.south)
    yc, _ = _coastline(np.array([s.canyon_x]), s.coast_amp, s.coast_phase)
    return {"island_lon": float(lon), "island_lat": float(lat),
            "canyon_lon": float(s.west + s.canyon_x * (s.east - s.west)),
            "coast_lat_at_canyon": float(s.south + yc[0] * (s.north - s.south)),
            "extent_m": [s.lx_m, s.ly_m]}
