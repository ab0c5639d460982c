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
Sensing (the environment)
    After every agent's move the env takes the agent's reading (the value, kg m-3; the
    reading at the start position after the spin-up before step 0): the observation's probe
    at the next step. The method knows where it took the reading only as well as it knows
    its own position (its navigation estimate, the observation's position then). Nothing
    else about the leaks reaches the method: it is never told which reading is near which
    leak.
Mission computer (the cue; the same for every method)
    Each agent has a survey route (:func:`survey_route`, in the briefing): its section of the
    pipeline polyline, from ``ROUTE_OVERLAP_M`` before the section's start (the first agent:
    from the start itself) to the section's end, so that the sections' coverage overlaps at
    the boundaries. The task's pointer along it advances on the agent's navigation estimate
    at every step (:func:`~oneocean.tasks.waypoints.waypoint_carrot`: the transit to the route's
    start ends within ``ARRIVE_M``, each leg ends within ``CUE_WP_TOL_M`` of its end, the
    carrot lies ``CUE_LOOKAHEAD_M`` ahead on the leg); the cue is that carrot at
    ``CUE_ALT_M`` above the charted seafloor (never shallower than ``CUE_MIN_DEPTH_M``), and
    past the route's last waypoint the agent's section is *finished* (the cue holds there).
    A follower of the cue inspects its section low over the pipeline.
Claims (the method's report, :func:`report`)
    The method files *leak claims*: positions it asserts are leaks, in the report
    (:data:`REPORT_DOC`: ``(E, MAX_CLAIMS, 3)`` rows x, z (m) and the method's own strength,
    unused by the score; a row with a non-finite x or z is no claim). The fused heuristic
    and oracle detect plume events in each agent's own reading series and claim one
    position per event (:mod:`oneocean.methods.heuristic.pi`); an outside policy writes the
    report it is handed (``Observation.report``) in place, before the episode ends.
Scoring (:func:`match_claims`, ground truth enters only here)
    Claims are matched one-to-one to the true leaks, greedily by increasing distance, among
    pairs closer than the detection gate ``DETECT_GATE_M``: repeatedly the closest unmatched
    (claim, leak) pair within the gate is matched. (Every tier's leaks are >= 200 m of a
    pipeline turning <= ``MAX_TURN_DEG`` per leg apart, more than two gates, so a claim is
    within the gate of at most one leak and the greedy matching is the optimal one.) A leak
    is *detected* if a claim is matched to it and *localised* if that claim lies within
    ``loc_tolerance_m``; an unmatched claim is a *false claim* (a second claim near an
    already matched leak is one too). The report is final when every agent's section is
    finished (the mission computer's), or at the time limit.
Success
    Every leak localised and no false claim when the report is final; ``T_s`` is then the time
    at which the last agent finished its section (the time limit on failure).
Metrics
    ``inspection_score`` (primary: localised / (leaks + false claims): 1 only for a perfect
    report, equal to localised / leaks without false claims; claiming everywhere does not
    pay), ``localisation_error_m`` (mean distance of the matched claims to their leaks, m,
    <= ``DETECT_GATE_M`` by construction; NaN if no claim was matched),
    ``detection_rate`` (detected / leaks), ``false_claims`` (count of unmatched claims).
Briefing (:class:`PIBriefing`, after the common fields of :mod:`oneocean.tasks.public`)
    The pipeline chart (its polyline), each agent's section, the mission computer's survey
    routes and the cue's altitude, the sensor's detection threshold and vertical scale, the
    scoring's gate and localisation tolerance, the report's room (:data:`BRIEF_FIELDS`).
Observation
    The cue is the mission computer's carrot along the agent's survey route; the probe is the
    agent's latest reading (kg m-3, taken at the vehicle's true position: where the
    observation's depth and altitude are measured). The task's own field
    (:data:`OBS_EXTRA`): ``section_done``, 1 once the agent's section is finished, else 0.
Methods
    :mod:`oneocean.methods.heuristic.pi` (both follow their section's polyline low over the
    seafloor at the full ``v_max``, detect plume events in their own readings and claim one
    position per event, its upstream edge along the current; heuristic: the sensor models of
    :mod:`oneocean.sensing`, so it logs and claims positions from its dead reckoning;
    oracle: true current and position). Their survey waypoints and event memory are their
    own; their claims are the report, scored here.

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset``; ``PIParams`` / ``PIWork``, ``cell_constants`` and
    ``make``; the public view: the briefing (``PIBriefing``, ``BRIEF_FIELDS``, ``brief``),
    the observation's own field (``OBS_EXTRA``) and the report (``report``,
    ``REPORT_DOC``); the env hooks ``begin`` (plume spin-up, the first readings, the
    mission computer and the report cleared), ``pre_step`` (the field's emit and transport),
    ``sense`` (the mission computer's pointer, ``section_done``), ``cue`` (the carrot and the
    latest reading), ``after_agent`` (the reading after the move), ``post_step`` (the report
    is final when every agent's section is finished), ``finish`` (the report, scored by
    :func:`match_claims`); the compiled loop is :mod:`oneocean.kernels.pi`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..engine import streams
from ..engine._jit import hot_kernel
from ..engine.constraints import DEFAULT_LAND_THRESHOLD, spawn_positions
from ..engine.grid import (current_from_parts, locate_time, sample_current_parts,
                           sample_elevation, sample_elevation_points, synthetic_tide)
from ..errors import ConfigError, NotApplicable
from ..models import pollution as pol
from .common import OBS_DIM, PURPOSE_RESET, STANDARD, fresh_cache
from .spawn import _call, _spawn_altitude, start_times
from .tiers import need_tier
from .waypoints import ARRIVE_M, waypoint_carrot
from .public import briefing_class, common_brief

TASK_ID = "PI"
METRICS = ("inspection_score", "localisation_error_m", "detection_rate", "false_claims")
INT_METRICS = ("false_claims",)
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
#: Detection gate: a claim is matched to a leak only if it lies within this distance, m
#: (a 2.5-cell plume neighbourhood; every tier's leaks are >= 2 gates apart).
DETECT_GATE_M = 50.0
#: Rows of the report: room for the team's claims per episode (:data:`REPORT_DOC`).
MAX_CLAIMS = 32
#: Rows of the payload's event log (its team observation).
MAX_EVENTS = 32
#: Seafloor clearance of the feasibility check, m; near-collision distance, m.
CLEARANCE_M = 1.0
R_COLL_M = 2.0
# ---- the mission computer (the cue)
#: Every agent's survey route but the first starts this far before its section, m (the
#: sections' coverage overlaps at the boundaries).
ROUTE_OVERLAP_M = 60.0
#: The cue's carrot lookahead along the route's leg, m; a leg ends within CUE_WP_TOL_M of
#: its end, m; the transit to the route's start ends within common.ARRIVE_M.
CUE_LOOKAHEAD_M = 12.0
CUE_WP_TOL_M = 1.0
#: The cue's altitude above the charted seafloor (the inspection altitude), m; its shallowest
#: depth, m.
CUE_ALT_M = 2.5
CUE_MIN_DEPTH_M = 1.0

_TIER_KEYS = ("current_band", "time_limit_s", "pipeline_length_m",
              "n_leaks", "leak_spacing_m", "leak_rate_kg_s", "detect_threshold_kg_m3",
              "loc_tolerance_m", "seafloor_min_m", "seafloor_max_m")

_C_SCORE, _C_LOC, _C_DET, _C_FALSE = (len(STANDARD) + i for i in range(len(METRICS)))


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


def _legs(tier) -> tuple:
    """The pipeline's number of legs (``round(pipeline_length_m / LEG_M)``, at least one) and
    their length, m."""
    L = float(tier["pipeline_length_m"])
    n_legs = max(1, int(round(L / LEG_M)))
    return n_legs, L / n_legs


def _shelf_nodes(grid, tier) -> tuple:
    """The grid nodes a pipeline may start from (seafloor depth in the tier's range, off
    land): their ``(j, i)`` indices, ``np.nonzero``'s order."""
    depth = -grid.elevation.astype(np.float64)
    ok = ((depth >= float(tier["seafloor_min_m"])) & (depth <= float(tier["seafloor_max_m"]))
          & (grid.land == 0.0))
    return np.nonzero(ok)


def sample_pipeline(grid, rng, tier, tries: int = 3000, what: str = "pipeline") -> np.ndarray:
    """A random pipeline polyline on the shelf (see the module docstring).

    From a random water node with seafloor depth in range, ``round(pipeline_length_m /
    LEG_M)`` equal legs (at least one) with a random initial heading and turns of at most
    ``MAX_TURN_DEG``; valid when :func:`_corridor_ok` accepts it.

    Parameters
    ----------
    grid : Grid
        The grid export.
    rng : numpy.random.Generator
        The episode's reset stream.
    tier : dict
        Tier parameters (``pipeline_length_m``, ``seafloor_min_m``, ``seafloor_max_m``).
    tries : int
        Attempts before giving up.
    what : str
        What is being drawn, for the error message.

    Returns
    -------
    (V, 2) float64
        The vertices [x, z], world m (V = legs + 1).

    Raises
    ------
    NotApplicable
        No valid pipeline in ``tries`` attempts (never a silent fallback).
    """
    n_legs, leg = _legs(tier)
    jj, ii = _shelf_nodes(grid, tier)
    L = float(tier["pipeline_length_m"])
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
    raise NotApplicable(
        f"{what}: no {L:g} m pipeline with seafloor depth in [{tier['seafloor_min_m']:g}, "
        f"{tier['seafloor_max_m']:g}] m found in {tries} tries; the grid has no such shelf")


def _arc(poly: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poly, axis=0).T))])


