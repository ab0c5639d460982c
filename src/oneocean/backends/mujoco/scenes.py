"""Scenes of the MuJoCo backend, built from config: labelled stand-ins for the paper's scenes.

The paper's realism-first backend ships four packaged scenes (Dam, OpenWater, PierHarbor,
SimpleUnderwater). They are not redistributable here, so each kind is a **stand-in** generated
from a spec, a product grid export and (optionally) a temporal export:

* ``dam`` -- a wall across the scene (east-west by default), from the seafloor to above the
  surface;
* ``open_water`` -- bathymetry only, no structures;
* ``pier_harbor`` -- a quay along the north edge and 2-3 piers reaching south from it (one solid
  box per pier, seafloor to deck);
* ``simple_underwater`` -- a basin (four walls reaching above the surface) over a flat floor.

Frames
------
A scene lives in the SAME world frame as the product grid it was cut from (x east, y depth
positive down, z north, metres; :func:`oneocean.engine.grid.lonlat_to_world`), so a task's
coordinates mean the same point on both backends.

The local grid
--------------
:attr:`Scene.grid_data` is a grid export (contracts §3 keys, loadable with
:func:`oneocean.engine.load_grid`) on a square of side ``size_m`` centred on the anchor, nodes
every ``resolution_m``:

* ``elevation``: the product's bathymetry sampled bilinearly (``sample_elevation``), or
  ``-depth_m`` everywhere when ``depth_m`` is given (flat floor; then only structures are land);
  structures never change it (terrain only);
* ``land_mask``: 1 where the product's sampled land mask is >= 0.5, inside the footprint of a
  structure that reaches the surface, or in the boundary band of width ``margin_m`` (default
  :data:`MARGIN_M`) along the square's edges (the task scenarios, which sample episodes in
  valid water, then avoid them; the scene backend counts a vehicle there as a violation, as the
  core rejects the move); 0 elsewhere;
* ``depth``: the product's depth axis; ``valid_mask``: water nodes at every level shallower
  than the seafloor, and always at the first level (so every water node has a current);
* currents (``u, v``; no separate tide layers, ``has_tide = 0``):

  - ``temporal`` (default, the paper's injection): ``u + u_tide`` and ``v + v_tide`` of the
    temporal export, uniform over all water nodes and levels;
  - ``field``: the product grid's current (data + tide layers, gain 1) resampled at the local
    nodes and levels with the engine's sampler, so the current differs between vehicles.

Dataset clock
-------------
A scene time ``t`` (s, the simulation clock of an episode) corresponds to the dataset time
``T = start + rate * t`` (s since the product's ``time0_unix_s``). The local grid's time axis is
``time_s_local = (T_k - start) / rate`` for the data times ``T_k > start``, preceded by one
node at ``t = 0`` holding the data linearly interpolated at ``T = start``; its
``time0_unix_s`` is the product's ``time0_unix_s + start`` (the Unix time of ``t = 0``; for
``rate != 1`` the Unix time at ``t`` is ``time0_unix_s + rate * t``). The engine's time
interpolation at ``t`` therefore returns exactly the data's linear interpolation at ``T``.

Files
-----
:func:`scene_files` writes ``scene.xml`` (MJCF of the scene without a vehicle; heightfield
inline), ``grid.npz`` (the local grid, :func:`oneocean.io.write_npz_atomic`) and
``scene.json`` (:attr:`Scene.meta`); all atomic and byte-identical on a rebuild.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from ...errors import ConfigError, DataError

__all__ = ["SCENE_KINDS", "SCENE_LABELS", "Structure", "Scene", "build_scene", "scene_files",
           "SCENE_FORMAT", "SceneRoutes", "route_guide"]

#: Scene kinds (stand-ins for the paper's packaged scenes).
SCENE_KINDS = ("dam", "open_water", "pier_harbor", "simple_underwater")

#: The label of each kind.
SCENE_LABELS = {
    "dam": "stand-in for the paper's Dam scene",
    "open_water": "stand-in for the paper's OpenWater scene",
    "pier_harbor": "stand-in for the paper's PierHarbor scene",
    "simple_underwater": "stand-in for the paper's SimpleUnderwater scene",
}

#: Version tag of the scene meta / file layout.
SCENE_FORMAT = "oneocean.scene/1"

#: Largest number of local-grid nodes per side (heightfield and grid).
MAX_NODES = 257

_TOP_KEYS = ("name", "kind", "anchor", "size_m", "resolution_m", "margin_m", "depth_m",
             "currents", "clock", "structures")

#: Default width of the scene's boundary band, m: land in the local grid (no episode starts or
#: routes there; a vehicle entering it counts a violation), open water for MuJoCo.
MARGIN_M = 40.0

#: Kind-specific structure parameters and their defaults (lengths in m; ``None`` = derived
#: from the scene size, see :func:`_structures`).
STRUCTURE_DEFAULTS = {
    "dam": {"offset_m": None, "thickness_m": 12.0, "crest_m": 3.0, "yaw_deg": 0.0,
            "spillway_m": 30.0, "spill_depth_m": 9.0},
    "open_water": {},
    "pier_harbor": {"n_piers": 3, "pier_length_m": None, "pier_width_m": 8.0,
                    "quay_width_m": 20.0, "deck_m": 2.0},
    "simple_underwater": {"basin_m": None, "wall_thickness_m": 4.0, "crest_m": 2.0},
}

#: How deep a structure is founded below the deepest seafloor of its footprint, m.
FOUNDATION_M = 1.0


@dataclass(frozen=True)
class Structure:
    """A box-shaped structure of a scene (wall, pier, quay, basin wall).

    Attributes
    ----------
    name : str
        Unique name (the MJCF geom name).
    centre : (float, float, float)
        Box centre (x east, y depth positive down, z north), m, core world frame.
    half : (float, float, float)
        Half-extents along (east, down, north) before the yaw, m.
    yaw_rad : float
        Rotation about the vertical, compass sense (clockwise from north seen from above), rad.
    kind : str
        ``"wall"``, ``"pier"``, ``"quay"``, ``"basin"``.
    """

    name: str
    centre: tuple
    half: tuple
    yaw_rad: float
    kind: str

    @property
    def surfacing(self) -> bool:
        """True when the box reaches the water surface (its top is at or above y = 0)."""
        return self.centre[1] - self.half[1] <= 0.0

    def contains(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Whether horizontal points lie inside the footprint.

        Parameters
        ----------
        x, z : array_like
            Points east and north, m, core world frame (broadcast together).

        Returns
        -------
        ndarray of bool
            True inside the (yawed) footprint, boundary included.
        """
        s, c = math.sin(self.yaw_rad), math.cos(self.yaw_rad)
        dx = np.asarray(x) - self.centre[0]
        dz = np.asarray(z) - self.centre[2]
        # body axes: east' = (cos, -sin) in (east, north), north' = (sin, cos) (compass yaw)
        le = c * dx - s * dz
        ln = s * dx + c * dz
        return (np.abs(le) <= self.half[0]) & (np.abs(ln) <= self.half[2])

    def as_dict(self) -> dict:
        """The structure as a JSON-serialisable dict (for :attr:`Scene.meta`).

        Returns
        -------
        dict
            ``{"name", "centre", "half", "yaw_rad", "kind"}``, tuples as lists.
        """
        return {"name": self.name, "centre": list(self.centre), "half": list(self.half),
                "yaw_rad": self.yaw_rad, "kind": self.kind}


