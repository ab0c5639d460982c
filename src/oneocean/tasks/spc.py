"""SPC — surface pollution cleanup (2-10 agents, default 10).

Objective
    A surface spill (:func:`~oneocean.models.pollution.make_spill`: a stretched Gaussian blob
    of ``SPILL_MASS_KG`` with radius ``spill_radius_m``) lies in valid water; it lives on a
    local regular grid of ``FIELD_H_M`` cells, ``domain_m`` wide, centred on the spill, and is
    advected and diffused (``kappa_m2s``) by the product's surface currents
    (:func:`~oneocean.models.pollution.step_field`, conservative finite volumes; face
    velocities sampled with :func:`~oneocean.tasks.common.current_at` at ``SURFACE_Y_M``
    every ``FACE_REFRESH_STEPS`` steps). The local grid's sides are OPEN: mass carried out of
    it has escaped (reached the coast / left the response area) and counts as not removed.
    Cells where a surface vehicle cannot be (land, too shallow, outside the product grid) are
    frozen land cells of the field. The team starts clustered at a staging point
    ``staging_distance_m`` from the spill centre (straight, clear surface path to it), UP-current
    of the spill (bearing opposite the data surface current at the centre at t0, gain and tides
    ignored so currents-off episodes share the geometry, +- ``STAGING_SPREAD_RAD``): the slick
    drifts away from the response base and the team has to catch it. The spill site's mean
    surface current over the episode lies in the tier's ``current_band`` (quantiles of the
    region's own surface speeds, :class:`oneocean.tasks.Cell`): harder tiers are spills in
    moving water (a spill in slack water is no response challenge); the currents-off ablation
    replays the same sites.
Physics (identical for every method)
    Each step every vehicle moves (:func:`~oneocean.engine.step.advance_agent`), then removes
    the fraction ``removal_rate_s * dt`` of the concentration of every field cell whose centre
    is within ``removal_radius_m`` of it (:func:`~oneocean.models.pollution.remove_in_radius`,
    in agent order), then the field advances by ``dt``.
Success and the metric horizon
    Success: ``removed >= target_fraction * initial mass`` (team total), checked after every
    step; ``T_s`` is the time at which it was first reached (the time limit on failure). The
    episode does NOT stop there: it runs to the fixed metric horizon, the tier's
    ``time_limit_s``, the same for every method and episode (``post_step`` returns the loop's
    ``REACHED``; :mod:`oneocean.tasks.loop`), so the cleanup rate measures removal over one
    fixed response time and can exceed the target. ``E``, ``violations`` and ``coll_ratio``
    cover the steps up to success (what a run stopped there reports). Mass budget at the
    horizon: removed + escaped + remaining = initial (round-off).
Metrics (fractions of the initial mass, at the metric horizon)
    ``cleanup_rate`` (primary: removed / initial mass), ``escaped_fraction`` (left the local
    grid / initial), ``remaining_fraction`` (still on the grid / initial),
    ``time_to_target_s`` (time at which the target fraction was reached; the time limit on
    failure, like ``T_s``).
Aerial survey (the task's sensor; the team observation :class:`SPCTeamObs`)
    Oil spill response relies on periodic surveillance overflights (aircraft / drone SLAR,
    IR); a surface vehicle's own sensor only sees the concentration under it. The survey maps
    the surface field in blocks of ``AERIAL_BLOCK_CELLS x AERIAL_BLOCK_CELLS`` cells (40 m):
    each block's oil mass and mass centroid, and the mapped total. It flies every
    ``aerial_period_s`` (the tier's), the first map one period after the start; a method given
    the true target (the oracle, ``SensingParams.true_target``: :func:`brief` sets it in
    ``W``) has the exact map every step from step 0. The map is taken at the step start
    (before the agents move) and kept until the next one; its time ``t_map`` says how old it is.
Briefing (:class:`SPCBriefing`, after the common fields of :mod:`oneocean.tasks.public`)
    The spill report (``report``: the spill's initial centroid, and its radius), the operating
    depth, the survey's period and first map, the layout of the survey's blocks (the field's
    cell (0, 0) centre, cell size, block size and counts), the cleanup equipment (removal
    radius and rate) and the success fraction.
Observation
    The cue is the task's own oil reference for each agent, at ``SURFACE_Y_M``: before the
    first map a ring of radius ``CUE_RING_FRAC * spill_radius_m`` around the spill report
    (agent i at bearing ``2 pi i / N``); at every map the blocks holding at least
    ``CUE_MASS_FRAC`` of the heaviest block's mass, heaviest first, each go to the nearest
    agent (its known position) without one, again from the heaviest once every such block has
    one (:func:`sense`), and the cue is the agent's block's mass centroid. Either is drifted
    since its time (the start, the map's) with the agent's current estimate of its last
    observation (``current_e_ms`` / ``current_n_ms``; none at step 0): the slick drifts with
    the water, so a follower that closes its cue offset through the water (not over ground)
    keeps up with its oil. The pollution probe is the surface concentration under the vehicle
    (its known position), kg m-2. No fields of its own (:data:`OBS_EXTRA` is empty); the team
    observation is the aerial map.
Methods
    :mod:`oneocean.methods.heuristic.spc` (greedy assignment of the agents to the mapped
    blocks as the team-level ``plan``, drift-compensated seek; both at full speed; heuristic:
    the periodic survey and the sensor models of :mod:`oneocean.sensing`; oracle: the exact
    map every step, true current and position).

Module layout: as :mod:`oneocean.tasks.g2g` (``reset``, split as ``reset_candidates`` /
``reset_build`` so that ``Cell.reset`` builds only the spills its current band keeps;
``SPCParams`` / ``SPCWork`` and ``make``: the per-episode field, land mask, face
velocities, mass accumulators, the survey's map and the cue's reference with a leading
episode axis; the public view: ``SPCBriefing`` / ``BRIEF_FIELDS`` / ``brief``,
``SPCTeamObs`` / ``TEAM_FIELDS`` / ``team_obs``; env hooks ``begin``, ``pre_step`` (face
refresh), ``cue``, ``sense`` (the survey, the cue's reference), ``post_step`` (removal in
agent order, field step, success reached), ``finish``; the compiled loop is
:mod:`oneocean.kernels.spc`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..engine import status as st
from ..engine import streams
from ..engine.constraints import DEFAULT_LAND_THRESHOLD, check_move
from ..engine.status import OK
from ..engine.grid import (current_from_parts, locate_time, sample_current_data,
                           sample_current_parts, synthetic_tide)
from ..engine._jit import hot_kernel
from ..errors import ConfigError, NotApplicable
from ..models import pollution as pol
from ..models.pollution import spill_box
from .common import O_CE, O_CN, PURPOSE_RESET, STANDARD, fresh_cache
from .spawn import _SPAWN_BATCH, _call, _segment_clear, _spawn_one_c, path_clear, start_times
from .tiers import episode_steps, need_tier
from .public import briefing_class, common_brief
from .loop import GO, REACHED
from ..engine import libm

TASK_ID = "SPC"
METRICS = ("cleanup_rate", "escaped_fraction", "remaining_fraction", "time_to_target_s")
#: Result-matrix columns written by the kernel (standard columns first).
COLUMNS = STANDARD + METRICS

#: Field cell size, m.
FIELD_H_M = 10.0
#: Initial spill mass, kg (results are fractions of it).
SPILL_MASS_KG = 1000.0
#: Operating depth of the surface vehicles, m.
SURFACE_Y_M = 0.5
#: Seafloor clearance of the feasibility check, m (engine default).
CLEARANCE_M = 1.0
#: Face velocities are re-sampled from the product every this many steps.
FACE_REFRESH_STEPS = 30
#: Staging cluster spacing, m.
STAGING_SPACING_M = 6.0
#: The staging point's bearing from the spill is up-current (opposite the data surface current
#: at the spill centre at t0, current gain and tides ignored) +- this spread, rad.
STAGING_SPREAD_RAD = math.pi / 4
#: The spill centre must have surface-feasible water on rings up to this many spill radii.
CLEAR_RADII = 1.5
#: Aerial survey block size, cells (with the task's 10 m cells: 40 m blocks).
AERIAL_BLOCK_CELLS = 4
#: The cue's blocks: those holding at least this fraction of the heaviest mapped block's mass.
CUE_MASS_FRAC = 0.25
#: Before the first map the cue spreads the team on a ring of this many spill radii around
#: the spill report.
CUE_RING_FRAC = 0.5

_C_CLEAN, _C_ESC, _C_REM, _C_TTT = (len(STANDARD) + i for i in range(len(METRICS)))

_TIER_KEYS = ("time_limit_s", "spill_radius_m",
              "target_fraction", "staging_distance_m", "removal_radius_m", "removal_rate_s",
              "kappa_m2s", "domain_m", "aerial_period_s")
#: Near-collision radius, m (task contract).
R_COLL_M = 2.0


def staging_offsets(n: int) -> np.ndarray:
    """Start offsets of the agents around the staging point: a square lattice.

    Parameters
    ----------
    n : int
        Number of agents.

    Returns
    -------
    (n, 2) float64
        Offsets, m, ``STAGING_SPACING_M`` apart, centred (before the rotation toward the
        spill that :func:`reset_candidates` applies).
    """
    cols = int(math.ceil(math.sqrt(n)))
    k = np.arange(n)
    off = np.stack([(k % cols) - 0.5 * (cols - 1), (k // cols) - 0.5 * ((n - 1) // cols)], 1)
    return STAGING_SPACING_M * off.astype(float)


def _surface_ok(grid, xz) -> np.ndarray:
    xyz = np.stack([xz[:, 0], np.full(len(xz), SURFACE_Y_M), xz[:, 1]], axis=1)
    return _surface_codes(grid, xyz) == st.OK


def _surface_codes(grid, xyz) -> np.ndarray:
    """``feasibility(grid, xyz, DEFAULT_LAND_THRESHOLD, CLEARANCE_M)`` of C-contiguous
    float64 points, through the compiled entry (no numba dispatch per call)."""
    from ..engine.constraints import check_points

    return _call(check_points, grid, xyz, float(DEFAULT_LAND_THRESHOLD), float(CLEARANCE_M),
                 np.empty(xyz.shape[0], dtype=np.int64))


def field_frame(domain_m: float) -> tuple[int, float]:
    """The local field's size for a domain width.

    Parameters
    ----------
    domain_m : float
        Domain width, m.

    Returns
    -------
    n : int
        Cells per side (at least 8), ``FIELD_H_M`` each.
    half : float
        Offset of cell 0's centre from the spill centre, m (half the distance between the
        first and last cell centres).
    """
    n = max(8, int(round(float(domain_m) / FIELD_H_M)))
    return n, 0.5 * (n - 1) * FIELD_H_M


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the spill, its local field, the staging point and the start time per episode.

    The same as :func:`reset_build` of :func:`reset_candidates` (the split ``Cell.reset``
    uses to build only the candidates it keeps).

    Returns
    -------
    dict
        ``pos0`` (E, N, 3) starts, m; ``psi0`` (E, N) headings toward the spill, rad;
        ``t0`` (E,) start times, s; ``C0`` (E, 1, n, n) initial field, kg m-2;
        ``land`` (E, n, n) uint8 frozen cells; ``origin`` (E, 2) world (x, z) of cell (0, 0)
        centre, m; ``report`` (E, 2) initial spill centroid (x, z), m; ``regime_points``
        (E, 1, 3) the spill centroid at the surface (``Cell.reset``).

    Raises
    ------
    ConfigError
        Team size outside 2..10, missing tier keys, or a spill too large for the domain.
    NotApplicable
        No valid spill site with a clear staging point.
    """
    cand = reset_candidates(grid, tier, n_agents, n_episodes, seed)
    cand["candidate"] = np.arange(int(n_episodes), dtype=np.int64)
    return reset_build(grid, tier, n_agents, cand, seed)


