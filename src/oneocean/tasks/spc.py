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
Observation
    The goal cue is the point the agent steers to, ``W.aim`` (E, N, 2) (x, z) at
    ``SURFACE_Y_M``: written by the fused policy every step (its target drifted with the
    probed current); for external policies it stays at the spill's reported initial centroid.
    The pollution probe is the surface concentration under the vehicle, kg m-2.
Methods
    :mod:`oneocean.methods.heuristic.spc` (aerial map and greedy block assignment as the
    team-level ``plan``; both at full speed; heuristic: stale periodic map and the sensor
    models of :mod:`oneocean.sensing`; oracle: the exact map every step, true current and
    position).

Module layout: as :mod:`oneocean.tasks.g2g` (``reset``, split as ``reset_candidates`` /
``reset_build`` so that ``Cell.reset`` builds only the spills its current band keeps;
``SPCParams`` / ``SPCWork`` and ``make``: the per-episode field, land mask, face
velocities, mass accumulators and the policy's plan tokens and map scratch with a leading
episode axis; env hooks ``begin``, ``pre_step`` (face refresh), ``cue``, ``post_step``
(removal in agent order, field step, success reached), ``finish``; the map scratch is sized
by the policy (``make``'s ``tokens``); the compiled loop is :mod:`oneocean.kernels.spc`).
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
from .common import (PURPOSE_RESET, STANDARD, _SPAWN_BATCH, _call, _segment_clear,
                     _spawn_one_c, episode_steps, fresh_cache, need_tier, need_tokens,
                     path_clear, start_times)
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

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    tier : dict
        Tier parameters (``data/tasks/SPC.yaml``) plus ``dt_s``.
    n_agents : int
        Team size, 2..10.
    n_episodes : int
        Number of episodes E.
    seed : int
        Run seed (each episode draws from its own reset stream).

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
    from .common import _spawn_one

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

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    tier : dict
        Tier parameters (``data/tasks/SPC.yaml``) plus ``dt_s``.
    n_agents : int
        Team size, 2..10.
    n_episodes : int
        Number of candidates E (candidates ``0 .. E - 1``).
    seed : int
        Run seed (each episode draws from its own reset stream).

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


class SPCWork(NamedTuple):
    """SPC's per-episode work arrays.

    Attributes
    ----------
    origin : (E, 2) float64
        World (x, z) of cell (0, 0) centre, m.
    report : (E, 2) float64
        Reported initial spill centroid (x, z), m.
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
    aim : (E, N, 2) float64
        Goal cue: the point each agent steers to (x, z), m.
    tgt : (E, N, 2) float64
        Policy plan tokens (:mod:`oneocean.methods.heuristic.spc`): targets (x, z) at the map
        time, m.
    tmap : (E,) float64
        Map time, s.
    bm : (E, nb) float64
        Block masses, kg.
    bx, bz : (E, nb) float64
        Block mass centroids x and z, m.
    cnt : (E, nb) int64
        Agents per block.
    done : (E, N) int64
        Agent assigned.
    """
    origin: np.ndarray  # (E, 2) world (x, z) of cell (0, 0) centre, m
    report: np.ndarray  # (E, 2) reported initial spill centroid (x, z), m
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
    aim: np.ndarray     # (E, N, 2) goal cue: the point each agent steers to (x, z), m
    # the policy's plan tokens and map scratch (methods.heuristic.spc)
    tgt: np.ndarray     # (E, N, 2) targets (x, z) at the map time, m
    tmap: np.ndarray    # (E,) map time, s
    bm: np.ndarray      # (E, nb) block masses, kg
    bx: np.ndarray      # (E, nb) block mass centroids x, m
    bz: np.ndarray      # (E, nb) block mass centroids z, m
    cnt: np.ndarray     # (E, nb) int64 agents per block
    done: np.ndarray    # (E, N) int64 agent assigned


def make(grid, tier: dict, init: dict, tokens: dict | None = None):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    The field is a copy of ``init["C0"]`` (never modified); the goal cue starts at the
    reported spill centroid.

    Parameters
    ----------
    grid : Grid
        The rollout's grid export (the ablations' forcing included).
    tier : dict
        Tier parameters plus ``dt_s``.
    init : dict
        The reset's dict (:func:`reset`).
    tokens : dict
        The policy's plan tokens (``plan_tokens``); ``map_blocks``: blocks of the map scratch.

    Returns
    -------
    P : SPCParams
        The env's typed scalars.
    W : SPCWork
        The env's per-episode work arrays.

    Raises
    ------
    ConfigError
        Missing tier parameters or plan tokens.
    """
    need_tier(TASK_ID, tier, *_TIER_KEYS, "dt_s")
    tokens = need_tokens(TASK_ID, tokens, "map_blocks")
    C = np.ascontiguousarray(init["C0"], dtype=np.float64).copy()
    n_ep, _, nz, nx = C.shape
    n_ag = init["pos0"].shape[1]
    nb = int(tokens["map_blocks"])
    report = np.ascontiguousarray(init["report"], dtype=np.float64)
    P = SPCParams(float(tier["dt_s"]), episode_steps(tier), FIELD_H_M, SURFACE_Y_M,
                  float(tier["kappa_m2s"]), float(tier["removal_radius_m"]),
                  float(tier["removal_rate_s"]), float(tier["target_fraction"]),
                  FACE_REFRESH_STEPS)
    W = SPCWork(np.ascontiguousarray(init["origin"], dtype=np.float64), report, C,
                np.ascontiguousarray(init["land"], dtype=np.uint8),
                np.zeros((n_ep, nz, nx + 1)), np.zeros((n_ep, nz + 1, nx)),
                np.zeros((n_ep, pol.work_size(1, nz, nx))),
                np.full((n_ep, 2), -1, dtype=np.int64),
                np.zeros((n_ep, nz * (nx + 1) + (nz + 1) * nx, 4)), np.zeros((n_ep, 1)),
                np.zeros((n_ep, 3)), np.full(n_ep, -1, np.int64),
                np.repeat(report[:, None, :], n_ag, axis=1),
                np.zeros((n_ep, n_ag, 2)), np.zeros(n_ep), np.zeros((n_ep, nb)),
                np.zeros((n_ep, nb)), np.zeros((n_ep, nb)), np.zeros((n_ep, nb), np.int64),
                np.zeros((n_ep, n_ag), np.int64))
    return P, W


@hot_kernel(inline="always")
def begin(grid, P, W, state, e):
    """Record the initial mass and reset the accumulators.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``state`` holds the start.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : SPCParams
        The task's params (:func:`make`).
    W : SPCWork
        The task's per-episode work arrays (:func:`make`).
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    e : int
        Episode index.

    Returns
    -------
    bool
        True (success at step 0, the episode ends) when there is nothing to remove.
    """
    m0 = pol.total_mass(W.C[e], P.h)
    W.acc[e, 0] = m0
    W.acc[e, 1] = 0.0
    W.acc[e, 2] = 0.0
    W.k_hit[e] = -1
    if 0.0 >= P.target * m0:   # nothing to remove: success at step 0, the episode ends
        W.k_hit[e] = 0
        return True
    return False


@hot_kernel(inline="always")
def pre_step(grid, P, W, state, e, k, t):
    """Re-sample the face velocities every ``P.refresh`` steps.

    Env hook (:mod:`oneocean.tasks.loop`), before the agents act in step ``k``.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : SPCParams
        The task's params (:func:`make`).
    W : SPCWork
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
    if k % P.refresh == 0:
        _refresh_faces(grid, W.uf[e], W.vf[e], W.origin[e, 0], W.origin[e, 1], P.h, P.y,
                       W.fkey[e], W.fpart[e], t)


@hot_kernel(inline="always")
def cue(grid, P, W, state, e, k, i):
    """The goal cue ``W.aim`` at the operating depth, and the pollution probe.

    Env hook (:mod:`oneocean.tasks.loop`): the observation's goal cue and probe.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : SPCParams
        The task's params (:func:`make`).
    W : SPCWork
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
        Surface concentration under the vehicle (its known position), kg m-2.
    """
    s = state[e, i]
    # surface concentration under the vehicle, kg m-2
    return (W.aim[e, i, 0], P.y, W.aim[e, i, 1],
            pol.probe(W.C[e], 0, s[0], s[2], W.origin[e, 0], W.origin[e, 1], P.h))


@hot_kernel(inline="always")
def post_step(grid, P, W, state, prev, e, k, t):
    """Removal by every agent in agent order, then the field step; the success check.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : SPCParams
        The task's params (:func:`make`).
    W : SPCWork
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
    int
        ``REACHED`` once the removed mass reaches the target fraction (the episode runs on to
        the metric horizon), else ``GO``.
    """
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


@hot_kernel(inline="always")
def finish(grid, P, W, state, e, k, row):
    """Write the fractions at the metric horizon (the end of the episode).

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : SPCParams
        The task's params (:func:`make`).
    W : SPCWork
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
        Success: the target was reached at some step (``W.k_hit``; removal only grows, so it
        still holds here).
    """
    a = W.acc[e]
    m0 = a[0]
    success = W.k_hit[e] >= 0
    row[_C_CLEAN] = a[1] / m0
    row[_C_ESC] = a[2] / m0
    row[_C_REM] = pol.total_mass(W.C[e], P.h) / m0
    row[_C_TTT] = W.k_hit[e] * P.dt if success else P.n_steps * P.dt
    return success


fresh_cache(_candidates_kernel, __file__, pol.__file__)
