"""AS heuristic and oracle: a lawnmower survey with terrain following and current feed-forward.

Plan (Python, :func:`prepare` before the episode's first step; the plan tokens are the
waypoint arrays of the task's work ``W``: ``wps``, ``wcount``, ``widx``)
    Strips at commanded altitude ``a_c = ALT_FRAC * max_altitude_m`` (so the footprint
    survives terrain-following errors), spacing at most ``2 a_c tan(half_angle) (1 - OVERLAP)``
    spread evenly over the region's width (:func:`plan_lawnmower`); the strips are split into
    contiguous blocks, one per agent (boustrophedon inside a block). Each agent's list starts
    with a run-in waypoint ``RUNIN_M`` before its first strip, on the strip's line
    (:func:`with_runin`), so a torpedo AUV enters the region aligned with the strip.
Act (``act``, every agent and step)
    The transit to the run-in waypoint ends within ``ARRIVE_M`` (wider than the vehicle's
    turning diameter: an underactuated torpedo cannot close on a point inside its turning
    circles and would orbit it). Strips are tracked with line-of-sight guidance (a carrot
    ``LOOKAHEAD_M`` ahead of the
    projection on the strip, :func:`~oneocean.tasks.common.waypoint_carrot`), terrain-following
    in depth (the carrot's depth is the seafloor depth there minus ``a_c``), crabbing against
    the current (:func:`~oneocean.tasks.common.seek_max`: the cross-track current is cancelled
    first); teammates closer than ``SEP_M`` repel each other (their positions are observed).
    The carrot is written to ``W.tgt`` (the observation's goal cue).

Both use the full speed budget ``v_max`` through the water, the same altitude and overlap.
``heuristic``: strips along the region's long axis (fewest turns); its current estimate and
navigation come from the sensor models (:mod:`oneocean.sensing`). ``oracle``: the truth, and a
planner: it orients the strips across the current (:func:`oracle_axis`: it predicts the scan
time of both orientations from the true currents over the episode and takes the faster one).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...engine.grid import sample_elevation, sample_elevation_points
from ...tasks.common import ARRIVE_M, seek_max, waypoint_carrot
from ...tasks.loop import noop_plan as plan  # noqa: F401  (the plan is made in Python)
from . import SENSING

#: Commanded altitude as a fraction of the sensor's maximum altitude (every method).
ALT_FRAC = 0.75
#: Swath overlap between neighbouring strips (fraction of the swath width; every method).
OVERLAP = 0.2
#: Line-of-sight lookahead along the strip, m.
LOOKAHEAD_M = 12.0
#: Proportional gain of point approaches (transit to the first strip), s-1.
KP = 0.5
#: A strip waypoint counts as reached this far (m) before its along-track end.
WP_TOL_M = 1.0
# The transit to the plan's first waypoint ends within tasks.common.ARRIVE_M: a torpedo AUV
# (remus100: turns no tighter than a 5 m radius) cannot close on a point inside its turning
# circle; with a 2 m arrival it orbited the waypoint at ~5 m for ever.
#: Run-in: the plan's first waypoint lies this far (m) before the first strip's start, on the
#: strip's line, so the vehicle is aligned with the strip when it enters the region.
RUNIN_M = 20.0
#: Shallowest commanded depth, m (stay submerged).
MIN_DEPTH_M = 1.0
#: Teammate avoidance: repulsion inside SEP_M (m), up to K_REP_MS (m s-1) at contact.
SEP_M = 6.0
K_REP_MS = 1.0


class ASPolicy(NamedTuple):
    budget: float   # speed budget through the water, m s-1
    kp: float       # approach gain, s-1
    look: float     # line-of-sight lookahead, m
    alt: float      # commanded altitude above the seafloor, m
    spacing: float  # nominal strip spacing, m
    oracle: int     # 1: orient the strips by the predicted scan time (true currents)
    v_max: float    # vehicle speed limit, m s-1 (the oracle's scan-time prediction)


def method_altitude(tier: dict, method: str) -> float:
    """Commanded altitude above the seafloor (m): the same for every method."""
    return ALT_FRAC * float(tier["max_altitude_m"])


def strip_spacing(tier: dict, method: str) -> float:
    """Lawnmower strip spacing (m) at the commanded altitude: the same for every method."""
    return (2.0 * method_altitude(tier, method)
            * math.tan(math.radians(float(tier["half_angle_deg"]))) * (1.0 - OVERLAP))


def params(method: str, tier: dict, vehicle) -> ASPolicy:
    v_max = float(vehicle.v_max)
    return ASPolicy(v_max, KP, LOOKAHEAD_M,
                    method_altitude(tier, method), strip_spacing(tier, method),
                    0 if method == "heuristic" else 1, v_max)


# ------------------------------------------------------------------------------ planning

def _n_strips(width: float, spacing: float, n_agents: int) -> int:
    return max(1, int(math.ceil(width / spacing - 1e-9)), int(n_agents))


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
    n_strips = _n_strips(width, spacing, n_agents)
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


def max_waypoints(tier: dict, region, n_agents: int) -> int:
    """Waypoints per agent that every method's plan fits in (either strip orientation), for
    the regions ``region`` (E, 4): the size of the plan-token array."""
    region = np.asarray(region, dtype=np.float64).reshape(-1, 4)
    sides = np.concatenate([region[:, 2] - region[:, 0], region[:, 3] - region[:, 1]])
    width = float(sides.max()) if sides.size else 0.0
    n = max(_n_strips(width, strip_spacing(tier, m), n_agents) for m in SENSING)
    return 2 * (-(-n // int(n_agents))) + 1


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
    from ...engine.grid import sample_currents

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


def plan_episode(grid, M: ASPolicy, box, long_axis: int, t0: float, duration: float,
                 n_agents: int):
    """The method's lawnmower over one episode's region ``box`` (x_lo, z_lo, x_hi, z_hi):
    :func:`plan_lawnmower` along the long axis (heuristic) or along :func:`oracle_axis`
    (``M.oracle``; ``duration``: the episode's time limit, s)."""
    if M.oracle == 0:
        axis = int(long_axis)
    else:
        depth = float(-sample_elevation_points(
            grid, np.array([[0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])]]),
            np.empty(1))[0]) - M.alt
        axis = oracle_axis(grid, box, max(depth, MIN_DEPTH_M), float(t0), duration, M.v_max,
                           M.spacing)
    wps, cnt = plan_lawnmower(box, axis, M.spacing, n_agents)
    return with_runin(wps, cnt)


