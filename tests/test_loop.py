"""The one episode loop (tasks/loop.py) and its Python driver (tasks/episodes.py)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from oneocean.errors import ConfigError
from oneocean.tasks import Cell
from oneocean.tasks.episodes import Episodes, rollout
from oneocean.tasks.loop import FINISHED


def _episodes(cell, method, n=4, seed=1, record=False):
    return Episodes(cell.mod, cell.grid, cell.params, cell.reset(n, seed), method, "6dof",
                    cell.vehicle, seed, record=record)


@pytest.mark.parametrize("method", ["heuristic", "oracle"])
def test_segments_resume_exactly(coast, method):
    """Running in K-step segments (what a planner or the step API does) gives the same
    episodes, bit for bit, as one call; the loop's state is kept between segments."""
    cell = Cell(coast, "G2G", 1)
    whole = _episodes(cell, method).run()
    parts = _episodes(cell, method)
    k = 0
    while not parts.done.all():
        k += 37
        parts.run(k)
        assert (parts.k <= k).all()
    np.testing.assert_array_equal(parts.res, whole.res)
    np.testing.assert_array_equal(parts.state, whole.state)
    # the loop state was written back (a heterogeneous NamedTuple: see loop.py)
    assert (whole.LS.status == FINISHED).all()
    T = whole.res[:, 1]
    ok = whole.res[:, 0] > 0.5
    np.testing.assert_array_equal(whole.LS.k[ok] * whole.dt, T[ok])
    assert (whole.LS.energy == whole.res[:, 2]).all() and (whole.LS.energy > 0).all()


def test_reached_runs_to_the_metric_horizon_with_standard_metrics_frozen(coast):
    """A post_step returning REACHED (SPC: the target fraction removed) latches success and
    the episode runs on to its time limit; T, E, violations and Coll are those at the
    success step (a run stopped there gives the same numbers), segments resume bit for bit,
    and a task whose post_step returns a bool never latches."""
    cell = Cell(coast, "SPC", 1, n_agents=4)
    whole = _episodes(cell, "oracle", n=3).run()
    r = whole.results()
    assert r["success"].all()
    np.testing.assert_array_equal(whole.LS.k, whole.n_steps)
    np.testing.assert_array_equal(whole.LS.k_succ * whole.dt, r["T_s"])
    parts = _episodes(cell, "oracle", n=3)
    for e in range(3):
        parts.run(int(whole.LS.k_succ[e]))
        assert parts.LS.energy[e] == r["E"][e]
        assert parts.LS.coll[e] == whole.LS.coll[e] and parts.LS.viol[e] == r["violations"][e]
    parts.run()
    np.testing.assert_array_equal(parts.res, whole.res)
    np.testing.assert_array_equal(parts.state, whole.state)
    g = _episodes(Cell(coast, "G2G", 1), "oracle").run()
    assert (g.LS.k_succ == -1).all() and np.isinf(g.LS.dmin).all()   # one agent: no pairs


def test_results_need_every_episode_to_end(coast):
    ep = _episodes(Cell(coast, "G2G", 1), "heuristic").run(3)
    with pytest.raises(RuntimeError, match="before every episode ended"):
        ep.results()


def test_unknown_method_is_a_config_error(coast):
    cell = Cell(coast, "G2G", 1)
    with pytest.raises(ConfigError, match="no fused policy"):
        rollout(cell.mod, cell.grid, cell.params, cell.reset(2, 0), "llm_x", "6dof",
                cell.vehicle, 0)
    with pytest.raises(ConfigError, match="trained weights"):   # bc without its network
        rollout(cell.mod, cell.grid, cell.params, cell.reset(2, 0), "bc", "6dof",
                cell.vehicle, 0)


def test_external_actions_shape_is_checked(coast):
    ep = _episodes(Cell(coast, "G2G", 1), None)
    with pytest.raises(ConfigError, match="expected shape"):
        ep.set_actions(np.zeros((3, 1, 3)))


