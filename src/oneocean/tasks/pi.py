"""PI — pipeline inspection and leak detection (1-10 agents; Table V uses N = 1, our default).

Objective
    A pipeline lies on the seafloor of the shelf: a polyline of ``pipeline_length_m`` made of
    legs of about ``LEG_M`` with turns of at most ``MAX_TURN_DEG``, every point of which (and
    a ``CORRIDOR_CHECK_M`` band on either side) is water with seafloor depth in
    ``[seafloor_min_m, seafloor_max_m]``. ``n_leaks`` leaks sit on it (arc length in
    ``[LEAK_ARC_FRAC, 1 - LEAK_ARC_FRAC] * length``, at least ``leak_spacing_m`` apart), each
    emitting ``U(0.5, 1) * leak_rate_kg_s`` of a dissolved tracer. Agent ``i`` of N starts near
    the start of its section (the i-th of N equal arc-length sections), ``SPAWN_ALTITUDE_M``
    above the seafloor; it must inspect its section and localise the leaks.
Plume physics (the environment; identical for every method)
    The tracer lives in a near-bottom layer: a 2-D column-mass field (kg m-2) on a local grid
    of ``FIELD_H_M`` cells aligned with the pipeline's chord and ``FIELD_MARGIN_M`` wider than
    the pipeline on every side (:mod:`oneocean.models.pollution`: conservative
    advection-diffusion, ``KAPPA_M2_S``, open boundaries: plume mass leaves the corridor).
    It is advected by the product's currents sampled ``NEAR_BOTTOM_M`` above the seafloor at
    the field's face centres, refreshed every ``FIELD_REFRESH_S`` (time-varying currents and
    tides), stepped every ``FIELD_EVERY`` agent steps; the leaks emit into it from
    ``SPINUP_S`` before the episode starts (the plumes are developed when the survey begins).
    The sensor reads the concentration at the vehicle: ``C(x, z) exp(-a / PLUME_SCALE_M) /
    PLUME_SCALE_M`` (kg m-3) at altitude ``a`` (an exponential vertical profile holding the
    column mass ``C``), so flying high weakens the signal.
Detection and scoring
    Readings are taken after every step. A reading at or above ``detect_threshold_kg_m3``
    within ``DETECT_RADIUS_M`` of a leak *detects* it (the evaluator attributes every reading
    to the nearest leak within that radius) and is logged for that leak with its
    *downstream coordinate* (the distance from the leak's first logged reading along the
    current the agent sensed at its step; 0 below ``MIN_CURRENT_MS``). The agent reports a
    position *estimate* for the leak from its readings logged near it (method-specific,
    below); the leak is *localised* if the estimate lies within ``loc_tolerance_m`` (the
    field resolves ``FIELD_H_M``; the oracle's estimator stays within ~10 m on the default
    region, the heuristic's peak within ~35 m). The inspection report is final when every
    agent has finished its section, or at the time limit.
Success
    Every leak localised (team) when the report is final; ``T_s`` is then the time at which
    the last agent finished its section (the time limit on failure).
Metrics
    ``inspection_score`` (primary: localised / total leaks), ``localisation_error_m`` (mean
    over detected leaks of the estimate's distance to the leak, m; NaN if none was detected),
    ``detection_rate`` (detected / total).
Methods
    :mod:`oneocean.methods.heuristic.pi` (both follow their section's polyline low over the
    seafloor; heuristic: ``ALT_HEURISTIC_M``, cruise budget, noisy probe, reports the plume's
    peak; oracle: ``ALT_ORACLE_M``, full speed, exact current, reports the plume's upstream
    edge). The survey waypoints are the method's plan (``survey``, stored in the work arrays);
    the leak estimate is the method's report (``estimate``), computed when the episode ends
    from the readings the env logged near each leak, and scored here.

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset``; ``PIParams`` / ``PIWork`` and ``make``; the env hooks
    ``begin`` (plume spin-up), ``pre_step`` (the field's emit and transport), ``cue`` (the
    agent's carrot and the reading before the move), ``after_agent`` (the reading after the
    move: detection and the per-leak reading log), ``post_step`` (the report is final when
    every agent has finished its section), ``finish`` (the method's estimates, scored);
    ``POLICY``; ``_kernel`` and ``_observe_kernel``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..engine._jit import hot_kernel
from ..engine.constraints import DEFAULT_LAND_THRESHOLD, spawn_positions
from ..engine.grid import sample_elevation, sample_elevation_points
from ..errors import ConfigError
from ..methods.heuristic import pi as POLICY
from ..models import pollution as pol
from .common import (STANDARD, current_at, episode_generators, fresh_cache, need_tier,
                     start_times)
from .loop import observe_next, run_episode

TASK_ID = "PI"
METRICS = ("inspection_score", "localisation_error_m", "detection_rate")
COLUMNS = STANDARD + METRICS

# ---- geometry
#: Nominal leg length of the pipeline polyline, m, and the largest turn between legs, deg.
LEG_M = 400.0
MAX_TURN_DEG = 20.0
#: Band on either side of the pipeline that must be water in the depth range, m.
CORRIDOR_CHECK_M = 40.0
#: Spacing of the geometry checks along the pipeline, m.
CHECK_SPACING_M = 10.0
#: Leaks lie in this fraction-of-length window: [f, 1 - f] of the arc length.
LEAK_ARC_FRAC = 0.08
#: Spawn box side around a section start, m, and altitude range, m (section starts are
#: length / N >= 80 m apart, so agents start well separated).
SPAWN_BOX_M = 20.0
SPAWN_ALTITUDE_M = (5.0, 15.0)
# ---- plume physics
#: Plume field cell size, m; its margin around the pipeline, m; diffusivity, m2 s-1.
FIELD_H_M = 20.0
FIELD_MARGIN_M = 80.0
KAPPA_M2_S = 1.0
#: The field is stepped every FIELD_EVERY agent steps; face currents refreshed every
#: FIELD_REFRESH_S; leaks emit from SPINUP_S before the start.
FIELD_EVERY = 3
FIELD_REFRESH_S = 60.0
SPINUP_S = 600.0
#: Height above the seafloor where the plume's currents are sampled, m.
NEAR_BOTTOM_M = 2.0
#: Vertical scale of the near-bottom plume layer, m.
PLUME_SCALE_M = 5.0
# ---- scoring
#: A reading above the threshold is attributed to the nearest leak within this distance, m.
DETECT_RADIUS_M = 50.0
#: Below this sensed current speed (m s-1) a reading's downstream coordinate is 0 (the
#: direction is undefined).
MIN_CURRENT_MS = 0.05
#: Readings kept per leak (later ones are dropped; 1024 s of readings inside the 100 m zone).
MAX_READS = 1024
#: Seafloor clearance of the feasibility check, m; near-collision distance, m.
CLEARANCE_M = 1.0
R_COLL_M = 2.0

_TIER_KEYS = ("current_gain", "time_limit_s", "probe_noise_ms", "pipeline_length_m",
              "n_leaks", "leak_spacing_m", "leak_rate_kg_s", "detect_threshold_kg_m3",
              "loc_tolerance_m", "seafloor_min_m", "seafloor_max_m")

_C_SCORE, _C_LOC, _C_DET = (len(STANDARD) + i for i in range(len(METRICS)))


# ------------------------------------------------------------------------------ geometry

def _densify(poly: np.ndarray, spacing: float) -> np.ndarray:
    """Points (k, 2) every <= ``spacing`` m along the polyline (n, 2)."""
    out = [poly[:1]]
    for a, b in zip(poly[:-1], poly[1:]):
        n = max(1, int(math.ceil(float(np.hypot(*(b - a))) / spacing)))
        w = np.linspace(0.0, 1.0, n + 1)[1:, None]
        out.append(a + w * (b - a))
    return np.concatenate(out)


def _corridor_ok(grid, poly: np.ndarray, tier) -> bool:
    """The pipeline and a CORRIDOR_CHECK_M band either side: inside the grid, off land, with
    seafloor depth in [seafloor_min_m, seafloor_max_m]."""
    pts = _densify(poly, CHECK_SPACING_M)
    d = np.diff(pts, axis=0)
    d = np.vstack([d, d[-1:]])
    nrm = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.maximum(np.hypot(d[:, 0], d[:, 1]),
                                                             1e-9)[:, None]
    allp = np.concatenate([pts, pts + CORRIDOR_CHECK_M * nrm, pts - CORRIDOR_CHECK_M * nrm])
    x, z = allp[:, 0], allp[:, 1]
    if (x.min() < grid.x0 or x.max() > grid.x_max or z.min() < grid.z0
            or z.max() > grid.z_max):
        return False
    depth = -sample_elevation_points(grid, np.ascontiguousarray(allp), np.empty(allp.shape[0]))
    if depth.min() < float(tier["seafloor_min_m"]) or depth.max() > float(tier["seafloor_max_m"]):
        return False
    j = np.clip(((z - grid.z0) * grid.inv_dz).astype(np.int64), 0, grid.ny - 2)
    i = np.clip(((x - grid.x0) * grid.inv_dx).astype(np.int64), 0, grid.nx - 2)
    land = np.maximum.reduce([grid.land[j, i], grid.land[j + 1, i], grid.land[j, i + 1],
                              grid.land[j + 1, i + 1]])
    return not np.any(land > 0.0)


def sample_pipeline(grid, rng, tier, tries: int = 3000, what: str = "pipeline") -> np.ndarray:
    """A random pipeline polyline (n_vertices, 2) [x, z] m on the shelf (see module doc).

    Raises
    ------
    ConfigError
        No valid pipeline in ``tries`` attempts (never a silent fallback).
    """
    L = float(tier["pipeline_length_m"])
    n_legs = max(1, int(round(L / LEG_M)))
    leg = L / n_legs
    depth = -grid.elevation.astype(np.float64)
    ok = ((depth >= float(tier["seafloor_min_m"])) & (depth <= float(tier["seafloor_max_m"]))
          & (grid.land == 0.0))
    jj, ii = np.nonzero(ok)
    turn = math.radians(MAX_TURN_DEG)
    if jj.size:
        for _ in range(int(tries)):
            k = rng.integers(jj.size)
            p = np.array([grid.x0 + ii[k] * grid.dx, grid.z0 + jj[k] * grid.dz])
            p += rng.uniform(-0.5, 0.5, 2) * (grid.dx, grid.dz)
            hdg = rng.uniform(-math.pi, math.pi)
            poly = [p]
            for j in range(n_legs):
                if j > 0:
                    hdg += rng.uniform(-turn, turn)
                poly.append(poly[-1] + leg * np.array([math.sin(hdg), math.cos(hdg)]))
            poly = np.array(poly)
            if _corridor_ok(grid, poly, tier):
                return poly
    raise ConfigError(
        f"{what}: no {L:g} m pipeline with seafloor depth in [{tier['seafloor_min_m']:g}, "
        f"{tier['seafloor_max_m']:g}] m found in {tries} tries; the grid has no such shelf")


def _arc(poly: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poly, axis=0).T))])


def point_at(poly: np.ndarray, s: float) -> np.ndarray:
    """Point (2,) at arc length ``s`` m along the polyline."""
    arc = _arc(poly)
    k = int(np.clip(np.searchsorted(arc, s, side="right") - 1, 0, len(poly) - 2))
    w = (s - arc[k]) / max(arc[k + 1] - arc[k], 1e-12)
    return poly[k] + w * (poly[k + 1] - poly[k])


def sub_polyline(poly: np.ndarray, s0: float, s1: float) -> np.ndarray:
    """The part of the polyline between arc lengths ``s0 < s1`` (vertices included)."""
    arc = _arc(poly)
    inner = [poly[k] for k in range(len(poly)) if s0 < arc[k] < s1]
    return np.array([point_at(poly, s0), *inner, point_at(poly, s1)])


def sample_leaks(rng, poly: np.ndarray, tier, tries: int = 1000, what: str = "leaks"):
    """Leak arc lengths (n,) sorted, at least ``leak_spacing_m`` apart (rejection sampling)."""
    n = int(tier["n_leaks"])
    L = _arc(poly)[-1]
    lo, hi = LEAK_ARC_FRAC * L, (1.0 - LEAK_ARC_FRAC) * L
    sp = float(tier["leak_spacing_m"])
    for _ in range(int(tries)):
        s = np.sort(rng.uniform(lo, hi, n))
        if n < 2 or np.diff(s).min() >= sp:
            return s
    raise ConfigError(f"{what}: cannot place {n} leaks {sp:g} m apart on a {L:g} m pipeline")


def field_frame(poly: np.ndarray, h: float, margin: float):
    """Local plume-field frame along the pipeline's chord.

    Returns
    -------
    origin : (2,) world [x, z] of the local origin (the first vertex), m
    axes : (2,) [cos theta, sin theta] of the local x axis (the chord), world frame
    s0, n0 : local coordinates of the centre of cell (0, 0), m
    nx, nz : int, cells needed along / across the chord
    """
    o = poly[0]
    d = poly[-1] - o
    th = math.atan2(d[1], d[0])
    c, s = math.cos(th), math.sin(th)
    loc = np.stack([(poly[:, 0] - o[0]) * c + (poly[:, 1] - o[1]) * s,
                    -(poly[:, 0] - o[0]) * s + (poly[:, 1] - o[1]) * c], axis=1)
    s_lo, n_lo = loc.min(0) - margin
    s_hi, n_hi = loc.max(0) + margin
    nx = int(math.ceil((s_hi - s_lo) / h))
    nz = int(math.ceil((n_hi - n_lo) / h))
    return o, np.array([c, s]), s_lo + 0.5 * h, n_lo + 0.5 * h, nx, nz


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the pipeline, leaks, start positions and start time of every episode.

    Returns
    -------
    dict
        ``poly`` (E, V, 2) pipeline vertices [x, z] m (V = legs + 1); ``leaks`` (E, n_leaks, 2)
        [x, z] m; ``leak_rate`` (E, n_leaks) kg s-1; ``sections`` (E, N, 2) arc-length
        range of each agent's section, m; ``pos0`` (E, N, 3) m; ``psi0`` (E, N) initial
        heading (0: north), rad; ``t0`` (E,) s.

    Raises
    ------
    ConfigError
        Team size outside [1, 10], missing tier keys, or no valid geometry for some episode.
    """
    n_agents = int(n_agents)
    if not 1 <= n_agents <= 10:
        raise ConfigError(f"task {TASK_ID}: n_agents must be in [1, 10], got {n_agents}")
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    n_leaks = int(tier["n_leaks"])
    if n_leaks < 1:
        raise ConfigError(f"task {TASK_ID}: n_leaks must be >= 1, got {n_leaks}")
    rngs = episode_generators(seed, n_episodes)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    polys, leaks, rates, sections, pos0 = [], [], [], [], []
    for e, rng in enumerate(rngs):
        what = f"task {TASK_ID} reset (episode {e})"
        poly = sample_pipeline(grid, rng, tier, what=what)
        s_leak = sample_leaks(rng, poly, tier, what=what)
        L = _arc(poly)[-1]
        cuts = np.linspace(0.0, L, n_agents + 1)
        p0 = np.empty((n_agents, 3))
        for i in range(n_agents):
            c = point_at(poly, cuts[i])
            box = {"x": (c[0] - 0.5 * SPAWN_BOX_M, c[0] + 0.5 * SPAWN_BOX_M),
                   "z": (c[1] - 0.5 * SPAWN_BOX_M, c[1] + 0.5 * SPAWN_BOX_M),
                   "altitude": SPAWN_ALTITUDE_M}
            p0[i] = spawn_positions(grid, rng, 1, box, clearance=CLEARANCE_M)[0]
        polys.append(poly)
        leaks.append(np.array([point_at(poly, s) for s in s_leak]))
        rates.append(float(tier["leak_rate_kg_s"]) * rng.uniform(0.5, 1.0, n_leaks))
        sections.append(np.stack([cuts[:-1], cuts[1:]], axis=1))
        pos0.append(p0)
    return {"poly": np.array(polys), "leaks": np.array(leaks), "leak_rate": np.array(rates),
            "sections": np.array(sections), "pos0": np.array(pos0),
            "psi0": np.zeros((n_episodes, n_agents)), "t0": t0}


