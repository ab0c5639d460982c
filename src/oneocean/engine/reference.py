"""Plain-Python/NumPy reference of the engine: one agent, one step at a time.

Written independently of the kernels (index search with ``np.searchsorted``, full 6 x 6
matrices ``M``, ``C(nu)``, ``D(nu)`` and ``np.linalg.solve``) so that it serves two purposes:

* a correctness oracle: the tests check that the jitted engine reproduces it;
* the denominator of the benchmark's speed-up (the "plain per-step loop of the same model").

Only a proportional go-to-goal controller is implemented. Semantics per step are those of
the episode loop (:func:`oneocean.tasks.loop.run_episode` with
:func:`oneocean.engine.advance_agent`): current at the agent, clip, energy, dynamics,
feasibility, near-collisions.
"""

from __future__ import annotations

import math

import numpy as np

from . import dynamics as dyn
from . import status as st
from .grid import Grid

_ACTIVE = {dyn.DOF3: [0, 1, 5], dyn.DOF4: [0, 1, 2, 5], dyn.DOF6: [0, 1, 2, 3, 4, 5]}


def _axis(ax: np.ndarray, v: float) -> tuple[int, int, float]:
    n = ax.size
    if n == 1:
        return 0, 0, 0.0
    if v <= ax[0]:
        return 0, 1, 0.0
    if v >= ax[-1]:
        return n - 2, n - 1, 1.0
    i = int(np.searchsorted(ax, v, side="right")) - 1
    return i, i + 1, (v - ax[i]) / (ax[i + 1] - ax[i])


def _cell(grid: Grid, x: float, z: float) -> tuple[int, int, float, float]:
    fx = min(max((x - grid.x0) / grid.dx, 0.0), grid.nx - 1.0)
    fz = min(max((z - grid.z0) / grid.dz, 0.0), grid.ny - 1.0)
    i = min(int(math.floor(fx)), grid.nx - 2)
    j = min(int(math.floor(fz)), grid.ny - 2)
    return i, j, fx - i, fz - j


def current(grid: Grid, x: float, y: float, z: float, t: float) -> tuple[float, float]:
    """Current at a world position and time, as :func:`oneocean.engine.grid.sample_current`.

    Parameters
    ----------
    grid : Grid
        The grid export.
    x, y, z : float
        World position (east, depth positive down, north), m.
    t : float
        Time, s since ``time0_unix_s``.

    Returns
    -------
    tuple of float
        ``(ce, cn)``: current east and north, m s-1.
    """
    i, j, wx, wz = _cell(grid, x, z)
    w2 = np.array([[(1 - wz) * (1 - wx), (1 - wz) * wx], [wz * (1 - wx), wz * wx]])
    # only nodes with currents count: renormalised by their share (>= 1/2), fading below it
    share = float(np.sum(w2 * grid.current_mask[j:j + 2, i:i + 2]))
    w2 = w2 / max(share, 0.5)
    k0, k1, wk = _axis(grid.depth, y)
    t0, t1, wt = _axis(grid.time_s, t)
    out = np.zeros(2)
    tide = np.zeros(2)
    for ti, a in ((t0, 1 - wt), (t1, wt)):
        for ki, b in ((k0, 1 - wk), (k1, wk)):
            block = grid.uv[ti, ki, j:j + 2, i:i + 2, :].astype(np.float64)
            out += a * b * np.einsum("ab,abc->c", w2, block)
        if grid.tide_layers:
            block = grid.uv_tide[ti, j:j + 2, i:i + 2, :].astype(np.float64)
            tide += a * np.einsum("ab,abc->c", w2, block)
    out = grid.gain * out + tide            # paper eq. 1: g scales u, v only
    if grid.tide_amp != 0.0:
        ph = grid.tide_omega * t + grid.tide_phase
        out += grid.tide_amp * np.array([math.sin(ph), math.cos(ph)])
    return float(out[0]), float(out[1])