def _spill_box(n: int, half: float, R: float) -> slice:
    """The field cells (per axis, the same for x and z) that can hold spill mass: the spill
    (:func:`~oneocean.models.pollution.make_spill`) is cut at ``2 R`` from the spill centre,
    the field's centre; one cell of margin for round-off."""
    off = np.arange(n) * FIELD_H_M - half
    inside = np.flatnonzero(np.abs(off) <= 2.0 * R + FIELD_H_M)
    return slice(int(inside[0]), int(inside[-1]) + 1)


#: Spill-site draws per candidate.
_SITE_TRIES = 1000
#: :func:`_candidates_kernel` statuses: the candidate drawn; no site in ``_SITE_TRIES``; a
#: case the kernel leaves to the Python sampler, which raises its error (no start water for
#: the spawn, no water cell near the spill).
_FOUND, _NO_SITE, _PYTHON = 0, 1, 2


def _rings(R: float) -> np.ndarray:
    """The offsets from a spill site that must be surface water: the site, then 16 bearings
    on rings of 0.5 to ``CLEAR_RADII`` spill radii, (m, 2) (x, z), m."""
    ang = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    return np.ascontiguousarray(np.concatenate(
        [[[0.0, 0.0]]] + [r * np.stack([libm.sin(ang), libm.cos(ang)], 1)
                          for r in np.linspace(0.5, CLEAR_RADII, 3) * R]))


