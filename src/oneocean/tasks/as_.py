"""AS — area scan over 3-D terrain (1-10 agents; Table V uses N = 1, our default).

Objective
    Map the seafloor of an axis-aligned rectangle of ``region_long_m x region_short_m``
    (long axis along x or z, drawn per episode) on the continental shelf. Every point of the
    region and a ``REGION_MARGIN_M`` band around it is water whose seafloor depth lies in
    ``[seafloor_min_m, seafloor_max_m]``, and the seafloor depth varies by at least
    ``min_relief_m`` across the region (3-D terrain, from the product's bathymetry). The agents
    start together near the region's south-west corner (within ``SPAWN_BOX_M``), at an
    altitude of ``SPAWN_ALTITUDE_M`` above the seafloor.
Sensor (the environment; identical for every method)
    A downward-looking swath sensor (multibeam/camera): at altitude ``a`` above the seafloor
    (``a = seafloor depth - vehicle depth``, bathymetry sampled with
    :func:`~oneocean.engine.sample_elevation`) it images every coverage cell whose centre lies
    within ``r(a) = a tan(half_angle_deg)`` of the vehicle's horizontal position, and nothing
    at all above ``max_altitude_m`` (no bottom lock). The region is discretised into square
    cells of ``cell_m``; a cell is covered once any agent has imaged it (sampled after every
    step: a ground step of a few metres, well below the footprint's diameter).
Success
    Team coverage fraction >= ``coverage_threshold`` (checked after every step; the episode
    stops there) within ``time_limit_s``. Multi-agent: the team's union of covered cells.
Metrics
    ``coverage_fraction`` (primary: covered cells / region cells at the end),
    ``footprint_loss_frac`` (fraction of agent-steps above ``max_altitude_m``: no imaging),
    ``mean_altitude_m`` (mean altitude over agent-steps, m).
Briefing (:class:`ASBriefing`, after the common fields of :mod:`oneocean.tasks.public`)
    The survey region and its long axis, the sensor (``max_altitude``, ``half_angle_deg``),
    the coverage cell and threshold, the agents' start fixes (``start``), the forecast of the
    current at the region's centre at the survey depth over the episode's window
    (``forecast_centre`` at ``forecast_times``, ``N_TIMES`` even times from the start to the
    time limit, at ``forecast_depth``: the chart's seafloor depth there less the survey
    altitude; the truth for the oracle), and the task's survey plan (below: ``survey_alt``,
    ``line_spacing``, ``lines``, ``line_count``). The chart (common ``chart``) is the
    bathymetry.
Observation
    The cue is the task's mission computer (:func:`cue`): every agent follows its own lines of
    the task's survey plan, a boustrophedon lawnmower over the region for the team
    (:func:`survey_plan`): strips along the region's long axis at the spacing
    ``2 a tan(half_angle) (1 - SURVEY_OVERLAP)`` of the survey altitude
    ``a = SURVEY_ALT_FRAC * max_altitude``, split into contiguous blocks, one per agent, each
    led in by a run-in point ``RUNIN_M`` before its first strip. The mission computer keeps
    each agent's place on its lines (``ASWork.lidx``, advanced on the agent's navigation
    estimate, the same for every method): the cue is the transit point (the run-in, reached
    within ``ARRIVE_M``), then a line-of-sight point ``CUE_LOOK_M`` ahead on the current strip
    or cross leg (a leg ends ``CUE_TOL_M`` before its end), then the last point; at the
    survey altitude above the chart there (never shallower than ``MIN_DEPTH_M``). A follower
    of the cue flies the plain plan on its navigation estimate: with no margins for its
    dead-reckoning drift it leaves holidays at the edges of long strips. The task has no
    observation fields of its own (:data:`OBS_EXTRA`).
Methods
    :mod:`oneocean.methods.heuristic.as_` (its own lawnmower: strips at a commanded altitude,
    terrain following on the chart, current feed-forward, full speed, the strips oriented by
    the scan time predicted on the briefing's forecast and the region extended by the margins
    its navigation error needs, as wide as the time limit allows; one policy for the heuristic
    and the oracle, which differ in information only: the oracle's briefing holds the true
    current and start and its sensors give zero margins). The plan is the method's memory.

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset`` (Python: region, starts and start times per episode);
    the survey geometry (:func:`plan_lawnmower`, :func:`with_runin`, :func:`survey_plan`,
    :func:`centre_forecast`); ``ASParams`` / ``ASWork`` and ``make`` (the env's typed scalars
    and per-episode arrays: coverage map, counters, the mission computer's plan); the
    briefing (``ASBriefing``, ``BRIEF_FIELDS``, ``brief``); the env hooks ``begin``, ``cue``,
    ``after_agent`` (altitude, footprint, coverage after every agent's move), ``post_step``
    (success), ``finish`` (``hot_kernel``, no allocation); the compiled loop is
    :mod:`oneocean.kernels.as_`.

Default team size: N = 1, as in the paper's Table V (so SRs are comparable); any N in
[1, 10] runs, with the strips divided between agents.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..engine import streams
from ..engine._jit import hot_kernel
from ..engine.constraints import DEFAULT_LAND_THRESHOLD, spawn_positions
from ..engine.grid import sample_elevation, sample_elevation_points
from ..errors import ConfigError, NotApplicable
from .common import PURPOSE_RESET, STANDARD, fresh_cache
from .spawn import _call, _spawn_altitude, start_times
from .tiers import need_tier
from .waypoints import ARRIVE_M, waypoint_carrot
from .public import briefing_class, common_brief

TASK_ID = "AS"
METRICS = ("coverage_fraction", "footprint_loss_frac", "mean_altitude_m")
#: Result-matrix columns written by the kernel (standard columns first).
COLUMNS = STANDARD + METRICS

#: Spawn: box side at the region's south-west corner, m; altitude range, m; separation, m.
SPAWN_BOX_M = 30.0
SPAWN_ALTITUDE_M = (5.0, 15.0)
SPAWN_SEPARATION_M = 5.0
#: Water band around the region that must also satisfy the depth rules, m.
REGION_MARGIN_M = 30.0
#: Spacing of the feasibility samples of a candidate region, m.
CHECK_SPACING_M = 15.0
#: Seafloor clearance of the feasibility check during the rollout, m (engine default).
CLEARANCE_M = 1.0
#: Near-collision distance for coll_ratio, m (engine default).
R_COLL_M = 2.0

#: The task's survey plan (the cue, :func:`survey_plan`): survey altitude as a fraction of the
#: sensor's maximum altitude; swath overlap of neighbouring strips (fraction of the swath
#: width); run-in before each agent's first strip, m.
SURVEY_ALT_FRAC = 0.75
SURVEY_OVERLAP = 0.2
RUNIN_M = 20.0
#: The cue's line-of-sight lookahead along a leg, m; a leg ends this far (m) before its end.
CUE_LOOK_M = 12.0
CUE_TOL_M = 1.0
#: Shallowest cue depth, m (stay submerged); also the shallowest forecast depth.
MIN_DEPTH_M = 1.0
#: Times (even, from the start to the time limit) of the briefing's forecast at the centre.
N_TIMES = 7

_TIER_KEYS = ("current_band", "time_limit_s", "region_long_m",
              "region_short_m", "coverage_threshold", "max_altitude_m", "half_angle_deg",
              "cell_m", "seafloor_min_m", "seafloor_max_m", "min_relief_m")

_C_COV, _C_LOSS, _C_ALT = (len(STANDARD) + i for i in range(len(METRICS)))


# ------------------------------------------------------------------------------ geometry

def _region_ok(grid, x_lo, z_lo, x_hi, z_hi, tier) -> bool:
    """True if the rectangle (plus margin) is water with seafloor depth in range and relief."""
    m = REGION_MARGIN_M
    if x_lo - m < grid.x0 or x_hi + m > grid.x_max or z_lo - m < grid.z0 or z_hi + m > grid.z_max:
        return False
    xs = np.arange(x_lo - m, x_hi + m + 1e-9, CHECK_SPACING_M)
    zs = np.arange(z_lo - m, z_hi + m + 1e-9, CHECK_SPACING_M)
    X, Z = np.meshgrid(xs, zs)
    pts = np.ascontiguousarray(np.stack([X.ravel(), Z.ravel()], axis=1))
    depth = -sample_elevation_points(grid, pts, np.empty(pts.shape[0]))
    if depth.min() < float(tier["seafloor_min_m"]) or depth.max() > float(tier["seafloor_max_m"]):
        return False
    j = np.clip(((pts[:, 1] - grid.z0) * grid.inv_dz).astype(np.int64), 0, grid.ny - 2)
    i = np.clip(((pts[:, 0] - grid.x0) * grid.inv_dx).astype(np.int64), 0, grid.nx - 2)
    land = np.maximum.reduce([grid.land[j, i], grid.land[j + 1, i], grid.land[j, i + 1],
                              grid.land[j + 1, i + 1]])
    if np.any(land > 0.0):
        return False
    inner = ((pts[:, 0] >= x_lo) & (pts[:, 0] <= x_hi) & (pts[:, 1] >= z_lo)
             & (pts[:, 1] <= z_hi))
    return float(np.ptp(depth[inner])) >= float(tier["min_relief_m"])


def _candidate_nodes(grid, tier) -> np.ndarray:
    """Grid nodes (k, 2) [x, z] whose seafloor depth is in range and that are off land."""
    depth = -grid.elevation.astype(np.float64)
    ok = ((depth >= float(tier["seafloor_min_m"])) & (depth <= float(tier["seafloor_max_m"]))
          & (grid.land == 0.0))
    j, i = np.nonzero(ok)
    return np.stack([grid.x0 + i * grid.dx, grid.z0 + j * grid.dz], axis=1)


def sample_region(grid, rng, tier, tries: int = 3000, what: str = "region"):
    """Draw a valid scan region.

    Around a random off-land grid node whose seafloor depth is in range, with a random long
    axis; valid when the region and its ``REGION_MARGIN_M`` band are water with seafloor depth
    in ``[seafloor_min_m, seafloor_max_m]`` and the region's relief is at least
    ``min_relief_m``.

    Parameters
    ----------
    grid : Grid
        The grid export.
    rng : numpy.random.Generator
        The episode's reset stream.
    tier : dict
        Tier parameters (``region_long_m``, ``region_short_m``, ``seafloor_min_m``,
        ``seafloor_max_m``, ``min_relief_m``).
    tries : int
        Attempts before giving up.
    what : str
        What is being drawn, for the error message.

    Returns
    -------
    tuple
        ``(x_lo, z_lo, x_hi, z_hi, long_axis)``: the region's bounds, world m, and
        ``long_axis`` 0 when the long side runs along x (east), 1 along z (north).

    Raises
    ------
    NotApplicable
        No valid region in ``tries`` attempts (never a silent fallback).
    """
    nodes = _candidate_nodes(grid, tier)
    L = float(tier["region_long_m"])
    W = float(tier["region_short_m"])
    if nodes.shape[0] > 0:
        for _ in range(int(tries)):
            c = nodes[rng.integers(nodes.shape[0])] + rng.uniform(-0.5, 0.5, 2) * (grid.dx,
                                                                                   grid.dz)
            axis = int(rng.integers(2))
            hx, hz = (0.5 * L, 0.5 * W) if axis == 0 else (0.5 * W, 0.5 * L)
            box = (c[0] - hx, c[1] - hz, c[0] + hx, c[1] + hz)
            if _region_ok(grid, *box, tier):
                return (*box, axis)
    raise NotApplicable(
        f"{what}: no {L:g} x {W:g} m region with seafloor depth in "
        f"[{tier['seafloor_min_m']:g}, {tier['seafloor_max_m']:g}] m and relief >= "
        f"{tier['min_relief_m']:g} m found in {tries} tries; the grid has no such shelf")


#: Attempts of :func:`sample_region` per episode; candidates of one spawn
#: (:func:`~oneocean.engine.constraints.spawn_positions`' default), drawn 64 at a time.
_REGION_TRIES = 3000
_SPAWN_MAX = 200_000
_SPAWN_BATCH = 64
#: :func:`_episodes_kernel` statuses: the episode drawn; no region; too few start positions;
#: a case the kernel leaves to the Python sampler (a region without inner check points).
_FOUND, _NO_REGION, _NO_SPAWN, _PYTHON = 0, 1, 2, 3


@hot_kernel
def _arange_at(start, step, i):
    """Entry ``i`` of ``np.arange(start, stop, step)`` (float64): ``start``, ``start + step``,
    then ``start + i * delta`` with ``delta`` the difference of those two (NumPy's fill)."""
    if i == 0:
        return start
    second = start + step
    if i == 1:
        return second
    return start + i * (second - start)


@hot_kernel
def _region_ok_c(grid, x_lo, z_lo, x_hi, z_hi, smin, smax, relief):
    """:func:`_region_ok`, compiled: 1 (valid), 0 (not), -1 (no check point inside the
    region, which NumPy's ``ptp`` rejects: left to Python)."""
    m = REGION_MARGIN_M
    if x_lo - m < grid.x0 or x_hi + m > grid.x_max or z_lo - m < grid.z0 or z_hi + m > grid.z_max:
        return 0
    xa = x_lo - m
    za = z_lo - m
    nx = int(math.ceil(((x_hi + m + 1e-9) - xa) / CHECK_SPACING_M))
    nz = int(math.ceil(((z_hi + m + 1e-9) - za) / CHECK_SPACING_M))
    dmin = math.inf
    dmax = -math.inf
    imin = math.inf
    imax = -math.inf
    for jz in range(max(nz, 0)):
        z = _arange_at(za, CHECK_SPACING_M, jz)
        for ix in range(max(nx, 0)):
            x = _arange_at(xa, CHECK_SPACING_M, ix)
            d = -sample_elevation(grid, x, z)
            dmin = min(dmin, d)
            dmax = max(dmax, d)
            if x >= x_lo and x <= x_hi and z >= z_lo and z <= z_hi:
                imin = min(imin, d)
                imax = max(imax, d)
    if dmin < smin or dmax > smax:
        return 0
    for jz in range(max(nz, 0)):
        z = _arange_at(za, CHECK_SPACING_M, jz)
        j = min(max(int((z - grid.z0) * grid.inv_dz), 0), grid.ny - 2)
        for ix in range(max(nx, 0)):
            x = _arange_at(xa, CHECK_SPACING_M, ix)
            i = min(max(int((x - grid.x0) * grid.inv_dx), 0), grid.nx - 2)
            if (grid.land[j, i] > 0.0 or grid.land[j + 1, i] > 0.0 or grid.land[j, i + 1] > 0.0
                    or grid.land[j + 1, i + 1] > 0.0):
                return 0
    if imax < imin:
        return -1
    return 1 if imax - imin >= relief else 0


@hot_kernel
def _episodes_kernel(grid, stv, buf, nodes, L, W, smin, smax, relief, n_agents, cand, out,
                     region, axis, pos0, status):
    """:func:`sample_region` then the agents' :func:`~oneocean.engine.constraints.
    spawn_positions` from each episode's stream ``stv[e]`` (``buf[e]`` its kept 32-bit
    half), compiled: the same draws in the same order and the same checks. ``status[e]``:
    ``_FOUND`` (``region[e]``, ``axis[e]``, ``pos0[e]`` written), ``_NO_REGION``,
    ``_NO_SPAWN`` or ``_PYTHON``."""
    lt = DEFAULT_LAND_THRESHOLD
    sep2 = SPAWN_SEPARATION_M ** 2
    k_nodes = nodes.shape[0]
    for e in range(stv.shape[0]):
        status[e] = _NO_REGION
        if k_nodes == 0:
            continue
        for _ in range(_REGION_TRIES):
            k = streams.integers(stv, buf, e, k_nodes)
            cx = nodes[k, 0] + streams.uniform(stv, e, -0.5, 0.5) * grid.dx
            cz = nodes[k, 1] + streams.uniform(stv, e, -0.5, 0.5) * grid.dz
            ax = streams.integers(stv, buf, e, 2)
            if ax == 0:
                hx, hz = 0.5 * L, 0.5 * W
            else:
                hx, hz = 0.5 * W, 0.5 * L
            x_lo, z_lo, x_hi, z_hi = cx - hx, cz - hz, cx + hx, cz + hz
            ok = _region_ok_c(grid, x_lo, z_lo, x_hi, z_hi, smin, smax, relief)
            if ok < 0:
                status[e] = _PYTHON
                break
            if ok == 0:
                continue
            region[e, 0] = x_lo
            region[e, 1] = z_lo
            region[e, 2] = x_hi
            region[e, 3] = z_hi
            axis[e] = ax
            # spawn_positions(n_agents, x, z in the box's south-west corner, altitude)
            xl, xh = x_lo, x_lo + SPAWN_BOX_M
            zl, zh = z_lo, z_lo + SPAWN_BOX_M
            got = _spawn_altitude(grid, stv, e, cand, n_agents, xl, xh, zl, zh,
                                  SPAWN_ALTITUDE_M[0], SPAWN_ALTITUDE_M[1], lt, CLEARANCE_M,
                                  sep2, _SPAWN_MAX, out)
            if got < n_agents:
                status[e] = _NO_SPAWN
                break
            for q in range(n_agents):
                pos0[e, q, 0] = out[q, 0]
                pos0[e, q, 1] = out[q, 1]
                pos0[e, q, 2] = out[q, 2]
            status[e] = _FOUND
            break
    return status


def _episode_python(grid, rng, tier, n_agents: int, e: int):
    """One episode's region, long axis and starts by the Python samplers."""
    *box, ax = sample_region(grid, rng, tier, what=f"task {TASK_ID} reset (episode {e})")
    spawn = {"x": (box[0], box[0] + SPAWN_BOX_M), "z": (box[1], box[1] + SPAWN_BOX_M),
             "altitude": SPAWN_ALTITUDE_M}
    return box, ax, spawn_positions(grid, rng, n_agents, spawn, clearance=CLEARANCE_M,
                                    min_separation=SPAWN_SEPARATION_M)


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the scan region, start positions and start time of every episode.

    Returns
    -------
    dict
        ``region`` (E, 4) ``[x_lo, z_lo, x_hi, z_hi]`` m; ``long_axis`` (E,) int64 (0 = x);
        ``pos0`` (E, N, 3) start positions, m; ``psi0`` (E, N) initial headings (0: north),
        rad; ``t0`` (E,) start times, s; ``regime_points`` (E, 5, 3) the region's corners and
        centre at the first agent's start depth, m (``Cell.reset``).

    Raises
    ------
    ConfigError
        Team size outside [1, 10], missing tier keys or a region side below two check
        spacings (``2 CHECK_SPACING_M``); no valid start positions
        (:func:`~oneocean.engine.constraints.spawn_positions`).
    NotApplicable
        No valid scan region for some episode.
    """
    n_agents = int(n_agents)
    if not 1 <= n_agents <= 10:
        raise ConfigError(f"task {TASK_ID}: n_agents must be in [1, 10], got {n_agents}")
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    for key in ("region_long_m", "region_short_m"):
        # the relief check needs seafloor samples inside the region: two spacings at least
        if not float(tier[key]) >= 2.0 * CHECK_SPACING_M:
            raise ConfigError(f"task {TASK_ID}: {key} must be >= {2.0 * CHECK_SPACING_M:g} m "
                              f"(two spacings of the region's seafloor checks), got "
                              f"{tier[key]!r}")
    rngs = streams.episode_states(seed, n_episodes, PURPOSE_RESET)   # one stream per episode
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    first = rngs.copy()                     # each episode's stream where its draws begin
    region = np.empty((n_episodes, 4))
    axis = np.zeros(n_episodes, dtype=np.int64)
    pos0 = np.empty((n_episodes, n_agents, 3))
    status = _call(_episodes_kernel, grid, rngs, np.zeros((n_episodes, 2), dtype=np.uint64),
                   np.ascontiguousarray(_candidate_nodes(grid, tier)),
                   float(tier["region_long_m"]), float(tier["region_short_m"]),
                   float(tier["seafloor_min_m"]), float(tier["seafloor_max_m"]),
                   float(tier["min_relief_m"]), n_agents, np.empty((_SPAWN_BATCH, 3)),
                   np.empty((n_agents, 3)), region, axis, pos0,
                   np.empty(n_episodes, dtype=np.int64))
    for e in np.flatnonzero(status):
        # the Python samplers from the episode's first draw: their own errors and messages
        # (raised for the first such episode, as the draws in order would), or the episode
        box, axis[e], pos0[e] = _episode_python(grid, streams.generator(first[e]), tier,
                                                n_agents, int(e))
        region[e] = box
    # the current regime is judged over the scan region (its centre and corners, at the
    # agents' start depth)
    y = pos0[:, :1, 1]
    xs = np.stack([region[:, 0], region[:, 2], region[:, 0], region[:, 2],
                   0.5 * (region[:, 0] + region[:, 2])], axis=1)
    zs = np.stack([region[:, 1], region[:, 1], region[:, 3], region[:, 3],
                   0.5 * (region[:, 1] + region[:, 3])], axis=1)
    pts = np.stack([xs, np.broadcast_to(y, xs.shape), zs], axis=-1)
    return {"region": region, "long_axis": axis, "pos0": pos0,
            "psi0": np.zeros((n_episodes, n_agents)), "t0": t0, "regime_points": pts}


# ------------------------------------------------------------------------------ survey

def n_strips(width: float, spacing: float, n_agents: int) -> int:
    """Strips of a lawnmower over ``width`` at most ``spacing`` apart, at least one per agent.

    Parameters
    ----------
    width : float
        Width to cover, m.
    spacing : float
        Largest strip spacing, m.
    n_agents : int
        Team size N.

    Returns
    -------
    int
        ``max(1, ceil(width / spacing), n_agents)``.
    """
    return max(1, int(math.ceil(width / spacing - 1e-9)), int(n_agents))


def plan_lawnmower(box, axis: int, spacing: float, n_agents: int, seam: float = 0.0):
    """Boustrophedon waypoints (x, z) per agent over ``box``, strips along ``axis``.

    ``n = max(ceil((W + (n_agents - 1) seam) / spacing), n_agents)`` strips (every agent gets
    at least one; a large team flies narrower, overlapping strips rather than idling or
    crowding), split into contiguous blocks, one per agent; every block starts at the strips'
    low end. The strips lie at ``(k + 1/2) U / n`` over the width unrolled to
    ``U = W + (n_agents - 1) seam``, block ``i`` shifted back by ``i seam``: neighbouring
    agents' swaths overlap by an extra ``seam`` m at the seam between their blocks (0: evenly
    spaced strips).

    Parameters
    ----------
    box : tuple of float
        The region ``(x_lo, z_lo, x_hi, z_hi)``, m.
    axis : int
        Strip orientation: 0 along x (offsets along z), 1 along z.
    spacing : float
        Strip spacing, m.
    n_agents : int
        Team size N.
    seam : float, optional
        Extra overlap between neighbouring agents' blocks, m (default 0).

    Returns
    -------
    wps : (n_agents, n_max, 2) float64
        Waypoints (x, z), m; agent ``i`` uses ``wps[i, :count[i]]`` (start and end of each
        strip).
    count : (n_agents,) int64
        Waypoints of each agent.
    """
    x_lo, z_lo, x_hi, z_hi = box
    if axis == 0:  # strips along x, offsets along z
        a_lo, a_hi, b_lo, b_hi = x_lo, x_hi, z_lo, z_hi
    else:
        a_lo, a_hi, b_lo, b_hi = z_lo, z_hi, x_lo, x_hi
    width = b_hi - b_lo + (n_agents - 1) * seam
    n = n_strips(width, spacing, n_agents)
    offs = b_lo + (np.arange(n) + 0.5) * width / n
    blocks = np.array_split(np.arange(n), n_agents)
    n_max = 2 * max(len(b) for b in blocks)
    wps = np.zeros((n_agents, n_max, 2))
    count = np.zeros(n_agents, dtype=np.int64)
    for i, blk in enumerate(blocks):
        k = 0
        for j, s in enumerate(blk):
            ends = (a_lo, a_hi) if j % 2 == 0 else (a_hi, a_lo)
            b = offs[s] - i * seam
            for a in ends:
                wps[i, k] = (a, b) if axis == 0 else (b, a)
                k += 1
        count[i] = k
    return wps, count


def with_runin(wps, count, runin: float = RUNIN_M):
    """The waypoints with a run-in waypoint prepended per agent.

    The run-in lies ``runin`` m before the first strip's start, on the strip's line (outside
    the region, inside its water margin), so a torpedo AUV enters the region aligned with
    the strip.

    Parameters
    ----------
    wps : (n_agents, n_max, 2) float64
        Waypoints (x, z), m (:func:`plan_lawnmower`).
    count : (n_agents,) int64
        Waypoints of each agent.
    runin : float, optional
        Run-in distance, m (default :data:`RUNIN_M`).

    Returns
    -------
    wps : (n_agents, n_max + 1, 2) float64
        Waypoints with the run-in first, m.
    count : (n_agents,) int64
        ``count + 1``.
    """
    n_ag, n_max, _ = wps.shape
    out = np.zeros((n_ag, n_max + 1, 2))
    out[:, 1:] = wps
    for i in range(n_ag):
        a, b = wps[i, 0], wps[i, 1]
        d = b - a
        L = float(np.hypot(d[0], d[1]))
        out[i, 0] = a - d / L * runin if L > 1e-9 else a
    return out, count + 1


def survey_altitude(tier: dict) -> float:
    """The survey altitude of the task's plan.

    Parameters
    ----------
    tier : dict
        Tier parameters; reads ``max_altitude_m``, the sensor's maximum altitude, m.

    Returns
    -------
    float
        ``SURVEY_ALT_FRAC * max_altitude_m``, m.
    """
    return SURVEY_ALT_FRAC * float(tier["max_altitude_m"])


def survey_spacing(tier: dict) -> float:
    """The strip spacing of the task's plan.

    Parameters
    ----------
    tier : dict
        Tier parameters; reads ``max_altitude_m`` (m) and ``half_angle_deg`` (the sensor's
        half swath angle, degrees).

    Returns
    -------
    float
        ``2 a tan(half_angle) (1 - SURVEY_OVERLAP)``, m, at the :func:`survey_altitude` ``a``.
    """
    return (2.0 * survey_altitude(tier) * math.tan(math.radians(float(tier["half_angle_deg"])))
            * (1.0 - SURVEY_OVERLAP))


def survey_plan(region, long_axis, spacing: float, n_agents: int):
    """The task's survey plan of every episode: the cue's lines.

    A lawnmower (:func:`plan_lawnmower`) over each region, strips along its long axis at
    ``spacing``, split into one block per agent, each led in by its run-in
    (:func:`with_runin`).

    Parameters
    ----------
    region : (E, 4) array_like
        The regions ``(x_lo, z_lo, x_hi, z_hi)``, m.
    long_axis : (E,) array_like
        0: the long side runs along x.
    spacing : float
        Strip spacing, m.
    n_agents : int
        Team size N.

    Returns
    -------
    lines : (E, N, L, 2) float64
        Each agent's points (x, z), m, run-in first (zeros past its count).
    count : (E, N) int64
        Points of each agent.
    """
    region = np.asarray(region, dtype=np.float64).reshape(-1, 4)
    plans = [with_runin(*plan_lawnmower(tuple(region[e]), int(long_axis[e]), spacing,
                                        n_agents)) for e in range(region.shape[0])]
    n_max = max((w.shape[1] for w, _ in plans), default=1)
    lines = np.zeros((region.shape[0], n_agents, n_max, 2))
    count = np.zeros((region.shape[0], n_agents), dtype=np.int64)
    for e, (w, c) in enumerate(plans):
        lines[e, :, :w.shape[1]] = w
        count[e] = c
    return lines, count


def centre_forecast(grid, box, t0: float, duration: float, altitude: float, fc=None,
                    e: int = 0, n_times: int = N_TIMES):
    """The current at the centre of ``box`` at the survey depth over the episode.

    Sampled at ``n_times`` even times over ``[t0, t0 + duration]`` at the depth
    ``max(seafloor depth at the centre - altitude, MIN_DEPTH_M)``: the truth, or given ``fc``
    episode ``e``'s forecast of it (:func:`oneocean.tasks.routing.forecast_field`).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    box : tuple of float
        The region ``(x_lo, z_lo, x_hi, z_hi)``, m.
    t0 : float
        Episode start time, s since the grid's ``time0_unix_s``.
    duration : float
        Episode duration, s.
    altitude : float
        Survey altitude above the seafloor, m.
    fc : (E, 5) float64, optional
        The episodes' forecast errors (``Mission.fc``); None: the truth.
    e : int, optional
        Episode index into ``fc`` (default 0).
    n_times : int, optional
        Number of sample times (default :data:`N_TIMES`).

    Returns
    -------
    times : (n_times,) float64
        The sample times, s since the grid's ``time0_unix_s``.
    cur : (n_times, 2) float64
        Currents (east, north), m s-1.
    depth : float
        The sampling depth, m.
    """
    from ..engine.grid import sample_currents
    from .routing import forecast_field

    x_lo, z_lo, x_hi, z_hi = box
    depth = float(-sample_elevation_points(
        grid, np.array([[0.5 * (x_lo + x_hi), 0.5 * (z_lo + z_hi)]]), np.empty(1))[0]) - altitude
    depth = max(depth, MIN_DEPTH_M)
    ts = float(t0) + np.linspace(0.0, float(duration), int(n_times))
    xyz = np.tile([0.5 * (x_lo + x_hi), float(depth), 0.5 * (z_lo + z_hi)], (ts.size, 1))
    cur = np.ascontiguousarray(sample_currents(grid, xyz, ts), dtype=np.float64)
    if fc is not None:
        cur = forecast_field(cur.reshape(ts.size, 1, 1, 2), fc, e).reshape(ts.size, 2)
    return ts, cur, depth


# ------------------------------------------------------------------------------ env

class ASParams(NamedTuple):
    """AS's params (one rollout).

    Attributes
    ----------
    alt_max : float
        The sensor's maximum altitude (bottom lock), m.
    tan_h : float
        ``tan(half_angle)``: footprint radius per metre of altitude.
    cell : float
        Coverage cell side, m.
    thr : float
        Coverage fraction of success.
    t_lim : float
        Time limit, s.
    alt : float
        The survey altitude of the task's plan (the cue's), m (:func:`survey_altitude`).
    spacing : float
        The strip spacing of the task's plan, m (:func:`survey_spacing`).
    """
    alt_max: float          # sensor's maximum altitude (bottom lock), m
    tan_h: float            # tan(half_angle): footprint radius per metre of altitude
    cell: float             # coverage cell side, m
    thr: float              # coverage fraction of success
    t_lim: float            # time limit, s
    alt: float              # survey altitude of the task's plan (the cue's), m
    spacing: float          # strip spacing of the task's plan, m


class ASWork(NamedTuple):
    """AS's per-episode work arrays.

    Attributes
    ----------
    region : (E, 4) float64
        ``[x_lo, z_lo, x_hi, z_hi]``, m.
    long_axis : (E,) int64
        0: the long side runs along x.
    ncell : (E, 2) int64
        Coverage cells along x, z.
    cov : (E, max cells) uint8
        Coverage map (row-major, z rows).
    cnt : (E, 2) int64
        Covered cells, agent-steps above ``alt_max``.
    alt_sum : (E,) float64
        Sum of altitudes over agent-steps, m.
    lines : (E, N, L, 2) float64
        The task's survey plan (:func:`survey_plan`): each agent's points (x, z), m.
    lcount : (E, N) int64
        Points of each agent.
    lidx : (E, N) int64
        The mission computer's place on each agent's lines (:func:`cue`).
    """
    region: np.ndarray      # (E, 4) [x_lo, z_lo, x_hi, z_hi], m
    long_axis: np.ndarray   # (E,) int64, 0 = the long side runs along x
    ncell: np.ndarray       # (E, 2) int64 coverage cells along x, z
    cov: np.ndarray         # (E, max cells) uint8 coverage map (row-major, z rows)
    cnt: np.ndarray         # (E, 2) int64 covered cells, agent-steps above alt_max
    alt_sum: np.ndarray     # (E,) sum of altitudes over agent-steps, m
    # the mission computer (the cue): the task's survey plan and each agent's place on it
    lines: np.ndarray       # (E, N, L, 2) each agent's points (x, z), m, run-in first
    lcount: np.ndarray      # (E, N) int64 points of each agent
    lidx: np.ndarray        # (E, N) int64 each agent's place on its lines


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    Returns
    -------
    P : ASParams
        The env's typed scalars.
    W : ASWork
        The env's per-episode work arrays (the task's survey plan: :func:`survey_plan`).

    Raises
    ------
    ConfigError
        Missing tier parameters.
    """
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    region = np.ascontiguousarray(init["region"], dtype=np.float64)
    long_axis = np.ascontiguousarray(init["long_axis"], dtype=np.int64)
    n_ep = region.shape[0]
    n_ag = init["pos0"].shape[1]
    cell = float(tier["cell_m"])
    ncell = np.empty((n_ep, 2), dtype=np.int64)
    ncell[:, 0] = np.maximum(1, np.round((region[:, 2] - region[:, 0]) / cell)).astype(np.int64)
    ncell[:, 1] = np.maximum(1, np.round((region[:, 3] - region[:, 1]) / cell)).astype(np.int64)
    n_cells = int((ncell[:, 0] * ncell[:, 1]).max()) if n_ep else 1
    P = ASParams(float(tier["max_altitude_m"]),
                 math.tan(math.radians(float(tier["half_angle_deg"]))), cell,
                 float(tier["coverage_threshold"]), float(tier["time_limit_s"]),
                 survey_altitude(tier), survey_spacing(tier))
    lines, lcount = survey_plan(region, long_axis, P.spacing, n_ag)
    W = ASWork(region, long_axis, ncell, np.zeros((n_ep, n_cells), dtype=np.uint8),
               np.zeros((n_ep, 2), dtype=np.int64), np.zeros(n_ep), lines, lcount,
               np.zeros((n_ep, n_ag), dtype=np.int64))
    return P, W


