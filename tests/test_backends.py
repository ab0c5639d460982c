"""The rollout protocol and the seam between a task (scenario, judge, accounting) and the
physics that moves its agents: the same kernel runs whole steps on the core (phase FULL) or
decides and judges around another backend's physics (phases DECIDE / JUDGE)."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from oneocean.backends.mujoco.episodes import SteppedEpisodes
from oneocean.backends.protocol import BACKENDS, Rollout, check_backend
from oneocean.engine import load_grid
from oneocean.engine.constraints import DEFAULT_LAND_THRESHOLD
from oneocean.engine.step import advance_agent
from oneocean.errors import ConfigError
from oneocean.tasks import Cell
from oneocean.tasks.episodes import Episodes
from oneocean.testing import make_test_grid


@njit(cache=False)
def _advance_all(grid, model, vp, state, cmd, cw, live, codes, v_max, dt, thr, clearance):
    for e in range(state.shape[0]):
        if not live[e]:
            continue
        for i in range(state.shape[1]):
            _, code = advance_agent(grid, model, vp, state[e, i], cmd[e, i], cw[e, i, 0],
                                    cw[e, i, 1], v_max, dt, thr, clearance)
            codes[e, i] = code


class CoreStepPhysics:
    """The core's own per-agent step behind the stepped protocol: every agent moves after
    all decided (the core moves them in turn; identical for one agent)."""

    def __init__(self, cell, dt):
        from oneocean.engine.dynamics import model_id

        self.cell, self.dt, self.model = cell, dt, model_id("6dof")

    def reset(self, state):
        self.codes = np.zeros(state.shape[:2], np.int64)

    def step(self, state, cmd, current, live):
        c = self.cell
        _advance_all(c.grid, self.model, c.vehicle.params, state, cmd, current,
                     np.asarray(live), self.codes, c.vehicle.v_max, self.dt,
                     DEFAULT_LAND_THRESHOLD, 1.0)
        return self.codes.copy()


@pytest.fixture(scope="module")
def grid():
    return load_grid(make_test_grid(nt=7, nz=3, ny=40, nx=50, dx_m=100.0, dz_m=100.0))


def test_backends_named_and_checked():
    assert BACKENDS == ("core", "mujoco")
    assert check_backend("core") == "core"
    with pytest.raises(ConfigError, match="rollouts.backend: unknown backend 'mujuco'"):
        check_backend("mujuco")


@pytest.mark.parametrize("task", ["G2G", "SK"])
def test_stepped_seam_equals_the_fused_loop_for_one_agent(grid, task):
    """DECIDE -> the core's step -> JUDGE gives the fused loop's results bit for bit when
    one agent moves (the order of moves is the only difference between the two paths): the
    scenario, judge and accounting are the same code."""
    cell = Cell(grid, task, 2)
    init = cell.reset(4, 3)
    full = cell.episodes(init, "heuristic", "6dof", 3, record=True)
    assert isinstance(full, Rollout) and full.backend == "core"
    ref = full.run().results()
    stepped = SteppedEpisodes(cell.mod, cell.grid, cell.params, init, "heuristic", "6dof",
                              cell.vehicle, 3, physics=CoreStepPhysics(cell, cell.params["dt_s"]),
                              record=True)
    assert isinstance(stepped, Rollout)
    got = stepped.run().results()
    assert set(got) == set(ref)
    for k in ref:
        np.testing.assert_array_equal(np.asarray(got[k]), np.asarray(ref[k]), err_msg=k)
    assert ref["success"].any()   # the comparison covers successful episodes


def test_stepped_seam_resumes_in_segments(grid):
    """run(k_stop) segments of the stepped path equal one run, as on the core."""
    cell = Cell(grid, "G2G", 1)
    init = cell.reset(3, 1)
    phys = CoreStepPhysics(cell, cell.params["dt_s"])
    one = SteppedEpisodes(cell.mod, cell.grid, cell.params, init, "heuristic", "6dof",
                          cell.vehicle, 1, physics=phys).run().results()
    seg = SteppedEpisodes(cell.mod, cell.grid, cell.params, init, "heuristic", "6dof",
                          cell.vehicle, 1, physics=CoreStepPhysics(cell, cell.params["dt_s"]))
    while not seg.done.all():
        seg.run(int(seg.k.max()) + 37)
    got = seg.results()
    for k in one:
        np.testing.assert_array_equal(got[k], one[k], err_msg=k)


def test_external_actions_through_the_stepped_seam(grid):
    """The step API's external actions reach the stepped path: zero actions keep the
    vehicle near its start (drift only), a constant east command moves it east."""
    cell = Cell(grid, "G2G", 1)
    init = cell.reset(2, 0)
    still = SteppedEpisodes(cell.mod, cell.grid, cell.params, init, None, "6dof", cell.vehicle,
                            0, physics=CoreStepPhysics(cell, cell.params["dt_s"]))
    east = SteppedEpisodes(cell.mod, cell.grid, cell.params, init, None, "6dof", cell.vehicle,
                           0, physics=CoreStepPhysics(cell, cell.params["dt_s"]))
    east.set_actions(np.tile([1.0, 0.0, 0.0], (2, 1, 1)))
    still.run(60)
    east.run(60)
    dx_still = still.state[:, 0, 0] - init["pos0"][:, 0, 0]
    dx_east = east.state[:, 0, 0] - init["pos0"][:, 0, 0]
    assert np.all(dx_east - dx_still > 40.0)   # ~1 m/s through the water for 60 s
    obs = east.observe()
    assert obs.shape == (2, 1, still.observe().shape[-1]) and np.isfinite(obs[..., :3]).all()


def test_core_episodes_default_backend_is_the_fused_kernel(grid):
    cell = Cell(grid, "G2G", 1)
    ep = cell.episodes(cell.reset(2, 0), "heuristic", "6dof", 0)
    assert type(ep) is Episodes and ep.backend == "core"


def test_mujoco_backend_needs_a_scene(grid):
    with pytest.raises(ConfigError, match="backend 'mujoco' needs a scene"):
        Cell(grid, "G2G", 1, backend="mujoco")
