"""FH — fish protection / herding under currents (exactly 8 agents).

Objective
    A school of ``fish_count`` fish (:mod:`oneocean.models.fish`, default parameters: flee
    vehicles within 15 m at up to 0.8 m/s, cohere, drift with the current) loiters at
    ``FISH_DEPTH_M``; a circular safe zone of radius ``zone_radius_m`` lies
    ``zone_distance_m`` away. The eight vehicles start on a ring ``START_RING_M`` around the
    school at the same depth and must herd the school into the zone. The straight corridor
    from the school to the zone (``CORRIDOR_HALF_WIDTH_M`` either side), the zone and every
    fish are in valid water ``ROUTE_CLEARANCE_M`` above the seafloor.
Fish physics (the environment)
    Every step, before the agents move (``pre_step``), the current is sampled at each fish
    (:func:`~oneocean.tasks.common.current_at` at ``FISH_DEPTH_M``) and
    :func:`oneocean.models.fish.step_school` advances the school (the vehicles' horizontal
    positions at the start of the step scare it). A fish whose new position is infeasible
    (land, outside the grid, or less than ``FISH_CLEARANCE_M`` above the seafloor at its
    depth) stays at its previous position with zero swim velocity (fish do not beach). The
    jitter stream of the cell's episode ``e`` is keyed by
    ``hash64(seed, e, PURPOSE_TASK_NOISE, 0)`` (``seed``: the run seed). After the moves
    (``post_step``) the school's true centroid and its velocity over the step (``W.school``:
    judging, snapshots, and what a method given the target perceives) are updated.
Perception (every non-oracle method; :func:`sonar`)
    Each ROV's imaging sonar (``sensors.yaml`` ``perception.fh_school``, read by
    :func:`school_sensor`) reports, at the start and after every step, the offset of the
    school's echo centroid from the ROV and the echo's extent (``W.sfix``): the fish within
    ``range_m`` of it, weighted by a fluctuating echo intensity (exponential, coefficient of
    variation ``echo_cv``) and by the shadowing of the fish in front
    (``exp(-(d - d_near) / extinction_m)``), so the centroid is pulled toward the sensor by a
    fraction of the school's extent; its offset gets the sonar's range and bearing noise
    (:func:`~oneocean.sensing.kernels.polar_fix`). The method places the readings where each
    ROV knows it is and tracks the school (:mod:`oneocean.methods.heuristic.fh`). A method
    given the target (``SensingParams.true_target``: the oracle, the ``true_target``
    ablation) perceives the true school instead; ``_episode`` copies the run seed and the
    sensing flags the hooks need into ``W.sinfo``.
Success
    The school's centroid stays inside the safe zone (distance <= ``zone_radius_m``) for
    ``hold_s`` consecutive seconds (checked after every step; the episode stops when the hold
    is complete and ``T_s`` is that time).
Metrics
    ``containment_success`` (primary, 0/1), ``final_centroid_distance_m`` (centroid to zone
    centre at the end, m), ``fraction_inside`` (fraction of fish inside the zone at the end),
    ``school_spread_m`` (RMS distance of the fish from their centroid at the end, m).
Methods (task logic; the environment above does not depend on it)
    :mod:`oneocean.methods.heuristic.fh` (herding from behind on an arc around the school;
    both at the vehicle's full speed, the school crabbed across the current, standoff adapted
    to its swim speed). Heuristic and oracle differ in information only: the heuristic
    tracks the school from the team's sonar readings, takes the team's mean current estimate
    at the school and navigates by the sensor models of :mod:`oneocean.sensing`; the oracle
    knows the school, the current at its centroid and its position.
    The observation's goal cue is the agent's herding waypoint (``W.tgt``, written by the
    method's ``plan``; the zone centre for external policies).

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset``; ``FHParams`` / ``FHWork`` and ``make``; the env hooks
    ``begin``, ``pre_step`` (the fish step), ``cue``, ``post_step``, ``finish``;
    ``seed_episode`` (called by the compiled loop, :mod:`oneocean.kernels.fh`, before the
    episode: derives the episode's fish-jitter key ``W.fseed`` from the run seed and copies
    the seed and the sensing flags into ``W.sinfo``; the env and policy hooks do not see the
    loop's params).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numba import njit

from ..engine import status as st
from ..engine._jit import hot_kernel
from ..engine.constraints import DEFAULT_LAND_THRESHOLD, check_move
from ..engine.status import OK
from ..engine.grid import locate_time, sample_current_at, synthetic_tide
from ..engine.rng import PURPOSE_TASK, hash64, uniform01
from ..errors import ConfigError, NotApplicable
from ..models.fish import (fish_params, fraction_inside_circle, init_school, school_centroid,
                           school_spread, step_school_into)
from ..sensing import perception, perception_values
from ..sensing.kernels import polar_fix
from .common import feasible_codes
from .common import (_SPAWN_BATCH, PURPOSE_RESET, PURPOSE_TASK_NOISE, STANDARD, _call,
                     _route_row, _segment_clear, fresh_cache, need_tier, path_clear,
                     sample_route, start_times)
from ..engine import libm
from ..engine import streams

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
#: Random stream of the sonar's per-fish echo intensities (one draw per fish, agent and
#: ping; the range and bearing noise of a reading is ``polar_fix``'s PURPOSE_PERCEPTION).
PURPOSE_SCHOOL_ECHO = PURPOSE_TASK + 24

_C_CONT, _C_DIST, _C_FRAC, _C_SPREAD = (len(STANDARD) + i for i in range(len(METRICS)))

_TIER_KEYS = ("current_band", "time_limit_s", "fish_count",
              "zone_distance_m", "zone_radius_m", "hold_s")


def _ok(grid, xz: np.ndarray, clearance: float) -> np.ndarray:
    """Feasibility (bool, (n,)) of horizontal points ``xz`` (n, 2) at ``FISH_DEPTH_M``."""
    xyz = np.stack([xz[:, 0], np.full(len(xz), FISH_DEPTH_M), xz[:, 1]], axis=1)
    return feasible_codes(grid, xyz, DEFAULT_LAND_THRESHOLD, clearance) == st.OK


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
    rim = np.stack([z0[0] + radius * libm.sin(a), z0[2] + radius * libm.cos(a)], axis=1)
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
        if feasible_codes(grid, p[None], DEFAULT_LAND_THRESHOLD, CLEARANCE_M)[0] != st.OK:
            continue
        starts[got] = p
        got += 1
        if got == N_AGENTS:
            return fx, fz, np.array([z0[0], z0[2]]), starts
    return None


#: Draws of an episode's geometry before the region is declared unable to host it.
_DRAWS = 200
#: :func:`_episodes` statuses: a geometry, none in ``_DRAWS`` draws, a route sampler failure.
_FOUND, _NONE, _NO_ROUTE = 0, 1, 2


@hot_kernel
def _episodes_kernel(grid, stv, n_fish, distance, radius, rim_s, rim_c, spacing, cand, route,
                     starts, fish0, zone, pos0, status):
    """:func:`_try_episode` up to ``_DRAWS`` times from each episode's stream ``stv[e]``,
    compiled: the same draws in the same order and the same checks (:func:`_route_row` for
    the route, :func:`_segment_clear` for the corridor, ``check_move`` for the rim, the
    fish and the starts; the rim's angles' sines and cosines given). ``status[e]``:
    ``_FOUND`` (the episode in ``fish0[e]``, ``zone[e]``, ``pos0[e]``), ``_NONE`` or
    ``_NO_ROUTE``."""
    lt = DEFAULT_LAND_THRESHOLD
    y = FISH_DEPTH_M
    for e in range(stv.shape[0]):
        status[e] = _NONE
        for _ in range(_DRAWS):
            if _route_row(grid, stv, e, 1, distance, y, y, ROUTE_CLEARANCE_M, math.pi, lt,
                          False, 2000, spacing, cand, route, 0) != 0:
                status[e] = _NO_ROUTE
                break
            sx, sy, sz = route[0, 0, 0], route[0, 0, 1], route[0, 0, 2]
            gx, gy, gz = route[0, 1, 0], route[0, 1, 1], route[0, 1, 2]
            dx = (gx - sx) / distance
            dz = (gz - sz) / distance
            ok = True
            for side in (-1.0, 1.0):
                w = side * CORRIDOR_HALF_WIDTH_M
                ox, oy, oz = w * dz, w * 0.0, w * -dx
                ax, ay, az = sx + ox, sy + oy, sz + oz
                bx, by, bz = gx + ox, gy + oy, gz + oz
                ex, ey, ez = bx - ax, by - ay, bz - az
                n = max(2, int(math.ceil(math.sqrt(ex * ex + ey * ey + ez * ez) / spacing)) + 1)
                if not _segment_clear(grid, ax, ay, az, bx, by, bz, n, lt, ROUTE_CLEARANCE_M):
                    ok = False
                    break
            if not ok:
                continue
            for k in range(rim_s.shape[0]):
                if check_move(grid, gx + radius * rim_s[k], y, gz + radius * rim_c[k], lt,
                              ROUTE_CLEARANCE_M) != OK:
                    ok = False
                    break
            if not ok:
                continue
            # init_school: radius * sqrt(u) with u ~ U(0, 1) for every fish, then the angles
            for f in range(n_fish):
                fish0[e, 0, f] = SCHOOL_RADIUS_M * math.sqrt(streams.uniform(stv, e, 0.0, 1.0))
            for f in range(n_fish):
                th = streams.uniform(stv, e, 0.0, 2.0 * math.pi)
                r = fish0[e, 0, f]
                fish0[e, 0, f] = sx + r * math.cos(th)
                fish0[e, 1, f] = sz + r * math.sin(th)
            for f in range(n_fish):
                if check_move(grid, fish0[e, 0, f], y, fish0[e, 1, f], lt,
                              FISH_CLEARANCE_M) != OK:
                    ok = False
                    break
            if not ok:
                continue
            got = 0
            for _t in range(100 * N_AGENTS):
                r = streams.uniform(stv, e, START_RING_M[0], START_RING_M[1])
                th = streams.uniform(stv, e, 0.0, 2.0 * math.pi)
                px = sx + r * math.sin(th)
                pz = sz + r * math.cos(th)
                near = False
                for a in range(got):
                    # starts share the depth: |p - s| is sqrt(dx^2 + dz^2) in either order
                    # of NumPy's sum over (x, y, z) (the y term is 0)
                    qx = starts[a, 0] - px
                    qy = starts[a, 1] - y
                    qz = starts[a, 2] - pz
                    if math.sqrt(qx * qx + (qy * qy + qz * qz)) < START_SEPARATION_M:
                        near = True
                        break
                if near:
                    continue
                if check_move(grid, px, y, pz, lt, CLEARANCE_M) != OK:
                    continue
                starts[got, 0] = px
                starts[got, 1] = y
                starts[got, 2] = pz
                got += 1
                if got == N_AGENTS:
                    break
            if got < N_AGENTS:
                continue
            zone[e, 0] = gx
            zone[e, 1] = gz
            for a in range(N_AGENTS):
                pos0[e, a, 0] = starts[a, 0]
                pos0[e, a, 1] = starts[a, 1]
                pos0[e, a, 2] = starts[a, 2]
            status[e] = _FOUND
            break
    return status


def _episodes(grid, stv, n_fish: int, distance: float, radius: float, fish0, zone,
              pos0) -> np.ndarray:
    """Every episode's geometry from its stream (``stv``, advanced in place) in one compiled
    call: :func:`_episodes_kernel`'s statuses, the geometries written into ``fish0``,
    ``zone``, ``pos0``."""
    a = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    spacing = min(20.0, 0.5 * min(float(grid.dx), float(grid.dz)))       # path_clear's
    return _call(_episodes_kernel, grid, stv, int(n_fish), float(distance), float(radius),
                 libm.sin(a), libm.cos(a), spacing, np.empty((_SPAWN_BATCH, 3)),
                 np.zeros((1, 2, 3)), np.empty((N_AGENTS, 3)), fish0, zone, pos0,
                 np.empty(stv.shape[0], dtype=np.int64))


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the school, the safe zone, the agents' starts and the start time per episode.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    tier : dict
        Tier parameters (see ``data/tasks/FH.yaml``) plus ``dt_s``.
    n_agents : int
        Must be ``N_AGENTS`` (8).
    n_episodes : int
        Number of episodes E.
    seed : int
        Run seed (each episode draws from its own reset stream).

    Returns
    -------
    dict
        ``fish0`` (E, 2, F) fish positions (row 0 x, row 1 z), m; ``zone`` (E, 2) zone
        centre (x, z), m; ``pos0`` (E, 8, 3) agent starts, m; ``psi0`` (E, 8) headings toward
        the school, rad; ``t0`` (E,) start times, s; ``regime_points`` (E, 2, 3) the school's
        centroid and the zone centre at the agents' depth, m (``Cell.reset``).

    Raises
    ------
    ConfigError
        Wrong team size, missing tier keys or fewer than 50 fish.
    NotApplicable
        No valid school/zone geometry for some episode in 200 draws.
    """
    if int(n_agents) != N_AGENTS:
        raise ConfigError(f"task {TASK_ID}: needs exactly {N_AGENTS} agents, got {n_agents}")
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    n_fish = int(tier["fish_count"])
    if n_fish < 50:
        raise ConfigError(f"task {TASK_ID}: fish_count={n_fish} < 50")
    dist = float(tier["zone_distance_m"])
    radius = float(tier["zone_radius_m"])
    rngs = streams.episode_states(seed, n_episodes, PURPOSE_RESET)   # one stream per episode
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    fish0 = np.empty((n_episodes, 2, n_fish))
    zone = np.empty((n_episodes, 2))
    pos0 = np.empty((n_episodes, N_AGENTS, 3))
    first = rngs.copy()                     # each episode's stream where its draws begin
    status = _episodes(grid, rngs, n_fish, dist, radius, fish0, zone, pos0)
    for e in np.flatnonzero(status):
        if status[e] == _NO_ROUTE:
            # the route sampler's own error, with its message: the episode's draws replayed
            # in Python up to it (for the first such episode, as the draws in order would)
            rng = streams.generator(first[e])
            for _ in range(_DRAWS):
                if _try_episode(grid, rng, n_fish, dist, radius) is not None:
                    break
        raise NotApplicable(f"task {TASK_ID} reset (episode {e}): no school/zone geometry with "
                            f"a {2 * CORRIDOR_HALF_WIDTH_M:g} m wide water corridor of "
                            f"{dist:g} m and a {radius:g} m zone found in {_DRAWS} draws")
    cx = fish0[:, 0].mean(axis=1)
    cz = fish0[:, 1].mean(axis=1)
    psi0 = libm.arctan2(cx[:, None] - pos0[..., 0], cz[:, None] - pos0[..., 2])
    # the current regime is judged where the school drifts: its centroid and the zone
    y = float(pos0[0, 0, 1]) if n_episodes else 0.0
    pts = np.stack([np.column_stack([cx, np.full_like(cx, y), cz]),
                    np.column_stack([zone[:, 0], np.full_like(cx, y), zone[:, 1]])], axis=1)
    return {"fish0": fish0, "zone": zone, "pos0": pos0, "psi0": psi0, "t0": t0,
            "regime_points": pts}




