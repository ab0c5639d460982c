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
    :func:`school_sensor`) reports, at every step's observation, the offset of the school's
    echo centroid from the ROV and the echo's extent: the fish within ``range_m`` of it,
    weighted by a fluctuating echo intensity (exponential, coefficient of variation
    ``echo_cv``) and by the shadowing of the fish in front (``exp(-(d - d_near) /
    extinction_m)``), so the centroid is pulled toward the sensor by a fraction of the
    school's extent; its offset gets the sonar's range and bearing noise
    (:func:`~oneocean.sensing.kernels.polar_fix`). A method given the target
    (``SensingParams.true_target``: the oracle, the ``true_target`` ablation; ``brief`` sets
    it in ``W.sinfo``) perceives the true school instead, at any range.
Success
    The school's centroid stays inside the safe zone (distance <= ``zone_radius_m``) for
    ``hold_s`` consecutive seconds (checked after every step; the episode stops when the hold
    is complete and ``T_s`` is that time).
Metrics
    ``containment_success`` (primary, 0/1), ``final_centroid_distance_m`` (centroid to zone
    centre at the end, m), ``fraction_inside`` (fraction of fish inside the zone at the end),
    ``school_spread_m`` (RMS distance of the fish from their centroid at the end, m).
Briefing (:class:`FHBriefing`, after the common fields of :mod:`oneocean.tasks.public`)
    The zone (``zone``, ``zone_radius``), the hold time, the school's and the team's depth,
    the school as reported when the team was deployed (``school0``: its centroid;
    ``school_radius``: the disc it occupied), ``fish_count``, the species' flee radius and
    sustained swim speed (the fish model's), the sonar's range (:data:`BRIEF_FIELDS`).
Observation
    The task's own fields (:data:`OBS_EXTRA`) are each agent's sonar reading: whether it sees
    the school, the offset of the echo centroid from the agent (m) and the echo's extent (m);
    NaN where it sees none. A method given the target reads, at any range, the offset of the
    true centroid from the agent's known position and the school's RMS spread. The team
    observation (:class:`FHTeamObs`, :data:`TEAM_FIELDS`) is the
    team's fused fix of the school (the mean of the agents' readings placed at their
    navigation estimates; the truth for a method given the target), its velocity (the truth
    for a method given the target, else NaN: a sonar gives positions) and the current at
    the school's last fix (the truth for a method given the true current, else the
    mission's forecast there: no vehicle samples the water at the school's centre).
    The cue is the task's herding station (:func:`stations`): agent i's station on an arc
    of ``CUE_ARC_DEG`` behind the school's last team fix (opposite the zone centre), agents
    matched to stations in angular order around the school, at most ``CUE_STEP_DEG`` of arc
    ahead of the agent's own bearing (a follower goes around the school, not through it),
    ``CUE_STANDOFF_M`` plus the school's extent out while the school is ``CUE_RAMP_M`` or
    more from the zone centre, backing off linearly to ``CUE_BACKOFF_M`` at the centre; the
    arc's direction is frozen within ``CUE_DEADBAND_FRAC`` of the zone radius of the centre.
    A follower of the cue pushes the school toward the zone.
Methods
    :mod:`oneocean.methods.heuristic.fh` (herding from behind on an arc around the school;
    both at the vehicle's full speed, the school crabbed across the current, standoff adapted
    to its swim speed). Heuristic and oracle differ in information only: the heuristic
    tracks the school from the team's sonar readings, takes the team's mean current estimate
    at the school and navigates by the sensor models of :mod:`oneocean.sensing`; the oracle
    perceives the school exactly and knows the current at its centroid and its own position.

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset``; ``FHParams`` / ``FHWork`` and ``make``; the public
    view: the briefing (``FHBriefing``, ``BRIEF_FIELDS``, ``brief``), the observation's own
    fields (``OBS_EXTRA``) and the team observation (``FHTeamObs``, ``TEAM_FIELDS``,
    ``team_obs``); the env hooks ``begin``, ``pre_step`` (the fish step), ``cue``, ``sense``
    (the sonar, the team fix, the current at the school, the stations), ``post_step``,
    ``finish``; the compiled loop is :mod:`oneocean.kernels.fh`.
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
from ..models.fish import (FISH_PARAM_NAMES, fish_params, fraction_inside_circle, init_school,
                           school_centroid, school_spread, step_school_into)
