"""UPL — underwater pollution lift to the surface (exactly 5 agents).

Objective
    A polluting object rests on the seafloor (centre ``OBJ_HALF_HEIGHT_M`` above it) at a site
    whose seafloor depth lies in ``[site_depth_m - SITE_DEPTH_SPAN_M, site_depth_m]`` (never
    below the grid's deepest current level). It carries ``N_SLOTS = 5`` attachment slots on a
    ring of radius ``SLOT_RING_M``, ``SLOT_RISE_M`` above its centre (adjacent slots 3.5 m
    apart). The five vehicles start APART from it: near the surface (``START_DEPTH_M``), at
    ``[START_RING_FRAC * start_distance_m, start_distance_m]`` horizontally from the site, each
    with a straight, clear descent to it. They must approach, attach, then lift the object
    cooperatively to the surface while holding it over the site against the currents.
Physics (the environment; identical for every method)
    * Attach: an unattached agent that stays within ``attach_radius_m`` of the same free slot
      for ``attach_dwell_s`` consecutive seconds latches onto it. Any agent may take any free
      slot (slots are >= 3.5 m apart, so at most one is in reach). An attached agent detaches
      (and must attach again) when it is more than ``detach_radius_m`` from its slot.
    * Lift: while at least ``quorum`` agents are attached, the object and the attached agents
      form one assembly. After every agent's own step (:func:`~oneocean.tasks.common.advance_agent`:
      dynamics, current, feasibility, energy), the assembly moves by the attached agents' mean
      displacement plus the sink of the object's net weight, ``w_load dt`` downward with
      ``w_load = sink_speed_ms * N_SLOTS / n_attached`` (the weight is shared by the attached
      agents: with all five the team must out-pull ``sink_speed_ms``). Each attached agent is
      displaced by (assembly displacement - mean agent displacement), i.e. it carries its share
      of the load; a correction that would make the agent's position infeasible is skipped.
      The seafloor stops the assembly: while the object rests on the floor and the team does
      not pull it up, it stays put (static friction) and so does the assembly's mean.
      (The default vehicle's heave is thrust-limited to ~0.7 m/s through the water in the
      rigid-body models, so the tiers keep ``sink_speed_ms`` well below it; the 3-DoF model
      holds its depth and cannot do this task.)
    * Without the quorum a suspended object sinks at ``sink_speed_ms`` and drifts with the
      current at its own depth; on the floor it rests. Land and the grid edge block it.
Success
    The object's centre is at depth <= ``success_depth_m`` while within ``hold_radius_m``
    (horizontally) of the site, i.e. over the waiting recovery vessel; checked after every
    step, the episode stops there. ``reset`` raises ConfigError unless the success depth is
    reachable: the slots must stay in the water there (``success_depth_m >= SLOT_RISE_M``) and
    the site deeper than the success depth (the reference's Tier 2/3 were not).
Metrics
    ``lift_success`` (primary, 0/1), ``final_object_depth_m`` (object centre depth at the end,
    m), ``attach_time_s`` (first time the quorum was attached, s; the time limit if never),
    ``object_drift_m`` (horizontal distance of the object from the site at the end, m).
Methods (task logic; the environment above does not depend on it)
    Assignment: greedy nearest (agent, slot) pairs at the start; an agent whose slot was taken
    by another retargets the nearest free slot. Unattached agents seek their slot with P-control
    (cruise speed), feed-forward of the probed current and of the object's last velocity.
    (``oracle``: crab steering, :func:`~oneocean.tasks.common.seek_max`.)
    Attached agents hold their slot until the quorum is attached, then lift: desired ground
    velocity = slot tracking + hold (P toward the site, capped at ``HOLD_SPEED_MS``) + full
    upward speed; the horizontal part (incl. the current feed-forward) has priority and the
    vertical part gets the rest of the speed budget.
    ``heuristic``: speed budget ``CRUISE_FRAC * v_max``, probed current with noise
    ``probe_noise_ms``. ``oracle``: exact current, full ``v_max``, same logic.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..engine import dynamics as dyn
from ..engine import status as st
from ..engine._jit import hot_kernel
from ..engine.constraints import (DEFAULT_LAND_THRESHOLD, check_move, feasibility,
                                  min_pairwise_distance)
from ..engine.grid import sample_elevation, sample_elevation_points
from ..errors import ConfigError
from .common import (HEURISTIC, OK, STANDARD, advance_agent, current_at, episode_generators,
                     episode_steps, fresh_cache, method_id, need_tier, obs_buffers, observe,
                     path_clear, rollout_results, seek, seek_max, sensed_current, set_velocity_cmd,
                     start_times)

TASK_ID = "UPL"
METRICS = ("lift_success", "final_object_depth_m", "attach_time_s", "object_drift_m")
COLUMNS = STANDARD + METRICS

#: Team size (one agent per attachment slot).
N_SLOTS = 5
#: Object centre height above the seafloor when resting, m.
OBJ_HALF_HEIGHT_M = 0.5
#: Radius of the ring of attachment slots around the object's vertical axis, m.
SLOT_RING_M = 3.0
#: Height of the slots above the object's centre, m (slot depth = object depth - this).
SLOT_RISE_M = 1.5
#: Seafloor-depth span of the site: depth in [site_depth_m - span, site_depth_m], m.
SITE_DEPTH_SPAN_M = 15.0
#: Start depth of the agents (launched from the surface), m.
START_DEPTH_M = 1.0
#: Start distances are uniform in [START_RING_FRAC, 1] * start_distance_m.
START_RING_FRAC = 0.7
#: Minimum separation of the start positions, m.
START_SEPARATION_M = 6.0
#: Seafloor clearance of the feasibility check (agents), m (engine default).
CLEARANCE_M = 1.0
#: Extra altitude margin required at every slot of a sampled site, m.
SLOT_MARGIN_M = 0.5
#: Heuristic speed budget as a fraction of v_max.
CRUISE_FRAC = 0.75
#: Slot-tracking proportional gain, s-1.
KP = 0.6
#: Hold (object over the site) proportional gain, s-1, and its speed cap, m s-1.
KP_HOLD = 0.1
HOLD_SPEED_MS = 0.5

_I_MODEL, _I_METHOD, _I_STEPS, _I_SEED, _I_QUORUM = range(5)
(_F_DT, _F_VMAX, _F_SPEED, _F_KP, _F_NOISE, _F_LAND, _F_CLEAR, _F_ATT_R, _F_DWELL, _F_DET_R,
 _F_SINK, _F_SUCC_D, _F_HOLD_R, _F_KPH, _F_HOLD_V) = range(15)
_C = {k: i for i, k in enumerate(COLUMNS)}
_C_SUCCESS, _C_T, _C_E, _C_COLL, _C_VIOL = (_C[k] for k in STANDARD)
_C_LIFT, _C_DEPTH, _C_ATT_T, _C_DRIFT = (_C[k] for k in METRICS)

_TIER_KEYS = ("current_gain", "time_limit_s", "probe_noise_ms", "site_depth_m",
              "start_distance_m", "attach_radius_m", "attach_dwell_s", "detach_radius_m",
              "sink_speed_ms", "quorum", "hold_radius_m", "success_depth_m")


def slot_offsets(phase: float = 0.0) -> np.ndarray:
    """Attachment-slot offsets from the object's centre, (N_SLOTS, 3) m (x, y, z).

    Slot k sits at compass angle ``phase + 2 pi k / N_SLOTS`` on the ring, ``SLOT_RISE_M``
    above the centre (smaller depth).
    """
    a = phase + 2.0 * np.pi * np.arange(N_SLOTS) / N_SLOTS
    return np.stack([SLOT_RING_M * np.sin(a), np.full(N_SLOTS, -SLOT_RISE_M),
                     SLOT_RING_M * np.cos(a)], axis=1)


def check_reachable(tier: dict, grid=None) -> None:
    """Raise ConfigError unless the tier's success depth can be reached (see module doc)."""
    sd = float(tier["success_depth_m"])
    if sd < SLOT_RISE_M:
        raise ConfigError(f"task {TASK_ID}: success_depth_m={sd:g} m is unreachable: the slots "
                          f"sit {SLOT_RISE_M:g} m above the object's centre and agents cannot "
                          "leave the water")
    lo = float(tier["site_depth_m"]) - SITE_DEPTH_SPAN_M
    if lo - OBJ_HALF_HEIGHT_M <= sd:
        raise ConfigError(f"task {TASK_ID}: site_depth_m={tier['site_depth_m']} leaves sites "
                          f"at or above the success depth {sd:g} m")
    q = int(tier["quorum"])
    if not 1 <= q <= N_SLOTS:
        raise ConfigError(f"task {TASK_ID}: quorum={q} outside [1, {N_SLOTS}]")
    if float(tier["detach_radius_m"]) < float(tier["attach_radius_m"]):
        raise ConfigError(f"task {TASK_ID}: detach_radius_m < attach_radius_m")
    if grid is not None and float(tier["site_depth_m"]) > float(grid.depth[-1]):
        raise ConfigError(f"task {TASK_ID}: site_depth_m={tier['site_depth_m']} m is below the "
                          f"grid's deepest current level ({float(grid.depth[-1]):g} m)")


