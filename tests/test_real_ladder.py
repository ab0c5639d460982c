"""The task ladder on a real region: the southern North Sea built through the ``files`` source
from the GLO12 daily currents and ETOPO 2022 files in ../shared/data. Every cell either runs
or is written as not applicable with its reason; none crashes. Tier current bands are the
region's own."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from oneocean.engine import load_grid, read_metrics_meta
from oneocean.product.exports import export_grid
from oneocean.reporting.cells import load_cells
from oneocean.reporting.ladder import ladder_markdown
from oneocean.registry import builtin_task_ids
from oneocean.tasks import Cell, rollout_to_file
from oneocean.testing import make_test_grid
from test_real_product import CMEMS, _north_sea


@pytest.fixture(scope="module")
def north_sea_grid(shared_data, tmp_path_factory):
    root = tmp_path_factory.mktemp("north_sea_ladder")
    product = _north_sea(shared_data, root, shared_data / CMEMS, variant="scene")
    out = root / "grid.npz"
    export_grid(product, out)
    return out


def test_every_cell_runs_or_is_not_applicable_on_the_real_region(north_sea_grid, tmp_path):
    files = []
    for task in builtin_task_ids():
        out = tmp_path / f"{task}.parquet"
        rollout_to_file(north_sea_grid, out, task, 3, "heuristic", 3, 1000, "kinematic")
        meta = read_metrics_meta(out)
        df = pd.read_parquet(out)
        if meta["applicable"]:
            assert len(df) == 3 and df["success"].dtype == bool, task
            assert np.isfinite(df["T_s"]).all() and (df["T_s"] > 0).all(), task
        else:
            assert len(df) == 0 and meta["reason"].startswith(f"{task} tier 3"), task
        files.append(out)
    cells = load_cells(files)
    # the real region hosts most of the ladder (its shelf is 18-50 m deep, currents <= 0.5 m/s);
    # the transits' Tier 3 asks for 0.6-2 m/s of mean current (absolute), which it never has
    assert cells["applicable"].sum() >= 7, cells[["task", "applicable", "reason"]]
    na = cells.set_index("task")
    for task in ("G2G", "RF"):
        assert not na.loc[task, "applicable"] and "m/s" in na.loc[task, "reason"], task
    md = ladder_markdown(cells, "southern_north_sea_files", 1000)
    assert md.startswith("Region `southern_north_sea_files`, evaluation seed 1000")
    for task in builtin_task_ids():
        assert f"| {task} |" in md


def test_current_bands_are_the_regions_own_quantiles(north_sea_grid):
    """Tier 3's band is "the fastest third of this region's water": a calm real region's
    threshold is far below the tidal synthetic one's, and both keep their own episodes."""
    real = Cell(load_grid(north_sea_grid), "DPT", 3)
    real.reset(4, 1000)
    tidal = Cell(load_grid(make_test_grid(nt=25, speed_ms=0.6, tide_ms=0.8, land=False)),
                 "DPT", 3)
    tidal.reset(4, 1000)
    assert real.regime.band == tidal.regime.band == (0.67, 1.0)
    assert real.regime.lo < 0.3 < tidal.regime.lo


def test_regime_samples_and_quantiles_on_the_real_region_equal_the_grid_sampler(north_sea_grid):
    """On the real region's grid the current regime's kept levels give the speeds
    ``sample_speeds_times`` gives at each depth, bit for bit, and its quantiles those of
    ``np.quantile``."""
    from oneocean.engine.grid import sample_speeds_times
    from oneocean.tasks.regime import RegimeSampler

    g = load_grid(north_sea_grid)
    sampler = RegimeSampler(g)
    for d in (0.2, 2.0, 4.7, 6.0, 30.0):
        k, x, z = sampler.nodes(d)
        want = sample_speeds_times(g, np.column_stack([x, np.full(x.size, d), z]),
                                   np.asarray(g.time_s, dtype=np.float64))
        assert np.array_equal(sampler.speeds(d).view(np.int64), want.view(np.int64)), d
        qs = [0.0, 0.33, 0.67, 0.83, 1.0]
        assert sampler.quantiles(d, qs) == tuple(np.quantile(want, qs).tolist()), d
        assert want.max() > 0.05