class FHParams(NamedTuple):
    """FH's params (one rollout).

    Attributes
    ----------
    zone_r : float
        Safe-zone radius, m.
    hold : float
        Hold time inside the zone for success, s.
    dt : float
        Step, s.
    depth : float
        Depth of the school and of the vehicles, m.
    land_thr : float
        Land-mask threshold of the fish feasibility check.
    fp : (n_params,) float64
        Fish-model parameters (:func:`oneocean.models.fish.fish_params`).
    sonar_r : float
        The school's perception (``sensors.yaml`` ``perception.fh_school``; every non-oracle
        method, each agent's imaging sonar every step): detection range, m.
    range_std : float
        Range noise of the echo centroid, m.
    bearing_std : float
        Bearing noise, rad.
    echo_cv : float
        Coefficient of variation of a fish's echo intensity per ping.
    ext_len : float
        Shadowing: extinction length behind the nearest fish, m.
    """
    zone_r: float           # safe-zone radius, m
    hold: float             # hold time inside the zone for success, s
    dt: float               # step, s
    depth: float            # depth of the school and of the vehicles, m
    land_thr: float         # land-mask threshold of the fish feasibility check
    fp: np.ndarray          # fish-model parameters (models.fish.fish_params)
    # the school's perception model (sensors.yaml perception.fh_school; every non-oracle
    # method): each agent's imaging sonar, every step
    sonar_r: float          # detection range, m
    range_std: float        # range noise of the echo centroid, m
    bearing_std: float      # bearing noise, rad
    echo_cv: float          # coefficient of variation of a fish's echo intensity per ping
    ext_len: float          # shadowing: extinction length behind the nearest fish, m


