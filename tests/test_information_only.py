"""Heuristic and oracle differ in information only (docs/sensing.md, "Heuristic and oracle"):
given the truth (its briefing's forecast is the true field; its observation the true current,
position and target; SPC's aerial map exact every step), the heuristic of every task IS the
oracle, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from oneocean import engine as E
from oneocean.tasks import run_cell
from oneocean.testing import make_test_grid
from oneocean.vocab import TASK_IDS


@pytest.fixture(scope="module")
def coast():
    return E.load_grid(make_test_grid(nt=5, nz=5, ny=40, nx=50, max_depth_m=60.0))


@pytest.mark.parametrize("task", TASK_IDS)
def test_heuristic_given_the_truth_is_the_oracle(coast, task):
    kw = dict(episodes=2, seed=11, dynamics="6dof")
    o = run_cell(coast, task, 1, "oracle", **kw)
    t = run_cell(coast, task, 1, "heuristic", info="truth", **kw)
    h = run_cell(coast, task, 1, "heuristic", **kw)
    cols = [c for c in o.columns if c not in ("method",)]
    assert o[cols].equals(t[cols])
    # with its sensors the heuristic is a different run (its estimates are not the truth)
    assert not h[cols].equals(t[cols])
