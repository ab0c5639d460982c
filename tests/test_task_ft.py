"""FT (formation transit): formation geometry, team success rule, Coll, determinism."""

from __future__ import annotations

import math

import numba
import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.errors import ConfigError
from oneocean.methods.heuristic import ft as FT_POLICY
from oneocean.tasks import ft, run_cell
from oneocean.tasks.spawn import path_clear
from oneocean.tasks.tiers import load_task_table
from oneocean.tasks.episodes import Episodes, rollout
from oneocean.testing import uniform_grid
from task_helpers import assert_tier_table_monotone, external_episodes, on_one_thread

TIER = {"time_limit_s": 700.0, "route_m": 400.0,
        "goal_radius_m": 5.0, "slot_tol_m": 1.5, "max_error_m": 5.0, "dt_s": 1.0}


def _grid(ce=0.0, cn=0.0, depth=60.0, n=31):
    return E.load_grid(uniform_grid(ce, cn, depth_m=depth, nx=n, ny=n, dx_m=100.0))


def _run(grid, tier, method, n_agents=4, dyn="kinematic", n=3, seed=0, init=None):
    init = init if init is not None else ft.reset(grid, tier, n_agents, n, seed)
    return init, rollout(ft, grid, tier, init, method, dyn, E.load_vehicle(), seed)


def _line_init(n_agents=3, offsets=None):
    """Hand-made episode: formation centroid from (-300, 5, 0) to (100, 5, 0), heading east."""
    start = np.array([[-300.0, 5.0, 0.0]])
    goal = np.array([[100.0, 5.0, 0.0]])
    if offsets is None:
        off2 = ft.wedge_offsets(n_agents)  # [forward, right] -> world (x east, z north)
        offsets = np.stack([off2[:, 0], np.zeros(n_agents), -off2[:, 1]], axis=1)[None]
    return {"pos0": start[:, None, :] + offsets, "offsets": offsets.copy(), "start": start,
            "goal": goal, "psi0": np.full((1, n_agents), math.pi / 2), "t0": np.zeros(1)}


def test_wedge_offsets():
    for n in (2, 5, 10):
        o = ft.wedge_offsets(n)
        assert o.shape == (n, 2)
        np.testing.assert_allclose(o.mean(axis=0), 0.0, atol=1e-12)
        d = np.linalg.norm(o[:, None] - o[None], axis=2) + np.eye(n) * 1e9
        assert d.min() >= ft.SPACING_M * (1 - 1e-9)  # slots at least one spacing apart
    o = ft.wedge_offsets(3)
    assert o[0, 0] > o[1, 0] and o[1, 1] == -o[2, 1]  # apex forward, symmetric arms


def test_reset_geometry_is_valid(coast):
    init = ft.reset(coast, TIER, 6, 5, seed=3)
    p0, off = init["pos0"], init["offsets"]
    assert p0.shape == (5, 6, 3)
    np.testing.assert_allclose(p0, init["start"][:, None] + off)
    np.testing.assert_allclose(off.mean(axis=1), 0.0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(init["goal"] - init["start"], axis=1),
                               TIER["route_m"])
    for e in range(5):
        for i in range(6):
            assert path_clear(coast, p0[e, i], init["goal"][e] + off[e, i], ft.MIN_ALTITUDE_M)
    # the formation frame follows the route: the apex (slot 0) is the most forward slot
    fwd = (init["goal"] - init["start"]) / TIER["route_m"]
    along = np.einsum("eik,ek->ei", off, fwd)
    assert np.all(np.argmax(along, axis=1) == 0)


def test_reset_raises_when_impossible():
    with pytest.raises(ConfigError, match="FT"):
        ft.reset(_grid(n=11), {**TIER, "route_m": 3000.0}, 4, 2, 0)
    with pytest.raises(ConfigError, match="n_agents"):
        ft.reset(_grid(), TIER, 1, 2, 0)
    with pytest.raises(ConfigError, match="n_agents"):
        run_cell(_grid(), "FT", 1, episodes=2, n_agents=11)