class FHWork(NamedTuple):
    """FH's per-episode work arrays (F fish, 8 agents).

    Attributes
    ----------
    zone : (E, 2) float64
        Zone centre (x, z), m.
    fish : (E, 2, 4, F) float64
        Fish state double buffer (x, z (m), vx, vz (m s-1)).
    fcur : (E,) int64
        Index of the current buffer of ``fish``.
    fc : (E, 2, F) float64
        Currents at the fish (east, north), m s-1.
    apos : (E, 2, 8) float64
        Agent x / z seen by the fish, m.
    fseed : (E,) uint64
        Fish-jitter key (set by :func:`seed_episode` from the run seed).
    school : (E, 5) float64
        The truth (judging, snapshots; the oracle's perception): centroid x, z (m), its
        velocity over the last step (m s-1), time inside the zone (s).
    done : (E,) int64
        1 once the hold is complete.
    sinfo : (E, 3) int64
        The method's information, copied by :func:`seed_episode` from the loop's params:
        run seed, ``true_target``, ``true_current``.
    sfix : (E, 8, 4) float64
        Each agent's latest sonar reading of the school: seen (1/0), offset of the echo
        centroid from the agent x, z (m), extent (weighted RMS radius, m); unused with
        ``true_target``.
    sest : (E, 6) float64
        The method's school estimate (:mod:`oneocean.methods.heuristic.fh`, as the rest):
        centroid x, z (m), velocity (m s-1), spread (m), 1 once initialised.
    herd : (E, 3) float64
        Angle behind the school (rad), integral standoff (m), slot radius (m).
    order : (E, 8) int64
        Agents in angular order around the school.
    keys : (E, 8) float64
        Angle of each agent relative to the arc centre, rad.
    rank : (E, 8) int64
        Arc slot of each agent.
    tgt : (E, 8, 2) float64
        Waypoint (x, z) of each agent, m (plan token, goal cue).
    cest : (E, 8, 2) float64
        Each agent's current estimate at its last step, m s-1.
    skey : (E,) int64
        The cell's episode whose sonar streams row ``e`` draws (:func:`seed_episode`:
        ``LP.e0 + e``; :func:`make`: ``e``).
    fscr : (E, 7, F) float64
        Scratch of the school's step (:func:`~oneocean.models.fish.step_school_into`).
    """
    zone: np.ndarray        # (E, 2) zone centre (x, z), m
    fish: np.ndarray        # (E, 2, 4, F) fish state double buffer (x, z, vx, vz)
    fcur: np.ndarray        # (E,) int64 index of the current buffer of ``fish``
    fc: np.ndarray          # (E, 2, F) currents at the fish, m s-1
    apos: np.ndarray        # (E, 2, 8) agent x/z seen by the fish, m
    fseed: np.ndarray       # (E,) uint64 fish-jitter key (set by _episode from the run seed)
    school: np.ndarray      # (E, 5) the truth (judging, snapshots; the oracle's perception):
                            #   centroid x, z (m), its velocity over the last step (m s-1),
                            #   time inside the zone (s)
    done: np.ndarray        # (E,) int64 1 once the hold is complete
    sinfo: np.ndarray       # (E, 3) int64 the method's information, copied by _episode from
                            #   the loop's params: run seed, true_target, true_current
    sfix: np.ndarray        # (E, 8, 4) each agent's latest sonar reading of the school: seen
                            #   (1/0), offset of the echo centroid from the agent x, z (m),
                            #   extent (weighted RMS radius, m); unused with true_target
    # method state (oneocean.methods.heuristic.fh)
    sest: np.ndarray        # (E, 6) the method's school estimate: centroid x, z (m), velocity
                            #   (m s-1), spread (m), 1 once initialised
    herd: np.ndarray        # (E, 3) angle behind the school (rad), integral standoff (m),
                            #   slot radius (m)
    order: np.ndarray       # (E, 8) int64 agents in angular order around the school
    keys: np.ndarray        # (E, 8) angle of each agent relative to the arc centre, rad
    rank: np.ndarray        # (E, 8) int64 arc slot of each agent
    tgt: np.ndarray         # (E, 8, 2) waypoint (x, z) of each agent, m (plan token, goal cue)
    cest: np.ndarray        # (E, 8, 2) each agent's current estimate at its last step, m s-1
    skey: np.ndarray        # (E,) int64 the cell's episode whose sonar streams row e draws
                            #   (set by _episode: LP.e0 + e; make: e)
    fscr: np.ndarray        # (E, 7, F) scratch of the school's step (step_school_into)