def _no_site(e: int, R: float, dist: float) -> str:
    return (f"task {TASK_ID} reset (episode {e}): no spill site clear of land within "
            f"{CLEAR_RADII * R:g} m with a clear staging point {dist:g} m away; the grid has "
            f"no such water for this tier")


def _candidate_python(grid, raw, rng, tier: dict, n_agents: int, t0: float, e: int):
    """One candidate by the Python samplers (what :func:`_candidates_kernel` draws):
    ``(starts, spill box, origin, report)``; raises their errors."""
    from .spawn import _spawn_one

    R = float(tier["spill_radius_m"])
    dist = float(tier["staging_distance_m"])
    n, half = field_frame(float(tier["domain_m"]))
    off = staging_offsets(n_agents)
    rings = _rings(R)
    box = _spill_box(n, half, R)
    b = box.stop - box.start
    for _ in range(_SITE_TRIES):
        try:   # spawn_positions(grid, rng, 1, {"y": (SURFACE_Y_M,) * 2}, ...)[0]
            c = _spawn_one(grid, rng, SURFACE_Y_M, DEFAULT_LAND_THRESHOLD, CLEARANCE_M)
        except ConfigError as exc:
            raise NotApplicable(f"task {TASK_ID} reset (episode {e}): {exc}") from None
        cxz = np.array([c[0], c[2]])
        if not _surface_ok(grid, cxz + rings).all():
            continue
        # the response base lies up-current of the spill: the slick drifts away from it
        ue, un = _call(sample_current_data, raw, float(c[0]), float(SURFACE_Y_M),
                       float(c[2]), float(t0))
        a = rng.uniform(-STAGING_SPREAD_RAD, STAGING_SPREAD_RAD)
        if math.isfinite(ue) and math.isfinite(un) and ue * ue + un * un > 1e-6:
            a += math.atan2(-ue, -un)
        else:
            a = rng.uniform(-np.pi, np.pi)  # slack water: any direction (documented)
        u = np.array([math.sin(a), math.cos(a)])
        stg = cxz + dist * u
        rot = np.stack([u[1] * off[:, 0] + u[0] * off[:, 1],
                        -u[0] * off[:, 0] + u[1] * off[:, 1]], 1)
        starts = stg + rot
        if not _surface_ok(grid, starts).all():
            continue
        p_s = np.array([stg[0], SURFACE_Y_M, stg[1]])
        if path_clear(grid, p_s, c, CLEARANCE_M, DEFAULT_LAND_THRESHOLD, spacing_m=10.0):
            break
    else:
        raise NotApplicable(_no_site(e, R, dist))
    x0, z0 = cxz[0] - half, cxz[1] - half
    # the box's land cells (none outside it), cell centres (x0 + ci[i], z0 + ci[j]), row j,
    # as the full mask has them
    ci = np.arange(n) * FIELD_H_M
    land = np.zeros((n, n), dtype=np.uint8)
    xyz = np.empty((b * b, 3))
    xyz[:, 1] = SURFACE_Y_M
    xyz[:, 0] = np.tile(x0 + ci[box], b)
    xyz[:, 2] = np.repeat(z0 + ci[box], b)
    land[box, box] = (_surface_codes(grid, xyz) != st.OK).reshape(b, b)
    C = pol.make_spill(n, n, FIELD_H_M, cxz, R, SPILL_MASS_KG, rng, x0=x0, z0=z0, land=land)
    if np.count_nonzero(C.view(np.int64)) != np.count_nonzero(C[0, box, box].view(np.int64)):
        raise RuntimeError(f"task {TASK_ID} reset (episode {e}): spill mass outside its "
                           f"box")   # never: make_spill cuts the blob at 2 R
    xc, zc, _ = pol.centroid(C, 0, x0, z0, FIELD_H_M)
    return starts, C[0, box, box], (x0, z0), (xc, zc)


@hot_kernel
def _candidates_kernel(grid, raw, stv, t0, rings, off, dist, R, cut, n, half, i0, i1, cand,
                       land, w, stack, starts, spill, origin, report, status):
    """:func:`_candidate_python` of every candidate from its stream ``stv[e]``, compiled: the
    same draws in the same order, the same checks and the same values (the spill through
    :func:`~oneocean.models.pollution.spill_box`, the centroid over its box: every other cell
    is zero). ``status[e]``: ``_FOUND`` (``starts[e]``, ``spill[e]``, ``origin[e]``,
    ``report[e]`` written), ``_NO_SITE`` or ``_PYTHON``."""
    lt = DEFAULT_LAND_THRESHOLD
    cl = CLEARANCE_M
    y = SURFACE_Y_M
    h = FIELD_H_M
    n_agents = off.shape[0]
    for e in range(stv.shape[0]):
        status[e] = _NO_SITE
        found = False
        cx = cy = cz = 0.0
        for _ in range(_SITE_TRIES):
            q = _spawn_one_c(grid, stv, e, cand, y, lt, cl)
            if q < 0:
                status[e] = _PYTHON
                break
            cx, cy, cz = cand[q, 0], cand[q, 1], cand[q, 2]
            clear = True
            for k in range(rings.shape[0]):
                if check_move(grid, cx + rings[k, 0], y, cz + rings[k, 1], lt, cl) != OK:
                    clear = False
                    break
            if not clear:
                continue
            ue, un = sample_current_data(raw, cx, y, cz, t0[e])
            a = streams.uniform(stv, e, -STAGING_SPREAD_RAD, STAGING_SPREAD_RAD)
            if math.isfinite(ue) and math.isfinite(un) and ue * ue + un * un > 1e-6:
                a += math.atan2(-ue, -un)
            else:
                a = streams.uniform(stv, e, -math.pi, math.pi)
            u0 = math.sin(a)
            u1 = math.cos(a)
            sx = cx + dist * u0
            sz = cz + dist * u1
            for q in range(n_agents):
                starts[e, q, 0] = sx + (u1 * off[q, 0] + u0 * off[q, 1])
                starts[e, q, 1] = sz + (-u0 * off[q, 0] + u1 * off[q, 1])
                if check_move(grid, starts[e, q, 0], y, starts[e, q, 1], lt, cl) != OK:
                    clear = False
                    break
            if not clear:
                continue
            # path_clear(staging point -> site, spacing 10 m)
            dx = cx - sx
            dy = cy - y
            dz = cz - sz
            k_pts = max(2, int(math.ceil(math.sqrt(dx * dx + dy * dy + dz * dz) / 10.0)) + 1)
            if _segment_clear(grid, sx, y, sz, cx, cy, cz, k_pts, lt, cl):
                found = True
                break
        if not found:
            continue
        x0 = cx - half
        z0 = cz - half
        for j in range(i0, i1):
            for i in range(i0, i1):
                land[j, i] = 0 if check_move(grid, x0 + i * h, y, z0 + j * h,
                                             lt, cl) == OK else 1
        stretch = streams.uniform(stv, e, 1.0, 2.0)
        th = streams.uniform(stv, e, 0.0, math.pi)
        total = spill_box(n, h, x0, z0, cx, cz, R, cut, SPILL_MASS_KG, stretch, th, land, i0,
                          i1, w, stack, spill[e])
        if not total > 0.0:
            status[e] = _PYTHON
            continue
        mm = 0.0
        mx = 0.0
        mz = 0.0
        for j in range(i0, i1):
            for i in range(i0, i1):
                c = spill[e, j - i0, i - i0]
                mm += c
                mx += c * (x0 + i * h)
                mz += c * (z0 + j * h)
        origin[e, 0] = x0
        origin[e, 1] = z0
        report[e, 0] = mx / mm
        report[e, 1] = mz / mm
        status[e] = _FOUND
    return status


