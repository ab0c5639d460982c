"""FT — formation transit under currents (2–10 agents; default 10 as in the paper's Table V).

Objective
    Move a formation of N agents ``route_m`` metres along a straight route at one depth while
    keeping its shape: a wedge ("V") of slots ``SPACING_M`` apart along each arm
    (``WEDGE_HALF_ANGLE_DEG`` off the route axis), apex forward, offsets centred on the
    formation centroid and oriented along the route. Every slot's own straight path from start
    to goal is in valid water with ``MIN_ALTITUDE_M`` of clearance. Agents start at rest in
    their slots, facing the route.
Formation error (method-independent)
    With offsets ``o_i`` (centred) and the agents' centroid ``p_bar``, agent i's slot error is
    ``e_i = ||p_i - (p_bar + o_i)||``: the shape error, independent of any virtual leader.
Success (team, never best-of-N)
    Before ``time_limit_s``: the centroid comes within ``goal_radius_m`` of the goal while
    EVERY agent is within ``slot_tol_m`` of its slot, and during the whole transit no agent's
    slot error ever exceeded ``max_error_m`` (exceeding it ends the episode as a failure).
Metrics
    ``formation_error_m`` (primary: time mean of the RMS over agents of e_i, m),
    ``max_slot_error_m`` (largest e_i seen, m), ``final_centroid_error_m`` (centroid to goal
    when the episode ends, m). ``coll_ratio`` counts steps with the minimum pairwise distance
    <= ``R_COLL_M``.
Methods (task logic lives here, not in the environment)
    A virtual centre advances along the route at ``pace * V_NOM_FRAC * budget``, where
    ``pace = clip(1 - (e_max - PACE_E0_M) / PACE_E1_M, 0, 1)`` slows it when the worst agent
    lags (``e_max`` = largest distance of an agent to its slot around the virtual centre).
    Each agent tracks its slot with feed-forward of the virtual centre's velocity plus
    P-control ``KP`` (capped at ``P_CAP_MS``) through :func:`~oneocean.tasks.common.steer`.
    ``heuristic``: NOISY probed current, throttle cap ``budget = CRUISE_FRAC * v_max``.
    ``oracle``: exact current, ``budget = v_max``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..engine.constraints import DEFAULT_LAND_THRESHOLD, DEFAULT_R_COLL_M, min_pairwise_distance
from ..engine.dynamics import CMD_DIM, model_id, new_state
from ..engine._jit import hot_kernel
from ..errors import ConfigError
from .common import (CLEARANCE_M, CRUISE_FRAC, DEPTH_RANGE_M, HEURISTIC, MIN_ALTITUDE_M, OK,
                     STANDARD, advance_agent, current_at, episode_generators, episode_steps,
                     fresh_cache, method_id, need_tier, obs_buffers, observe, path_clear,
                     rollout_results, sample_route, sensed_current, set_velocity_cmd, start_times,
                     steer)

TASK_ID = "FT"
METRICS = ("formation_error_m", "max_slot_error_m", "final_centroid_error_m")
COLUMNS = STANDARD + METRICS

#: Distance between consecutive slots along a wedge arm, m.
SPACING_M = 8.0
#: Angle of the wedge arms off the (backward) route axis, degrees.
WEDGE_HALF_ANGLE_DEG = 50.0
#: Virtual-centre nominal speed as a fraction of the method's speed budget.
V_NOM_FRAC = 0.8
#: Pacing: the virtual centre slows once the worst slot lag exceeds PACE_E0_M and stops at
#: PACE_E0_M + PACE_E1_M, m.
PACE_E0_M = 1.0
PACE_E1_M = 3.0
#: Slot-tracking gain (s-1) and cap of the P part of the ground-velocity request (m s-1).
KP = 0.3
P_CAP_MS = 0.6
#: Near-collision radius, m (task contract: 2 m).
R_COLL_M = DEFAULT_R_COLL_M

_I_MODEL, _I_METHOD, _I_STEPS, _I_SEED = range(4)
(_F_DT, _F_VMAX, _F_SPEED, _F_KP, _F_NOISE, _F_RADIUS, _F_LAND, _F_CLEAR, _F_SLOT, _F_EMAX,
 _F_RCOLL, _F_VNOM, _F_E0, _F_E1, _F_PCAP) = range(15)
_C = {k: i for i, k in enumerate(COLUMNS)}
_C_SUCCESS, _C_T, _C_E, _C_COLL, _C_VIOL = (_C[k] for k in STANDARD)
_C_FERR, _C_EMAX, _C_FINAL = (_C[k] for k in METRICS)


def wedge_offsets(n: int, spacing: float = SPACING_M,
                  half_angle_deg: float = WEDGE_HALF_ANGLE_DEG) -> np.ndarray:
    """Slot offsets (n, 2) ``[forward, right]`` m of a wedge, apex first, centred on 0.

    Slot 0 is the apex; slots 1, 2 are the first rank (right, left), 3, 4 the second, ...
    """
    if n < 1:
        raise ConfigError(f"task {TASK_ID}: need at least 1 agent, got {n}")
    a = math.radians(half_angle_deg)
    off = np.zeros((n, 2))
    for i in range(1, n):
        rank = (i + 1) // 2
        side = 1.0 if i % 2 == 1 else -1.0
        off[i] = (-rank * spacing * math.cos(a), side * rank * spacing * math.sin(a))
    return off - off.mean(axis=0)


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the route (start centroid, goal), the formation frame and start times.

    Returns
    -------
    dict
        ``pos0`` (E, N, 3) agents in their start slots, m; ``offsets`` (E, N, 3) world-frame
        slot offsets (centred), m; ``start`` and ``goal`` (E, 3) centroid start / goal, m;
        ``psi0`` (E, N) heading along the route, rad; ``t0`` (E,) s.

    Raises
    ------
    ConfigError
        Team size outside [2, 10] is checked by ``run_cell``; here: missing tier keys or no
        route along which every slot path is clear.
    """
    n = int(n_agents)
    if n < 2:
        raise ConfigError(f"task {TASK_ID}: team task needs n_agents >= 2, got {n}")
    need_tier(TASK_ID, tier, "route_m", "time_limit_s")
    route_m = float(tier["route_m"])
    rngs = episode_generators(seed, n_episodes)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    off2 = wedge_offsets(n)
    pos0 = np.empty((n_episodes, n, 3))
    offsets = np.empty((n_episodes, n, 3))
    start = np.empty((n_episodes, 3))
    goal = np.empty((n_episodes, 3))
    psi = np.empty(n_episodes)
    tries = 2000
    for e, rng in enumerate(rngs):
        for _ in range(tries):
            c0 = sample_route(grid, rng, 0, 0.0, DEPTH_RANGE_M, MIN_ALTITUDE_M,
                              land_threshold=DEFAULT_LAND_THRESHOLD,
                              what=f"task {TASK_ID} reset (episode {e})")[0]
            h = rng.uniform(-math.pi, math.pi)
            fwd = np.array([math.sin(h), 0.0, math.cos(h)])
            right = np.array([math.cos(h), 0.0, -math.sin(h)])
            o = off2[:, :1] * fwd + off2[:, 1:] * right
            g = c0 + route_m * fwd
            if all(path_clear(grid, c0 + o[i], g + o[i], MIN_ALTITUDE_M,
                              DEFAULT_LAND_THRESHOLD) for i in range(n)):
                break
        else:
            raise ConfigError(f"task {TASK_ID} reset (episode {e}): no {route_m:g} m route "
                              f"clear for all {n} slots found in {tries} tries; the grid is too "
                              "small or too shallow for this tier")
        start[e] = c0
        goal[e] = g
        offsets[e] = o
        pos0[e] = c0 + o
        psi[e] = h
    return {"pos0": pos0, "offsets": offsets, "start": start, "goal": goal,
            "psi0": np.repeat(psi[:, None], n, axis=1), "t0": t0}


