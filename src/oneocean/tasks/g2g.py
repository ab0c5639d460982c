"""G2G — go-to-goal under currents (1 agent).

Objective
    Reach a goal ``goal_distance_m`` metres from the start, at the start's depth, before
    ``time_limit_s``. Start, goal and the straight segment between them are in valid water
    (off land, inside the grid, ``MIN_ALTITUDE_M`` above the seafloor), so every episode is
    solvable without path planning; the difficulty is the current along the way.
Success
    The agent comes within ``goal_radius_m`` of the goal (checked after every step); the
    episode stops there and ``T_s`` is the time to success (the time limit on failure).
Metrics
    ``final_error_m`` (primary: distance to the goal when the episode ends, m),
    ``min_error_m`` (closest approach, m), ``path_length_m`` (ground track length, m).
Methods
    ``heuristic``: a transit at cruise speed through the water, ``|a| <= CRUISE_FRAC * v_max``
    (an economical survey-AUV cruise, 1.2 m s-1), compensating the NOISY probed current by crabbing:
    the cross-track current is fed forward first and the rest of the cruise budget goes along
    the goal bearing, with P-control (``KP``) of the approach
    (:func:`~oneocean.tasks.common.seek_max` with the cruise budget). A head current therefore
    costs it ground speed, a cross current above the cruise speed sets it off track.
    ``oracle``: the same steering with the exact current and the full ``v_max``.

Module layout (the template every task module follows)
    ``TASK_ID``, ``METRICS``, module constants of the (fixed) heuristic; ``reset`` (Python:
    geometry and start times per episode from :func:`~oneocean.tasks.common.episode_generators`);
    ``_episode`` (one episode, serial, ``hot_kernel``: no allocation, calls
    :func:`~oneocean.tasks.common.advance_agent` every agent-step and writes one row of the
    result matrix); ``_kernel`` (``njit(parallel=True, cache=True)``: ``prange`` over
    episodes); ``rollout`` (Python: packs the tier into ``ipar``/``fpar``, preallocates work
    arrays, calls the kernel, unpacks the columns ``COLUMNS = STANDARD + METRICS``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..engine.dynamics import CMD_DIM, model_id, new_state
from ..engine._jit import hot_kernel
from ..engine.constraints import DEFAULT_LAND_THRESHOLD
from ..errors import ConfigError
from .common import (CLEARANCE_M, CRUISE_FRAC, DEPTH_RANGE_M, HEURISTIC, MIN_ALTITUDE_M, OK,
                     STANDARD, advance_agent, current_at, episode_generators, episode_steps,
                     fresh_cache, method_id, need_tier, obs_buffers, observe, rollout_results,
                     sample_route, seek_max, sensed_current, set_velocity_cmd, start_times)

TASK_ID = "G2G"
METRICS = ("final_error_m", "min_error_m", "path_length_m")
#: Result-matrix columns written by the kernel (standard columns first).
COLUMNS = STANDARD + METRICS

#: Proportional gain of the approach (ground speed = min(KP * distance, cruise)), s-1.
KP = 0.5

# indices of ipar / fpar (the kernel's scalar parameters)
_I_MODEL, _I_METHOD, _I_STEPS, _I_SEED = range(4)
_F_DT, _F_VMAX, _F_SPEED, _F_KP, _F_NOISE, _F_RADIUS, _F_LAND, _F_CLEAR = range(8)
_C = {k: i for i, k in enumerate(COLUMNS)}
_C_SUCCESS, _C_T, _C_E, _C_COLL, _C_VIOL = (_C[k] for k in STANDARD)
_C_FINAL, _C_MIN, _C_PATH = (_C[k] for k in METRICS)


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample start, goal and start time of every episode.

    Parameters
    ----------
    grid : Grid
    tier : dict
        Tier parameters (``goal_distance_m``, ``time_limit_s``, ...) plus ``dt_s``.
    n_agents : int
        Must be 1 (single-agent task).
    n_episodes, seed : int

    Returns
    -------
    dict
        ``pos0`` (E, 1, 3) start positions, m; ``goal`` (E, 3) goal positions, m;
        ``psi0`` (E, 1) initial heading (facing the goal), rad; ``t0`` (E,) start times, s.

    Raises
    ------
    ConfigError
        Wrong team size, missing tier keys, or no valid geometry for some episode.
    """
    if int(n_agents) != 1:
        raise ConfigError(f"task {TASK_ID}: single-agent task, got n_agents={n_agents}")
    need_tier(TASK_ID, tier, "goal_distance_m", "time_limit_s")
    rngs = episode_generators(seed, n_episodes)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    pos0 = np.empty((n_episodes, 1, 3))
    goal = np.empty((n_episodes, 3))
    for e, rng in enumerate(rngs):
        route = sample_route(grid, rng, 1, float(tier["goal_distance_m"]), DEPTH_RANGE_M,
                             MIN_ALTITUDE_M, land_threshold=DEFAULT_LAND_THRESHOLD,
                             what=f"task {TASK_ID} reset (episode {e})")
        pos0[e, 0] = route[0]
        goal[e] = route[1]
    d = goal - pos0[:, 0]
    psi0 = np.arctan2(d[:, 0], d[:, 2])[:, None]
    return {"pos0": pos0, "goal": goal, "psi0": psi0, "t0": t0}


