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
    surface current over the episode (:func:`site_drift`, the tier's forcing) is at least
    ``min_drift_ms``: harder tiers are spills in moving water (a spill in slack water is no
    response challenge); the currents-off ablation replays the same sites.
Physics (identical for every method)
    Each step every vehicle moves (:func:`~oneocean.tasks.common.advance_agent`), then removes
    the fraction ``removal_rate_s * dt`` of the concentration of every field cell whose centre
    is within ``removal_radius_m`` of it (:func:`~oneocean.models.pollution.remove_in_radius`,
    in agent order), then the field advances by ``dt``.
Success
    ``removed >= target_fraction * initial mass`` (team total), checked after every step; the
    episode stops there. Mass budget: removed + escaped + remaining = initial (round-off).
Metrics
    ``cleanup_rate`` (primary: removed / initial mass at the end), ``escaped_fraction``
    (left the local grid / initial), ``remaining_fraction`` (still on the grid / initial),
    ``time_to_target_s`` (time at which the target fraction was reached; the time limit on
    failure, like ``T_s``).
Methods (one fixed task logic)
    Targets come from a coarse "aerial" map: the field summed over blocks of
    ``BLOCK_CELLS x BLOCK_CELLS`` cells (mass and mass centroid per block). Justification: oil
    spill response relies on periodic surveillance overflights (aircraft / drone SLAR, IR);
    a surface vehicle's own sensor only sees the concentration under it. Assignment (greedy,
    distinct targets first): N times, take the block with the largest ``mass / (1 + number of
    agents already on it)`` and give it to the nearest unassigned agent; its target is the
    block's mass centroid. Between maps each agent moves its target with the current it
    probes (the spill drifts with the water). Steering: through-water velocity
    ``KP * (target - position)`` capped at the speed budget, plus a teammate repulsion inside
    ``SEP_M`` (keeps >= 3 m apart), realised against the (probed) current by
    :func:`~oneocean.tasks.common.steer`; depth held at ``SURFACE_Y_M``.
    ``heuristic``: knows only the spill's reported initial centroid until the first overflight
    (targets on a ring of radius ``spill_radius_m / 2`` around the report), then gets the
    aerial map every ``aerial_period_s``; NOISY probed current (std ``probe_noise_ms``);
    budget ``CRUISE_FRAC * v_max``.
    ``oracle``: the exact map every step, exact current, full ``v_max``.

Module layout: as :mod:`oneocean.tasks.g2g` (``reset`` / ``_episode`` / ``_kernel`` /
``rollout``); the per-episode field, land mask, face velocities, map and work vectors are
allocated in ``rollout`` with a leading episode axis.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..engine import status as st
from ..engine.constraints import (DEFAULT_LAND_THRESHOLD, feasibility, min_pairwise_distance,
                                  spawn_positions)
from ..engine.dynamics import CMD_DIM, model_id, new_state
from ..engine.grid import sample_current_data, sample_currents
from ..engine._jit import hot_kernel
from ..errors import ConfigError
from ..models import pollution as pol
from .common import (HEURISTIC, OK, STANDARD, advance_agent, current_at, episode_generators,
                     episode_steps, fresh_cache, method_id, need_tier, obs_buffers, observe,
                     path_clear, rollout_results, sensed_current, set_velocity_cmd, start_times,
                     steer)

