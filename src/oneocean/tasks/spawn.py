"""What an episode reset draws, and the checks it draws with: a reset dict's episode rows,
each episode's seed and random generators, start times, clear straight paths
(:func:`path_clear`, :func:`paths_clear`), feasible points (:func:`feasible_codes`), start
points and random routes (:func:`sample_route`, and compiled over many streams
:func:`sample_routes`), and the compiled samplers the tasks' reset kernels inline
(``_spawn_one_c``, ``_route_row``, ``_spawn_altitude``, ``_segment_clear``).
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..engine import status as st
from ..engine import streams
from ..engine.constraints import check_move
from ..engine._jit import hot_kernel
from ..engine.grid import Grid, sample_elevation
from ..engine.rng import episode_rng
from ..errors import ConfigError, NotApplicable
from .common import OK, PURPOSE_RESET


def episode_rows(init: dict, index, n_all: int) -> dict:
    """A reset dict's episodes ``index``: every array whose leading axis has the ``n_all``
    episodes is indexed along it; other entries (scalars, shared arrays) are kept as they are.

    Parameters
    ----------
    init : dict
        A reset dict (the tasks' ``reset``, :meth:`oneocean.tasks.Cell.reset`).
    index : slice or numpy.ndarray
        Which episodes (a slice, or integer indices).
    n_all : int
        The number of episodes ``init`` holds.

    Returns
    -------
    dict
        The same keys; a slice gives views, integer indices copies.
    """
    return {k: (v[index] if isinstance(v, np.ndarray) and v.ndim and v.shape[0] == n_all
                else v) for k, v in init.items()}


def episode_generators(seed: int, n_episodes: int, purpose: int = PURPOSE_RESET):
    """One independent random generator per episode.

    Parameters
    ----------
    seed : int
        Run seed.
    n_episodes : int
        Number of episodes.
    purpose : int
        Stream purpose, default ``PURPOSE_RESET``.

    Returns
    -------
    list of numpy.random.Generator
        Generator ``e``: :func:`oneocean.engine.rng.episode_rng` ``(seed, e, purpose)``.
    """
    return [episode_rng(seed, e, purpose) for e in range(n_episodes)]


def start_times(grid: Grid, rngs, duration_s: float) -> np.ndarray:
    """Episode start times, uniform over the part of the grid's time span that leaves
    ``duration_s`` of data.

    Parameters
    ----------
    grid : Grid
        The grid export.
    rngs : sequence of numpy.random.Generator, or (n, 4) uint64
        One generator per episode, or one stream per episode
        (:func:`oneocean.engine.streams.episode_states`, advanced in place); each gives one
        uniform draw.
    duration_s : float
        Episode duration, s.

    Returns
    -------
    (len(rngs),) float64
        Start times, s since the grid's ``time0``; all the grid's first time (no draw) where
        the span is shorter than ``duration_s`` (e.g. a single-time grid).
    """
    t_lo = float(grid.time_s[0])
    t_hi = float(grid.time_s[-1]) - float(duration_s)
    if t_hi <= t_lo:
        return np.full(len(rngs), t_lo)
    if isinstance(rngs, np.ndarray):
        return streams.uniform_rows(rngs, t_lo, t_hi)[:, 0]
    return np.array([r.uniform(t_lo, t_hi) for r in rngs])


def path_clear(grid: Grid, p0, p1, clearance: float, land_threshold: float = 0.5,
               spacing_m: float | None = None) -> bool:
    """Whether the straight segment ``p0 -> p1`` is feasible.

    Checked every ``spacing_m`` metres (:func:`oneocean.engine.constraints.feasibility`:
    land, grid extent and ``clearance`` above the seafloor).

    Parameters
    ----------
    grid : Grid
        The grid export.
    p0, p1 : (3,) array_like
        Segment ends, world m.
    clearance : float
        Seafloor clearance, m.
    land_threshold : float
        Land-mask threshold.
    spacing_m : float, optional
        Check spacing, m; default 20 m, or half the grid's node spacing where that is finer
        (a scene's local grid, whose thin structures a 20 m check would step over).

    Returns
    -------
    bool
        True if every check point is feasible.
    """
    from ..engine.constraints import feasibility

    if spacing_m is None:
        spacing_m = min(20.0, 0.5 * min(float(grid.dx), float(grid.dz)))
    p0 = np.asarray(p0, dtype=np.float64)
    p1 = np.asarray(p1, dtype=np.float64)
    d = p1 - p0                      # not np.linalg.norm: a 1-D norm is BLAS's dot, CPU-dependent
    n = max(2, int(math.ceil(math.sqrt(float(np.sum(d * d))) / spacing_m)) + 1)
    if p0.shape != (3,) or p1.shape != (3,):
        w = np.linspace(0.0, 1.0, n)[:, None]
        return bool(np.all(feasibility(grid, p0 + w * (p1 - p0), land_threshold, clearance)
                           == st.OK))
    return bool(_call(_segment_clear, grid, float(p0[0]), float(p0[1]), float(p0[2]),
                      float(p1[0]), float(p1[1]), float(p1[2]), int(n),
                      float(land_threshold), float(clearance)))


def paths_clear(grid: Grid, p0, p1, clearance: float, land_threshold: float = 0.5) -> np.ndarray:
    """:func:`path_clear` of many segments in one compiled call (the same checks, at its
    default spacing).

    Parameters
    ----------
    grid : Grid
        The grid export.
    p0, p1 : (m, 3) array_like
        Segment ends, world m.
    clearance : float
        Seafloor clearance, m.
    land_threshold : float
        Land-mask threshold.

    Returns
    -------
    (m,) bool
        Whether each segment is feasible.
    """
    p0 = np.ascontiguousarray(p0, dtype=np.float64).reshape(-1, 3)
    p1 = np.ascontiguousarray(p1, dtype=np.float64).reshape(-1, 3)
    spacing = min(20.0, 0.5 * min(float(grid.dx), float(grid.dz)))
    out = np.empty(p0.shape[0], dtype=np.bool_)
    return _call(_paths_kernel, grid, p0, p1, float(spacing), float(land_threshold),
                 float(clearance), out)


@hot_kernel
def _paths_kernel(grid, p0, p1, spacing, land_threshold, clearance, out):
    for j in range(p0.shape[0]):
        dx = p1[j, 0] - p0[j, 0]
        dy = p1[j, 1] - p0[j, 1]
        dz = p1[j, 2] - p0[j, 2]
        n = max(2, int(math.ceil(math.sqrt(dx * dx + dy * dy + dz * dz) / spacing)) + 1)
        out[j] = _segment_clear(grid, p0[j, 0], p0[j, 1], p0[j, 2], p1[j, 0], p1[j, 1],
                                p1[j, 2], n, land_threshold, clearance)
    return out


@hot_kernel
def _segment_clear(grid, ax, ay, az, bx, by, bz, n, land_threshold, clearance):
    """:func:`path_clear`'s test, compiled: the points ``p0 + w (p1 - p0)`` at ``w =
    np.linspace(0, 1, n)`` (the same values) all pass :func:`~oneocean.engine.constraints.
    check_move`; stops at the first that fails."""
    dx = bx - ax
    dy = by - ay
    dz = bz - az
    step = 1.0 / (n - 1)
    for i in range(n):
        w = 1.0 if i == n - 1 else i * step + 0.0
        if check_move(grid, ax + w * dx, ay + w * dy, az + w * dz, land_threshold,
                      clearance) != OK:
            return False
    return True


_ENTRIES: dict = {}
_MAX_ENTRIES = 16


def _call(kernel, grid, *args):
    """``kernel(grid, *args)`` through its compiled entry point for these argument types
    (:func:`oneocean.engine.dispatch.fast_entry`: no numba dispatch, which costs several us
    with the Grid's many arrays); the entry is kept per kernel and grid (the Grid itself
    is kept with it, so its id is not reused; at most ``_MAX_ENTRIES``, then the cache
    starts over, so few grids are held)."""
    key = (id(kernel), id(grid))
    hit = _ENTRIES.get(key)
    if hit is not None and hit[0] is grid:
        return hit[1](grid, *args)
    from ..engine.dispatch import fast_entry

    out = kernel(grid, *args)          # compiles (or loads) the version for these types
    if len(_ENTRIES) >= _MAX_ENTRIES:
        _ENTRIES.clear()
    _ENTRIES[key] = (grid, fast_entry(kernel, (grid,) + args))
    return out


def feasible_codes(grid: Grid, xyz, land_threshold: float, clearance: float) -> np.ndarray:
    """:func:`oneocean.engine.constraints.feasibility` through the compiled entry point.

    The same codes, without numba's dispatch: for the resets' many small checks.

    Parameters
    ----------
    grid : Grid
        The grid export.
    xyz : (n, 3) or (3,) array_like
        Points, world m.
    land_threshold : float
        Land-mask threshold.
    clearance : float
        Seafloor clearance, m.

    Returns
    -------
    (n,) int64
        Status of each point (:mod:`oneocean.engine.status`; ``OK`` = feasible).
    """
    from ..engine.constraints import check_points

    xyz = np.ascontiguousarray(np.atleast_2d(xyz), dtype=np.float64)
    return _call(check_points, grid, xyz, float(land_threshold), float(clearance),
                 np.empty(xyz.shape[0], dtype=np.int64))


#: Candidates of one start point (:func:`sample_route`), drawn ``_SPAWN_BATCH`` at a time.
_SPAWN_MAX = 4096
_SPAWN_BATCH = 64


def _spawn_one(grid: Grid, rng: np.random.Generator, y: float, land_threshold: float,
               clearance: float) -> np.ndarray:
    """``spawn_positions(grid, rng, 1, {"y": (y, y)}, land_threshold=..., clearance=...,
    max_candidates=4096)[0]`` (:func:`oneocean.engine.constraints.spawn_positions`): the same
    draws from ``rng`` and the same point, without its per-call overhead. Where no candidate
    is valid the generator is rewound and ``spawn_positions`` itself raises its ConfigError."""
    from ..engine.constraints import check_points, spawn_positions

    state = rng.bit_generator.state
    xl, xh = float(grid.x0), float(grid.x_max)
    zl, zh = float(grid.z0), float(grid.z_max)
    y = float(y)
    lt, cl = float(land_threshold), float(clearance)
    m = _SPAWN_BATCH
    codes = np.empty(m, dtype=np.int64)
    cand = np.empty((m, 3))
    for _ in range(_SPAWN_MAX // m):          # 4096 is a multiple of 64
        cand[:, 0] = rng.uniform(xl, xh, m)
        cand[:, 2] = rng.uniform(zl, zh, m)
        cand[:, 1] = rng.uniform(y, y, m)
        _call(check_points, grid, cand, lt, cl, codes)
        ok = np.flatnonzero(codes == st.OK)
        if ok.size:
            return cand[ok[0]].copy()
    rng.bit_generator.state = state
    return spawn_positions(grid, rng, 1, {"y": (y, y)}, land_threshold=land_threshold,
                           clearance=clearance, max_candidates=_SPAWN_MAX)[0]


def sample_route(grid: Grid, rng: np.random.Generator, n_legs: int, leg_m: float,
                 depth_m: tuple[float, float], clearance: float, *,
                 max_turn_rad: float = math.pi, land_threshold: float = 0.5,
                 vary_depth: bool = False, tries: int = 2000,
                 what: str = "route") -> np.ndarray:
    """A random polyline of ``n_legs`` straight legs, clear of land and the seafloor.

    Every leg is ``leg_m`` metres long at one depth (or between per-vertex depths with
    ``vary_depth``), clear of land and ``clearance`` m above the seafloor (:func:`path_clear`).
    ``n_legs = 0`` samples one valid point (a station).

    Parameters
    ----------
    grid : Grid
        The grid export.
    rng : numpy.random.Generator
        The episode's reset stream.
    n_legs : int
        Number of legs (0: one point).
    leg_m : float
        Leg length, m.
    depth_m : (lo, hi)
        Range of the (constant) route depth, m, positive down; drawn uniformly per try.
    clearance : float
        Seafloor clearance of the start point and of every leg, m.
    max_turn_rad : float
        Largest heading change between consecutive legs, rad (pi = any direction).
    land_threshold : float
        Land-mask threshold.
    vary_depth : bool
        Draw every vertex's depth independently in ``depth_m`` (a piecewise-linear depth
        profile whose straight 3-D legs all keep ``clearance``) instead of one depth.
    tries : int
        Attempts before giving up.
    what : str
        What is being drawn, for the error message.

    Returns
    -------
    (n_legs + 1, 3) float64
        Vertices (x, y, z) in world metres; vertex 0 is the start.

    Raises
    ------
    NotApplicable
        If no valid route was found in ``tries`` attempts, or no start point at the drawn
        depths five times (never a silent fallback): the region cannot host this cell.
    """
    n_legs = int(n_legs)
    lo, hi = float(depth_m[0]), float(depth_m[1])
    out = np.empty((n_legs + 1, 3))
    spawn_fails = 0
    for _ in range(int(tries)):
        y = rng.uniform(lo, hi)
        try:
            out[0] = _spawn_one(grid, rng, y, land_threshold, clearance)
        except ConfigError as exc:
            spawn_fails += 1
            if spawn_fails >= 5:   # no valid water at these depths: fail now, loudly
                raise NotApplicable(f"{what}: {exc}") from None
            continue
        heading = rng.uniform(-math.pi, math.pi)
        ok = True
        for leg in range(n_legs):
            if leg > 0:
                heading += rng.uniform(-max_turn_rad, max_turn_rad)
            p = out[leg] + leg_m * np.array([math.sin(heading), 0.0, math.cos(heading)])
            if vary_depth:
                p[1] = rng.uniform(lo, hi)
            if not path_clear(grid, out[leg], p, clearance, land_threshold):
                ok = False
                break
            out[leg + 1] = p
        if ok:
            return out
    raise _no_route(what, n_legs, leg_m, lo, hi, clearance, tries)


def _no_route(what, n_legs, leg_m, lo, hi, clearance, tries) -> NotApplicable:
    return NotApplicable(f"{what}: no {n_legs}-leg route of {leg_m:g} m legs at depths "
                         f"[{lo:g}, {hi:g}] m with {clearance:g} m clearance found in {tries} "
                         "tries; the region cannot host this tier")


@hot_kernel(inline="always")
def _spawn_one_c(grid, stv, r, cand, y, land_threshold, clearance):
    """:func:`_spawn_one` from stream ``r`` of ``stv``, compiled: batches of ``cand.shape[0]``
    x, then z, then y draws over the grid at depth ``y``, up to ``_SPAWN_MAX`` candidates.
    Returns the row of ``cand`` that holds the first valid point, or -1 (none: the draws of
    all ``_SPAWN_MAX`` spent, as ``spawn_positions`` spends them)."""
    xl, xh = grid.x0, grid.x_max
    zl, zh = grid.z0, grid.z_max
    m = cand.shape[0]
    for _b in range(_SPAWN_MAX // m):
        for c in range(m):
            cand[c, 0] = streams.uniform(stv, r, xl, xh)
        for c in range(m):
            cand[c, 2] = streams.uniform(stv, r, zl, zh)
        for c in range(m):
            cand[c, 1] = streams.uniform(stv, r, y, y)
        for c in range(m):
            if check_move(grid, cand[c, 0], cand[c, 1], cand[c, 2], land_threshold,
                          clearance) == OK:
                return c
    return -1


@hot_kernel(inline="always")
def _route_row(grid, stv, r, n_legs, leg_m, lo, hi, clearance, max_turn, land_threshold,
               vary_depth, tries, spacing, cand, out, j):
    """:func:`sample_route` from stream ``r`` of ``stv``, compiled: the same draws in the
    same order (``_spawn_one``'s batches of ``_SPAWN_BATCH`` x, then z, then y; a failed
    start point spends its ``_SPAWN_MAX`` candidates, as ``spawn_positions`` does) and the
    same checks; the vertices in ``out[j]``. Returns 0 (a route), 1 (five failed start
    points) or 2 (none in ``tries``)."""
    spawn_fails = 0
    for _ in range(tries):
        y = streams.uniform(stv, r, lo, hi)
        q = _spawn_one_c(grid, stv, r, cand, y, land_threshold, clearance)
        if q < 0:
            spawn_fails += 1
            if spawn_fails >= 5:
                return 1
            continue
        out[j, 0, 0] = cand[q, 0]
        out[j, 0, 1] = cand[q, 1]
        out[j, 0, 2] = cand[q, 2]
        heading = streams.uniform(stv, r, -math.pi, math.pi)
        ok = True
        for leg in range(n_legs):
            if leg > 0:
                heading += streams.uniform(stv, r, -max_turn, max_turn)
            ax, ay, az = out[j, leg, 0], out[j, leg, 1], out[j, leg, 2]
            px = ax + leg_m * math.sin(heading)
            py = ay + leg_m * 0.0
            pz = az + leg_m * math.cos(heading)
            if vary_depth:
                py = streams.uniform(stv, r, lo, hi)
            dx, dy, dz = px - ax, py - ay, pz - az
            n = max(2, int(math.ceil(math.sqrt(dx * dx + dy * dy + dz * dz) / spacing)) + 1)
            if not _segment_clear(grid, ax, ay, az, px, py, pz, n, land_threshold,
                                  clearance):
                ok = False
                break
            out[j, leg + 1, 0] = px
            out[j, leg + 1, 1] = py
            out[j, leg + 1, 2] = pz
        if ok:
            return 0
    return 2


@hot_kernel(inline="always")
def _spawn_altitude(grid, stv, r, cand, n, xl, xh, zl, zh, alt_lo, alt_hi, land_threshold,
                    clearance, sep2, max_candidates, out):
    """:func:`~oneocean.engine.constraints.spawn_positions` of ``n`` points with an
    ``altitude`` range from stream ``r`` of ``stv``, compiled: batches of ``cand.shape[0]``
    (``max(64, 4 (n - got))`` for ``n <= 16``) x, then z, then altitudes in NumPy's order,
    the candidates accepted greedily at squared separation ``sep2`` into ``out[:n]``.
    Returns how many were found (``n`` unless ``max_candidates`` ran out)."""
    m = cand.shape[0]
    got = 0
    tried = 0
    while got < n and tried < max_candidates:
        mb = min(m, max_candidates - tried)
        for c in range(mb):
            cand[c, 0] = streams.uniform(stv, r, xl, xh)
        for c in range(mb):
            cand[c, 2] = streams.uniform(stv, r, zl, zh)
        for c in range(mb):
            floor = -sample_elevation(grid, cand[c, 0], cand[c, 2])
            cand[c, 1] = floor - streams.uniform(stv, r, alt_lo, alt_hi)
        tried += mb
        for c in range(mb):
            if check_move(grid, cand[c, 0], cand[c, 1], cand[c, 2], land_threshold,
                          clearance) != OK:
                continue
            near = False
            for q in range(got):
                d0 = out[q, 0] - cand[c, 0]
                d1 = out[q, 1] - cand[c, 1]
                d2 = out[q, 2] - cand[c, 2]
                if d0 * d0 + d1 * d1 + d2 * d2 < sep2:
                    near = True
                    break
            if near:
                continue
            out[got, 0] = cand[c, 0]
            out[got, 1] = cand[c, 1]
            out[got, 2] = cand[c, 2]
            got += 1
            if got == n:
                break
    return got


@hot_kernel
def _routes_kernel(grid, stv, rows, n_legs, leg_m, lo, hi, clearance, max_turn, land_threshold,
                   vary_depth, tries, spacing, cand, out, status):
    """:func:`_route_row` of every stream ``rows[j]`` of ``stv`` into ``out[j]``;
    ``status[j]`` its result."""
    for j in range(rows.shape[0]):
        status[j] = _route_row(grid, stv, rows[j], n_legs, leg_m, lo, hi, clearance,
                               max_turn, land_threshold, vary_depth, tries, spacing, cand,
                               out, j)
    return status


#: The route guide in force (:func:`route_guide`); None: the tasks' own sampler.
_GUIDE = [None]


@contextmanager
def route_guide(guide):
    """Draw :func:`sample_routes` from ``guide`` inside the block (None: the usual sampler).

    A scene with structures supplies one (:func:`oneocean.backends.mujoco.scenes.route_guide`):
    the scene-specific part of a scene cell's scenario, so every task that draws its routes,
    stations or start points here draws them on the scene's structures, from the same streams.

    Parameters
    ----------
    guide : callable or None
        ``guide(grid, stv, rows, n_legs, leg_m, depth_m, clearance, max_turn_rad,
        land_threshold, tries, what) -> (routes, failed)``, :func:`sample_routes`' contract.

    Yields
    ------
    None
        Inside the block, :func:`sample_routes` draws from ``guide``.
    """
    prev = _GUIDE[0]
    _GUIDE[0] = guide
    try:
        yield
    finally:
        _GUIDE[0] = prev


def sample_routes(grid: Grid, stv: np.ndarray, n_legs: int, leg_m: float,
                  depth_m: tuple[float, float], clearance: float, *, rows=None,
                  max_turn_rad: float = math.pi, land_threshold: float = 0.5,
                  vary_depth: bool = False, tries: int = 2000, what=None):
    """:func:`sample_route` from each of several streams (:mod:`oneocean.engine.streams`) in
    one compiled call: the routes ``sample_route`` draws from the same streams' generators,
    bit for bit, and the streams advanced as far.

    Parameters
    ----------
    grid : Grid
        The grid export.
    stv : (n, 4) uint64
        Stream states (:func:`oneocean.engine.streams.episode_states`), advanced in place.
    n_legs, leg_m, depth_m, clearance, max_turn_rad, land_threshold, vary_depth, tries
        As :func:`sample_route`.
    rows : array_like of int, optional
        Which streams (default all).
    what : callable, optional
        ``what(j)``: what row ``j`` draws, for its error message (default ``"route"``).

    Returns
    -------
    routes : (len(rows), n_legs + 1, 3) float64
        Vertices, world m (undefined in a failed row).
    failed : dict
        ``{j: NotApplicable}`` for every row with no route: the error ``sample_route``
        raises there.
    """
    rows = (np.arange(stv.shape[0]) if rows is None
            else np.asarray(rows, dtype=np.int64).reshape(-1))
    n_legs = int(n_legs)
    if _GUIDE[0] is not None:      # a scene's structures (route_guide)
        return _GUIDE[0](grid, stv, rows, n_legs, float(leg_m), depth_m, float(clearance),
                         float(max_turn_rad), float(land_threshold), int(tries), what)
    lo, hi = float(depth_m[0]), float(depth_m[1])
    spacing = min(20.0, 0.5 * min(float(grid.dx), float(grid.dz)))    # path_clear's
    start = stv[rows].copy()
    out = np.zeros((rows.size, n_legs + 1, 3))
    status = _call(_routes_kernel, grid, stv, rows.astype(np.int64), n_legs, float(leg_m), lo,
                   hi, float(clearance), float(max_turn_rad), float(land_threshold),
                   bool(vary_depth), int(tries), float(spacing),
                   np.empty((_SPAWN_BATCH, 3)), out, np.empty(rows.size, dtype=np.int64))
    failed = {}
    for j in np.flatnonzero(status):
        label = "route" if what is None else what(int(j))
        if status[j] == 2:
            failed[int(j)] = _no_route(label, n_legs, leg_m, lo, hi, clearance, int(tries))
            continue
        try:         # the generator's own path raises its error (a start point's reasons)
            sample_route(grid, streams.generator(start[j]), n_legs, leg_m, depth_m,
                         clearance, max_turn_rad=max_turn_rad, land_threshold=land_threshold,
                         vary_depth=vary_depth, tries=tries, what=label)
        except NotApplicable as exc:
            failed[int(j)] = exc
        else:       # pragma: no cover - the two paths are tested to agree
            raise AssertionError(f"{label}: the compiled route sampler found no route where "
                                 "sample_route finds one")
    return out, failed


# this module's own kernels (the resets' samplers) inline the engine's (check_move, the
# streams): drop their cache entries when the engine or this file changes
def _fresh_own_cache() -> None:
    from ..engine._jit import ensure_fresh_cache

    ensure_fresh_cache(_routes_kernel, ("spawn.",), Path(__file__).resolve())


_fresh_own_cache()
