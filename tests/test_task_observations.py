"""Per-agent observations and actions of every task (``run_cell(..., observations=True)``)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.tasks import Cell, run_cell, task_module
from oneocean.tasks.common import ACT_FIELDS, N_MATES, OBS_DIM, OBS_DOCS, OBS_FIELDS
from oneocean.testing import make_test_grid
from oneocean.vocab import TASK_IDS

#: (n_agents, tier) per task on the test grid: team tasks with several agents.
SETUP = {"G2G": (None, 1), "SK": (None, 1), "RF": (None, 1), "DPT": (None, 1),
         "AS": (3, 1), "PI": (2, 1), "FT": (5, 1), "SPC": (4, 1), "UPL": (None, 1),
         "FH": (None, 1)}
FIELD_TASKS = ("SPC", "PI")
COL = {k: i for i, k in enumerate(OBS_FIELDS)}


@pytest.fixture(scope="module")
def coast():
    return E.load_grid(make_test_grid(nt=5, nz=5, ny=40, nx=50, max_depth_m=60.0))


def test_layout():
    assert OBS_DIM == len(OBS_FIELDS) == 8 + 2 * N_MATES + 9
    assert len(set(OBS_FIELDS)) == OBS_DIM and len(ACT_FIELDS) == 3
    assert tuple(OBS_DOCS) == OBS_FIELDS and all(len(v) == 2 for v in OBS_DOCS.values())
    for task in TASK_IDS:                 # a task's own fields follow the common head
        extra = getattr(task_module(task), "OBS_EXTRA", ())
        assert len(extra) <= 8 and not set(extra) & set(OBS_FIELDS)


@pytest.mark.parametrize("task", TASK_IDS)
def test_observations_and_actions(coast, task):
    n_agents, tier = SETUP[task]
    plain = run_cell(coast, task, tier, "heuristic", episodes=2, seed=3, n_agents=n_agents)
    df, obs, act = run_cell(coast, task, tier, "heuristic", episodes=2, seed=3,
                            n_agents=n_agents, observations=True)
    # recording never changes the episode
    pd.testing.assert_frame_equal(plain, df)
    _, obs_true, _ = run_cell(coast, task, tier, "heuristic", episodes=2, seed=3,
                              n_agents=n_agents, observations=True, info="true_position")
    n = int(df["n_agents"].iloc[0])
    assert obs.shape[:3] == act.shape[:3] and obs.shape[0] == 2 and obs.shape[2] == n
    extra = getattr(task_module(task), "OBS_EXTRA", ())
    assert obs.shape[3] == OBS_DIM + len(extra) and act.shape[3] == 3
    # the cell's episodes: the candidates its current band kept (recorded in the table)
    init = Cell(coast, task, tier, n_agents=n_agents).reset(2, 3)
    np.testing.assert_array_equal(df["candidate"], init["candidate"])
    for e in range(2):
        o0 = obs[e, 0]
        # step 0 is recorded for every agent, from the start state
        assert np.isfinite(o0[:, :7]).all() and np.isfinite(act[e, 0]).all()
        np.testing.assert_allclose(o0[:, COL["depth_m"]], init["pos0"][e, :, 1])
        alt = -np.array([E.sample_elevation(coast, x, z) for x, _, z in init["pos0"][e]])
        np.testing.assert_allclose(o0[:, COL["altitude_m"]], alt - init["pos0"][e, :, 1])
        # the pollution probe only where the task has a field
        pol = obs[e, :, :, COL["pollution"]]
        rec = np.isfinite(obs[e, :, :, 0])
        if task in FIELD_TASKS:
            assert np.all(pol[rec] >= 0.0)
        else:
            assert np.isnan(pol).all()
        # teammates: the nearest first, NaN past the team (the step's start: exact check)
        mates = o0[:, 8:8 + 2 * N_MATES].reshape(n, N_MATES, 2)
        k = min(n - 1, N_MATES)
        for i in range(n):
            d = np.hypot(mates[i, :, 0], mates[i, :, 1])
            assert np.isfinite(d[:k]).all() and np.isnan(d[k:]).all()
            assert np.all(np.diff(d[:k]) >= 0)
        if k:
            # offsets between navigation estimates: with the true position they are exact
            p = init["pos0"][e]
            others = np.hypot(p[1:, 0] - p[0, 0], p[1:, 2] - p[0, 2])
            m0 = obs_true[e, 0, 0, 8:10]
            assert math.isclose(np.hypot(*m0), others.min(), rel_tol=1e-9)
            # with the sensors they are off by the agents' start fixes (3-sigma truncated)
            assert abs(np.hypot(*mates[0, 0]) - others.min()) <= 2 * 3 * 3.0 * math.sqrt(2)
        # time, position and velocity: the step's, the navigation estimate's, the DVL's
        np.testing.assert_allclose(o0[:, COL["t_s"]], 0.0)
        np.testing.assert_allclose(obs_true[e, 0, :, COL["x_m"]], init["pos0"][e, :, 0])
        np.testing.assert_allclose(obs_true[e, 0, :, COL["z_m"]], init["pos0"][e, :, 2])
        np.testing.assert_allclose(obs_true[e, 0, :, COL["vx_ms"]], 0.0)
        # the recorded steps are a prefix covering the episode (T), actions alongside
        rec = np.isfinite(obs[e, :, 0, 0])
        m = int(rec.sum())
        assert rec[:m].all() and m <= obs.shape[1]
        if df["success"].iloc[e]:   # T is the time to success (a failure's is the limit)
            assert m >= int(round(df["T_s"].iloc[e]))
        assert np.isfinite(act[e, :m]).all() and not np.isfinite(act[e, m:]).any()
        np.testing.assert_allclose(obs[e, :m, 0, COL["t_s"]], np.arange(m) * float(
            Cell(coast, task, tier, n_agents=n_agents).params["dt_s"]))
        # the energy proxy each agent has used grows with its actions
        assert np.all(np.diff(obs[e, :m, :, COL["energy_m2s"]], axis=0) >= 0.0)

def test_goal_cue_points_at_the_goal(coast):
    df, obs, _ = run_cell(coast, "G2G", 1, "oracle", episodes=2, seed=1, observations=True)
    # the episodes run_cell kept (the tier's current band selects among the candidates)
    init = Cell(coast, "G2G", 1).reset(2, 1)
    np.testing.assert_array_equal(df["candidate"], init["candidate"])
    np.testing.assert_allclose(obs[:, 0, 0, :3], init["goal"] - init["pos0"][:, 0, :])
    # the goal's depth is fixed: cue + depth is constant along every episode
    for e in range(2):
        steps = int(round(df["T_s"].iloc[e]))
        np.testing.assert_allclose(obs[e, :steps, 0, 1] + obs[e, :steps, 0, 5],
                                   init["goal"][e, 1], atol=1e-9)