def test_oracle_transits_in_formation():
    _, r = _run(_grid(), TIER, "oracle", n_agents=5, init=_line_init(5))
    assert r["success"][0]
    assert r["formation_error_m"][0] < 1e-9 and r["max_slot_error_m"][0] < 1e-9
    assert r["final_centroid_error_m"][0] <= TIER["goal_radius_m"]
    assert r["coll_ratio"][0] == 0.0 and r["violations"][0] == 0
    # the virtual centre runs at the method's v_nom (V_NOM_FRAC * its budget,
    # methods.heuristic.ft): 395 m in 395 / v_nom s
    v_nom = FT_POLICY.V_NOM_FRAC * E.load_vehicle().v_max
    assert 395.0 / v_nom - 2.0 <= r["T_s"][0] <= 395.0 / v_nom + 13.0


def test_heuristic_in_calm_and_default_team(coast):
    _, r = _run(_grid(), TIER, "heuristic", n_agents=5, init=_line_init(5))
    v_nom = FT_POLICY.V_NOM_FRAC * E.load_vehicle().v_max
    assert r["success"][0] and 395 / v_nom - 2 < r["T_s"][0] < 395 / v_nom + 20
    _, r = _run(E.with_forcing(coast, current_gain=0.0), TIER, "heuristic", n_agents=10, n=3)
    assert r["success"].all()


def test_success_is_team_wide_not_best_of_n():
    # one agent released 100 m off its slot: still beyond max_error_m = 5 when the form-up
    # allowance (SETTLE_S) ends, the team fails then
    init = _line_init(4)
    init["pos0"][0, 2] += np.array([0.0, 0.0, 100.0])
    _, r = _run(_grid(), TIER, "oracle", n_agents=4, init=init)
    assert not r["success"][0] and r["T_s"][0] == TIER["time_limit_s"]
    assert r["max_slot_error_m"][0] > TIER["max_error_m"]
    # with a loose bound it recovers into the slot and the team succeeds
    _, r = _run(_grid(), {**TIER, "max_error_m": 150.0}, "oracle", n_agents=4, init=init)
    assert r["success"][0]


def test_error_bound_applies_after_the_form_up_allowance():
    # 8 m off its slot (> max_error_m = 5) at the release: the agent forms up within
    # SETTLE_S, so the bound never ends the episode and the team succeeds
    init = _line_init(4)
    init["pos0"][0, 2] += np.array([0.0, 0.0, 8.0])
    _, r = _run(_grid(), TIER, "oracle", n_agents=4, init=init)
    assert r["success"][0] and r["max_slot_error_m"][0] > TIER["max_error_m"]
    P, _ = ft.make(_grid(), TIER, init)
    assert P.settle_k == int(ft.SETTLE_S / TIER["dt_s"])