def test_task_kernel_loads_from_the_cache_in_a_new_process(coast):
    """A task kernel gets its hooks as module globals, never as run-time arguments, so numba
    can cache it: a second process loads it instead of compiling it again."""
    code = textwrap.dedent("""
        from oneocean import engine as E
        from oneocean.testing import make_test_grid
        from oneocean.kernels import g2g
        from oneocean.tasks import run_cell
        g = E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
        run_cell(g, "G2G", 1, "heuristic", episodes=2, seed=0)
        print(sum(g2g._kernel.stats.cache_hits.values()),
              sum(g2g._kernel.stats.cache_misses.values()))
    """)
    out = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True).stdout.split() for _ in range(2)]
    hits, misses = map(int, out[1])
    assert hits == 1 and misses == 0, out


def test_python_planner_between_segments_drives_the_fused_policy(coast):
    """The planner kind: a Python planner writes the method's plan between K-step segments
    and the fused low-level policy follows it. A segment ends with the next step's
    observation taken, so replaying the fused plan hook from Python every step reproduces
    the fused rollout exactly; planning every 5 steps changes it."""
    cell = Cell(coast, "FT", 1, n_agents=4)
    fused = _episodes(cell, "heuristic", n=3).run()

    def replay(ep):
        pol = ep.kern.POLICY
        for e in range(ep.n_episodes):
            if not ep.done[e]:
                k = int(ep.k[e])
                assert ep.LS.sensed[e] == k   # the observation of step k is in C.O
                pol.plan(ep.C, e, k)

    def make():
        return Episodes(cell.mod, cell.grid, cell.params, cell.reset(3, 1), "heuristic",
                        "6dof", cell.vehicle, 1, fused_plan=False)

    planned = make().run_planned(replay, every=1)
    np.testing.assert_array_equal(planned.res, fused.res)
    sparse = make().run_planned(replay, every=5)
    assert not np.array_equal(sparse.res, fused.res)
    with pytest.raises(ConfigError, match="every must be"):
        make().run_planned(replay, every=0)


def test_the_observation_is_taken_once_before_anyone_moves(coast):
    """Every agent's observation of step k is taken before any agent of step k moves: the
    teammates' offsets an agent sees are those of the step start, as an external policy sees
    them through the step API; a segment ends with the next step's observation in ``C.O``;
    the final state's observation stays after the end."""
    cell = Cell(coast, "FT", 1, n_agents=4)
    ep = _episodes(cell, "heuristic", n=2, record=True).run()
    X = ep.obs[..., [14, 15]]                      # navigation x, z of every agent
    for m in range(3):                             # the nearest teammates' offsets
        dx = ep.obs[..., 8 + 2 * m]
        ok = np.isfinite(dx)
        mates = np.full(dx.shape, np.nan)
        for i in range(4):
            d = X - X[:, :, i:i + 1]
            dd = np.where(np.arange(4) == i, np.inf, np.hypot(d[..., 0], d[..., 1]))
            j = np.argsort(dd, axis=-1, kind="stable")[..., m]
            mates[:, :, i] = np.take_along_axis(d[..., 0], j[..., None], -1)[..., 0]
        np.testing.assert_allclose(dx[ok], mates[ok], rtol=0, atol=1e-9)
    part = _episodes(cell, "heuristic", n=2)
    part.run(10)
    np.testing.assert_array_equal(part.LS.sensed, [10, 10])
    np.testing.assert_allclose(part.C.O[..., 20], 10 * part.dt)     # t_s of step 10
    done = part.run()
    assert np.isfinite(done.C.O[..., 14]).all()


def test_external_heading_reaches_the_vehicle(coast):
    """An external action's fourth column is the commanded heading (NaN: free)."""
    ep = _episodes(Cell(coast, "G2G", 1), None, n=2)
    a = np.zeros((2, 1, 4))
    a[..., 3] = [[0.5], [np.nan]]
    ep.set_actions(a)
    ep.run(1)
    assert ep.cmd[0, 0, 3] == 0.5 and np.isnan(ep.cmd[1, 0, 3])
    ep.set_actions(np.zeros((2, 1, 3)))
    assert np.isnan(ep.ext[..., 3]).all()