# ------------------------------------------------------------------------------ kernels

@hot_kernel(inline="always")
def _to_local(x, z, ox, oz, ca, sa):
    dx = x - ox
    dz = z - oz
    return dx * ca + dz * sa, -dx * sa + dz * ca


@hot_kernel
def _refresh_faces(grid, frame, uf, vf, e, nx, nz, h, t):
    """Sample the near-bottom current at every face of episode ``e``'s field, in local axes."""
    ox = frame[e, 0]
    oz = frame[e, 1]
    ca = frame[e, 2]
    sa = frame[e, 3]
    s0 = frame[e, 4]
    n0 = frame[e, 5]
    for j in range(nz):
        for f in range(nx + 1):
            s = s0 + (f - 0.5) * h
            n = n0 + j * h
            x = ox + s * ca - n * sa
            z = oz + s * sa + n * ca
            y = -sample_elevation(grid, x, z) - NEAR_BOTTOM_M
            if y < 0.5:
                y = 0.5
            ce, cn = current_at(grid, x, y, z, t)
            uf[e, j, f] = ce * ca + cn * sa
    for f in range(nz + 1):
        for i in range(nx):
            s = s0 + i * h
            n = n0 + (f - 0.5) * h
            x = ox + s * ca - n * sa
            z = oz + s * sa + n * ca
            y = -sample_elevation(grid, x, z) - NEAR_BOTTOM_M
            if y < 0.5:
                y = 0.5
            ce, cn = current_at(grid, x, y, z, t)
            vf[e, f, i] = -ce * sa + cn * ca


