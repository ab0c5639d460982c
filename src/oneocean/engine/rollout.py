"""Batched, deterministic rollouts: one ``@njit(parallel=True)`` call advances E episodes x A
agents over many steps (``prange`` over episodes).

Per step and agent: probe the current at the agent (4-D sampling), compute the controller's
command, clip it to ``v_max`` (eq. 1's a_t), accumulate the energy proxy ``||a||^2 dt``
(eq. 7), advance the dynamics, check feasibility (eq. 3) and reject infeasible moves (position
kept, velocity zeroed, violation counted, status code set). Per step and episode: near-collision
count ``min_{i<j} ||p_i - p_j|| <= r_coll`` (eq. 4) and the minimum pair distance. Optional
subsampled trajectories.

Runs are resumable: :func:`run` advances a :class:`Batch` by ``steps`` and returns it, so an
outer Python loop can update goals or plans every K steps. Results do not depend on the thread
count: each episode is computed by one thread and no float is reduced across episodes; action
noise is a counter-based hash of (seed, episode id, purpose, step, agent, component).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numba import njit, prange

from ..errors import ConfigError
from . import dynamics as dyn
from . import status as st
from .constraints import (DEFAULT_CLEARANCE_M, DEFAULT_LAND_THRESHOLD, DEFAULT_R_COLL_M,
                          check_move, min_pairwise_distance)
from .controllers import Controller, compute_command
from .grid import Grid, locate_time, sample_current_at, synthetic_tide
from .rng import PURPOSE_ACTION_NOISE, normal
from ._jit import hot_kernel


@dataclass
class Batch:
    """Mutable rollout state of E episodes x A agents (all arrays owned by the batch).

    Attributes
    ----------
    state : (E, A, STATE_DIM) float64
        Agent states (layout in :mod:`oneocean.engine.dynamics`).
    t0 : (E,) float64
        Start time of each episode, s since the grid's ``time0``.
    steps : (E,) int64
        Steps taken by each episode.
    alive : (E,) uint8
        0 = episode finished (skipped by :func:`run`); set by the caller.
    status : (E, A) int64
        Status code of each agent's last step (:mod:`oneocean.engine.status`).
    violations : (E, A) int64
        Rejected moves per agent.
    energy : (E, A) float64
        Energy proxy ``sum_t ||a_t||^2 dt`` per agent, m2 s-1.
    coll_steps : (E,) int64
        Steps with ``min pair distance <= r_coll``.
    min_dist : (E,) float64
        Smallest pair distance seen, m (inf for one agent).
    wp_idx : (E, A) int64
        Current waypoint index (PLAN controller).
    traj : (E, A, K, 3) float32
        Positions every ``record_every`` steps (index 0 = start); K = 0 if not recorded.
    record_every : int
    episode_ids : (E,) int64
        Global episode numbers (seed streams and metrics use them).
    seed : int
    """

    state: np.ndarray
    t0: np.ndarray
    steps: np.ndarray
    alive: np.ndarray
    status: np.ndarray
    violations: np.ndarray
    energy: np.ndarray
    coll_steps: np.ndarray
    min_dist: np.ndarray
    wp_idx: np.ndarray
    traj: np.ndarray
    record_every: int
    episode_ids: np.ndarray
    seed: int

    @property
    def n_episodes(self) -> int:
        return self.state.shape[0]

    @property
    def n_agents(self) -> int:
        return self.state.shape[1]

    @property
    def positions(self) -> np.ndarray:
        """(E, A, 3) view of the agent positions, m."""
        return self.state[..., dyn.X:dyn.Z + 1]

    def recorded(self) -> np.ndarray:
        """Recorded positions (E, A, K', 3) trimmed to the samples taken so far (K' common)."""
        if self.record_every <= 0:
            return self.traj
        k = int(self.steps.max() // self.record_every) + 1 if self.steps.size else 0
        return self.traj[:, :, :min(k, self.traj.shape[2])]


def init_batch(positions, *, t0=0.0, heading=0.0, seed: int = 0, episode_ids=None,
               record_every: int = 0, max_steps: int = 0) -> Batch:
    """A batch at rest at ``positions`` (E, A, 3) m.

    Parameters
    ----------
    positions : (E, A, 3) array
    t0 : float or (E,) array
        Episode start times, s since the grid's ``time0``.
    heading : float or (E, A) array
        Initial heading, rad (compass: clockwise from north).
    seed : int
        Run seed (action-noise streams).
    episode_ids : (E,) ints, optional
        Global episode numbers (default ``0..E-1``).
    record_every, max_steps : int
        Keep positions every ``record_every`` steps for up to ``max_steps`` steps (0 = off).
    """
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[2] != 3 or pos.shape[0] < 1 or pos.shape[1] < 1:
        raise ConfigError(f"positions: expected shape (episodes, agents, 3), got {pos.shape}")
    if not np.all(np.isfinite(pos)):
        raise ConfigError("positions: must be finite")
    e, a = pos.shape[:2]
    if not 0 <= int(seed) < 2**63:
        raise ConfigError(f"seed: must be in [0, 2**63), got {seed}")
    state = dyn.new_state(e, a, pos, heading)
    t0a = np.ascontiguousarray(np.broadcast_to(np.asarray(t0, dtype=np.float64), (e,)))
    ids = np.arange(e, dtype=np.int64) if episode_ids is None else \
        np.ascontiguousarray(episode_ids, dtype=np.int64)
    if ids.shape != (e,):
        raise ConfigError(f"episode_ids: expected shape ({e},), got {ids.shape}")
    record_every = int(record_every)
    if record_every > 0:
        if int(max_steps) <= 0:
            raise ConfigError("record_every > 0 needs max_steps > 0 (trajectory buffer size)")
        k = int(max_steps) // record_every + 1
        traj = np.full((e, a, k, 3), np.nan, dtype=np.float32)
        traj[:, :, 0] = pos
    else:
        traj = np.zeros((e, a, 0, 3), dtype=np.float32)
    return Batch(state=state, t0=t0a.copy(), steps=np.zeros(e, np.int64),
                 alive=np.ones(e, np.uint8), status=np.zeros((e, a), np.int64),
                 violations=np.zeros((e, a), np.int64), energy=np.zeros((e, a)),
                 coll_steps=np.zeros(e, np.int64), min_dist=np.full(e, np.inf),
                 wp_idx=np.zeros((e, a), np.int64), traj=traj, record_every=record_every,
                 episode_ids=ids, seed=int(seed))


@hot_kernel(inline="always")
def advance_agent(grid, model, vp, s, cmd, ce, cn, v_max, dt, land_threshold, clearance):
    """Clip the command, advance one agent one step and enforce feasibility, in place.

    Parameters
    ----------
    s : (STATE_DIM,) float64
        Agent state (see :mod:`oneocean.engine.dynamics`), modified in place.
    cmd : (CMD_DIM,) float64
        ``[ax, ay, az, psi_cmd, thrust]``: desired velocity relative to the water (world m s-1);
        clipped here to ``v_max`` (the executed action a_t is written back into ``cmd``).
    ce, cn : float
        True current at the agent (m s-1), frozen over the step.

    Returns
    -------
    energy : float
        ``||a_t||^2 dt`` of the clipped action (m2 s-1), 0 when thrust is off.
    code : int
        Status of the move (``OK`` or the rejection reason); a rejected move keeps the
        position and zeroes the velocity.
    """
    ax, ay, az = dyn.clip_action(cmd[0], cmd[1], cmd[2], v_max)
    cmd[0] = ax
    cmd[1] = ay
    cmd[2] = az
    e = (ax * ax + ay * ay + az * az) * dt if cmd[4] != 0.0 else 0.0
    px = s[0]
    py = s[1]
    pz = s[2]
    dyn.step_agent(model, vp, s, cmd, ce, cn, dt)
    code = check_move(grid, s[0], s[1], s[2], land_threshold, clearance)
    if code != st.OK:
        s[0] = px
        s[1] = py
        s[2] = pz
        for c in range(dyn.U, dyn.W + 1):
            s[c] = 0.0
        for c in range(dyn.VX, dyn.VZ + 1):
            s[c] = 0.0
    return e, code


@hot_kernel
def run_episode(grid, vp, cp, goals, plan, plan_len, mlp_sizes, mlp_w, feats, actions, state,
                t0, steps, alive, status, violations, energy, coll_steps, min_dist, wp_idx, traj,
                episode_ids, ipar, fpar, cmd_ws, buf_ws, ei):
    """Advance episode ``ei`` of the batch arrays (serial; see :func:`run`).

    ``ipar`` = [model, kind, n_steps, record_every, seed] (int64),
    ``fpar`` = [dt, v_max, land_threshold, clearance, r_coll, noise_std] (float64),
    ``cmd_ws`` (E, CMD_DIM) and ``buf_ws`` (E, 2 * max MLP width) are per-episode scratch rows
    (preallocated so that this kernel never allocates).
    """
    if alive[ei] == 0:
        return
    model = ipar[0]
    kind = ipar[1]
    n_steps = ipar[2]
    record_every = ipar[3]
    seed = ipar[4]
    dt = fpar[0]
    v_max = fpar[1]
    land_threshold = fpar[2]
    clearance = fpar[3]
    r_coll = fpar[4]
    noise_std = fpar[5]
    n_ag = state.shape[1]
    cmd = cmd_ws[ei]
    buf = buf_ws[ei]
    st_e = state[ei]
    eid = episode_ids[ei]
    for k in range(n_steps):
        kstep = steps[ei]
        t = t0[ei] + kstep * dt
        te, tn = synthetic_tide(grid, t)
        it0, it1, wt = locate_time(grid, t)
        for ai in range(n_ag):
            s = st_e[ai]
            px = s[0]
            py = s[1]
            pz = s[2]
            ce, cn = sample_current_at(grid, px, py, pz, it0, it1, wt)
            ce += te
            cn += tn
            compute_command(kind, cp, ei, ai, k, s, ce, cn, goals, plan, plan_len, wp_idx,
                            mlp_sizes, mlp_w, feats, actions, buf, cmd)
            ax = cmd[0]
            ay = cmd[1]
            az = cmd[2]
            if noise_std > 0.0:
                base = (kstep * n_ag + ai) * 3
                ax += noise_std * normal(seed, eid, PURPOSE_ACTION_NOISE, base)
                ay += noise_std * normal(seed, eid, PURPOSE_ACTION_NOISE, base + 1)
                az += noise_std * normal(seed, eid, PURPOSE_ACTION_NOISE, base + 2)
            cmd[0] = ax
            cmd[1] = ay
            cmd[2] = az
            en, code = advance_agent(grid, model, vp, s, cmd, ce, cn, v_max, dt, land_threshold,
                                     clearance)
            energy[ei, ai] += en
            if code != st.OK:
                violations[ei, ai] += 1
            status[ei, ai] = code
        steps[ei] = kstep + 1
        if n_ag > 1:
            d = min_pairwise_distance(st_e)
            if d <= r_coll:
                coll_steps[ei] += 1
            if d < min_dist[ei]:
                min_dist[ei] = d
        if record_every > 0 and (kstep + 1) % record_every == 0:
            idx = (kstep + 1) // record_every
            if idx < traj.shape[2]:
                for ai in range(n_ag):
                    traj[ei, ai, idx, 0] = st_e[ai, 0]
                    traj[ei, ai, idx, 1] = st_e[ai, 1]
                    traj[ei, ai, idx, 2] = st_e[ai, 2]


@njit(parallel=True, cache=True)
def _rollout_kernel(grid, vp, cp, goals, plan, plan_len, mlp_sizes, mlp_w, feats, actions, state,
                    t0, steps, alive, status, violations, energy, coll_steps, min_dist, wp_idx,
                    traj, episode_ids, ipar, fpar, cmd_ws, buf_ws):
    for i in prange(state.shape[0]):
        run_episode(grid, vp, cp, goals, plan, plan_len, mlp_sizes, mlp_w, feats, actions, state,
                    t0, steps, alive, status, violations, energy, coll_steps, min_dist, wp_idx,
                    traj, episode_ids, ipar, fpar, cmd_ws, buf_ws, np.int64(i))


def _check_controller(ctrl: Controller, e: int, a: int, steps: int) -> None:
    shapes = {"goals": (ctrl.goals, (e, a, 4)), "features": (ctrl.features, (e, a, None)),
              "plan": (ctrl.plan, (e, a, None, 3)), "plan_len": (ctrl.plan_len, (e, a)),
              "actions": (ctrl.actions, (steps, e, a, 3))}
    need = {0: ("goals",), 1: ("goals", "features"), 2: ("plan", "plan_len"), 3: ("actions",)}
    for key in need[ctrl.kind]:
        arr, want = shapes[key]
        ok = arr.ndim == len(want) and all(w is None or s == w for s, w in zip(arr.shape, want))
        if not ok:
            shown = tuple("*" if w is None else w for w in want)
            raise ConfigError(f"controller {key}: expected shape {shown}, got {arr.shape}")


def run(grid: Grid, batch: Batch, controller: Controller, steps: int, *,
        dynamics: str = "kinematic", vehicle: dyn.Vehicle | None = None, dt: float = 1.0,
        v_max: float | None = None, land_threshold: float = DEFAULT_LAND_THRESHOLD,
        clearance: float = DEFAULT_CLEARANCE_M, r_coll: float = DEFAULT_R_COLL_M,
        action_noise: float = 0.0, threads: int | None = None,
        allow_time_clamp: bool = False) -> Batch:
    """Advance ``batch`` by ``steps`` steps of ``dt`` seconds in place and return it.

    Parameters
    ----------
    grid : Grid
    batch : Batch
    controller : Controller
    steps : int
    dynamics : {"kinematic", "3dof", "4dof", "6dof"}
    vehicle : Vehicle, optional
        Default: :func:`oneocean.engine.dynamics.load_vehicle` ().
    dt : float
        Step, s.
    v_max : float, optional
        Action speed limit, m s-1 (default: the vehicle's).
    land_threshold, clearance, r_coll : float
        Feasibility threshold (0..1), seafloor clearance (m), near-collision radius (m).
    action_noise : float
        Std of Gaussian noise added to each action component before clipping, m s-1.
    threads : int, optional
        ``numba.set_num_threads`` for this call (restored afterwards).
    allow_time_clamp : bool
        Allow episodes to run past the grid's last time (currents then frozen at the last
        time); by default that is a ConfigError.
    """
    model = dyn.model_id(dynamics)
    veh = vehicle if vehicle is not None else dyn.load_vehicle()
    vmax = float(veh.v_max if v_max is None else v_max)
    steps = int(steps)
    dt = float(dt)
    if steps < 0 or not dt > 0 or not vmax >= 0:
        raise ConfigError(f"run: need steps >= 0, dt > 0, v_max >= 0 (got {steps}, {dt}, {vmax})")
    for name, val in (("land_threshold", land_threshold), ("clearance", clearance),
                      ("r_coll", r_coll), ("action_noise", action_noise)):
        if not np.isfinite(val) or val < 0:
            raise ConfigError(f"run: {name} must be finite and >= 0, got {val}")
    e, a = batch.n_episodes, batch.n_agents
    _check_controller(controller, e, a, steps)
    if grid.time_s.shape[0] > 1 and not allow_time_clamp:
        t_end = batch.t0 + (batch.steps + steps) * dt
        live = batch.alive != 0
        lo, hi = grid.time_s[0], grid.time_s[-1]
        bad = live & ((batch.t0 < lo) | (t_end > hi + dt))
        if bad.any():
            i = int(np.argmax(bad))
            raise ConfigError(
                f"run: episode {int(batch.episode_ids[i])} spans t=[{batch.t0[i]:g}, "
                f"{t_end[i]:g}] s beyond the grid's time range [{lo:g}, {hi:g}] s; shorten it, "
                "move its start, or pass allow_time_clamp=True")
    c = controller
    arrays = [np.ascontiguousarray(x, dtype=dtp) for x, dtp in (
        (c.goals, np.float64), (c.plan, np.float64), (c.plan_len, np.int64),
        (c.mlp_sizes, np.int64), (c.mlp_weights, np.float64), (c.features, np.float64),
        (c.actions, np.float64))]
    prev = numba.get_num_threads()
    if threads is not None:
        numba.set_num_threads(int(threads))
    try:
        ipar = np.array([model, int(c.kind), steps, batch.record_every, batch.seed],
                        dtype=np.int64)
        nbuf = 2 * max(int(arrays[3].max()) if arrays[3].size else 1, 1)
        cmd_ws = np.zeros((e, dyn.CMD_DIM))
        buf_ws = np.zeros((e, nbuf))
        fpar = np.array([dt, vmax, land_threshold, clearance, r_coll, action_noise],
                        dtype=np.float64)
        _rollout_kernel(grid, veh.params, c.params, *arrays, batch.state, batch.t0, batch.steps,
                        batch.alive, batch.status, batch.violations, batch.energy,
                        batch.coll_steps, batch.min_dist, batch.wp_idx, batch.traj,
                        batch.episode_ids, ipar, fpar, cmd_ws, buf_ws)
    finally:
        if threads is not None:
            numba.set_num_threads(prev)
    if np.any(batch.status == st.NONFINITE):
        i, j = np.argwhere(batch.status == st.NONFINITE)[0]
        raise RuntimeError(f"engine: non-finite state for episode {int(batch.episode_ids[i])}, "
                           f"agent {int(j)} ({dynamics}); check the vehicle parameters and dt")
    return batch