def point_at(poly: np.ndarray, s: float) -> np.ndarray:
    """The point at an arc length along a polyline.

    Parameters
    ----------
    poly : (V, 2) float64
        Polyline vertices [x, z], m.
    s : float
        Arc length from the first vertex, m (outside ``[0, length]``: extrapolated along
        the first or last leg).

    Returns
    -------
    (2,) float64
        The point [x, z], m.
    """
    arc = _arc(poly)
    k = int(np.clip(np.searchsorted(arc, s, side="right") - 1, 0, len(poly) - 2))
    w = (s - arc[k]) / max(arc[k + 1] - arc[k], 1e-12)
    return poly[k] + w * (poly[k + 1] - poly[k])


def sub_polyline(poly: np.ndarray, s0: float, s1: float) -> np.ndarray:
    """The part of a polyline between two arc lengths.

    Parameters
    ----------
    poly : (V, 2) float64
        Polyline vertices [x, z], m.
    s0, s1 : float
        Arc lengths of its ends, ``s0 < s1``, m.

    Returns
    -------
    (K, 2) float64
        The points at ``s0`` and ``s1`` with the vertices strictly between them, m.
    """
    arc = _arc(poly)
    inner = [poly[k] for k in range(len(poly)) if s0 < arc[k] < s1]
    return np.array([point_at(poly, s0), *inner, point_at(poly, s1)])


def survey_route(poly, sections, overlap: float = ROUTE_OVERLAP_M):
    """Every agent's survey route: its section of the pipeline polyline as waypoints.

    Each agent's waypoints run from ``overlap`` m before its section's start (the first agent
    from the start itself; never before the pipeline's start) to the section's end: the
    vertices of the pipeline strictly between, with the two ends (:func:`sub_polyline`).

    Parameters
    ----------
    poly : (E, V, 2) array_like
        Pipeline vertices [x, z], m.
    sections : (E, N, 2) array_like
        The arc-length range of each agent's section, m.
    overlap : float
        How far before its section a route starts (every agent but the first), m.

    Returns
    -------
    wps : (E, N, R, 2) float64
        Waypoints [x, z], m (R: the most any agent has; rows past ``wcount`` are 0).
    wcount : (E, N) int64
        Waypoints of each agent.
    """
    poly = np.asarray(poly, dtype=np.float64)
    sections = np.asarray(sections, dtype=np.float64)
    n_ep, n_ag = sections.shape[:2]
    secs = [[sub_polyline(poly[e], max(float(sections[e, i, 0]) - overlap, 0.0)
                          if i > 0 else float(sections[e, i, 0]), float(sections[e, i, 1]))
             for i in range(n_ag)] for e in range(n_ep)]
    n_max = max(len(s) for row in secs for s in row)
    wps = np.zeros((n_ep, n_ag, n_max, 2))
    wcount = np.zeros((n_ep, n_ag), dtype=np.int64)
    for e in range(n_ep):
        for i in range(n_ag):
            wps[e, i, :len(secs[e][i])] = secs[e][i]
            wcount[e, i] = len(secs[e][i])
    return wps, wcount


def sample_leaks(rng, poly: np.ndarray, tier, tries: int = 1000, what: str = "leaks"):
    """Leak positions along a pipeline, by rejection sampling.

    Parameters
    ----------
    rng : numpy.random.Generator
        The episode's reset stream.
    poly : (V, 2) float64
        Pipeline vertices [x, z], m.
    tier : dict
        Tier parameters (``n_leaks``, ``leak_spacing_m``).
    tries : int
        Attempts before giving up.
    what : str
        What is being drawn, for the error message.

    Returns
    -------
    (n_leaks,) float64
        Sorted arc lengths, m, uniform in ``[LEAK_ARC_FRAC, 1 - LEAK_ARC_FRAC]`` of the
        length and at least ``leak_spacing_m`` apart.

    Raises
    ------
    ConfigError
        No such placement in ``tries`` attempts.
    """
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

    Parameters
    ----------
    poly : (V, 2) float64
        Pipeline vertices [x, z], m.
    h : float
        Field cell size, m.
    margin : float
        Margin of the field around the pipeline, m.

    Returns
    -------
    origin : (2,) float64
        World [x, z] of the local origin (the first vertex), m.
    axes : (2,) float64
        ``[cos theta, sin theta]`` of the local x axis (the chord), world frame.
    s0, n0 : float
        Local coordinates of the centre of cell (0, 0), m.
    nx, nz : int
        Cells needed along / across the chord.
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


