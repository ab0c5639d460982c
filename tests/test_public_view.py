"""The public view every method is given (docs/policy.md): each task's briefing and its own
observation fields are declared and documented, the briefing holds the forecast for every
non-oracle method and the truth for the oracle (and for the information ablation that is given
the true current), and its arrays lead with the episode axis."""

from __future__ import annotations

import numpy as np
import pytest

from oneocean import engine as E
from oneocean.tasks import Cell, task_module
from oneocean.tasks import routing
from oneocean.tasks.common import OBS_DIM
from oneocean.tasks.public import COMMON, briefing_rows
from oneocean.testing import make_test_grid
from oneocean.vocab import TASK_IDS

N_AGENTS = {"AS": 2, "PI": 2, "FT": 3, "SPC": 3}


@pytest.fixture(scope="module")
def coast():
    return E.load_grid(make_test_grid(nt=5, nz=5, ny=40, nx=50, max_depth_m=60.0))


def _batch(coast, task, method, info=None):
    cell = Cell(coast, task, 1, n_agents=N_AGENTS.get(task))
    return cell.episodes(cell.reset(2, 3), method, "6dof", 3, info=info)


@pytest.mark.parametrize("task", TASK_IDS)
def test_every_task_declares_and_documents_its_public_view(coast, task):
    mod = task_module(task)
    assert all(len(v) == 3 for v in mod.BRIEF_FIELDS.values())
    assert tuple(mod.OBS_EXTRA) == tuple(mod.OBS_EXTRA_DOCS) and len(mod.OBS_EXTRA) <= 8
    assert all(len(v) == 2 and v[1] for v in mod.OBS_EXTRA_DOCS.values())
    assert isinstance(mod.CUE_DOC, str) and mod.CUE_DOC
    ep = _batch(coast, task, None)
    B = ep.B
    assert type(B).__name__ == f"{task}Briefing"
    assert B._fields == tuple(COMMON) + tuple(mod.BRIEF_FIELDS)
    # every top-level array leads with the episode axis; the common values are the cell's
    for name, v in B._asdict().items():
        if isinstance(v, np.ndarray):
            assert v.shape[0] == 2, name
    assert B.t_lim == ep.n_steps * ep.dt and B.dt == ep.dt and B.n_agents == ep.n_agents
    assert B.v_max == ep.vehicle.v_max
    one = briefing_rows(B, [1])
    assert one.t0.shape == (1,) and one.t0[0] == B.t0[1]
    # the observation: the common head, then the task's own fields
    assert ep.observe().shape == (2, ep.n_agents, OBS_DIM + len(mod.OBS_EXTRA))
    team = getattr(mod, "team_obs", None)
    assert (team is None) == (not getattr(mod, "TEAM_FIELDS", {}))
    if team is not None:
        assert tuple(ep.C.T._fields) == tuple(mod.TEAM_FIELDS)
    assert (getattr(mod, "report", None) is None) == (not getattr(mod, "REPORT_DOC", ""))


def _points(task, B, e):
    if task == "G2G":
        return np.array([[B.start[e, 0], B.start[e, 2]], [B.goal[e, 0], B.goal[e, 2]]]), \
            float(B.goal[e, 1])
    return np.ascontiguousarray(B.route[e][:, [0, 2]]), float(B.route[e, 0, 1])


@pytest.mark.parametrize("task", ["G2G", "RF"])
def test_the_briefings_field_is_the_forecast_and_the_oracles_the_truth(coast, task):
    """The field a transit plans on: the truth for the oracle (and for the ablation given the
    true current), the forecast (the truth through the episode's error model) for everyone
    else -- as values, never the truth with its error model."""
    h, o = _batch(coast, task, "heuristic"), _batch(coast, task, "oracle")
    a = _batch(coast, task, "heuristic", info="true_current")
    fixed = task == "RF"
    for e in range(2):
        for ep, fc in ((h, h.LS.fc), (o, None), (a, None)):
            pts, depth = _points(task, ep.B, e)
            want = routing.mission_field(ep.grid, pts, depth, float(ep.t0[e]), ep.B.t_lim,
                                         fixed=fixed, fc=fc, e=e)
            got = routing.unpack_field(ep.B, e)
            np.testing.assert_array_equal(got.cur, want.cur)
            np.testing.assert_array_equal(got.free, want.free)
            assert (got.x0, got.z0, got.h) == (want.x0, want.z0, want.h)
        # the forecast is not the truth
        pts, depth = _points(task, h.B, e)
        truth = routing.mission_field(h.grid, pts, depth, float(h.t0[e]), h.B.t_lim,
                                      fixed=fixed)
        assert not np.array_equal(routing.unpack_field(h.B, e).cur, truth.cur)


def test_the_chart_carries_no_currents(coast):
    B = _batch(coast, "AS", None).B
    assert B.chart.uv.size == 0 and B.chart.uv_tide.size == 0 and B.chart.gain == 0.0
    np.testing.assert_array_equal(B.chart.elevation, coast.elevation)
    x, z = 0.5 * (coast.x0 + coast.x_max), 0.5 * (coast.z0 + coast.z_max)
    assert E.sample_elevation(B.chart, x, z) == E.sample_elevation(coast, x, z)