TASK_ID = "SPC"
METRICS = ("cleanup_rate", "escaped_fraction", "remaining_fraction", "time_to_target_s")
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
#: Aerial-map block size, cells (BLOCK_CELLS * FIELD_H_M = 40 m blocks).
BLOCK_CELLS = 4
#: Heuristic throttle cap (fraction of v_max), as every task's heuristic.
CRUISE_FRAC = 0.6
#: Target-approach gain, s-1; depth-hold gain, s-1.
KP = 0.5
KP_DEPTH = 0.5
#: Teammate repulsion: active below SEP_M, speed SEP_GAIN * (SEP_M - d) (m s-1).
SEP_M = 4.5
SEP_GAIN = 1.0
#: Staging cluster spacing, m.
STAGING_SPACING_M = 6.0
#: The staging point's bearing from the spill is up-current (opposite the data surface current
#: at the spill centre at t0, current gain and tides ignored) +- this spread, rad.
STAGING_SPREAD_RAD = math.pi / 4
#: The spill centre must have surface-feasible water on rings up to this many spill radii.
CLEAR_RADII = 1.5
#: Blocks lighter than this fraction of the mapped mass are not targets.
MIN_BLOCK_FRAC = 1e-4

_I_MODEL, _I_METHOD, _I_STEPS, _I_SEED, _I_AERIAL, _I_REFRESH, _I_BLOCK = range(7)
(_F_DT, _F_VMAX, _F_SPEED, _F_KP, _F_NOISE, _F_LAND, _F_CLEAR, _F_H, _F_KAPPA, _F_RAD,
 _F_EFF, _F_TARGET, _F_Y, _F_KPY, _F_SEP, _F_SEPG, _F_RCOLL, _F_RING) = range(18)
_C = {k: i for i, k in enumerate(COLUMNS)}
_C_SUCCESS, _C_T, _C_E, _C_COLL, _C_VIOL = (_C[k] for k in STANDARD)
_C_CLEAN, _C_ESC, _C_REM, _C_TTT = (_C[k] for k in METRICS)

_TIER_KEYS = ("current_gain", "time_limit_s", "probe_noise_ms", "spill_radius_m",
              "target_fraction", "staging_distance_m", "removal_radius_m", "removal_rate_s",
              "kappa_m2s", "domain_m", "aerial_period_s", "min_drift_ms")
#: Near-collision radius, m (task contract).
R_COLL_M = 2.0