def test_usbl_tracks_the_team_in_turn():
    """FT's escort vessel interrogates the team's transponders in turn (sensors.yaml
    navigation.aids.usbl, sequential): with N agents each gets a fix every N slots, agent i
    in slot i; other tasks' aids are untouched (no ``sequential`` key)."""
    from oneocean import sensing
    from numba import njit

    from oneocean.engine.dynamics import STATE_DIM
    from oneocean.sensing.kernels import nav_update

    aid = sensing.nav_aid(load_task_table("FT"), "FT")
    assert aid == ("usbl", 1.0, True)
    sp = sensing.sensing_params("sensors", 1.0, aid)
    assert sp.fix_seq == 1 and sp.fix_every == 1
    assert sensing.sensing_params("sensors", 1.0, ("usbl", 1.0)).fix_seq == 0
    for bad in ({"aid": "usbl", "period_s": 1, "sequential": "yes"},
                {"aid": "usbl", "period_s": 1, "every": 2}):
        with pytest.raises(ConfigError, match="navigation"):
            sensing.nav_aid({"navigation": bad}, "FT.yaml")

    @njit
    def fixes(SP, nerr, state, n_steps):
        navc = np.zeros((1, state.shape[1], 3))
        navc[..., 0] = 1.0
        navc[..., 1] = 1.0
        out = np.zeros((n_steps, state.shape[1]))
        for k in range(n_steps):
            for i in range(state.shape[1]):
                before = nerr[0, i, 0]
                nav_update(SP, 3, navc, nerr, state, state, 0, k, i, state.shape[1], 1.0)
                out[k, i] = nerr[0, i, 0] != before
        return out

    n = 4
    state = np.zeros((1, n, STATE_DIM))
    state[..., 1] = 5.0   # underwater
    sp0 = sp._replace(vel_noise=0.0)
    got = fixes(sp0, np.ones((1, n, 2)), state, 3 * n)
    want = np.zeros((3 * n, n))
    for k in range(3 * n):
        want[k, k % n] = 1.0   # agent i in slot i of every sequence of n slots
    np.testing.assert_array_equal(got, want)


def test_arrival_needs_every_agent_in_slot_tolerance():
    init = _line_init(3)
    # with tolerance 0 arrival never counts (the 6dof team is never exactly in shape)
    _, r6 = _run(_grid(), {**TIER, "slot_tol_m": 0.0}, "oracle", n_agents=3, dyn="6dof",
                 init=init)
    assert not r6["success"][0] and r6["T_s"][0] == TIER["time_limit_s"]
    # the centroid did arrive (it paces on, held at the goal by nobody's slot tolerance)
    assert r6["final_centroid_error_m"][0] <= 2 * TIER["goal_radius_m"]
    _, ok = _run(_grid(), TIER, "oracle", n_agents=3, dyn="6dof", init=_line_init(3))
    assert ok["success"][0]


def test_coll_ratio_counts_near_collision_steps():
    # all slots stacked on one point: every step is a near collision (distance 0 <= 2 m)
    init = _line_init(3, offsets=np.zeros((1, 3, 3)))
    _, r = _run(_grid(), TIER, "oracle", n_agents=3, init=init)
    assert r["coll_ratio"][0] == 1.0
    # two agents 3 m apart (> 2 m), held exactly: never
    off = np.zeros((1, 2, 3))
    off[0, 0, 2] = 1.5
    off[0, 1, 2] = -1.5
    _, r = _run(_grid(), TIER, "oracle", n_agents=2, init=_line_init(2, offsets=off))
    assert r["coll_ratio"][0] == 0.0 and r["success"][0]


def test_coll_on_a_head_on_pass():
    """Coll (eq. 4) through the FT kernel: two vehicles 20 m apart driven head-on at 1 m/s
    each (external actions, kinematic, calm water) are within r_coll = 2 m after steps 9, 10
    and 11 of 30 (distances 2, 0, 2 m): Coll = 3 / 30 exactly; the closest distance is 0."""
    ep = external_episodes(_grid(), [[[-10.0, 5.0, 0.0], [10.0, 5.0, 0.0]]], 30)
    ep.set_actions(np.array([[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]]))
    r = ep.run().results()
    assert r["coll_ratio"][0] == pytest.approx(0.1) and ep.LS.coll[0] == 3
    assert ep.LS.dmin[0] == pytest.approx(0.0, abs=1e-9)
    # the same pass in lanes 2.5 m apart: never within 2 m
    ep = external_episodes(_grid(), [[[-10.0, 5.0, 0.0], [10.0, 5.0, 2.5]]], 30)
    ep.set_actions(np.array([[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]]))
    r = ep.run().results()
    assert r["coll_ratio"][0] == 0.0 and ep.LS.dmin[0] == pytest.approx(2.5)