@dataclass(frozen=True)
class Scene:
    """A scene: local grid, structures, clock and the metadata to rebuild it.

    Attributes
    ----------
    name, kind, label : str
        Scene name, one of :data:`SCENE_KINDS`, and its stand-in label.
    grid_data : dict
        Local grid export (contracts §3 keys), loadable with :func:`oneocean.engine.load_grid`.
    structures : tuple of Structure
        The scene's structures (none for ``open_water``).
    extent : (x0, x1, z0, z1)
        Horizontal extent of the local grid, m (core world frame).
    anchor : (lat, lon)
        Scene centre, degrees.
    currents : str
        ``"temporal"`` or ``"field"``.
    clock : (start_s, rate)
        Dataset time of scene time 0 (s since the product's time0) and dataset seconds per
        simulated second.
    meta : dict
        JSON-serialisable record of everything needed to rebuild the scene.
    """

    name: str
    kind: str
    label: str
    grid_data: dict = field(repr=False)
    structures: tuple
    extent: tuple
    anchor: tuple
    currents: str
    clock: tuple
    meta: dict = field(repr=False)

    @property
    def resolution_m(self) -> float:
        """Node spacing of the local grid and heightfield, m."""
        return float(self.grid_data["dx_m"])


# ----------------------------------------------------------------------------- validation


def _num(spec: Mapping, key: str, default, *, positive: bool = False, minimum=None,
         integer: bool = False, where: str = "scene"):
    val = spec.get(key, default)
    if val is None:
        return None
    if isinstance(val, bool) or not isinstance(val, (int, float, np.integer, np.floating)):
        raise ConfigError(f"{where}.{key}: must be a number, got {val!r}")
    val = float(val)
    if not math.isfinite(val):
        raise ConfigError(f"{where}.{key}: must be finite, got {val!r}")
    if positive and not val > 0:
        raise ConfigError(f"{where}.{key}: must be > 0, got {val!r}")
    if minimum is not None and val < minimum:
        raise ConfigError(f"{where}.{key}: must be >= {minimum}, got {val!r}")
    if integer:
        if val != int(val):
            raise ConfigError(f"{where}.{key}: must be an integer, got {val!r}")
        return int(val)
    return val