def reset_candidates(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """The first half of :func:`reset`: what ``Cell.reset``'s band check needs of the candidates,
    and what :func:`reset_build` needs to finish them.

    Per candidate (its own stream): the start time, the spill site and staging search, the
    spill (its mass lies within ``2 spill_radius_m`` of the site, so only the land cells of
    that box are checked: the field is bit for bit the one of the full land mask) and its
    centroid.

    Returns
    -------
    dict
        ``t0`` (E,) start times, s; ``regime_points`` (E, 1, 3) the spill centroid at the
        surface, m; ``starts`` (E, N, 2) the agents' (x, z) starts, m; ``spill`` (E, b, b) the
        box of the initial field that holds the spill, kg m-2; ``origin`` (E, 2) world (x, z) of
        cell (0, 0) centre, m; ``report`` (E, 2) initial spill centroid (x, z), m.

    Raises
    ------
    ConfigError
        Team size outside 2..10, missing tier keys, or a spill too large for the domain.
    NotApplicable
        No valid spill site with a clear staging point.
    """
    n_agents = int(n_agents)
    if not 2 <= n_agents <= 10:
        raise ConfigError(f"task {TASK_ID}: n_agents must be in [2, 10], got {n_agents}")
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    R = float(tier["spill_radius_m"])
    dist = float(tier["staging_distance_m"])
    n, half = field_frame(float(tier["domain_m"]))
    if 2.0 * R > half:
        raise ConfigError(f"task {TASK_ID}: spill_radius_m={R:g} too large for domain_m="
                          f"{tier['domain_m']}")
    rngs = streams.episode_states(seed, n_episodes, PURPOSE_RESET)   # one stream per episode
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    first = rngs.copy()                     # each episode's stream where its draws begin
    off = staging_offsets(n_agents)
    rings = _rings(R)
    box = _spill_box(n, half, R)
    b = box.stop - box.start
    starts_all = np.empty((n_episodes, n_agents, 2))
    spill = np.empty((n_episodes, b, b))
    origin = np.empty((n_episodes, 2))
    report = np.empty((n_episodes, 2))
    # the mean data current (gain and tides dropped: same geometry with currents off)
    raw = grid._replace(gain=1.0, tide_layers=0)
    status = _call(_candidates_kernel, grid, raw, rngs, t0, rings, off, dist, R, (2.0 * R) ** 2,
                   n, half, box.start, box.stop, np.empty((_SPAWN_BATCH, 3)),
                   np.zeros((n, n), dtype=np.uint8), np.empty(n * n), np.empty((64, 5)),
                   starts_all, spill, origin, report, np.empty(n_episodes, dtype=np.int64))
    for e in np.flatnonzero(status):
        # in the episodes' order, as the draws in order would: the Python sampler from the
        # episode's first draw (its own errors and messages), or no site in the tries
        if status[e] == _NO_SITE:
            raise NotApplicable(_no_site(e, R, dist))
        starts_all[e], spill[e], origin[e], report[e] = _candidate_python(
            grid, raw, streams.generator(first[e]), tier, n_agents, float(t0[e]), int(e))
    # the current regime is judged where the slick drifts: the spill's centre at the surface
    site = np.column_stack([report[:, 0], np.full(n_episodes, SURFACE_Y_M), report[:, 1]])
    return {"t0": t0, "regime_points": site[:, None, :], "starts": starts_all,
            "spill": spill, "origin": origin, "report": report}


def reset_build(grid, tier: dict, n_agents: int, cand: dict, seed: int) -> dict:
    """The second half of :func:`reset`: the episodes of the chosen candidates.

    The full land mask, the initial field, the starts and headings.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    tier : dict
        Tier parameters (``spill_radius_m``, ``domain_m``).
    n_agents : int
        Team size N.
    cand : dict
        A :func:`reset_candidates` dict with every per-candidate array indexed by the chosen
        candidates (``cand["candidate"]``: their indices, unused here).
    seed : int
        Run seed (unused: everything random was drawn by :func:`reset_candidates`).

    Returns
    -------
    dict
        :func:`reset`'s dict.
    """
    R = float(tier["spill_radius_m"])
    n, half = field_frame(float(tier["domain_m"]))
    box = _spill_box(n, half, R)
    t0, starts, origin, report = cand["t0"], cand["starts"], cand["origin"], cand["report"]
    n_episodes = t0.shape[0]
    pos0 = np.empty((n_episodes, int(n_agents), 3))
    C0 = np.zeros((n_episodes, 1, n, n))
    land = np.empty((n_episodes, n, n), dtype=np.uint8)
    ci = np.arange(n) * FIELD_H_M
    xyz = np.empty((n * n, 3))
    xyz[:, 1] = SURFACE_Y_M
    for e in range(n_episodes):
        x0, z0 = origin[e]
        # the cell centres (x0 + ci[i], z0 + ci[j]), row j (np.meshgrid's order)
        xyz[:, 0] = np.tile(x0 + ci, n)
        xyz[:, 2] = np.repeat(z0 + ci, n)
        ok = (_surface_codes(grid, xyz) == st.OK).reshape(n, n)
        land[e] = (~ok).astype(np.uint8)
        C0[e, 0, box, box] = cand["spill"][e]
        pos0[e, :, 0] = starts[e, :, 0]
        pos0[e, :, 1] = SURFACE_Y_M
        pos0[e, :, 2] = starts[e, :, 1]
    d = report[:, None, :] - pos0[:, :, [0, 2]]
    psi0 = libm.arctan2(d[..., 0], d[..., 1])
    return {"pos0": pos0, "psi0": psi0, "t0": t0, "C0": C0, "land": land, "origin": origin,
            "report": report, "regime_points": cand["regime_points"]}


@hot_kernel
def _refresh_faces(grid, uf, vf, x0, z0, h, y, key, part, t):
    """Sample the surface current at the field's face centres (see pollution module doc):
    :func:`~.common.current_at` at one time ``t``, the time located and the synthetic tide
    taken once per refresh instead of per face; each face's component over the time
    interval in parts (``key`` (2,) the interval ``part`` (F, 4) holds), sampled when ``t``
    enters a new interval (the same arithmetic)."""
    nz = uf.shape[0]
    nx = vf.shape[1]
    ti0, ti1, wt = locate_time(grid, t)
    te, tn = synthetic_tide(grid, t)
    if key[0] != ti0 or key[1] != ti1:
        p = 0
        for j in range(nz):
            z = z0 + j * h
            for i in range(nx + 1):
                u0, u1, _, _, ut0, ut1, _, _ = sample_current_parts(
                    grid, x0 + (i - 0.5) * h, y, z, ti0, ti1)
                part[p, 0], part[p, 1], part[p, 2], part[p, 3] = u0, u1, ut0, ut1
                p += 1
        for j in range(nz + 1):
            z = z0 + (j - 0.5) * h
            for i in range(nx):
                _, _, v0, v1, _, _, vt0, vt1 = sample_current_parts(grid, x0 + i * h, y, z,
                                                                    ti0, ti1)
                part[p, 0], part[p, 1], part[p, 2], part[p, 3] = v0, v1, vt0, vt1
                p += 1
        key[0] = ti0
        key[1] = ti1
    p = 0
    for j in range(nz):
        for i in range(nx + 1):
            uf[j, i] = current_from_parts(grid, wt, part[p, 0], part[p, 1], part[p, 2],
                                          part[p, 3]) + te
            p += 1
    for j in range(nz + 1):
        for i in range(nx):
            vf[j, i] = current_from_parts(grid, wt, part[p, 0], part[p, 1], part[p, 2],
                                          part[p, 3]) + tn
            p += 1




class SPCParams(NamedTuple):
    """SPC's params (one rollout).

    Attributes
    ----------
    dt : float
        Step, s.
    n_steps : int
        Episode length, steps (the time limit).
    h : float
        Field cell size, m.
    y : float
        Operating depth, m.
    kappa : float
        Diffusivity, m2 s-1.
    rad : float
        Removal radius, m.
    eff : float
        Removal rate, s-1.
    target : float
        Success: removed fraction of the initial mass.
    refresh : int
        Face velocities are re-sampled every this many steps.
    cue_frac : float
        The cue's blocks hold at least this fraction of the heaviest block's mass
        (:data:`CUE_MASS_FRAC`).
    ring : float
        Radius of the cue's ring around the spill report before the first map, m
        (``CUE_RING_FRAC * spill_radius_m``).
    """
    dt: float           # step, s
    n_steps: int        # episode length, steps (the time limit)
    h: float            # field cell size, m
    y: float            # operating depth, m
    kappa: float        # diffusivity, m2 s-1
    rad: float          # removal radius, m
    eff: float          # removal rate, s-1
    target: float       # success: removed fraction of the initial mass
    refresh: int        # face velocities re-sampled every this many steps
    cue_frac: float     # the cue's blocks: at least this fraction of the heaviest's mass
    ring: float         # radius of the cue's ring around the report before the first map, m


class SPCWork(NamedTuple):
    """SPC's per-episode work arrays.

    Attributes
    ----------
    origin : (E, 2) float64
        World (x, z) of cell (0, 0) centre, m.
    report : (E, 2) float64
        Reported initial spill centroid (x, z), m.
    t0 : (E,) float64
        Start times, s since the grid's ``time0``.
    C : (E, 1, nz, nx) float64
        Field, kg m-2 (a copy of ``init["C0"]``).
    land : (E, nz, nx) uint8
        Frozen cells.
    uf : (E, nz, nx + 1) float64
        x-face velocities, m s-1.
    vf : (E, nz + 1, nx) float64
        z-face velocities, m s-1.
    work : (E, work_size) float64
        Field-step scratch.
    fkey : (E, 2) int64
        The interval of the grid's time axis ``fpart`` holds (-1: none yet).
    fpart : (E, F, 4) float64
        Every face centre's velocity component over that interval, in parts
        (:func:`oneocean.engine.grid.sample_current_parts`: east at the x-faces, north at the
        z-faces); ``F = nz (nx + 1) + (nz + 1) nx``, the x-faces row by row, then the
        z-faces.
    fpar : (E, 1) float64
        Field-kind parameters (tracer: unused).
    acc : (E, 3) float64
        Initial mass, removed, escaped, kg.
    k_hit : (E,) int64
        Steps to the target fraction (-1: not reached).
    map_every, map_from : (E,) int64
        The aerial survey maps at the steps ``k >= map_from`` with ``k % map_every == 0``
        (:func:`make`: every ``aerial_period_s`` from one period on; :func:`brief`: every step
        from step 0 for a method given the true target).
    tmap : (E,) float64
        The map's time, s since the grid's ``time0`` (NaN: no map yet).
    bm : (E, nb) float64
        The map's block masses, kg.
    bx, bz : (E, nb) float64
        The map's block mass centroids x and z, m (0 for an empty block).
    mtot : (E,) float64
        The mapped mass, kg.
    cue_xz : (E, N, 2) float64
        Each agent's cue point (x, z) at the cue's time, m (the ring around the report, then
        its block's centroid).
    cue_t : (E,) float64
        The cue's time (the start, then the map's), s since the grid's ``time0``.
    cest : (E, N, 2) float64
        Each agent's current estimate (east, north) of its last observation, m s-1 (0 at
        step 0): the cue's drift.
    cue_used : (E, nb) int64
        Scratch of the cue's assignment: block given in the current round.
    cue_given : (E, N) int64
        Scratch of the cue's assignment: agent given a block.
    """
    origin: np.ndarray  # (E, 2) world (x, z) of cell (0, 0) centre, m
    report: np.ndarray  # (E, 2) reported initial spill centroid (x, z), m
    t0: np.ndarray      # (E,) start times, s since the grid's time0
    C: np.ndarray       # (E, 1, nz, nx) field, kg m-2 (a copy of init C0)
    land: np.ndarray    # (E, nz, nx) uint8 frozen cells
    uf: np.ndarray      # (E, nz, nx + 1) x-face velocities, m s-1
    vf: np.ndarray      # (E, nz + 1, nx) z-face velocities, m s-1
    work: np.ndarray    # (E, work_size) field-step scratch
    fkey: np.ndarray    # (E, 2) int64 the time interval fpart holds (-1: none)
    fpart: np.ndarray   # (E, F, 4) the face centres' components over it, in parts
    fpar: np.ndarray    # (E, 1) field-kind parameters (tracer: unused)
    acc: np.ndarray     # (E, 3) initial mass, removed, escaped, kg
    k_hit: np.ndarray   # (E,) int64 steps to the target fraction (-1: not reached)
    # the aerial survey (the team observation, team_obs)
    map_every: np.ndarray  # (E,) int64 a map every this many steps ...
    map_from: np.ndarray   # (E,) int64 ... from this step on
    tmap: np.ndarray    # (E,) the map's time, s since time0 (NaN: none yet)
    bm: np.ndarray      # (E, nb) block masses, kg
    bx: np.ndarray      # (E, nb) block mass centroids x, m
    bz: np.ndarray      # (E, nb) block mass centroids z, m
    mtot: np.ndarray    # (E,) mapped mass, kg
    # the cue's reference
    cue_xz: np.ndarray  # (E, N, 2) cue points (x, z) at the cue's time, m
    cue_t: np.ndarray   # (E,) the cue's time (start, then the map's), s since time0
    cest: np.ndarray    # (E, N, 2) current estimates of the last observation, m s-1
    cue_used: np.ndarray   # (E, nb) int64 scratch: block given in this round
    cue_given: np.ndarray  # (E, N) int64 scratch: agent given a block


def n_blocks(nz: int, nx: int) -> tuple[int, int]:
    """The aerial survey's blocks of an (nz, nx) field.

    Parameters
    ----------
    nz, nx : int
        Field cells along z (north) and x (east).

    Returns
    -------
    nbz, nbx : int
        Blocks of ``AERIAL_BLOCK_CELLS x AERIAL_BLOCK_CELLS`` cells along z and x (partial
        blocks at the far edges included); block ``b = jb nbx + ib`` holds the cells
        ``[jb B, (jb + 1) B) x [ib B, (ib + 1) B)`` (z, x; ``B = AERIAL_BLOCK_CELLS``).
    """
    b = AERIAL_BLOCK_CELLS
    return (nz + b - 1) // b, (nx + b - 1) // b


def aerial_steps(tier: dict) -> int:
    """The aerial survey's period in steps: ``aerial_period_s / dt_s`` (at least 1).

    Parameters
    ----------
    tier : dict
        Tier parameters plus ``dt_s``.

    Returns
    -------
    int
    """
    return max(1, int(round(float(tier["aerial_period_s"]) / float(tier["dt_s"]))))


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    The field is a copy of ``init["C0"]`` (never modified); the survey maps every
    ``aerial_period_s`` from one period on (:func:`brief` makes it every step for a method
    given the true target).

    Returns
    -------
    P : SPCParams
        The env's typed scalars.
    W : SPCWork
        The env's per-episode work arrays.

    Raises
    ------
    ConfigError
        Missing tier parameters.
    """
    need_tier(TASK_ID, tier, *_TIER_KEYS, "dt_s")
    C = np.ascontiguousarray(init["C0"], dtype=np.float64).copy()
    n_ep, _, nz, nx = C.shape
    n_ag = init["pos0"].shape[1]
    nbz, nbx = n_blocks(int(nz), int(nx))
    nb = nbz * nbx
    report = np.ascontiguousarray(init["report"], dtype=np.float64)
    P = SPCParams(float(tier["dt_s"]), episode_steps(tier), FIELD_H_M, SURFACE_Y_M,
                  float(tier["kappa_m2s"]), float(tier["removal_radius_m"]),
                  float(tier["removal_rate_s"]), float(tier["target_fraction"]),
                  FACE_REFRESH_STEPS, CUE_MASS_FRAC,
                  CUE_RING_FRAC * float(tier["spill_radius_m"]))
    W = SPCWork(np.ascontiguousarray(init["origin"], dtype=np.float64), report,
                np.ascontiguousarray(init["t0"], dtype=np.float64).copy(), C,
                np.ascontiguousarray(init["land"], dtype=np.uint8),
                np.zeros((n_ep, nz, nx + 1)), np.zeros((n_ep, nz + 1, nx)),
                np.zeros((n_ep, pol.work_size(1, nz, nx))),
                np.full((n_ep, 2), -1, dtype=np.int64),
                np.zeros((n_ep, nz * (nx + 1) + (nz + 1) * nx, 4)), np.zeros((n_ep, 1)),
                np.zeros((n_ep, 3)), np.full(n_ep, -1, np.int64),
                np.full(n_ep, aerial_steps(tier), np.int64), np.ones(n_ep, np.int64),
                np.full(n_ep, np.nan), np.zeros((n_ep, nb)), np.zeros((n_ep, nb)),
                np.zeros((n_ep, nb)), np.zeros(n_ep),
                np.repeat(report[:, None, :], n_ag, axis=1),
                np.ascontiguousarray(init["t0"], dtype=np.float64).copy(),
                np.zeros((n_ep, n_ag, 2)), np.zeros((n_ep, nb), np.int64),
                np.zeros((n_ep, n_ag), np.int64))
    return P, W


#: The briefing's own fields (after :data:`oneocean.tasks.public.COMMON`): name -> (shape,
#: unit, meaning).
BRIEF_FIELDS = {
    "report": ("(E, 2)", "m", "the spill report: the spill's initial mass centroid (x east, "
               "z north)"),
    "spill_radius": ("", "m", "the spill report: the spill's radius"),
    "depth": ("", "m", "the operating depth of the surface vehicles (y, positive down)"),
    "aerial_period_s": ("", "s", "the aerial survey's period (a map every this long; the step "
                        "for a method given the true target)"),
    "aerial_first_s": ("", "s", "time of the first map after the start (0: at the start)"),
    "field_origin": ("(E, 2)", "m", "world (x, z) of the centre of the surveyed area's cell "
                     "(0, 0)"),
    "field_h": ("", "m", "the survey's cell size"),
    "block_cells": ("", "", "survey block size, cells (per side)"),
    "map_nbx": ("", "", "survey blocks along x (east); block b = jb * map_nbx + ib covers "
                "cells [ib, ib + 1) * block_cells along x and [jb, jb + 1) * block_cells "
                "along z"),
    "map_nbz": ("", "", "survey blocks along z (north)"),
    "removal_radius": ("", "m", "each vehicle removes oil from the cells whose centre is "
                       "this close"),
    "removal_rate": ("", "s-1", "... the fraction removal_rate * dt of their concentration "
                     "every step"),
    "target_fraction": ("", "", "success: the removed fraction of the initial mass"),
}


SPCBriefing = briefing_class("SPC", BRIEF_FIELDS, __name__)


def brief(P: SPCParams, W: SPCWork, init: dict, m) -> SPCBriefing:
    """The briefing of every episode of a batch (:class:`oneocean.tasks.public.Mission`
    ``m``): the spill report, the survey's schedule and layout, the equipment, the target.

    A method given the true target (``m.sens.true_target``: the oracle) has the exact aerial
    map every step from step 0: set here in ``W.map_every`` / ``W.map_from``.

    Returns
    -------
    SPCBriefing
    """
    if m.sens.true_target != 0:
        W.map_every[:] = 1
        W.map_from[:] = 0
    every = int(W.map_every[0]) if W.map_every.shape[0] else 1
    first = -(-int(W.map_from[0]) // every) * every if W.map_from.shape[0] else 0
    nbz, nbx = n_blocks(W.C.shape[2], W.C.shape[3])
    return SPCBriefing(**common_brief(m), report=W.report.copy(),
                       spill_radius=float(m.tier["spill_radius_m"]), depth=P.y,
                       aerial_period_s=every * P.dt, aerial_first_s=first * P.dt,
                       field_origin=W.origin.copy(), field_h=P.h,
                       block_cells=AERIAL_BLOCK_CELLS, map_nbx=nbx, map_nbz=nbz,
                       removal_radius=P.rad, removal_rate=P.eff, target_fraction=P.target)


#: The team observation's fields (:class:`SPCTeamObs`): name -> (shape, unit, meaning).
TEAM_FIELDS = {
    "t_map": ("(E,)", "s", "the aerial map's time, since the product's time origin (as "
              "t0; the map's age is t0 + t_s - t_map); NaN before the first map"),
    "mass": ("(E, nb)", "kg", "each survey block's oil mass (nb = map_nbz * map_nbx)"),
    "x": ("(E, nb)", "m", "each block's oil mass centroid, x east (0: no oil)"),
    "z": ("(E, nb)", "m", "each block's oil mass centroid, z north (0: no oil)"),
    "total": ("(E,)", "kg", "the mapped oil mass"),
}


class SPCTeamObs(NamedTuple):
    """SPC's team observation: the aerial map (:data:`TEAM_FIELDS`), views of ``W``."""
    t_map: np.ndarray
    mass: np.ndarray
    x: np.ndarray
    z: np.ndarray
    total: np.ndarray


def team_obs(W: SPCWork) -> SPCTeamObs:
    """The team observation: the aerial map the ``sense`` hook keeps in ``W`` (views).

    Returns
    -------
    SPCTeamObs
    """
    return SPCTeamObs(W.tmap, W.bm, W.bx, W.bz, W.mtot)


#: The task's own observation fields: none (the aerial map is the team observation).
OBS_EXTRA_DOCS: dict = {}
OBS_EXTRA = ()
#: What the cue is (the observation's ``goal_d*`` fields).
CUE_DOC = ("the surface point of the oil the task's dispatcher gives the agent: before the first "
           "aerial map a ring around the spill report, then at every map the heaviest mapped "
           "blocks, each to the nearest agent without one; drifted since its time with the "
           "agent's current estimate")


@hot_kernel
def begin(ctx, e):
    """Record the initial mass and reset the accumulators, the map (none yet) and the cue
    (the ring around the spill report, at the start).

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``ctx.state`` holds the start.

    Returns
    -------
    bool
        True (success at step 0, the episode ends) when there is nothing to remove.
    """
    P, W = ctx.P, ctx.W
    m0 = pol.total_mass(W.C[e], P.h)
    W.acc[e, 0] = m0
    W.acc[e, 1] = 0.0
    W.acc[e, 2] = 0.0
    W.k_hit[e] = -1
    W.tmap[e] = math.nan
    W.mtot[e] = 0.0
    for b in range(W.bm.shape[1]):
        W.bm[e, b] = 0.0
        W.bx[e, b] = 0.0
        W.bz[e, b] = 0.0
    W.cue_t[e] = W.t0[e]
    n_ag = W.cue_xz.shape[1]
    for i in range(n_ag):   # a ring around the report, agent i at bearing 2 pi i / N
        a = 2.0 * math.pi * i / n_ag
        W.cue_xz[e, i, 0] = W.report[e, 0] + P.ring * math.sin(a)
        W.cue_xz[e, i, 1] = W.report[e, 1] + P.ring * math.cos(a)
        W.cest[e, i, 0] = 0.0
        W.cest[e, i, 1] = 0.0
    if 0.0 >= P.target * m0:   # nothing to remove: success at step 0, the episode ends
        W.k_hit[e] = 0
        return True
    return False


@hot_kernel
def pre_step(ctx, e, k):
    """Re-sample the face velocities every ``P.refresh`` steps.

    Env hook (:mod:`oneocean.tasks.loop`), before the agents act in step ``k``.
    """
    grid, P, W = ctx.grid, ctx.P, ctx.W
    t = ctx.t0[e] + k * ctx.dt
    if k % P.refresh == 0:
        _refresh_faces(grid, W.uf[e], W.vf[e], W.origin[e, 0], W.origin[e, 1], P.h, P.y,
                       W.fkey[e], W.fpart[e], t)


@hot_kernel
def aerial_map(C, x0, z0, h, bsz, bm, bx, bz):
    """The aerial survey of a field: block masses (kg) and mass centroids (m).

    Parameters
    ----------
    C : (1, nz, nx) float64
        The field, kg m-2.
    x0, z0 : float
        World (x, z) of cell (0, 0) centre, m.
    h : float
        Cell size, m.
    bsz : int
        Block size, cells.
    bm, bx, bz : (nb,) float64
        Written: each block's mass (kg) and mass centroid x, z (m; 0 for an empty block).

    Returns
    -------
    float
        The mapped mass, kg.
    """
    nz = C.shape[1]
    nx = C.shape[2]
    nbx = (nx + bsz - 1) // bsz
    nb = bm.shape[0]
    for b in range(nb):
        bm[b] = 0.0
        bx[b] = 0.0
        bz[b] = 0.0
    for j in range(nz):
        for i in range(nx):
            c = C[0, j, i]
            if c > 0.0:
                b = (j // bsz) * nbx + i // bsz
                bm[b] += c
                bx[b] += c * (x0 + i * h)
                bz[b] += c * (z0 + j * h)
    tot = 0.0
    for b in range(nb):
        if bm[b] > 0.0:
            bx[b] /= bm[b]
            bz[b] /= bm[b]
            tot += bm[b]
        bm[b] *= h * h
    return tot * h * h


@hot_kernel
def _cue_assign(X, bm, bx, bz, thr, used, given, cue_xz):
    """The cue's blocks: those of mass >= ``thr``, heaviest first (the lower index on a tie),
    each to the nearest agent (known positions ``X`` (N, STATE_DIM)) without one; once every
    such block has one, again from the heaviest. Writes ``cue_xz`` (N, 2)."""
    n_ag = X.shape[0]
    nb = bm.shape[0]
    for b in range(nb):
        used[b] = 0
    for i in range(n_ag):
        given[i] = 0
    for _ in range(n_ag):
        best = -1
        for _r in range(2):
            m_best = -1.0
            for b in range(nb):
                if used[b] == 0 and bm[b] >= thr and bm[b] > m_best:
                    m_best = bm[b]
                    best = b
            if best >= 0:
                break
            for b in range(nb):   # every block has one: the next round
                used[b] = 0
        ia = -1
        d_best = math.inf
        for i in range(n_ag):
            if given[i] == 0:
                d = (X[i, 0] - bx[best]) ** 2 + (X[i, 2] - bz[best]) ** 2
                if d < d_best:
                    d_best = d
                    ia = i
        used[best] = 1
        given[ia] = 1
        cue_xz[ia, 0] = bx[best]
        cue_xz[ia, 1] = bz[best]


@hot_kernel
def sense(ctx, e, k):
    """The aerial survey (the team observation) at its steps, and the cue's reference.

    Each agent's current estimate of its last observation (``O[e, i]`` still holds step
    ``k - 1``'s; 0 at step 0) is kept as its cue's drift. At a map step (``k >= W.map_from[e]``,
    ``k % W.map_every[e] == 0``) the field is surveyed into ``W.bm`` / ``W.bx`` / ``W.bz`` /
    ``W.mtot`` at the time ``W.tmap[e]``, and the cue points are assigned
    (:func:`_cue_assign`, blocks of at least ``P.cue_frac`` of the heaviest block's mass, on
    the known positions ``X``; unchanged when the map holds no oil). Env hook
    (:mod:`oneocean.tasks.loop`).
    """
    P, W, X, O = ctx.P, ctx.W, ctx.X, ctx.O
    n_ag = X.shape[1]
    for i in range(n_ag):
        ce = 0.0
        cn = 0.0
        if k > 0:
            ce = O[e, i, O_CE]
            cn = O[e, i, O_CN]
            if not (math.isfinite(ce) and math.isfinite(cn)):
                ce = 0.0
                cn = 0.0
        W.cest[e, i, 0] = ce
        W.cest[e, i, 1] = cn
    if k < W.map_from[e] or k % W.map_every[e] != 0:
        return
    bm = W.bm[e]
    bx = W.bx[e]
    bz = W.bz[e]
    W.mtot[e] = aerial_map(W.C[e], W.origin[e, 0], W.origin[e, 1], P.h, AERIAL_BLOCK_CELLS,
                           bm, bx, bz)
    t = W.t0[e] + k * P.dt
    W.tmap[e] = t
    heavy = 0.0
    for b in range(bm.shape[0]):
        if bm[b] > heavy:
            heavy = bm[b]
    if not heavy > 0.0:
        return
    W.cue_t[e] = t
    _cue_assign(X[e], bm, bx, bz, P.cue_frac * heavy, W.cue_used[e], W.cue_given[e],
                W.cue_xz[e])


@hot_kernel
def cue(ctx, e, k, i):
    """The task's oil reference at the operating depth, and the pollution probe.

    Env hook (:mod:`oneocean.tasks.loop`): agent ``i``'s cue point (its place on the ring
    around the spill report, then its block of the last aerial map: :func:`sense`) drifted
    since the cue's time with the agent's current estimate of its last observation.

    Returns
    -------
    gx, gy, gz : float
        The cue, world m.
    probe : float
        Surface concentration under the vehicle (its known position), kg m-2.
    """
    P, W, X = ctx.P, ctx.W, ctx.X
    s = X[e, i]
    age = W.t0[e] + k * P.dt - W.cue_t[e]
    return (W.cue_xz[e, i, 0] + W.cest[e, i, 0] * age, P.y,
            W.cue_xz[e, i, 1] + W.cest[e, i, 1] * age,
            pol.probe(W.C[e], 0, s[0], s[2], W.origin[e, 0], W.origin[e, 1], P.h))


@hot_kernel
def post_step(ctx, e, k):
    """Removal by every agent in agent order, then the field step; the success check.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``.

    Returns
    -------
    int
        ``REACHED`` once the removed mass reaches the target fraction (the episode runs on to
        the metric horizon), else ``GO``.
    """
    P, W, state = ctx.P, ctx.W, ctx.state
    S = state[e]
    Ce = W.C[e]
    x0 = W.origin[e, 0]
    z0 = W.origin[e, 1]
    a = W.acc[e]
    removed = a[1]
    for i in range(S.shape[0]):  # in agent order, after every agent moved
        removed += pol.remove_in_radius(Ce, S[i, 0], S[i, 2], P.rad, P.eff, P.dt, x0, z0, P.h)
    a[1] = removed
    a[2] += pol.step_field(Ce, pol.KIND_TRACER, W.fpar[e], W.uf[e], W.vf[e], W.land[e], P.h,
                           P.dt, P.kappa, pol.OPEN_ALL, W.work[e])
    if removed >= P.target * a[0]:
        if W.k_hit[e] < 0:
            W.k_hit[e] = k + 1
        return REACHED   # success; the episode runs on to the metric horizon
    return GO


@hot_kernel
def finish(ctx, e, k):
    """Write the fractions at the metric horizon (the end of the episode).

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Returns
    -------
    bool
        Success: the target was reached at some step (``W.k_hit``; removal only grows, so it
        still holds here).
    """
    P, W = ctx.P, ctx.W
    row = ctx.res[e]
    a = W.acc[e]
    m0 = a[0]
    success = W.k_hit[e] >= 0
    row[_C_CLEAN] = a[1] / m0
    row[_C_ESC] = a[2] / m0
    row[_C_REM] = pol.total_mass(W.C[e], P.h) / m0
    row[_C_TTT] = W.k_hit[e] * P.dt if success else P.n_steps * P.dt
    return success


fresh_cache(_candidates_kernel, __file__, pol.__file__)
