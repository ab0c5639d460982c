"""Speed of the engine's current sampling, ns per sample (printed figures, not a timed test).

Times, in one run and on the same points, the engine's kernels and a frozen copy of the
pre-issue-#9 kernel (plain bilinear over zero-filled nodes, no renormalisation, gain on the
tide layers too), so the cost of the NaN-aware rule (contracts §5, "Water without currents")
is measured against its predecessor on the same machine load:

* ``at``: many agents at one time, :func:`~oneocean.engine.grid.locate_time` once, then
  :func:`~oneocean.engine.grid.sample_current_at` per agent (the episode loops' pattern);
* ``full``: :func:`~oneocean.engine.grid.sample_current` with a time per point.

Grid: the analytic grid of the ``public`` variant's size (49 x 7 x 150 x 200, tide layers,
coast along the west edge, gain 1.3). Two point sets: ``walk`` (1000 random walks of 1-m steps,
one after the other: cache-friendly, like agents in an episode, so the arithmetic shows) and
``random`` (uniform over the extent, 0..60 m depth and the time axis: memory-bound).

Usage::

    python benchmarks/sampling.py                # 2e5 points per set, best of 60
    python benchmarks/sampling.py --quick        # 1e5 points, best of 10

Many short repeats, the four kernels taking turns within each, and the best of each: on a
shared machine that is the figure least disturbed by the other jobs.
    python benchmarks/sampling.py --json out.json
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from oneocean.engine._jit import hot_kernel
from oneocean.engine.grid import (_hcell, _locate, _slab, _slab2, load_grid, locate_time,
                                  sample_current, sample_current_at)
from oneocean.testing import make_test_grid

GRID_KW = dict(nt=49, nz=7, ny=150, nx=200, dx_m=143.0, dz_m=222.0, max_depth_m=120.0)


@hot_kernel(inline="always", cache=False)
def _baseline_at(grid, x, y, z, t0, t1, wt):
    """The sampling kernel before issue #9 (frozen copy, for the comparison only)."""
    i, j, wx, wz = _hcell(grid, x, z)
    k0, k1, wk = _locate(grid.depth, grid.depth_inv, grid.depth_lut, grid.depth_lut_inv_h, y)
    a00 = (1.0 - wx) * (1.0 - wz)
    a10 = wx * (1.0 - wz)
    a01 = (1.0 - wx) * wz
    a11 = wx * wz
    uv = grid.uv
    u00, v00 = _slab(uv, t0, k0, j, i, a00, a10, a01, a11)
    u01, v01 = _slab(uv, t0, k1, j, i, a00, a10, a01, a11)
    u10, v10 = _slab(uv, t1, k0, j, i, a00, a10, a01, a11)
    u11, v11 = _slab(uv, t1, k1, j, i, a00, a10, a01, a11)
    wt0 = 1.0 - wt
    wk0 = 1.0 - wk
    ue = wt0 * (wk0 * u00 + wk * u01) + wt * (wk0 * u10 + wk * u11)
    vn = wt0 * (wk0 * v00 + wk * v01) + wt * (wk0 * v10 + wk * v11)
    if grid.tide_layers == 1:
        tt = grid.uv_tide
        ut0, vt0 = _slab2(tt, t0, j, i, a00, a10, a01, a11)
        ut1, vt1 = _slab2(tt, t1, j, i, a00, a10, a01, a11)
        ue += wt0 * ut0 + wt * ut1
        vn += wt0 * vt0 + wt * vt1
    return grid.gain * ue, grid.gain * vn


@hot_kernel(cache=False)
def _loop_at_new(grid, xyz, t, out):
    t0, t1, wt = locate_time(grid, t)
    for n in range(xyz.shape[0]):
        ce, cn = sample_current_at(grid, xyz[n, 0], xyz[n, 1], xyz[n, 2], t0, t1, wt)
        out[n, 0] = ce
        out[n, 1] = cn


@hot_kernel(cache=False)
def _loop_at_old(grid, xyz, t, out):
    t0, t1, wt = locate_time(grid, t)
    for n in range(xyz.shape[0]):
        ce, cn = _baseline_at(grid, xyz[n, 0], xyz[n, 1], xyz[n, 2], t0, t1, wt)
        out[n, 0] = ce
        out[n, 1] = cn