@hot_kernel
def _field_step(C, params, uf, vf, land, work, leak_loc, rate, e, n_leak, h, s0, n0, dt,
                kappa):
    """Emit every leak for ``dt`` then transport the field of episode ``e``."""
    for q in range(n_leak):
        pol.emit(C[e], 0, leak_loc[e, q, 0], leak_loc[e, q, 1], rate[e, q], dt, s0, n0, h)
    pol.step_field(C[e], pol.KIND_TRACER, params, uf[e], vf[e], land[e], h, dt, kappa,
                   pol.OPEN_ALL, work[e])



def _field_land(grid, frame_e, nx, nz, h) -> np.ndarray:
    """Land flags (nz, nx) uint8 of one episode's field cells: 1 where the bilinear land mask
    at the cell centre is >= the land threshold, or outside the grid."""
    ox, oz, ca, sa, s0, n0 = frame_e
    S, N = np.meshgrid(s0 + h * np.arange(nx), n0 + h * np.arange(nz))
    X = ox + S * ca - N * sa
    Z = oz + S * sa + N * ca
    inside = (X >= grid.x0) & (X <= grid.x_max) & (Z >= grid.z0) & (Z <= grid.z_max)
    fx = np.clip((X - grid.x0) * grid.inv_dx, 0.0, grid.nx - 1.0)
    fz = np.clip((Z - grid.z0) * grid.inv_dz, 0.0, grid.ny - 1.0)
    i = np.minimum(fx.astype(np.int64), grid.nx - 2)
    j = np.minimum(fz.astype(np.int64), grid.ny - 2)
    wx, wz = fx - i, fz - j
    lm = grid.land
    land = ((1 - wz) * ((1 - wx) * lm[j, i] + wx * lm[j, i + 1])
            + wz * ((1 - wx) * lm[j + 1, i] + wx * lm[j + 1, i + 1]))
    return ((~inside) | (land >= DEFAULT_LAND_THRESHOLD)).astype(np.uint8)


