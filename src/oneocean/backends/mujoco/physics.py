"""The physics step of the scene backend: vehicles as MuJoCo rigid bodies.

:class:`ScenePhysics` replaces the core's :func:`oneocean.engine.step.advance_agent` for the
MuJoCo backend. One compiled model (scene + one vehicle, :func:`.mjcf.build_model`) is copied
into a pool; each copy is configured for the vehicle it advances, so each vehicle has its own
current (the true current at that vehicle, frozen over the control step, entering through its
damper controls) and its own fin authority. Vehicles do not interact (no vehicle-vehicle
contacts; the tasks count near-collisions geometrically). The core state array is the only
state: every step starts from it (core -> MuJoCo mapping of :mod:`.mjcf`) and writes the
result back, so a caller that edits a row (e.g. a rejected move) is honoured.

A control step ``dt`` is split into control periods (``control_period``, default 0.2 s, the
core's largest substep for REMUS) of ``n`` MuJoCo steps each. At the start of every period the
guidance of the core (:mod:`oneocean.engine.dynamics` header) is evaluated from the MuJoCo
state and gives the velocity-servo setpoints, held over the period (zero-order hold; the servos
themselves act every MuJoCo step):

* heading reference ``psi_ref`` (once per step, as the core): the explicit heading command, or
  the direction of the commanded horizontal velocity when it exceeds ``heading_min_speed_ms``
  (thrust on), else held;
* holonomic (ROV): body image of the commanded relative velocity; roll/pitch rate commands
  ``-k_att phi``, ``-k_att theta``; yaw rate ``clip(k_psi wrap(psi_ref - psi), +-r_max)``;
* torpedo (REMUS): surge = commanded relative speed (body-x projection when a heading is
  commanded); pitch rate toward ``atan2(-a_down, |a_h|)`` (limited to ``pitch_max_deg``); yaw
  rate as above, also limited to ``|u_r| / turn_radius_min_m``; fin force ranges
  ``|N_uudr| u_r^2 delta_max`` (rudder) and ``|M_uuds| u_r^2 delta_max`` (stern planes) from
  the relative surge speed ``u_r`` at the period's start.

MuJoCo's servo regulates the body velocity over ground, so a translational setpoint is the
commanded relative velocity ``c`` plus the current's body-frame projection; every setpoint
also carries the core controller's feed-forward divided by ``kv``: the damping
``(D_l + D_q |nu_r|) c`` at the period's relative velocity and, in roll and pitch, the
restoring moment ``W BG (cos theta sin phi, sin theta)``. The servo force is then the core's
``tau = D(nu_r) c + g(eta) + kv (c - nu_r)`` (without the core's Coriolis and lift
cancellation), and at steady state the speed through the water equals the command. Thrust off
(``cmd[4] == 0``) sets every servo's force range to 0 (unactuated drift).

Drag: at the start of every period each damper actuator (:mod:`.mjcf`) gets the coefficient
``d_i = D_l,i + D_q,i |nu_r,i|`` of the current relative velocity and, as its control, the
current's body-frame projection (translations; 0 for rotations): the force ``-d_i (nu_i -
nu_c,i)`` acts on the velocity relative to the water, implicitly integrated.

Simulation: :func:`mujoco.rollout.rollout` over the live vehicles in batches of the model pool
(``max_models``), one thread and no thread pool (bit-identical results whatever the thread
settings), control held per period. Rollout and a Python loop of ``mj_step`` measured the same
within 5 % (physics only, 8 BlueROV2: ~800 vs ~760 simulated s per wall s on one core);
rollout is kept for its single C call per period and batch. Contacts: a
``contact`` sensor counts the hull's contacts with the seafloor or a structure every MuJoCo step;
a step with any contact returns :data:`CONTACT`.
"""

from __future__ import annotations

import copy
import math

import numpy as np

from ...engine import dynamics as dyn
from ...engine import status as st
from ...errors import ConfigError
from . import mjcf
from ...engine import libm

__all__ = ["ScenePhysics", "CONTACT"]

#: Status code of a step during which the vehicle touched the seafloor or a structure (the
#: move is kept: MuJoCo resolved the contact): :data:`oneocean.engine.status.CONTACT` (13).
CONTACT = st.CONTACT