from ..sensing import perception, perception_values
from ..sensing.kernels import forecast, polar_fix
from .public import briefing_class, common_brief
from .common import OBS_DIM, PURPOSE_RESET, PURPOSE_TASK_NOISE, STANDARD, current_at, fresh_cache
from .spawn import (_SPAWN_BATCH, _call, _route_row, _segment_clear, feasible_codes, path_clear,
                    sample_route, start_times)
from .tiers import need_tier
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

#: The task's herding stations (the observation's cue, :func:`stations`): the arc behind the
#: school (degrees), at most this much arc ahead of the agent's own bearing around the school
#: (degrees), the standoff from the school's fix under a push (m, plus the school's extent),
#: the standoff at the zone centre (m, outside the fish's 15 m flee radius), the distance of
#: the school from the zone centre over which it backs off (m), and the dead band (fraction of
#: the zone radius around the centre) within which the arc's direction is frozen.
CUE_ARC_DEG = 200.0
CUE_STEP_DEG = 45.0
CUE_STANDOFF_M = 8.0
CUE_BACKOFF_M = 20.0
CUE_RAMP_M = 15.0
CUE_DEADBAND_FRAC = 0.25

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
        Fish-jitter key (set by :func:`brief` from the run seed).
    school : (E, 5) float64
        The truth (judging, snapshots; the perception of a method given the target): centroid
        x, z (m), its velocity over the last step (m s-1), time inside the zone (s).
    done : (E,) int64
        1 once the hold is complete.
    sinfo : (E, 3) int64
        The run seed (:func:`brief`) and what the method is
        given (:func:`brief`, from the mission): ``true_target``, ``true_current``.
    sfix : (E, 8, 4) float64
        Each agent's latest sonar reading of the school (:func:`sonar`): seen (1/0), offset of
        the echo centroid from the agent x, z (m), extent (weighted RMS radius, m); unused with
        ``true_target``.
    skey : (E,) int64
        The cell's episode whose sonar streams row ``e`` draws (:func:`brief`:
        ``LP.e0 + e``; :func:`make`: ``e``).
    fscr : (E, 7, F) float64
        Scratch of the school's step (:func:`~oneocean.models.fish.step_school_into`).
    t0 : (E,) float64
        Start times, s since the grid's ``time0`` (the current at the school).
    fce : (E, 5) float64
        The episode's forecast error (:func:`brief`, from the mission; zeros for a method
        given the true current): the forecast of the current at the school.
    school0 : (E, 2) float64
        The school's centroid at the start (x, z), m: the briefing's report.
    fix : (E, 3) float64
        The team's fix of the school at this step (the team observation): x, z (m), extent
        (m); NaN when no agent sees it.
    vel : (E, 2) float64
        The school's velocity (the team observation), m s-1; NaN unless perceived exactly.
    cur : (E, 2) float64
        The current at the school's last fix (the team observation), east, north, m s-1.
    sch : (E, 3) float64
        The school's last team fix: x, z (m), extent (m) (the reported start before any).
    cth : (E,) float64
        The stations' direction behind the school, compass rad (NaN: not yet set).
    ckey : (E, 8) float64
        Scratch: each agent's bearing around the school relative to ``cth``, rad.
    cue : (E, 8, 2) float64
        Each agent's herding station (x, z), m: the observation's cue.
    """
    zone: np.ndarray        # (E, 2) zone centre (x, z), m
    fish: np.ndarray        # (E, 2, 4, F) fish state double buffer (x, z, vx, vz)
    fcur: np.ndarray        # (E,) int64 index of the current buffer of ``fish``
    fc: np.ndarray          # (E, 2, F) currents at the fish, m s-1
    apos: np.ndarray        # (E, 2, 8) agent x/z seen by the fish, m
    fseed: np.ndarray       # (E,) uint64 fish-jitter key (set by brief from the run seed)
    school: np.ndarray      # (E, 5) the truth: centroid x, z (m), its velocity over the last
                            #   step (m s-1), time inside the zone (s)
    done: np.ndarray        # (E,) int64 1 once the hold is complete
    sinfo: np.ndarray       # (E, 3) int64 run seed (brief), true_target, true_current
                            #   (brief)
    sfix: np.ndarray        # (E, 8, 4) each agent's latest sonar reading: seen (1/0), offset
                            #   of the echo centroid x, z (m), extent (m)
    skey: np.ndarray        # (E,) int64 the cell's episode whose sonar streams row e draws
    fscr: np.ndarray        # (E, 7, F) scratch of the school's step (step_school_into)
    t0: np.ndarray          # (E,) start times, s
    fce: np.ndarray         # (E, 5) forecast error (brief; zeros given the true current)
    school0: np.ndarray     # (E, 2) the school's centroid at the start (x, z), m
    # the public view the task keeps (sense): the team observation and the cue
    fix: np.ndarray         # (E, 3) team fix of the school this step: x, z, extent (m); NaN
    vel: np.ndarray         # (E, 2) the school's velocity, m s-1 (NaN unless exact)
    cur: np.ndarray         # (E, 2) current at the school's last fix, m s-1
    sch: np.ndarray         # (E, 3) the school's last team fix: x, z, extent (m)
    cth: np.ndarray         # (E,) stations' direction behind the school, rad (NaN: unset)
    ckey: np.ndarray        # (E, 8) scratch: agents' bearings around the school, rad
    cue: np.ndarray         # (E, 8, 2) each agent's herding station (x, z), m


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

    Returns
    -------
    P : FHParams
        The env's typed scalars.
    W : FHWork
        The env's per-episode work arrays.

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
    school0 = np.empty((n_ep, 2))
    for e in range(n_ep):
        school0[e] = school_centroid(fish[e, 0, 0], fish[e, 0, 1])
    P = FHParams(float(tier["zone_radius_m"]), float(tier["hold_s"]), float(tier["dt_s"]),
                 FISH_DEPTH_M, DEFAULT_LAND_THRESHOLD, fish_params(), *school_sensor())
    W = FHWork(zone, fish, np.zeros(n_ep, dtype=np.int64), np.zeros((n_ep, 2, n_fish)),
               np.zeros((n_ep, 2, n)), np.zeros(n_ep, dtype=np.uint64), np.zeros((n_ep, 5)),
               np.zeros(n_ep, dtype=np.int64), np.zeros((n_ep, 3), dtype=np.int64),
               np.zeros((n_ep, n, 4)), np.arange(n_ep, dtype=np.int64),
               np.zeros((n_ep, 7, n_fish)),
               np.ascontiguousarray(init["t0"], dtype=np.float64).copy(), np.zeros((n_ep, 5)),
               school0, np.full((n_ep, 3), np.nan), np.full((n_ep, 2), np.nan),
               np.full((n_ep, 2), np.nan), np.zeros((n_ep, 3)), np.full(n_ep, np.nan),
               np.zeros((n_ep, n)), np.zeros((n_ep, n, 2)))
    return P, W


#: The task's own observation fields (after :data:`oneocean.tasks.common.OBS_FIELDS`): the
#: agent's sonar reading of the school (:func:`sonar`): 1 if it sees the school, else 0; the
#: offset of the school's echo centroid from the agent (measured from where it is), x east
#: and z north, m; the echo's extent (weighted RMS radius), m. NaN (and 0) where the sonar
#: sees no fish in range. A method given the target reads, at any range, the offset of the
#: true centroid from the agent's known position (its ``x_m``, ``z_m``) and the school's RMS
#: spread.
OBS_EXTRA_DOCS = {
    "school_seen": ("", "1 if the agent's imaging sonar sees the school, else 0"),
    "school_dx_m": ("m", "the sonar's echo centroid minus the agent's navigation estimate, east "
                         "(NaN: none seen)"),
    "school_dz_m": ("m", "the same, north"),
    "school_spread_m": ("m", "the echo's extent (NaN: none seen)"),
}
OBS_EXTRA = tuple(OBS_EXTRA_DOCS)
#: What the cue is (the observation's ``goal_d*`` fields).
CUE_DOC = ("the agent's herding station on an arc behind the school's last team fix, opposite the "
           "zone centre, a standoff plus the school's extent out")
#: Their columns in an observation row.
O_SEEN, O_SDX, O_SDZ, O_SSPREAD = (OBS_DIM + j for j in range(len(OBS_EXTRA)))

#: The team observation (:class:`FHTeamObs`): name -> (shape, unit, meaning).
TEAM_FIELDS = {
    "fix": ("(E, 3)", "m", "the team's fix of the school at this step: x, z and extent, the "
            "mean of the readings of the agents that see it, each placed at the agent's "
            "navigation estimate (the true centroid and RMS spread for a method given the "
            "target); NaN when no agent sees it"),
    "vel": ("(E, 2)", "m s-1", "the school centroid's velocity over the last step (x, z) for a "
            "method given the target; NaN otherwise (the sonar measures positions)"),
    "cur": ("(E, 2)", "m s-1", "the current (east, north) at the school's last team fix (before "
            "any: the reported start): the truth for a method given the true current, else "
            "the mission's forecast there (no vehicle samples it)"),
}


class FHTeamObs(NamedTuple):
    """FH's team observation (:data:`TEAM_FIELDS`): views of the task's work arrays, updated
    by :func:`sense` every step."""
    fix: np.ndarray
    vel: np.ndarray
    cur: np.ndarray


def team_obs(W: FHWork) -> FHTeamObs:
    """The team observation of every episode: views of ``W.fix``, ``W.vel``, ``W.cur``.

    Returns
    -------
    FHTeamObs
    """
    return FHTeamObs(W.fix, W.vel, W.cur)


#: The briefing's own fields (after :data:`oneocean.tasks.public.COMMON`): name -> (shape,
#: unit, meaning).
BRIEF_FIELDS = {
    "zone": ("(E, 2)", "m", "the safe zone's centre (x east, z north)"),
    "zone_radius": ("", "m", "the safe zone's radius: success is the school's centroid within "
                    "it"),
    "hold_s": ("", "s", "how long the centroid must stay inside the zone without a break"),
    "depth": ("", "m", "the school's depth, where the team works"),
    "school0": ("(E, 2)", "m", "the school's centroid (x, z) when the team was deployed, as "
                "the mission reports it"),
    "school_radius": ("", "m", "the radius of the disc around school0 the school occupied"),
    "fish_count": ("", "", "fish in the school"),
    "flee_radius": ("", "m", "the species' reaction distance: fish flee a vehicle closer than "
                    "this"),
    "fish_speed": ("", "m s-1", "the species' sustained swim speed (relative to the water)"),
    "sonar_range": ("", "m", "each vehicle's sonar sees the fish within this horizontal range"),
}


FHBriefing = briefing_class("FH", BRIEF_FIELDS, __name__)


def brief(P: FHParams, W: FHWork, init: dict, m) -> FHBriefing:
    """The briefing of every episode of a batch (:class:`oneocean.tasks.public.Mission`
    ``m``): the zone, the hold, the reported school, the species' behaviour, the sonar's range.

    Sets what the task's sensing depends on in ``W.sinfo`` (the run seed; a method given
    the target perceives the school exactly; one given the true current gets the true
    current at the school), the fish-jitter keys and the sonar's episodes (``W.fseed``,
    ``W.skey``: the cell's episode ``m.e0 + e`` of row ``e``) and the episodes' forecast
    errors in ``W.fce`` (the forecast at the school).

    Returns
    -------
    FHBriefing
    """
    n_ep = W.zone.shape[0]
    for e in range(n_ep):      # the fish-jitter keys and the sonar's streams: the run's
        W.fseed[e] = hash64(m.seed, m.e0 + e, PURPOSE_TASK_NOISE, 0)
    W.skey[:] = m.e0 + np.arange(n_ep)
    W.sinfo[:, 0] = m.seed
    W.sinfo[:, 1] = int(m.sens.true_target != 0)
    W.sinfo[:, 2] = int(m.sens.true_current != 0)
    fc = m.forecast
    W.fce[:] = 0.0 if fc is None else fc
    fi = FISH_PARAM_NAMES.index
    return FHBriefing(**common_brief(m), zone=W.zone.copy(), zone_radius=P.zone_r,
                      hold_s=P.hold, depth=P.depth, school0=W.school0.copy(),
                      school_radius=SCHOOL_RADIUS_M, fish_count=int(W.fish.shape[3]),
                      flee_radius=float(P.fp[fi("flee_radius")]),
                      fish_speed=float(P.fp[fi("max_speed")]), sonar_range=P.sonar_r)


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



@hot_kernel
def sonar(P, W, state, e, ping):
    """Every agent's sonar reading of the school (``sensors.yaml`` ``perception.fh_school``)
    into ``W.sfix[e]``, from the true agents and fish (the current buffer of ``W.fish``).

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
        Number of the reading (the step ``k`` whose observation it is), so that no two draws
        share a counter.
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