#: The task's own observation fields (after :data:`oneocean.tasks.common.OBS_FIELDS`): none.
OBS_EXTRA_DOCS: dict = {}
OBS_EXTRA = ()
#: What the cue is (the observation's ``goal_d*`` fields).
CUE_DOC = ("the next point of the agent's lines of the task's survey plan (a lawnmower over the "
           "region for the team, at 0.75 of the maximum altitude above the chart): its run-in "
           "point, then 12 m ahead on the current strip or cross leg")

#: The briefing's own fields (after :data:`oneocean.tasks.public.COMMON`): name -> (shape,
#: unit, meaning).
BRIEF_FIELDS = {
    "region": ("(E, 4)", "m", "the survey region [x_lo, z_lo, x_hi, z_hi] (world x east, "
               "z north)"),
    "long_axis": ("(E,)", "", "0: the region's long side runs along x (east), 1 along z"),
    "max_altitude": ("", "m", "the sensor's maximum altitude: nothing is imaged above it"),
    "half_angle_deg": ("", "deg", "the sensor's half swath angle: footprint radius = "
                       "altitude tan(half angle)"),
    "cell": ("", "m", "side of the coverage cells"),
    "coverage_threshold": ("", "", "success: the team's covered fraction of the region's "
                           "cells"),
    "start": ("(E, N, 3)", "m", "the agents' start fixes (world x east, y depth, z north), "
              "as their navigation knows them"),
    "forecast_centre": ("(E, N_TIMES, 2)", "m s-1", "the forecast current (east, north) at "
                        "the region's centre at forecast_depth, at forecast_times (the "
                        "truth for the oracle)"),
    "forecast_times": ("(E, N_TIMES)", "s", "the forecast's times: N_TIMES even times from "
                       "the start to the time limit, since the product's time origin"),
    "forecast_depth": ("(E,)", "m", "the forecast's depth: the chart's seafloor depth at the "
                       "centre less survey_alt (at least MIN_DEPTH_M)"),
    "survey_alt": ("", "m", "the task's survey plan: altitude above the chart of its cue"),
    "line_spacing": ("", "m", "the task's survey plan: strip spacing"),
    "lines": ("(E, N, L, 2)", "m", "the task's survey plan: each agent's points (x, z), "
              "run-in first, then the ends of its strips (the cue follows them)"),
    "line_count": ("(E, N)", "", "the task's survey plan: points of each agent"),
}