def feasible(grid: Grid, x, y, z, land_threshold, clearance) -> int:
    """Status code of a position, as :func:`oneocean.engine.constraints.check_move`.

    Parameters
    ----------
    grid : Grid
        The grid export.
    x, y, z : float
        Position, m (x east, y depth positive down, z north).
    land_threshold : float
        Rejection threshold on the bilinearly sampled land mask (0..1).
    clearance : float
        Required distance above the seafloor, m.

    Returns
    -------
    int
        Status code (:mod:`oneocean.engine.status`).
    """
    if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
        return st.NONFINITE
    if x < grid.x0 or x > grid.x_max or z < grid.z0 or z > grid.z_max or y < 0:
        return st.OUTSIDE
    i, j, wx, wz = _cell(grid, x, z)
    w2 = np.array([[(1 - wz) * (1 - wx), (1 - wz) * wx], [wz * (1 - wx), wz * wx]])
    land = float(np.sum(w2 * grid.land[j:j + 2, i:i + 2]))
    elev = float(np.sum(w2 * grid.elevation[j:j + 2, i:i + 2]))
    if land >= land_threshold:
        return st.LAND
    if y + clearance > -elev:
        return st.SEAFLOOR
    return st.OK


def rotation(phi: float, theta: float, psi: float) -> np.ndarray:
    """Fossen zyx rotation matrix, body to NED.

    Parameters
    ----------
    phi, theta, psi : float
        Roll, pitch and yaw (compass heading), rad.

    Returns
    -------
    (3, 3) float64
        ``R`` with ``v_ned = R v_body``.
    """
    cf, sf, ct, s_t, cp, sp = (math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta),
                               math.cos(psi), math.sin(psi))
    return np.array([[cp * ct, -sp * cf + cp * s_t * sf, sp * sf + cp * cf * s_t],
                     [sp * ct, cp * cf + sf * s_t * sp, -cp * sf + s_t * sp * cf],
                     [-s_t, ct * sf, ct * cf]])


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def coriolis(mass: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Kirchhoff Coriolis-centripetal matrix of a diagonal mass matrix.

    Parameters
    ----------
    mass : (6,) float64
        Diagonal of ``M = M_RB + M_A`` (kg for surge/sway/heave, kg m2 for roll/pitch/yaw).
    nu : (6,) float64
        Body velocity ``(u, v, w, p, q, r)``, m s-1 and rad s-1.

    Returns
    -------
    (6, 6) float64
        ``C(nu)``, skew-symmetric.
    """
    a = mass[:3] * nu[:3]
    b = mass[3:] * nu[3:]
    c = np.zeros((6, 6))
    c[:3, 3:] = -_skew(a)
    c[3:, :3] = -_skew(a)
    c[3:, 3:] = -_skew(b)
    return c


def step(model: int, vp: np.ndarray, s: np.ndarray, cmd: np.ndarray, ce: float, cn: float,
         dt: float) -> None:
    """One step of one agent, in place (same scheme as ``dynamics.step_agent``).

    It covers the kinematic model and the rigid-body models of holonomic vehicles with box
    thrust limits: no lift, fins, coupled thruster groups or turn-radius limit.

    Parameters
    ----------
    model : int
        Dynamics model id (``KINEMATIC``, ``DOF3``, ``DOF4``, ``DOF6``).
    vp : (PARAM_DIM,) float64
        Vehicle parameters (:func:`oneocean.engine.dynamics.vehicle_params`).
    s : (STATE_DIM,) float64
        Agent state, modified in place.
    cmd : (CMD_DIM,) float64
        ``[ax, ay, az, psi_cmd, thrust]``; the velocity must already be clipped.
    ce, cn : float
        Current (east, north) at the agent, m s-1, frozen over the step.
    dt : float
        Step, s.
    """
    if model == dyn.KINEMATIC:
        a = cmd[:3] if cmd[4] != 0 else np.zeros(3)
        v = a + np.array([ce, 0.0, cn])
        s[0:3] = s[0:3] + v * dt
        s[12:15] = v
        if s[1] < 0:
            s[1] = 0.0
            s[13] = max(s[13], 0.0)
        return
    mass = vp[dyn.P_M:dyn.P_M + 6]
    dl = vp[dyn.P_DL:dyn.P_DL + 6]
    dq = vp[dyn.P_DQ:dyn.P_DQ + 6]
    tmax = vp[dyn.P_TMAX:dyn.P_TMAX + 6]
    kgain = vp[dyn.P_K:dyn.P_K + 6]
    wb, bgb = vp[dyn.P_WB], vp[dyn.P_BGB]
    act = _ACTIVE[model]
    six = model == dyn.DOF6
    heave = model != dyn.DOF3
    thrust = cmd[4] != 0
    n_sub = max(int(math.ceil(dt / vp[dyn.P_HMAX] - 1e-9)), 1)
    h = dt / n_sub
    a_ned = np.array([cmd[2], cmd[0], cmd[1] if heave else 0.0])
    if cmd[3] == cmd[3]:
        s[15] = cmd[3]
    elif thrust and a_ned[0] ** 2 + a_ned[1] ** 2 >= vp[dyn.P_VYAW] ** 2:
        s[15] = math.atan2(a_ned[1], a_ned[0])
    eta = np.array([s[2], s[0], s[1], s[3], s[4], s[5]])  # NED position, attitude
    nu = s[6:12].copy()
    if not six:
        eta[3:5] = 0.0
        nu[3:5] = 0.0
    if not heave:
        nu[2] = 0.0
    v_c = np.array([cn, ce, 0.0])
    rmat = np.eye(3)
    for _ in range(n_sub):
        phi, th, psi = eta[3:]
        rmat = rotation(phi, th, psi)
        nu_c = np.concatenate([rmat.T @ v_c, np.zeros(3)])
        nu_r = nu - nu_c
        c_lin = rmat.T @ a_ned
        err = (s[15] - psi + math.pi) % (2 * math.pi) - math.pi
        rm = vp[dyn.P_RMAX]
        katt = vp[dyn.P_KATT]
        rates = np.clip([-katt * phi, -katt * th, vp[dyn.P_KPSI] * err], -rm, rm)
        cvec = np.concatenate([c_lin, rates])
        g = np.array([wb * math.sin(th), -wb * math.cos(th) * math.sin(phi),
                      -wb * math.cos(th) * math.cos(phi), bgb * math.cos(th) * math.sin(phi),
                      bgb * math.sin(th), 0.0])
        cmat = coriolis(mass, nu_r)
        # feed-forward without C: a thruster's controller cancels its row of C(nu_r,k) at the
        # new velocities (the row's coupling terms are dropped from the implicit system)
        ff = (dl + dq * np.abs(nu_r)) * cvec + g
        a_base = np.diag(mass + h * (dl + dq * np.abs(nu_r))) + h * cmat
        kst = h * h * bgb * math.cos(th) * math.cos(phi)
        if six and kst > 0:
            a_base[3, 3] += kst
            a_base[4, 4] += kst
        b_base = mass * nu_r - h * g
        sat = {}
        for _pass in range(7):
            amat = a_base.copy()
            bvec = b_base.copy()
            for i in act:
                if thrust and tmax[i] > 0:
                    if i in sat:
                        bvec[i] += h * sat[i]
                    else:
                        diag = amat[i, i]
                        amat[i, :] = 0.0
                        amat[i, i] = diag + h * kgain[i]
                        bvec[i] += h * (ff[i] + kgain[i] * cvec[i])
            x = np.zeros(6)
            x[act] = np.linalg.solve(amat[np.ix_(act, act)], bvec[act])
            if not thrust:
                break
            new = False
            for i in act:
                if tmax[i] > 0 and i not in sat:
                    tau = ff[i] + cmat[i] @ x + kgain[i] * (cvec[i] - x[i])
                    if abs(tau) > tmax[i]:
                        sat[i] = math.copysign(tmax[i], tau)
                        new = True
            if not new:
                break
        # over ground = R nu_r + v_c; the relative velocity carries over to the next substep
        # (its equation does not depend on a uniform current: Fossen 2011, Property 10.1)
        eta[:3] += h * (rmat @ x[:3] + v_c)
        nu = x
        if not heave:
            eta[2] = s[1]
        if six:
            p, q, r = nu[3:]
            eta[3] += h * (p + math.sin(phi) * math.tan(th) * q + math.cos(phi) * math.tan(th) * r)
            eta[4] += h * (math.cos(phi) * q - math.sin(phi) * r)
            eta[5] += h * (math.sin(phi) * q + math.cos(phi) * r) / math.cos(th)
        else:
            eta[5] += h * nu[5]
        eta[5] = (eta[5] + math.pi) % (2 * math.pi) - math.pi
        rmat = rotation(*eta[3:])
        nu = x + np.concatenate([rmat.T @ v_c, np.zeros(3)])
        if not heave:
            nu[2] = 0.0
    v_world_ned = rmat @ nu[:3]
    s[0], s[1], s[2] = eta[1], eta[2], eta[0]
    s[3:6] = eta[3:]
    s[6:12] = nu
    s[12], s[13], s[14] = v_world_ned[1], v_world_ned[2], v_world_ned[0]
    if s[1] < 0:
        vd = s[13]
        s[1] = 0.0
        if vd < 0:
            s[13] = 0.0
            s[6:9] = nu[:3] - vd * rmat[2, :]


def reference_run(grid: Grid, positions, goals, steps: int, *, dynamics: str = "kinematic",
                  vehicle: dyn.Vehicle | None = None, dt: float = 1.0, kp: float = 0.3,
                  feedforward: bool = True, thrust: bool = True, v_max: float | None = None,
                  land_threshold: float = 0.5, clearance: float = 1.0, r_coll: float = 2.0,
                  t0: float = 0.0, heading: float = 0.0) -> dict:
    """Roll out a proportional go-to-goal controller with a per-step Python loop.

    The action is ``kp (goal - p)``, minus the current at the agent when ``feedforward``,
    clipped to ``v_max``. Every agent starts at rest.

    Parameters
    ----------
    grid : Grid
        The grid export.
    positions : array_like
        (E, N, 3) start positions ``[x, y, z]``, m (E episodes, N agents).
    goals : array_like
        (E, N, 3) goal positions, m, or (E, N, 4) with a heading command (rad, NaN = free) in
        the last column.
    steps : int
        Number of steps per episode.
    dynamics : str, default "kinematic"
        Dynamics model name (:data:`oneocean.vocab.DYNAMICS`).
    vehicle : Vehicle, optional
        Vehicle; default: :func:`~oneocean.engine.dynamics.load_vehicle`'s default.
    dt : float, default 1.0
        Step, s.
    kp : float, default 0.3
        Proportional gain, s-1.
    feedforward : bool, default True
        Subtract the current at the agent from the action.
    thrust : bool, default True
        Controller on; False: unactuated drift (no energy).
    v_max : float, optional
        Speed limit, m s-1; default: the vehicle's.
    land_threshold : float, default 0.5
        Rejection threshold on the sampled land mask (0..1).
    clearance : float, default 1.0
        Required distance above the seafloor, m.
    r_coll : float, default 2.0
        Near-collision distance, m: a step counts when the closest pair is within it.
    t0 : float, default 0.0
        Time of step 0, s since ``time0_unix_s``.
    heading : float or array_like, default 0.0
        Initial heading, rad (scalar or (E, N)).

    Returns
    -------
    dict
        ``"state"`` (E, N, STATE_DIM) final states, ``"energy"`` (E, N) ``sum ||a||^2 dt``
        (m2 s-1), ``"violations"`` (E, N) rejected moves, ``"status"`` (E, N) int64 status of
        the last step and ``"coll_steps"`` (E,) near-collision steps.
    """
    model = dyn.model_id(dynamics)
    veh = vehicle if vehicle is not None else dyn.load_vehicle()
    vp = veh.params
    vmax = veh.v_max if v_max is None else float(v_max)
    pos = np.asarray(positions, dtype=np.float64)
    goal = np.asarray(goals, dtype=np.float64)
    if goal.shape[-1] == 3:
        goal = np.concatenate([goal, np.full(goal.shape[:-1] + (1,), np.nan)], axis=-1)
    e_n, a_n = pos.shape[:2]
    state = dyn.new_state(e_n, a_n, pos, heading)
    energy = np.zeros((e_n, a_n))
    viol = np.zeros((e_n, a_n), dtype=np.int64)
    status = np.zeros((e_n, a_n), dtype=np.int64)
    coll = np.zeros(e_n, dtype=np.int64)
    for e in range(e_n):
        for k in range(steps):
            t = t0 + k * dt
            for a in range(a_n):
                s = state[e, a]
                p0 = s[:3].copy()
                ce, cn = current(grid, *p0, t)
                act = kp * (goal[e, a, :3] - p0)
                if feedforward:
                    act = act - np.array([ce, 0.0, cn])
                norm = float(np.sqrt(act @ act))
                if norm > vmax:
                    act = act * (vmax / norm)
                cmd = np.array([act[0], act[1], act[2], goal[e, a, 3], 1.0 if thrust else 0.0])
                if thrust:
                    energy[e, a] += float(act @ act) * dt
                step(model, vp, s, cmd, ce, cn, dt)
                code = feasible(grid, s[0], s[1], s[2], land_threshold, clearance)
                if code != st.OK:
                    s[:3] = p0
                    s[6:9] = 0.0
                    s[12:15] = 0.0
                    viol[e, a] += 1
                status[e, a] = code
            if a_n > 1:
                p = state[e, :, :3]
                d = np.sqrt(((p[:, None, :] - p[None, :, :]) ** 2).sum(-1))
                d[np.diag_indices(a_n)] = np.inf
                if d.min() <= r_coll:
                    coll[e] += 1
    return {"state": state, "energy": energy, "violations": viol, "status": status,
            "coll_steps": coll}