def normalise_spec(spec: Mapping) -> dict:
    """Validate a scene spec and return it with every default filled in.

    Parameters
    ----------
    spec : mapping
        Scene spec (keys as :func:`build_scene`'s ``spec``).

    Returns
    -------
    dict
        ``name``, ``kind``, ``anchor`` (``{lat, lon}`` or None), ``size_m``, ``resolution_m``,
        ``margin_m``, ``depth_m`` (or None), ``currents``, ``clock`` (``{start, rate}``) and
        ``structures`` (the kind's parameters of :data:`STRUCTURE_DEFAULTS`, defaults filled).

    Raises
    ------
    ConfigError
        A bad key or value (one line naming the key), or a size, resolution and margin that
        give too many nodes or no water.
    """
    if not isinstance(spec, Mapping):
        raise ConfigError(f"scene: spec must be a mapping, got {type(spec).__name__}")
    unknown = [k for k in spec if k not in _TOP_KEYS]
    if unknown:
        raise ConfigError(f"scene: unknown key '{unknown[0]}' (allowed: {', '.join(_TOP_KEYS)})")
    name = spec.get("name")
    if not isinstance(name, str) or not name.strip():
        raise ConfigError(f"scene.name: must be a non-empty string, got {name!r}")
    kind = spec.get("kind")
    if kind not in SCENE_KINDS:
        raise ConfigError(f"scene.kind: must be one of {', '.join(SCENE_KINDS)}, got {kind!r}")
    out = {"name": name, "kind": kind}
    anchor = spec.get("anchor")
    if anchor is None:
        out["anchor"] = None
    else:
        if not isinstance(anchor, Mapping):
            raise ConfigError(f"scene.anchor: must be a mapping {{lat, lon}} or null, "
                              f"got {anchor!r}")
        bad = [k for k in anchor if k not in ("lat", "lon")]
        if bad:
            raise ConfigError(f"scene.anchor: unknown key '{bad[0]}' (allowed: lat, lon)")
        lat = _num(anchor, "lat", None, where="scene.anchor")
        lon = _num(anchor, "lon", None, where="scene.anchor")
        if lat is None or lon is None:
            raise ConfigError("scene.anchor: needs both lat and lon (degrees)")
        if not -90.0 <= lat <= 90.0:
            raise ConfigError(f"scene.anchor.lat: must be in [-90, 90], got {lat!r}")
        out["anchor"] = {"lat": lat, "lon": lon}
    out["size_m"] = _num(spec, "size_m", 400.0, positive=True)
    out["resolution_m"] = _num(spec, "resolution_m", 4.0, positive=True)
    n = int(round(out["size_m"] / out["resolution_m"])) + 1
    if n > MAX_NODES:
        raise ConfigError(f"scene.resolution_m: {out['size_m']:g} m / {out['resolution_m']:g} m "
                          f"gives {n} nodes per side (max {MAX_NODES}); coarsen it")
    if n < 3:
        raise ConfigError(f"scene.size_m: must span at least 2 resolution_m cells, got "
                          f"{out['size_m']:g} m at {out['resolution_m']:g} m")
    out["margin_m"] = _num(spec, "margin_m", MARGIN_M, minimum=0.0)
    if 2.0 * out["margin_m"] >= out["size_m"]:
        raise ConfigError(f"scene.margin_m: {out['margin_m']:g} m leaves no water inside a "
                          f"{out['size_m']:g} m scene")
    out["depth_m"] = _num(spec, "depth_m", None, positive=True)
    currents = spec.get("currents", "temporal")
    if currents not in ("temporal", "field"):
        raise ConfigError(f"scene.currents: must be 'temporal' or 'field', got {currents!r}")
    out["currents"] = currents
    clock = spec.get("clock", {}) or {}
    if not isinstance(clock, Mapping):
        raise ConfigError(f"scene.clock: must be a mapping {{start, rate}}, got {clock!r}")
    bad = [k for k in clock if k not in ("start", "rate")]
    if bad:
        raise ConfigError(f"scene.clock: unknown key '{bad[0]}' (allowed: start, rate)")
    start = clock.get("start", "data_start")
    if start != "data_start":
        start = _num(clock, "start", None, where="scene.clock")
    out["clock"] = {"start": start,
                    "rate": _num(clock, "rate", 1.0, positive=True, where="scene.clock")}
    st = spec.get("structures", {}) or {}
    if not isinstance(st, Mapping):
        raise ConfigError(f"scene.structures: must be a mapping, got {st!r}")
    allowed = STRUCTURE_DEFAULTS[kind]
    bad = [k for k in st if k not in allowed]
    if bad:
        opts = ", ".join(allowed) if allowed else "none for this kind"
        raise ConfigError(f"scene.structures: unknown key '{bad[0]}' for kind '{kind}' "
                          f"(allowed: {opts})")
    sp = {}
    for k, default in allowed.items():
        if k == "n_piers":
            v = _num(st, k, default, integer=True, where="scene.structures")
            if not 1 <= v <= 6:
                raise ConfigError(f"scene.structures.n_piers: must be in 1..6, got {v}")
        elif k == "yaw_deg":
            v = _num(st, k, default, where="scene.structures")
        elif k in ("crest_m", "deck_m", "spill_depth_m"):
            v = _num(st, k, default, minimum=0.0, where="scene.structures")
        else:
            v = _num(st, k, default, positive=True, where="scene.structures")
        sp[k] = v
    out["structures"] = sp
    return out


# ----------------------------------------------------------------------------- building


def _column_box(name, kind, cx, cz, hx, hz, yaw, top_y, floor_depth):
    """A box from ``FOUNDATION_M`` below ``floor_depth`` (m, positive down) up to ``top_y``."""
    bottom = float(floor_depth) + FOUNDATION_M
    return Structure(name=name, centre=(float(cx), 0.5 * (bottom + top_y), float(cz)),
                     half=(float(hx), 0.5 * (bottom - top_y), float(hz)), yaw_rad=float(yaw),
                     kind=kind)