ASBriefing = briefing_class("AS", BRIEF_FIELDS, __name__)


def brief(P: ASParams, W: ASWork, init: dict, m) -> ASBriefing:
    """The briefing of every episode of a batch.

    The region, the sensor, the success rule, the start fixes (``m.X0``), the forecast at the
    region's centre (:func:`centre_forecast` at the survey altitude; the truth for a method
    given the true current) and the task's survey plan.

    Returns
    -------
    ASBriefing
    """
    n_ep = W.region.shape[0]
    times = np.zeros((n_ep, N_TIMES))
    cur = np.zeros((n_ep, N_TIMES, 2))
    depth = np.zeros(n_ep)
    fc = m.forecast
    for e in range(n_ep):
        times[e], cur[e], depth[e] = centre_forecast(m.grid, tuple(W.region[e]),
                                                     float(m.t0[e]), P.t_lim, P.alt, fc, e)
    return ASBriefing(**common_brief(m), region=W.region.copy(),
                      long_axis=W.long_axis.copy(), max_altitude=P.alt_max,
                      half_angle_deg=float(m.tier["half_angle_deg"]), cell=P.cell,
                      coverage_threshold=P.thr,
                      start=np.ascontiguousarray(m.X0[:, :, :3], dtype=np.float64),
                      forecast_centre=cur, forecast_times=times, forecast_depth=depth,
                      survey_alt=P.alt, line_spacing=P.spacing, lines=W.lines.copy(),
                      line_count=W.lcount.copy())


