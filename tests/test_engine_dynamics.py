"""Vehicle dynamics: closed forms, physical invariants and the reference's failure modes.

Rollouts run on the one episode loop with external actions (``task_helpers.drive``); what the
loop cannot command (thrust off, a heading) is stepped with ``dynamics.step_agent`` directly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from oneocean import engine as E
from oneocean.engine import dynamics as D
from oneocean.engine.reference import reference_run
from oneocean.errors import ConfigError
from oneocean.tasks.loop import C_COLL, C_E, C_VIOL
from oneocean.testing import make_test_grid, uniform_grid
from task_helpers import drive, external_episodes, goal_control

RIGID = ("3dof", "4dof", "6dof")


@pytest.fixture(scope="module")
def vehicle():
    # the engine's invariants on the fully actuated test vehicle (the plain-NumPy reference
    # implements its holonomic controller); tests/test_vehicles.py covers the real vehicles
    return D.load_vehicle("generic_auv")


def still_grid(ce=0.0, cn=0.0):
    return E.load_grid(uniform_grid(ce, cn, depth_m=200.0, nx=41, ny=41, dx_m=200.0))


def test_unknown_model_and_bad_vehicle():
    with pytest.raises(ConfigError, match=r"dynamics: invalid value '5dof'.*'kinematic', '3dof'"):
        D.model_id("5dof")
    with pytest.raises(ConfigError, match="unknown override keys: mass"):
        D.load_vehicle("generic_auv", overrides={"mass": 3.0})
    with pytest.raises(ConfigError, match="max_substep_s"):
        D.load_vehicle(overrides={"max_substep_s": 1.0})
    with pytest.raises(ConfigError, match="added_mass"):
        D.load_vehicle(overrides={"added_mass": [1.0, 2.0]})


def test_clip_action():
    assert D.clip_action(0.3, 0.4, 0.0, 1.0) == (0.3, 0.4, 0.0)
    a = np.array(D.clip_action(3.0, 4.0, 12.0, 2.0))
    assert np.linalg.norm(a) == pytest.approx(2.0, rel=1e-15)
    np.testing.assert_allclose(a / np.linalg.norm(a), np.array([3, 4, 12]) / 13.0, rtol=1e-15)


def test_sincos_and_wrap():
    x = np.linspace(-50, 50, 20001)
    s = np.array([D.sincos(v) for v in x])
    assert np.abs(s[:, 0] - np.sin(x)).max() < 3e-16
    assert np.abs(s[:, 1] - np.cos(x)).max() < 3e-16
    w = np.array([D.wrap_angle(v) for v in x])
    assert w.min() >= -math.pi and w.max() < math.pi
    np.testing.assert_allclose(np.sin(w), np.sin(x), atol=1e-13)


def test_kinematic_matches_closed_form_exactly():
    # spatially and temporally varying currents: p_{t+1} = p_t + (a_t + c(p_t, t)) dt, bit for bit
    g = E.load_grid(make_test_grid(), tide={"amplitude_ms": 0.2, "period_s": 5000.0})
    rng = np.random.default_rng(0)
    steps, dt = 60, 2.0
    p0 = np.array([[[800.0, 4.0, 200.0]]])
    acts = rng.uniform(-0.8, 0.8, (steps, 1, 1, 3))
    acts[..., 1] *= 0.05
    ep = external_episodes(g, p0, steps, dt=dt, t0=500.0,
                           vehicle=D.load_vehicle("generic_auv",
                                                  overrides={"speed_limit_ms": 10.0}))
    drive(ep, acts)
    p = p0[0, 0].copy()
    for k in range(steps):
        ce, cn = E.sample_current(g, p[0], p[1], p[2], 500.0 + k * dt)
        a = acts[k, 0, 0]
        p = np.array([p[0] + (a[0] + ce) * dt, p[1] + a[1] * dt, p[2] + (a[2] + cn) * dt])
    assert ep.res[0, C_VIOL] == 0
    np.testing.assert_array_equal(ep.state[0, 0, :3], p)


@pytest.mark.parametrize("model", RIGID)
def test_zero_current_zero_action_stays_exactly_still(model, vehicle):
    g = still_grid()
    p0 = np.array([[[10.0, 30.0, -20.0]]])
    ep = external_episodes(g, p0, 300, dyn=model, vehicle=vehicle, psi0=0.7).run()
    expect = D.new_state(1, 1, p0, 0.7)
    np.testing.assert_array_equal(ep.state, expect)


@pytest.mark.parametrize("model", ("kinematic",) + RIGID)
def test_unactuated_vehicle_drifts_with_the_current(model, vehicle):
    ce, cn = 0.4, -0.3
    m = D.model_id(model)
    s = D.new_state(1, 1, np.array([[[0.0, 30.0, 0.0]]]), 1.0)[0, 0]
    cmd = D.make_cmd(thrust=False)
    for _ in range(200):
        D.step_agent(m, vehicle.params, s, cmd, ce, cn, 1.0)
    assert abs(s[D.VX] - ce) < 1e-6 and abs(s[D.VZ] - cn) < 1e-6
    # the displacement over the next 100 steps is the current's
    p = s[:3].copy()
    for _ in range(100):
        D.step_agent(m, vehicle.params, s, cmd, ce, cn, 1.0)
    d = s[:3] - p
    assert d[0] == pytest.approx(100 * ce, abs=1e-3)
    assert d[2] == pytest.approx(100 * cn, abs=1e-3)


@pytest.mark.parametrize("model", ("kinematic",) + RIGID)
def test_zero_action_drifts_with_the_current_at_no_energy(model, vehicle):
    # in the loop (thrust on): a zero request through the water is carried by the current
    ce, cn = 0.4, -0.3
    g = still_grid(ce, cn)
    ep = external_episodes(g, [[[0.0, 30.0, 0.0]]], 300, dyn=model, vehicle=vehicle, psi0=1.0)
    traj = drive(ep, np.zeros((300, 1, 1, 3)))
    c32 = np.float32(ce), np.float32(cn)
    s = ep.state[0, 0]
    assert abs(s[D.VX] - c32[0]) < 1e-6 and abs(s[D.VZ] - c32[1]) < 1e-6
    assert ep.res[0, C_E] == 0.0 and ep.res[0, C_VIOL] == 0
    d = traj[300, 0, 0] - traj[200, 0, 0]
    assert d[0] == pytest.approx(100 * c32[0], abs=1e-3)
    assert d[2] == pytest.approx(100 * c32[1], abs=1e-3)


def _mech_energy(model, vp, s, ce, cn):
    return D.kinetic_energy_rel(model, vp, s, ce, cn) + D.potential_energy(vp, s)


@pytest.mark.parametrize("model", RIGID)
@pytest.mark.parametrize("current", [(0.0, 0.0), (0.5, -0.2)])
@pytest.mark.parametrize("buoyancy", [0.0, 2.0])
def test_dissipation_never_adds_energy(model, current, buoyancy):
    # thrust off: kinetic energy relative to the water + restoring potential energy
    # (net buoyancy, BG roll/pitch) never increases, at the benchmark dt and below
    vp = D.load_vehicle("generic_auv", overrides={"net_buoyancy_n": buoyancy}).params
    ce, cn = current
    s = np.zeros(D.STATE_DIM)
    s[D.Y] = 50.0
    s[D.PSI] = 0.3
    s[D.U:D.R + 1] = [1.5, -0.8, 0.4, 0.6, -0.5, 0.7]
    if model == "6dof":
        s[D.PHI], s[D.THETA] = 0.3, -0.2
    m = D.model_id(model)
    cmd = D.make_cmd(thrust=False)
    e_prev = _mech_energy(m, vp, s, ce, cn)
    e0 = e_prev
    for dt in [1.0] * 150 + [0.1] * 50:
        D.step_agent(m, vp, s, cmd, ce, cn, dt)
        e = _mech_energy(m, vp, s, ce, cn)
        assert e <= e_prev + 1e-12 * abs(e0), (e, e_prev)
        e_prev = e
    if buoyancy == 0.0:
        assert D.kinetic_energy_rel(m, vp, s, ce, cn) < 1e-6


@pytest.mark.parametrize("model", RIGID)
@pytest.mark.parametrize("current", [(0.0, 0.0), (0.5, 0.3)])
def test_station_keeping_settles_and_stays(model, current, vehicle):
    # the reference's "6DoF" chattered +-1.2 m/s around every set-point: no limit cycle here
    g = still_grid(*current)
    goal = np.array([[[0.0, 30.0, 0.0]]])
    off = np.array([4.0, 0.0 if model == "3dof" else 2.0, -3.0])  # 3dof holds its depth
    ep = external_episodes(g, goal + off, 400, dyn=model, vehicle=vehicle)
    traj = drive(ep, goal_control(goal, kp=0.3))[:, 0, 0]
    err = np.linalg.norm(traj - goal[0, 0], axis=1)
    assert err[0] >= 5
    assert err[-150:].max() < 0.05, err[-150:].max()
    speed = np.linalg.norm(np.diff(traj[-150:], axis=0), axis=1)
    assert speed.max() < 1e-3
    assert np.linalg.norm(ep.state[0, 0, D.VX:D.VZ + 1]) < 1e-3


def test_yaw_convention_compass_heading(vehicle):
    g = still_grid()
    for name, act, psi in (("east", (1.0, 0, 0), math.pi / 2), ("north", (0, 0, 1.0), 0.0),
                           ("south-west", (-1.0, 0, -1.0), -3 * math.pi / 4)):
        ep = external_episodes(g, [[[0.0, 30.0, 0.0]]], 80, dyn="6dof", vehicle=vehicle,
                               psi0=0.3)
        ep.set_actions(np.array([[act]], dtype=float))
        s = ep.run().state[0, 0]
        assert abs(D.wrap_angle(s[D.PSI] - psi)) < 1e-3, name
        # facing the direction of travel: all speed is surge
        assert s[D.U] == pytest.approx(np.linalg.norm(act), abs=1e-3), name
        assert abs(s[D.V]) < 1e-3
        np.testing.assert_allclose(s[D.VX:D.VZ + 1], act, atol=1e-3)


def test_commanded_heading_is_held(vehicle):
    # a heading command (the loop's external actions leave the heading free)
    goal = np.array([0.0, 30.0, 0.0])
    s = D.new_state(1, 1, (goal + [3.0, 0.0, 0.0])[None, None], 0.0)[0, 0]
    m = D.model_id("4dof")
    for _ in range(200):
        a = 0.3 * (goal - s[:3])
        D.step_agent(m, vehicle.params, s, D.make_cmd(*a, psi=-2.0), 0.0, 0.0, 1.0)
    assert s[D.PSI] == pytest.approx(-2.0, abs=1e-4)


def test_six_dof_converges_to_kinematic_path_as_time_constants_shrink(vehicle):
    g = E.load_grid(make_test_grid())
    p0 = np.array([[[1500.0, 5.0, 0.0]]])
    goal = p0 + np.array([[[-300.0, 3.0, 250.0]]])
    steps = 150

    def path(model, veh):
        # start facing the goal: the shrinking quantities are time constants, not thrust
        # limits (a sideways start saturates sway thrust, which is physics, not lag)
        d = goal[0, 0] - p0[0, 0]
        ep = external_episodes(g, p0, steps, dyn=model, vehicle=veh,
                               psi0=math.atan2(d[0], d[2]))
        return drive(ep, goal_control(goal, kp=0.02))[:, 0, 0]

    kin = path("kinematic", vehicle)
    errs = []
    for s in (1.0, 0.1, 0.01, 0.001):
        spec = vehicle.spec
        veh = D.load_vehicle("generic_auv", overrides={
            "mass_kg": spec["mass_kg"] * s,
            "inertia_kg_m2": [v * s for v in spec["inertia_kg_m2"]],
            "added_mass": [v * s for v in spec["added_mass"]],
            "velocity_time_constant_s": [v * s for v in spec["velocity_time_constant_s"]],
            "net_buoyancy_n": 0.0})
        errs.append(np.linalg.norm(path("6dof", veh) - kin, axis=1).max())
    assert all(a > b for a, b in zip(errs, errs[1:])), errs
    assert errs[0] > 0.3 and errs[-1] < 2e-3, errs  # error ~ time constant (linear)


def test_surface_is_a_boundary_not_a_violation(vehicle):
    g = still_grid()
    for model in ("kinematic", "4dof", "6dof"):
        ep = external_episodes(g, [[[0.0, 3.0, 0.0]]], 40, dyn=model, vehicle=vehicle)
        ep.set_actions(np.array([[[0.0, -1.0, 0.0]]]))
        s = ep.run().state[0, 0]
        assert s[D.Y] == 0.0 and ep.res[0, C_VIOL] == 0, model
        assert s[D.VY] == 0.0


def test_depth_is_held_by_3dof(vehicle):
    g = still_grid()
    ep = external_episodes(g, [[[0.0, 12.5, 0.0]]], 30, dyn="3dof", vehicle=vehicle)
    ep.set_actions(np.array([[[0.5, 0.7, 0.2]]]))
    s = ep.run().state[0, 0]
    assert s[D.Y] == 12.5 and s[D.X] > 10.0


@pytest.mark.parametrize("model", ("kinematic",) + RIGID)
def test_engine_matches_the_plain_numpy_reference(model, vehicle):
    # an independent implementation (searchsorted, full matrices, np.linalg.solve) against
    # the one loop (FT, external P-control actions); the scenario includes land rejections
    # and near-collisions
    g = E.load_grid(make_test_grid(), tide={"amplitude_ms": 0.1, "period_s": 3600.0})
    pos = np.array([[[-2600.0, 3.0, 0.0], [-2598.5, 3.0, 0.5]],
                    [[1000.0, 4.0, 100.0], [1010.0, 6.0, 90.0]]])
    goals = pos + np.array([[[-900.0, 0.0, 40.0], [-900.0, 0.0, 40.0]],
                            [[60.0, 3.0, -50.0], [40.0, -2.0, -30.0]]])
    ep = external_episodes(g, pos, 60, dyn=model, vehicle=vehicle, t0=100.0)
    drive(ep, goal_control(goals, kp=0.2))
    r = reference_run(g, pos, goals, 60, dynamics=model, vehicle=vehicle, kp=0.2, t0=100.0)
    assert r["violations"][0].sum() > 0 and r["coll_steps"][0] > 0  # the scenario bites
    np.testing.assert_allclose(ep.state, r["state"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(ep.res[:, C_E], r["energy"].sum(axis=1), rtol=1e-12)
    np.testing.assert_array_equal(ep.res[:, C_VIOL], r["violations"].sum(axis=1))
    np.testing.assert_array_equal(ep.LS.coll, r["coll_steps"])
    np.testing.assert_array_equal(ep.res[:, C_COLL], r["coll_steps"] / 60)


# ----------------------------------------------------------------------- unsteady current


def _rel_lin(s, ce, cn):
    """Linear velocity relative to the water, body frame (m s-1)."""
    R = np.array(D._rotation(s[D.PSI], s[D.PHI], s[D.THETA], True)[4:]).reshape(3, 3)
    return s[D.U:D.W + 1] - R.T @ np.array([cn, ce, 0.0])


@pytest.mark.parametrize("model", RIGID)
def test_neutral_body_moves_with_an_accelerating_current(model):
    """Thrust off, water accelerating uniformly at A from rest: with the water's
    acceleration (Froude-Krylov m_d A + added mass M_A A) a neutrally buoyant body keeps zero
    velocity relative to the water (it IS a parcel of water: kappa = (m - m_d)/(m + M_A) = 0);
    stepped without it (``step_agent``, what the loop does) the hull keeps its momentum over
    ground and only drag drags it along: it lags the water."""
    veh = D.load_vehicle("generic_auv", overrides={"net_buoyancy_n": 0.0})
    np.testing.assert_allclose(veh.params[D.P_ACC:D.P_ACC + 3], 1.0, rtol=1e-15)
    m = D.model_id(model)
    ae, an, dt = 0.004, -0.003, 1.0
    s = D.new_state(1, 1, np.array([[[0.0, 50.0, 0.0]]]), 0.4)[0, 0]
    s0 = s.copy()
    cmd = D.make_cmd(thrust=False)
    x = 0.0
    for k in range(1, 121):
        ce, cn = ae * k * dt, an * k * dt
        D.step_agent_unsteady(m, veh.params, s, cmd, ce, cn, ae, an, dt)
        D.step_agent(m, veh.params, s0, cmd, ce, cn, dt)
        x += ce * dt
        assert np.abs(_rel_lin(s, ce, cn)).max() < 1e-12, k
    assert s[D.VX] == pytest.approx(ce, abs=1e-12) and s[D.VZ] == pytest.approx(cn, abs=1e-12)
    assert s[D.X] == pytest.approx(x, rel=1e-12)   # the water's own path, sample by sample
    # without the water's acceleration: the body lags (drag balances (m + M_A) A)
    assert np.linalg.norm(_rel_lin(s0, ce, cn)) > 5e-3


def test_heavy_body_lags_an_accelerating_current():
    """A body heavier than the water it displaces (m_d < m) in water accelerating at A
    settles at the relative velocity where drag carries the part of its inertia the water
    does not: D(nu_r) nu_r = -(m - m_d) A (3dof: depth held, the weight does not act). The
    neutral body has no lag; without the water's acceleration the lag is the whole
    (m + M_A) A."""
    dt, steps, a = 0.1, 4000, 0.005
    dl, dq = 10.0, 25.0   # generic_auv surge damping

    def lag(net_buoyancy, unsteady):
        veh = D.load_vehicle("generic_auv", overrides={"net_buoyancy_n": net_buoyancy})
        s = D.new_state(1, 1, np.array([[[0.0, 50.0, 0.0]]]), 0.0)[0, 0]   # facing north
        cmd = D.make_cmd(thrust=False)
        for k in range(1, steps + 1):
            if unsteady:
                D.step_agent_unsteady(1, veh.params, s, cmd, 0.0, a * k * dt, 0.0, a, dt)
            else:
                D.step_agent(1, veh.params, s, cmd, 0.0, a * k * dt, dt)
        return _rel_lin(s, 0.0, a * steps * dt)[0]

    def balance(mass):   # dl x + dq |x| x = -mass a, x < 0
        return (dl - math.sqrt(dl * dl + 4.0 * dq * mass * a)) / (2.0 * dq)

    g, m, ma = 9.81, 40.0, 4.0
    heavy = -10.0 * g     # B - W: m_d = m - 10 kg
    assert lag(heavy, True) == pytest.approx(balance(10.0), rel=0.03)
    assert abs(lag(0.0, True)) < 1e-12
    assert lag(heavy, False) == pytest.approx(balance(m + ma), rel=0.03)
    assert lag(0.0, False) == pytest.approx(balance(m + ma), rel=0.03)


@pytest.mark.parametrize("model", ("kinematic",) + RIGID)
def test_step_agent_is_the_unsteady_step_without_acceleration(model, vehicle):
    # the loop's step (no water acceleration given) is unchanged, bit for bit
    m = D.model_id(model)
    rng = np.random.default_rng(3)
    a = D.new_state(1, 1, np.array([[[0.0, 30.0, 0.0]]]), 0.2)[0, 0]
    b = a.copy()
    for k in range(60):
        ce, cn = 0.3 + 0.01 * k, -0.2 + 0.005 * k
        cmd = D.make_cmd(*rng.uniform(-1.0, 1.0, 3))
        D.step_agent(m, vehicle.params, a, cmd.copy(), ce, cn, 1.0)
        D.step_agent_unsteady(m, vehicle.params, b, cmd.copy(), ce, cn, 0.0, 0.0, 1.0)
    np.testing.assert_array_equal(a, b)