@hot_kernel
def _episode(grid, vp, ipar, fpar, offsets, start, goal, t0, state, cmd, obs, act, res, e):
    """Run episode ``e`` (serial) and write row ``e`` of ``res`` (see ``COLUMNS``)."""
    model = ipar[_I_MODEL]
    method = ipar[_I_METHOD]
    n_steps = ipar[_I_STEPS]
    seed = ipar[_I_SEED]
    dt = fpar[_F_DT]
    v_max = fpar[_F_VMAX]
    budget = fpar[_F_SPEED] if method == HEURISTIC else v_max
    kp = fpar[_F_KP]
    noise = fpar[_F_NOISE]
    radius = fpar[_F_RADIUS]
    land_thr = fpar[_F_LAND]
    clearance = fpar[_F_CLEAR]
    slot_tol = fpar[_F_SLOT]
    e_bound = fpar[_F_EMAX]
    r_coll = fpar[_F_RCOLL]
    v_nom = fpar[_F_VNOM] * budget
    e0 = fpar[_F_E0]
    e1 = fpar[_F_E1]
    p_cap = fpar[_F_PCAP]
    st_e = state[e]
    n = st_e.shape[0]
    sx = start[e, 0]
    sy = start[e, 1]
    sz = start[e, 2]
    lx = goal[e, 0] - sx
    ly = goal[e, 1] - sy
    lz = goal[e, 2] - sz
    length = math.sqrt(lx * lx + ly * ly + lz * lz)
    tx = lx / length
    ty = ly / length
    tz = lz / length
    sigma = 0.0          # virtual centre's distance along the route, m
    energy = 0.0
    viol = 0
    coll = 0
    sum_rms = 0.0
    e_seen = 0.0
    cx = sx
    cy = sy
    cz = sz
    success = False
    broken = False
    k = 0
    while k < n_steps and not success and not broken:
        t = t0[e] + k * dt
        # --- method: pace the virtual centre by the worst slot lag around it
        vcx = sx + sigma * tx
        vcy = sy + sigma * ty
        vcz = sz + sigma * tz
        lag = 0.0
        for i in range(n):
            d = math.sqrt((st_e[i, 0] - vcx - offsets[e, i, 0]) ** 2
                          + (st_e[i, 1] - vcy - offsets[e, i, 1]) ** 2
                          + (st_e[i, 2] - vcz - offsets[e, i, 2]) ** 2)
            if d > lag:
                lag = d
        pace = min(max(1.0 - (lag - e0) / e1, 0.0), 1.0)
        step = min(pace * v_nom * dt, length - sigma)
        sigma += step
        fx = step / dt * tx
        fy = step / dt * ty
        fz = step / dt * tz
        # --- every agent tracks its slot (around the virtual centre at the start of the step)
        #     with feed-forward of the virtual centre's velocity over the step
        for i in range(n):
            s = st_e[i]
            c = cmd[e, i]
            px = s[0]
            py = s[1]
            pz = s[2]
            ce, cn = current_at(grid, px, py, pz, t)
            pe, pn = sensed_current(method, ce, cn, noise, seed, e, 2 * (k * n + i))
            qx = kp * (vcx + offsets[e, i, 0] - px)
            qy = kp * (vcy + offsets[e, i, 1] - py)
            qz = kp * (vcz + offsets[e, i, 2] - pz)
            qn = math.sqrt(qx * qx + qy * qy + qz * qz)
            if qn > p_cap:
                f = p_cap / qn
                qx *= f
                qy *= f
                qz *= f
            ax, ay, az = steer(fx + qx, fy + qy, fz + qz, budget, pe, pn)
            observe(obs, act, e, k, i, grid, state, vcx + offsets[e, i, 0], vcy + offsets[e, i, 1],
                    vcz + offsets[e, i, 2], pe, pn, math.nan, ax, ay, az)
            set_velocity_cmd(c, ax, ay, az)
            en, code = advance_agent(grid, model, vp, s, c, ce, cn, v_max, dt, land_thr,
                                     clearance)
            energy += en
            if code != OK:
                viol += 1
        k += 1
        # --- task: shape error around the centroid, collisions, bound, arrival
        cx = 0.0
        cy = 0.0
        cz = 0.0
        for i in range(n):
            cx += st_e[i, 0]
            cy += st_e[i, 1]
            cz += st_e[i, 2]
        cx /= n
        cy /= n
        cz /= n
        sq = 0.0
        emax = 0.0
        for i in range(n):
            d2 = ((st_e[i, 0] - cx - offsets[e, i, 0]) ** 2
                  + (st_e[i, 1] - cy - offsets[e, i, 1]) ** 2
                  + (st_e[i, 2] - cz - offsets[e, i, 2]) ** 2)
            sq += d2
            if d2 > emax:
                emax = d2
        emax = math.sqrt(emax)
        sum_rms += math.sqrt(sq / n)
        if emax > e_seen:
            e_seen = emax
        if min_pairwise_distance(st_e) <= r_coll:
            coll += 1
        if emax > e_bound:
            broken = True
        elif emax <= slot_tol:
            dg = math.sqrt((cx - goal[e, 0]) ** 2 + (cy - goal[e, 1]) ** 2
                           + (cz - goal[e, 2]) ** 2)
            if dg <= radius:
                success = True
    kk = k if k > 0 else 1
    res[e, _C_SUCCESS] = 1.0 if success else 0.0
    res[e, _C_T] = k * dt if success else n_steps * dt
    res[e, _C_E] = energy
    res[e, _C_COLL] = coll / kk
    res[e, _C_VIOL] = viol
    res[e, _C_FERR] = sum_rms / kk
    res[e, _C_EMAX] = e_seen
    res[e, _C_FINAL] = math.sqrt((cx - goal[e, 0]) ** 2 + (cy - goal[e, 1]) ** 2
                                 + (cz - goal[e, 2]) ** 2)


