"""FH — fish protection / herding under currents (exactly 8 agents).

Objective
    A school of ``fish_count`` fish (:mod:`oneocean.models.fish`, default parameters: flee
    vehicles within 15 m at up to 1 m/s, cohere, drift with the current) loiters at
    ``FISH_DEPTH_M``; a circular safe zone of radius ``zone_radius_m`` lies
    ``zone_distance_m`` away. The eight vehicles start on a ring ``START_RING_M`` around the
    school at the same depth and must herd the school into the zone. The straight corridor from
    the school to the zone (``CORRIDOR_HALF_WIDTH_M`` either side), the zone and every fish are in
    valid water ``ROUTE_CLEARANCE_M`` above the seafloor.
Fish physics (the environment)
    Every step the current is sampled at each fish (:func:`~oneocean.tasks.common.current_at`
    at ``FISH_DEPTH_M``) and :func:`oneocean.models.fish.step_school` advances the school
    (vehicles' horizontal positions scare it). A fish whose new position is infeasible (land,
    outside the grid, or less than ``FISH_CLEARANCE_M`` above the seafloor at its depth) stays
    at its previous position with zero swim velocity (fish do not beach). The jitter stream of
    episode ``e`` is keyed by ``hash64(seed, e, PURPOSE_TASK_NOISE, 0)``.
Success
    The school's centroid stays inside the safe zone (distance <= ``zone_radius_m``) for
    ``hold_s`` consecutive seconds (checked after every step; the episode stops when the hold
    is complete and ``T_s`` is that time).
Metrics
    ``containment_success`` (primary, 0/1), ``final_centroid_distance_m`` (centroid to zone
    centre at the end, m), ``fraction_inside`` (fraction of fish inside the zone at the end),
    ``school_spread_m`` (RMS distance of the fish from their centroid at the end, m).
Methods (task logic; the environment above does not depend on it)
    Steer from behind: the school should move toward the zone centre at the planned ground
    velocity ``v = min(PUSH_SPEED_MS, KP_PUSH * distance)``; the needed swim is ``w``. The eight
    agents take slots on an arc of ``ARC_RAD`` centred behind the school (opposite to ``w``)
    at ``standoff + SPREAD_GAIN * spread`` from the centroid, where the standoff shrinks from
    ``BACKOFF_M`` (no push needed) to ``STANDOFF_M`` (``|w| >= PUSH_SPEED_MS``). Agents are
    matched to slots in angular order around the school (no crossings) and travel around it
    (waypoints at most 45 degrees of arc ahead on the slot circle), not through it. Each agent
    seeks its waypoint with P-control, feed-forward of the school's velocity (centroid
    displacement over the last step) and of its current probe. The push direction is frozen
    while the centroid is within ``DEADBAND_FRAC * zone_radius_m`` of the centre.
    ``heuristic``: ``w = v`` (the school's drift is ignored); the arc re-aims at once; cruise
    ``CRUISE_FRAC * v_max``; noisy probe (``probe_noise_ms``).
    ``oracle``: ``w = v - c`` with the exact current ``c`` at the centroid, where ``v`` is the
    fastest ground velocity toward the zone with ``|w| <= ORACLE_SWIM_MS`` (the school crabs
    across the current; same ramp); the arc turns at most ``SLEW_RAD_S``; within
    ``ORACLE_I_ZONE`` zone radii an integral action on the school's measured ground-velocity
    error adapts the standoff (removes the steady offset a drifting school settles at); full
    ``v_max``, exact current, crab steering of the vehicles.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..engine import dynamics as dyn
from ..engine import status as st
from ..engine._jit import hot_kernel
from ..engine.constraints import DEFAULT_LAND_THRESHOLD, check_move, feasibility, \
    min_pairwise_distance
from ..engine.rng import hash64
from ..errors import ConfigError
from ..models import fish as _fish
from ..models.fish import (fish_params, fraction_inside_circle, init_school, school_centroid,
                           school_spread, step_school)
from .common import (HEURISTIC, OK, PURPOSE_TASK_NOISE, STANDARD, advance_agent, current_at,
                     episode_generators, episode_steps, fresh_cache, method_id, need_tier,
                     obs_buffers, observe, path_clear, rollout_results, sample_route, seek,
                     seek_max, sensed_current, set_velocity_cmd, start_times)

TASK_ID = "FH"
METRICS = ("containment_success", "final_centroid_distance_m", "fraction_inside",
           "school_spread_m")
COLUMNS = STANDARD + METRICS

#: Team size.
N_AGENTS = 8
#: Depth of the school and of the vehicles, m.
FISH_DEPTH_M = 2.0
#: Seafloor clearance of a fish position, m.
FISH_CLEARANCE_M = 1.0
#: Seafloor clearance of the route/zone sampling (seafloor >= FISH_DEPTH_M + this), m.
ROUTE_CLEARANCE_M = 3.0
#: Half-width of the school-to-zone corridor that must be water, m.
CORRIDOR_HALF_WIDTH_M = 20.0
#: Radius of the initial school disc, m.
SCHOOL_RADIUS_M = 8.0
#: The agents start at distances in START_RING_M from the school centre, m.
START_RING_M = (35.0, 50.0)
#: Minimum separation of the start positions, m.
START_SEPARATION_M = 5.0
#: Seafloor clearance of the vehicles' feasibility check, m (engine default).
CLEARANCE_M = 1.0
#: Heuristic cruise speed as a fraction of v_max.
CRUISE_FRAC = 0.75
#: Slot-tracking proportional gain, s-1.
KP = 0.5
#: Herding arc: total angle (rad), standoff (m) and its growth with the school's spread.
ARC_RAD = math.radians(200.0)
STANDOFF_M = 6.0
SPREAD_GAIN = 1.5
#: Standoff when no push is needed (the school is where it should be), m.
BACKOFF_M = 14.0
#: Planned school ground speed toward the zone centre: min(PUSH_SPEED_MS, KP_PUSH * distance).
PUSH_SPEED_MS = 0.7
KP_PUSH = 0.05
#: The push direction is frozen while the centroid is within this fraction of the zone radius
#: (heuristic, oracle).
DEADBAND_FRAC = (0.5, 0.25)
#: Largest turn rate of the push direction, rad s-1 (heuristic: none, the arc re-aims at once;
#: oracle: the arc rotates around the school).
SLEW_RAD_S = (math.inf, 0.2)
#: Oracle: largest swim speed (relative to the water) it plans for the school, m s-1 (the
#: fish swim at most 1 m s-1).
ORACLE_SWIM_MS = 0.85
#: Oracle: rate of its standoff adaptation to the school's swim-speed error, m per m s-1 per s.
ORACLE_KS = 3.0
#: Oracle: smallest adapted standoff, m.
ORACLE_STANDOFF_MIN_M = 3.0
#: Oracle: its integral action is on within this many zone radii of the zone centre.
ORACLE_I_ZONE = 3.0

_I_MODEL, _I_METHOD, _I_STEPS, _I_SEED = range(4)
(_F_DT, _F_VMAX, _F_SPEED, _F_KP, _F_NOISE, _F_LAND, _F_CLEAR, _F_ZONE_R, _F_HOLD, _F_ARC,
 _F_STAND, _F_SGAIN, _F_BACK, _F_PUSH, _F_OSWIM, _F_KPP, _F_DEADB, _F_OKS, _F_SMIN,
 _F_SLEW) = range(20)
_C = {k: i for i, k in enumerate(COLUMNS)}
_C_SUCCESS, _C_T, _C_E, _C_COLL, _C_VIOL = (_C[k] for k in STANDARD)
_C_CONT, _C_DIST, _C_FRAC, _C_SPREAD = (_C[k] for k in METRICS)

_TIER_KEYS = ("current_gain", "time_limit_s", "probe_noise_ms", "fish_count",
              "zone_distance_m", "zone_radius_m", "hold_s")


def _ok(grid, xz: np.ndarray, clearance: float) -> np.ndarray:
    """Feasibility (bool, (n,)) of horizontal points ``xz`` (n, 2) at ``FISH_DEPTH_M``."""
    xyz = np.stack([xz[:, 0], np.full(len(xz), FISH_DEPTH_M), xz[:, 1]], axis=1)
    return feasibility(grid, xyz, DEFAULT_LAND_THRESHOLD, clearance) == st.OK


def _try_episode(grid, rng, n_fish: int, distance: float, radius: float):
    """School, zone and agent starts for one episode, or None if this draw is invalid."""
    route = sample_route(grid, rng, 1, distance, (FISH_DEPTH_M, FISH_DEPTH_M),
                         ROUTE_CLEARANCE_M, land_threshold=DEFAULT_LAND_THRESHOLD,
                         what=f"task {TASK_ID} reset")
    s0 = route[0]
    z0 = route[1]
    d = (z0 - s0) / distance
    nrm = np.array([d[2], 0.0, -d[0]])
    for side in (-1.0, 1.0):
        off = side * CORRIDOR_HALF_WIDTH_M * nrm
        if not path_clear(grid, s0 + off, z0 + off, ROUTE_CLEARANCE_M, DEFAULT_LAND_THRESHOLD):
            return None
    a = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    rim = np.stack([z0[0] + radius * np.sin(a), z0[2] + radius * np.cos(a)], axis=1)
    if not np.all(_ok(grid, rim, ROUTE_CLEARANCE_M)):
        return None
    fx, fz, _, _ = init_school(n_fish, (s0[0], s0[2]), SCHOOL_RADIUS_M, rng)
    if not np.all(_ok(grid, np.stack([fx, fz], axis=1), FISH_CLEARANCE_M)):
        return None
    starts = np.empty((N_AGENTS, 3))
    got = 0
    for _ in range(100 * N_AGENTS):
        r = rng.uniform(*START_RING_M)
        th = rng.uniform(0.0, 2.0 * np.pi)
        p = np.array([s0[0] + r * math.sin(th), FISH_DEPTH_M, s0[2] + r * math.cos(th)])
        if got and np.min(np.linalg.norm(starts[:got] - p, axis=1)) < START_SEPARATION_M:
            continue
        if feasibility(grid, p[None], DEFAULT_LAND_THRESHOLD, CLEARANCE_M)[0] != st.OK:
            continue
        starts[got] = p
        got += 1
        if got == N_AGENTS:
            return fx, fz, np.array([z0[0], z0[2]]), starts
    return None


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the school, the safe zone, the agents' starts and the start time per episode.

    Parameters
    ----------
    grid : Grid
    tier : dict
        Tier parameters (see ``data/tasks/FH.yaml``) plus ``dt_s``.
    n_agents : int
        Must be ``N_AGENTS`` (8).
    n_episodes, seed : int

    Returns
    -------
    dict
        ``fish0`` (E, 2, F) fish positions (row 0 x, row 1 z), m; ``zone`` (E, 2) zone
        centre (x, z), m; ``pos0`` (E, 8, 3) agent starts, m; ``psi0`` (E, 8) headings toward
        the school, rad; ``t0`` (E,) start times, s.

    Raises
    ------
    ConfigError
        Wrong team size, missing tier keys, fewer than 50 fish, or no valid geometry.
    """
    if int(n_agents) != N_AGENTS:
        raise ConfigError(f"task {TASK_ID}: needs exactly {N_AGENTS} agents, got {n_agents}")
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    n_fish = int(tier["fish_count"])
    if n_fish < 50:
        raise ConfigError(f"task {TASK_ID}: fish_count={n_fish} < 50")
    dist = float(tier["zone_distance_m"])
    radius = float(tier["zone_radius_m"])
    rngs = episode_generators(seed, n_episodes)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    fish0 = np.empty((n_episodes, 2, n_fish))
    zone = np.empty((n_episodes, 2))
    pos0 = np.empty((n_episodes, N_AGENTS, 3))
    for e, rng in enumerate(rngs):
        found = None
        for _ in range(200):
            found = _try_episode(grid, rng, n_fish, dist, radius)
            if found is not None:
                break
        if found is None:
            raise ConfigError(f"task {TASK_ID} reset (episode {e}): no school/zone geometry with "
                              f"a {2 * CORRIDOR_HALF_WIDTH_M:g} m wide water corridor of "
                              f"{dist:g} m and a {radius:g} m zone found in 200 draws")
        fish0[e, 0], fish0[e, 1], zone[e], pos0[e] = found
    cx = fish0[:, 0].mean(axis=1)
    cz = fish0[:, 1].mean(axis=1)
    psi0 = np.arctan2(cx[:, None] - pos0[..., 0], cz[:, None] - pos0[..., 2])
    return {"fish0": fish0, "zone": zone, "pos0": pos0, "psi0": psi0, "t0": t0}


