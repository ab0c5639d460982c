"""Analytic grids for tests, benchmarks and examples.

Grid exports (the contracts §3 mapping of arrays) built from closed-form fields, so that a
test, a benchmark or an example needs no data product::

    from oneocean.engine import load_grid
    from oneocean.testing import make_test_grid, uniform_grid

    coast = load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40))   # coast, slope, tides
    calm = load_grid(uniform_grid(0.3, -0.1))                      # known, uniform current

* :func:`make_test_grid`: currents varying in x, z, depth and time, real tide layers, a coast
  with land along the west edge and a seafloor sloping down to the east;
* :func:`uniform_grid`: no land, a flat seafloor and one current everywhere, for tests that
  need an exact, known disturbance.
"""

from __future__ import annotations

import json

import numpy as np

from .errors import ConfigError

__all__ = ["make_test_grid", "uniform_grid"]


def make_test_grid(nt: int = 13, nz: int = 5, ny: int = 40, nx: int = 50, *,
                   dx_m: float = 150.0, dz_m: float = 150.0, dt_s: float = 3600.0,
                   depths=None, max_depth_m: float = 60.0, speed_ms: float = 0.5,
                   tide_ms: float = 0.2, has_tide: bool = True, land: bool = True,
                   origin_lat: float = 50.25, origin_lon: float = -4.40,
                   time0_unix_s: float = 1735689600.0) -> dict:
    """An analytic grid export with exactly the contracts §3 keys (for tests and benchmarks).

    Currents vary in x, z, depth and time; a coast with land lies along the west edge, the
    seafloor slopes down to ``1.25 * max_depth_m`` toward the east. The result can be saved
    with :func:`oneocean.io.write_npz_atomic` and loaded with
    :func:`oneocean.engine.load_grid`.

    Parameters
    ----------
    nt, nz, ny, nx : int, default 13, 5, 40, 50
        Grid size (time, depth, north, east). ``nt=49, nz=7, ny=150, nx=200`` is the size of
        the ``public`` variant (48 h hourly, 0.002 deg over 0.3 x 0.4 deg).
    dx_m, dz_m : float, default 150.0
        Spacing east / north, m.
    dt_s : float, default 3600.0
        Time step of the fields, s.
    depths : array-like, optional
        Depth levels, m (positive down), shape ``(nz,)``; default 0.5 m, then ``nz - 1``
        levels spaced geometrically from 2 m to ``max_depth_m``.
    max_depth_m : float, default 60.0
        Deepest default level, m; the seafloor deepens toward ``1.25 * max_depth_m`` and the
        currents decay with depth on the scale ``0.6 * max_depth_m``.
    speed_ms, tide_ms : float, default 0.5, 0.2
        Scale of the ocean currents and of the tidal currents, m s-1.
    has_tide : bool, default True
        Give M2 tide layers (``u_tide, v_tide``, zero on land); False: zero layers and
        ``has_tide`` 0.
    land : bool, default True
        A coast with land along the west edge; False: no land, a seafloor deepening from
        ``0.75 * max_depth_m`` in the west to ``1.25 * max_depth_m`` in the east.
    origin_lat, origin_lon : float, default 50.25, -4.40
        The grid centre (the local tangent plane's origin), degrees.
    time0_unix_s : float, default 1735689600.0
        POSIX time of the first field, s (2025-01-01T00:00Z).

    Returns
    -------
    dict of str to numpy.ndarray
        The grid export's arrays (``current_mask`` left out: the loader derives it from
        ``valid_mask``); ``u, v`` (nt, nz, ny, nx) float32 m s-1, zero where not valid.

    Raises
    ------
    ConfigError
        ``depths`` does not have shape ``(nz,)``.
    """
    if depths is None:
        depths = np.concatenate([[0.5], np.geomspace(2.0, max_depth_m, nz - 1)]) if nz > 1 \
            else np.array([0.5])
    depth = np.asarray(depths, dtype=np.float64)
    if depth.shape != (nz,):
        raise ConfigError(f"make_test_grid: depths has shape {depth.shape}, expected ({nz},)")
    deg = np.pi / 180.0
    m_lat = 111_195.0
    m_lon = 111_195.0 * np.cos(origin_lat * deg)
    x0 = -0.5 * (nx - 1) * dx_m
    z0 = -0.5 * (ny - 1) * dz_m
    x = x0 + dx_m * np.arange(nx)
    z = z0 + dz_m * np.arange(ny)
    time_s = dt_s * np.arange(nt, dtype=np.float64)
    lx = (nx - 1) * dx_m
    lz = (ny - 1) * dz_m
    X, Z = np.meshgrid(x, z)  # (ny, nx)
    H = 1.25 * max_depth_m
    if land:
        coast = x0 + lx * (0.12 + 0.05 * np.sin(2 * np.pi * (Z - z0) / lz))
        elev = -H * np.tanh(2.5 * (X - coast) / lx)
        elev = np.where(elev >= 0, 5.0 + elev, elev)  # a visible step up onto land
    else:
        elev = -H * (0.6 + 0.4 * (X - x0) / lx)
    land_mask = (elev >= 0).astype(np.float32)
    valid = ((-elev[None, :, :] > depth[:, None, None]) & (land_mask[None] == 0)).astype(np.uint8)
    T = time_s[:, None, None, None]
    D = depth[None, :, None, None]
    Xb, Zb = X[None, None], Z[None, None]
    semi = 2 * np.pi / 44712.0  # M2, rad s-1
    vert = np.exp(-D / (0.6 * max_depth_m))
    u = speed_ms * (0.6 + 0.4 * np.sin(2 * np.pi * Xb / lx + 0.5) * np.cos(2 * np.pi * Zb / lz)) \
        * vert * (1.0 + 0.3 * np.sin(semi * T))
    v = speed_ms * 0.5 * np.cos(2 * np.pi * Xb / lx) * np.sin(2 * np.pi * Zb / lz + 0.3) \
        * vert * (1.0 + 0.3 * np.cos(0.5 * semi * T))
    u = np.where(valid[None] == 1, u, 0.0).astype(np.float32)
    v = np.where(valid[None] == 1, v, 0.0).astype(np.float32)
    if has_tide:
        amp = tide_ms * (1.0 + 0.5 * (X - x0) / lx)
        ph = semi * time_s[:, None, None]
        u_t = amp[None] * np.cos(ph)
        v_t = 0.6 * amp[None] * np.sin(ph)
        water = (land_mask == 0)[None]
        u_t = np.where(water, u_t, 0.0).astype(np.float32)
        v_t = np.where(water, v_t, 0.0).astype(np.float32)
    else:
        u_t = np.zeros((nt, ny, nx), np.float32)
        v_t = np.zeros((nt, ny, nx), np.float32)
    meta = {"source": "oneocean.testing.make_test_grid", "variant": "test",
            "region": "analytic", "shape": [nt, nz, ny, nx]}
    return {
        "u": u, "v": v, "u_tide": u_t, "v_tide": v_t,
        "has_tide": np.array(1 if has_tide else 0, dtype=np.int8),
        "time_s": time_s, "time0_unix_s": np.array(float(time0_unix_s)),
        "depth": depth,
        "lat": origin_lat + z / m_lat, "lon": origin_lon + x / m_lon,
        "x0_m": np.array(x0), "dx_m": np.array(float(dx_m)),
        "z0_m": np.array(z0), "dz_m": np.array(float(dz_m)),
        "origin_lat": np.array(float(origin_lat)), "origin_lon": np.array(float(origin_lon)),
        "m_per_deg_lat": np.array(m_lat), "m_per_deg_lon": np.array(m_lon),
        "elevation": elev.astype(np.float32), "land_mask": land_mask, "valid_mask": valid,
        "meta_json": np.array(json.dumps(meta, sort_keys=True)),
    }


