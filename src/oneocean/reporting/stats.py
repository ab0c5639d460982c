"""Statistics of the reporting: 95 % intervals of rates and means, and the macro aggregates.

Every table and figure takes its intervals from here, so a number is the same wherever it is
shown:

* a rate: the Wilson score interval (:func:`wilson`; :func:`rate_ci` of a success vector,
  :func:`cell_rate` of ``k`` successes in ``n`` episodes as a :class:`Rate`);
* a mean: the seeded percentile bootstrap (:func:`mean_ci`); a mean over the episodes of
  several tasks pooled, the stratified bootstrap (:func:`pooled_mean_ci`); a plain mean of the
  finite values (:func:`finite_mean`);
* a macro (the unweighted mean over tasks of their success rates): the stratified bootstrap
  that resamples episodes within each task (:func:`stratified_macro`);
* a difference of two rates: the bootstrap of the difference, both cells resampled
  independently (:func:`diff_ci`).

Every bootstrap draws :data:`N_BOOT` replicates from a seeded generator (:data:`BOOT_SEED`
unless told), so the table bytes are reproducible. Pure functions of arrays; no cell files
(:mod:`oneocean.reporting.cells` reads those).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Two-sided 95 % normal quantile.
Z95 = 1.959963984540054
#: Replicates of every bootstrap interval.
N_BOOT = 2000
#: Default seed of every bootstrap interval.
BOOT_SEED = 20250101


def wilson(k: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval of ``k`` successes in ``n`` trials.

    Parameters
    ----------
    k : int
        Successes.
    n : int
        Trials.
    z : float, default ``Z95``
        Normal quantile of the two-sided level (95 %).

    Returns
    -------
    tuple of float
        ``(lo, hi)`` as fractions in [0, 1]; NaNs for ``n <= 0``.
    """
    if n <= 0:
        return (math.nan, math.nan)
    p = k / n
    den = 1.0 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, mid - half), min(1.0, mid + half))


@dataclass(frozen=True)
class Rate:
    """A success rate in percent with its 95 % interval (NaN when not applicable).

    Attributes
    ----------
    sr : float
        Success rate, %.
    lo, hi : float
        Bounds of the 95 % interval, %.
    n : int
        Episodes.
    """

    sr: float
    lo: float
    hi: float
    n: int


def cell_rate(k: int, n: int) -> Rate:
    """A cell's success rate with its Wilson 95 % interval.

    Parameters
    ----------
    k : int
        Successes.
    n : int
        Episodes.

    Returns
    -------
    Rate
        Rate and bounds in %; the rate is NaN for ``n = 0``.
    """
    lo, hi = wilson(k, n)
    return Rate(100.0 * k / n if n else math.nan, 100.0 * lo, 100.0 * hi, n)


def rate_ci(success) -> tuple[float, float, float]:
    """Success rate of a success vector with its Wilson 95 % interval.

    Parameters
    ----------
    success : array_like
        Per-episode success (bool).

    Returns
    -------
    tuple of float
        ``(sr, lo, hi)`` in %; NaNs if empty.
    """
    s = np.asarray(success, dtype=bool)
    if s.size == 0:
        return (math.nan, math.nan, math.nan)
    lo, hi = wilson(int(s.sum()), int(s.size))
    return (100.0 * float(s.mean()), 100.0 * lo, 100.0 * hi)