@hot_kernel
def _episode(grid, vp, ipar, fpar, pos0, goal, t0, state, cmd, obs, act, res, e):
    """Run episode ``e`` (serial) and write row ``e`` of ``res`` (see ``COLUMNS``).

    ``state`` (E, 1, STATE_DIM) must hold the initial state; ``cmd`` (E, 1, CMD_DIM) is scratch.
    """
    model = ipar[_I_MODEL]
    method = ipar[_I_METHOD]
    n_steps = ipar[_I_STEPS]
    seed = ipar[_I_SEED]
    dt = fpar[_F_DT]
    v_max = fpar[_F_VMAX]
    speed = fpar[_F_SPEED]
    kp = fpar[_F_KP]
    noise = fpar[_F_NOISE]
    radius = fpar[_F_RADIUS]
    land_thr = fpar[_F_LAND]
    clearance = fpar[_F_CLEAR]
    s = state[e, 0]
    c = cmd[e, 0]
    gx = goal[e, 0]
    gy = goal[e, 1]
    gz = goal[e, 2]
    energy = 0.0
    viol = 0
    path = 0.0
    d = math.sqrt((s[0] - gx) ** 2 + (s[1] - gy) ** 2 + (s[2] - gz) ** 2)
    d_min = d
    success = d <= radius
    t_s = 0.0
    k = 0
    while k < n_steps and not success:
        t = t0[e] + k * dt
        px = s[0]
        py = s[1]
        pz = s[2]
        ce, cn = current_at(grid, px, py, pz, t)
        pe, pn = sensed_current(method, ce, cn, noise, seed, e, 2 * k)
        ax, ay, az = seek_max(px, py, pz, gx, gy, gz, speed if method == HEURISTIC else v_max, kp,
                              pe, pn)
        observe(obs, act, e, k, 0, grid, state, gx, gy, gz, pe, pn, math.nan, ax, ay, az)
        set_velocity_cmd(c, ax, ay, az)
        en, code = advance_agent(grid, model, vp, s, c, ce, cn, v_max, dt, land_thr, clearance)
        energy += en
        if code != OK:
            viol += 1
        path += math.sqrt((s[0] - px) ** 2 + (s[1] - py) ** 2 + (s[2] - pz) ** 2)
        d = math.sqrt((s[0] - gx) ** 2 + (s[1] - gy) ** 2 + (s[2] - gz) ** 2)
        if d < d_min:
            d_min = d
        k += 1
        if d <= radius:
            success = True
            t_s = k * dt
    res[e, _C_SUCCESS] = 1.0 if success else 0.0
    res[e, _C_T] = t_s if success else n_steps * dt
    res[e, _C_E] = energy
    res[e, _C_COLL] = 0.0
    res[e, _C_VIOL] = viol
    res[e, _C_FINAL] = d
    res[e, _C_MIN] = d_min
    res[e, _C_PATH] = path


@njit(parallel=True, cache=True)
def _kernel(grid, vp, ipar, fpar, pos0, goal, t0, state, cmd, obs, act, res):
    for e in prange(res.shape[0]):
        _episode(grid, vp, ipar, fpar, pos0, goal, t0, state, cmd, obs, act, res, e)


def rollout(grid, tier: dict, init: dict, method: str, dyn: str, vehicle,
            seed: int, *, record: bool = False) -> dict:
    """Run every episode of ``init`` (from :func:`reset`) with one method.

    Parameters
    ----------
    grid : Grid
        Forcing already applied (``run_cell`` sets the tier's ``current_gain``).
    tier : dict
        Tier parameters plus ``dt_s``.
    init : dict
        Output of :func:`reset`.
    method : {"heuristic", "oracle"}
    dyn : {"kinematic", "3dof", "4dof", "6dof"}
    vehicle : Vehicle
    seed : int
        Run seed (probe-noise streams).

    Returns
    -------
    dict of (E,) arrays
        ``success`` (bool), ``T_s`` (s), ``E`` (m2 s-1), ``coll_ratio`` (0 for one agent),
        ``violations`` (int) and ``METRICS``.
    """
    need_tier(TASK_ID, tier, "time_limit_s", "goal_radius_m", "probe_noise_ms", "dt_s")
    dt = float(tier["dt_s"])
    n_ep = init["goal"].shape[0]
    v_max = float(vehicle.v_max)
    ipar = np.array([model_id(dyn), method_id(method),
                     episode_steps(tier), int(seed)],
                    dtype=np.int64)
    fpar = np.array([dt, v_max, CRUISE_FRAC * v_max, KP, float(tier["probe_noise_ms"]),
                     float(tier["goal_radius_m"]), DEFAULT_LAND_THRESHOLD, CLEARANCE_M])
    state = new_state(n_ep, 1, init["pos0"], init["psi0"])
    cmd = np.zeros((n_ep, 1, CMD_DIM))
    res = np.zeros((n_ep, len(COLUMNS)))
    obs, act = obs_buffers(tier, init, record)
    _kernel(grid, vehicle.params, ipar, fpar, init["pos0"], np.ascontiguousarray(init["goal"]),
            np.ascontiguousarray(init["t0"], dtype=np.float64), state, cmd, obs, act, res)
    return rollout_results(res, COLUMNS, obs, act, record)


# numba keys a cache entry on this file only; drop it when the engine or the task layer
# changes.
fresh_cache(_kernel, __file__)