#: Attempts of :func:`sample_pipeline` and of :func:`sample_leaks` per episode; candidates
#: of one spawn (:func:`~oneocean.engine.constraints.spawn_positions`' default), drawn 64 at
#: a time.
_PIPE_TRIES = 3000
_LEAK_TRIES = 1000
_SPAWN_MAX = 200_000
_SPAWN_BATCH = 64


@hot_kernel
def _arc_c(poly, arc):
    """:func:`_arc` into ``arc`` (V,): 0, then the cumulative ``hypot`` of the legs."""
    arc[0] = 0.0
    acc = 0.0
    for k in range(1, poly.shape[0]):
        acc += math.hypot(poly[k, 0] - poly[k - 1, 0], poly[k, 1] - poly[k - 1, 1])
        arc[k] = acc


@hot_kernel
def _point_at_c(poly, arc, s):
    """:func:`point_at` with the arc lengths at hand: ``(x, z)``."""
    v = poly.shape[0]
    k = 0
    while k < v and arc[k] <= s:       # searchsorted(arc, s, side="right")
        k += 1
    k = min(max(k - 1, 0), v - 2)
    w = (s - arc[k]) / max(arc[k + 1] - arc[k], 1e-12)
    return (poly[k, 0] + w * (poly[k + 1, 0] - poly[k, 0]),
            poly[k, 1] + w * (poly[k + 1, 1] - poly[k, 1]))


@hot_kernel
def _corridor_ok_c(grid, poly, pts, smin, smax):
    """:func:`_corridor_ok`, compiled (``pts`` a work array for the densified line): 1
    (valid), 0 (not), -1 (``pts`` too small: left to Python)."""
    # _densify: the first vertex, then every leg's points at np.linspace(0, 1, n + 1)[1:]
    pts[0, 0] = poly[0, 0]
    pts[0, 1] = poly[0, 1]
    n_p = 1
    for q in range(1, poly.shape[0]):
        ax, az = poly[q - 1, 0], poly[q - 1, 1]
        bx, bz = poly[q, 0], poly[q, 1]
        n = max(1, int(math.ceil(math.hypot(bx - ax, bz - az) / CHECK_SPACING_M)))
        if n_p + n > pts.shape[0]:
            return -1
        step = 1.0 / n
        for i in range(1, n + 1):
            w = 1.0 if i == n else float(i) * step + 0.0
            pts[n_p, 0] = ax + w * (bx - ax)
            pts[n_p, 1] = az + w * (bz - az)
            n_p += 1
    inside = True
    dmin = math.inf
    dmax = -math.inf
    land = False
    for k in range(n_p):
        kk = k if k < n_p - 1 else n_p - 2            # the last point takes the last step
        dx = pts[kk + 1, 0] - pts[kk, 0]
        dz = pts[kk + 1, 1] - pts[kk, 1]
        h = max(math.hypot(dx, dz), 1e-9)
        nx = -dz / h
        nz = dx / h
        for side in range(3):
            if side == 0:
                x, z = pts[k, 0], pts[k, 1]
            elif side == 1:
                x, z = pts[k, 0] + CORRIDOR_CHECK_M * nx, pts[k, 1] + CORRIDOR_CHECK_M * nz
            else:
                x, z = pts[k, 0] - CORRIDOR_CHECK_M * nx, pts[k, 1] - CORRIDOR_CHECK_M * nz
            if x < grid.x0 or x > grid.x_max or z < grid.z0 or z > grid.z_max:
                inside = False
            d = -sample_elevation(grid, x, z)
            dmin = min(dmin, d)
            dmax = max(dmax, d)
            j = min(max(int((z - grid.z0) * grid.inv_dz), 0), grid.ny - 2)
            i = min(max(int((x - grid.x0) * grid.inv_dx), 0), grid.nx - 2)
            if (grid.land[j, i] > 0.0 or grid.land[j + 1, i] > 0.0 or grid.land[j, i + 1] > 0.0
                    or grid.land[j + 1, i + 1] > 0.0):
                land = True
    if not inside or dmin < smin or dmax > smax or land:
        return 0
    return 1


@hot_kernel
def _episodes_kernel(grid, stv, buf, ii, jj, n_legs, leg, turn, smin, smax, n_leaks, sp,
                     rate, n_agents, poly, pts, arc, s_leak, cand, out_poly, out_leaks,
                     out_rate, out_sections, out_pos0, status):
    """:func:`sample_pipeline`, :func:`sample_leaks`, the section starts'
    :func:`~oneocean.engine.constraints.spawn_positions` and the leak rates from each
    episode's stream ``stv[e]`` (``buf[e]`` its kept 32-bit half), compiled: the same draws
    in the same order and the same checks. ``status[e]``: 0 (the episode written), 1 (no
    pipeline, no leak placement, no start or a line too long for ``pts``: left to the
    Python samplers, which raise their own errors)."""
    lt = DEFAULT_LAND_THRESHOLD
    v = n_legs + 1
    lo_f = LEAK_ARC_FRAC
    hi_f = 1.0 - LEAK_ARC_FRAC
    half = 0.5 * SPAWN_BOX_M
    for e in range(stv.shape[0]):
        status[e] = 1
        # the pipeline
        found = False
        if ii.shape[0] > 0:
            for _ in range(_PIPE_TRIES):
                k = streams.integers(stv, buf, e, ii.shape[0])
                px = grid.x0 + ii[k] * grid.dx
                pz = grid.z0 + jj[k] * grid.dz
                px = px + streams.uniform(stv, e, -0.5, 0.5) * grid.dx
                pz = pz + streams.uniform(stv, e, -0.5, 0.5) * grid.dz
                hdg = streams.uniform(stv, e, -math.pi, math.pi)
                poly[0, 0] = px
                poly[0, 1] = pz
                for q in range(n_legs):
                    if q > 0:
                        hdg += streams.uniform(stv, e, -turn, turn)
                    poly[q + 1, 0] = poly[q, 0] + leg * math.sin(hdg)
                    poly[q + 1, 1] = poly[q, 1] + leg * math.cos(hdg)
                ok = _corridor_ok_c(grid, poly, pts, smin, smax)
                if ok < 0:
                    break
                if ok == 1:
                    found = True
                    break
        if not found:
            continue
        # the leaks: sorted arc lengths in the window, at least sp apart
        _arc_c(poly, arc)
        L = arc[v - 1]
        lo, hi = lo_f * L, hi_f * L
        placed = False
        for _ in range(_LEAK_TRIES):
            for q in range(n_leaks):
                s_leak[q] = streams.uniform(stv, e, lo, hi)
            for q in range(1, n_leaks):            # insertion sort: np.sort's values
                x = s_leak[q]
                r = q - 1
                while r >= 0 and s_leak[r] > x:
                    s_leak[r + 1] = s_leak[r]
                    r -= 1
                s_leak[r + 1] = x
            placed = True
            for q in range(1, n_leaks):
                if not s_leak[q] - s_leak[q - 1] >= sp:
                    placed = False
                    break
            if n_leaks < 2 or placed:
                placed = True
                break
        if not placed:
            continue
        # the section starts: np.linspace(0, L, n_agents + 1), one start near each
        step = L / n_agents
        spawned = True
        for a in range(n_agents):
            cut = float(a) * step + 0.0
            out_sections[e, a, 0] = cut
            out_sections[e, a, 1] = L if a + 1 == n_agents else float(a + 1) * step + 0.0
            cx, cz = _point_at_c(poly, arc, cut)
            xl, xh = cx - half, cx + half
            zl, zh = cz - half, cz + half
            got = _spawn_altitude(grid, stv, e, cand, 1, xl, xh, zl, zh, SPAWN_ALTITUDE_M[0],
                                  SPAWN_ALTITUDE_M[1], lt, CLEARANCE_M, 0.0, _SPAWN_MAX,
                                  out_pos0[e, a:])
            if got < 1:
                spawned = False
                break
        if not spawned:
            continue
        for q in range(v):
            out_poly[e, q, 0] = poly[q, 0]
            out_poly[e, q, 1] = poly[q, 1]
        for q in range(n_leaks):
            out_leaks[e, q, 0], out_leaks[e, q, 1] = _point_at_c(poly, arc, s_leak[q])
        for q in range(n_leaks):
            out_rate[e, q] = rate * streams.uniform(stv, e, 0.5, 1.0)
        status[e] = 0
    return status