@hot_kernel(inline="always")
def _wrap(a):
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@hot_kernel
def _current(grid, x, y, z, t):
    """:func:`~oneocean.tasks.common.current_at`, not inlined (once per step)."""
    return current_at(grid, x, y, z, t)


@njit(cache=True)
def _fish_step(grid, fx, fz, fvx, fvz, ax, az, cx, cz, fp, fseed, k, t, dt, land_thr, gx, gz,
               gvx, gvz):
    """Sample the current at every fish, advance the school into ``g*``, keep beached fish."""
    for f in range(fx.shape[0]):
        ce, cn = current_at(grid, fx[f], FISH_DEPTH_M, fz[f], t)
        cx[f] = ce
        cz[f] = cn
    step_school(fx, fz, fvx, fvz, ax, az, cx, cz, fp, fseed, k, dt, gx, gz, gvx, gvz)
    for f in range(fx.shape[0]):
        if check_move(grid, gx[f], FISH_DEPTH_M, gz[f], land_thr, FISH_CLEARANCE_M) != st.OK:
            gx[f] = fx[f]
            gz[f] = fz[f]
            gvx[f] = 0.0
            gvz[f] = 0.0


@hot_kernel
def _episode(grid, vp, ipar, fpar, fp, zone, t0, state, cmd, cur, apos, order, keys, fa, fb,
             fc, obs, act, res, e):
    """Run episode ``e`` (serial) and write row ``e`` of ``res`` (see ``COLUMNS``).

    Work arrays (indexed ``[e]``): ``state`` (E, 8, STATE_DIM) initial states; ``cmd``
    (E, 8, CMD_DIM); ``cur`` (E, 8, 2) currents at the agents; ``apos`` (E, 2, 8) agent x/z
    seen by the fish; ``order`` (E, 8) int and ``keys`` (E, 8) angular sort; ``fa``, ``fb``
    (E, 4, F) fish state double buffer (x, z, vx, vz; ``fa`` holds the initial school);
    ``fc`` (E, 2, F) currents at the fish.
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
    land_thr = fpar[_F_LAND]
    clearance = fpar[_F_CLEAR]
    zr = fpar[_F_ZONE_R]
    hold_s = fpar[_F_HOLD]
    arc = fpar[_F_ARC]
    stand = fpar[_F_STAND]
    sgain = fpar[_F_SGAIN]
    back = fpar[_F_BACK]
    push = fpar[_F_PUSH]
    oswim = fpar[_F_OSWIM]
    kpp = fpar[_F_KPP]
    deadband = fpar[_F_DEADB]
    oks = fpar[_F_OKS]
    stand_min = fpar[_F_SMIN]
    slew = fpar[_F_SLEW]
    n = state.shape[1]
    S = state[e]
    C = cmd[e]
    CU = cur[e]
    AX = apos[e, 0]
    AZ = apos[e, 1]
    OR = order[e]
    KY = keys[e]
    A = fa[e]
    B = fb[e]
    zx = zone[e, 0]
    zz = zone[e, 1]
    fseed = hash64(seed, e, PURPOSE_TASK_NOISE, 0)
    cxs, czs = school_centroid(A[0], A[1])
    vcx = 0.0
    vcz = 0.0
    th_back = 0.0
    r_int = 0.0
    energy = 0.0
    viol = 0
    n_close = 0
    inside_s = 0.0
    success = False
    t_s = 0.0
    k = 0
    cur_is_a = True
    while k < n_steps and not success:
        t = t0[e] + k * dt
        F = A if cur_is_a else B
        G = B if cur_is_a else A
        spread = school_spread(F[0], F[1])
        dxz = zx - cxs
        dzz = zz - czs
        dist = math.sqrt(dxz * dxz + dzz * dzz)
        # push direction (method logic): the swim ``w`` the school needs. Heuristic: move toward
        # the zone centre at min(push, KP_PUSH * dist), the school's drift ignored. Oracle:
        # fastest ground speed toward the zone whose swim, against the exact current at the
        # centroid, is at most ``oswim`` (crab steering of the school), same ramp near the zone
        vd = push if kpp * dist > push else kpp * dist
        ux = dxz / dist if dist > 1e-9 else 0.0
        uz = dzz / dist if dist > 1e-9 else 0.0
        if method == HEURISTIC:
            wx = ux * vd
            wz = uz * vd
        else:
            ce, cn = _current(grid, cxs, FISH_DEPTH_M, czs, t)
            cpar = ce * ux + cn * uz
            qx = ce - cpar * ux
            qz = cn - cpar * uz
            q2 = qx * qx + qz * qz
            if q2 >= oswim * oswim:
                f = oswim / math.sqrt(q2)
                wx = -qx * f
                wz = -qz * f
            else:
                vg = cpar + math.sqrt(oswim * oswim - q2)
                if vg > kpp * dist:
                    vg = kpp * dist
                wx = ux * vg - ce
                wz = uz * vg - cn
        wn = math.sqrt(wx * wx + wz * wz)
        # compass angle of "behind the school": frozen near the zone centre (dead band) so the
        # arc does not flip around the school when the centroid crosses the centre, and turned
        # at most ``slew`` rad/s so the agents circle around the school, not through it
        if k == 0:
            th_back = math.atan2(-wx, -wz)
        elif dist > deadband * zr:
            dth = _wrap(math.atan2(-wx, -wz) - th_back)
            if dth > slew * dt:
                dth = slew * dt
            elif dth < -slew * dt:
                dth = -slew * dt
            th_back = _wrap(th_back + dth)
        # close in when a strong push is needed, back off toward the flee radius otherwise
        g = wn / (push if method == HEURISTIC else oswim)
        if g > 1.0:
            g = 1.0
        r_adj = stand + (back - stand) * (1.0 - g)
        if method != HEURISTIC:
            # oracle, near the zone: integral action on the school's ground-velocity error
            # along w (closer when the school is slower than planned), removing the
            # steady-state offset a drifting school has under the open-loop standoff
            if dist < ORACLE_I_ZONE * zr and k > 0 and wn > 1e-9:
                r_int += oks * ((vcx - ce - wx) * wx + (vcz - cn - wz) * wz) / wn * dt
                if r_int < stand_min - r_adj:
                    r_int = stand_min - r_adj
                elif r_int > back - r_adj:
                    r_int = back - r_adj
            else:
                r_int = 0.0
            r_adj += r_int
        r_slot = r_adj + sgain * spread
        # match agents to arc slots in angular order around the school
        for i in range(n):
            OR[i] = i
            KY[i] = _wrap(math.atan2(S[i, 0] - cxs, S[i, 2] - czs) - th_back)
        for i in range(1, n):
            j = i
            while j > 0 and KY[OR[j - 1]] > KY[OR[j]]:
                tmp = OR[j - 1]
                OR[j - 1] = OR[j]
                OR[j] = tmp
                j -= 1
        for r in range(n):
            i = OR[r]
            px = S[i, 0]
            py = S[i, 1]
            pz = S[i, 2]
            ce, cn = current_at(grid, px, py, pz, t)
            CU[i, 0] = ce
            CU[i, 1] = cn
            pe, pn = sensed_current(method, ce, cn, noise, seed, e, 2 * (k * n + i))
            delta = -0.5 * arc + arc * r / (n - 1)
            # go around the school: at most 45 degrees of arc toward the slot per waypoint
            ang_i = KY[i]
            dang = delta - ang_i
            if dang > 0.25 * math.pi:
                dang = 0.25 * math.pi
            elif dang < -0.25 * math.pi:
                dang = -0.25 * math.pi
            a = th_back + ang_i + dang
            gx = cxs + r_slot * math.sin(a)
            gz = czs + r_slot * math.cos(a)
            if method == HEURISTIC:
                ax, ay, az = seek(px, py, pz, gx, FISH_DEPTH_M, gz, speed, kp, pe - vcx,
                                  pn - vcz)
            else:
                ax, ay, az = seek_max(px, py, pz, gx, FISH_DEPTH_M, gz, speed, kp, pe - vcx,
                                      pn - vcz)
            observe(obs, act, e, k, i, grid, state, gx, FISH_DEPTH_M, gz, pe, pn, math.nan, ax, ay,
                    az)
            set_velocity_cmd(C[i], ax, ay, az)
        for i in range(n):
            AX[i] = S[i, 0]
            AZ[i] = S[i, 2]
        # the school reacts to the vehicles' positions at time t
        _fish_step(grid, F[0], F[1], F[2], F[3], AX, AZ, fc[e, 0], fc[e, 1], fp, fseed, k,
                   t, dt, land_thr, G[0], G[1], G[2], G[3])
        for i in range(n):
            en, code = advance_agent(grid, model, vp, S[i], C[i], CU[i, 0], CU[i, 1], v_max,
                                     dt, land_thr, clearance)
            energy += en
            if code != OK:
                viol += 1
        cur_is_a = not cur_is_a
        nx, nz = school_centroid(G[0], G[1])
        vcx = (nx - cxs) / dt
        vcz = (nz - czs) / dt
        cxs = nx
        czs = nz
        k += 1
        if min_pairwise_distance(S) <= 2.0:
            n_close += 1
        if math.sqrt((cxs - zx) ** 2 + (czs - zz) ** 2) <= zr:
            inside_s += dt
            if inside_s >= hold_s - 1e-9:
                success = True
                t_s = k * dt
        else:
            inside_s = 0.0
    F = A if cur_is_a else B
    res[e, _C_SUCCESS] = 1.0 if success else 0.0
    res[e, _C_T] = t_s if success else n_steps * dt
    res[e, _C_E] = energy
    res[e, _C_COLL] = n_close / k if k > 0 else 0.0
    res[e, _C_VIOL] = viol
    res[e, _C_CONT] = 1.0 if success else 0.0
    res[e, _C_DIST] = math.sqrt((cxs - zx) ** 2 + (czs - zz) ** 2)
    res[e, _C_FRAC] = fraction_inside_circle(F[0], F[1], zx, zz, zr)
    res[e, _C_SPREAD] = school_spread(F[0], F[1])


@njit(parallel=True, cache=True)
def _kernel(grid, vp, ipar, fpar, fp, zone, t0, state, cmd, cur, apos, order, keys, fa, fb, fc,
            obs, act, res):
    for e in prange(res.shape[0]):
        _episode(grid, vp, ipar, fpar, fp, zone, t0, state, cmd, cur, apos, order, keys, fa,
                 fb, fc, obs, act, res, e)


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
        Run seed (probe-noise and fish-jitter streams).

    Returns
    -------
    dict of (E,) arrays
        ``success`` (bool), ``T_s`` (s), ``E`` (m2 s-1), ``coll_ratio``, ``violations``
        (int) and ``METRICS``.
    """
    need_tier(TASK_ID, tier, *_TIER_KEYS, "dt_s")
    dt = float(tier["dt_s"])
    n_ep, n = init["pos0"].shape[:2]
    n_fish = init["fish0"].shape[2]
    v_max = float(vehicle.v_max)
    mid = method_id(method)
    ipar = np.array([dyn.model_id(dyn_name), mid,
                     episode_steps(tier), int(seed)],
                    dtype=np.int64)
    speed = CRUISE_FRAC * v_max if mid == HEURISTIC else v_max
    fpar = np.array([dt, v_max, speed, KP, float(tier["probe_noise_ms"]),
                     DEFAULT_LAND_THRESHOLD, CLEARANCE_M, float(tier["zone_radius_m"]),
                     float(tier["hold_s"]), ARC_RAD, STANDOFF_M, SPREAD_GAIN, BACKOFF_M,
                     PUSH_SPEED_MS, ORACLE_SWIM_MS, KP_PUSH, DEADBAND_FRAC[mid], ORACLE_KS,
                     ORACLE_STANDOFF_MIN_M, SLEW_RAD_S[mid]])
    state = dyn.new_state(n_ep, n, init["pos0"], init["psi0"])
    cmd = np.zeros((n_ep, n, dyn.CMD_DIM))
    cur = np.zeros((n_ep, n, 2))
    apos = np.zeros((n_ep, 2, n))
    order = np.zeros((n_ep, n), dtype=np.int64)
    keys = np.zeros((n_ep, n))
    fa = np.zeros((n_ep, 4, n_fish))
    fa[:, :2] = init["fish0"]
    fb = np.zeros((n_ep, 4, n_fish))
    fc = np.zeros((n_ep, 2, n_fish))
    res = np.zeros((n_ep, len(COLUMNS)))
    obs, act = obs_buffers(tier, init, record)
    _kernel(grid, vehicle.params, ipar, fpar, fish_params(), np.ascontiguousarray(init["zone"]),
            np.ascontiguousarray(init["t0"], dtype=np.float64), state, cmd, cur, apos, order,
            keys, fa, fb, fc, obs, act, res)
    return rollout_results(res, COLUMNS, obs, act, record)


# numba keys a cache entry on this file only; drop it when the engine, the task layer or
# the model changes.
fresh_cache(_kernel, __file__, _fish.__file__)
