"""UPL — underwater pollution lift to the surface (exactly 5 agents).

Objective
    A polluting object rests on the seafloor (centre ``OBJ_HALF_HEIGHT_M`` above it) at a site
    whose seafloor depth lies in ``[site_depth_m - SITE_DEPTH_SPAN_M, site_depth_m]`` (below
    the product's deepest current level the engine holds that level's current down to the
    seafloor, docs/contracts.md §5). It carries ``N_SLOTS = 5`` attachment slots on a
    ring of radius ``SLOT_RING_M``, ``SLOT_RISE_M`` above its centre (adjacent slots 3.5 m
    apart). The five vehicles start APART from it: near the surface (``START_DEPTH_M``), at
    ``[START_RING_FRAC * start_distance_m, start_distance_m]`` horizontally from the site, each
    with a straight, clear descent to it. They must approach, attach, then lift the object
    cooperatively to the surface while holding it over the site against the currents.
Mission data and perception
    The team knows the object from the site survey's chart (``reset``'s ``chart``: the true
    centre moved horizontally by the survey's error, ``survey_std_m`` per axis, truncated at
    3 sigma, at the charted seafloor depth there; the same for every method) and sees it with
    each ROV's forward-looking imaging sonar (``sensors.yaml`` ``perception.upl_object``,
    docs/sensing.md): ``pre_step`` writes every agent's fix (the object's offset from the
    agent with range, bearing and elevation noise and the echo centre's offset, within the
    detection range, once per period) into ``W.fix``; a method that perceives the target
    exactly (the oracle, the ``true_target`` ablation; ``brief`` sets it) gets the exact
    offset at any range. The team fuses the fixes into one estimate of the object
    (:func:`perceive`, in ``sense``, every step, for every method): a constant-velocity
    Kalman filter per axis (process noise ``QA_REST`` while the object rests or sinks,
    ``QA_LIFT`` while the quorum lifts it), started at the chart (its stated error
    ``survey_std_m`` horizontally, ``SITE_PRIOR_STD_Y_M`` vertically), each fix placed at the
    ROV's navigation estimate with the sonar's range and angular noise at its range, the echo
    centre's offset and the USBL-aided navigation's error ``NAV_STD_M`` (horizontal); exact
    (the true centre and velocity) for a method that perceives the object exactly. Attach,
    detach and success are judged on the truth.
Physics (the environment; identical for every method)
    * Attach: an unattached agent that stays within ``attach_radius_m`` of the same free slot
      for ``attach_dwell_s`` consecutive seconds latches onto it. Any agent may take any free
      slot (slots are >= 3.5 m apart, so at most one is in reach). An attached agent detaches
      (and must attach again) when it is more than ``detach_radius_m`` from its slot.
    * Lift: while at least ``quorum`` agents are attached, the object and the attached agents
      form one assembly. After every agent's own step
      (:func:`~oneocean.engine.step.advance_agent`: dynamics, current, feasibility, energy),
      the assembly moves by the attached agents' mean displacement plus the sink of the
      object's net weight, ``w_load dt`` downward with
      ``w_load = sink_speed_ms * N_SLOTS / n_attached`` (the weight is shared by the attached
      agents: with all five the team must out-pull ``sink_speed_ms``). Each attached agent is
      displaced by (assembly displacement - mean agent displacement), i.e. it carries its
      share of the load; a correction that would make the agent's position infeasible is
      skipped.
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
    reachable: the slots must stay in the water there (``success_depth_m >= SLOT_RISE_M``)
    and the site deeper than the success depth.
Metrics
    ``lift_success`` (primary, 0/1), ``final_object_depth_m`` (object centre depth at the end,
    m), ``attach_time_s`` (first time the quorum was attached, s; the time limit if never),
    ``object_drift_m`` (horizontal distance of the object from the site at the end, m).
Briefing (:class:`UPLBriefing`)
    The object's chart (its last known centre; the true one for a method that perceives the
    object exactly), the slot offsets (the object's drawing), the rules (quorum, attach radius
    and dwell, detach radius, the object's sink speed, success depth, hold radius), the
    survey's stated error and the sonar's detection range.
Observation
    The cue is the task's own slot guidance, on the team's object estimate: the agent's own
    slot while attached, else the nearest slot no agent holds; while the agent is attached
    and the quorum holds (the lift), that slot at the surface (the vertical goal of the lift:
    the object's centre then ``SLOT_RISE_M`` deep, above the success depth, so a follower
    that closes its cue offset only in part still lifts the object past it). It does not
    search: where the chart is farther off than the sonar's range, a follower waits at the
    charted slot. The task's own fields
    (:data:`OBS_EXTRA`): whether the team has a fix of the object, the team's estimate of the
    object's centre relative to the agent's navigation estimate and its velocity, and the
    agent's attached slot (-1: none; the attachments are physical state the team sees). The
    team observation (:class:`UPLTeamObs`): the team's object estimate in world coordinates
    and the detection flag.
Methods
    :mod:`oneocean.methods.heuristic.upl` (greedy slot assignment, slot seeking with a search
    when the chart is wrong, held lift; both at full speed; heuristic: the sensor models of
    :mod:`oneocean.sensing` and the object's sonar model; oracle: true current, position and
    object; information only). The environment above does not depend on the method.

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset`` (Python: site, slots, starts, start times, chart);
    ``UPLParams`` / ``UPLWork`` and ``make`` (the env's typed scalars and per-episode arrays:
    object, attachments, sonar fixes, the team's object estimate); ``object_perception`` (the
    sonar model's scalars); the public view: ``UPLBriefing`` / ``BRIEF_FIELDS`` / ``brief``,
    ``OBS_EXTRA``, ``UPLTeamObs`` / ``TEAM_FIELDS`` / ``team_obs``; the env hooks ``begin``,
    ``pre_step`` (positions, attached count and sonar fixes at the step start), ``cue``,
    ``sense`` (the team's object estimate, :func:`perceive`, and the observation's fields),
    ``after_agent`` (after the last agent's move: the object and the assembly move, so the
    near-collision count sees the carried agents), ``post_step`` (attach / detach, quorum
    time, success), ``finish``; the compiled loop is :mod:`oneocean.kernels.upl`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..engine import status as st
from ..engine._jit import hot_kernel
from ..engine.constraints import DEFAULT_LAND_THRESHOLD, check_move
from ..engine.grid import sample_elevation, sample_elevation_points
from ..errors import ConfigError, NotApplicable
from ..sensing import perception, perception_values
from ..sensing.kernels import PURPOSE_PERCEPTION, draw, polar_fix
from .public import briefing_class, common_brief
from .common import OBS_DIM, OK, PURPOSE_RESET, STANDARD, current_at, fresh_cache
from .spawn import _call, _segment_clear, feasible_codes, path_clear, start_times
from .tiers import episode_steps, need_tier
from ..engine import libm
from ..engine import streams

TASK_ID = "UPL"
METRICS = ("lift_success", "final_object_depth_m", "attach_time_s", "object_drift_m")
#: Result-matrix columns written by the kernel (standard columns first).
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
#: Vertical standard deviation of the charted object depth (the chart's seafloor depth at the
#: charted point vs the object's), m: the prior of the team's object filter.
SITE_PRIOR_STD_Y_M = 2.0

_C_LIFT, _C_DEPTH, _C_ATT_T, _C_DRIFT = (len(STANDARD) + i for i in range(len(METRICS)))

_TIER_KEYS = ("time_limit_s", "site_depth_m",
              "start_distance_m", "attach_radius_m", "attach_dwell_s", "detach_radius_m",
              "sink_speed_ms", "quorum", "hold_radius_m", "success_depth_m", "survey_std_m")


def slot_offsets(phase: float = 0.0) -> np.ndarray:
    """Attachment-slot offsets from the object's centre.

    Slot k sits at compass angle ``phase + 2 pi k / N_SLOTS`` on the ring of radius
    ``SLOT_RING_M``, ``SLOT_RISE_M`` above the centre (smaller depth).

    Parameters
    ----------
    phase : float
        Compass angle of slot 0 (clockwise from north), rad.

    Returns
    -------
    (N_SLOTS, 3) float64
        Offsets (x, y, z), world m.
    """
    a = phase + 2.0 * np.pi * np.arange(N_SLOTS) / N_SLOTS
    return np.stack([SLOT_RING_M * libm.sin(a), np.full(N_SLOTS, -SLOT_RISE_M),
                     SLOT_RING_M * libm.cos(a)], axis=1)


def check_reachable(tier: dict, grid=None) -> None:
    """Check that the tier's success depth can be reached and its parameters are coherent
    (see the module docstring).

    Parameters
    ----------
    tier : dict
        Tier parameters (``success_depth_m``, ``site_depth_m``, ``quorum``,
        ``attach_radius_m``, ``detach_radius_m``, ``survey_std_m``).
    grid : Grid, optional
        Unused.

    Raises
    ------
    ConfigError
        ``success_depth_m`` below ``SLOT_RISE_M`` or sites not deeper than it, ``quorum``
        outside 1..5, ``detach_radius_m < attach_radius_m``, or a ``survey_std_m`` that is not
        a number >= 0.
    """
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
    sv = tier.get("survey_std_m", 0.0)
    if isinstance(sv, bool) or not isinstance(sv, (int, float)) or not sv >= 0.0:
        raise ConfigError(f"task {TASK_ID}: survey_std_m must be a number >= 0 m, got {sv!r}")


def _site_candidates(grid, rng, lo: float, hi: float, n: int = 4096) -> np.ndarray:
    """Random points (m, 2 columns x, z) in water whose seafloor depth is in [lo, hi]."""
    xz = np.empty((n, 2))
    xz[:, 0] = rng.uniform(grid.x0, grid.x_max, n)
    xz[:, 1] = rng.uniform(grid.z0, grid.z_max, n)
    floor = -sample_elevation_points(grid, xz, np.empty(n))
    xyz = np.stack([xz[:, 0], np.zeros(n), xz[:, 1]], axis=1)
    ok = (feasible_codes(grid, xyz, DEFAULT_LAND_THRESHOLD, 0.0) == st.OK) & (floor >= lo) & \
        (floor <= hi)
    return xz[ok]


def _try_site(grid, rng, x: float, z: float, start_distance: float):
    """Object centre, slot phase and agent starts for a site at (x, z), or None."""
    floor = -float(sample_elevation_points(grid, np.array([[x, z]]), np.empty(1))[0])
    obj = np.array([x, floor - OBJ_HALF_HEIGHT_M, z])
    phase = rng.uniform(0.0, 2.0 * np.pi)
    slots = obj + slot_offsets(phase)
    if np.any(feasible_codes(grid, slots, DEFAULT_LAND_THRESHOLD, CLEARANCE_M + SLOT_MARGIN_M)
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
        if feasible_codes(grid, p[None], DEFAULT_LAND_THRESHOLD, CLEARANCE_M)[0] != st.OK:
            continue
        if not path_clear(grid, p, above, CLEARANCE_M, DEFAULT_LAND_THRESHOLD, spacing_m=5.0):
            continue
        starts[got] = p
        got += 1
        if got == N_SLOTS:
            return obj, phase, starts
    return None


#: Rounds of site candidates (``_SITE_DRAWS`` points each, the first ``_SITE_TRIES`` in the
#: depth band tried) before the region is declared unable to host an episode.
_SITE_ROUNDS = 8
_SITE_DRAWS = 4096
_SITE_TRIES = 50


@hot_kernel
def _sites_kernel(grid, stv, lo, hi, start_distance, n, cur, starts, obj0, phase0, pos0,
                  found):
    """:func:`_site_candidates` and :func:`_try_site` for each episode's stream ``stv[e]``,
    compiled: the same draws in the same order and the same checks (``check_move`` for the
    candidates, slots and starts, :func:`~.spawn._segment_clear` for the descents).
    ``found[e]`` is 1 where a site was found (its centre, slot phase and starts written),
    else 0.

    A round's ``n`` x then ``n`` z coordinates are read from two cursors (``cur`` (2, 4)
    uint64: the stream at the block's start and ``n`` draws on) only as far as candidates
    are examined, and the stream jumps over the block (:func:`~oneocean.engine.streams.
    advance`): the same numbers, the stream left where the block leaves it."""
    lt = DEFAULT_LAND_THRESHOLD
    slot_c = CLEARANCE_M + SLOT_MARGIN_M
    two_pi = 2.0 * math.pi
    for e in range(stv.shape[0]):
        found[e] = 0
        for _r in range(_SITE_ROUNDS):
            streams.advance(cur, 0, stv, e, 0)          # the block's x coordinates
            streams.advance(cur, 1, stv, e, n)          # its z coordinates
            streams.advance(stv, e, stv, e, 2 * n)      # the stream after the block
            tried = 0
            for c in range(n):
                if tried == _SITE_TRIES:
                    break
                x = streams.uniform(cur, 0, grid.x0, grid.x_max)
                z = streams.uniform(cur, 1, grid.z0, grid.z_max)
                fl = -sample_elevation(grid, x, z)
                if not (check_move(grid, x, 0.0, z, lt, 0.0) == OK and fl >= lo and fl <= hi):
                    continue
                tried += 1
                # _try_site at (x, z)
                oy = fl - OBJ_HALF_HEIGHT_M
                ph = streams.uniform(stv, e, 0.0, two_pi)
                good = True
                for k in range(N_SLOTS):
                    a = ph + two_pi * float(k) / N_SLOTS
                    if check_move(grid, x + SLOT_RING_M * math.sin(a), oy + -SLOT_RISE_M,
                                  z + SLOT_RING_M * math.cos(a), lt, slot_c) != OK:
                        good = False
                        break
                if not good:
                    continue
                ay = oy - SLOT_RISE_M
                got = 0
                for _t in range(60 * N_SLOTS):
                    r = start_distance * streams.uniform(stv, e, START_RING_FRAC, 1.0)
                    a = streams.uniform(stv, e, 0.0, two_pi)
                    px = x + r * math.sin(a)
                    pz = z + r * math.cos(a)
                    near = False
                    for b in range(got):
                        # starts share the depth: the y term of NumPy's norm is 0
                        qx = starts[b, 0] - px
                        qy = starts[b, 1] - START_DEPTH_M
                        qz = starts[b, 2] - pz
                        if math.sqrt(qx * qx + qy * qy + qz * qz) < START_SEPARATION_M:
                            near = True
                            break
                    if near:
                        continue
                    if check_move(grid, px, START_DEPTH_M, pz, lt, CLEARANCE_M) != OK:
                        continue
                    dx, dy, dz = x - px, ay - START_DEPTH_M, z - pz
                    m = max(2, int(math.ceil(math.sqrt(dx * dx + dy * dy + dz * dz) / 5.0)) + 1)
                    if not _segment_clear(grid, px, START_DEPTH_M, pz, x, ay, z, m, lt,
                                          CLEARANCE_M):
                        continue
                    starts[got, 0] = px
                    starts[got, 1] = START_DEPTH_M
                    starts[got, 2] = pz
                    got += 1
                    if got == N_SLOTS:
                        break
                if got < N_SLOTS:
                    continue
                obj0[e, 0] = x
                obj0[e, 1] = oy
                obj0[e, 2] = z
                phase0[e] = ph
                for b in range(N_SLOTS):
                    for i in range(3):
                        pos0[e, b, i] = starts[b, i]
                found[e] = 1
                break
            if found[e]:
                break
    return found


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the object's site, its slots, the agents' starts and the start time per episode.

    The same as :func:`reset_build` of :func:`reset_candidates` (the split ``Cell.reset``
    uses to finish only the candidates the tier's current band keeps).

    Returns
    -------
    dict
        ``obj0`` (E, 3) object centre, m; ``slot_off`` (E, 5, 3) slot offsets from the centre,
        m; ``pos0`` (E, 5, 3) agent starts, m; ``psi0`` (E, 5) headings toward the site, rad;
        ``t0`` (E,) start times, s; ``chart`` (E, 3) the survey's charted object centre, m;
        ``regime_points`` (E, 3, 3) the object's site, half its depth and the success depth
        above it, m (``Cell.reset``).

    Raises
    ------
    ConfigError
        Wrong team size, missing or unreachable tier parameters.
    NotApplicable
        No valid site for some episode.
    """
    return reset_build(grid, tier, n_agents,
                       reset_candidates(grid, tier, n_agents, n_episodes, seed), seed)