def _episode_python(grid, rng, tier, n_agents: int, e: int) -> tuple:
    """One episode's pipeline, leaks, leak rates, sections and starts by the Python
    samplers."""
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
    leaks = np.array([point_at(poly, s) for s in s_leak])
    rates = float(tier["leak_rate_kg_s"]) * rng.uniform(0.5, 1.0, int(tier["n_leaks"]))
    return poly, leaks, rates, np.stack([cuts[:-1], cuts[1:]], axis=1), p0


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
        Team size outside [1, 10], missing tier keys, ``n_leaks`` below 1, no leak placement
        or no valid start positions for some episode.
    NotApplicable
        No valid pipeline for some episode (:func:`sample_pipeline`).
    """
    n_agents = int(n_agents)
    if not 1 <= n_agents <= 10:
        raise ConfigError(f"task {TASK_ID}: n_agents must be in [1, 10], got {n_agents}")
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    n_leaks = int(tier["n_leaks"])
    if n_leaks < 1:
        raise ConfigError(f"task {TASK_ID}: n_leaks must be >= 1, got {n_leaks}")
    rngs = streams.episode_states(seed, n_episodes, PURPOSE_RESET)   # one stream per episode
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    first = rngs.copy()                     # each episode's stream where its draws begin
    n_legs, leg = _legs(tier)
    jj, ii = _shelf_nodes(grid, tier)
    poly = np.empty((n_episodes, n_legs + 1, 2))
    leaks = np.empty((n_episodes, n_leaks, 2))
    rates = np.empty((n_episodes, n_leaks))
    sections = np.empty((n_episodes, n_agents, 2))
    pos0 = np.empty((n_episodes, n_agents, 3))
    per_leg = int(math.ceil(leg / CHECK_SPACING_M)) + 2
    status = _call(_episodes_kernel, grid, rngs, np.zeros((n_episodes, 2), dtype=np.uint64),
                   ii.astype(np.int64), jj.astype(np.int64), n_legs, leg,
                   math.radians(MAX_TURN_DEG), float(tier["seafloor_min_m"]),
                   float(tier["seafloor_max_m"]), n_leaks, float(tier["leak_spacing_m"]),
                   float(tier["leak_rate_kg_s"]), n_agents, np.empty((n_legs + 1, 2)),
                   np.empty((n_legs * per_leg + 1, 2)), np.empty(n_legs + 1),
                   np.empty(n_leaks), np.empty((_SPAWN_BATCH, 3)), poly, leaks, rates,
                   sections, pos0, np.empty(n_episodes, dtype=np.int64))
    for e in np.flatnonzero(status):
        # the Python samplers from the episode's first draw: their own errors and messages
        # (raised for the first such episode, as the draws in order would), or the episode
        poly[e], leaks[e], rates[e], sections[e], pos0[e] = _episode_python(
            grid, streams.generator(first[e]), tier, n_agents, int(e))
    return {"poly": poly, "leaks": leaks, "leak_rate": rates, "sections": sections,
            "pos0": pos0, "psi0": np.zeros((n_episodes, n_agents)), "t0": t0}


# ------------------------------------------------------------------------------ kernels

@hot_kernel
def _to_local(x, z, ox, oz, ca, sa):
    dx = x - ox
    dz = z - oz
    return dx * ca + dz * sa, -dx * sa + dz * ca


@hot_kernel
def _face_parts(grid, frame, e, s, n, ti0, ti1, out):
    """The current parts over ``(ti0, ti1)`` (:func:`oneocean.engine.grid.
    sample_current_parts`) at the field point of local ``(s, n)``, ``NEAR_BOTTOM_M`` above
    the seafloor (at least 0.5 m deep), into ``out`` (8,)."""
    ca = frame[e, 2]
    sa = frame[e, 3]
    x = frame[e, 0] + s * ca - n * sa
    z = frame[e, 1] + s * sa + n * ca
    y = -sample_elevation(grid, x, z) - NEAR_BOTTOM_M
    if y < 0.5:
        y = 0.5
    (out[0], out[1], out[2], out[3], out[4], out[5], out[6],
     out[7]) = sample_current_parts(grid, x, y, z, ti0, ti1)


@hot_kernel
def _refresh_faces(grid, frame, uf, vf, e, nx, nz, h, key, part, t):
    """Sample the near-bottom current at every face of episode ``e``'s field, in local axes
    (:func:`~.common.current_at` at one time ``t``: the time located and the synthetic tide
    taken once per refresh, not per face; each face's current over the time interval in
    parts, ``part[e]``, sampled when ``t`` enters a new interval; the same arithmetic)."""
    ti0, ti1, wt = locate_time(grid, t)
    te, tn = synthetic_tide(grid, t)
    ca = frame[e, 2]
    sa = frame[e, 3]
    pe = part[e]
    if key[e, 0] != ti0 or key[e, 1] != ti1:
        s0 = frame[e, 4]
        n0 = frame[e, 5]
        p = 0
        for j in range(nz):
            for f in range(nx + 1):
                _face_parts(grid, frame, e, s0 + (f - 0.5) * h, n0 + j * h, ti0, ti1, pe[p])
                p += 1
        for f in range(nz + 1):
            for i in range(nx):
                _face_parts(grid, frame, e, s0 + i * h, n0 + (f - 0.5) * h, ti0, ti1, pe[p])
                p += 1
        key[e, 0] = ti0
        key[e, 1] = ti1
    p = 0
    for j in range(nz):
        for f in range(nx + 1):
            q = pe[p]
            ce = current_from_parts(grid, wt, q[0], q[1], q[4], q[5]) + te
            cn = current_from_parts(grid, wt, q[2], q[3], q[6], q[7]) + tn
            uf[e, j, f] = ce * ca + cn * sa
            p += 1
    for f in range(nz + 1):
        for i in range(nx):
            q = pe[p]
            ce = current_from_parts(grid, wt, q[0], q[1], q[4], q[5]) + te
            cn = current_from_parts(grid, wt, q[2], q[3], q[6], q[7]) + tn
            vf[e, f, i] = -ce * sa + cn * ca
            p += 1


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
    """PI's params (one rollout).

    Attributes
    ----------
    n_leak : int
        Leaks per episode.
    n_spin : int
        Spin-up field steps before the start.
    refresh : int
        Face currents refreshed every this many field steps.
    dt : float
        Agent step, s (the field steps ``FIELD_EVERY dt``).
    thr : float
        The sensor's detection threshold, kg m-3.
    tol : float
        Localisation tolerance, m.
    gate : float
        Detection gate of the claim matching, m.
    h : float
        Field cell size, m.
    kappa : float
        Diffusivity, m2 s-1.
    tracer : (n_params,) float64
        The field's ``step_field`` params (tracer, no decay).
    """
    n_leak: int             # leaks per episode
    n_spin: int             # spin-up field steps before the start
    refresh: int            # face currents refreshed every this many field steps
    dt: float               # agent step, s (the field steps FIELD_EVERY dt)
    thr: float              # the sensor's detection threshold, kg m-3
    tol: float              # localisation tolerance, m
    gate: float             # detection gate of the claim matching, m
    h: float                # field cell size, m
    kappa: float            # diffusivity, m2 s-1
    tracer: np.ndarray      # (n_params,) the field's step_field params (tracer, no decay)


class PIWork(NamedTuple):
    """PI's per-episode work arrays.

    The env's episode and plume field are the truth (no method reads them); the sensor
    (``sense``) and the mission computer (``route`` .. ``done``) give the observation; the
    report (``claims``) is the method's, which the judge reads.

    Attributes
    ----------
    t0 : (E,) float64
        Start times, s (the spin-up ends there).
    leaks : (E, n_leaks, 2) float64
        Leak positions [x, z], m (scoring only).
    leak_loc : (E, n_leaks, 2) float64
        The same in the field's local frame, m.
    rate : (E, n_leaks) float64
        Emission rates, kg s-1.
    frame : (E, 6) float64
        Field frame: origin x, z (m), cos, sin of the chord, cell (0, 0) centre s, n (m).
    C : (E, 1, nz, nx) float64
        Column mass, kg m-2.
    uf : (E, nz, nx + 1) float64
        Face currents along the chord, m s-1.
    vf : (E, nz + 1, nx) float64
        Face currents across the chord, m s-1.
    land : (E, nz, nx) uint8
        Land / outside flags of the field's cells.
    work : (E, work_size) float64
        ``step_field`` scratch.
    fkey : (E, 2) int64
        The interval of the grid's time axis ``fpart`` holds (-1: none yet).
    fpart : (E, F, 8) float64
        Every face centre's current over that interval, in parts
        (:func:`oneocean.engine.grid.sample_current_parts`); ``F = nz (nx + 1) + (nz + 1)
        nx``, the along-chord faces row by row, then the cross-chord ones.
    sense : (E, N) float64
        Each agent's latest reading, kg m-3 (the observation's probe).
    route : (E, N, R, 2) float64
        Every agent's survey route [x, z], m (:func:`survey_route`).
    route_n : (E, N) int64
        Waypoints of each route.
    ridx : (E, N) int64
        The mission computer's pointer: the route waypoint the agent is heading for.
    tgt : (E, N, 3) float64
        The cue: the carrot at the inspection altitude, world m.
    done : (E, N) int64
        1: the agent's section is finished (past its route's last waypoint).
    ev : (E, N, 4) float64
        The payload's event detector per agent: 1 while a run of readings at or above the
        threshold is open, its peak reading (kg m-3) and where the agent knew it was then
        [x, z] (m).
    evlog : (E, MAX_EVENTS, 3) float64
        The payload's event log (the team observation): every closed event [x, z, peak];
        NaN rows: none yet.
    nev : (E,) int64
        Events logged.
    claims : (E, MAX_CLAIMS, 3) float64
        The report: the method's leak claims [x, z (m), strength]; NaN rows: none.
    """
    # ---- env: the episode and the plume field (truth: no method reads these)
    t0: np.ndarray          # (E,) start times, s (the spin-up ends there)
    leaks: np.ndarray       # (E, n_leaks, 2) leak positions [x, z], m (scoring only)
    leak_loc: np.ndarray    # (E, n_leaks, 2) the same in the field's local frame, m
    rate: np.ndarray        # (E, n_leaks) emission rates, kg s-1
    frame: np.ndarray       # (E, 6) field frame: origin x, z, cos, sin, cell (0, 0) s, n
    C: np.ndarray           # (E, 1, nz, nx) column mass, kg m-2
    uf: np.ndarray          # (E, nz, nx + 1) face currents along the chord, m s-1
    vf: np.ndarray          # (E, nz + 1, nx) face currents across the chord, m s-1
    land: np.ndarray        # (E, nz, nx) uint8 land / outside flags of the field's cells
    work: np.ndarray        # (E, work_size) step_field scratch
    fkey: np.ndarray        # (E, 2) int64 the time interval fpart holds (-1: none)
    fpart: np.ndarray       # (E, F, 8) the face centres' currents over it, in parts
    # ---- env -> method: the sensor (the observation's probe)
    sense: np.ndarray       # (E, N) the agent's latest reading, kg m-3
    # ---- the mission computer (the cue and section_done)
    route: np.ndarray       # (E, N, R, 2) every agent's survey route [x, z], m
    route_n: np.ndarray     # (E, N) int64 waypoints of each route
    ridx: np.ndarray        # (E, N) int64 the route waypoint the agent is heading for
    tgt: np.ndarray         # (E, N, 3) the cue: the carrot at the inspection altitude, m
    done: np.ndarray        # (E, N) int64 1: the agent's section is finished
    # ---- the payload's event log (the team observation)
    ev: np.ndarray          # (E, N, 4) per agent: open, peak reading, its [x, z] (known), m
    evlog: np.ndarray       # (E, MAX_EVENTS, 3) closed events [x, z, peak]; NaN: none
    nev: np.ndarray         # (E,) int64 events logged
    # ---- method -> env: the report (scored by finish)
    claims: np.ndarray      # (E, MAX_CLAIMS, 3) the leak claims [x, z, strength]; NaN: none


def _field_shape(frames) -> tuple[int, int]:
    """The largest ``(nx, nz)`` of :func:`field_frame` results ``frames``."""
    return max(f[4] for f in frames), max(f[5] for f in frames)


def cell_constants(tier: dict, init: dict) -> dict:
    """What every episode of a cell shares, computed on the whole cell's episodes ``init``
    (:meth:`oneocean.tasks.Cell.reset`): ``field_shape``, the plume field's ``(nx, nz)``
    cells, the largest episode's (each episode's field is centred in it). A shard of the cell
    then runs its episodes on the same field as the whole cell does.

    Parameters
    ----------
    tier : dict
        The cell's tier parameters (unused: the shape depends on the pipelines only).
    init : dict
        :func:`reset` output of the cell's episodes (``poly`` (E, V, 2), m).

    Returns
    -------
    dict
        ``{"field_shape": (nx, nz)}``, ints.
    """
    poly = np.asarray(init["poly"], dtype=np.float64)
    frames = [field_frame(poly[e], FIELD_H_M, FIELD_MARGIN_M) for e in range(poly.shape[0])]
    return {"field_shape": _field_shape(frames)}


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    Every episode's field has the same shape, the cell's largest (``init["field_shape"]``
    from :func:`cell_constants`, else the batch's largest), with the episode's extent
    centred in it.

    Returns
    -------
    P : PIParams
        The env's typed scalars.
    W : PIWork
        The env's per-episode work arrays.

    Raises
    ------
    ConfigError
        Missing tier parameters, more than 62 leaks, or a ``field_shape`` smaller than an
        episode's field.
    """
    need_tier(TASK_ID, tier, *_TIER_KEYS, "dt_s")
    dt = float(tier["dt_s"])
    poly = np.asarray(init["poly"], dtype=np.float64)
    n_ep = poly.shape[0]
    n_ag = init["pos0"].shape[1]
    leaks = np.ascontiguousarray(init["leaks"], dtype=np.float64)
    n_leak = leaks.shape[1]
    if n_leak > 62:
        raise ConfigError(f"task {TASK_ID}: at most 62 leaks per episode, got {n_leak}")
    h = FIELD_H_M
    # per-episode field frames (same shape for every episode: the cell's largest one, from
    # cell_constants, else the batch's)
    frames = [field_frame(poly[e], h, FIELD_MARGIN_M) for e in range(n_ep)]
    own = _field_shape(frames)
    nx, nz = init.get("field_shape") or own
    if nx < own[0] or nz < own[1]:
        raise ConfigError(f"task {TASK_ID}: field_shape {(nx, nz)} smaller than an episode's "
                          f"field {own}")
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
    route, route_n = survey_route(poly, init["sections"])
    dtf = FIELD_EVERY * dt
    _, tracer = pol.field_params(pol.KIND_TRACER, 1)
    P = PIParams(n_leak, int(round(SPINUP_S / dtf)), max(1, int(round(FIELD_REFRESH_S / dtf))),
                 dt, float(tier["detect_threshold_kg_m3"]), float(tier["loc_tolerance_m"]),
                 DETECT_GATE_M, h, KAPPA_M2_S, tracer)
    W = PIWork(np.ascontiguousarray(init["t0"], dtype=np.float64), leaks, leak_loc,
               np.ascontiguousarray(init["leak_rate"], dtype=np.float64), frame,
               np.zeros((n_ep, 1, nz, nx)), np.zeros((n_ep, nz, nx + 1)),
               np.zeros((n_ep, nz + 1, nx)), land, np.zeros((n_ep, pol.work_size(1, nz, nx))),
               np.full((n_ep, 2), -1, dtype=np.int64),
               np.zeros((n_ep, nz * (nx + 1) + (nz + 1) * nx, 8)),
               np.zeros((n_ep, n_ag)), route, route_n, np.zeros((n_ep, n_ag), dtype=np.int64),
               np.zeros((n_ep, n_ag, 3)), np.zeros((n_ep, n_ag), dtype=np.int64),
               np.zeros((n_ep, n_ag, 4)), np.full((n_ep, MAX_EVENTS, 3), np.nan),
               np.zeros(n_ep, dtype=np.int64), np.full((n_ep, MAX_CLAIMS, 3), np.nan))
    return P, W