def staging_offsets(n: int) -> np.ndarray:
    """Start offsets of ``n`` agents around the staging point: a square lattice, (n, 2) m."""
    cols = int(math.ceil(math.sqrt(n)))
    k = np.arange(n)
    off = np.stack([(k % cols) - 0.5 * (cols - 1), (k // cols) - 0.5 * ((n - 1) // cols)], 1)
    return STAGING_SPACING_M * off.astype(float)


def _surface_ok(grid, xz) -> np.ndarray:
    xyz = np.stack([xz[:, 0], np.full(len(xz), SURFACE_Y_M), xz[:, 1]], axis=1)
    return feasibility(grid, xyz, DEFAULT_LAND_THRESHOLD, CLEARANCE_M) == st.OK


def field_frame(domain_m: float) -> tuple[int, float]:
    """Cells per side and half-width (centre of cell 0 relative to the spill centre), m."""
    n = max(8, int(round(float(domain_m) / FIELD_H_M)))
    return n, 0.5 * (n - 1) * FIELD_H_M


def site_drift(grid, c, t0: float, duration: float, n_times: int = 3) -> float:
    """Mean surface current speed (m s-1) at spill centre ``c`` (x, y, z) over the episode:
    the tier's forcing (gain, product tides, synthetic tide) at ``n_times`` instants."""
    ts = t0 + np.linspace(0.0, duration, n_times)
    xyz = np.tile([c[0], SURFACE_Y_M, c[2]], (n_times, 1))
    cur = sample_currents(grid, xyz, ts)
    return float(np.hypot(cur[:, 0], cur[:, 1]).mean())


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the spill, its local field, the staging point and the start time per episode.

    Parameters
    ----------
    grid : Grid
    tier : dict
        Tier parameters (see ``data/tasks/SPC.yaml``) plus ``dt_s``.
    n_agents : int
        Team size, 2..10.
    n_episodes, seed : int

    Returns
    -------
    dict
        ``pos0`` (E, N, 3) starts, m; ``psi0`` (E, N) headings toward the spill, rad;
        ``t0`` (E,) start times, s; ``C0`` (E, 1, n, n) initial field, kg m-2;
        ``land`` (E, n, n) uint8 frozen cells; ``origin`` (E, 2) world (x, z) of cell (0, 0)
        centre, m; ``report`` (E, 2) initial spill centroid (x, z), m.

    Raises
    ------
    ConfigError
        Team size outside 2..10, missing tier keys, or no valid spill/staging geometry.
    """
    n_agents = int(n_agents)
    if not 2 <= n_agents <= 10:
        raise ConfigError(f"task {TASK_ID}: n_agents must be in [2, 10], got {n_agents}")
    need_tier(TASK_ID, tier, *_TIER_KEYS)
    R = float(tier["spill_radius_m"])
    dist = float(tier["staging_distance_m"])
    min_drift = float(tier["min_drift_ms"])
    T = float(tier["time_limit_s"])
    n, half = field_frame(float(tier["domain_m"]))
    if 2.0 * R > half:
        raise ConfigError(f"task {TASK_ID}: spill_radius_m={R:g} too large for domain_m="
                          f"{tier['domain_m']}")
    rngs = episode_generators(seed, n_episodes)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    off = staging_offsets(n_agents)
    ang = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    rings = np.concatenate([[[0.0, 0.0]]] + [r * np.stack([np.sin(ang), np.cos(ang)], 1)
                                             for r in np.linspace(0.5, CLEAR_RADII, 3) * R])
    pos0 = np.empty((n_episodes, n_agents, 3))
    C0 = np.empty((n_episodes, 1, n, n))
    land = np.empty((n_episodes, n, n), dtype=np.uint8)
    origin = np.empty((n_episodes, 2))
    report = np.empty((n_episodes, 2))
    ci = np.arange(n) * FIELD_H_M
    # the mean data current (gain and tides dropped: same geometry with currents off)
    raw = grid._replace(gain=1.0, tide_layers=0)
    for e, rng in enumerate(rngs):
        found = False
        for _ in range(1000):
            try:
                c = spawn_positions(grid, rng, 1, {"y": (SURFACE_Y_M, SURFACE_Y_M)},
                                    land_threshold=DEFAULT_LAND_THRESHOLD,
                                    clearance=CLEARANCE_M, max_candidates=4096)[0]
            except ConfigError as exc:
                raise ConfigError(f"task {TASK_ID} reset (episode {e}): {exc}") from None
            cxz = np.array([c[0], c[2]])
            if not _surface_ok(grid, cxz + rings).all():
                continue
            # the response base lies up-current of the spill: the slick drifts away from it
            if min_drift > 0.0 and not site_drift(grid, c, t0[e], T) >= min_drift:
                continue  # (also rejects NaN)
            ue, un = sample_current_data(raw, c[0], SURFACE_Y_M, c[2], t0[e])
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
            if not path_clear(grid, p_s, c, CLEARANCE_M, DEFAULT_LAND_THRESHOLD, spacing_m=10.0):
                continue
            found = True
            break
        if not found:
            raise ConfigError(f"task {TASK_ID} reset (episode {e}): no spill site clear of land "
                              f"within {CLEAR_RADII * R:g} m, with a surface drift >= "
                              f"{min_drift:g} m/s and a clear staging point {dist:g} m away; "
                              f"the grid has no such water for this tier")
        x0, z0 = cxz[0] - half, cxz[1] - half
        X, Z = np.meshgrid(x0 + ci, z0 + ci)
        ok = _surface_ok(grid, np.stack([X.ravel(), Z.ravel()], 1)).reshape(n, n)
        land[e] = (~ok).astype(np.uint8)
        C0[e] = pol.make_spill(n, n, FIELD_H_M, cxz, R, SPILL_MASS_KG, rng, x0=x0, z0=z0,
                               land=land[e])
        origin[e] = (x0, z0)
        xc, zc, _ = pol.centroid(C0[e], 0, x0, z0, FIELD_H_M)
        report[e] = (xc, zc)
        pos0[e, :, 0] = starts[:, 0]
        pos0[e, :, 1] = SURFACE_Y_M
        pos0[e, :, 2] = starts[:, 1]
    d = report[:, None, :] - pos0[:, :, [0, 2]]
    psi0 = np.arctan2(d[..., 0], d[..., 1])
    return {"pos0": pos0, "psi0": psi0, "t0": t0, "C0": C0, "land": land, "origin": origin,
            "report": report}


@hot_kernel
def _refresh_faces(grid, uf, vf, x0, z0, h, y, t):
    """Sample the surface current at the field's face centres (see pollution module doc)."""
    nz = uf.shape[0]
    nx = vf.shape[1]
    for j in range(nz):
        z = z0 + j * h
        for i in range(nx + 1):
            ce, cn = current_at(grid, x0 + (i - 0.5) * h, y, z, t)
            uf[j, i] = ce
    for j in range(nz + 1):
        z = z0 + (j - 0.5) * h
        for i in range(nx):
            ce, cn = current_at(grid, x0 + i * h, y, z, t)
            vf[j, i] = cn


@hot_kernel
def _aerial_map(C, x0, z0, h, bsz, bm, bx, bz):
    """Block masses (kg) and mass centroids (m) of the field; returns the total mass (kg)."""
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
def _assign(S, bm, bx, bz, cnt, tgt, done, tot):
    """Greedy assignment: N times, the block with max mass/(1+count) -> nearest free agent."""
    n_ag = S.shape[0]
    nb = bm.shape[0]
    for b in range(nb):
        cnt[b] = 0
    for i in range(n_ag):
        done[i] = 0
    for _ in range(n_ag):
        best = -1
        score = 0.0
        for b in range(nb):
            if bm[b] > MIN_BLOCK_FRAC * tot:
                sc = bm[b] / (1.0 + cnt[b])
                if sc > score:
                    score = sc
                    best = b
        if best < 0:
            return
        ia = -1
        dmin = np.inf
        for i in range(n_ag):
            if done[i] == 0:
                d = (S[i, 0] - bx[best]) ** 2 + (S[i, 2] - bz[best]) ** 2
                if d < dmin:
                    dmin = d
                    ia = i
        done[ia] = 1
        cnt[best] += 1
        tgt[ia, 0] = bx[best]
        tgt[ia, 1] = bz[best]


@hot_kernel
def _episode(grid, vp, ipar, fpar, dparams, t0, origin, report, C, land, uf, vf, work, bm, bx,
             bz, cnt, done, tgt, state, cmd, obs, act, res, e):
    """Run episode ``e`` (serial) and write row ``e`` of ``res`` (see ``COLUMNS``)."""
    model = ipar[_I_MODEL]
    method = ipar[_I_METHOD]
    n_steps = ipar[_I_STEPS]
    seed = ipar[_I_SEED]
    aerial = ipar[_I_AERIAL]
    refresh = ipar[_I_REFRESH]
    bsz = ipar[_I_BLOCK]
    dt = fpar[_F_DT]
    v_max = fpar[_F_VMAX]
    budget = fpar[_F_SPEED] if method == HEURISTIC else v_max
    kp = fpar[_F_KP]
    noise = fpar[_F_NOISE]
    land_thr = fpar[_F_LAND]
    clearance = fpar[_F_CLEAR]
    h = fpar[_F_H]
    kappa = fpar[_F_KAPPA]
    rad = fpar[_F_RAD]
    eff = fpar[_F_EFF]
    target = fpar[_F_TARGET]
    y_op = fpar[_F_Y]
    kpy = fpar[_F_KPY]
    sep = fpar[_F_SEP]
    sep_gain = fpar[_F_SEPG]
    r_coll = fpar[_F_RCOLL]
    ring = fpar[_F_RING]
    S = state[e]
    Ce = C[e]
    x0 = origin[e, 0]
    z0 = origin[e, 1]
    n_ag = S.shape[0]
    m0 = pol.total_mass(Ce, h)
    removed = 0.0
    escaped = 0.0
    energy = 0.0
    viol = 0
    coll = 0
    t_map = t0[e]
    # before the first map: a ring around the reported centroid (the oracle maps at k = 0)
    for i in range(n_ag):
        a = 2.0 * math.pi * i / n_ag
        tgt[e, i, 0] = report[e, 0] + ring * math.sin(a)
        tgt[e, i, 1] = report[e, 1] + ring * math.cos(a)
    success = removed >= target * m0
    t_s = 0.0
    k = 0
    while k < n_steps and not success:
        t = t0[e] + k * dt
        if k % refresh == 0:
            _refresh_faces(grid, uf[e], vf[e], x0, z0, h, y_op, t)
        if (method == HEURISTIC and k > 0 and k % aerial == 0) or method != HEURISTIC:
            tot = _aerial_map(Ce, x0, z0, h, bsz, bm[e], bx[e], bz[e])
            _assign(S, bm[e], bx[e], bz[e], cnt[e], tgt[e], done[e], tot)
            t_map = t
        age = t - t_map
        for i in range(n_ag):
            s = S[i]
            px = s[0]
            py = s[1]
            pz = s[2]
            ce, cn = current_at(grid, px, py, pz, t)
            pe, pn = sensed_current(method, ce, cn, noise, seed, e, 2 * (k * n_ag + i))
            # through-water velocity toward the (drifting) target
            wx = kp * (tgt[e, i, 0] + pe * age - px)
            wz = kp * (tgt[e, i, 1] + pn * age - pz)
            w = math.sqrt(wx * wx + wz * wz)
            if w > budget:
                wx *= budget / w
                wz *= budget / w
            for j in range(n_ag):
                if j != i:
                    dx = px - S[j, 0]
                    dz = pz - S[j, 2]
                    d = math.sqrt(dx * dx + dz * dz)
                    if d < sep:
                        if d > 1e-6:
                            wx += sep_gain * (sep - d) * dx / d
                            wz += sep_gain * (sep - d) * dz / d
                        else:
                            wx += sep_gain * sep * (1.0 if i > j else -1.0)
            ax, ay, az = steer(wx + pe, kpy * (y_op - py), wz + pn, budget, pe, pn)
            if k < obs.shape[1]:  # surface concentration under the vehicle, kg m-2
                observe(obs, act, e, k, i, grid, state, tgt[e, i, 0] + pe * age, y_op,
                        tgt[e, i, 1] + pn * age, pe, pn, pol.probe(Ce, 0, px, pz, x0, z0, h), ax,
                        ay, az)
            c = cmd[e, i]
            set_velocity_cmd(c, ax, ay, az)
            en, code = advance_agent(grid, model, vp, s, c, ce, cn, v_max, dt, land_thr,
                                     clearance)
            energy += en
            if code != OK:
                viol += 1
        for i in range(n_ag):
            removed += pol.remove_in_radius(Ce, S[i, 0], S[i, 2], rad, eff, dt, x0, z0, h)
        escaped += pol.step_field(Ce, pol.KIND_TRACER, dparams, uf[e], vf[e], land[e], h, dt,
                                  kappa, pol.OPEN_ALL, work[e])
        if min_pairwise_distance(S) <= r_coll:
            coll += 1
        k += 1
        if removed >= target * m0:
            success = True
            t_s = k * dt
    remaining = pol.total_mass(Ce, h)
    res[e, _C_SUCCESS] = 1.0 if success else 0.0
    res[e, _C_T] = t_s if success else n_steps * dt
    res[e, _C_E] = energy
    res[e, _C_COLL] = coll / k if k > 0 else 0.0
    res[e, _C_VIOL] = viol
    res[e, _C_CLEAN] = removed / m0
    res[e, _C_ESC] = escaped / m0
    res[e, _C_REM] = remaining / m0
    res[e, _C_TTT] = res[e, _C_T]


@njit(parallel=True, cache=True)
def _kernel(grid, vp, ipar, fpar, dparams, t0, origin, report, C, land, uf, vf, work, bm, bx,
            bz, cnt, done, tgt, state, cmd, obs, act, res):
    for e in prange(res.shape[0]):
        _episode(grid, vp, ipar, fpar, dparams, t0, origin, report, C, land, uf, vf, work, bm,
                 bx, bz, cnt, done, tgt, state, cmd, obs, act, res, e)


def rollout(grid, tier: dict, init: dict, method: str, dyn: str, vehicle,
            seed: int, *, record: bool = False) -> dict:
    """Run every episode of ``init`` (from :func:`reset`) with one method.

    Parameters
    ----------
    grid : Grid
        Forcing already applied (``run_cell`` sets the tier's ``current_gain``).
    tier : dict
        Tier parameters plus ``dt_s``.
    init : dict
        Output of :func:`reset` (its ``C0`` is copied, never modified).
    method : {"heuristic", "oracle"}
    dyn : {"kinematic", "3dof", "4dof", "6dof"}
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
    dt = float(tier["dt_s"])
    C = np.ascontiguousarray(init["C0"], dtype=np.float64).copy()
    n_ep, _, nz, nx = C.shape
    n_ag = init["pos0"].shape[1]
    v_max = float(vehicle.v_max)
    aerial = max(1, int(round(float(tier["aerial_period_s"]) / dt)))
    ipar = np.array([model_id(dyn), method_id(method),
                     episode_steps(tier), int(seed),
                     aerial, FACE_REFRESH_STEPS, BLOCK_CELLS], dtype=np.int64)
    fpar = np.array([dt, v_max, CRUISE_FRAC * v_max, KP, float(tier["probe_noise_ms"]),
                     DEFAULT_LAND_THRESHOLD, CLEARANCE_M, FIELD_H_M, float(tier["kappa_m2s"]),
                     float(tier["removal_radius_m"]), float(tier["removal_rate_s"]),
                     float(tier["target_fraction"]), SURFACE_Y_M, KP_DEPTH, SEP_M, SEP_GAIN,
                     R_COLL_M, 0.5 * float(tier["spill_radius_m"])])
    nb = ((nx + BLOCK_CELLS - 1) // BLOCK_CELLS) * ((nz + BLOCK_CELLS - 1) // BLOCK_CELLS)
    state = new_state(n_ep, n_ag, init["pos0"], init["psi0"])
    cmd = np.zeros((n_ep, n_ag, CMD_DIM))
    res = np.zeros((n_ep, len(COLUMNS)))
    obs, act = obs_buffers(tier, init, record)
    _kernel(grid, vehicle.params, ipar, fpar, np.zeros(1), np.ascontiguousarray(init["t0"],
            dtype=np.float64), np.ascontiguousarray(init["origin"], dtype=np.float64),
            np.ascontiguousarray(init["report"], dtype=np.float64), C,
            np.ascontiguousarray(init["land"], dtype=np.uint8), np.zeros((n_ep, nz, nx + 1)),
            np.zeros((n_ep, nz + 1, nx)), np.zeros((n_ep, pol.work_size(1, nz, nx))),
            np.zeros((n_ep, nb)), np.zeros((n_ep, nb)), np.zeros((n_ep, nb)),
            np.zeros((n_ep, nb), dtype=np.int64), np.zeros((n_ep, n_ag), dtype=np.int64),
            np.zeros((n_ep, n_ag, 2)), state, cmd, obs, act, res)
    return rollout_results(res, COLUMNS, obs, act, record)


# numba keys a cache entry on this file only; drop it when the engine, the task layer or
# the model changes.
fresh_cache(_kernel, __file__, pol.__file__)