def _structures(kind: str, sp: dict, cx: float, cz: float, size: float,
                max_depth: float) -> tuple:
    """The kind's structures around the scene centre (cx, cz); ``max_depth`` (m) is the
    deepest seafloor of the scene (foundations reach below it)."""
    half = 0.5 * size
    if kind == "open_water":
        return ()
    if kind == "dam":
        off = sp["offset_m"] if sp["offset_m"] is not None else 0.25 * size
        yaw = math.radians(sp["yaw_deg"])
        # a wall along east' (compass yaw 0: east-west), offset north' of the centre, long
        # enough to cross the scene (the scene's width; sqrt(2) x that at an oblique yaw)
        s, c = math.sin(yaw), math.cos(yaw)
        wx, wz = cx + off * s, cz + off * c
        axis_aligned = abs(math.sin(2.0 * yaw)) < 1e-12
        length = half if axis_aligned else half * math.sqrt(2.0)
        # a spillway of width ``spillway_m`` at the scene's centre line: its crest is
        # ``spill_depth_m`` below the surface, the rest of the wall reaches above it
        sw = min(0.5 * sp["spillway_m"], 0.5 * length)
        piece = 0.5 * (length - sw)
        t2 = 0.5 * sp["thickness_m"]
        out = []
        for name, sgn in (("dam_wall_w", -1.0), ("dam_wall_e", 1.0)):
            a = sgn * (sw + piece)   # along east' from the wall's centre
            out.append(_column_box(name, "wall", wx + a * c, wz - a * s, piece, t2, yaw,
                                   -sp["crest_m"], max_depth))
        out.append(_column_box("dam_spillway", "crest", wx, wz, sw, t2, yaw,
                               min(sp["spill_depth_m"], max_depth), max_depth))
        return tuple(out)
    if kind == "pier_harbor":
        qw = sp["quay_width_m"]
        n = sp["n_piers"]
        length = sp["pier_length_m"] if sp["pier_length_m"] is not None else 0.35 * size
        top = -sp["deck_m"]
        quay_cz = cz + half - 0.5 * qw
        out = [_column_box("quay", "quay", cx, quay_cz, half, 0.5 * qw, 0.0, top, max_depth)]
        pw = sp["pier_width_m"]
        for k in range(n):
            px = cx - half + size * (k + 1) / (n + 1)
            pz = cz + half - qw - 0.5 * length
            out.append(_column_box(f"pier_{k}", "pier", px, pz, 0.5 * pw,
                                   0.5 * length + 0.5 * qw, 0.0, top, max_depth))
        return tuple(out)
    # simple_underwater: basin of four walls
    b = sp["basin_m"] if sp["basin_m"] is not None else 0.8 * size
    t = sp["wall_thickness_m"]
    top = -sp["crest_m"]
    hb = 0.5 * b
    return (
        _column_box("basin_n", "basin", cx, cz + hb, hb + t, 0.5 * t, 0.0, top, max_depth),
        _column_box("basin_s", "basin", cx, cz - hb, hb + t, 0.5 * t, 0.0, top, max_depth),
        _column_box("basin_e", "basin", cx + hb, cz, 0.5 * t, hb + t, 0.0, top, max_depth),
        _column_box("basin_w", "basin", cx - hb, cz, 0.5 * t, hb + t, 0.0, top, max_depth),
    )