#: The task's own observation field (after :data:`oneocean.tasks.common.OBS_FIELDS`): 1 once
#: the mission computer has the agent's section finished (past its route's last waypoint;
#: the report is final once every agent's is), else 0.
OBS_EXTRA_DOCS = {
    "section_done": ("", "1 once the agent's section of the pipeline is finished (its route's "
                         "last waypoint passed, as its mission computer knows it), else 0"),
}
OBS_EXTRA = tuple(OBS_EXTRA_DOCS)
#: What the cue is (the observation's ``goal_d*`` fields).
CUE_DOC = ("the carrot 12 m ahead along the agent's survey route over its section of the "
           "pipeline, 2.5 m above the charted seafloor")

#: The report a method files and the judge reads (:func:`report`; ``Ctx.R`` of a fused
#: policy, ``Observation.report`` of an outside one, written in place).
REPORT_DOC = (
    "(E, MAX_CLAIMS, 3) float64, the team's leak claims of each episode, one per row: x "
    "(east) and z (north) of the claimed leak position, world m, and a strength of the "
    "method's own (unused by the score). A row whose x or z is not finite is no claim; the "
    "report starts all NaN. Rows may be written, changed or cleared at any step; the judge "
    "reads every row once the report is final (every agent's section finished, or the time "
    "limit) and matches the claims one-to-one to the true leaks within the detection gate "
    "(match_claims).")