@njit(parallel=True, cache=True)
def _kernel(grid, vp, ipar, fpar, offsets, start, goal, t0, state, cmd, obs, act, res):
    for e in prange(res.shape[0]):
        _episode(grid, vp, ipar, fpar, offsets, start, goal, t0, state, cmd, obs, act, res, e)


def rollout(grid, tier: dict, init: dict, method: str, dyn: str, vehicle, seed: int, *,
            record: bool = False) -> dict:
    """Run every episode of ``init`` (from :func:`reset`); see :func:`.g2g.rollout`."""
    need_tier(TASK_ID, tier, "time_limit_s", "goal_radius_m", "slot_tol_m", "max_error_m",
          "probe_noise_ms", "dt_s")
    dt = float(tier["dt_s"])
    pos0 = np.ascontiguousarray(init["pos0"], dtype=np.float64)
    n_ep, n = pos0.shape[:2]
    v_max = float(vehicle.v_max)
    ipar = np.array([model_id(dyn), method_id(method),
                     episode_steps(tier), int(seed)],
                    dtype=np.int64)
    fpar = np.array([dt, v_max, CRUISE_FRAC * v_max, KP, float(tier["probe_noise_ms"]),
                     float(tier["goal_radius_m"]), DEFAULT_LAND_THRESHOLD, CLEARANCE_M,
                     float(tier["slot_tol_m"]), float(tier["max_error_m"]), R_COLL_M,
                     V_NOM_FRAC, PACE_E0_M, PACE_E1_M, P_CAP_MS])
    state = new_state(n_ep, n, pos0, init["psi0"])
    cmd = np.zeros((n_ep, n, CMD_DIM))
    res = np.zeros((n_ep, len(COLUMNS)))
    obs, act = obs_buffers(tier, init, record)
    _kernel(grid, vehicle.params, ipar, fpar, np.ascontiguousarray(init["offsets"]),
            np.ascontiguousarray(init["start"]), np.ascontiguousarray(init["goal"]),
            np.ascontiguousarray(init["t0"], dtype=np.float64), state, cmd, obs, act, res)
    return rollout_results(res, COLUMNS, obs, act, record)


# numba keys a cache entry on this file only; drop it when the engine or the task layer
# changes.
fresh_cache(_kernel, __file__)