def reset_candidates(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """The first half of :func:`reset`: each candidate's geometry, what ``Cell.reset``'s band
    check needs and what :func:`reset_build` needs to finish it.

    Per candidate (its own stream): the start time, then, in one compiled call over the
    candidates (:func:`_sites_kernel`), the site, the slots' phase and the starts.

    Returns
    -------
    dict
        ``obj0`` (E, 3), ``pos0`` (E, 5, 3), ``t0`` (E,) and ``regime_points`` (E, 3, 3) as
        :func:`reset`'s; ``phase`` (E,) the slot ring's phase, rad; ``stream`` (E, 4) uint64
        each candidate's stream where its geometry's draws left it
        (:mod:`oneocean.engine.streams`: the survey error is drawn from it).

    Raises
    ------
    ConfigError
        Wrong team size, missing or unreachable tier parameters.
    NotApplicable
        No valid site for some candidate.
    """
    if int(n_agents) != N_SLOTS:
        raise ConfigError(f"task {TASK_ID}: needs exactly {N_SLOTS} agents, got {n_agents}")
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    check_reachable(tier, grid)
    hi = float(tier["site_depth_m"])
    lo = hi - SITE_DEPTH_SPAN_M
    dist = float(tier["start_distance_m"])
    rngs = streams.episode_states(seed, n_episodes, PURPOSE_RESET)   # one stream per episode
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    obj0 = np.empty((n_episodes, 3))
    phase = np.empty(n_episodes)
    pos0 = np.empty((n_episodes, N_SLOTS, 3))
    found = _call(_sites_kernel, grid, rngs, lo, hi, dist, _SITE_DRAWS,
                  np.empty((2, 4), dtype=np.uint64), np.empty((N_SLOTS, 3)), obj0, phase, pos0,
                  np.empty(n_episodes, dtype=np.int64))
    for e in np.flatnonzero(found == 0)[:1]:
        raise NotApplicable(f"task {TASK_ID} reset (episode {e}): no site with seafloor depth "
                            f"in [{lo:g}, {hi:g}] m, feasible slots and clear descents from "
                            f"{dist:g} m found; the grid has no such water for this tier")
    # the current regime is judged at the object: its site, and the water column it rises in
    col = np.repeat(obj0[:, None, :], 3, axis=1)
    col[:, 1, 1] *= 0.5
    col[:, 2, 1] = float(tier["success_depth_m"])
    return {"obj0": obj0, "phase": phase, "pos0": pos0, "t0": t0, "stream": rngs,
            "regime_points": col}


def reset_build(grid, tier: dict, n_agents: int, cand: dict, seed: int) -> dict:
    """The second half of :func:`reset`: the episodes of the chosen candidates.

    The slot offsets, the headings and the survey's chart of the object (the true centre
    with the survey's horizontal error, truncated at 3 sigma, at the charted seafloor depth
    there), the error drawn last from each candidate's own stream.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    tier : dict
        Tier parameters (``survey_std_m``).
    n_agents : int
        Team size (5).
    cand : dict
        A :func:`reset_candidates` dict with every per-candidate array indexed by the chosen
        candidates (``cand["candidate"]``: their indices, unused here).
    seed : int
        Run seed (unused: each candidate's stream is in ``cand["stream"]``).

    Returns
    -------
    dict
        :func:`reset`'s dict.
    """
    survey = float(tier["survey_std_m"])
    obj0, pos0 = cand["obj0"], cand["pos0"]
    n_episodes = obj0.shape[0]
    slot_off = np.empty((n_episodes, N_SLOTS, 3))
    chart = np.empty((n_episodes, 3))
    for e in range(n_episodes):
        slot_off[e] = slot_offsets(float(cand["phase"][e]))
        # the site survey's chart of the object (mission data, every method's), by the
        # candidate's generator where the geometry's draws left its stream (drawn last: the
        # geometry does not depend on it)
        err = np.clip(streams.generator(cand["stream"][e]).normal(0.0, 1.0, 2), -3.0,
                      3.0) * survey
        chart[e] = _chart_point(grid, obj0[e], err)
    d = obj0[:, None, :] - pos0
    psi0 = libm.arctan2(d[..., 0], d[..., 2])
    return {"obj0": obj0, "slot_off": slot_off, "pos0": pos0, "psi0": psi0, "t0": cand["t0"],
            "chart": chart, "regime_points": cand["regime_points"]}


def _chart_point(grid, obj: np.ndarray, err) -> np.ndarray:
    """The charted object centre: ``obj`` moved horizontally by the survey error ``err``
    (x, z) m, at the charted seafloor depth there (the object's own depth where the charted
    point is dry or off the grid)."""
    x = float(obj[0] + err[0])
    z = float(obj[2] + err[1])
    inside = grid.x0 <= x <= grid.x_max and grid.z0 <= z <= grid.z_max
    floor = -float(sample_elevation_points(grid, np.array([[x, z]]), np.empty(1))[0])
    y = floor - OBJ_HALF_HEIGHT_M if inside and floor > OBJ_HALF_HEIGHT_M else float(obj[1])
    return np.array([x, y, z])


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


class UPLParams(NamedTuple):
    """UPL's params (one rollout).

    Attributes
    ----------
    quorum : int
        Attached agents needed to lift.
    dt : float
        Step, s.
    t_limit : float
        Time limit (``n_steps dt``), s.
    land_thr : float
        Land-mask threshold of the object / carry checks.
    clearance : float
        Seafloor clearance of the carry check, m.
    att_r : float
        Attach radius, m.
    dwell_s : float
        Attach dwell, s.
    det_r : float
        Detach radius, m.
    sink : float
        Sink speed of the object alone, m s-1.
    succ_d : float
        Success depth of the object's centre, m.
    hold_r : float
        Success radius around the site (horizontal), m.
    survey_std : float
        The chart's stated error per horizontal axis (mission data), m.
    p_range : float
        The object's perception (``data/sensors.yaml`` ``perception.upl_object``; every
        non-oracle method's, docs/sensing.md): detection range (slant), m.
    p_range_std : float
        Range noise, m.
    p_bearing_std : float
        Bearing and elevation noise, rad.
    p_centre_std : float
        Echo centre's offset from the object's centre (line of sight), m.
    p_every : int
        One fix per ROV every this many steps.
    """
    quorum: int             # attached agents needed to lift
    dt: float               # step, s
    t_limit: float          # time limit (n_steps dt), s
    land_thr: float         # land-mask threshold of the object / carry checks
    clearance: float        # seafloor clearance of the carry check, m
    att_r: float            # attach radius, m
    dwell_s: float          # attach dwell, s
    det_r: float            # detach radius, m
    sink: float             # sink speed of the object alone, m s-1
    succ_d: float           # success depth of the object's centre, m
    hold_r: float           # success radius around the site (horizontal), m
    survey_std: float       # the chart's stated error per horizontal axis (mission data), m
    # the object's perception model (data/sensors.yaml perception.upl_object; every
    # non-oracle method's: docs/sensing.md)
    p_range: float          # detection range (slant), m
    p_range_std: float      # range noise, m
    p_bearing_std: float    # bearing and elevation noise, rad
    p_centre_std: float     # echo centre's offset from the object's centre (line of sight), m
    p_every: int            # one fix per ROV every this many steps


class UPLWork(NamedTuple):
    """UPL's per-episode work arrays (5 agents, 5 slots).

    Attributes
    ----------
    site : (E, 3) float64
        Object's start (the site; the vessel waits above), m.
    slot_off : (E, 5, 3) float64
        Slot offsets from the object's centre, m.
    obj : (E, 3) float64
        Object centre, m.
    vobj : (E, 3) float64
        Object velocity over the last step, m s-1.
    on_floor : (E,) bool
        The object rests on the seafloor.
    att : (E, 5) int64
        Slot of each attached agent (-1: none).
    owner : (E, 5) int64
        Agent attached to each slot (-1: none).
    dwell : (E, 5) float64
        Time each agent has been in reach of ``dslot``, s.
    dslot : (E, 5) int64
        Slot in reach (-1: none).
    prev : (E, 5, 3) float64
        Agent positions at the start of the step, m.
    t : (E,) float64
        Time of the current step, s since the grid's ``time0``.
    n_att : (E,) int64
        Attached agents at the start of the step.
    t_att : (E,) float64
        First time the quorum was attached, s since the episode's start (-1: not yet).
    chart : (E, 3) float64
        The survey's charted object centre (mission data), m.
    pcfg : (3,) int64
        The object's perception: run seed (:func:`brief`), 1 = the method
        perceives the object exactly (:func:`brief`), the cell's episode of row 0 (row ``e``
        draws episode ``pcfg[2] + e``; :func:`brief`).
    fix : (E, 5, 4) float64
        This step's sonar fix per agent: measured offset of the object's centre from the
        agent (x, y, z) m, 1 = valid.
    oest : (E, 6) float64
        The team's estimate of the object (:func:`perceive`): centre (x, y, z) m, velocity
        m s-1.
    ocov : (E, 3, 3) float64
        Its covariance per axis: P_pp m2, P_pv m2 s-1, P_vv m2 s-2.
    odet : (E,) int64
        1 once the team has a fix of the object.
    fixk : (E,) int64
        Step of the latest fixes in ``fix`` (-1: none yet).
    kf : (E,) int64
        Step of the fixes the estimate last fused (-1: none).
    """
    site: np.ndarray        # (E, 3) object's start (the site; the vessel waits above), m
    slot_off: np.ndarray    # (E, 5, 3) slot offsets from the object's centre, m
    obj: np.ndarray         # (E, 3) object centre, m
    vobj: np.ndarray        # (E, 3) object velocity over the last step, m s-1
    on_floor: np.ndarray    # (E,) bool the object rests on the seafloor
    att: np.ndarray         # (E, 5) int slot of each attached agent (-1 none)
    owner: np.ndarray       # (E, 5) int agent attached to each slot (-1 none)
    dwell: np.ndarray       # (E, 5) s agent has been in reach of ``dslot``
    dslot: np.ndarray       # (E, 5) int slot in reach (-1 none)
    prev: np.ndarray        # (E, 5, 3) agent positions at the start of the step, m
    t: np.ndarray           # (E,) time of the current step, s
    n_att: np.ndarray       # (E,) int attached agents at the start of the step
    t_att: np.ndarray       # (E,) first time the quorum was attached, s (-1: not yet)
    chart: np.ndarray       # (E, 3) the survey's charted object centre (mission data), m
    # the object's perception (pre_step: the fixes; sense: the team's estimate; brief sets
    # pcfg)
    pcfg: np.ndarray        # (3,) int: run seed, 1 = the method perceives the object exactly,
                            #   the cell's episode of row 0 (row e draws episode pcfg[2] + e)
    fix: np.ndarray         # (E, 5, 4) this step's sonar fix per agent: measured offset of
                            # the object's centre from the agent (x, y, z) m, 1 = valid
    oest: np.ndarray        # (E, 6) the team's object estimate: centre (x, y, z) m, velocity
    ocov: np.ndarray        # (E, 3, 3) its covariance per axis: P_pp m2, P_pv m2 s-1, P_vv
    odet: np.ndarray        # (E,) int 1 once the team has a fix of the object
    fixk: np.ndarray        # (E,) int step of the latest fixes in ``fix`` (-1: none yet)
    kf: np.ndarray          # (E,) int step of the fixes the estimate last fused (-1: none)


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    Returns
    -------
    P : UPLParams
        The env's typed scalars.
    W : UPLWork
        The env's per-episode work arrays.

    Raises
    ------
    ConfigError
        Missing or unreachable tier parameters (:func:`check_reachable`), or a bad object
        perception model (:func:`object_perception`).
    """
    need_tier(TASK_ID, tier, *_TIER_KEYS, "dt_s")
    check_reachable(tier)
    dt = float(tier["dt_s"])
    n_ep, n = init["pos0"].shape[:2]
    P = UPLParams(int(tier["quorum"]), dt, episode_steps(tier) * dt, DEFAULT_LAND_THRESHOLD,
                  CLEARANCE_M, float(tier["attach_radius_m"]), float(tier["attach_dwell_s"]),
                  float(tier["detach_radius_m"]), float(tier["sink_speed_ms"]),
                  float(tier["success_depth_m"]), float(tier["hold_radius_m"]),
                  float(tier["survey_std_m"]), *object_perception(dt))
    site = np.ascontiguousarray(init["obj0"], dtype=np.float64)
    chart = np.ascontiguousarray(init.get("chart", site), dtype=np.float64)
    W = UPLWork(site, np.ascontiguousarray(init["slot_off"], dtype=np.float64), site.copy(),
                np.zeros((n_ep, 3)), np.ones(n_ep, dtype=np.bool_),
                np.full((n_ep, n), -1, dtype=np.int64), np.full((n_ep, n), -1, dtype=np.int64),
                np.zeros((n_ep, n)), np.full((n_ep, n), -1, dtype=np.int64),
                np.zeros((n_ep, n, 3)), np.zeros(n_ep), np.zeros(n_ep, dtype=np.int64),
                np.full(n_ep, -1.0), chart.copy(), np.zeros(3, dtype=np.int64),
                np.zeros((n_ep, n, 4)), np.zeros((n_ep, 6)), np.zeros((n_ep, 3, 3)),
                np.zeros(n_ep, dtype=np.int64), np.full(n_ep, -1, dtype=np.int64),
                np.full(n_ep, -1, dtype=np.int64))
    return P, W


def object_perception(dt: float) -> tuple[float, float, float, float, int]:
    """The object's perception model (``sensors.yaml`` ``perception.upl_object``) as the
    kernel's scalars.

    Parameters
    ----------
    dt : float
        Step, s (the fix period ``period_s`` in steps, at least 1).

    Returns
    -------
    tuple
        Detection range (m), range noise (m), bearing noise (rad), echo-centre offset (m),
        one fix every this many steps (int): the tail of ``UPLParams``.

    Raises
    ------
    ConfigError
        A missing parameter (one line, naming it).
    """
    rng, rstd, bdeg, cstd, period = perception_values(
        perception("upl_object"), "upl_object",
        ("range_m", "range_std_m", "bearing_std_deg", "centre_std_m", "period_s"))
    every = max(1, int(round(period / float(dt))))
    return rng, rstd, math.radians(bdeg), cstd, every


#: The task's own observation fields (after :data:`oneocean.tasks.common.OBS_FIELDS`): 1 once
#: the team has a sonar fix of the object (0: its estimate is still the chart); the team's
#: estimate of the object's centre relative to the agent's navigation estimate (x east, y
#: down, z north), m; the estimate's velocity (world), m s-1; the agent's attached slot (index
#: into the briefing's ``slot_off``; -1: not attached). The team's attachments are every
#: agent's ``slot`` (the number attached: the rows with ``slot >= 0``).
OBS_EXTRA_DOCS = {
    "obj_detected": ("", "1 once the team has a sonar fix of the object, else 0"),
    "obj_dx_m": ("m", "the team's estimate of the object's centre minus the agent's navigation "
                      "estimate, east"),
    "obj_dy_m": ("m", "the same, down"),
    "obj_dz_m": ("m", "the same, north"),
    "obj_vx_ms": ("m s-1", "the estimate's velocity, east"),
    "obj_vy_ms": ("m s-1", "the same, down"),
    "obj_vz_ms": ("m s-1", "the same, north"),
    "slot": ("", "the slot the agent is attached to (-1: none)"),
}
OBS_EXTRA = tuple(OBS_EXTRA_DOCS)
#: What the cue is (the observation's ``goal_d*`` fields).
CUE_DOC = ("the agent's own slot on the team's object estimate while attached, else the nearest "
           "slot no agent holds; during the lift, that slot at the surface")

#: The briefing's own fields (after :data:`oneocean.tasks.public.COMMON`): name -> (shape,
#: unit, meaning).
BRIEF_FIELDS = {
    "obj_chart": ("(E, 3)", "m", "the object's charted centre: its last known position, the "
                  "site survey's (the true centre for a method that perceives the object "
                  "exactly)"),
    "slot_off": ("(E, 5, 3)", "m", "the attachment slots' offsets from the object's centre "
                 "(the object's drawing; world frame)"),
    "quorum": ("", "", "attached agents needed before the object moves"),
    "attach_radius": ("", "m", "an agent attaches within this distance of a free slot ..."),
    "attach_dwell": ("", "s", "... after staying there this long"),
    "detach_radius": ("", "m", "an attached agent farther than this from its slot detaches"),
    "sink_speed": ("", "m s-1", "sink speed of the object's net weight alone (the attached "
                   "agents share it)"),
    "success_depth": ("", "m", "success: the object's centre at most this deep ..."),
    "hold_radius": ("", "m", "... within this horizontal distance of the site (the vessel "
                    "waits above it)"),
    "survey_std": ("", "m", "the chart's stated error per horizontal axis"),
    "p_range": ("", "m", "the ROVs' sonar detection range (slant) of the object"),
}


UPLBriefing = briefing_class("UPL", BRIEF_FIELDS, __name__)


def brief(P: UPLParams, W: UPLWork, init: dict, m) -> UPLBriefing:
    """The briefing of every episode of a batch (:class:`oneocean.tasks.public.Mission`
    ``m``): the object's chart, its slots, the rules.

    Also sets the team's sonar (``W.pcfg``): its error streams (the run's seed, the cell's
    episode of row 0) and whether it perceives the object exactly (the method is given the
    true target, ``m.sens.true_target``: the oracle and the ``true_target`` ablation); such a
    method's chart is the object's true centre.

    Returns
    -------
    UPLBriefing
    """
    exact = int(m.sens.true_target != 0)
    W.pcfg[0] = m.seed        # the sonar's error streams: the run's, row e is episode e0 + e
    W.pcfg[1] = exact
    W.pcfg[2] = m.e0
    return UPLBriefing(**common_brief(m), obj_chart=(W.site if exact else W.chart).copy(),
                       slot_off=W.slot_off.copy(), quorum=P.quorum, attach_radius=P.att_r,
                       attach_dwell=P.dwell_s, detach_radius=P.det_r, sink_speed=P.sink,
                       success_depth=P.succ_d, hold_radius=P.hold_r, survey_std=P.survey_std,
                       p_range=P.p_range)


class UPLTeamObs(NamedTuple):
    """UPL's team observation (:data:`TEAM_FIELDS`): views of the team's object estimate,
    updated by :func:`sense` every step."""
    obj_est: np.ndarray     # (E, 6) the object's centre (x, y, z) m and velocity m s-1
    obj_det: np.ndarray     # (E,) int64 1 once the team has a fix of the object


#: The team observation's fields: name -> (shape, unit, meaning).
TEAM_FIELDS = {
    "obj_est": ("(E, 6)", "m, m s-1", "the team's estimate of the object: its centre (world x "
                "east, y down, z north; the navigation's frame) and velocity; the chart at "
                "rest before the first fix"),
    "obj_det": ("(E,)", "", "1 once the team has a sonar fix of the object"),
}


def team_obs(W: UPLWork) -> UPLTeamObs:
    """The team observation: views of ``W.oest`` and ``W.odet`` (:func:`sense` updates them).

    Returns
    -------
    UPLTeamObs
    """
    return UPLTeamObs(W.oest, W.odet)


@hot_kernel
def begin(ctx, e):
    """Put the object at its site, at rest on the floor, clear the attachments, and start
    the team's object estimate from the chart.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``ctx.state`` holds the start. The
    estimate's prior: the charted centre at rest, with the survey's stated error
    horizontally and ``SITE_PRIOR_STD_Y_M`` vertically.

    Returns
    -------
    bool
        False: the episode starts.
    """
    P, W, state = ctx.P, ctx.W, ctx.state
    n = state.shape[1]
    for c in range(3):
        W.obj[e, c] = W.site[e, c]
        W.vobj[e, c] = 0.0
    W.on_floor[e] = True
    for i in range(n):
        W.att[e, i] = -1
        W.owner[e, i] = -1
        W.dwell[e, i] = 0.0
        W.dslot[e, i] = -1
    W.t_att[e] = -1.0
    # the team's prior of the object: the chart, at rest, with the survey's stated error
    # (horizontal) and the charted seafloor's (vertical, SITE_PRIOR_STD_Y_M)
    for c in range(3):
        W.oest[e, c] = W.chart[e, c]
        W.oest[e, 3 + c] = 0.0
        sd = P.survey_std if c != 1 else SITE_PRIOR_STD_Y_M
        W.ocov[e, c, 0] = sd * sd + 1e-6
        W.ocov[e, c, 1] = 0.0
        W.ocov[e, c, 2] = 1e-6
    W.odet[e] = 0
    W.fixk[e] = -1
    W.kf[e] = -1
    return False


@hot_kernel
def pre_step(ctx, e, k):
    """Record the agents' positions, the time and the attached count at the step's start,
    and take this step's sonar fixes of the object (``W.fix``, ``W.fixk``).

    Env hook (:mod:`oneocean.tasks.loop`), before the agents act.
    """
    P, W, state = ctx.P, ctx.W, ctx.state
    t = ctx.t0[e] + k * ctx.dt
    n = state.shape[1]
    S = state[e]
    for i in range(n):
        W.prev[e, i, 0] = S[i, 0]
        W.prev[e, i, 1] = S[i, 1]
        W.prev[e, i, 2] = S[i, 2]
    W.t[e] = t
    n_att = 0
    for i in range(n):
        if W.att[e, i] >= 0:
            n_att += 1
    W.n_att[e] = n_att
    _sonar_fixes(P, W, state, e, k)
    W.fixk[e] = k


@hot_kernel
def _sonar_fixes(P, W, state, e, k):
    """This step's sonar fix of the object by every agent (``W.fix``): the offset of the
    object's centre from the agent, exact for a method that perceives the target exactly
    (``W.pcfg[1]``: the oracle; every step, any range); otherwise, every ``P.p_every`` steps
    while the object is within the slant range ``P.p_range``, the horizontal offset with the
    sonar's range and bearing noise (:func:`~oneocean.sensing.kernels.polar_fix`, counters
    ``4 (k N + i)`` and ``+ 1``) and the vertical one with its elevation noise (``+ 2``),
    plus the echo centre's offset from the object's centre along the line of sight (one
    draw per agent and episode, ``P.p_centre_std``, counter ``4 i + 3``)."""
    n = state.shape[1]
    seed = W.pcfg[0]
    ep = W.pcfg[2] + e
    exact = W.pcfg[1] != 0
    due = k % P.p_every == 0
    for i in range(n):
        dx = W.obj[e, 0] - state[e, i, 0]
        dy = W.obj[e, 1] - state[e, i, 1]
        dz = W.obj[e, 2] - state[e, i, 2]
        F = W.fix[e, i]
        if exact:
            F[0] = dx
            F[1] = dy
            F[2] = dz
            F[3] = 1.0
            continue
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        if not due or r > P.p_range:
            F[3] = 0.0
            continue
        c = 4 * (k * n + i)
        mx, mz = polar_fix(seed, ep, c, dx, dz, P.p_range_std, P.p_bearing_std)
        # the echo's centre lies off the object's centre along the line of sight (the
        # facing surface; per agent and episode: counter 4 i + 3, unused by the steps)
        b = draw(seed, ep, PURPOSE_PERCEPTION, 4 * i + 3, P.p_centre_std)
        if r > 0.0:
            b /= r
        F[0] = mx + b * dx
        F[1] = dy + b * dy + draw(seed, ep, PURPOSE_PERCEPTION, c + 2, r * P.p_bearing_std)
        F[2] = mz + b * dz
        F[3] = 1.0


# ------------------------------------------------------------------ the team's object estimate
#: Horizontal navigation error per axis the object filter assumes for a fix's placement, m
#: (the USBL-aided navigation's, docs/sensing.md: ~0.15 m RMS per axis).
NAV_STD_M = 0.15
#: Acceleration noise of the object filter's constant-velocity model, m s-1.5: resting or
#: sinking, and lifted by the quorum.
QA_REST = 0.02
QA_LIFT = 0.2


@hot_kernel
def _filter(P, W, state, e):
    """Predict the object's estimate over the step, then update it with every valid sonar
    fix (sequential scalar Kalman updates per axis)."""
    n = state.shape[1]
    dt = P.dt
    qa = QA_LIFT if W.n_att[e] >= P.quorum else QA_REST
    q2 = qa * qa
    O = W.oest[e]
    C = W.ocov[e]
    for c in range(3):
        a = C[c, 0]
        b = C[c, 1]
        d = C[c, 2]
        O[c] += O[3 + c] * dt
        C[c, 0] = a + 2.0 * dt * b + dt * dt * d + q2 * dt * dt * dt / 3.0
        C[c, 1] = b + dt * d + 0.5 * q2 * dt * dt
        C[c, 2] = d + q2 * dt
    for i in range(n):
        F = W.fix[e, i]
        if F[3] == 0.0:
            continue
        W.odet[e] = 1
        r2 = F[0] * F[0] + F[1] * F[1] + F[2] * F[2]
        rv = (P.p_range_std * P.p_range_std + P.p_centre_std * P.p_centre_std
              + r2 * P.p_bearing_std * P.p_bearing_std)
        for c in range(3):
            v = rv + (NAV_STD_M * NAV_STD_M if c != 1 else 0.0)   # depth is measured
            a = C[c, 0]
            b = C[c, 1]
            d = C[c, 2]
            s = a + v
            kp_ = a / s
            kv_ = b / s
            y = state[e, i, c] + F[c] - O[c]
            O[c] += kp_ * y
            O[3 + c] += kv_ * y
            C[c, 0] = a - kp_ * a
            C[c, 1] = b - kp_ * b
            C[c, 2] = d - kv_ * b


@hot_kernel
def perceive(P, W, X, e):
    """Fuse the latest sonar fixes into the team's object estimate, once per set of fixes
    (``W.fixk`` / ``W.kf``).

    Exact for a method that perceives the object exactly (``W.pcfg[1]``, :func:`brief`),
    else a constant-velocity Kalman filter per axis with the fixes placed at the agents'
    known positions ``X`` (module docstring). Called by :func:`sense` every step, for every
    method.

    Parameters
    ----------
    P : UPLParams
        The task's params (:func:`make`).
    W : UPLWork
        The task's per-episode work arrays (:func:`make`); ``oest``, ``ocov``, ``odet`` and
        ``kf`` updated.
    X : (E, N, STATE_DIM) float64
        The vehicle states the method knows (layout: :mod:`oneocean.engine.dynamics`).
    e : int
        Episode index.
    """
    if W.kf[e] == W.fixk[e]:
        return
    W.kf[e] = W.fixk[e]
    if W.pcfg[1] != 0:   # the object perceived exactly
        for c in range(3):
            W.oest[e, c] = W.obj[e, c]
            W.oest[e, 3 + c] = W.vobj[e, c]
        W.odet[e] = 1
    else:
        _filter(P, W, X, e)


@hot_kernel(inline="always")
def cue(ctx, e, k, i):
    """Agent ``i``'s cue: its slot on the team's object estimate (the task's own guidance).

    Env hook (:mod:`oneocean.tasks.loop`), after :func:`sense` updated the estimate. The
    agent's own slot while attached; else the nearest slot (to its navigation estimate) that
    no agent holds. While the agent is attached and the quorum holds (the lift), the slot at
    the surface (the object's centre ``SLOT_RISE_M`` deep, above the success depth): the
    vertical goal of the lift. No probe (NaN).

    Returns
    -------
    gx, gy, gz : float
        The goal cue, world m.
    probe : float
        NaN (the task has no field).
    """
    P, W, X = ctx.P, ctx.W, ctx.X
    off = W.slot_off[e]
    ox = W.oest[e, 0]
    oy = W.oest[e, 1]
    oz = W.oest[e, 2]
    n_att = 0
    for i2 in range(X.shape[1]):
        if W.att[e, i2] >= 0:
            n_att += 1
    j = W.att[e, i]
    if j < 0:
        best = np.inf
        for j2 in range(off.shape[0]):
            if W.owner[e, j2] >= 0:
                continue
            d2 = ((X[e, i, 0] - ox - off[j2, 0]) ** 2
                  + (X[e, i, 1] - oy - off[j2, 1]) ** 2
                  + (X[e, i, 2] - oz - off[j2, 2]) ** 2)
            if d2 < best:
                best = d2
                j = j2
    elif n_att >= P.quorum:   # lifting: the slot at the surface
        oy = SLOT_RISE_M
    if j < 0:   # every slot held (a team larger than the slots): no cue
        return math.nan, math.nan, math.nan, math.nan
    return ox + off[j, 0], oy + off[j, 1], oz + off[j, 2], math.nan


@hot_kernel
def sense(ctx, e, k):
    """The team's object estimate (:func:`perceive`, on this step's sonar fixes) and the
    task's observation fields (:data:`OBS_EXTRA`) of every agent. Env hook
    (:mod:`oneocean.tasks.loop`), before the cue.
    """
    P, W, X, O = ctx.P, ctx.W, ctx.X, ctx.O
    perceive(P, W, X, e)
    est = W.oest[e]
    det = float(W.odet[e])
    for i in range(X.shape[1]):
        o = O[e, i]
        o[OBS_DIM] = det
        o[OBS_DIM + 1] = est[0] - X[e, i, 0]
        o[OBS_DIM + 2] = est[1] - X[e, i, 1]
        o[OBS_DIM + 3] = est[2] - X[e, i, 2]
        o[OBS_DIM + 4] = est[3]
        o[OBS_DIM + 5] = est[4]
        o[OBS_DIM + 6] = est[5]
        o[OBS_DIM + 7] = float(W.att[e, i])


@hot_kernel(inline="always")
def after_agent(ctx, e, k, i):
    """After the last agent's own step: the object (and the assembly) moves, before the
    near-collision count.

    Env hook (:mod:`oneocean.tasks.loop`), right after agent ``i`` moved; nothing for the
    other agents. With the quorum attached the assembly moves (module docstring, Lift);
    without it a suspended object sinks at ``P.sink`` and drifts with the current.
    """
    grid, P, W, state = ctx.grid, ctx.P, ctx.W, ctx.state
    n = state.shape[1]
    if i != n - 1:
        return
    dt = P.dt
    sink = P.sink
    land_thr = P.land_thr
    S = state[e]
    PV = W.prev[e]
    A = W.att[e]
    ox = W.obj[e, 0]
    oy = W.obj[e, 1]
    oz = W.obj[e, 2]
    on_floor = W.on_floor[e]
    n_att = W.n_att[e]
    pox = ox
    poy = oy
    poz = oz
    if n_att >= P.quorum:
        mx = 0.0
        my = 0.0
        mz = 0.0
        for i2 in range(n):
            if A[i2] >= 0:
                mx += S[i2, 0] - PV[i2, 0]
                my += S[i2, 1] - PV[i2, 1]
                mz += S[i2, 2] - PV[i2, 2]
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
        for i2 in range(n):
            if A[i2] >= 0:
                qx = S[i2, 0] + cx
                qy = S[i2, 1] + cy
                qz = S[i2, 2] + cz
                if qy >= 0.0 and _feasible(grid, qx, qy, qz, land_thr, P.clearance):
                    S[i2, 0] = qx
                    S[i2, 1] = qy
                    S[i2, 2] = qz
    elif not on_floor:  # suspended without the quorum: sinks and drifts
        ce, cn = _current(grid, ox, oy, oz, W.t[e])
        ox, oy, oz, on_floor = _place_object(grid, ox, oy, oz, ox + ce * dt,
                                             oy + sink * dt, oz + cn * dt, land_thr)
    W.obj[e, 0] = ox
    W.obj[e, 1] = oy
    W.obj[e, 2] = oz
    W.on_floor[e] = on_floor
    W.vobj[e, 0] = (ox - pox) / dt
    W.vobj[e, 1] = (oy - poy) / dt
    W.vobj[e, 2] = (oz - poz) / dt


@hot_kernel
def post_step(ctx, e, k):
    """Attach / detach, the quorum's first time, success.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``.

    Returns
    -------
    bool
        True (STOP) once the object's centre is at most ``P.succ_d`` deep within
        ``P.hold_r`` (horizontally) of the site.
    """
    P, W, state = ctx.P, ctx.W, ctx.state
    n = state.shape[1]
    dt = P.dt
    S = state[e]
    A = W.att[e]
    O = W.owner[e]
    DW = W.dwell[e]
    DS = W.dslot[e]
    off = W.slot_off[e]
    ox = W.obj[e, 0]
    oy = W.obj[e, 1]
    oz = W.obj[e, 2]
    for i in range(n):
        px = S[i, 0]
        py = S[i, 1]
        pz = S[i, 2]
        j = A[i]
        if j >= 0:
            d = math.sqrt((px - ox - off[j, 0]) ** 2 + (py - oy - off[j, 1]) ** 2
                          + (pz - oz - off[j, 2]) ** 2)
            if d > P.det_r:
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
                if d <= P.att_r:
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
            if DW[i] >= P.dwell_s - 1e-9:
                A[i] = jn
                O[jn] = i
    if W.t_att[e] < 0.0:
        n_att = 0
        for i in range(n):
            if A[i] >= 0:
                n_att += 1
        if n_att >= P.quorum:
            W.t_att[e] = (k + 1) * dt
    return _success(P, W, e)


@hot_kernel
def _success(P, W, e):
    drift = math.sqrt((W.obj[e, 0] - W.site[e, 0]) ** 2 + (W.obj[e, 2] - W.site[e, 2]) ** 2)
    return W.obj[e, 1] <= P.succ_d and drift <= P.hold_r


@hot_kernel
def finish(ctx, e, k):
    """Write the UPL metrics.

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Returns
    -------
    bool
        Success: the object's centre at most ``P.succ_d`` deep within ``P.hold_r`` of the
        site.
    """
    P, W = ctx.P, ctx.W
    row = ctx.res[e]
    success = _success(P, W, e)
    row[_C_LIFT] = 1.0 if success else 0.0
    row[_C_DEPTH] = W.obj[e, 1]
    row[_C_ATT_T] = W.t_att[e] if W.t_att[e] >= 0.0 else P.t_limit
    row[_C_DRIFT] = math.sqrt((W.obj[e, 0] - W.site[e, 0]) ** 2
                              + (W.obj[e, 2] - W.site[e, 2]) ** 2)
    return success


fresh_cache(_sites_kernel, __file__)