@pytest.mark.parametrize("method", ["heuristic", "oracle"])
def test_wedge_spacing_bounds_the_closest_pair(coast, method):
    """Why FT's Coll is 0 by construction: slots are >= SPACING_M (8 m) apart, so
    |p_i - p_j| >= SPACING_M - e_i - e_j >= SPACING_M - 2 max_slot_error: no near collision
    while every slot error stays below (SPACING_M - r_coll) / 2 = 3 m. The loop's recorded
    closest distance (LoopState.dmin) obeys the bound on real rollouts."""
    tier = {**TIER, "probe_noise_ms": 0.3, "max_error_m": 10.0}
    init = ft.reset(coast, tier, 10, 4, 2)
    ep = Episodes(ft, coast, tier, init, method, "6dof", E.load_vehicle(), 2).run()
    r = ep.results()
    bound = ft.SPACING_M - 2.0 * r["max_slot_error_m"]
    assert np.all(ep.LS.dmin >= bound - 1e-9)
    small = r["max_slot_error_m"] < 0.5 * (ft.SPACING_M - ft.R_COLL_M)
    assert small.any() and np.all(r["coll_ratio"][small] == 0.0)


def test_determinism_and_threads(coast):
    a = run_cell(coast, "FT", 3, "heuristic", episodes=3, seed=5, n_agents=6)
    b = run_cell(coast, "FT", 3, "heuristic", episodes=3, seed=5, n_agents=6)
    pd.testing.assert_frame_equal(a, b)
    np.testing.assert_array_equal(a["primary"], a["formation_error_m"])
    assert a.attrs["n_agents"] == 6
    if numba.config.NUMBA_NUM_THREADS >= 2:
        c = on_one_thread(run_cell, coast, "FT", 3, "heuristic", episodes=3, seed=5, n_agents=6)
        pd.testing.assert_frame_equal(a, c)


def test_tier_table_monotone_and_declared():
    table = load_task_table("FT")
    tiers = table["tiers"]
    assert_tier_table_monotone(table)
    for t in (1, 2, 3):
        assert set(tiers[t]) == set(table["harder"])
        assert tiers[t]["slot_tol_m"] < tiers[t]["max_error_m"]
    assert table["agents"] == {"default": 10, "range": [2, 10]}


def test_the_cue_is_the_tasks_formation_reference():
    # every agent's cue: its slot around the team's navigated centroid, led P.lead m toward
    # the goal -- the task's own, the same for every method (the heuristic never writes it)
    grid = _grid(0.3, -0.2)
    init = _line_init(5)
    veh = E.load_vehicle()
    ep = Episodes(ft, grid, TIER, init, None, "kinematic", veh, 0)
    O = ep.observe()
    X = ep.known_state[0, :, :3]
    c = X.mean(axis=0)
    u = (init["goal"][0] - c) / np.linalg.norm(init["goal"][0] - c)
    lead = ft.CUE_LEAD_S * ft.TRANSIT_FRAC * veh.v_max
    np.testing.assert_allclose(X + O[0, :, 0:3], c + init["offsets"][0] + lead * u, atol=1e-9)
    assert ep.P.lead == lead


def test_a_follower_of_the_cue_transits_in_formation():
    # the task's cue alone is enough in calm water: close the cue offset in CUE_LEAD_S
    # (the docs' example controller: seek the cue, cancel the known current)
    grid = _grid()
    init = _line_init(5)
    ep = Episodes(ft, grid, TIER, init, None, "kinematic", E.load_vehicle(), 0)
    O = ep.observe()
    while not ep.done.all():
        a = O[..., 0:3] / ft.CUE_LEAD_S
        a[..., 0] -= O[..., 3]
        a[..., 2] -= O[..., 4]
        ep.set_actions(a)
        O = ep.step_observe()
    r = ep.results()
    assert r["success"][0] and r["max_slot_error_m"][0] < TIER["slot_tol_m"]