def _interp_series(t_data: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Linear interpolation of ``values`` (nt, ...) on ``t_data`` at times ``t`` (clamped)."""
    out = np.empty((t.size,) + values.shape[1:], dtype=np.float64)
    for k, tk in enumerate(t):
        i = int(np.clip(np.searchsorted(t_data, tk, side="right") - 1, 0, max(t_data.size - 2, 0)))
        if t_data.size == 1:
            out[k] = values[0]
            continue
        w = (tk - t_data[i]) / (t_data[i + 1] - t_data[i])
        w = min(max(w, 0.0), 1.0)
        out[k] = (1.0 - w) * values[i] + w * values[i + 1]
    return out


def _temporal_series(temporal: Mapping) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    keys = ("time_s", "u", "v", "u_tide", "v_tide")
    missing = [k for k in keys if k not in temporal]
    if missing:
        raise DataError(f"temporal export: missing fields: {', '.join(missing)}")
    t = np.asarray(temporal["time_s"], dtype=np.float64)
    arrs = [np.asarray(temporal[k], dtype=np.float64) for k in keys[1:]]
    if t.ndim != 1 or t.size < 1 or any(a.shape != t.shape for a in arrs):
        raise DataError("temporal export: time_s, u, v, u_tide, v_tide must be 1-D of one length")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        raise DataError("temporal export: 'time_s' must be strictly ascending")
    if not all(np.all(np.isfinite(a)) for a in [t] + arrs):
        raise DataError("temporal export: non-finite values in time_s or the currents")
    return t, arrs[0] + arrs[2], arrs[1] + arrs[3]  # u + u_tide, v + v_tide


def _scalar(d: Mapping, key: str) -> float:
    return float(np.asarray(d[key]).reshape(()))


def build_scene(spec: Mapping, grid_data: Mapping, temporal: Mapping | None = None) -> Scene:
    """Build a scene (local grid, structures, clock) from a spec and the product's exports.

    Parameters
    ----------
    spec : mapping
        ``name``, ``kind`` (one of :data:`SCENE_KINDS`), ``anchor: {lat, lon}`` (degrees; null =
        the temporal export's point), ``size_m`` (square side, default 400 m),
        ``resolution_m`` (node spacing, default 4 m), ``depth_m`` (flat seafloor depth, m;
        default: the product's bathymetry), ``currents`` (``temporal`` or ``field``; default
        temporal), ``clock: {start: "data_start" | seconds since the product's time0,
        rate: dataset seconds per simulated second (default 1)}``, ``structures`` (kind-specific
        parameters, :data:`STRUCTURE_DEFAULTS`).
    grid_data : mapping
        The product's grid export (contracts §3).
    temporal : mapping, optional
        The temporal export (``time_s, u, v, u_tide, v_tide, lat, lon``); required for
        ``currents: temporal`` or a null anchor.

    Returns
    -------
    Scene
        The built scene.

    Raises
    ------
    ConfigError
        A bad spec key or value (one line naming the key), an anchor outside the grid or a
        scene square not inside it, a clock start outside the data's time span.
    DataError
        A malformed export, a temporal export whose time axis disagrees with the grid's, a
        scene without water.
    """
    from ...engine.grid import load_grid, lonlat_to_world, sample_currents, \
        sample_elevation_points, grid_metadata

    sp = normalise_spec(spec)
    src = load_grid(grid_data, use_tide_layers=True)
    if sp["anchor"] is None:
        if temporal is None:
            raise ConfigError("scene.anchor: null needs a temporal export (its point is used)")
        lat, lon = _scalar(temporal, "lat"), _scalar(temporal, "lon")
    else:
        lat, lon = sp["anchor"]["lat"], sp["anchor"]["lon"]
    ax, az = (float(a) for a in lonlat_to_world(src, lon, lat))
    x_lo, x_hi, z_lo, z_hi = src.x0, src.x_max, src.z0, src.z_max
    if not (x_lo <= ax <= x_hi and z_lo <= az <= z_hi):
        raise ConfigError(f"scene.anchor: ({lat:.6f}, {lon:.6f}) lies outside the grid "
                          f"(world x {ax:.0f} m, z {az:.0f} m; grid x [{x_lo:.0f}, {x_hi:.0f}], "
                          f"z [{z_lo:.0f}, {z_hi:.0f}] m)")
    size, res = sp["size_m"], sp["resolution_m"]
    n = int(round(size / res)) + 1
    size = res * (n - 1)
    x0, z0 = ax - 0.5 * size, az - 0.5 * size
    x1, z1 = x0 + size, z0 + size
    tol = 1e-6 * max(1.0, abs(x_hi - x_lo))
    if x0 < x_lo - tol or x1 > x_hi + tol or z0 < z_lo - tol or z1 > z_hi + tol:
        raise ConfigError(f"scene.size_m: the {size:g} m square around the anchor leaves the "
                          f"grid (x [{x0:.0f}, {x1:.0f}] vs [{x_lo:.0f}, {x_hi:.0f}], z "
                          f"[{z0:.0f}, {z1:.0f}] vs [{z_lo:.0f}, {z_hi:.0f}] m); shrink it or "
                          "move the anchor")
    xs = x0 + res * np.arange(n)
    zs = z0 + res * np.arange(n)
    X, Z = np.meshgrid(xs, zs)  # (ny, nx): row j = north index
    xz = np.ascontiguousarray(np.stack([X.ravel(), Z.ravel()], axis=1))
    elev_src = sample_elevation_points(src, xz, np.empty(xz.shape[0])).reshape(n, n)
    land_src = sample_elevation_points(src._replace(elevation=src.land), xz,
                                       np.empty(xz.shape[0])).reshape(n, n)
    if sp["depth_m"] is not None:
        elev = np.full((n, n), -sp["depth_m"])
        land = np.zeros((n, n), dtype=bool)
    else:
        elev = elev_src
        land = land_src >= 0.5
    water_depth = np.where(land, 0.0, -elev)
    max_depth = float(max(np.max(water_depth), 1.0))
    structures = _structures(sp["kind"], sp["structures"], ax, az, size, max_depth)
    for s in structures:
        if s.surfacing:
            land = land | s.contains(X, Z)
    water = ~land   # the water: currents are defined in it, the boundary band included
    m = sp["margin_m"]   # the boundary band: land to the scenario and the judge
    land = land | (X < x0 + m) | (X > x1 - m) | (Z < z0 + m) | (Z > z1 - m)
    if not np.any(~land):
        raise DataError(f"scene '{sp['name']}': no water inside the scene square")
    depth = np.asarray(src.depth, dtype=np.float64)
    nz = depth.size
    valid = (water[None] & (depth[:, None, None] < -elev[None])).astype(np.uint8)
    valid[0] = water.astype(np.uint8)

    # ---- clock and currents
    t_data = np.asarray(grid_data["time_s"], dtype=np.float64)
    time0 = _scalar(grid_data, "time0_unix_s")
    if sp["currents"] == "temporal" or temporal is not None:
        if temporal is None:
            raise ConfigError("scene.currents: 'temporal' needs a temporal export")
        t_series, u_series, v_series = _temporal_series(temporal)
        if "time" in temporal:
            t0_tmp = float(np.asarray(temporal["time"]).astype("datetime64[s]")
                           .astype(np.int64)[0]) - float(t_series[0])
            if abs(t0_tmp - time0) > 0.5:
                raise DataError(f"temporal export: its time origin ({t0_tmp:.0f} s Unix) differs "
                                f"from the grid's time0_unix_s ({time0:.0f}): not the same product")
    t_axis = t_series if sp["currents"] == "temporal" else t_data
    rate = sp["clock"]["rate"]
    start = float(t_axis[0]) if sp["clock"]["start"] == "data_start" else sp["clock"]["start"]
    if not t_axis[0] <= start <= t_axis[-1]:
        raise ConfigError(f"scene.clock.start: {start:g} s is outside the data's time span "
                          f"[{t_axis[0]:g}, {t_axis[-1]:g}] s")
    later = t_axis[t_axis > start]
    t_dataset = np.concatenate([[start], later])
    time_local = (t_dataset - start) / rate
    if time_local.size == 1:  # a clock starting at the last sample: hold it
        time_local = np.array([0.0, 1.0])
        t_dataset = np.array([start, start])
    nt = time_local.size
    if sp["currents"] == "temporal":
        ue = _interp_series(t_series, u_series, t_dataset)
        vn = _interp_series(t_series, v_series, t_dataset)
        u = np.broadcast_to(ue[:, None, None, None], (nt, nz, n, n))
        v = np.broadcast_to(vn[:, None, None, None], (nt, nz, n, n))
        u = np.where(valid[None] == 1, u, 0.0)
        v = np.where(valid[None] == 1, v, 0.0)
    else:
        u = np.zeros((nt, nz, n, n))
        v = np.zeros((nt, nz, n, n))
        pts = np.empty((n * n, 3))
        pts[:, 0] = X.ravel()
        pts[:, 2] = Z.ravel()
        for ti, td in enumerate(t_dataset):
            for k in range(nz):
                pts[:, 1] = depth[k]
                c = sample_currents(src, pts, np.full(n * n, td))
                u[ti, k] = c[:, 0].reshape(n, n)
                v[ti, k] = c[:, 1].reshape(n, n)
        u = np.where(valid[None] == 1, u, 0.0)
        v = np.where(valid[None] == 1, v, 0.0)
    m_lat, m_lon = _scalar(grid_data, "m_per_deg_lat"), _scalar(grid_data, "m_per_deg_lon")
    olat, olon = _scalar(grid_data, "origin_lat"), _scalar(grid_data, "origin_lon")
    src_meta = grid_metadata(grid_data)
    tmp_meta = {}
    if temporal is not None and "meta_json" in temporal:
        try:
            tmp_meta = json.loads(str(np.asarray(temporal["meta_json"]).reshape(())))
        except json.JSONDecodeError:
            raise DataError("temporal export: 'meta_json' is not valid JSON") from None
    meta = {
        "format": SCENE_FORMAT,
        "name": sp["name"], "kind": sp["kind"], "label": SCENE_LABELS[sp["kind"]],
        "spec": sp,
        "anchor": {"lat": lat, "lon": lon, "x_m": ax, "z_m": az},
        "extent_m": [x0, x1, z0, z1], "nodes": n, "resolution_m": res,
        "clock": {"start_s": start, "rate": rate, "time0_unix_s": time0 + start,
                  "dataset_time0_unix_s": time0},
        "currents": sp["currents"],
        "structures": [s.as_dict() for s in structures],
        "source_grid": src_meta,
        "temporal": tmp_meta,
        "land_nodes": int(land.sum()),
    }
    local_meta = {"source": "oneocean.backends.mujoco.scenes", "variant": "scene-local",
                  "scene": sp["name"], "kind": sp["kind"], "label": SCENE_LABELS[sp["kind"]],
                  "region": src_meta.get("region", ""), "shape": [nt, nz, n, n]}
    grid = {
        "u": u.astype(np.float32), "v": v.astype(np.float32),
        "u_tide": np.zeros((nt, n, n), np.float32), "v_tide": np.zeros((nt, n, n), np.float32),
        "has_tide": np.array(0, dtype=np.int8),
        "time_s": time_local.astype(np.float64), "time0_unix_s": np.array(time0 + start),
        "depth": depth.copy(),
        "lat": olat + zs / m_lat, "lon": olon + xs / m_lon,
        "x0_m": np.array(float(x0)), "dx_m": np.array(float(res)),
        "z0_m": np.array(float(z0)), "dz_m": np.array(float(res)),
        "origin_lat": np.array(olat), "origin_lon": np.array(olon),
        "m_per_deg_lat": np.array(m_lat), "m_per_deg_lon": np.array(m_lon),
        "elevation": elev.astype(np.float32), "land_mask": land.astype(np.float32),
        "valid_mask": valid, "current_mask": valid.any(axis=0).astype(np.uint8),
        "meta_json": np.array(json.dumps(local_meta, sort_keys=True)),
    }
    load_grid(grid)  # the local grid must be a valid export
    return Scene(name=sp["name"], kind=sp["kind"], label=SCENE_LABELS[sp["kind"]],
                 grid_data=grid, structures=structures, extent=(x0, x1, z0, z1),
                 anchor=(lat, lon), currents=sp["currents"], clock=(start, rate), meta=meta)


def scene_files(scene: Scene, out_dir, vehicle=None) -> dict:
    """Write a scene's files atomically: ``scene.xml``, ``grid.npz``, ``scene.json``.

    Parameters
    ----------
    scene : Scene
        The scene (:func:`build_scene`).
    out_dir : path-like
        Output folder (created).
    vehicle : str or Vehicle, optional
        Add this vehicle to ``scene.xml`` (default: the scene alone).

    Returns
    -------
    dict
        ``{"xml": path, "grid": path, "meta": path}``. Identical inputs give identical bytes.
    """
    from ...io import write_json_atomic, write_npz_atomic, write_text_atomic
    from .mjcf import scene_xml

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"xml": out / "scene.xml", "grid": out / "grid.npz", "meta": out / "scene.json"}
    write_text_atomic(paths["xml"], scene_xml(scene, vehicle))
    write_npz_atomic(paths["grid"], scene.grid_data)
    write_json_atomic(paths["meta"], scene.meta)
    return paths


# ----------------------------------------------------------------------------- routes

#: Standoff of a scene route from a structure's footprint, and least water over a submerged
#: structure's top, m (:class:`SceneRoutes`).
ROUTE_CLEAR_M = 2.0
#: Distance band between a scene route's pivot and the structure it follows, m: the inner face
#: of a basin wall or the side of a pier (:class:`SceneRoutes`).
LANE_OFFSET_M = (6.0, 14.0)
#: Largest heading change between the legs a scene route adds around its pivot leg, rad
#: (the task's own ``max_turn_rad`` when smaller).
LANE_TURN_RAD = math.radians(20.0)
#: Spread of a pivot leg's heading about the structure's axis, rad.
PIVOT_SPREAD_RAD = math.radians(15.0)


class SceneRoutes:
    """The scene-specific part of a scene cell's scenario: routes drawn on the structures.

    A task draws its routes, stations and start points with
    :func:`oneocean.tasks.spawn.sample_routes` (same arguments on every backend). In a scene
    with structures :class:`oneocean.tasks.Cell` installs this guide
    (:func:`oneocean.tasks.spawn.route_guide`), and ``sample_routes`` draws from it instead, from
    the same per-episode streams (deterministic in the seed). Each try draws a **pivot** from
    the scene's geometry, then builds the route around it:

    * ``dam``: a point on the spillway's crest line, at least 6 m inside its ends, the pivot
      leg crossing the wall
      (its normal +- 15 deg, either way); the route's depth at least :data:`ROUTE_CLEAR_M`
      above the crest: the route flies over the crest, between the surfacing wall pieces;
    * ``pier_harbor``: a point beside a pier (one of its two sides, :data:`LANE_OFFSET_M` from
      its face, between its tip and 30 m short of the quay), the pivot leg along the pier
      (+- 15 deg, either way): the route runs between the piers;
    * ``simple_underwater``: a point inside the basin :data:`LANE_OFFSET_M` from one wall's
      inner face, at least 40 m from the corners, the pivot leg along the wall (+- 15 deg):
      the route runs along the basin's walls.

    With ``n_legs = 0`` (a station, a start point) the route is the pivot (at the dam: the
    pivot moved 10-60 m back along its heading, before the spillway). Otherwise a random
    leg of the route passes through the pivot (at 20-80 % of its length) and the others
    follow from it, each turning by at most :data:`LANE_TURN_RAD` (and the task's
    ``max_turn_rad``). A try is kept when every vertex and every point of every leg (every
    1 m) lies in the scene's water (not land, not the boundary band), with the task's
    ``clearance`` over the seafloor, at least :data:`ROUTE_CLEAR_M` from every structure's
    footprint unless the structure's top is that far below the route's depth; else the
    next try, up to ``tries``.

    Parameters
    ----------
    scene : Scene
        A scene with structures (:func:`route_guide`).
    """

    def __init__(self, scene):
        g = scene.grid_data
        self.scene = scene
        self.land = np.asarray(g["land_mask"], dtype=np.float64)
        self.elev = np.asarray(g["elevation"], dtype=np.float64)
        self.x0, self.z0 = float(g["x0_m"]), float(g["z0_m"])
        self.res = float(g["dx_m"])
        self.structures = scene.structures
        self.depth_cap = math.inf
        for s in scene.structures:   # a route passes over a submerged crest
            if s.kind == "crest":
                self.depth_cap = min(self.depth_cap,
                                     s.centre[1] - s.half[1] - ROUTE_CLEAR_M)

    # -- the pivot of a try
    def pivot(self, u: np.ndarray) -> tuple[float, float, float]:
        """The pivot of one try, drawn on the scene's structures.

        Parameters
        ----------
        u : numpy.ndarray
            At least 5 uniforms in [0, 1) (one try's row of the episode's stream).

        Returns
        -------
        tuple of float
            ``(x, z, heading)``: world m and compass radians.
        """
        kind = self.scene.kind
        st = self.structures
        flip = math.pi if u[4] < 0.5 else 0.0
        spread = (2.0 * u[3] - 1.0) * PIVOT_SPREAD_RAD
        if kind == "dam":
            c = next(s for s in st if s.kind == "crest")
            s_, c_ = math.sin(c.yaw_rad), math.cos(c.yaw_rad)
            a = (2.0 * u[0] - 1.0) * max(c.half[0] - 6.0, 0.0)
            return (c.centre[0] + a * c_, c.centre[2] - a * s_, c.yaw_rad + spread + flip)
        lo, hi = LANE_OFFSET_M
        off = lo + (hi - lo) * u[0]
        if kind == "pier_harbor":
            piers = [s for s in st if s.kind == "pier"]
            p = piers[min(int(u[2] * len(piers)), len(piers) - 1)]
            side = 1.0 if (u[2] * len(piers)) % 1.0 < 0.5 else -1.0
            x = p.centre[0] + side * (p.half[0] + off)
            z_tip = p.centre[2] - p.half[2]
            z = z_tip + u[1] * max(2.0 * p.half[2] - 30.0, 0.0)
            return (x, z, spread + flip)
        walls = [s for s in st if s.kind == "basin"]
        w = walls[min(int(u[2] * len(walls)), len(walls) - 1)]
        cx = float(np.mean([s.centre[0] for s in walls]))
        cz = float(np.mean([s.centre[2] for s in walls]))
        if w.half[0] > w.half[2]:      # a north or south wall: along east
            inner = -1.0 if w.centre[2] > cz else 1.0
            z = w.centre[2] + inner * (w.half[2] + off)
            x = cx + (2.0 * u[1] - 1.0) * max(w.half[0] - 40.0, 0.0)
            return (x, z, 0.5 * math.pi + spread + flip)
        inner = -1.0 if w.centre[0] > cx else 1.0
        x = w.centre[0] + inner * (w.half[0] + off)
        z = cz + (2.0 * u[1] - 1.0) * max(w.half[2] - 40.0, 0.0)
        return (x, z, spread + flip)

    # -- validity
    def _node(self, arr, x, z):
        """The largest of ``arr``'s four nodes around each point (conservative), or +inf
        off the grid."""
        fi = (np.asarray(x) - self.x0) / self.res
        fj = (np.asarray(z) - self.z0) / self.res
        ny, nx = arr.shape
        i0, j0 = np.floor(fi).astype(np.int64), np.floor(fj).astype(np.int64)
        off = (i0 < 0) | (j0 < 0) | (i0 + 1 > nx - 1) | (j0 + 1 > ny - 1)
        i0, j0 = np.clip(i0, 0, nx - 2), np.clip(j0, 0, ny - 2)
        m = np.maximum(np.maximum(arr[j0, i0], arr[j0, i0 + 1]),
                       np.maximum(arr[j0 + 1, i0], arr[j0 + 1, i0 + 1]))
        return np.where(off, np.inf, m)

    def clear(self, x: np.ndarray, z: np.ndarray, depth: float, clearance: float,
              land_threshold: float) -> bool:
        """Whether every point is in the scene's water, clear of seafloor and structures.

        Parameters
        ----------
        x, z : numpy.ndarray
            The points, world m.
        depth : float
            Their depth, m.
        clearance : float
            Least water under them, m.
        land_threshold : float
            Land-mask value from which a node is land.

        Returns
        -------
        bool
            True when every point is in water, ``clearance`` over the seafloor and at least
            :data:`ROUTE_CLEAR_M` from every structure not that far below ``depth``.
        """
        if np.any(self._node(self.land, x, z) >= land_threshold):
            return False
        if np.any(-self._node(self.elev, x, z) - depth < clearance):
            return False
        for s in self.structures:
            if s.centre[1] - s.half[1] >= depth + ROUTE_CLEAR_M:
                continue   # far enough below the route
            big = Structure(s.name, s.centre, (s.half[0] + ROUTE_CLEAR_M, s.half[1],
                                               s.half[2] + ROUTE_CLEAR_M), s.yaw_rad, s.kind)
            if np.any(big.contains(x, z)):
                return False
        return True

    def route(self, u: np.ndarray, n_legs: int, leg_m: float, depth_m, clearance: float,
              max_turn_rad: float, land_threshold: float):
        """One try of a route around a pivot on the structures (class doc).

        Parameters
        ----------
        u : numpy.ndarray
            ``8 + n_legs`` uniforms in [0, 1).
        n_legs : int
            Legs of the route (0: a single point).
        leg_m : float
            Leg length, m.
        depth_m : sequence of float
            The task's depth range ``(lo, hi)``, m (capped above a submerged crest).
        clearance, max_turn_rad, land_threshold : float
            As in :meth:`clear`; the task's largest heading change between legs, rad.

        Returns
        -------
        numpy.ndarray or None
            ``(n_legs + 1, 3)`` vertices (world m), or None when the try is not clear.
        """
        lo, hi = float(depth_m[0]), min(float(depth_m[1]), self.depth_cap)
        if hi < lo:
            return None
        y = lo + (hi - lo) * u[5]
        px, pz, h = self.pivot(u)
        if n_legs == 0:
            if self.scene.kind == "dam":   # a point before the spillway, not on its crest
                d = 10.0 + 50.0 * u[7]
                px, pz = px - d * math.sin(h), pz - d * math.cos(h)
            pts = np.array([[px, y, pz]])
            return pts if self.clear(pts[:, 0], pts[:, 2], y, clearance, land_threshold) \
                else None
        k = min(int(u[6] * n_legs), n_legs - 1)      # the pivot leg
        f = 0.2 + 0.6 * u[7]
        turn = min(LANE_TURN_RAD, float(max_turn_rad))
        heads = np.empty(n_legs)
        heads[k] = h
        for j in range(k + 1, n_legs):
            heads[j] = heads[j - 1] + (2.0 * u[8 + j] - 1.0) * turn
        for j in range(k - 1, -1, -1):
            heads[j] = heads[j + 1] + (2.0 * u[8 + j] - 1.0) * turn
        v = np.empty((n_legs + 1, 2))
        v[k] = (px - f * leg_m * math.sin(h), pz - f * leg_m * math.cos(h))
        for j in range(k, n_legs):
            v[j + 1] = v[j] + leg_m * np.array([math.sin(heads[j]), math.cos(heads[j])])
        for j in range(k - 1, -1, -1):
            v[j] = v[j + 1] - leg_m * np.array([math.sin(heads[j]), math.cos(heads[j])])
        n = max(int(math.ceil(leg_m)), 1) + 1
        t = np.linspace(0.0, 1.0, n)
        xs = (v[:-1, None, 0] + t * (v[1:, None, 0] - v[:-1, None, 0])).ravel()
        zs = (v[:-1, None, 1] + t * (v[1:, None, 1] - v[:-1, None, 1])).ravel()
        if not self.clear(xs, zs, y, clearance, land_threshold):
            return None
        return np.stack([v[:, 0], np.full(n_legs + 1, y), v[:, 1]], axis=1)

    def __call__(self, grid, stv, rows, n_legs, leg_m, depth_m, clearance, max_turn_rad,
                 land_threshold, tries, what):
        """:func:`oneocean.tasks.spawn.sample_routes`' contract: ``(routes, failed)``."""
        from ...engine import streams
        from ...errors import NotApplicable

        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        n_legs = int(n_legs)
        out = np.zeros((rows.size, n_legs + 1, 3))
        todo = np.arange(rows.size)
        for _ in range(int(tries)):
            if not todo.size:
                break
            u = streams.uniform_rows(stv, 0.0, 1.0, 8 + n_legs, rows[todo])
            done = np.zeros(todo.size, dtype=bool)
            for i, j in enumerate(todo):
                r = self.route(u[i], n_legs, float(leg_m), depth_m, float(clearance),
                               float(max_turn_rad), float(land_threshold))
                if r is not None:
                    out[j] = r
                    done[i] = True
            todo = todo[~done]
        failed = {}
        for j in todo:
            label = "route" if what is None else what(int(j))
            failed[int(j)] = NotApplicable(
                f"{label}: no {n_legs}-leg route of {float(leg_m):g} m legs on the "
                f"{self.scene.kind} scene's structures found in {int(tries)} tries")
        return out, failed


def route_guide(scene):
    """The scene's route guide (:class:`SceneRoutes`), or None for a scene without
    structures (``open_water``: the tasks' own sampler).

    Parameters
    ----------
    scene : Scene
        The scene.

    Returns
    -------
    SceneRoutes or None
    """
    if scene is None or scene.kind not in ("dam", "pier_harbor", "simple_underwater") \
            or not scene.structures:
        return None
    return SceneRoutes(scene)
