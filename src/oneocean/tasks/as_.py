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
Methods
    :mod:`oneocean.methods.heuristic.as_` (a lawnmower: strips at a commanded altitude,
    terrain following, current feed-forward, full speed; one policy for the heuristic and the
    oracle, which differ in information only). The strips are flown on the method's
    navigation estimate while the sensor images the true seafloor, so the heuristic's
    dead-reckoning drift (no navigation aid: a 0.5 m start fix, then ~0.9 % of the
    displacement) opens holidays at the region's edges; its planner extends the region by the
    margins its navigation error needs, as wide as the time limit allows, and orients the
    strips by the scan time predicted on its forecast of the currents (the oracle: the true
    currents, zero margins). Its
    plan (the waypoint lists per agent) is made in Python before the episode's first step and
    kept in ``W`` (``wps``, ``wcount``, ``widx``: the plan tokens); the observation's goal cue
    is the carrot the method follows (``W.tgt``).

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset`` (Python: region, starts and start times per episode);
    ``ASParams`` / ``ASWork`` and ``make`` (the env's typed scalars and per-episode arrays:
    coverage map, counters, plan tokens); the env hooks ``begin``, ``cue``, ``after_agent``
    (altitude, footprint, coverage after every agent's move), ``post_step`` (success),
    ``finish`` (``hot_kernel``, no allocation). The plan tokens hold
    ``tokens["max_waypoints"]`` waypoints per agent (the policy's ``plan_tokens``); the
    policy's Python planner ``prepare`` writes them before the first segment
    (:class:`~oneocean.tasks.episodes.Episodes` calls it); the compiled loop is
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
from .common import (PURPOSE_RESET, STANDARD, _call, fresh_cache, need_tier, need_tokens,
                     _spawn_altitude, start_times)

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


@hot_kernel(inline="always")
def _arange_at(start, step, i):
    """Entry ``i`` of ``np.arange(start, stop, step)`` (float64): ``start``, ``start + step``,
    then ``start + i * delta`` with ``delta`` the difference of those two (NumPy's fill)."""
    if i == 0:
        return start
    second = start + step
    if i == 1:
        return second
    return start + i * (second - start)


@hot_kernel(inline="always")
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

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    tier : dict
        Tier parameters (``data/tasks/AS.yaml``) plus ``dt_s``.
    n_agents : int
        Team size N, 1..10.
    n_episodes : int
        Number of episodes E.
    seed : int
        Run seed (each episode draws from its own reset stream).

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
        Time limit, s (the planner's horizon).
    """
    alt_max: float          # sensor's maximum altitude (bottom lock), m
    tan_h: float            # tan(half_angle): footprint radius per metre of altitude
    cell: float             # coverage cell side, m
    thr: float              # coverage fraction of success
    t_lim: float            # time limit, s (the planner's horizon)


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
    wps : (E, N, n_max, 2) float64
        Plan tokens (the method's, written by its ``prepare``; read by the cue): lawnmower
        waypoints (x, z) per agent, m.
    wcount : (E, N) int64
        Waypoints of each agent.
    widx : (E, N) int64
        Current waypoint of each agent.
    tgt : (E, N, 3) float64
        The carrot each agent follows (the goal cue), m; NaN until the method writes it.
    planned : (E,) int64
        1 once the plan tokens are written.
    """
    region: np.ndarray      # (E, 4) [x_lo, z_lo, x_hi, z_hi], m
    long_axis: np.ndarray   # (E,) int64, 0 = the long side runs along x
    ncell: np.ndarray       # (E, 2) int64 coverage cells along x, z
    cov: np.ndarray         # (E, max cells) uint8 coverage map (row-major, z rows)
    cnt: np.ndarray         # (E, 2) int64 covered cells, agent-steps above alt_max
    alt_sum: np.ndarray     # (E,) sum of altitudes over agent-steps, m
    # plan tokens (the method's, written by its prepare; read by the cue)
    wps: np.ndarray         # (E, N, n_max, 2) lawnmower waypoints (x, z) per agent, m
    wcount: np.ndarray      # (E, N) int64 waypoints of each agent
    widx: np.ndarray        # (E, N) int64 current waypoint of each agent
    tgt: np.ndarray         # (E, N, 3) the carrot each agent follows (goal cue), m
    planned: np.ndarray     # (E,) int64 1 once the plan tokens are written


def make(grid, tier: dict, init: dict, tokens: dict | None = None):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    The plan tokens (the waypoints of every agent's plan, filled by the policy's
    ``prepare``) hold ``tokens["max_waypoints"]`` per agent.

    Parameters
    ----------
    grid : Grid
        The rollout's grid export (the ablations' forcing included).
    tier : dict
        Tier parameters plus ``dt_s``.
    init : dict
        The reset's dict (:func:`reset`).
    tokens : dict
        The policy's plan tokens (``plan_tokens``); ``max_waypoints``: waypoints per agent.

    Returns
    -------
    P : ASParams
        The env's typed scalars.
    W : ASWork
        The env's per-episode work arrays.

    Raises
    ------
    ConfigError
        Missing tier parameters or plan tokens.
    """
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    tokens = need_tokens(TASK_ID, tokens, "max_waypoints")
    region = np.ascontiguousarray(init["region"], dtype=np.float64)
    n_ep = region.shape[0]
    n_ag = init["pos0"].shape[1]
    cell = float(tier["cell_m"])
    ncell = np.empty((n_ep, 2), dtype=np.int64)
    ncell[:, 0] = np.maximum(1, np.round((region[:, 2] - region[:, 0]) / cell)).astype(np.int64)
    ncell[:, 1] = np.maximum(1, np.round((region[:, 3] - region[:, 1]) / cell)).astype(np.int64)
    n_cells = int((ncell[:, 0] * ncell[:, 1]).max()) if n_ep else 1
    n_max = int(tokens["max_waypoints"])
    P = ASParams(float(tier["max_altitude_m"]),
                 math.tan(math.radians(float(tier["half_angle_deg"]))), cell,
                 float(tier["coverage_threshold"]), float(tier["time_limit_s"]))
    W = ASWork(region, np.ascontiguousarray(init["long_axis"], dtype=np.int64), ncell,
               np.zeros((n_ep, n_cells), dtype=np.uint8), np.zeros((n_ep, 2), dtype=np.int64),
               np.zeros(n_ep), np.zeros((n_ep, n_ag, n_max, 2)),
               np.zeros((n_ep, n_ag), dtype=np.int64), np.zeros((n_ep, n_ag), dtype=np.int64),
               np.full((n_ep, n_ag, 3), np.nan), np.zeros(n_ep, dtype=np.int64))
    return P, W


@hot_kernel(inline="always")
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


@hot_kernel(inline="always")
def begin(grid, P, W, state, e):
    """Clear the coverage map and the counters.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``state`` holds the start.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : ASParams
        The task's params (:func:`make`).
    W : ASWork
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
    for c in range(W.ncell[e, 0] * W.ncell[e, 1]):
        W.cov[e, c] = 0
    W.cnt[e, 0] = 0
    W.cnt[e, 1] = 0
    W.alt_sum[e] = 0.0
    return False


@hot_kernel(inline="always")
def cue(grid, P, W, state, e, k, i):
    """The goal cue: the carrot the method follows (``W.tgt``).

    Env hook (:mod:`oneocean.tasks.loop`): the observation's goal cue and probe.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : ASParams
        The task's params (:func:`make`).
    W : ASWork
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
    g = W.tgt[e, i]
    return g[0], g[1], g[2], math.nan


@hot_kernel(inline="always")
def after_agent(grid, P, W, state, e, k, i, code):
    """Image the seafloor under agent ``i``'s new position.

    Env hook (:mod:`oneocean.tasks.loop`), right after the agent moved: its altitude is summed;
    below ``alt_max`` the cells within the footprint radius ``alt tan_h`` are marked covered;
    above it the agent-step counts as footprint loss.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : ASParams
        The task's params (:func:`make`).
    W : ASWork
        The task's per-episode work arrays (:func:`make`).
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    e : int
        Episode index.
    k : int
        Step index.
    i : int
        Agent index.
    code : int
        Status of the agent's move (:mod:`oneocean.engine.status`).
    """
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


@hot_kernel(inline="always")
def post_step(grid, P, W, state, prev, e, k, t):
    """The success check after the step.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : ASParams
        The task's params (:func:`make`).
    W : ASWork
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
        True (STOP) once the covered fraction reaches ``P.thr``.
    """
    return W.cnt[e, 0] >= P.thr * (W.ncell[e, 0] * W.ncell[e, 1])


@hot_kernel(inline="always")
def finish(grid, P, W, state, e, k, row):
    """Write the AS metrics.

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : ASParams
        The task's params (:func:`make`).
    W : ASWork
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
        Success: the covered fraction reached ``P.thr``.
    """
    n_ag = state.shape[1]
    n_cells = W.ncell[e, 0] * W.ncell[e, 1]
    covered = W.cnt[e, 0]
    row[_C_COV] = covered / n_cells
    row[_C_LOSS] = W.cnt[e, 1] / (k * n_ag) if k > 0 else 0.0
    row[_C_ALT] = W.alt_sum[e] / (k * n_ag) if k > 0 else 0.0
    return covered >= P.thr * n_cells


fresh_cache(_episodes_kernel, __file__)