@hot_kernel
def begin(ctx, e):
    """Start the school's truth (centroid, no velocity, no time inside) and the task's view
    of it: the last team fix is the reported start, the stations' direction unset.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``ctx.state`` holds the start.

    Returns
    -------
    bool
        False: the episode starts.
    """
    W = ctx.W
    F = W.fish[e, 0]
    cx, cz = school_centroid(F[0], F[1])
    W.fcur[e] = 0
    W.school[e, 0] = cx
    W.school[e, 1] = cz
    W.school[e, 2] = 0.0
    W.school[e, 3] = 0.0
    W.school[e, 4] = 0.0
    W.done[e] = 0
    W.sch[e, 0] = W.school0[e, 0]
    W.sch[e, 1] = W.school0[e, 1]
    W.sch[e, 2] = SCHOOL_RADIUS_M / math.sqrt(2.0)   # RMS radius of the reported disc
    W.cth[e] = math.nan
    return False


@hot_kernel
def pre_step(ctx, e, k):
    """The fish step: the school reacts to the vehicles' positions at time ``t`` (into the
    other buffer of ``W.fish``).

    Env hook (:mod:`oneocean.tasks.loop`), before the agents act.
    """
    grid, P, W, state = ctx.grid, ctx.P, ctx.W, ctx.state
    t = ctx.t0[e] + k * ctx.dt
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