def mean_ci(x, seed: int = BOOT_SEED) -> tuple[float, float, float]:
    """Mean and seeded percentile-bootstrap 95 % interval of the finite values of ``x``.

    Parameters
    ----------
    x : array_like
        Values; NaN and infinite ones are dropped.
    seed : int, default ``BOOT_SEED``
        Bootstrap seed (:data:`N_BOOT` replicates).

    Returns
    -------
    tuple of float
        ``(mean, lo, hi)``; NaNs when no finite value is left.
    """
    x = np.asarray(x, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return (math.nan, math.nan, math.nan)
    rng = np.random.default_rng(seed)
    boots = x[rng.integers(0, x.size, size=(N_BOOT, x.size))].mean(axis=1)
    lo, hi = np.quantile(boots, [0.025, 0.975])
    return (float(x.mean()), float(lo), float(hi))


def finite_mean(x) -> float:
    """Mean of the finite values of ``x`` (no interval).

    Parameters
    ----------
    x : array_like
        Values; NaN and infinite ones are dropped.

    Returns
    -------
    float
        The mean; NaN when no finite value is left.
    """
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else math.nan


def pooled_mean_ci(groups, seed: int | None = None) -> tuple[float, float, float]:
    """Mean of the finite values of several groups (tasks) pooled, with a bootstrap interval.

    The 95 % interval is a seeded stratified percentile bootstrap (values resampled within
    each group, groups in the given order).

    Parameters
    ----------
    groups : iterable of array_like
        Each group's values; non-finite ones are dropped.
    seed : int, optional
        Bootstrap seed (default :data:`BOOT_SEED`).

    Returns
    -------
    tuple of float
        ``(mean, lo, hi)``; NaNs when no finite value.
    """
    xs = [np.asarray(g, dtype=np.float64) for g in groups]
    xs = [x[np.isfinite(x)] for x in xs]
    xs = [x for x in xs if x.size]
    if not xs:
        return (math.nan, math.nan, math.nan)
    rng = np.random.default_rng(BOOT_SEED if seed is None else seed)
    total = np.zeros(N_BOOT)
    for x in xs:
        total += x[rng.integers(0, x.size, size=(N_BOOT, x.size))].sum(axis=1)
    n = sum(x.size for x in xs)
    lo, hi = np.quantile(total / n, [0.025, 0.975])
    return (float(np.concatenate(xs).mean()), float(lo), float(hi))


def stratified_macro(groups, seed: int = BOOT_SEED) -> tuple[float, float, float]:
    """Unweighted mean over groups (tasks) of their success rates, with a bootstrap interval.

    The 95 % interval comes from a seeded stratified bootstrap (:data:`N_BOOT` replicates,
    episodes resampled within each group, in the given order). Empty groups are skipped.

    Parameters
    ----------
    groups : iterable of array_like
        Each group's per-episode success (bool or 0/1).
    seed : int, default ``BOOT_SEED``
        Bootstrap seed.

    Returns
    -------
    tuple of float
        ``(mean, lo, hi)`` in %; NaNs when no group has episodes.
    """
    succ = [np.asarray(g, dtype=np.float64) for g in groups if len(g)]
    if not succ:
        return (math.nan, math.nan, math.nan)
    rng = np.random.default_rng(seed)
    boots = np.zeros(N_BOOT)
    for s in succ:
        boots += s[rng.integers(0, s.size, size=(N_BOOT, s.size))].mean(axis=1)
    boots *= 100.0 / len(succ)
    lo, hi = np.quantile(boots, [0.025, 0.975])
    return (100.0 * float(np.mean([s.mean() for s in succ])), float(lo), float(hi))


def diff_ci(pairs, seed: int | None = None) -> tuple[float, float, float]:
    """Difference of success rates in points, ``mean over pairs of (SR(a) - SR(b))``.

    One pair gives one task's drop; several a macro drop over the tasks. The 95 % interval
    is a seeded percentile bootstrap (every success vector resampled independently, pairs
    in the given order).

    Parameters
    ----------
    pairs : iterable of (array_like, array_like)
        ``(success_a, success_b)`` per task; pairs with an empty side are skipped.
    seed : int, optional
        Bootstrap seed (default :data:`BOOT_SEED`).

    Returns
    -------
    tuple of float
        ``(diff, lo, hi)`` in percentage points; NaNs when no pair is left.
    """
    pairs = [(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
             for a, b in pairs]
    pairs = [(a, b) for a, b in pairs if a.size and b.size]
    if not pairs:
        return (math.nan, math.nan, math.nan)
    rng = np.random.default_rng(BOOT_SEED if seed is None else seed)
    boots = np.zeros(N_BOOT)
    for a, b in pairs:
        boots += a[rng.integers(0, a.size, size=(N_BOOT, a.size))].mean(axis=1)
        boots -= b[rng.integers(0, b.size, size=(N_BOOT, b.size))].mean(axis=1)
    boots *= 100.0 / len(pairs)
    lo, hi = np.quantile(boots, [0.025, 0.975])
    point = 100.0 * float(np.mean([a.mean() - b.mean() for a, b in pairs]))
    return (point, float(lo), float(hi))
