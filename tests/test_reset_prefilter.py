"""Cell.reset's band check before the build: a task module that splits its reset
(``reset_candidates`` / ``reset_build``, SPC) builds only the kept candidates, and the episodes
are bit for bit those of building every candidate with its ``reset`` and filtering afterwards;
a module without the split (SK, or SPC with the split hidden) resets through ``reset``."""

from __future__ import annotations

import types

import numpy as np
import pytest

from oneocean import engine as E
from oneocean.engine.grid import current_coverage
from oneocean.models import pollution as pol
from oneocean.tasks import Cell, sk, spc
from oneocean.tasks.regime import current_regime, site_speeds
from oneocean.testing import make_test_grid


@pytest.fixture(scope="module")
def coast():
    """A narrow coastal strip: many spill fields reach the land (SPC's land mask matters)."""
    return E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=12, dt_s=3600.0))


def _build_all_then_filter(cell: Cell, episodes: int, seed: int) -> dict:
    """The reference: ``reset`` of all candidates of the first draw, then the band check
    (coverage at the regime points, the regime at their median depth, the mean speed)."""
    band = cell.params["current_band"]
    n_cand = int(np.ceil(2.0 * episodes / max(float(band[1]) - float(band[0]), 0.05)))
    init = cell.mod.reset(cell.grid_reset, cell.params, cell.n_agents, n_cand, seed)
    pts = np.asarray(init.pop("regime_points"), dtype=np.float64)
    ok = (current_coverage(cell.grid_reset, pts.reshape(-1, 3)) >= 1.0).reshape(
        n_cand, -1).all(axis=1)
    reg = current_regime(cell.grid_reset, cell.params, float(np.median(pts[..., 1])))
    speed = np.full(n_cand, np.nan)
    speed[ok] = site_speeds(cell.grid_reset, pts[ok], init["t0"][ok],
                            float(cell.params["time_limit_s"]))
    ok &= (speed >= reg.lo) & (speed <= reg.hi)
    keep = np.flatnonzero(ok)[:episodes]
    assert keep.size == episodes          # the first draw suffices on this grid
    assert keep[-1] >= episodes           # and the band really removed candidates
    out = {k: v[keep] for k, v in init.items()}
    out["candidate"] = keep
    return out


def _assert_same(a: dict, b: dict) -> None:
    assert list(a) == list(b)
    for k in a:
        x, y = np.asarray(a[k]), np.asarray(b[k])
        assert x.dtype == y.dtype and x.shape == y.shape, k
        assert np.ascontiguousarray(x).tobytes() == np.ascontiguousarray(y).tobytes(), k


@pytest.mark.parametrize("task, tier, n_agents", [("SPC", 3, 3), ("SK", 3, None)])
def test_reset_equals_building_all_candidates_and_filtering(coast, task, tier, n_agents):
    cell = Cell(coast, task, tier, n_agents=n_agents)
    assert hasattr(cell.mod, "reset_candidates") == (task == "SPC")
    got = cell.reset(6, 3)
    _assert_same(got, _build_all_then_filter(cell, 6, 3))
    assert cell.regime is not None
    if task == "SPC":
        assert got["land"].any()            # the land mask is exercised


def test_a_module_without_the_split_resets_through_reset(coast):
    split = Cell(coast, "SPC", 3, n_agents=3)
    plain = Cell(coast, "SPC", 3, n_agents=3)
    plain.mod = types.SimpleNamespace(**{k: v for k, v in vars(spc).items()
                                         if k not in ("reset_candidates", "reset_build")})
    _assert_same(split.reset(6, 3), plain.reset(6, 3))


def test_candidates_do_not_depend_on_how_many_are_drawn(coast):
    """Candidate ``c`` is drawn from its own stream: a draw of more candidates extends a
    draw of fewer (what lets Cell.reset build only the kept ones, and double its draws)."""
    cell = Cell(coast, "SPC", 3, n_agents=3)
    args = (cell.grid_reset, cell.params, cell.n_agents)
    few, many = spc.reset_candidates(*args, 4, 9), spc.reset_candidates(*args, 9, 9)
    for k in few:
        assert np.array_equal(few[k], many[k][:4]), k
    cell = Cell(coast, "SK", 3)
    args = (cell.grid_reset, cell.params, cell.n_agents)
    few, many = sk.reset(*args, 4, 9), sk.reset(*args, 9, 9)
    for k in few:
        assert np.array_equal(few[k], many[k][:4]), k


def test_spc_build_of_chosen_candidates_is_their_rows_of_reset(coast):
    """Including a spill whose box (the cells reset_candidates checks for land) holds land."""
    cell = Cell(coast, "SPC", 3, n_agents=3)
    args = (cell.grid_reset, cell.params, cell.n_agents)
    full = spc.reset(*args, 25, 3)
    cand = spc.reset_candidates(*args, 25, 3)
    keep = np.array([1, 4, 23, 24])
    n, half = spc.field_frame(float(cell.params["domain_m"]))
    box = spc._spill_box(n, half, float(cell.params["spill_radius_m"]))
    assert full["land"][23, box, box].any() and full["land"][1].any()
    chosen = {k: v[keep] for k, v in cand.items()}
    chosen["candidate"] = keep
    _assert_same(spc.reset_build(*args, chosen, 3), {k: v[keep] for k, v in full.items()})
    # the premise of the box: the spill never reaches a land cell outside it, so the field
    # made with the box's land cells is the field made with the full mask, bit for bit
    R = float(cell.params["spill_radius_m"])
    for e in (1, 23):
        x0, z0 = full["origin"][e]
        part = np.zeros_like(full["land"][e])
        part[box, box] = full["land"][e][box, box]
        a, b = (pol.make_spill(n, n, spc.FIELD_H_M, (x0 + half, z0 + half), R,
                               spc.SPILL_MASS_KG, np.random.default_rng(e), x0=x0, z0=z0,
                               land=m) for m in (full["land"][e], part))
        assert a.tobytes() == b.tobytes()