@hot_kernel
def cue(ctx, e, k, i):
    """Agent ``i``'s cue: its herding station (:func:`stations`, computed by :func:`sense`
    this step) at the school's depth. Env hook (:mod:`oneocean.tasks.loop`).

    Returns
    -------
    gx, gy, gz : float
        The station, world m.
    probe : float
        NaN (the task has no field).
    """
    P, W = ctx.P, ctx.W
    return W.cue[e, i, 0], P.depth, W.cue[e, i, 1], math.nan


@hot_kernel
def stations(P, W, X, e):
    """Every agent's herding station ``W.cue[e]`` around the school's last team fix
    ``W.sch[e]`` (the task's cue, module docstring).

    The arc's centre lies behind the fix, opposite the zone centre (compass angle
    ``W.cth[e]``, kept while the fix is within ``CUE_DEADBAND_FRAC`` zone radii of the
    centre); its radius is ``CUE_STANDOFF_M`` plus the school's extent, backing off linearly
    to ``CUE_BACKOFF_M`` plus the extent as the fix nears the centre (within ``CUE_RAMP_M``).
    The agents (at their known positions ``X``) take the ``CUE_ARC_DEG`` arc's evenly spaced
    slots in the angular order of their bearings from the fix; each station is on the arc's
    circle at most ``CUE_STEP_DEG`` from the agent's own bearing toward its slot.

    Parameters
    ----------
    P : FHParams
        The task's params (:func:`make`).
    W : FHWork
        The task's per-episode work arrays; ``cth[e]``, ``ckey[e]`` and ``cue[e]`` written.
    X : (E, N, STATE_DIM) float64
        The states the method knows.
    e : int
        Episode index.
    """
    n = X.shape[1]
    cx = W.sch[e, 0]
    cz = W.sch[e, 1]
    dx = W.zone[e, 0] - cx
    dz = W.zone[e, 1] - cz
    d = math.sqrt(dx * dx + dz * dz)
    th = W.cth[e]
    if th != th or d > CUE_DEADBAND_FRAC * P.zone_r:
        th = math.atan2(-dx, -dz)
        W.cth[e] = th
    g = d / CUE_RAMP_M
    if g > 1.0:
        g = 1.0
    r = CUE_STANDOFF_M + (CUE_BACKOFF_M - CUE_STANDOFF_M) * (1.0 - g) + W.sch[e, 2]
    arc = math.radians(CUE_ARC_DEG)
    step = math.radians(CUE_STEP_DEG)
    KY = W.ckey[e]
    for i in range(n):
        a = math.atan2(X[e, i, 0] - cx, X[e, i, 2] - cz) - th
        KY[i] = a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))
    for i in range(n):
        rank = 0
        for j in range(n):
            if KY[j] < KY[i] or (KY[j] == KY[i] and j < i):
                rank += 1
        delta = -0.5 * arc + arc * rank / (n - 1) if n > 1 else 0.0
        dang = delta - KY[i]
        if dang > step:
            dang = step
        elif dang < -step:
            dang = -step
        a = th + KY[i] + dang
        W.cue[e, i, 0] = cx + r * math.sin(a)
        W.cue[e, i, 1] = cz + r * math.cos(a)