def uniform_grid(ce: float = 0.0, cn: float = 0.0, *, depth_m: float = 100.0, nx: int = 21,
                 ny: int = 21, dx_m: float = 100.0, nt: int = 2, dt_s: float = 86400.0) -> dict:
    """A land-free grid export with a spatially and temporally uniform current.

    Flat seafloor at ``depth_m``, two depth levels (0 and ``depth_m / 2``), no tide; used by
    tests that need exact, known disturbances. Otherwise as :func:`make_test_grid`.

    Parameters
    ----------
    ce, cn : float, default 0.0
        The current east / north, m s-1.
    depth_m : float, default 100.0
        Water depth everywhere, m.
    nx, ny : int, default 21
        Grid size east / north.
    dx_m : float, default 100.0
        Node spacing east and north, m.
    nt : int, default 2
        Number of time steps.
    dt_s : float, default 86400.0
        Time step of the fields, s.

    Returns
    -------
    dict of str to numpy.ndarray
        The grid export's arrays (the keys of :func:`make_test_grid`).
    """
    g = make_test_grid(nt=nt, nz=2, ny=ny, nx=nx, dx_m=dx_m, dz_m=dx_m, dt_s=dt_s,
                       depths=[0.0, 0.5 * depth_m], max_depth_m=depth_m, has_tide=False,
                       land=False)
    g["elevation"] = np.full((ny, nx), -float(depth_m), np.float32)
    g["land_mask"] = np.zeros((ny, nx), np.float32)
    g["valid_mask"] = np.ones((2, ny, nx), np.uint8)
    g["u"] = np.full((nt, 2, ny, nx), ce, np.float32)
    g["v"] = np.full((nt, 2, ny, nx), cn, np.float32)
    return g


def uniform_temporal(grid: dict, ce: float = 0.0, cn: float = 0.0) -> dict:
    """The temporal export (scene backend) of a steady, uniform current on ``grid``'s clock.

    Parameters
    ----------
    grid : dict
        A grid export (e.g. :func:`uniform_grid`): its ``time_s`` and origin are used.
    ce, cn : float, default 0.0
        The current east / north, m s-1, at every time; no tide.

    Returns
    -------
    dict of str to numpy.ndarray
        ``time_s``, ``u``, ``v``, ``u_tide``, ``v_tide``, ``lat``, ``lon``.
    """
    t = np.asarray(grid["time_s"], dtype=np.float64)
    return {"time_s": t, "u": np.full_like(t, ce), "v": np.full_like(t, cn),
            "u_tide": np.zeros_like(t), "v_tide": np.zeros_like(t),
            "lat": np.array(float(grid["origin_lat"])),
            "lon": np.array(float(grid["origin_lon"]))}