def _site_candidates(grid, rng, lo: float, hi: float, n: int = 4096) -> np.ndarray:
    """Random points (m, 2 columns x, z) in water whose seafloor depth is in [lo, hi]."""
    xz = np.empty((n, 2))
    xz[:, 0] = rng.uniform(grid.x0, grid.x_max, n)
    xz[:, 1] = rng.uniform(grid.z0, grid.z_max, n)
    floor = -sample_elevation_points(grid, xz, np.empty(n))
    xyz = np.stack([xz[:, 0], np.zeros(n), xz[:, 1]], axis=1)
    ok = (feasibility(grid, xyz, DEFAULT_LAND_THRESHOLD, 0.0) == st.OK) & (floor >= lo) & \
        (floor <= hi)
    return xz[ok]


def _try_site(grid, rng, x: float, z: float, start_distance: float):
    """Object centre, slot phase and agent starts for a site at (x, z), or None."""
    floor = -float(sample_elevation_points(grid, np.array([[x, z]]), np.empty(1))[0])
    obj = np.array([x, floor - OBJ_HALF_HEIGHT_M, z])
    phase = rng.uniform(0.0, 2.0 * np.pi)
    slots = obj + slot_offsets(phase)
    if np.any(feasibility(grid, slots, DEFAULT_LAND_THRESHOLD, CLEARANCE_M + SLOT_MARGIN_M)
              != st.OK):
        return None
    above = np.array([x, obj[1] - SLOT_RISE_M, z])
    starts = np.empty((N_SLOTS, 3))
    got = 0
    for _ in range(60 * N_SLOTS):
        r = start_distance * rng.uniform(START_RING_FRAC, 1.0)
        a = rng.uniform(0.0, 2.0 * np.pi)
        p = np.array([x + r * math.sin(a), START_DEPTH_M, z + r * math.cos(a)])
        if got and np.min(np.linalg.norm(starts[:got] - p, axis=1)) < START_SEPARATION_M:
            continue
        if feasibility(grid, p[None], DEFAULT_LAND_THRESHOLD, CLEARANCE_M)[0] != st.OK:
            continue
        if not path_clear(grid, p, above, CLEARANCE_M, DEFAULT_LAND_THRESHOLD, spacing_m=5.0):
            continue
        starts[got] = p
        got += 1
        if got == N_SLOTS:
            return obj, phase, starts
    return None


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the object's site, its slots, the agents' starts and the start time per episode.

    Parameters
    ----------
    grid : Grid
    tier : dict
        Tier parameters (see ``data/tasks/UPL.yaml``) plus ``dt_s``.
    n_agents : int
        Must be ``N_SLOTS`` (5).
    n_episodes, seed : int

    Returns
    -------
    dict
        ``obj0`` (E, 3) object centre, m; ``slot_off`` (E, 5, 3) slot offsets from the centre,
        m; ``pos0`` (E, 5, 3) agent starts, m; ``psi0`` (E, 5) headings toward the site, rad;
        ``t0`` (E,) start times, s.

    Raises
    ------
    ConfigError
        Wrong team size, missing or unreachable tier parameters, or no valid site.
    """
    if int(n_agents) != N_SLOTS:
        raise ConfigError(f"task {TASK_ID}: needs exactly {N_SLOTS} agents, got {n_agents}")
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    check_reachable(tier, grid)
    hi = float(tier["site_depth_m"])
    lo = hi - SITE_DEPTH_SPAN_M
    dist = float(tier["start_distance_m"])
    rngs = episode_generators(seed, n_episodes)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    obj0 = np.empty((n_episodes, 3))
    slot_off = np.empty((n_episodes, N_SLOTS, 3))
    pos0 = np.empty((n_episodes, N_SLOTS, 3))
    for e, rng in enumerate(rngs):
        found = None
        for _ in range(8):
            for x, z in _site_candidates(grid, rng, lo, hi)[:50]:
                found = _try_site(grid, rng, float(x), float(z), dist)
                if found is not None:
                    break
            if found is not None:
                break
        if found is None:
            raise ConfigError(f"task {TASK_ID} reset (episode {e}): no site with seafloor depth "
                              f"in [{lo:g}, {hi:g}] m, feasible slots and clear descents from "
                              f"{dist:g} m found; the grid has no such water for this tier")
        obj0[e], phase, pos0[e] = found
        slot_off[e] = slot_offsets(phase)
    d = obj0[:, None, :] - pos0
    psi0 = np.arctan2(d[..., 0], d[..., 2])
    return {"obj0": obj0, "slot_off": slot_off, "pos0": pos0, "psi0": psi0, "t0": t0}


@hot_kernel  # not inlined: called once per step, keeps the episode kernel's compile time down
def _place_object(grid, ox, oy, oz, nx, ny, nz, land_thr):
    """Move the object from (ox, oy, oz) toward (nx, ny, nz): land and the grid edge block the
    horizontal move, the seafloor stops it (centre >= OBJ_HALF_HEIGHT_M above), the surface
    bounds it. Returns the new position and whether it rests on the floor."""
    if check_move(grid, nx, 0.0, nz, land_thr, -1e9) != st.OK:  # land / outside: stay put
        nx = ox
        nz = oz
    floor = -sample_elevation(grid, nx, nz)
    on_floor = False
    if ny > floor - OBJ_HALF_HEIGHT_M:
        ny = floor - OBJ_HALF_HEIGHT_M
        on_floor = True
    if ny < 0.0:
        ny = 0.0
    return nx, ny, nz, on_floor


@hot_kernel
def _current(grid, x, y, z, t):
    """:func:`~oneocean.tasks.common.current_at`, not inlined (once per step)."""
    return current_at(grid, x, y, z, t)


@hot_kernel
def _feasible(grid, x, y, z, land_thr, clearance):
    """:func:`~oneocean.engine.constraints.check_move` is OK, not inlined."""
    return check_move(grid, x, y, z, land_thr, clearance) == OK


@hot_kernel
def _episode(grid, vp, ipar, fpar, obj0, slot_off, t0, state, cmd, prev, cur, att, owner,
             dwell, dslot, target, obs, act, res, e):
    """Run episode ``e`` (serial) and write row ``e`` of ``res`` (see ``COLUMNS``).

    Work arrays (all indexed ``[e]``): ``state`` (E, 5, STATE_DIM) initial states; ``cmd``
    (E, 5, CMD_DIM); ``prev`` (E, 5, 3) positions before the step; ``cur`` (E, 5, 2) true
    currents; ``att`` (E, 5) int slot of each attached agent (-1 none); ``owner`` (E, 5) int
    agent attached to each slot (-1 none); ``dwell`` (E, 5) s in reach of ``dslot`` (E, 5) int;
    ``target`` (E, 5) int the method's slot assignment.
    """
    model = ipar[_I_MODEL]
    method = ipar[_I_METHOD]
    n_steps = ipar[_I_STEPS]
    seed = ipar[_I_SEED]
    quorum = ipar[_I_QUORUM]
    dt = fpar[_F_DT]
    v_max = fpar[_F_VMAX]
    speed = fpar[_F_SPEED]
    kp = fpar[_F_KP]
    noise = fpar[_F_NOISE]
    land_thr = fpar[_F_LAND]
    clearance = fpar[_F_CLEAR]
    att_r = fpar[_F_ATT_R]
    dwell_s = fpar[_F_DWELL]
    det_r = fpar[_F_DET_R]
    sink = fpar[_F_SINK]
    succ_d = fpar[_F_SUCC_D]
    hold_r = fpar[_F_HOLD_R]
    kph = fpar[_F_KPH]
    hold_v = fpar[_F_HOLD_V]
    n = state.shape[1]
    S = state[e]
    C = cmd[e]
    P = prev[e]
    CU = cur[e]
    A = att[e]
    O = owner[e]
    DW = dwell[e]
    DS = dslot[e]
    TG = target[e]
    off = slot_off[e]
    sx0 = obj0[e, 0]
    sz0 = obj0[e, 2]
    ox = obj0[e, 0]
    oy = obj0[e, 1]
    oz = obj0[e, 2]
    on_floor = True
    vox = 0.0
    voy = 0.0
    voz = 0.0
    for i in range(n):
        A[i] = -1
        O[i] = -1
        DW[i] = 0.0
        DS[i] = -1
        TG[i] = -1
    # method: greedy nearest (agent, slot) assignment
    for _r in range(n):
        best = np.inf
        bi = -1
        bj = -1
        for i in range(n):
            if TG[i] >= 0:
                continue
            for j in range(n):
                taken = False
                for i2 in range(n):
                    if TG[i2] == j:
                        taken = True
                if taken:
                    continue
                d2 = ((S[i, 0] - ox - off[j, 0]) ** 2 + (S[i, 1] - oy - off[j, 1]) ** 2
                      + (S[i, 2] - oz - off[j, 2]) ** 2)
                if d2 < best:
                    best = d2
                    bi = i
                    bj = j
        TG[bi] = bj
    energy = 0.0
    viol = 0
    n_close = 0
    success = False
    t_s = 0.0
    t_att = -1.0
    k = 0
    while k < n_steps and not success:
        t = t0[e] + k * dt
        n_att = 0
        for i in range(n):
            if A[i] >= 0:
                n_att += 1
        lifting = n_att >= quorum
        # hold: desired horizontal velocity of the assembly toward the site (method logic)
        hx = kph * (sx0 - ox)
        hz = kph * (sz0 - oz)
        hn = math.sqrt(hx * hx + hz * hz)
        if hn > hold_v:
            hx *= hold_v / hn
            hz *= hold_v / hn
        # ---- commands (all agents see the state at time t)
        for i in range(n):
            px = S[i, 0]
            py = S[i, 1]
            pz = S[i, 2]
            ce, cn = current_at(grid, px, py, pz, t)
            CU[i, 0] = ce
            CU[i, 1] = cn
            pe, pn = sensed_current(method, ce, cn, noise, seed, e, 2 * (k * n + i))
            j = A[i]
            if j < 0:
                j = TG[i]
                if O[j] >= 0 and O[j] != i:  # taken by a teammate: nearest free slot
                    best = np.inf
                    for j2 in range(n):
                        if O[j2] < 0:
                            d2 = ((px - ox - off[j2, 0]) ** 2 + (py - oy - off[j2, 1]) ** 2
                                  + (pz - oz - off[j2, 2]) ** 2)
                            if d2 < best:
                                best = d2
                                j = j2
                    TG[i] = j
            gx = ox + off[j, 0]
            gy = oy + off[j, 1]
            gz = oz + off[j, 2]
            if A[i] >= 0 and lifting:
                ax = kp * (gx - px) + hx - pe
                az = kp * (gz - pz) + hz - pn
                vy = kp * (gy - py) - speed
                ah = math.sqrt(ax * ax + az * az)
                if ah >= speed:
                    ax *= speed / ah
                    az *= speed / ah
                    ay = 0.0
                else:
                    vb = math.sqrt(speed * speed - ah * ah)
                    ay = min(max(vy, -vb), vb)
            elif method == HEURISTIC:
                ax, ay, az = seek(px, py, pz, gx, gy, gz, speed, kp, pe - vox, pn - voz)
                ay += voy
            else:
                ax, ay, az = seek_max(px, py, pz, gx, gy, gz, speed, kp, pe - vox, pn - voz)
                ay += voy
            observe(obs, act, e, k, i, grid, state, gx, gy, gz, pe, pn, math.nan, ax, ay, az)
            set_velocity_cmd(C[i], ax, ay, az)
        # ---- every agent's own step
        for i in range(n):
            P[i, 0] = S[i, 0]
            P[i, 1] = S[i, 1]
            P[i, 2] = S[i, 2]
            en, code = advance_agent(grid, model, vp, S[i], C[i], CU[i, 0], CU[i, 1], v_max,
                                     dt, land_thr, clearance)
            energy += en
            if code != OK:
                viol += 1
        # ---- the object
        pox = ox
        poy = oy
        poz = oz
        if lifting:
            mx = 0.0
            my = 0.0
            mz = 0.0
            for i in range(n):
                if A[i] >= 0:
                    mx += S[i, 0] - P[i, 0]
                    my += S[i, 1] - P[i, 1]
                    mz += S[i, 2] - P[i, 2]
            mx /= n_att
            my /= n_att
            mz /= n_att
            dy = my + sink * N_SLOTS / n_att * dt
            if not (on_floor and dy >= 0.0):
                ox, oy, oz, on_floor = _place_object(grid, ox, oy, oz, ox + mx, oy + dy,
                                                     oz + mz, land_thr)
            # attached agents carry their share: displaced by (assembly - mean agent) motion
            cx = (ox - pox) - mx
            cy = (oy - poy) - my
            cz = (oz - poz) - mz
            for i in range(n):
                if A[i] >= 0:
                    qx = S[i, 0] + cx
                    qy = S[i, 1] + cy
                    qz = S[i, 2] + cz
                    if qy >= 0.0 and _feasible(grid, qx, qy, qz, land_thr, clearance):
                        S[i, 0] = qx
                        S[i, 1] = qy
                        S[i, 2] = qz
        elif not on_floor:  # suspended without the quorum: sinks and drifts
            ce, cn = _current(grid, ox, oy, oz, t)
            ox, oy, oz, on_floor = _place_object(grid, ox, oy, oz, ox + ce * dt,
                                                 oy + sink * dt, oz + cn * dt, land_thr)
        vox = (ox - pox) / dt
        voy = (oy - poy) / dt
        voz = (oz - poz) / dt
        # ---- attach / detach
        for i in range(n):
            px = S[i, 0]
            py = S[i, 1]
            pz = S[i, 2]
            j = A[i]
            if j >= 0:
                d = math.sqrt((px - ox - off[j, 0]) ** 2 + (py - oy - off[j, 1]) ** 2
                              + (pz - oz - off[j, 2]) ** 2)
                if d > det_r:
                    A[i] = -1
                    O[j] = -1
                    DW[i] = 0.0
                    DS[i] = -1
                continue
            jn = -1
            for j2 in range(n):
                if O[j2] < 0:
                    d = math.sqrt((px - ox - off[j2, 0]) ** 2 + (py - oy - off[j2, 1]) ** 2
                                  + (pz - oz - off[j2, 2]) ** 2)
                    if d <= att_r:
                        jn = j2
            if jn < 0:
                DW[i] = 0.0
                DS[i] = -1
            else:
                if DS[i] == jn:
                    DW[i] += dt
                else:
                    DS[i] = jn
                    DW[i] = dt
                if DW[i] >= dwell_s - 1e-9:
                    A[i] = jn
                    O[jn] = i
        k += 1
        if min_pairwise_distance(S) <= 2.0:
            n_close += 1
        if t_att < 0.0:
            n_att = 0
            for i in range(n):
                if A[i] >= 0:
                    n_att += 1
            if n_att >= quorum:
                t_att = k * dt
        drift = math.sqrt((ox - sx0) ** 2 + (oz - sz0) ** 2)
        if oy <= succ_d and drift <= hold_r:
            success = True
            t_s = k * dt
    res[e, _C_SUCCESS] = 1.0 if success else 0.0
    res[e, _C_T] = t_s if success else n_steps * dt
    res[e, _C_E] = energy
    res[e, _C_COLL] = n_close / k if k > 0 else 0.0
    res[e, _C_VIOL] = viol
    res[e, _C_LIFT] = 1.0 if success else 0.0
    res[e, _C_DEPTH] = oy
    res[e, _C_ATT_T] = t_att if t_att >= 0.0 else n_steps * dt
    res[e, _C_DRIFT] = math.sqrt((ox - sx0) ** 2 + (oz - sz0) ** 2)


@njit(parallel=True, cache=True)
def _kernel(grid, vp, ipar, fpar, obj0, slot_off, t0, state, cmd, prev, cur, att, owner, dwell,
            dslot, target, obs, act, res):
    for e in prange(res.shape[0]):
        _episode(grid, vp, ipar, fpar, obj0, slot_off, t0, state, cmd, prev, cur, att, owner,
                 dwell, dslot, target, obs, act, res, e)


def rollout(grid, tier: dict, init: dict, method: str, dyn_name: str, vehicle,
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
    dyn_name : {"kinematic", "3dof", "4dof", "6dof"}
    vehicle : Vehicle
    seed : int
        Run seed (probe-noise streams).

    Returns
    -------
    dict of (E,) arrays
        ``success`` (bool), ``T_s`` (s), ``E`` (m2 s-1), ``coll_ratio``, ``violations``
        (int) and ``METRICS``.
    """
    need_tier(TASK_ID, tier, *_TIER_KEYS, "dt_s")
    check_reachable(tier)
    dt = float(tier["dt_s"])
    n_ep, n = init["pos0"].shape[:2]
    v_max = float(vehicle.v_max)
    mid = method_id(method)
    ipar = np.array([dyn.model_id(dyn_name), mid,
                     episode_steps(tier), int(seed),
                     int(tier["quorum"])], dtype=np.int64)
    speed = CRUISE_FRAC * v_max if mid == HEURISTIC else v_max
    fpar = np.array([dt, v_max, speed, KP, float(tier["probe_noise_ms"]),
                     DEFAULT_LAND_THRESHOLD, CLEARANCE_M, float(tier["attach_radius_m"]),
                     float(tier["attach_dwell_s"]), float(tier["detach_radius_m"]),
                     float(tier["sink_speed_ms"]), float(tier["success_depth_m"]),
                     float(tier["hold_radius_m"]), KP_HOLD, HOLD_SPEED_MS])
    state = dyn.new_state(n_ep, n, init["pos0"], init["psi0"])
    cmd = np.zeros((n_ep, n, dyn.CMD_DIM))
    prev = np.zeros((n_ep, n, 3))
    cur = np.zeros((n_ep, n, 2))
    ints = [np.zeros((n_ep, n), dtype=np.int64) for _ in range(4)]
    dwell = np.zeros((n_ep, n))
    res = np.zeros((n_ep, len(COLUMNS)))
    obs, act = obs_buffers(tier, init, record)
    _kernel(grid, vehicle.params, ipar, fpar, np.ascontiguousarray(init["obj0"]),
            np.ascontiguousarray(init["slot_off"]),
            np.ascontiguousarray(init["t0"], dtype=np.float64), state, cmd, prev, cur,
            ints[0], ints[1], dwell, ints[2], ints[3], obs, act, res)
    return rollout_results(res, COLUMNS, obs, act, record)


# numba keys a cache entry on this file only; drop it when the engine or the task layer
# changes.
fresh_cache(_kernel, __file__)