#: The briefing's own fields (after :data:`oneocean.tasks.public.COMMON`): name -> (shape,
#: unit, meaning).
BRIEF_FIELDS = {
    "pipeline": ("(E, V, 2)", "m", "the pipeline chart: the polyline's vertices [x east, "
                 "z north] (the pipeline lies on the seafloor)"),
    "sections": ("(E, N, 2)", "m", "each agent's section: its arc-length range along the "
                 "pipeline from the first vertex"),
    "route": ("(E, N, R, 2)", "m", "the mission computer's survey route of each agent "
              "[x, z] (survey_route: its section, from route_overlap before it for every "
              "agent but the first); rows past route_n are 0"),
    "route_n": ("(E, N)", "", "waypoints of each route"),
    "route_overlap": ("", "m", "how far before its section every route but the first starts"),
    "cue_alt": ("", "m", "the cue's altitude above the charted seafloor (the inspection "
                "altitude)"),
    "thr": ("", "kg m-3", "the sensor's detection threshold"),
    "plume_scale": ("", "m", "the plume's vertical scale: a reading is C exp(-a / scale) / "
                    "scale at altitude a over column mass C (kg m-2)"),
    "gate": ("", "m", "the scoring's detection gate: a claim is matched to a leak only "
             "within it"),
    "loc_tol": ("", "m", "the localisation tolerance: a matched claim within it localises "
                "its leak"),
    "max_claims": ("", "", "rows of the report (MAX_CLAIMS)"),
}


PIBriefing = briefing_class("PI", BRIEF_FIELDS, __name__)


