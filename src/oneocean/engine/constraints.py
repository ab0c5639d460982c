"""Feasibility, spawning and near-collision accounting (paper eqs. 3 and 4).

The valid set is ``C = {(x, y, z) : m_land(x, z) < tau_land, y + clearance <= -h(x, z)}``
inside the grid's horizontal extent. A step whose end point leaves ``C`` is rejected by the
rollout: position kept, velocity zeroed, violation counted, status code set.
"""

from __future__ import annotations

from typing import Mapping

import math

import numpy as np

from ..errors import ConfigError
from . import status as st
from .grid import Grid, _bilinear2d, _hcell, current_coverage, sample_elevation_points
from ._jit import hot_kernel

DEFAULT_LAND_THRESHOLD = 0.5
DEFAULT_CLEARANCE_M = 1.0
DEFAULT_R_COLL_M = 2.0


@hot_kernel(inline="always")
def check_move(grid, x, y, z, land_threshold, clearance):
    """Status of a proposed position: OK, OUTSIDE, LAND, SEAFLOOR or NONFINITE.

    OUTSIDE means beyond the grid's horizontal extent or above the surface (``y < 0``; the
    dynamics keep vehicles at ``y >= 0``, so surfacing is never a violation in a rollout).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    x, y, z : float
        Proposed position, m (x east, y depth positive down, z north).
    land_threshold : float
        Rejection threshold on the bilinearly sampled land mask (0..1).
    clearance : float
        Required distance above the seafloor, m: rejected if ``y + clearance > -h(x, z)``.

    Returns
    -------
    int
        Status code (:mod:`oneocean.engine.status`).
    """
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        return st.NONFINITE
    if x < grid.x0 or x > grid.x_max or z < grid.z0 or z > grid.z_max or y < 0.0:
        return st.OUTSIDE
    i, j, wx, wz = _hcell(grid, x, z)
    if _bilinear2d(grid.land, i, j, wx, wz) >= land_threshold:
        return st.LAND
    if y + clearance > -_bilinear2d(grid.elevation, i, j, wx, wz):
        return st.SEAFLOOR
    return st.OK


#: Contract §5 name of :func:`check_move`.
is_feasible = check_move


@hot_kernel
def check_points(grid, xyz, land_threshold, clearance, out):
    """Vectorised :func:`check_move`.

    Parameters
    ----------
    grid : Grid
        The grid export.
    xyz : (n, 3) float64
        Proposed positions ``[x, y, z]``, m.
    land_threshold, clearance : float
        As in :func:`check_move`.
    out : (n,) int64
        Output array, written in place.

    Returns
    -------
    (n,) int64
        ``out``: the status codes.
    """
    for n in range(xyz.shape[0]):
        out[n] = check_move(grid, xyz[n, 0], xyz[n, 1], xyz[n, 2], land_threshold, clearance)
    return out


@hot_kernel(inline="always")
def min_pairwise_distance(pos):
    """Smallest distance between any two rows of ``pos``.

    O(n^2 / 2), meant for n <= ~10 agents.

    Parameters
    ----------
    pos : (n, >=3) float64
        Positions; columns 0..2 are x, y, z, m (e.g. a state array's agents).

    Returns
    -------
    float
        The smallest distance, m; ``inf`` when n < 2.
    """
    n = pos.shape[0]
    best = np.inf
    for i in range(n - 1):
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2]
        for j in range(i + 1, n):
            dx = pos[j, 0] - xi
            dy = pos[j, 1] - yi
            dz = pos[j, 2] - zi
            d2 = dx * dx + dy * dy + dz * dz
            if d2 < best:
                best = d2
    return math.sqrt(best) if best < np.inf else np.inf


def feasibility(grid: Grid, xyz, land_threshold: float = DEFAULT_LAND_THRESHOLD,
                clearance: float = DEFAULT_CLEARANCE_M) -> np.ndarray:
    """Status codes of points (:func:`check_move` at each).

    Parameters
    ----------
    grid : Grid
        The grid export.
    xyz : array_like
        (n, 3) points ``[x, y, z]``, m.
    land_threshold : float, default 0.5
        Rejection threshold on the sampled land mask (0..1).
    clearance : float, default 1.0
        Required distance above the seafloor, m.

    Returns
    -------
    (n,) int64
        Status codes (:mod:`oneocean.engine.status`).
    """
    xyz = np.ascontiguousarray(np.atleast_2d(xyz), dtype=np.float64)
    return check_points(grid, xyz, float(land_threshold), float(clearance),
                        np.empty(xyz.shape[0], dtype=np.int64))