@hot_kernel
def _mark(cov, e, x, z, r, x_lo, z_lo, cell, ncx, ncz):
    """Mark cells of episode ``e`` whose centre is within ``r`` of (x, z); returns new count."""
    new = 0
    ilo = int(math.ceil((x - r - x_lo) / cell - 0.5))
    ihi = int(math.floor((x + r - x_lo) / cell - 0.5))
    jlo = int(math.ceil((z - r - z_lo) / cell - 0.5))
    jhi = int(math.floor((z + r - z_lo) / cell - 0.5))
    if ilo < 0:
        ilo = 0
    if jlo < 0:
        jlo = 0
    if ihi > ncx - 1:
        ihi = ncx - 1
    if jhi > ncz - 1:
        jhi = ncz - 1
    r2 = r * r
    for j in range(jlo, jhi + 1):
        dz = z_lo + (j + 0.5) * cell - z
        for i in range(ilo, ihi + 1):
            dx = x_lo + (i + 0.5) * cell - x
            if dx * dx + dz * dz <= r2:
                k = j * ncx + i
                if cov[e, k] == 0:
                    cov[e, k] = 1
                    new += 1
    return new


@hot_kernel
def begin(ctx, e):
    """Clear the coverage map and the counters; every agent at the start of its lines.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``ctx.state`` holds the start.

    Returns
    -------
    bool
        False: the episode starts.
    """
    W = ctx.W
    for c in range(W.ncell[e, 0] * W.ncell[e, 1]):
        W.cov[e, c] = 0
    W.cnt[e, 0] = 0
    W.cnt[e, 1] = 0
    W.alt_sum[e] = 0.0
    for i in range(W.lidx.shape[1]):
        W.lidx[e, i] = 0
    return False