def brief(P: PIParams, W: PIWork, init: dict, m) -> PIBriefing:
    """The briefing of every episode of a batch (:class:`oneocean.tasks.public.Mission`
    ``m``): the pipeline chart, the sections and routes, the sensor's threshold, the
    scoring's gate and tolerance.

    Returns
    -------
    PIBriefing
    """
    return PIBriefing(**common_brief(m),
                      pipeline=np.array(init["poly"], dtype=np.float64),
                      sections=np.array(init["sections"], dtype=np.float64),
                      route=W.route.copy(), route_n=W.route_n.copy(),
                      route_overlap=ROUTE_OVERLAP_M, cue_alt=CUE_ALT_M, thr=P.thr,
                      plume_scale=PLUME_SCALE_M, gate=P.gate, loc_tol=P.tol,
                      max_claims=int(W.claims.shape[1]))


def report(W: PIWork) -> np.ndarray:
    """The report the method files and the judge reads (:data:`REPORT_DOC`): ``W.claims``
    itself (a method writes it in place).

    Returns
    -------
    (E, MAX_CLAIMS, 3) float64
    """
    return W.claims


class PITeamObs(NamedTuple):
    """PI's team observation (:data:`TEAM_FIELDS`): the payload's event log, views of ``W``."""
    events: np.ndarray
    n_events: np.ndarray


#: The team observation's fields: name -> (shape, unit, meaning).
TEAM_FIELDS = {
    "events": ("(E, MAX_EVENTS, 3)", "m, m, kg m-3", "the inspection payload's event log: "
               "every run of an agent's readings at or above the threshold, once it ends, as "
               "[x, z] where the agent knew it was at the run's peak and the peak reading; "
               "NaN rows: none yet"),
    "n_events": ("(E,)", "", "events logged"),
}


def team_obs(W: PIWork) -> PITeamObs:
    """The team observation: the payload's event log (views of ``W``).

    Returns
    -------
    PITeamObs
    """
    return PITeamObs(W.evlog, W.nev)


@hot_kernel
def reference_report(C, e, k):
    """The task's reference report, a rule any method may use (behaviour cloning does): claim
    every logged event at its peak (``C.T.events`` into the report ``C.R``, strength the
    peak reading). Report hook (:mod:`oneocean.tasks.loop`)."""
    T = C.T
    R = C.R[e]
    for j in range(min(T.n_events[e], R.shape[0])):
        for c in range(3):
            R[j, c] = T.events[e, j, c]


@hot_kernel
def begin(ctx, e):
    """Spin up the plumes and take every agent's first reading, at its start position; the
    mission computer at the routes' starts, the report empty.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0: the field is cleared, then the
    leaks emit for ``P.n_spin`` field steps ending at ``t0``.

    Returns
    -------
    bool
        False: the episode starts.
    """
    grid, P, W, state = ctx.grid, ctx.P, ctx.W, ctx.state
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
            _refresh_faces(grid, W.frame, W.uf, W.vf, e, nx, nz, h, W.fkey, W.fpart, t)
        _field_step(C, P.tracer, W.uf, W.vf, W.land, W.work, W.leak_loc, W.rate, e, P.n_leak,
                    h, s0, n0, dtf, P.kappa)
    for i in range(state.shape[1]):
        _take_reading(grid, P, W, state, e, i)
        W.ridx[e, i] = 0
        W.done[e, i] = 0
    for j in range(W.claims.shape[1]):
        for c in range(W.claims.shape[2]):
            W.claims[e, j, c] = math.nan
    for j in range(W.evlog.shape[1]):
        for c in range(3):
            W.evlog[e, j, c] = math.nan
    for i in range(state.shape[1]):
        W.ev[e, i, 0] = 0.0
    W.nev[e] = 0
    return False