def _region_box(grid: Grid, region) -> tuple:
    """(x_lo, x_hi, y_lo, y_hi, z_lo, z_hi, altitude) from a region spec."""
    if region is None:
        region = {}
    if isinstance(region, Mapping):
        unknown = set(region) - {"x", "y", "z", "altitude"}
        if unknown:
            raise ConfigError(f"spawn region: unknown keys {sorted(unknown)}; expected x, y, z "
                              "(each (lo, hi) m) and optionally altitude (lo, hi) m")
        if "y" in region and "altitude" in region:
            raise ConfigError("spawn region: give either 'y' (depth range) or 'altitude', not both")

        def rng(key, default):
            v = region.get(key, default)
            try:
                lo, hi = (float(a) for a in v)
            except (TypeError, ValueError) as exc:
                raise ConfigError(f"spawn region.{key}: expected (lo, hi), got {v!r}") from exc
            if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
                raise ConfigError(f"spawn region.{key}: need finite lo <= hi, got {v!r}")
            return lo, hi

        xl, xh = rng("x", (grid.x0, grid.x_max))
        zl, zh = rng("z", (grid.z0, grid.z_max))
        yl, yh = rng("y", (0.0, 0.0))
        alt = rng("altitude", None) if "altitude" in region else None
        return xl, xh, yl, yh, zl, zh, alt
    try:
        xl, xh, yl, yh, zl, zh = (float(a) for a in region)
    except (TypeError, ValueError) as exc:
        raise ConfigError("spawn region: expected a mapping {x, y|altitude, z} or "
                          f"(x_lo, x_hi, y_lo, y_hi, z_lo, z_hi), got {region!r}") from exc
    if not (xl <= xh and yl <= yh and zl <= zh):
        raise ConfigError(f"spawn region: need lo <= hi on every axis, got {region!r}")
    return xl, xh, yl, yh, zl, zh, None


def spawn_positions(grid: Grid, rng, n: int, region=None, *,
                    land_threshold: float = DEFAULT_LAND_THRESHOLD,
                    clearance: float = DEFAULT_CLEARANCE_M, min_separation: float = 0.0,
                    max_candidates: int = 200_000, min_current_defined: float = 0.0
                    ) -> np.ndarray:
    """Draw ``n`` feasible positions by vectorised rejection sampling, or fail loudly.

    Parameters
    ----------
    grid : Grid
        The grid export.
    rng : int, numpy.random.SeedSequence or numpy.random.Generator
        Randomness; use :func:`oneocean.engine.rng.episode_rng` for per-episode streams.
    n : int
        Number of positions.
    region : mapping or 6-tuple, optional
        ``{"x": (lo, hi), "z": (lo, hi), "y": (lo, hi)}`` in world m (defaults: the grid
        extent and the surface ``y = 0``), or ``"altitude": (lo, hi)`` m above the seafloor
        instead of ``y``; or ``(x_lo, x_hi, y_lo, y_hi, z_lo, z_hi)``.
    land_threshold, clearance : float
        As in :func:`check_move` (defaults 0.5 and 1.0 m).
    min_separation : float, default 0.0
        Minimum distance between the returned positions, m (accepted greedily).
    max_candidates : int, default 200000
        Give up after this many candidates.
    min_current_defined : float, default 0.0
        Also reject candidates where less than this share of the bilinear weight lies on nodes
        with currents (:func:`oneocean.engine.grid.current_defined`; 1.0 = fully inside the
        currents' coverage, away from water without currents). 0 = no check.

    Returns
    -------
    (n, 3) float64
        Positions ``[x, y, z]``, m.

    Raises
    ------
    ConfigError
        If ``n < 0``, ``region`` is malformed, or fewer than ``n`` valid positions were found
        (with the rejection reasons counted).
    """
    n = int(n)
    if n < 0:
        raise ConfigError(f"spawn n: must be >= 0, got {n}")
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    xl, xh, yl, yh, zl, zh, alt = _region_box(grid, region)
    out = np.empty((n, 3))
    got = 0
    tried = 0
    reasons = {st.OUTSIDE: 0, st.LAND: 0, st.SEAFLOOR: 0, "no current": 0, "separation": 0}
    min_cur = float(min_current_defined)
    sep2 = float(min_separation) ** 2
    while got < n and tried < max_candidates:
        m = int(min(max(64, 4 * (n - got)), max_candidates - tried))
        cand = np.empty((m, 3))
        cand[:, 0] = gen.uniform(xl, xh, m)
        cand[:, 2] = gen.uniform(zl, zh, m)
        if alt is not None:
            floor = -sample_elevation_points(grid, np.ascontiguousarray(cand[:, [0, 2]]),
                                             np.empty(m))
            cand[:, 1] = floor - gen.uniform(alt[0], alt[1], m)
        else:
            cand[:, 1] = gen.uniform(yl, yh, m)
        tried += m
        codes = feasibility(grid, cand, land_threshold, clearance)
        for code in (st.OUTSIDE, st.LAND, st.SEAFLOOR, st.NONFINITE):
            if code in reasons:
                reasons[code] += int(np.sum(codes == code))
        if min_cur > 0.0:
            ok = codes == st.OK
            short = ok & (current_coverage(grid, cand[:, [0, 2]]) < min_cur - 1e-12)
            reasons["no current"] += int(short.sum())
            codes = np.where(short, -1, codes)
        for c in cand[codes == st.OK]:
            if sep2 > 0 and got and np.min(np.sum((out[:got] - c) ** 2, axis=1)) < sep2:
                reasons["separation"] += 1
                continue
            out[got] = c
            got += 1
            if got == n:
                break
    if got < n:
        why = ", ".join(f"{st.NAMES.get(k, k)}: {v}" for k, v in reasons.items() if v)
        raise ConfigError(
            f"spawn: found only {got} of {n} valid positions in region x=[{xl:g}, {xh:g}] "
            f"z=[{zl:g}, {zh:g}] " + (f"altitude=[{alt[0]:g}, {alt[1]:g}]" if alt is not None
                                       else f"y=[{yl:g}, {yh:g}]")
            + f" m after {tried} candidates (rejected: {why or 'none'}); widen the region, "
            "reduce clearance or min_separation")
    return out