@hot_kernel(cache=False)
def _loop_full_new(grid, xyz, ts, out):
    for n in range(xyz.shape[0]):
        ce, cn = sample_current(grid, xyz[n, 0], xyz[n, 1], xyz[n, 2], ts[n])
        out[n, 0] = ce
        out[n, 1] = cn


@hot_kernel(cache=False)
def _loop_full_old(grid, xyz, ts, out):
    for n in range(xyz.shape[0]):
        t0, t1, wt = locate_time(grid, ts[n])
        ce, cn = _baseline_at(grid, xyz[n, 0], xyz[n, 1], xyz[n, 2], t0, t1, wt)
        out[n, 0] = ce
        out[n, 1] = cn


def _best_interleaved(cases: dict, repeats: int) -> dict:
    """Best-of-``repeats`` seconds per case, the cases run in turn within every repeat (a change
    in machine load hits them alike)."""
    for fn, a in cases.values():
        fn(*a)  # compile
    best = {k: np.inf for k in cases}
    for _ in range(repeats):
        for k, (fn, a) in cases.items():
            t = time.perf_counter()
            fn(*a)
            best[k] = min(best[k], time.perf_counter() - t)
    return best


def _points(grid, rng, n: int, walk: bool):
    """``n`` points (x, y, z) m and times s: uniform over the grid (``walk=False``, memory-bound)
    or 1000 random walks of 1-m steps, one after the other (cache-friendly, like agents)."""
    if not walk:
        xyz = np.column_stack([rng.uniform(grid.x0, grid.x_max, n), rng.uniform(0.0, 60.0, n),
                               rng.uniform(grid.z0, grid.z_max, n)])
        return xyz, rng.uniform(0.0, float(grid.time_s[-1]), n)
    m = n // 1000
    start = np.column_stack([rng.uniform(grid.x0 + 2000, grid.x_max - 2000, 1000),
                             rng.uniform(5.0, 40.0, 1000),
                             rng.uniform(grid.z0 + 2000, grid.z_max - 2000, 1000)])
    steps = rng.normal(0.0, 1.0, (1000, m, 3)) * np.array([1.0, 0.05, 1.0])
    xyz = (start[:, None, :] + np.cumsum(steps, axis=1)).reshape(-1, 3)
    t0 = rng.uniform(0.0, float(grid.time_s[-1]) - m, 1000)
    ts = (t0[:, None] + np.arange(m)[None, :]).reshape(-1)
    return np.ascontiguousarray(xyz), np.ascontiguousarray(ts)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="1e5 points, best of 10")
    ap.add_argument("--json", help="also write the results to this JSON file")
    args = ap.parse_args(argv)
    n, repeats = (100_000, 10) if args.quick else (200_000, 60)
    grid = load_grid(make_test_grid(**GRID_KW), current_gain=1.3)
    rng = np.random.default_rng(0)
    out = np.empty((n, 2))
    load0 = os.getloadavg()
    rows = {}
    for kind in ("walk", "random"):
        xyz, ts = _points(grid, rng, n, kind == "walk")
        t_one = float(ts[0])
        cases = {f"{kind}_at_old": (_loop_at_old, (grid, xyz, t_one, out)),
                 f"{kind}_at_new": (_loop_at_new, (grid, xyz, t_one, out)),
                 f"{kind}_full_old": (_loop_full_old, (grid, xyz, ts, out)),
                 f"{kind}_full_new": (_loop_full_new, (grid, xyz, ts, out))}
        for k, sec in _best_interleaved(cases, repeats).items():
            rows[k] = sec / n * 1e9
    ratio = {f"{kind}_{p}": rows[f"{kind}_{p}_new"] / rows[f"{kind}_{p}_old"]
             for kind in ("walk", "random") for p in ("at", "full")}
    res = {"points": n, "repeats": repeats, "ns_per_sample": rows, "new_over_old": ratio,
           "load_avg_before": load0, "load_avg_after": os.getloadavg()}
    print(f"points {n}, best of {repeats}, load {load0[0]:.2f} -> {os.getloadavg()[0]:.2f}")
    for k, v in rows.items():
        print(f"  {k:16s} {v:7.2f} ns/sample")
    for k, v in ratio.items():
        print(f"  new/old {k:12s} {v:.3f}")
    if args.json:
        from oneocean.io import write_json_atomic

        write_json_atomic(args.json, res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
