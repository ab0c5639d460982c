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
Methods (task logic lives here, not in the environment)
    Lawnmower: strips at commanded altitude ``a_c = ALT_FRAC * max_altitude_m`` (so the
    footprint survives terrain-following errors), spacing at most ``2 a_c tan(half_angle)
    (1 - OVERLAP)`` spread evenly over the region's width; the strips are split into contiguous
    blocks, one per agent (boustrophedon inside a block); teammates closer than ``SEP_M``
    repel each other (their positions are observed). Strips are tracked with
    line-of-sight guidance (a carrot ``LOOKAHEAD_M`` ahead of the projection on the strip),
    terrain-following in depth (the carrot's depth is the seafloor depth there minus ``a_c``),
    crabbing against the current (:func:`~oneocean.tasks.common.seek_max`: the cross-track
    current is cancelled first).
    ``heuristic``: strips along the region's long axis (fewest turns), speed budget
    ``CRUISE_FRAC * v_max`` through the water, feed-forward of the NOISY probed current
    (std ``probe_noise_ms``). ``oracle``: exact current, full ``v_max``, a higher altitude
    (``ALT_FRAC_ORACLE``) and less overlap (``OVERLAP_ORACLE``: wider strips), and it orients
    the strips across the current (it predicts the scan time of both orientations from the
    true currents over the episode and takes the faster one).

Default team size: N = 1, as in the paper's Table V (so SRs are comparable); any N in
[1, 10] runs, with the strips divided between agents.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..engine import dynamics as dyn
from ..engine._jit import hot_kernel
from ..engine.constraints import DEFAULT_LAND_THRESHOLD, min_pairwise_distance, spawn_positions
from ..engine.grid import sample_elevation, sample_elevation_points
from ..errors import ConfigError
from .common import (HEURISTIC, OK, STANDARD, advance_agent, current_at, episode_generators,
                     fresh_cache, method_id, need_tier, obs_buffers, observe, rollout_results,
                     seek_max, sensed_current, set_velocity_cmd, start_times, waypoint_carrot)

TASK_ID = "AS"
METRICS = ("coverage_fraction", "footprint_loss_frac", "mean_altitude_m")
COLUMNS = STANDARD + METRICS

#: Heuristic speed budget through the water as a fraction of v_max.
CRUISE_FRAC = 0.75
#: Commanded altitude as a fraction of the sensor's maximum altitude (heuristic, oracle):
#: the oracle's exact terrain-following and current knowledge let it fly closer to the limit.
ALT_FRAC = 0.6
ALT_FRAC_ORACLE = 0.75
#: Swath overlap between neighbouring strips (fraction of the swath width; heuristic, oracle).
OVERLAP = 0.2
OVERLAP_ORACLE = 0.1
#: Line-of-sight lookahead along the strip, m.
LOOKAHEAD_M = 12.0
#: Proportional gain of point approaches (transit to the first strip), s-1.
KP = 0.5
#: A strip waypoint counts as reached this far (m) before its along-track end.
WP_TOL_M = 1.0
#: Shallowest commanded depth, m (stay submerged).
MIN_DEPTH_M = 1.0
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
#: Near-collision distance for coll_ratio, m.
R_COLL_M = 2.0
#: Teammate avoidance: repulsion inside SEP_M (m), up to K_REP_MS (m s-1) at contact.
SEP_M = 6.0
K_REP_MS = 1.0

_TIER_KEYS = ("current_gain", "time_limit_s", "probe_noise_ms", "region_long_m",
              "region_short_m", "coverage_threshold", "max_altitude_m", "half_angle_deg",
              "cell_m", "seafloor_min_m", "seafloor_max_m", "min_relief_m")

_I_MODEL, _I_METHOD, _I_STEPS, _I_SEED, _I_NAG = range(5)
(_F_DT, _F_VMAX, _F_SPEED, _F_KP, _F_NOISE, _F_LAND, _F_CLEAR, _F_ALT_C, _F_ALT_MAX,
 _F_TAN, _F_CELL, _F_THR, _F_LOOK) = range(13)
_C = {k: i for i, k in enumerate(COLUMNS)}
_C_SUCCESS, _C_T, _C_E, _C_COLL, _C_VIOL = (_C[k] for k in STANDARD)
_C_COV, _C_LOSS, _C_ALT = (_C[k] for k in METRICS)


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
    """Draw a valid scan region: ``(x_lo, z_lo, x_hi, z_hi, long_axis)``.

    ``long_axis`` is 0 when the long side runs along x (east), 1 along z (north).

    Raises
    ------
    ConfigError
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
    raise ConfigError(
        f"{what}: no {L:g} x {W:g} m region with seafloor depth in "
        f"[{tier['seafloor_min_m']:g}, {tier['seafloor_max_m']:g}] m and relief >= "
        f"{tier['min_relief_m']:g} m found in {tries} tries; the grid has no such shelf")


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the scan region, start positions and start time of every episode.

    Returns
    -------
    dict
        ``region`` (E, 4) ``[x_lo, z_lo, x_hi, z_hi]`` m; ``long_axis`` (E,) int64 (0 = x);
        ``pos0`` (E, N, 3) start positions, m; ``t0`` (E,) start times, s.

    Raises
    ------
    ConfigError
        Team size outside [1, 10], missing tier keys, or no valid geometry for some episode.
    """
    n_agents = int(n_agents)
    if not 1 <= n_agents <= 10:
        raise ConfigError(f"task {TASK_ID}: n_agents must be in [1, 10], got {n_agents}")
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    rngs = episode_generators(seed, n_episodes)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    region = np.empty((n_episodes, 4))
    axis = np.empty(n_episodes, dtype=np.int64)
    pos0 = np.empty((n_episodes, n_agents, 3))
    for e, rng in enumerate(rngs):
        what = f"task {TASK_ID} reset (episode {e})"
        *box, ax = sample_region(grid, rng, tier, what=what)
        region[e] = box
        axis[e] = ax
        spawn = {"x": (box[0], box[0] + SPAWN_BOX_M), "z": (box[1], box[1] + SPAWN_BOX_M),
                 "altitude": SPAWN_ALTITUDE_M}
        pos0[e] = spawn_positions(grid, rng, n_agents, spawn, clearance=CLEARANCE_M,
                                  min_separation=SPAWN_SEPARATION_M)
    return {"region": region, "long_axis": axis, "pos0": pos0, "t0": t0}


# ------------------------------------------------------------------------------ planning

def method_altitude(tier: dict, mid: int) -> float:
    """Commanded altitude above the seafloor (m) of method ``mid``."""
    return (ALT_FRAC if mid == HEURISTIC else ALT_FRAC_ORACLE) * float(tier["max_altitude_m"])


def strip_spacing(tier: dict, mid: int) -> float:
    """Lawnmower strip spacing (m) of method ``mid`` at its commanded altitude."""
    overlap = OVERLAP if mid == HEURISTIC else OVERLAP_ORACLE
    return (2.0 * method_altitude(tier, mid)
            * math.tan(math.radians(float(tier["half_angle_deg"]))) * (1.0 - overlap))


def plan_lawnmower(box, axis: int, spacing: float, n_agents: int):
    """Boustrophedon waypoints (x, z) per agent over ``box``, strips along ``axis``.

    ``n = max(ceil(W / spacing), n_agents)`` strips (every agent gets at least one; a large
    team flies narrower, overlapping strips rather than idling or crowding) at offsets
    ``(k + 1/2) W / n``, split into contiguous blocks, one per agent; every block starts at
    the strips' low end.

    Returns
    -------
    wps : (n_agents, n_max, 2) float64, m
        Waypoints; agent ``i`` uses ``wps[i, :count[i]]`` (start and end of each strip).
    count : (n_agents,) int64
    """
    x_lo, z_lo, x_hi, z_hi = box
    if axis == 0:  # strips along x, offsets along z
        a_lo, a_hi, b_lo, b_hi = x_lo, x_hi, z_lo, z_hi
    else:
        a_lo, a_hi, b_lo, b_hi = z_lo, z_hi, x_lo, x_hi
    width = b_hi - b_lo
    n_strips = max(1, int(math.ceil(width / spacing - 1e-9)), int(n_agents))
    offs = b_lo + (np.arange(n_strips) + 0.5) * width / n_strips
    blocks = np.array_split(np.arange(n_strips), n_agents)
    n_max = 2 * max(len(b) for b in blocks)
    wps = np.zeros((n_agents, n_max, 2))
    count = np.zeros(n_agents, dtype=np.int64)
    for i, blk in enumerate(blocks):
        k = 0
        for j, s in enumerate(blk):
            ends = (a_lo, a_hi) if j % 2 == 0 else (a_hi, a_lo)
            for a in ends:
                wps[i, k] = (a, offs[s]) if axis == 0 else (offs[s], a)
                k += 1
        count[i] = k
    return wps, count


def _along_speed(ce: float, cn: float, ux: float, uz: float, v: float) -> float:
    """Largest ground speed along unit (ux, uz) with |a| <= v through current (ce, cn)."""
    c_par = ce * ux + cn * uz
    q2 = ce * ce + cn * cn - c_par * c_par
    if q2 >= v * v:
        return 0.0
    return max(0.0, c_par + math.sqrt(v * v - q2))


def oracle_axis(grid, box, depth: float, t0: float, duration: float, v: float,
                spacing: float = 20.0, n_times: int = 7) -> int:
    """Strip orientation (0 = along x) with the shorter predicted scan under the true currents.

    A scan along an axis has ``n = ceil(W / spacing)`` strips of length ``L`` flown
    alternately each way and ``n - 1`` cross legs of ``spacing``; each leg's time uses the
    fastest ground speed along it through the current (:func:`_along_speed`), averaged over
    ``n_times`` times of the episode at the region's centre.
    """
    from ..engine.grid import sample_currents

    x_lo, z_lo, x_hi, z_hi = box
    cx, cz = 0.5 * (x_lo + x_hi), 0.5 * (z_lo + z_hi)
    ts = t0 + np.linspace(0.0, duration, n_times)
    xyz = np.tile([cx, depth, cz], (n_times, 1))
    cur = sample_currents(grid, xyz, ts)
    cost = []
    for axis, (L, W) in enumerate(((x_hi - x_lo, z_hi - z_lo), (z_hi - z_lo, x_hi - x_lo))):
        ux, uz = (1.0, 0.0) if axis == 0 else (0.0, 1.0)
        n = max(1, int(math.ceil(W / spacing - 1e-9)))
        tot = 0.0
        for ce, cn in cur:
            strips = 0.5 * L * (1.0 / max(_along_speed(ce, cn, ux, uz, v), 1e-3)
                                + 1.0 / max(_along_speed(ce, cn, -ux, -uz, v), 1e-3))
            cross = W / n / max(_along_speed(ce, cn, uz, ux, v), 1e-3)
            tot += n * strips + (n - 1) * cross
        cost.append(tot)
    return int(np.argmin(cost))


# ------------------------------------------------------------------------------ kernels

@hot_kernel(inline="always")
def _repulsion(state, e, i, n_ag):
    """Horizontal velocity (m s-1) pushing agent ``i`` away from teammates closer than
    ``SEP_M``: ``K_REP_MS (SEP_M - d) / SEP_M`` per teammate, along the separation."""
    rx = 0.0
    rz = 0.0
    px = state[e, i, 0]
    pz = state[e, i, 2]
    for j in range(n_ag):
        if j == i:
            continue
        dx = px - state[e, j, 0]
        dz = pz - state[e, j, 2]
        d = math.sqrt(dx * dx + dz * dz)
        if d < SEP_M and d > 1e-9:
            f = K_REP_MS * (SEP_M - d) / (SEP_M * d)
            rx += dx * f
            rz += dz * f
    return rx, rz


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


@hot_kernel
def _episode(grid, vp, ipar, fpar, region, ncell, wps, wcount, t0, state, cmd, widx, cov,
             obs, act, res, e):
    """Run episode ``e`` (serial) and write row ``e`` of ``res`` (see ``COLUMNS``)."""
    model = ipar[_I_MODEL]
    method = ipar[_I_METHOD]
    n_steps = ipar[_I_STEPS]
    seed = ipar[_I_SEED]
    n_ag = ipar[_I_NAG]
    dt = fpar[_F_DT]
    v_max = fpar[_F_VMAX]
    speed = fpar[_F_SPEED]
    kp = fpar[_F_KP]
    noise = fpar[_F_NOISE]
    land_thr = fpar[_F_LAND]
    clearance = fpar[_F_CLEAR]
    alt_c = fpar[_F_ALT_C]
    alt_max = fpar[_F_ALT_MAX]
    tan_h = fpar[_F_TAN]
    cell = fpar[_F_CELL]
    thr = fpar[_F_THR]
    look = fpar[_F_LOOK]
    x_lo = region[e, 0]
    z_lo = region[e, 1]
    ncx = ncell[e, 0]
    ncz = ncell[e, 1]
    n_cells = ncx * ncz
    need = thr * n_cells
    for k in range(n_cells):
        cov[e, k] = 0
    for i in range(n_ag):
        widx[e, i] = 0
    covered = 0
    energy = 0.0
    viol = 0
    n_coll = 0
    n_loss = 0
    alt_sum = 0.0
    success = False
    t_s = 0.0
    k = 0
    while k < n_steps and not success:
        t = t0[e] + k * dt
        for i in range(n_ag):
            s = state[e, i]
            c = cmd[e, i]
            px = s[0]
            py = s[1]
            pz = s[2]
            ce, cn = current_at(grid, px, py, pz, t)
            fe, fn = sensed_current(method, ce, cn, noise, seed, e, 2 * (k * n_ag + i))
            budget = speed if method == HEURISTIC else v_max
            gx, gz, w = waypoint_carrot(wps, widx, wcount, e, i, px, pz, look, WP_TOL_M)
            # terrain following: the carrot's depth is the seafloor there minus a_c
            gy = -sample_elevation(grid, gx, gz) - alt_c
            if gy < MIN_DEPTH_M:
                gy = MIN_DEPTH_M
            ax, ay, az = seek_max(px, py, pz, gx, gy, gz, budget, kp, fe, fn)
            if n_ag > 1:  # keep clear of teammates (their positions are observed)
                rx, rz = _repulsion(state, e, i, n_ag)
                ax += rx
                az += rz
            observe(obs, act, e, k, i, grid, state, gx, gy, gz, fe, fn, math.nan, ax, ay, az)
            set_velocity_cmd(c, ax, ay, az)
            en, code = advance_agent(grid, model, vp, s, c, ce, cn, v_max, dt, land_thr,
                                     clearance)
            energy += en
            if code != OK:
                viol += 1
            alt = -sample_elevation(grid, s[0], s[2]) - s[1]
            alt_sum += alt
            if alt <= alt_max:
                if alt > 0.0:
                    covered += _mark(cov, e, s[0], s[2], alt * tan_h, x_lo, z_lo, cell, ncx,
                                     ncz)
            else:
                n_loss += 1
        if n_ag > 1 and min_pairwise_distance(state[e]) <= R_COLL_M:
            n_coll += 1
        k += 1
        if covered >= need:
            success = True
            t_s = k * dt
    res[e, _C_SUCCESS] = 1.0 if success else 0.0
    res[e, _C_T] = t_s if success else n_steps * dt
    res[e, _C_E] = energy
    res[e, _C_COLL] = n_coll / k if (n_ag > 1 and k > 0) else 0.0
    res[e, _C_VIOL] = viol
    res[e, _C_COV] = covered / n_cells
    res[e, _C_LOSS] = n_loss / (k * n_ag) if k > 0 else 0.0
    res[e, _C_ALT] = alt_sum / (k * n_ag) if k > 0 else 0.0


@njit(parallel=True, cache=True)
def _kernel(grid, vp, ipar, fpar, region, ncell, wps, wcount, t0, state, cmd, widx, cov, obs,
            act, res):
    for e in prange(res.shape[0]):
        _episode(grid, vp, ipar, fpar, region, ncell, wps, wcount, t0, state, cmd, widx, cov,
                 obs, act, res, e)


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
        Run seed (probe-noise streams).

    Returns
    -------
    dict of (E,) arrays
        ``success`` (bool), ``T_s`` (s), ``E`` (m2 s-1), ``coll_ratio``, ``violations`` (int)
        and ``METRICS``.
    """
    need_tier(TASK_ID, tier, *_TIER_KEYS, "dt_s")
    mid = method_id(method)
    dt = float(tier["dt_s"])
    region = np.ascontiguousarray(init["region"], dtype=np.float64)
    n_ep = region.shape[0]
    pos0 = np.ascontiguousarray(init["pos0"], dtype=np.float64)
    n_ag = pos0.shape[1]
    v_max = float(vehicle.v_max)
    t_lim = float(tier["time_limit_s"])
    alt_c = method_altitude(tier, mid)
    spacing = strip_spacing(tier, mid)
    cell = float(tier["cell_m"])
    ncell = np.empty((n_ep, 2), dtype=np.int64)
    ncell[:, 0] = np.maximum(1, np.round((region[:, 2] - region[:, 0]) / cell)).astype(np.int64)
    ncell[:, 1] = np.maximum(1, np.round((region[:, 3] - region[:, 1]) / cell)).astype(np.int64)
    plans = []
    for e in range(n_ep):
        box = tuple(region[e])
        if mid == HEURISTIC:
            axis = int(init["long_axis"][e])
        else:
            depth = float(-sample_elevation_points(
                grid, np.array([[0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])]]),
                np.empty(1))[0]) - alt_c
            axis = oracle_axis(grid, box, max(depth, MIN_DEPTH_M), float(init["t0"][e]), t_lim,
                               v_max, spacing)
        plans.append(plan_lawnmower(box, axis, spacing, n_ag))
    n_max = max(p[0].shape[1] for p in plans)
    wps = np.zeros((n_ep, n_ag, n_max, 2))
    wcount = np.zeros((n_ep, n_ag), dtype=np.int64)
    for e, (w, cnt) in enumerate(plans):
        wps[e, :, :w.shape[1]] = w
        wcount[e] = cnt
    ipar = np.array([dyn.model_id(dyn_name), mid, int(math.ceil(t_lim / dt - 1e-9)), int(seed),
                     n_ag], dtype=np.int64)
    fpar = np.array([dt, v_max, CRUISE_FRAC * v_max, KP, float(tier["probe_noise_ms"]),
                     DEFAULT_LAND_THRESHOLD, CLEARANCE_M, alt_c, float(tier["max_altitude_m"]),
                     math.tan(math.radians(float(tier["half_angle_deg"]))), cell,
                     float(tier["coverage_threshold"]), LOOKAHEAD_M])
    state = dyn.new_state(n_ep, n_ag, pos0)
    cmd = np.zeros((n_ep, n_ag, dyn.CMD_DIM))
    widx = np.zeros((n_ep, n_ag), dtype=np.int64)
    cov = np.zeros((n_ep, int((ncell[:, 0] * ncell[:, 1]).max())), dtype=np.uint8)
    res = np.zeros((n_ep, len(COLUMNS)))
    obs, act = obs_buffers(tier, init, record)
    _kernel(grid, vehicle.params, ipar, fpar, region, ncell, wps, wcount,
            np.ascontiguousarray(init["t0"], dtype=np.float64), state, cmd, widx, cov, obs, act,
            res)
    return rollout_results(res, COLUMNS, obs, act, record)


# numba keys a cache entry on this file only; drop it when the engine or the task layer
# changes.
fresh_cache(_kernel, __file__)