@hot_kernel
def sense(ctx, e, k):
    """The task's observation fields (:data:`OBS_EXTRA`), its team observation
    (:data:`TEAM_FIELDS`) and the stations of the cue, before step ``k``.

    Every agent's sonar reading (:func:`sonar`, ping ``k``) -- or, for a method given the
    target, the true centroid's offset and the school's spread --; the team's fix (the mean
    of the seen readings placed at the agents' known positions ``X``) and the last one in
    ``W.sch``; the school's velocity (given the target); the current at the last fix at the
    step's time (the truth given the true current, else the forecast there); then
    :func:`stations`. Env hook (:mod:`oneocean.tasks.loop`).
    """
    grid, P, W, X, state, O = ctx.grid, ctx.P, ctx.W, ctx.X, ctx.state, ctx.O
    n = X.shape[1]
    fx = W.fix[e]
    if W.sinfo[e, 1] != 0:   # the school perceived exactly (oracle, true_target ablation)
        F = W.fish[e, W.fcur[e]]
        cx = W.school[e, 0]
        cz = W.school[e, 1]
        sp = school_spread(F[0], F[1])
        for i in range(n):
            o = O[e, i]
            o[O_SEEN] = 1.0
            o[O_SDX] = cx - X[e, i, 0]
            o[O_SDZ] = cz - X[e, i, 2]
            o[O_SSPREAD] = sp
        fx[0] = cx
        fx[1] = cz
        fx[2] = sp
        W.vel[e, 0] = W.school[e, 2]
        W.vel[e, 1] = W.school[e, 3]
    else:
        sonar(P, W, state, e, k)
        m = 0.0
        mx = 0.0
        mz = 0.0
        ms = 0.0
        for j in range(n):
            o = O[e, j]
            if W.sfix[e, j, 0] != 0.0:
                o[O_SEEN] = 1.0
                o[O_SDX] = W.sfix[e, j, 1]
                o[O_SDZ] = W.sfix[e, j, 2]
                o[O_SSPREAD] = W.sfix[e, j, 3]
                m += 1.0
                mx += X[e, j, 0] + W.sfix[e, j, 1]
                mz += X[e, j, 2] + W.sfix[e, j, 2]
                ms += W.sfix[e, j, 3]
            else:
                o[O_SEEN] = 0.0
                o[O_SDX] = math.nan
                o[O_SDZ] = math.nan
                o[O_SSPREAD] = math.nan
        if m > 0.0:
            fx[0] = mx / m
            fx[1] = mz / m
            fx[2] = ms / m
        else:
            fx[0] = math.nan
            fx[1] = math.nan
            fx[2] = math.nan
        W.vel[e, 0] = math.nan
        W.vel[e, 1] = math.nan
    if fx[0] == fx[0]:
        W.sch[e, 0] = fx[0]
        W.sch[e, 1] = fx[1]
        W.sch[e, 2] = fx[2]
    ce, cn = current_at(grid, W.sch[e, 0], P.depth, W.sch[e, 1], W.t0[e] + k * P.dt)
    if W.sinfo[e, 2] == 0:
        ce, cn = forecast(W.fce, e, ce, cn)
    W.cur[e, 0] = ce
    W.cur[e, 1] = cn
    stations(P, W, X, e)


@hot_kernel
def post_step(ctx, e, k):
    """Swap the fish buffers, update the school's truth and time the hold inside the zone.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``: the
    time inside the zone grows by ``dt`` while the centroid is within ``P.zone_r`` of the
    zone centre and restarts from 0 when it leaves.

    Returns
    -------
    bool
        True (STOP) once the hold reaches ``P.hold``.
    """
    P, W = ctx.P, ctx.W
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
    if math.sqrt((nx - zx) ** 2 + (nz - zz) ** 2) <= P.zone_r:
        sc[4] += dt
        if sc[4] >= P.hold - 1e-9:
            W.done[e] = 1
            return True
    else:
        sc[4] = 0.0
    return False


@hot_kernel
def finish(ctx, e, k):
    """Write the FH metrics.

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Returns
    -------
    bool
        Success: the hold was completed.
    """
    P, W = ctx.P, ctx.W
    row = ctx.res[e]
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


fresh_cache(_episodes_kernel, __file__, Path(__file__).resolve().parents[1] / "models" /
            "fish.py")