@hot_kernel
def cue(ctx, e, k, i):
    """The mission computer: the point of agent ``i``'s lines to make for.

    Env hook (:mod:`oneocean.tasks.loop`): the observation's cue. On the agent's navigation
    estimate ``X[e, i]``, agent ``i``'s place on its lines of the task's survey plan
    (``W.lidx``) advances (:func:`~oneocean.tasks.waypoints.waypoint_carrot`: the transit to the
    run-in ends within ``ARRIVE_M``, a leg ``CUE_TOL_M`` before its end); the cue is the
    run-in during the transit, then the point ``CUE_LOOK_M`` ahead on the current leg, then
    the last point, at the survey altitude ``P.alt`` above the seafloor there (at least
    ``MIN_DEPTH_M`` deep).

    Returns
    -------
    gx, gy, gz : float
        The cue, world m.
    probe : float
        NaN (the task has no field).
    """
    grid, P, W, X = ctx.grid, ctx.P, ctx.W, ctx.X
    gx, gz, w = waypoint_carrot(W.lines, W.lidx, W.lcount, e, i, X[e, i, 0], X[e, i, 2],
                                CUE_LOOK_M, CUE_TOL_M, ARRIVE_M)
    gy = -sample_elevation(grid, gx, gz) - P.alt
    if gy < MIN_DEPTH_M:
        gy = MIN_DEPTH_M
    return gx, gy, gz, math.nan