class PIParams(NamedTuple):
    n_leak: int             # leaks per episode
    n_spin: int             # spin-up field steps before the start
    refresh: int            # face currents refreshed every this many field steps
    dt: float               # agent step, s (the field steps FIELD_EVERY dt)
    thr: float              # detection threshold, kg m-3
    tol: float              # localisation tolerance, m
    h: float                # field cell size, m
    kappa: float            # diffusivity, m2 s-1
    tracer: np.ndarray      # (n_params,) the field's step_field params (tracer, no decay)


class PIWork(NamedTuple):
    # ---- env: the episode, the plume field, the reading log, the report
    t0: np.ndarray          # (E,) start times, s (the spin-up ends there)
    leaks: np.ndarray       # (E, n_leaks, 2) leak positions [x, z], m
    leak_loc: np.ndarray    # (E, n_leaks, 2) the same in the field's local frame, m
    rate: np.ndarray        # (E, n_leaks) emission rates, kg s-1
    frame: np.ndarray       # (E, 6) field frame: origin x, z, cos, sin, cell (0, 0) s, n
    C: np.ndarray           # (E, 1, nz, nx) column mass, kg m-2
    uf: np.ndarray          # (E, nz, nx + 1) face currents along the chord, m s-1
    vf: np.ndarray          # (E, nz + 1, nx) face currents across the chord, m s-1
    land: np.ndarray        # (E, nz, nx) uint8 land / outside flags of the field's cells
    work: np.ndarray        # (E, work_size) step_field scratch
    peak: np.ndarray        # (E, n_leaks) largest reading >= threshold near a leak (-1: none)
    nread: np.ndarray       # (E, n_leaks) int64 readings logged near a leak
    reads: np.ndarray       # (E, n_leaks, MAX_READS, 4) [x, z, value, downstream coordinate]
    org: np.ndarray         # (E, n_leaks, 2) first reading near a leak (downstream origin), m
    est: np.ndarray         # (E, n_leaks, 2) the method's final estimates, m (NaN: none)
    # ---- policy (plan tokens and memory; see oneocean.methods.heuristic.pi)
    wps: np.ndarray         # (E, N, V, 2) survey waypoints [x, z], m
    wcount: np.ndarray      # (E, N) int64 waypoints of each agent
    widx: np.ndarray        # (E, N) int64 waypoint being followed
    tgt: np.ndarray         # (E, N, 3) the step's carrot (the observation's goal cue), m
    flow: np.ndarray        # (E, N, 2) current the agent sensed at its step, m s-1
    done: np.ndarray        # (E, N) int64 1: the agent has finished its section
    estimator: np.ndarray   # (E,) int64 the report the method files (its PEAK / ONSET)


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`); the
    survey waypoints are the method's plan (:func:`oneocean.methods.heuristic.pi.survey`)."""
    need_tier(TASK_ID, tier, *_TIER_KEYS, "dt_s")
    dt = float(tier["dt_s"])
    poly = np.asarray(init["poly"], dtype=np.float64)
    n_ep = poly.shape[0]
    n_ag = init["pos0"].shape[1]
    leaks = np.ascontiguousarray(init["leaks"], dtype=np.float64)
    n_leak = leaks.shape[1]
    h = FIELD_H_M
    # per-episode field frames (same shape for every episode: the largest one)
    frames = [field_frame(poly[e], h, FIELD_MARGIN_M) for e in range(n_ep)]
    nx = max(f[4] for f in frames)
    nz = max(f[5] for f in frames)
    frame = np.empty((n_ep, 6))
    leak_loc = np.empty((n_ep, n_leak, 2))
    land = np.empty((n_ep, nz, nx), dtype=np.uint8)
    for e, (o, ax_, s0, n0, fx, fz) in enumerate(frames):
        # centre the episode's extent inside the common shape
        s0 -= 0.5 * (nx - fx) * h
        n0 -= 0.5 * (nz - fz) * h
        frame[e] = (o[0], o[1], ax_[0], ax_[1], s0, n0)
        dx = leaks[e, :, 0] - o[0]
        dz = leaks[e, :, 1] - o[1]
        leak_loc[e, :, 0] = dx * ax_[0] + dz * ax_[1]
        leak_loc[e, :, 1] = -dx * ax_[1] + dz * ax_[0]
        land[e] = _field_land(grid, frame[e], nx, nz, h)
    wps, wcount = POLICY.survey(init)
    dtf = FIELD_EVERY * dt
    _, tracer = pol.field_params(pol.KIND_TRACER, 1)
    P = PIParams(n_leak, int(round(SPINUP_S / dtf)), max(1, int(round(FIELD_REFRESH_S / dtf))),
                 dt, float(tier["detect_threshold_kg_m3"]), float(tier["loc_tolerance_m"]), h,
                 KAPPA_M2_S, tracer)
    W = PIWork(np.ascontiguousarray(init["t0"], dtype=np.float64), leaks, leak_loc,
               np.ascontiguousarray(init["leak_rate"], dtype=np.float64), frame,
               np.zeros((n_ep, 1, nz, nx)), np.zeros((n_ep, nz, nx + 1)),
               np.zeros((n_ep, nz + 1, nx)), land, np.zeros((n_ep, pol.work_size(1, nz, nx))),
               np.zeros((n_ep, n_leak)), np.zeros((n_ep, n_leak), dtype=np.int64),
               np.zeros((n_ep, n_leak, MAX_READS, 4)), np.zeros((n_ep, n_leak, 2)),
               np.zeros((n_ep, n_leak, 2)),
               wps, wcount, np.zeros((n_ep, n_ag), dtype=np.int64), np.zeros((n_ep, n_ag, 3)),
               np.zeros((n_ep, n_ag, 2)), np.zeros((n_ep, n_ag), dtype=np.int64),
               np.zeros(n_ep, dtype=np.int64))
    return P, W


@hot_kernel(inline="always")
def begin(grid, P, W, state, e):
    """Spin-up (the leaks have been emitting for ``n_spin`` field steps); empty logs."""
    C = W.C
    nz = C.shape[2]
    nx = C.shape[3]
    n_spin = P.n_spin
    h = P.h
    dtf = FIELD_EVERY * P.dt
    s0 = W.frame[e, 4]
    n0 = W.frame[e, 5]
    for j in range(nz):
        for i in range(nx):
            C[e, 0, j, i] = 0.0
    for k in range(n_spin):
        t = W.t0[e] - (n_spin - k) * dtf
        if k % P.refresh == 0:
            _refresh_faces(grid, W.frame, W.uf, W.vf, e, nx, nz, h, t)
        _field_step(C, P.tracer, W.uf, W.vf, W.land, W.work, W.leak_loc, W.rate, e, P.n_leak,
                    h, s0, n0, dtf, P.kappa)
    for q in range(P.n_leak):
        W.peak[e, q] = -1.0
        W.nread[e, q] = 0
        W.est[e, q, 0] = math.nan
        W.est[e, q, 1] = math.nan
    return False


@hot_kernel(inline="always")
def pre_step(grid, P, W, state, e, k, t):
    """The field: emit and transport every FIELD_EVERY steps (faces refreshed on schedule)."""
    if k % FIELD_EVERY == 0:
        C = W.C
        nz = C.shape[2]
        nx = C.shape[3]
        h = P.h
        if (k // FIELD_EVERY) % P.refresh == 0:
            _refresh_faces(grid, W.frame, W.uf, W.vf, e, nx, nz, h, t)
        _field_step(C, P.tracer, W.uf, W.vf, W.land, W.work, W.leak_loc, W.rate, e, P.n_leak,
                    h, W.frame[e, 4], W.frame[e, 5], FIELD_EVERY * P.dt, P.kappa)


@hot_kernel(inline="always")
def _reading(grid, P, W, e, x, z, alt):
    """The sensor's concentration (kg m-3) at ``(x, z)``, ``alt`` m above the seafloor."""
    inv_scale = 1.0 / PLUME_SCALE_M
    ls, ln = _to_local(x, z, W.frame[e, 0], W.frame[e, 1], W.frame[e, 2], W.frame[e, 3])
    return (pol.probe(W.C[e], 0, ls, ln, W.frame[e, 4], W.frame[e, 5], P.h)
            * math.exp(-alt * inv_scale) * inv_scale)


@hot_kernel(inline="always")
def cue(grid, P, W, state, e, k, i):
    """Goal cue: the agent's carrot (plan token ``tgt``); probe: the reading before the move."""
    s = state[e, i]
    px = s[0]
    py = s[1]
    pz = s[2]
    a0 = max(-sample_elevation(grid, px, pz) - py, 0.0)
    r0 = _reading(grid, P, W, e, px, pz, a0)
    return W.tgt[e, i, 0], W.tgt[e, i, 1], W.tgt[e, i, 2], r0


@hot_kernel(inline="always")
def after_agent(grid, P, W, state, e, k, i, code):
    """The reading after the move: attributed to the nearest leak within DETECT_RADIUS_M
    (detection when >= the threshold), logged with its downstream coordinate along the
    current the agent sensed (``flow``)."""
    s = state[e, i]
    alt = -sample_elevation(grid, s[0], s[2]) - s[1]
    if alt < 0.0:
        alt = 0.0
    r = _reading(grid, P, W, e, s[0], s[2], alt)
    leaks = W.leaks
    peak = W.peak
    org = W.org
    reads = W.reads
    q_min = -1
    d_min = DETECT_RADIUS_M * DETECT_RADIUS_M
    for q in range(P.n_leak):
        d2 = (leaks[e, q, 0] - s[0]) ** 2 + (leaks[e, q, 1] - s[2]) ** 2
        if d2 <= d_min:
            d_min = d2
            q_min = q
    if q_min >= 0:
        if r >= P.thr and r > peak[e, q_min]:
            peak[e, q_min] = r
        m = W.nread[e, q_min]
        if m == 0:  # origin of the downstream coordinate near this leak
            org[e, q_min, 0] = s[0]
            org[e, q_min, 1] = s[2]
        if m < reads.shape[2]:
            # downstream coordinate along the agent's current knowledge (the oracle's
            # estimator uses it)
            fe = W.flow[e, i, 0]
            fn = W.flow[e, i, 1]
            cs = math.sqrt(fe * fe + fn * fn)
            dn = 0.0
            if cs > MIN_CURRENT_MS:
                dn = ((s[0] - org[e, q_min, 0]) * fe
                      + (s[2] - org[e, q_min, 1]) * fn) / cs
            reads[e, q_min, m, 0] = s[0]
            reads[e, q_min, m, 1] = s[2]
            reads[e, q_min, m, 2] = r
            reads[e, q_min, m, 3] = dn
            W.nread[e, q_min] = m + 1


@hot_kernel(inline="always")
def post_step(grid, P, W, state, prev, e, k, t):
    """The report is final once every agent has finished its section (``done``)."""
    for i in range(state.shape[1]):
        if W.done[e, i] == 0:
            return False
    return True


@hot_kernel(inline="always")
def finish(grid, P, W, state, e, k, row):
    """The method's estimate of every detected leak (:func:`POLICY.estimate`), scored."""
    n_leak = P.n_leak
    leaks = W.leaks
    est = W.est
    n_loc = 0
    n_det = 0
    err = 0.0
    for q in range(n_leak):
        if W.peak[e, q] >= 0.0:
            POLICY.estimate(W, e, q)
            n_det += 1
            d = math.sqrt((est[e, q, 0] - leaks[e, q, 0]) ** 2
                          + (est[e, q, 1] - leaks[e, q, 1]) ** 2)
            err += d
            if d <= P.tol:
                n_loc += 1
    row[_C_SCORE] = n_loc / n_leak
    row[_C_LOC] = err / n_det if n_det > 0 else math.nan
    row[_C_DET] = n_det / n_leak
    return n_loc == n_leak


# the one loop specialised to this task's hooks (see oneocean.tasks.loop for why two levels)
@hot_kernel
def _episode(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop):
    run_episode(begin, pre_step, cue, after_agent, post_step, finish, POLICY.plan, POLICY.act,
                grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop)


@njit(cache=True, nogil=True)
def _kernel(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, k_stop, e_lo, e_hi):
    for e in range(e_lo, e_hi):
        _episode(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, e, k_stop)


@hot_kernel
def _observe(grid, LP, P, W, LS, t0, state, nobs, nact, e):
    observe_next(grid, cue, P, W, LP, state, t0, e, LS.k[e], nobs, nact)


@njit(cache=True, nogil=True)
def _observe_kernel(grid, LP, P, W, LS, t0, state, nobs, nact, e_lo, e_hi):
    for e in range(e_lo, e_hi):
        _observe(grid, LP, P, W, LS, t0, state, nobs, nact, e)


# numba keys a cache entry on this file only; drop it when the engine, the task layer, the
# policy or the plume model changes.
fresh_cache(_kernel, __file__, POLICY.__file__, pol.__file__)