def with_runin(wps, count, runin: float = RUNIN_M):
    """``wps`` with a run-in waypoint prepended per agent: ``runin`` m before the first
    strip's start, on the strip's line (outside the region, inside its water margin)."""
    n_ag, n_max, _ = wps.shape
    out = np.zeros((n_ag, n_max + 1, 2))
    out[:, 1:] = wps
    for i in range(n_ag):
        a, b = wps[i, 0], wps[i, 1]
        d = b - a
        L = float(np.hypot(d[0], d[1]))
        out[i, 0] = a - d / L * runin if L > 1e-9 else a
    return out, count + 1


def prepare(grid, P, W, M: ASPolicy, t0, LP=None, LS=None, X=None) -> None:
    """The Python planner: write the plan tokens of every episode not yet planned (``W.wps``,
    ``W.wcount``, ``W.widx = 0``, ``W.tgt`` = the first waypoint at the commanded altitude)
    before the episode's first step. Idempotent (``W.planned``). (``LP``, ``LS``, ``X``: the
    loop's params and state and the known state, :class:`~oneocean.tasks.episodes.Episodes`;
    unused: the strips depend on the region only.)"""
    todo = np.flatnonzero(W.planned == 0)
    if todo.size == 0:
        return
    n_ag = W.wcount.shape[1]
    for e in todo:
        wps, cnt = plan_episode(grid, M, tuple(W.region[e]), W.long_axis[e], t0[e], P.t_lim,
                                n_ag)
        if wps.shape[1] > W.wps.shape[2]:
            raise RuntimeError(f"AS plan of episode {e}: {wps.shape[1]} waypoints per agent, "
                               f"the plan-token array holds {W.wps.shape[2]}")
        W.wps[e] = 0.0
        W.wps[e, :, :wps.shape[1]] = wps
        W.wcount[e] = cnt
        W.widx[e] = 0
        first = np.ascontiguousarray(wps[:, 0])
        gy = -sample_elevation_points(grid, first, np.empty(n_ag)) - M.alt
        W.tgt[e, :, 0] = first[:, 0]
        W.tgt[e, :, 1] = np.maximum(gy, MIN_DEPTH_M)
        W.tgt[e, :, 2] = first[:, 1]
        W.planned[e] = 1


# ------------------------------------------------------------------------------ acting

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
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    n_ag = state.shape[1]
    s = state[e, i]
    px = s[0]
    py = s[1]
    pz = s[2]
    gx, gz, w = waypoint_carrot(W.wps, W.widx, W.wcount, e, i, px, pz, M.look, WP_TOL_M,
                                ARRIVE_M)
    # terrain following: the carrot's depth is the seafloor there minus a_c
    gy = -sample_elevation(grid, gx, gz) - M.alt
    if gy < MIN_DEPTH_M:
        gy = MIN_DEPTH_M
    ax, ay, az = seek_max(px, py, pz, gx, gy, gz, M.budget, M.kp, pe, pn)
    if n_ag > 1:  # keep clear of teammates (their positions are observed)
        rx, rz = _repulsion(state, e, i, n_ag)
        ax += rx
        az += rz
    g = W.tgt[e, i]
    g[0] = gx
    g[1] = gy
    g[2] = gz
    return ax, ay, az, math.nan
