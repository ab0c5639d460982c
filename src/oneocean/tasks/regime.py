"""The current regime of a tier: the band of a region's own current-speed quantiles
(tier key ``current_band``) an episode's mean current must lie in (:class:`Regime`,
:func:`current_regime`, the quantiles' :class:`RegimeSampler`), and the mean current speed a
candidate episode meets (:func:`site_speeds`, :func:`site_speed`).
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from ..engine.grid import Grid
from ..errors import ConfigError, NotApplicable


class Regime(NamedTuple):
    """A tier's current regime on one region: episodes are accepted where the mean current
    speed over the episode lies in ``[lo, hi]`` m s-1, the region's own speed quantiles
    ``band = (q_lo, q_hi)`` (tier key ``current_band``) at the reference depth ``depth_m``.

    The quantiles are taken over every water node of the grid level nearest ``depth_m`` and
    every time of the grid (the data current with its tide layers, as ``Cell.grid_reset``
    holds it: no run forcing, so forcing ablations replay the same episodes), so "Tier 3 = the
    fastest third of this region's water" means the same in a calm region and in a tidal one.
    """

    band: tuple
    lo: float
    hi: float
    depth_m: float


#: Most bytes of one grid level's currents at its nodes a :class:`RegimeSampler` keeps
#: (``REGIME_LEVELS_KEPT`` of them at most); beyond it the speeds are sampled from the grid
#: at each depth (the same numbers, slower).
REGIME_LEVEL_BYTES = 64 * 2 ** 20
REGIME_LEVELS_KEPT = 4


class RegimeSampler:
    """The speeds a grid's current regime takes its quantiles of, at any reference depth.

    The samples are every water node of the grid level nearest the depth (every
    ``jj.size // 20000``-th, at most about 40,000) at every time of the grid: the
    :func:`~oneocean.engine.grid.sample_speeds_times` of those points at that depth, the
    same bits. The nodes and each level's data current at them are kept
    (:func:`~oneocean.engine.grid.level_currents`), so the next depth between the same two
    levels costs only the blend and the ``hypot`` (a reset's candidates are drawn at their
    own median depth, a different one for every seed).

    Parameters
    ----------
    grid : Grid
        The grid export (``Cell.grid_reset``: the data current, the tier's gain).
    """

    def __init__(self, grid: Grid):
        self.grid = grid
        self._nodes = {}      # nearest level -> (x, z, cells, weights)
        self._levels = {}     # (nearest level, level) -> (T, P, 2) currents, or None

    def nodes(self, depth_m: float) -> tuple:
        """The sampled water nodes for a depth.

        Parameters
        ----------
        depth_m : float
            Reference depth, m.

        Returns
        -------
        tuple
            ``(k, x, z)``: the grid level nearest ``depth_m`` (int) and the nodes' positions
            east and north, (P,) float64 each, m.

        Raises
        ------
        NotApplicable
            No water with currents on that level.
        """
        grid = self.grid
        k = int(np.argmin(np.abs(np.asarray(grid.depth) - float(depth_m))))
        hit = self._nodes.get(k)
        if hit is None:
            water = (np.asarray(grid.valid[k]) == 1) & (np.asarray(grid.land) < 0.5)
            jj, ii = np.nonzero(water)
            if jj.size == 0:
                raise NotApplicable(f"no water with currents at {depth_m:g} m")
            stride = max(1, jj.size // 20000)
            jj, ii = jj[::stride], ii[::stride]
            x = grid.x0 + ii * grid.dx
            z = grid.z0 + jj * grid.dz
            hit = self._nodes[k] = (x, z, None, None)
        return (k,) + hit[:2]

    def _parts(self, depth_m: float):
        """The nodes at ``depth_m`` (P, 3), the kept currents of the depth's two levels and of
        the tide layers and the weight of the deeper level; the levels None when they are not
        kept (too large, or times the kept levels cannot stand for)."""
        from ..engine.grid import _point_weights, level_currents, tide_layer_currents

        grid = self.grid
        k, x, z = self.nodes(depth_m)
        xyz = np.column_stack([x, np.full(x.size, float(depth_m)), z])
        n_t, n_p = len(grid.time_s), x.size
        if n_t * n_p * 16 > REGIME_LEVEL_BYTES:
            return xyz, None, None, None, 0.0
        _, _, cells, weights = self._nodes[k]
        if cells is None:
            cells = np.empty((n_p, 4), dtype=np.int64)
            weights = np.empty((n_p, 5))
            _point_weights(grid, xyz, cells, weights)
            self._nodes[k] = (x, z, cells, weights)
        # the depth's levels and weight (the horizontal place does not depend on it)
        c1 = np.empty((1, 4), dtype=np.int64)
        w1 = np.empty((1, 5))
        _point_weights(grid, xyz[:1], c1, w1)
        parts = []
        for level in (int(c1[0, 2]), int(c1[0, 3]), -1):
            key = (k, level)
            if key in self._levels:
                self._levels[key] = self._levels.pop(key)      # most recently used last
            else:
                while len(self._levels) >= REGIME_LEVELS_KEPT:
                    self._levels.pop(next(iter(self._levels)))
                if level < 0 and grid.tide_layers != 1:
                    self._levels[key] = np.zeros((1, 1, 2))
                elif level < 0:
                    out = np.empty((n_t, n_p, 2))
                    tide_layer_currents(grid, cells, weights, out)
                    self._levels[key] = out
                else:
                    out = np.empty((n_t, n_p, 2))
                    self._levels[key] = out if level_currents(grid, cells, weights, level,
                                                              out) else None
            parts.append(self._levels[key])
        if parts[0] is None or parts[1] is None:
            return xyz, None, None, None, 0.0
        return xyz, parts[0], parts[1], parts[2], float(w1[0, 4])

    def speeds(self, depth_m: float) -> np.ndarray:
        """Current speed at the nodes at every time of the grid.

        Parameters
        ----------
        depth_m : float
            Reference depth, m.

        Returns
        -------
        (T * P,) float64
            Speeds, m s-1, time-major: ``sample_speeds_times(grid, nodes at depth_m,
            grid.time_s)``, the same bits.
        """
        from ..engine.grid import sample_speeds_times, speeds_from_levels

        xyz, c0, c1, ct, wk = self._parts(depth_m)
        if c0 is None:
            return sample_speeds_times(self.grid, xyz, np.asarray(self.grid.time_s,
                                                                  dtype=np.float64))
        return speeds_from_levels(self.grid, c0, c1, ct, wk,
                                  np.empty(c0.shape[0] * c0.shape[1]))

    def quantiles(self, depth_m: float, qs) -> tuple:
        """Quantiles of :meth:`speeds`.

        From the speeds' order statistics
        (:func:`~oneocean.engine.grid.order_stats_from_levels`) when they can be certified,
        else from the speeds themselves.

        Parameters
        ----------
        depth_m : float
            Reference depth, m.
        qs : sequence of float
            Quantiles in ``[0, 1]``.

        Returns
        -------
        tuple of float
            ``np.quantile(self.speeds(depth_m), qs)`` (linear method), the same values,
            m s-1.
        """
        from ..engine.grid import order_stats_from_levels

        qs = [float(q) for q in qs]
        xyz, c0, c1, ct, wk = self._parts(depth_m)
        if c0 is not None and _linear_quantile_matches_numpy():
            size = c0.shape[0] * c0.shape[1]
            where = [_linear_quantile_ranks(size, q) for q in qs]
            ranks = np.array(sorted({r for w in where for r in w[:2]}), dtype=np.int64)
            vals = np.empty(ranks.size)
            if order_stats_from_levels(self.grid, c0, c1, ct, wk, ranks, np.empty(size),
                                       vals):
                at = dict(zip(ranks.tolist(), vals.tolist()))
                return tuple(_linear_quantile_lerp(at[i], at[j], gamma)
                             for i, j, gamma in where)
        return tuple(float(v) for v in np.quantile(self.speeds(depth_m), qs))


def _linear_quantile_ranks(n: int, q: float) -> tuple:
    """NumPy's linear-method quantile ``q`` of ``n`` sorted values: the ranks ``(i, j)`` it
    interpolates between and the weight ``gamma`` of ``j``."""
    v = float(n - 1) * q
    i = float(math.floor(v))
    j = i + 1.0
    if v >= n - 1:
        i = j = -1.0
    if v < 0:
        i = j = 0.0
    gamma = v - i
    return int(i) % n, int(j) % n, gamma


def _linear_quantile_lerp(a: float, b: float, gamma: float) -> float:
    """NumPy's interpolation between the two order statistics of a linear-method quantile."""
    d = b - a
    return b - d * (1.0 - gamma) if gamma >= 0.5 else a + d * gamma


@functools.lru_cache(maxsize=1)
def _linear_quantile_matches_numpy() -> bool:
    """Whether :func:`_linear_quantile_ranks` and :func:`_linear_quantile_lerp` give this
    NumPy's ``np.quantile`` to the bit (checked once per process on random samples; if not,
    the regime's quantiles are taken by ``np.quantile`` itself)."""
    rng = np.random.default_rng(12345)
    for n in (1, 2, 3, 7, 100, 1001):
        x = rng.gamma(2.0, 0.3, n)
        xs = np.sort(x)
        for q in (0.0, 1e-9, 0.15, 0.25, 1.0 / 3.0, 0.5, 0.55, 0.83, 0.999, 1.0):
            i, j, gamma = _linear_quantile_ranks(n, q)
            got = _linear_quantile_lerp(float(xs[i]), float(xs[j]), gamma)
            if got != float(np.quantile(x, q)):
                return False
    return True


def current_regime(grid: Grid, tier: dict, depth_m: float,
                   sampler: RegimeSampler | None = None) -> Regime | None:
    """The :class:`Regime` of a tier's ``current_band`` on ``grid``.

    Parameters
    ----------
    grid : Grid
        The grid export.
    tier : dict
        Tier parameters; ``current_band`` ``[q_lo, q_hi]``, speed quantiles with
        ``0 <= q_lo < q_hi <= 1``.
    depth_m : float
        Reference depth, m (the quantiles are taken on the grid level nearest it).
    sampler : RegimeSampler, optional
        A sampler of ``grid`` kept between calls (its levels are reused); a new one if None.

    Returns
    -------
    Regime or None
        The regime (``hi`` is inf when ``q_hi == 1``); None when the tier has no
        ``current_band``.

    Raises
    ------
    ConfigError
        A malformed ``current_band``.
    NotApplicable
        No water with currents at ``depth_m``.
    """
    band = tier.get("current_band")
    if band is None:
        return None
    try:
        q_lo, q_hi = (float(b) for b in band)
    except (TypeError, ValueError):
        raise ConfigError(f"current_band: expected [q_lo, q_hi], got {band!r}") from None
    if not 0.0 <= q_lo < q_hi <= 1.0:
        raise ConfigError(f"current_band: need 0 <= q_lo < q_hi <= 1, got {band!r}")
    if sampler is None or sampler.grid is not grid:
        sampler = RegimeSampler(grid)
    lo, hi = sampler.quantiles(depth_m, [q_lo, q_hi])
    return Regime((q_lo, q_hi), float(lo), float(hi) if q_hi < 1.0 else math.inf,
                  float(depth_m))


def site_speeds(grid: Grid, points, t0, duration_s: float, n_times: int = 5) -> np.ndarray:
    """Mean current speed of each candidate episode, in one vectorised sample.

    The mean over the candidate's points and ``n_times`` times evenly spread over
    ``[t0[c], t0[c] + duration_s]``: the current an episode there meets.

    Parameters
    ----------
    grid : Grid
        The grid export.
    points : (C, P, 3) array_like
        Points of each candidate, world m.
    t0 : (C,) array_like
        Start times, s since the grid's ``time0``.
    duration_s : float
        Episode duration, s.
    n_times : int
        Sample times per candidate.

    Returns
    -------
    (C,) float64
        Mean current speed, m s-1.
    """
    from ..engine.grid import sample_currents

    pts = np.asarray(points, dtype=np.float64)
    t0 = np.asarray(t0, dtype=np.float64)
    n_c, n_p = pts.shape[0], pts.shape[1]
    ts = np.linspace(t0, t0 + float(duration_s), int(n_times), axis=1)        # (C, T)
    xyz = np.broadcast_to(pts[:, None], (n_c, ts.shape[1], n_p, 3)).reshape(-1, 3)
    t = np.broadcast_to(ts[:, :, None], (n_c, ts.shape[1], n_p)).reshape(-1)
    c = sample_currents(grid, xyz, t)
    return np.hypot(c[:, 0], c[:, 1]).reshape(n_c, -1).mean(axis=1)


def site_speed(grid: Grid, points, t0: float, duration_s: float, n_times: int = 5) -> float:
    """:func:`site_speeds` of one episode.

    Parameters
    ----------
    grid : Grid
        The grid export.
    points : (P, 3) array_like
        The episode's points, world m.
    t0 : float
        Start time, s since the grid's ``time0``.
    duration_s : float
        Episode duration, s.
    n_times : int
        Sample times.

    Returns
    -------
    float
        Mean current speed, m s-1.
    """
    pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
    return float(site_speeds(grid, pts[None], [float(t0)], duration_s, n_times)[0])