@hot_kernel
def pre_step(ctx, e, k):
    """Advance the plume field: emit and transport every ``FIELD_EVERY`` steps (face
    currents refreshed every ``P.refresh`` field steps).

    Env hook (:mod:`oneocean.tasks.loop`), before the agents act.
    """
    grid, P, W = ctx.grid, ctx.P, ctx.W
    t = ctx.t0[e] + k * ctx.dt
    if k % FIELD_EVERY == 0:
        C = W.C
        nz = C.shape[2]
        nx = C.shape[3]
        h = P.h
        if (k // FIELD_EVERY) % P.refresh == 0:
            _refresh_faces(grid, W.frame, W.uf, W.vf, e, nx, nz, h, W.fkey, W.fpart, t)
        _field_step(C, P.tracer, W.uf, W.vf, W.land, W.work, W.leak_loc, W.rate, e, P.n_leak,
                    h, W.frame[e, 4], W.frame[e, 5], FIELD_EVERY * P.dt, P.kappa)


@hot_kernel
def _reading(grid, P, W, e, x, z, alt):
    """The sensor's concentration (kg m-3) at ``(x, z)``, ``alt`` m above the seafloor."""
    inv_scale = 1.0 / PLUME_SCALE_M
    ls, ln = _to_local(x, z, W.frame[e, 0], W.frame[e, 1], W.frame[e, 2], W.frame[e, 3])
    return (pol.probe(W.C[e], 0, ls, ln, W.frame[e, 4], W.frame[e, 5], P.h)
            * math.exp(-alt * inv_scale) * inv_scale)


@hot_kernel
def sense(ctx, e, k):
    """The mission computer: every agent's pointer along its survey route advanced on the
    state the method knows (its navigation estimate; the truth for the oracle), the cue's
    carrot (``W.tgt``) and whether its section is finished (``W.done``, the observation's
    ``section_done``); the payload's event log (the team observation: every run of readings
    at or above the threshold, its peak logged where the agent knew it was).

    Env hook (:mod:`oneocean.tasks.loop`), at the start of every step before the cues (module
    docstring: Mission computer).
    """
    grid, P, W, X, O = ctx.grid, ctx.P, ctx.W, ctx.X, ctx.O
    for i in range(X.shape[1]):
        px = X[e, i, 0]
        pz = X[e, i, 2]
        gx, gz, w = waypoint_carrot(W.route, W.ridx, W.route_n, e, i, px, pz,
                                    CUE_LOOKAHEAD_M, CUE_WP_TOL_M, ARRIVE_M)
        W.done[e, i] = 0 if w < W.route_n[e, i] else 1
        gy = -sample_elevation(grid, gx, gz) - CUE_ALT_M
        if gy < CUE_MIN_DEPTH_M:
            gy = CUE_MIN_DEPTH_M
        W.tgt[e, i, 0] = gx
        W.tgt[e, i, 1] = gy
        W.tgt[e, i, 2] = gz
        O[e, i, OBS_DIM] = float(W.done[e, i])
        # the payload's event detector on the latest reading, placed where the agent knows
        # it is: a run at or above the threshold is an event; its peak is logged at its end
        r = W.sense[e, i]
        ev = W.ev[e, i]
        if r >= P.thr:
            if ev[0] == 0.0 or r > ev[1]:
                ev[1] = r
                ev[2] = px
                ev[3] = pz
            ev[0] = 1.0
        elif ev[0] != 0.0:
            ev[0] = 0.0
            n = W.nev[e]
            if n < W.evlog.shape[1]:
                W.evlog[e, n, 0] = ev[2]
                W.evlog[e, n, 1] = ev[3]
                W.evlog[e, n, 2] = ev[1]
                W.nev[e] = n + 1


@hot_kernel
def cue(ctx, e, k, i):
    """The cue: the mission computer's carrot along agent ``i``'s survey route at the
    inspection altitude (``W.tgt``, from :func:`sense`); the probe: the agent's latest
    reading (``W.sense``, kg m-3).

    Env hook (:mod:`oneocean.tasks.loop`): the observation's goal cue and probe. The reading
    was taken by the sensor at the vehicle's true position (after its last move, or at the
    start), at its altitude above the seafloor (at least 0).

    Returns
    -------
    gx, gy, gz : float
        The cue, world m.
    probe : float
        The sensor's concentration, kg m-3.
    """
    W = ctx.W
    return W.tgt[e, i, 0], W.tgt[e, i, 1], W.tgt[e, i, 2], W.sense[e, i]


@hot_kernel
def _take_reading(grid, P, W, state, e, i):
    """The sensor: agent ``i``'s reading at its position, handed to the method (``sense``)."""
    s = state[e, i]
    alt = -sample_elevation(grid, s[0], s[2]) - s[1]
    if alt < 0.0:
        alt = 0.0
    W.sense[e, i] = _reading(grid, P, W, e, s[0], s[2], alt)


@hot_kernel
def after_agent(ctx, e, k, i):
    """Take agent ``i``'s reading after its move into ``W.sense`` (the probe of its next
    observation).

    Env hook (:mod:`oneocean.tasks.loop`), right after the agent moved.
    """
    grid, P, W, state = ctx.grid, ctx.P, ctx.W, ctx.state
    _take_reading(grid, P, W, state, e, i)


@hot_kernel
def post_step(ctx, e, k):
    """The report is final once every agent's section is finished (``W.done``, the mission
    computer's).

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``.

    Returns
    -------
    bool
        True (STOP) once every agent is done; :func:`finish` then scores the report.
    """
    W, state = ctx.W, ctx.state
    for i in range(state.shape[1]):
        if W.done[e, i] == 0:
            return False
    return True


@hot_kernel
def match_claims(claims, n_claims, leaks, n_leak, gate, tol):
    """Score a report: the claims against the true leaks.

    One-to-one greedy matching by increasing distance among pairs within ``gate``: the
    closest unmatched (claim, leak) pair is matched, repeatedly. At most 62 claims and 62
    leaks (bit masks).

    Parameters
    ----------
    claims : (n, >=2) float64
        Claims [x, z, ...], m; claims with a non-finite position are ignored.
    n_claims : int
        Claims used (``claims[:n_claims]``).
    leaks : (m, 2) float64
        True leak positions [x, z], m.
    n_leak : int
        Leaks used (``leaks[:n_leak]``).
    gate : float
        Detection gate, m.
    tol : float
        Localisation tolerance, m.

    Returns
    -------
    n_detected : int
        Matched leaks.
    n_localised : int
        Matched claims within ``tol``.
    n_false : int
        Unmatched (finite) claims.
    err_sum : float
        Summed distance of the matched pairs, m.
    """
    used_c = 0
    used_l = 0
    n_valid = 0
    for c in range(n_claims):
        if math.isfinite(claims[c, 0]) and math.isfinite(claims[c, 1]):
            n_valid += 1
    n_det = 0
    n_loc = 0
    err = 0.0
    while True:
        best = gate
        bc = -1
        bl = -1
        for c in range(n_claims):
            if ((used_c >> c) & 1) != 0:
                continue
            if not (math.isfinite(claims[c, 0]) and math.isfinite(claims[c, 1])):
                continue
            for q in range(n_leak):
                if ((used_l >> q) & 1) != 0:
                    continue
                d = math.sqrt((claims[c, 0] - leaks[q, 0]) ** 2
                              + (claims[c, 1] - leaks[q, 1]) ** 2)
                if d <= best:
                    best = d
                    bc = c
                    bl = q
        if bc < 0:
            break
        used_c |= 1 << bc
        used_l |= 1 << bl
        n_det += 1
        err += best
        if best <= tol:
            n_loc += 1
    return n_det, n_loc, n_valid - n_det, err


def score_claims(claims, leaks, tol: float, gate: float = DETECT_GATE_M) -> dict:
    """:func:`match_claims` on plain arrays, as the metric columns of one episode.

    Parameters
    ----------
    claims : (n, >=2) array_like
        Claims [x, z, ...], m (empty: none).
    leaks : (m, 2) array_like
        True leak positions [x, z], m.
    tol : float
        Localisation tolerance, m.
    gate : float
        Detection gate, m.

    Returns
    -------
    dict
        ``inspection_score``, ``localisation_error_m`` (m, NaN when nothing matched),
        ``detection_rate``, ``false_claims``, plus ``detected``, ``localised`` and
        ``success``.

    Raises
    ------
    ConfigError
        More than 62 claims, or leaks outside 1..62.
    """
    c = np.ascontiguousarray(np.atleast_2d(np.asarray(claims, dtype=np.float64)))
    lk = np.ascontiguousarray(np.atleast_2d(np.asarray(leaks, dtype=np.float64)))
    if c.size == 0:
        c = np.zeros((0, 2))
    n_leak = lk.shape[0]
    if c.shape[0] > 62 or n_leak > 62 or n_leak < 1:
        raise ConfigError(f"score_claims: need 1..62 leaks and at most 62 claims, got "
                          f"{n_leak} and {c.shape[0]}")
    n_det, n_loc, n_false, err = match_claims(c, c.shape[0], lk, n_leak, float(gate),
                                              float(tol))
    return {"inspection_score": n_loc / (n_leak + n_false),
            "localisation_error_m": err / n_det if n_det else math.nan,
            "detection_rate": n_det / n_leak, "false_claims": int(n_false),
            "detected": int(n_det), "localised": int(n_loc),
            "success": bool(n_loc == n_leak and n_false == 0)}


@hot_kernel
def finish(ctx, e, k):
    """Score the report (``W.claims``: every row, non-finite ones no claim) against the true
    leaks (:func:`match_claims`) and write the PI metrics.

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Returns
    -------
    bool
        Success: every leak localised and no false claim.
    """
    P, W = ctx.P, ctx.W
    row = ctx.res[e]
    n_leak = P.n_leak
    n_det, n_loc, n_false, err = match_claims(W.claims[e], W.claims.shape[1], W.leaks[e],
                                              n_leak, P.gate, P.tol)
    row[_C_SCORE] = n_loc / (n_leak + n_false)
    row[_C_LOC] = err / n_det if n_det > 0 else math.nan
    row[_C_DET] = n_det / n_leak
    row[_C_FALSE] = n_false
    return n_loc == n_leak and n_false == 0


fresh_cache(_episodes_kernel, __file__)