def school_sensor(path=None) -> tuple[float, float, float, float, float]:
    """The school's perception model (``sensors.yaml`` ``perception.fh_school``).

    Parameters
    ----------
    path : str or Path, optional
        Sensor table (default: the shipped ``data/sensors.yaml``).

    Returns
    -------
    tuple of float
        Detection range (m), range noise (m), bearing noise (rad), echo-intensity
        coefficient of variation (-), extinction length (m): the tail of ``FHParams``.

    Raises
    ------
    ConfigError
        A missing parameter, or a range or extinction length that is not > 0 (one line
        naming the key).
    """
    rng, rstd, bdeg, cv, ext = perception_values(
        perception("fh_school", path), "fh_school",
        ("range_m", "range_std_m", "bearing_std_deg", "echo_cv", "extinction_m"))
    for key, v in (("range_m", rng), ("extinction_m", ext)):
        if not v > 0.0:
            raise ConfigError(f"sensors.yaml: 'perception.fh_school.{key}' must be > 0, "
                              f"got {v!r}")
    return rng, rstd, math.radians(bdeg), cv, ext


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    Parameters
    ----------
    grid : Grid
        The rollout's grid export (the ablations' forcing included).
    tier : dict
        Tier parameters plus ``dt_s``.
    init : dict
        The reset's dict (:func:`reset`).

    Returns
    -------
    P : FHParams
        The env's typed scalars.
    W : FHWork
        The env's per-episode work arrays (the herding waypoints start at the zone centre).

    Raises
    ------
    ConfigError
        Missing tier parameters, or a bad school perception model (:func:`school_sensor`).
    """
    need_tier(TASK_ID, tier, *_TIER_KEYS, "dt_s")
    n_ep, n = init["pos0"].shape[:2]
    fish0 = np.asarray(init["fish0"], dtype=np.float64)
    n_fish = fish0.shape[2]
    zone = np.ascontiguousarray(init["zone"], dtype=np.float64)
    fish = np.zeros((n_ep, 2, 4, n_fish))
    fish[:, 0, :2] = fish0
    P = FHParams(float(tier["zone_radius_m"]), float(tier["hold_s"]), float(tier["dt_s"]),
                 FISH_DEPTH_M, DEFAULT_LAND_THRESHOLD, fish_params(), *school_sensor())
    W = FHWork(zone, fish, np.zeros(n_ep, dtype=np.int64), np.zeros((n_ep, 2, n_fish)),
               np.zeros((n_ep, 2, n)), np.zeros(n_ep, dtype=np.uint64), np.zeros((n_ep, 5)),
               np.zeros(n_ep, dtype=np.int64), np.zeros((n_ep, 3), dtype=np.int64),
               np.zeros((n_ep, n, 4)), np.zeros((n_ep, 6)), np.zeros((n_ep, 3)),
               np.zeros((n_ep, n), dtype=np.int64), np.zeros((n_ep, n)),
               np.zeros((n_ep, n), dtype=np.int64),
               np.ascontiguousarray(np.repeat(zone[:, None, :], n, axis=1)),
               np.zeros((n_ep, n, 2)), np.arange(n_ep, dtype=np.int64),
               np.zeros((n_ep, 7, n_fish)))
    return P, W


@njit(cache=True)
def _fish_step(grid, fx, fz, fvx, fvz, ax, az, cx, cz, fp, fseed, k, t, dt, land_thr, gx, gz,
               gvx, gvz, scr):
    """Sample the current at every fish, advance the school into ``g*``, keep beached fish.
    (:func:`~.common.current_at` at one time ``t``: the time located and the synthetic tide
    taken once per step, not per fish; the same arithmetic.) ``scr``: the school step's
    scratch, (7, F) float64."""
    ti0, ti1, wt = locate_time(grid, t)
    te, tn = synthetic_tide(grid, t)
    for f in range(fx.shape[0]):
        ce, cn = sample_current_at(grid, fx[f], FISH_DEPTH_M, fz[f], ti0, ti1, wt)
        cx[f] = ce + te
        cz[f] = cn + tn
    step_school_into(fx, fz, fvx, fvz, ax, az, cx, cz, fp, fseed, k, dt, gx, gz, gvx, gvz,
                     scr)
    for f in range(fx.shape[0]):
        if check_move(grid, gx[f], FISH_DEPTH_M, gz[f], land_thr, FISH_CLEARANCE_M) != st.OK:
            gx[f] = fx[f]
            gz[f] = fz[f]
            gvx[f] = 0.0
            gvz[f] = 0.0



@hot_kernel(inline="always")
def sonar(P, W, state, e, ping):
    """Every agent's sonar reading of the school (``sensors.yaml`` ``perception.fh_school``)
    into ``W.sfix[e]``, from the true agents and fish.

    The echo centroid of agent ``i`` is the mean of the fish within ``P.sonar_r`` of it,
    weighted by each fish's echo intensity ``max(0, 1 + echo_cv (X - 1))`` (``X`` an
    exponential draw of stream ``PURPOSE_SCHOOL_ECHO``) times the shadowing
    ``exp(-(d - d_near) / ext_len)`` (``d`` the fish's range, ``d_near`` the nearest fish's);
    its offset from the agent gets the range and bearing noise of
    :func:`~oneocean.sensing.kernels.polar_fix` (counters ``2 (ping N + i)`` and ``+1``). The
    extent is the weighted RMS radius about the echo centroid, m. No fish in range: no
    reading (``sfix[e, i, 0] = 0``). With ``true_target`` the method reads the truth instead
    and nothing is drawn.

    Parameters
    ----------
    P : FHParams
        The task's params (:func:`make`).
    W : FHWork
        The task's per-episode work arrays (:func:`make`); ``sfix[e]`` written.
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    e : int
        Episode index.
    ping : int
        Number of the reading (0 at the start, ``k + 1`` after step ``k``), so that no two
        draws share a counter.
    """
    if W.sinfo[e, 1] != 0:
        return
    S = state[e]
    n = S.shape[0]
    F = W.fish[e, W.fcur[e]]
    fx = F[0]
    fz = F[1]
    nf = fx.shape[0]
    seed = W.sinfo[e, 0]
    ep = W.skey[e]
    r2 = P.sonar_r * P.sonar_r
    for i in range(n):
        ax = S[i, 0]
        az = S[i, 2]
        W.sfix[e, i, 0] = 0.0
        near2 = math.inf
        for f in range(nf):
            d2 = (fx[f] - ax) ** 2 + (fz[f] - az) ** 2
            if d2 < near2:
                near2 = d2
        if not near2 < r2:
            continue
        near = math.sqrt(near2)
        base = (ping * n + i) * nf
        sw = 0.0
        sx = 0.0
        sz = 0.0
        ss = 0.0
        for f in range(nf):
            dx = fx[f] - ax
            dz = fz[f] - az
            d2 = dx * dx + dz * dz
            if d2 < r2:
                u = uniform01(seed, ep, PURPOSE_SCHOOL_ECHO, base + f)
                amp = 1.0 + P.echo_cv * (-math.log(1.0 - u) - 1.0)
                if amp > 0.0:
                    w = amp * math.exp(-(math.sqrt(d2) - near) / P.ext_len)
                    sw += w
                    sx += w * dx
                    sz += w * dz
                    ss += w * d2
        if not sw > 0.0:
            continue
        cx = sx / sw
        cz = sz / sw
        v = ss / sw - cx * cx - cz * cz
        mx, mz = polar_fix(seed, ep, 2 * (ping * n + i), cx, cz, P.range_std, P.bearing_std)
        W.sfix[e, i, 0] = 1.0
        W.sfix[e, i, 1] = mx
        W.sfix[e, i, 2] = mz
        W.sfix[e, i, 3] = math.sqrt(v) if v > 0.0 else 0.0


@hot_kernel(inline="always")
def begin(grid, P, W, state, e):
    """Start the school's truth (centroid, no velocity, no time inside), clear the
    method's school estimate and take the first sonar readings.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``state`` holds the start.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : FHParams
        The task's params (:func:`make`).
    W : FHWork
        The task's per-episode work arrays (:func:`make`).
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    e : int
        Episode index.

    Returns
    -------
    bool
        False: the episode starts.
    """
    F = W.fish[e, 0]
    cx, cz = school_centroid(F[0], F[1])
    W.fcur[e] = 0
    W.school[e, 0] = cx
    W.school[e, 1] = cz
    W.school[e, 2] = 0.0
    W.school[e, 3] = 0.0
    W.school[e, 4] = 0.0
    W.done[e] = 0
    W.sest[e, 5] = 0.0
    sonar(P, W, state, e, 0)
    return False


@hot_kernel(inline="always")
def pre_step(grid, P, W, state, e, k, t):
    """The fish step: the school reacts to the vehicles' positions at time ``t`` (into the
    other buffer of ``W.fish``).

    Env hook (:mod:`oneocean.tasks.loop`), before the agents act.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : FHParams
        The task's params (:func:`make`).
    W : FHWork
        The task's per-episode work arrays (:func:`make`).
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    e : int
        Episode index.
    k : int
        Step index.
    t : float
        Time at the start of the step, s since the grid's ``time0`` (``t0[e] + k dt``).
    """
    S = state[e]
    AX = W.apos[e, 0]
    AZ = W.apos[e, 1]
    c = W.fcur[e]
    F = W.fish[e, c]
    G = W.fish[e, 1 - c]
    for i in range(S.shape[0]):
        AX[i] = S[i, 0]
        AZ[i] = S[i, 2]
    _fish_step(grid, F[0], F[1], F[2], F[3], AX, AZ, W.fc[e, 0], W.fc[e, 1], P.fp, W.fseed[e],
               k, t, P.dt, P.land_thr, G[0], G[1], G[2], G[3], W.fscr[e])


@hot_kernel(inline="always")
def cue(grid, P, W, state, e, k, i):
    """The goal cue: the agent's herding waypoint (``W.tgt``) at the school's depth.

    Env hook (:mod:`oneocean.tasks.loop`): the observation's goal cue and probe.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : FHParams
        The task's params (:func:`make`).
    W : FHWork
        The task's per-episode work arrays (:func:`make`).
    state : (E, N, STATE_DIM) float64
        The vehicle states the method knows (its navigation estimate; the truth for
        the oracle); layout: :mod:`oneocean.engine.dynamics`.
    e : int
        Episode index.
    k : int
        Step index.
    i : int
        Agent index.

    Returns
    -------
    gx, gy, gz : float
        The goal cue, world m.
    probe : float
        NaN (the task has no field).
    """
    return W.tgt[e, i, 0], P.depth, W.tgt[e, i, 1], math.nan


@hot_kernel(inline="always")
def post_step(grid, P, W, state, prev, e, k, t):
    """Swap the fish buffers, update the school's truth and the sonar readings, and time
    the hold inside the zone.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``: the
    time inside the zone grows by ``dt`` while the centroid is within ``P.zone_r`` of the
    zone centre and restarts from 0 when it leaves.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : FHParams
        The task's params (:func:`make`).
    W : FHWork
        The task's per-episode work arrays (:func:`make`).
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    prev : (E, N, 3) float64
        Positions before the step, world m.
    e : int
        Episode index.
    k : int
        Step index.
    t : float
        Time at the start of the step, s since the grid's ``time0`` (``t0[e] + k dt``).

    Returns
    -------
    bool
        True (STOP) once the hold reaches ``P.hold``.
    """
    c = 1 - W.fcur[e]
    W.fcur[e] = c
    G = W.fish[e, c]
    sc = W.school[e]
    dt = P.dt
    cxs = sc[0]
    czs = sc[1]
    nx, nz = school_centroid(G[0], G[1])
    sc[2] = (nx - cxs) / dt
    sc[3] = (nz - czs) / dt
    sc[0] = nx
    sc[1] = nz
    zx = W.zone[e, 0]
    zz = W.zone[e, 1]
    sonar(P, W, state, e, k + 1)   # what the sensors see of the school after the step
    if math.sqrt((nx - zx) ** 2 + (nz - zz) ** 2) <= P.zone_r:
        sc[4] += dt
        if sc[4] >= P.hold - 1e-9:
            W.done[e] = 1
            return True
    else:
        sc[4] = 0.0
    return False


@hot_kernel(inline="always")
def finish(grid, P, W, state, e, k, row):
    """Write the FH metrics.

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : FHParams
        The task's params (:func:`make`).
    W : FHWork
        The task's per-episode work arrays (:func:`make`).
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    e : int
        Episode index.
    k : int
        Steps the episode ran.
    row : (C,) float64
        Episode ``e``'s result row (``COLUMNS``); the hook writes the task's metric columns.

    Returns
    -------
    bool
        Success: the hold was completed.
    """
    F = W.fish[e, W.fcur[e]]
    zx = W.zone[e, 0]
    zz = W.zone[e, 1]
    cxs = W.school[e, 0]
    czs = W.school[e, 1]
    success = W.done[e] != 0
    row[_C_CONT] = 1.0 if success else 0.0
    row[_C_DIST] = math.sqrt((cxs - zx) ** 2 + (czs - zz) ** 2)
    row[_C_FRAC] = fraction_inside_circle(F[0], F[1], zx, zz, P.zone_r)
    row[_C_SPREAD] = school_spread(F[0], F[1])
    return success


@hot_kernel(inline="always")
def seed_episode(W, LP, e):
    """Before the episode, from the loop's params (which only they carry): the fish-jitter
    key of the episode and the run seed and sensing flags the sonar's draws and the method's
    information need. The kernel calls it before the loop.

    Parameters
    ----------
    W : FHWork
        The task's per-episode work arrays; ``fseed[e]``, ``skey[e]`` and ``sinfo[e]``
        written.
    LP : LoopParams
        The loop's params (:class:`oneocean.tasks.loop.LoopParams`: ``seed``, ``e0``,
        ``sens``).
    e : int
        Episode index (row ``e`` is the cell's episode ``LP.e0 + e``).
    """
    W.fseed[e] = hash64(LP.seed, LP.e0 + e, PURPOSE_TASK_NOISE, 0)
    W.skey[e] = LP.e0 + e
    W.sinfo[e, 0] = LP.seed
    W.sinfo[e, 1] = LP.sens.true_target
    W.sinfo[e, 2] = LP.sens.true_current


fresh_cache(_episodes_kernel, __file__, Path(__file__).resolve().parents[1] / "models" /
            "fish.py")