_SIGN6 = np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])  # FRD <-> FLU per DOF


def _wrap(a):
    """Wrap angles (rad) to [-pi, pi) (the core's convention)."""
    return a - 2.0 * math.pi * np.floor((a + math.pi) / (2.0 * math.pi))


class ScenePhysics:
    """Vehicles of ``n_episodes x n_agents`` as MuJoCo rigid bodies in one scene.

    Parameters
    ----------
    scene : Scene
        The scene (:class:`oneocean.backends.mujoco.scenes.Scene`).
    vehicle : str, Vehicle or VehicleModel
        The vehicle (:func:`oneocean.backends.mujoco.mjcf.vehicle_model`).
    n_episodes, n_agents : int
        Number of episodes E and agents per episode N (>= 1 each).
    dt : float, default 1.0
        Control step, s (a whole number of ``timestep``).
    timestep : float, default 0.02
        MuJoCo step, s.
    control_period : float, default 0.2
        Longest period of the guidance update inside a step, s (the step is split into the
        fewest equal periods of whole MuJoCo steps that are no longer; at most one MuJoCo
        step). 0: once per step.
    max_models : int, default 64
        Size of the pool of compiled model copies (memory ~1.6 MB each for a 101 x 101
        heightfield); vehicles are advanced in batches of this size.

    Attributes
    ----------
    contacts : (E, N) int64
        Cumulative MuJoCo steps in contact, per vehicle.
    force_ratio : (E, N, n_servo) float
        Largest ``|servo force| / force limit`` over the last step's MuJoCo steps (actuator
        order of :data:`.mjcf.ACTUATORS`; ``inf`` if a servo pushed with a zero limit); <= 1
        when the limits hold.
    models : list of mujoco.MjModel
        The pool of model copies; before each rollout, copy ``j`` of a batch is configured for
        the vehicle it advances (servo force ranges, damper coefficients), so a vehicle's
        parameters (its current, its fin authority) are its own.
    vm : mjcf.VehicleModel
        The vehicle's MuJoCo parameters.

    Raises
    ------
    ConfigError
        If E or N is below 1, ``dt`` is not a whole number of ``timestep``, or the compiled
        model is not one free body.
    """

    def __init__(self, scene, vehicle, n_episodes: int, n_agents: int, *, dt: float = 1.0,
                 timestep: float = 0.02, control_period: float = 0.2, max_models: int = 64):
        mujoco = mjcf.import_mujoco()
        self.E, self.N = int(n_episodes), int(n_agents)
        if self.E < 1 or self.N < 1:
            raise ConfigError(f"ScenePhysics: need >= 1 episode and agent, got {self.E} x {self.N}")
        nsub = int(round(dt / timestep))
        if nsub < 1 or abs(nsub * timestep - dt) > 1e-9 * max(1.0, dt):
            raise ConfigError(f"ScenePhysics: dt {dt!r} s must be a whole number of timesteps "
                              f"({timestep!r} s)")
        want = max(1, math.ceil(dt / control_period - 1e-9)) if control_period > 0 else 1
        # the fewest periods per step that are no longer than `control_period` and divide it
        nchunk = min(d for d in range(1, nsub + 1) if nsub % d == 0 and d >= min(want, nsub))
        self.dt, self.timestep, self.nsub = float(dt), float(timestep), nsub
        self.nchunk, self.chunk_steps = nchunk, nsub // nchunk
        model, vm = mjcf.build_model(scene, vehicle, timestep=timestep)
        self.vm = vm
        self.model = model
        npool = max(1, min(self.E * self.N, int(max_models)))
        self.models = [copy.deepcopy(model) for _ in range(npool)]
        self.data = mujoco.MjData(model)
        self._spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
        self.nstate = mujoco.mj_stateSize(model, self._spec)
        if model.nq != 7 or model.nv != 6 or self.nstate != 1 + model.nq + model.nv:
            raise ConfigError("ScenePhysics: unexpected model layout (one free body expected)")
        self.nu = model.nu
        from mujoco import rollout

        self._rollout = rollout.rollout
        p = vm.vehicle.params
        self._kpsi, self._rmax = float(p[dyn.P_KPSI]), float(p[dyn.P_RMAX])
        self._katt, self._vyaw = float(p[dyn.P_KATT]), float(p[dyn.P_VYAW])
        self._pmax, self._rturn = float(p[dyn.P_PMAX]), float(p[dyn.P_RTURN])
        self._torpedo = vm.guidance == "torpedo"
        self._dofs = np.array([d for _, d in vm.actuators])
        self._kv = vm.kv[self._dofs]
        self._dl = vm.damping_linear.copy()
        self._dq = vm.damping_quadratic.copy()
        self.n_servo = len(self._dofs)
        self._wbg = vm.mass * vm.gravity * vm.bg  # restoring coefficient W BG, N m
        self._cap = np.array([vm.thrust_max[d] for d in self._dofs])
        self.contacts = np.zeros((self.E, self.N), dtype=np.int64)
        self.force_ratio = np.zeros((self.E, self.N, self.n_servo))

    # ------------------------------------------------------------------ conversions

    def _to_mj(self, s: np.ndarray) -> np.ndarray:
        """FULLPHYSICS states (K, nstate) of core states (K, STATE_DIM)."""
        k = s.shape[0]
        out = np.zeros((k, self.nstate))
        out[:, 1:4] = mjcf.core_to_mj(s[:, 0:3])
        rot = mjcf.euler_to_matrix(s[:, dyn.PHI], s[:, dyn.THETA], s[:, dyn.PSI])
        out[:, 4:8] = mjcf._mat_to_quat(rot)
        out[:, 8:14] = mjcf.core_to_mj_velocity(rot, s[:, dyn.U:dyn.R + 1])
        return out

    def _to_core(self, ms: np.ndarray, s: np.ndarray) -> None:
        """Write MuJoCo states (K, nstate) into core rows ``s`` (K, STATE_DIM) (psi_ref kept)."""
        s[:, 0:3] = mjcf.mj_to_core(ms[:, 1:4])
        rot = mjcf.quat_to_matrix(ms[:, 4:8])
        phi, th, psi = mjcf.quat_to_euler(ms[:, 4:8])
        s[:, dyn.PHI], s[:, dyn.THETA], s[:, dyn.PSI] = phi, th, _wrap(psi)
        vw = ms[:, 8:11]
        vb = np.einsum("kji,kj->ki", rot, vw)  # R^T v
        s[:, dyn.U:dyn.W + 1] = vb * _SIGN6[:3]
        s[:, dyn.P:dyn.R + 1] = ms[:, 11:14] * _SIGN6[3:]
        s[:, dyn.VX] = vw[:, 0]
        s[:, dyn.VY] = -vw[:, 2]
        s[:, dyn.VZ] = vw[:, 1]

    # ------------------------------------------------------------------ API

    def reset(self, state: np.ndarray) -> None:
        """Start episodes from core states; clears the contacts.

        Each step reads the poses and velocities from the state it is given, so this only
        validates the layout and zeroes :attr:`contacts`.

        Parameters
        ----------
        state : (E, N, STATE_DIM) float64
            Core vehicle states (:mod:`oneocean.engine.dynamics`).

        Raises
        ------
        ConfigError
            If ``state`` has the wrong shape or a non-finite pose or velocity.
        """
        state = np.asarray(state)
        if state.shape != (self.E, self.N, dyn.STATE_DIM):
            raise ConfigError(f"ScenePhysics.reset: state shape {state.shape}, expected "
                              f"({self.E}, {self.N}, {dyn.STATE_DIM})")
        if not np.all(np.isfinite(state[..., :dyn.VZ + 1])):
            raise ConfigError("ScenePhysics.reset: non-finite state")
        self.contacts[:] = 0

    def step(self, state: np.ndarray, cmd: np.ndarray, current: np.ndarray,
             live: np.ndarray | None = None) -> np.ndarray:
        """Advance the live episodes by ``dt``, in place.

        Parameters
        ----------
        state : (E, N, STATE_DIM) float64
            Core states; rows of live episodes are overwritten with the new state (position,
            attitude, body velocity over ground, world ground velocity, heading reference).
        cmd : (E, N, CMD_DIM) float64
            Command rows ``[ax, ay, az, psi_cmd, thrust]`` (relative to the water, world
            m s-1, already clipped to ``v_max``).
        current : (E, N, 2) float64
            True current (east, north) m s-1 at each agent, frozen over the step.
        live : (E,) bool, optional
            Episodes that advance (default all); the others are untouched.

        Returns
        -------
        codes : (E, N) int64
            ``oneocean.engine.status.OK``, :data:`CONTACT` (touched the seafloor or a
            structure during the step) or ``NONFINITE`` (state kept, velocities zeroed).

        Raises
        ------
        ConfigError
            If the shapes of ``state``, ``cmd`` or ``current`` do not match (E, N).
        """
        E, N = self.E, self.N
        if state.shape != (E, N, dyn.STATE_DIM) or cmd.shape != (E, N, dyn.CMD_DIM) \
                or current.shape != (E, N, 2):
            raise ConfigError(f"ScenePhysics.step: shapes state {state.shape}, cmd {cmd.shape}, "
                              f"current {current.shape} do not match ({E}, {N})")
        codes = np.zeros((E, N), dtype=np.int64)
        ep = np.arange(E) if live is None else np.flatnonzero(np.asarray(live, dtype=bool))
        if ep.size == 0:
            return codes
        flat = (ep[:, None] * N + np.arange(N)[None, :]).ravel()
        s = state.reshape(E * N, dyn.STATE_DIM)[flat].copy()
        c = cmd.reshape(E * N, dyn.CMD_DIM)[flat]
        cur = current.reshape(E * N, 2)[flat]
        thrust = c[:, dyn.C_THRUST] != 0.0
        # the command of an unactuated vehicle is not used (and may be anything)
        a = np.where(thrust[:, None] & np.isfinite(c[:, :3]), c[:, :3], 0.0)
        ae, ad, an = a[:, 0], a[:, 1], a[:, 2]
        ah = np.hypot(ae, an)
        psi_free = np.isnan(c[:, dyn.C_PSI])
        psi_ref = s[:, dyn.PSI_REF].copy()
        psi_ref = np.where(np.isfinite(psi_ref), psi_ref, s[:, dyn.PSI])  # unset: hold heading
        upd = psi_free & thrust & (ah * ah >= self._vyaw * self._vyaw)
        psi_ref = np.where(~psi_free, c[:, dyn.C_PSI], np.where(upd, libm.arctan2(ae, an), psi_ref))
        s[:, dyn.PSI_REF] = psi_ref
        spd = np.sqrt(ah * ah + ad * ad)
        th_ref = np.zeros_like(spd)
        if self._pmax > 0:
            th_ref = np.clip(libm.arctan2(-ad, ah), -self._pmax, self._pmax)
        a_mj = np.stack([ae, an, -ad], axis=1)
        cur_mj = np.stack([cur[:, 0], cur[:, 1], np.zeros(len(flat))], axis=1)
        ms = self._to_mj(s)
        K = len(flat)
        hits = np.zeros(K, dtype=np.int64)
        ratio = np.zeros((K, self.n_servo))
        pool = len(self.models)
        for b0 in range(0, K, pool):  # batches of at most `max_models` vehicles
            sl = slice(b0, min(K, b0 + pool))
            nb = sl.stop - sl.start
            models = self.models[:nb]
            msb = ms[sl]
            sens = np.empty((nb, self.chunk_steps, 1 + self.n_servo))
            traj = np.empty((nb, self.chunk_steps, self.nstate))
            for _ in range(self.nchunk):
                ctrl, cap = self._guidance(msb, a_mj[sl], cur_mj[sl], spd[sl], psi_free[sl],
                                           psi_ref[sl], th_ref[sl], thrust[sl], models)
                self._rollout(models, [self.data], msb, ctrl[:, None, :],
                              nstep=self.chunk_steps, state=traj, sensordata=sens,
                              persistent_pool=False)
                msb = traj[:, -1, :].copy()
                hits[sl] += (sens[:, :, 0] > 0).sum(axis=1)
                frc = np.abs(sens[:, :, 1:]).max(axis=1)
                ratio[sl] = np.maximum(ratio[sl], np.where(
                    cap > 0, frc / np.where(cap > 0, cap, 1.0), np.where(frc > 0, np.inf, 0.0)))
            ms[sl] = msb
        ms[:, 0] = 0.0
        self._to_core(ms, s)
        bad = ~np.all(np.isfinite(s), axis=1)
        out_codes = np.where(hits > 0, CONTACT, st.OK)
        if bad.any():
            old = state.reshape(E * N, dyn.STATE_DIM)[flat][bad]
            old[:, dyn.U:dyn.W + 1] = 0.0
            old[:, dyn.VX:dyn.VZ + 1] = 0.0
            s[bad] = old
            out_codes[bad] = st.NONFINITE
        state.reshape(E * N, dyn.STATE_DIM)[flat] = s
        codes.reshape(-1)[flat] = out_codes
        self.contacts.reshape(-1)[flat] += hits
        self.force_ratio.reshape(-1, self.n_servo)[flat] = ratio
        return codes

    # ------------------------------------------------------------------ guidance

    def _guidance(self, ms, a_mj, cur_mj, spd, psi_free, psi_ref, th_ref, thrust, models):
        """Servo controls (K, nu) from MuJoCo states and the step's commands; sets the force
        ranges of each model (thrust switch, fin authority)."""
        rot = mjcf.quat_to_matrix(ms[:, 4:8])
        phi, th, psi = mjcf.quat_to_euler(ms[:, 4:8])
        rt = np.swapaxes(rot, 1, 2)
        v_flu = np.einsum("kij,kj->ki", rt, ms[:, 8:11])
        c_flu = np.einsum("kij,kj->ki", rt, cur_mj)  # current in the body frame
        a_flu = np.einsum("kij,kj->ki", rt, a_mj)  # commanded relative velocity, body frame
        ur = v_flu[:, 0] - c_flu[:, 0]
        if self._torpedo:
            cmd_rel = np.zeros_like(a_flu)
            cmd_rel[:, 0] = np.where(psi_free, spd, a_flu[:, 0])
        else:
            cmd_rel = a_flu
        rmax = self._rmax
        pc = np.clip(-self._katt * phi, -rmax, rmax)
        qc = np.clip(self._katt * (th_ref - th), -rmax, rmax)
        rlim = np.full_like(ur, rmax)
        if self._rturn > 0:
            rlim = np.minimum(rmax, np.abs(ur) / self._rturn)
        rc = np.clip(self._kpsi * _wrap(psi_ref - psi), -rlim, rlim)
        rate_flu = np.stack([pc, -qc, -rc], axis=1)
        # damping coefficients of the current relative velocity (lagged over the period)
        dl, dq = self._dl, self._dq
        rel = np.concatenate([v_flu - c_flu, ms[:, 11:14]], axis=1)
        dcoef = dl[None, :] + dq[None, :] * np.abs(rel)
        # the core's feed-forward: D(|nu_r|) c + g(eta) (restoring moment held by the roll and
        # pitch loops), so the servo force is tau = D c + g + kv (c - nu_r) as in the core
        ff = np.concatenate([dcoef[:, :3] * cmd_rel, dcoef[:, 3:] * rate_flu], axis=1)
        ff[:, 3] += self._wbg * libm.cos(th) * libm.sin(phi)
        ff[:, 4] -= self._wbg * libm.sin(th)
        ctrl = np.zeros((ms.shape[0], self.nu))
        for k, dof in enumerate(self._dofs):
            kv = self._kv[k]
            if dof < 3:
                ctrl[:, k] = cmd_rel[:, dof] + c_flu[:, dof] + ff[:, dof] / kv
            else:
                ctrl[:, k] = rate_flu[:, dof - 3] + ff[:, dof] / kv
        # dampers: control = the current's body projection (FLU axes = core axes up to sign,
        # |.| unchanged)
        ns = self.n_servo
        ctrl[:, ns:ns + 3] = c_flu
        cap = np.broadcast_to(self._cap, (ms.shape[0], ns)).copy()
        if self._torpedo:
            u2 = ur * ur
            cap[:, 1] = self.vm.fin_q * u2
            cap[:, 2] = self.vm.fin_r * u2
        cap[~thrust] = 0.0
        for m, cp, dc in zip(models, cap, dcoef):
            fr = m.actuator_forcerange
            fr[:ns, 0] = -cp
            fr[:ns, 1] = cp
            m.actuator_gainprm[ns:, 0] = dc
            m.actuator_biasprm[ns:, 2] = -dc
        return ctrl, cap