@hot_kernel
def after_agent(ctx, e, k, i):
    """Image the seafloor under agent ``i``'s new position.

    Env hook (:mod:`oneocean.tasks.loop`), right after the agent moved: its altitude is summed;
    below ``alt_max`` the cells within the footprint radius ``alt tan_h`` are marked covered;
    above it the agent-step counts as footprint loss.
    """
    grid, P, W, state = ctx.grid, ctx.P, ctx.W, ctx.state
    # the sensor images the seafloor under the agent's new position
    s = state[e, i]
    alt = -sample_elevation(grid, s[0], s[2]) - s[1]
    W.alt_sum[e] += alt
    if alt <= P.alt_max:
        if alt > 0.0:
            W.cnt[e, 0] += _mark(W.cov, e, s[0], s[2], alt * P.tan_h, W.region[e, 0],
                                 W.region[e, 1], P.cell, W.ncell[e, 0], W.ncell[e, 1])
    else:
        W.cnt[e, 1] += 1


@hot_kernel
def post_step(ctx, e, k):
    """The success check after the step.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``.

    Returns
    -------
    bool
        True (STOP) once the covered fraction reaches ``P.thr``.
    """
    P, W = ctx.P, ctx.W
    return W.cnt[e, 0] >= P.thr * (W.ncell[e, 0] * W.ncell[e, 1])


@hot_kernel
def finish(ctx, e, k):
    """Write the AS metrics.

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Returns
    -------
    bool
        Success: the covered fraction reached ``P.thr``.
    """
    P, W, state = ctx.P, ctx.W, ctx.state
    row = ctx.res[e]
    n_ag = state.shape[1]
    n_cells = W.ncell[e, 0] * W.ncell[e, 1]
    covered = W.cnt[e, 0]
    row[_C_COV] = covered / n_cells
    row[_C_LOSS] = W.cnt[e, 1] / (k * n_ag) if k > 0 else 0.0
    row[_C_ALT] = W.alt_sum[e] / (k * n_ag) if k > 0 else 0.0
    return covered >= P.thr * n_cells


fresh_cache(_episodes_kernel, __file__)
