"""The literature vehicles (data/vehicles.yaml): cited values, their derived limits, and where
the rigid-body models must differ from the kinematic abstraction ``p += (a + c) dt`` and where
they must agree.

``remus100``: REMUS 100-class torpedo (Prestero 2001), propeller + rudder + stern planes, no
sway/heave/roll actuation, directionally unstable hull. ``bluerov2_heavy``: BlueROV2 Heavy-class
ROV (von Benzon et al. 2022), eight T200 thrusters in two coupled groups of four.
Rollouts call ``dynamics.step_agent`` (and ``step_agent_traced`` for actuator forces) directly.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
import yaml

from oneocean.engine import dynamics as D
from oneocean.errors import ConfigError

G0 = 9.80665  # kgf -> N
RIGID = ("3dof", "4dof", "6dof")
NEW = ("remus100", "bluerov2_heavy")


@pytest.fixture(scope="module")
def remus():
    return D.load_vehicle("remus100")


@pytest.fixture(scope="module")
def rov():
    return D.load_vehicle("bluerov2_heavy")


def run(veh, model, cmd, steps, *, dt=1.0, ce=0.0, cn=0.0, psi0=0.0, s=None):
    """Roll one agent; ``cmd(k)`` -> (ax, ay, az[, psi]) relative to the water (clipped to
    v_max here, as advance_agent does). Returns states (steps + 1, STATE_DIM) and actuator
    traces (steps, TRACE_DIM; zeros for the kinematic model)."""
    m = D.model_id(model)
    s = D.new_state(1, 1, np.array([[[0.0, 50.0, 0.0]]]), psi0)[0, 0] if s is None else s.copy()
    tr = np.zeros(D.TRACE_DIM)
    states, traces = [s.copy()], []
    for k in range(steps):
        c = cmd(k)
        a = D.clip_action(c[0], c[1], c[2], veh.v_max)
        c4 = np.array([a[0], a[1], a[2], c[3] if len(c) > 3 else np.nan, 1.0])
        if m == D.KINEMATIC:
            D.step_agent(m, veh.params, s, c4, ce, cn, dt)
            tr[:] = 0.0
        else:
            D.step_agent_traced(m, veh.params, s, c4, ce, cn, dt, tr)
        states.append(s.copy())
        traces.append(tr.copy())
    return np.array(states), np.array(traces)


def heading_error(psi, target):
    return np.abs(np.array([D.wrap_angle(target - p) for p in np.atleast_1d(psi)]))


# ----------------------------------------------------------------------------- the catalogue


def test_catalogue_default_and_test_vehicle():
    assert D.vehicle_names() == ("remus100", "bluerov2_heavy", "generic_auv")
    assert D.load_vehicle().name == "remus100"
    assert "TEST VEHICLE" in D.load_vehicle("generic_auv").spec["description"]


def test_every_literature_value_carries_a_source():
    # every key of the two literature vehicles is preceded by a comment that cites a source
    # ([P01] Prestero, [vB22] von Benzon, [W18] Wu, [T200] Blue Robotics, [WHOI]) or says why
    # the value was chosen / how it was derived
    text = D.vehicles_file().read_text().splitlines()
    tags = re.compile(r"\[(P01|vB22|W18|T200|WHOI)\]|[Cc]hosen|[Dd]erived")
    for name in NEW:
        start = text.index(f"  {name}:")
        block = []
        for line in text[start + 1:]:
            if re.match(r"  \S", line):
                break
            block.append(line)
        keys = [re.match(r"    (\w+):", ln).group(1) for ln in block if re.match(r"    \w+:", ln)]
        assert set(keys) - {"description"} == set(D._VEHICLE_KEYS) - {"description"}, name
        for i, line in enumerate(block):
            m = re.match(r"    (\w+):", line)
            if not m or m.group(1) == "description":
                continue
            j, comment = i - 1, ""
            while j >= 0 and block[j].strip().startswith("#"):
                comment = block[j] + comment
                j -= 1
            assert tags.search(comment), (name, m.group(1))


def test_remus_values_are_prestero_s(remus):
    s = remus.spec
    assert s["mass_kg"] == pytest.approx(299.0 / 9.81, abs=0.01)  # W = 299 N
    assert s["inertia_kg_m2"] == [0.177, 3.45, 3.45]
    assert s["added_mass"] == [0.93, 35.5, 35.5, 0.0704, 4.88, 4.88]
    assert s["quadratic_damping"] == [1.62, 131.0, 131.0, 0.130, 9.4, 9.4]
    assert s["fin_coefficients"] == [9.64, -6.15, -9.64, -6.15]
    assert s["fin_angle_max_deg"] == 13.6
    assert s["metacentric_height_m"] == 0.0196
    # lift without the added-mass parts: with the Munk moment of the diagonal M the totals are
    # Prestero's combined N_uv = -24.0 and M_uw = +24.0 (Table C.8: N_uva = -M_uwa = -34.6)
    m = remus.params[D.P_M:D.P_M + 6]
    munk = m[1] - m[0]
    y_uv, y_ur, n_uv, n_ur, z_uw, z_uq, m_uw, m_uq = s["lift_coefficients"]
    assert munk == pytest.approx(34.57, abs=0.01)
    assert n_uv - munk == pytest.approx(-24.0, abs=0.05)
    assert m_uw + munk == pytest.approx(24.0, abs=0.05)
    # fin lift at x_fin = N_uudr / Y_uudr = -0.638 m gives the fin parts of the lift terms
    x_fin = -6.15 / 9.64
    assert y_ur == pytest.approx(-9.64 * x_fin, abs=0.01)        # Y_urf
    assert n_ur == pytest.approx(9.64 * x_fin ** 2 * -1, abs=0.01)  # N_urf
    assert (y_uv, z_uw, z_uq, m_uq) == (-28.6, -28.6, -6.15, -3.93)


def test_remus_limits_follow_from_the_data(remus):
    p, s = remus.params, remus.spec
    x_uu = s["quadratic_damping"][0]
    # the propeller holds the 2.5 m/s speed limit (WHOI, Fossen MSS) through the water; its
    # free-running top speed is 2.6 m/s
    assert remus.v_max == 2.5
    assert x_uu * 2.5 ** 2 < s["thrust_max"][0] <= x_uu * 2.6 ** 2 + 0.1
    assert math.sqrt(s["thrust_max"][0] / x_uu) == pytest.approx(2.6, abs=0.01)
    # Prestero's cruise point: X_prop = 3.86 N (Table C.9) -> 1.54 m/s
    assert math.sqrt(3.86 / x_uu) == pytest.approx(1.54, abs=0.01)
    # fin authority: |N_uudr| delta_max per u_r^2, and no sway, heave or roll thrust
    assert p[D.P_FINR] == pytest.approx(6.15 * math.radians(13.6), rel=1e-12)
    assert p[D.P_FINQ] == pytest.approx(6.15 * math.radians(13.6), rel=1e-12)
    assert p[D.P_FINY] == pytest.approx(9.64 / -6.15, rel=1e-12)
    assert list(p[D.P_TMAX:D.P_TMAX + 6]) == [11.0, 0, 0, 0, 0, 0]


def test_rov_values_and_thrust_geometry(rov):
    s = rov.spec
    assert (s["mass_kg"], s["inertia_kg_m2"]) == (13.5, [0.26, 0.23, 0.37])
    assert s["added_mass"] == [6.36, 7.12, 18.68, 0.189, 0.135, 0.222]
    assert s["linear_damping"] == [13.7, 0.0, 33.0, 0.0, 0.8, 0.0]
    assert s["quadratic_damping"] == [141.0, 217.0, 190.0, 1.19, 0.47, 1.5]
    # T200 at 16 V: 5.25 kgf forward, 4.10 kgf reverse; mean per-thruster limit
    t = 0.5 * (5.25 + 4.10) * G0
    arm = (0.156 + 0.111) * math.sin(math.pi / 4)
    want = [4 * t * math.cos(math.pi / 4)] * 2 + [4 * t, 4 * t * 0.218, 4 * t * 0.120,
                                                 4 * t * arm]
    np.testing.assert_allclose(s["thrust_max"], want, atol=0.06)
    assert s["thrust_coupling"] == [1, 1]
    # buoyancy: 0.0134 m3 of sea water (1025 kg/m3) minus the weight
    assert s["net_buoyancy_n"] == pytest.approx(1025 * 9.81 * 0.0134 - 13.5 * 9.81, abs=0.01)


def test_rov_top_speeds_follow_thrust_vs_drag(rov):
    # surge: 141 u^2 + 13.7 u = 129.7 N -> 0.91 m/s, above the 0.85 m/s limit, which it holds;
    # sway: 217 v^2 = 129.7 N -> 0.773 m/s (commanded 0.85 sideways, heading held)
    x_max, y_max = rov.spec["thrust_max"][:2]
    u_top = (-13.7 + math.sqrt(13.7 ** 2 + 4 * 141.0 * x_max)) / (2 * 141.0)
    assert u_top == pytest.approx(0.912, abs=1e-3) and u_top > rov.v_max
    st, _ = run(rov, "6dof", lambda k: (0.0, 0.0, 0.85), 40)
    assert st[-1, D.U] == pytest.approx(0.85, abs=1e-6)
    st, tr = run(rov, "6dof", lambda k: (0.85, 0.0, 0.0, 0.0), 40)
    assert st[-1, D.V] == pytest.approx(math.sqrt(y_max / 217.0), abs=1e-4)
    assert tr[-1, 1] == pytest.approx(y_max, rel=1e-9)  # sway thrust saturated
    assert heading_error(st[-1, D.PSI], 0.0)[0] < 1e-9
    st, _ = run(rov, "6dof", lambda k: (0.0, 0.85, 0.0), 40)  # heave holds 0.85 m/s down
    assert st[-1, D.VY] == pytest.approx(0.85, abs=1e-6)


def test_load_vehicle_reads_each_file_version_once_and_hands_out_copies(tmp_path):
    a = D.load_vehicle("remus100")
    a.spec["mass_kg"] = -1.0                 # a caller's change stays with the caller
    a.spec["thrust_max"][0] = -1.0
    b = D.load_vehicle("remus100")
    assert b.spec["mass_kg"] > 0 and b.spec["thrust_max"][0] > 0
    f = tmp_path / "vehicles.yaml"
    text = D.vehicles_file().read_text()
    f.write_text(text)
    v1 = D.load_vehicle("remus100", path=f).v_max
    doc = yaml.safe_load(f.read_text())
    doc["vehicles"]["remus100"]["speed_limit_ms"] = 0.5 * v1
    f.write_text(yaml.safe_dump(doc))        # a new version of the file is read again
    assert D.load_vehicle("remus100", path=f).v_max == pytest.approx(0.5 * v1)


def test_vehicle_validation():
    bad = {"lift_coefficients": [-28.6, 6.15, 40.0, -3.93, 0, 0, 0, 0]}
    with pytest.raises(ConfigError, match="not dissipative"):
        D.load_vehicle("remus100", overrides=bad)
    with pytest.raises(ConfigError, match="must have thrust_max 0"):
        D.load_vehicle("remus100", overrides={"thrust_max": [11, 0, 0, 0, 0, 5.0]})
    with pytest.raises(ConfigError, match="thrust_coupling"):
        D.load_vehicle("bluerov2_heavy", overrides={"thrust_coupling": [1, 0.5]})
    with pytest.raises(ConfigError, match="guidance.*'holonomic', 'torpedo'"):
        D.load_vehicle("bluerov2_heavy", overrides={"guidance": "glider"})
    with pytest.raises(ConfigError, match="velocity_time_constant_s"):
        D.load_vehicle("remus100", overrides={"velocity_time_constant_s": [1, 0, 0, 0, 0, 0]})


# ------------------------------------------------------- where 6dof must agree with kinematic


@pytest.mark.parametrize("name, lag_band", [("remus100", (10.0, 12.5)),
                                            ("bluerov2_heavy", (0.1, 0.4))])
def test_straight_run_at_the_speed_limit_matches_kinematic(name, lag_band):
    # still water, start at rest facing the goal, command v_max ahead: after the acceleration
    # transient the rigid body moves exactly like the kinematic model; it trails by a constant
    # lag = integral of (v_max - u) dt (REMUS: 11 N against 10.1 N of drag at 2.5 m/s)
    veh = D.load_vehicle(name)
    vmax = veh.v_max
    st, _ = run(veh, "6dof", lambda k: (0.0, 0.0, vmax), 60)
    kin, _ = run(veh, "kinematic", lambda k: (0.0, 0.0, vmax), 60)
    step = np.diff(st[:, D.Z])
    np.testing.assert_allclose(step[40:], vmax, atol=1e-4 * vmax)
    lag = kin[:, D.Z] - st[:, D.Z]
    assert lag_band[0] < lag[-1] < lag_band[1]
    assert abs(lag[-1] - lag[40]) < 1e-3
    np.testing.assert_allclose(st[-1, [D.X, D.Y]], kin[-1, [D.X, D.Y]], atol=1e-9)


# ------------------------------------------------------- where 6dof must differ: turning


def _remus_cruising(remus, speed=1.5):
    st, _ = run(remus, "6dof", lambda k: (0.0, 0.0, speed), 40)
    return st[-1]


def _steady_turn_rudder(veh, u, r):
    """Rudder moment that holds a steady turn (u, r) in still water, from the YAML
    coefficients alone (sway and yaw balance of the relative-velocity model at level trim)."""
    s, p = veh.spec, veh.params
    m11, m22 = p[D.P_M], p[D.P_M + 1]
    y_uv, y_ur, n_uv, n_ur = s["lift_coefficients"][:4]
    y_vv, n_rr = s["quadratic_damping"][1], s["quadratic_damping"][5]
    k_y = p[D.P_FINY]

    def rudder(v):
        return -(-(m22 - m11) * u * v + n_uv * u * v + n_ur * u * r - n_rr * r * abs(r))

    def sway(v):
        return -m11 * u * r + y_uv * u * v + y_ur * u * r - y_vv * v * abs(v) + k_y * rudder(v)

    lo, hi = -2.0, 2.0  # bisection on the sway balance
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if np.sign(sway(mid)) == np.sign(sway(lo)):
            lo = mid
        else:
            hi = mid
    return rudder(0.5 * (lo + hi))


def test_reversal_remus_turns_kinematic_and_rov_do_not(remus, rov):
    s0 = _remus_cruising(remus, 1.5)
    back = lambda k: (0.0, 0.0, -1.5)  # noqa: E731
    # kinematic: the velocity reverses within the step, no turn, no lateral excursion
    kin, _ = run(remus, "kinematic", back, 1, s=s0)
    assert kin[-1, D.VZ] == -1.5 and kin[-1, D.X] == s0[D.X]
    st, tr = run(remus, "6dof", back, 60, s=s0)
    u, r = st[:, D.U], st[:, D.R]
    # the autopilot turns at its smallest radius R = 5 m (yaw rate |u_r| / R) ...
    rmin = remus.spec["turn_radius_min_m"]
    turning = np.abs(r) > 0.95 * np.abs(r).max()
    assert turning.sum() >= 5
    np.testing.assert_allclose(u[turning] / np.abs(r[turning]), rmin, rtol=0.02)
    # ... which the rudder can hold: the moment it applies in the steady turn matches the
    # steady-turn balance of the coefficients (reverse rudder: the hull is unstable) and uses
    # 65 % of the fin authority 1.46 u^2 N m, leaving 35 % to end the turn
    k = np.flatnonzero(turning)[2]
    need = _steady_turn_rudder(remus, u[k], r[k])
    cap = remus.params[D.P_FINR] * u[k] ** 2
    assert tr[k - 1, 5] == pytest.approx(need, rel=0.02)
    assert 0.6 < abs(need) / cap < 0.7 and np.sign(need) == -np.sign(r[k])
    # time to point backwards (within 5 deg): at least half a circle at the limit rate,
    # pi R / u = 10.5 s, plus the roll-in and roll-out; the loop it flies is ~2R wide
    err = heading_error(st[:, D.PSI], math.pi)
    t_rev = next(i for i in range(len(err)) if err[i:].max() < math.radians(5))
    assert math.pi * rmin / 1.5 < t_rev < math.pi * rmin / 1.5 + 8
    assert 2 * rmin < np.ptp(st[:, D.X]) < 2.6 * rmin
    # the ROV reverses without turning (heading held): velocity reversed within 3 s
    r0, _ = run(rov, "6dof", lambda k: (0.0, 0.0, 0.5, 0.0), 20)
    st, _ = run(rov, "6dof", lambda k: (0.0, 0.0, -0.5, 0.0), 10, s=r0[-1])
    assert st[3, D.VZ] == pytest.approx(-0.5, abs=0.01)
    assert np.abs(st[:, D.PSI]).max() < 1e-9 and np.ptp(st[:, D.X]) < 1e-9


def test_sideways_command_rov_crabs_remus_must_yaw_first(remus, rov):
    # pure sideways (east) relative command while heading north
    s0 = _remus_cruising(remus, 1.5)
    side = lambda k: (1.5, 0.0, 0.0)  # noqa: E731
    kin, _ = run(remus, "kinematic", side, 3, s=s0)
    st, _ = run(remus, "6dof", side, 3, s=s0)
    lat_kin = kin[-1, D.X] - s0[D.X]
    lat = st[-1, D.X] - s0[D.X]
    assert lat_kin == pytest.approx(4.5)
    assert lat < 0.25 * lat_kin          # no sway thrust: it cannot crab ...
    assert math.degrees(st[-1, D.PSI]) > 25  # ... it yaws toward the command first
    assert np.abs(st[:, D.V]).max() < 0.3
    # the ROV, heading held, moves sideways nearly as the kinematic model does
    r0, _ = run(rov, "6dof", lambda k: (0.0, 0.0, 0.5, 0.0), 20)
    side = lambda k: (0.5, 0.0, 0.0, 0.0)  # noqa: E731
    kin, _ = run(rov, "kinematic", side, 5, s=r0[-1])
    st, _ = run(rov, "6dof", side, 5, s=r0[-1])
    assert st[-1, D.X] - r0[-1, D.X] > 0.85 * (kin[-1, D.X] - r0[-1, D.X])
    assert np.abs(st[:, D.PSI]).max() < 1e-9


def test_fin_authority_scales_with_speed_squared(remus, rov):
    # at rest the fins have no authority: a heading command changes nothing; the ROV turns
    st, tr = run(remus, "6dof", lambda k: (0.0, 0.0, 0.0, 1.0), 30)
    assert st[-1, D.PSI] == 0.0 and np.all(tr[:, 11] == 0.0)
    st, _ = run(rov, "6dof", lambda k: (0.0, 0.0, 0.0, 1.0), 30)
    assert st[-1, D.PSI] == pytest.approx(1.0, abs=1e-6)
    # cruising at u, a 90 deg heading command saturates the rudder at 1.46 u^2 N m
    moments = {}
    for speed in (0.5, 1.0, 2.0):
        s0 = _remus_cruising(remus, speed)
        ur = s0[D.U]
        _, tr = run(remus, "6dof", lambda k: (speed, 0.0, 0.0), 1, dt=0.2, s=s0)
        assert tr[0, 11] == pytest.approx(remus.params[D.P_FINR] * ur ** 2, rel=1e-12)
        assert abs(tr[0, 5]) == pytest.approx(tr[0, 11], rel=1e-12)
        moments[speed] = abs(tr[0, 5]) / ur ** 2
    assert moments[0.5] == pytest.approx(moments[2.0], rel=1e-9)
    assert moments[1.0] == pytest.approx(1.4598, abs=1e-4)


# ------------------------------------------------------- where 6dof must differ: speed loss


def test_rov_cross_current_saturates_coupled_thrust(rov):
    # heading held north in a 0.6 m/s eastward current; the command asks for 0.6 m/s west (to
    # stem the current) and 0.6 m/s north through the water (|a| = 0.85 = v_max): the kinematic
    # model goes straight north at 0.6 m/s. The group of four horizontal thrusters cannot
    # supply both (|a_x| + |a_y| = 0.39 + 0.60 > 1 at those speeds), so the ROV makes less
    # ground progress and is set east; independent (box) limits of the same size would not be
    cmd = lambda k: (-0.6, 0.0, 0.6, 0.0)  # noqa: E731
    kin, _ = run(rov, "kinematic", cmd, 60, ce=0.6)
    st, tr = run(rov, "6dof", cmd, 60, ce=0.6)
    load = np.abs(tr[-1, 0] / tr[-1, 6]) + np.abs(tr[-1, 1] / tr[-1, 7])
    assert load == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(kin[-1, D.VX:D.VZ + 1], [0.0, 0.0, 0.6], atol=1e-12)
    assert st[-1, D.VZ] < 0.59 and st[-1, D.VX] > 0.01  # slower north, set east
    assert kin[-1, D.Z] - st[-1, D.Z] > 1.0 and st[-1, D.X] - kin[-1, D.X] > 0.5
    assert np.abs(st[:, D.PSI]).max() < math.radians(1)
    box = D.load_vehicle("bluerov2_heavy", overrides={"thrust_coupling": [0, 0]})
    sb, _ = run(box, "6dof", cmd, 60, ce=0.6)
    np.testing.assert_allclose(sb[-1, D.VX:D.VZ + 1], kin[-1, D.VX:D.VZ + 1], atol=1e-4)


def test_remus_dives_only_with_forward_speed(remus):
    down = lambda k: (0.0, 0.5, 0.0)  # noqa: E731
    kin, _ = run(remus, "kinematic", down, 60)
    st, _ = run(remus, "6dof", down, 60)
    assert kin[3, D.Y] - 50.0 == pytest.approx(1.5)
    # from rest: no speed, no stern-plane authority, neutral trim -> no depth change at first
    assert abs(st[3, D.Y] - 50.0) < 0.01
    # a pure vertical 0.5 m/s command makes it swim forward at 0.5 m/s, where the planes can
    # barely pitch it against BG: it dives far slower than commanded, and only by moving
    assert st[-1, D.Y] - 50.0 < 0.1 * (kin[-1, D.Y] - 50.0)
    assert np.hypot(st[-1, D.X], st[-1, D.Z]) > 25.0
    # cruising, the same vertical rate is reached by pitching (angle of attack costs 5 %)
    st, _ = run(remus, "6dof", lambda k: (0.0, 0.5, 1.5), 90)
    assert math.degrees(st[-1, D.THETA]) == pytest.approx(-math.degrees(math.atan(0.5 / 1.5)),
                                                          abs=0.1)
    assert 0.45 < st[-1, D.VY] < 0.5
    # 3-DoF / 4-DoF torpedoes have no pitch: they cannot change depth at all
    for model in ("3dof", "4dof"):
        st, _ = run(remus, model, lambda k: (0.0, 0.5, 1.5), 30)
        assert st[-1, D.Y] == 50.0


# ------------------------------------------------------- invariants for every vehicle


@pytest.mark.parametrize("name", NEW)
@pytest.mark.parametrize("model", RIGID)
def test_actuator_forces_stay_within_limits(name, model):
    veh = D.load_vehicle(name)
    h = veh.spec["max_substep_s"]
    rng = np.random.default_rng(3)
    cmds = rng.uniform(-1.0, 1.0, (40, 3)) * veh.v_max
    cmds[:, 1] *= 0.3
    psis = np.where(rng.uniform(size=40) < 0.3, rng.uniform(-3, 3, 40), np.nan)
    m = D.model_id(model)
    s = D.new_state(1, 1, np.array([[[0.0, 40.0, 0.0]]]), 0.3)[0, 0]
    tr = np.zeros(D.TRACE_DIM)
    p = veh.params
    n_sat = 0
    for k in range(int(240 / h)):
        j = int(k * h) // 6
        a = D.clip_action(*cmds[j], veh.v_max)
        ce, cn = 0.4 * math.sin(0.01 * k), -0.3
        # the fin capacity of this (single) substep comes from u_r at its start
        ur = s[D.U] - (math.cos(s[D.THETA]) * math.cos(s[D.PSI]) * cn
                       + math.cos(s[D.THETA]) * math.sin(s[D.PSI]) * ce)
        D.step_agent_traced(m, p, s, np.array([*a, psis[j], 1.0]), ce, cn, h, tr)
        tau, cap = tr[:6], tr[6:12]
        assert np.all(np.abs(tau) <= cap * (1 + 1e-12) + 1e-12), (k, tau, cap)
        if name == "remus100":
            assert cap[5] == pytest.approx(p[D.P_FINR] * ur * ur, rel=1e-9, abs=1e-15)
            assert tr[12] == pytest.approx(p[D.P_FINY] * tau[5], rel=1e-12)
            assert np.all(tau[1:4] == 0.0)  # no sway, heave or roll actuator
        else:
            hl = sum(abs(tau[i]) / cap[i] for i in (0, 1) if cap[i] > 0)
            hl = max(hl, abs(tau[0]) / cap[0] + abs(tau[5]) / cap[5],
                     abs(tau[1]) / cap[1] + abs(tau[5]) / cap[5])
            assert hl <= 1 + 1e-12
            if model == "6dof":
                vl = max(abs(tau[2]) / cap[2] + abs(tau[3]) / cap[3],
                         abs(tau[2]) / cap[2] + abs(tau[4]) / cap[4],
                         abs(tau[3]) / cap[3] + abs(tau[4]) / cap[4])
                assert vl <= 1 + 1e-12
            n_sat += hl > 1 - 1e-9
        assert np.all(np.isfinite(s))
    if name == "bluerov2_heavy":
        assert n_sat > 10  # the coupled limit was exercised


def _mech_energy(model, vp, s, ce, cn):
    return D.kinetic_energy_rel(model, vp, s, ce, cn) + D.potential_energy(vp, s)


@pytest.mark.parametrize("name", NEW)
@pytest.mark.parametrize("model", RIGID)
@pytest.mark.parametrize("current", [(0.0, 0.0), (0.5, -0.2)])
def test_thrust_off_never_adds_energy(name, model, current):
    # lift and Munk terms included: with thrust off the mechanical energy relative to the
    # water never increases, at the benchmark dt and below
    veh = D.load_vehicle(name, overrides={"net_buoyancy_n": 1.0})
    vp = veh.params
    ce, cn = current
    s = np.zeros(D.STATE_DIM)
    s[D.Y] = 50.0
    s[D.PSI] = 0.3
    s[D.U:D.R + 1] = [1.5, -0.4, 0.3, 0.6, -0.3, 0.5]
    if model == "6dof":
        s[D.PHI], s[D.THETA] = 0.3, -0.2
    m = D.model_id(model)
    cmd = D.make_cmd(thrust=False)
    e0 = e_prev = _mech_energy(m, vp, s, ce, cn)
    for dt in [1.0] * 150 + [0.1] * 50:
        D.step_agent(m, vp, s, cmd, ce, cn, dt)
        e = _mech_energy(m, vp, s, ce, cn)
        assert e <= e_prev + 1e-12 * abs(e0), (e, e_prev)
        e_prev = e
    assert D.kinetic_energy_rel(m, vp, s, ce, cn) < 0.02 * D.kinetic_energy_rel(
        m, vp, np.r_[s[:6], [1.5, -0.4, 0.3, 0.6, -0.3, 0.5], s[12:]], ce, cn)


@pytest.mark.parametrize("name", D.vehicle_names())
def test_relative_motion_does_not_depend_on_a_uniform_current(name):
    # Fossen's relative-velocity equations are invariant to an irrotational constant current:
    # started with the same velocity relative to the water, a vehicle in a current c does
    # exactly what it does in still water, plus c t (the substeps carry nu_r; re-adding the
    # current of the pre-substep attitude to nu, as the engine used to, is not invariant)
    veh = D.load_vehicle(name)
    cmd = lambda k: (0.6 * veh.v_max * math.sin(0.05 * k), 0.05, 0.8 * veh.v_max)  # noqa: E731
    s0 = D.new_state(1, 1, np.array([[[0.0, 50.0, 0.0]]]), 0.0)[0, 0]
    still, _ = run(veh, "6dof", cmd, 80, s=s0)
    ce, cn = 0.35, -0.25
    s0[D.U], s0[D.V] = cn, ce  # heading north: at rest relative to the water
    moving, _ = run(veh, "6dof", cmd, 80, ce=ce, cn=cn, s=s0)
    t = np.arange(81.0)
    rel = moving[:, :3] - np.outer(t, [ce, 0.0, cn])
    np.testing.assert_allclose(rel, still[:, :3], atol=1e-8)
    np.testing.assert_allclose(moving[:, D.PHI:D.PSI + 1], still[:, D.PHI:D.PSI + 1], atol=1e-10)
    assert np.ptp(still[:, D.PSI]) > 0.3  # it did turn


def test_remus_substep_is_accurate_enough(remus):
    # from cruise: a 180 deg turn, then a dive: the 0.2 s substep stays within 1.5 m of a
    # 0.01 s solution over 90 s (the unstable sway-yaw mode grows at ~0.66 u_r s-1). Starts
    # with a large sideslip (e.g. at rest in a cross current) sit at the edge of the fins'
    # authority and are sensitive to any change, physical or numerical.
    fine = D.load_vehicle("remus100", overrides={"max_substep_s": 0.01})
    s0 = _remus_cruising(remus, 1.5)

    def cmd(k):
        return (0.0, 0.0, -1.5) if k < 45 else (0.0, 0.4, -1.5)

    a, _ = run(remus, "6dof", cmd, 90, s=s0)
    b, _ = run(fine, "6dof", cmd, 90, s=s0)
    assert np.linalg.norm(a[:, :3] - b[:, :3], axis=1).max() < 1.5
