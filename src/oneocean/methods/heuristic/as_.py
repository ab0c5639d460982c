"""AS heuristic and oracle: a lawnmower survey with terrain following and current feed-forward.

Plan
    Made in Python by :func:`prepare` before the episode's first step; the plan tokens are
    the waypoint arrays of the task's work ``W``: ``wps``, ``wcount``, ``widx``. Strips at
    commanded altitude ``a_c = ALT_FRAC * max_altitude_m`` (so the footprint survives
    terrain-following errors), spacing at most ``2 a_c tan(half_angle) (1 - OVERLAP)`` spread
    evenly over the width (:func:`plan_lawnmower`); the strips are split into contiguous
    blocks, one per agent (boustrophedon inside a block). Each agent's list starts with a
    run-in waypoint ``RUNIN_M`` before its first strip, on the strip's line
    (:func:`with_runin`), so a torpedo AUV enters the region aligned with the strip. The
    strips are flown on the vehicle's navigation estimate while its footprint falls on the
    true seafloor, so dead-reckoning drift opens holidays at the region's edges. The planner
    (:func:`plan_episode`) therefore lays the strips over the region extended on each side by
    a navigation margin, ``k`` standard deviations of the dead-reckoning error it expects
    there (:func:`nav_margins`, from the navigation model's own figures: start fix, heading
    bias, scale factor, velocity noise), taking the widest margin, ``k`` from ``NAV_K`` down
    to 0, whose predicted scan (:func:`predicted_time`) fits the time limit less
    ``TIME_RESERVE``; it orients the strips along x or z, whichever gives the shorter
    predicted scan through the currents it knows (:func:`scan_axis`, :func:`known_currents`).
Act
    ``act``, every agent and step. The transit to the run-in waypoint ends within
    ``ARRIVE_M`` (wider than the vehicle's turning diameter: an underactuated torpedo cannot
    close on a point inside its turning circles and would orbit it). Strips are tracked with
    line-of-sight guidance (a carrot ``LOOKAHEAD_M`` ahead of the projection on the strip,
    :func:`~oneocean.tasks.common.waypoint_carrot`), terrain-following in depth (the carrot's
    depth is the seafloor depth there minus ``a_c``), crabbing against the current
    (:func:`~oneocean.tasks.common.seek_max`: the cross-track current is cancelled first);
    teammates closer than ``SEP_M`` repel each other (their positions are observed). The
    carrot is written to ``W.tgt`` (the observation's goal cue).

Heuristic and oracle are one policy with the same parameters (the full speed budget
``v_max`` through the water, the same altitude, overlap, planner and rules); they differ in
information only (``LoopParams.sens``). The heuristic plans on its forecast of the currents
(``LoopState.fc``), from its start fix, with the margins its dead reckoning needs, and flies
on its navigation estimate and filtered current estimate (:mod:`oneocean.sensing`); the
oracle plans on the true currents from its true position, with zero margins (its position
error is 0), and flies on the truth. Given the truth the heuristic is the oracle, bit for bit.
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
#: Navigation margin of the survey plan, in standard deviations of the expected
#: dead-reckoning error at the region's edges (:func:`nav_margins`): one-sided, an edge is
#: imaged through ~98 % of the drifts (every method; 0 m for a method that knows its position).
NAV_K = 2.0
#: Steps (standard deviations) by which the planner narrows its margin to fit the time limit.
K_STEP = 0.25
#: Fraction of the time limit the plan keeps in hand: the scan-time model leaves out the turns
#: and the terrain following (the oracle's actual / predicted scan time on the calibration
#: seeds, T2 and T3: median 1.02, upper quartile 1.07-1.08).
TIME_RESERVE = 0.05
#: Reach (m) of a start fix from the region's corner assumed by :func:`margin_bound`.
SPAWN_REACH_M = 100.0
#: Times over the episode at which the planner samples the currents it knows.
N_TIMES = 7


class ASPolicy(NamedTuple):
    """Parameters ``M`` of the AS policy (the same for heuristic and oracle).

    Attributes
    ----------
    budget : float
        Speed budget through the water, m s-1 (the vehicle's ``v_max``).
    kp : float
        Approach gain, s-1 (:data:`KP`).
    look : float
        Line-of-sight lookahead along the strip, m (:data:`LOOKAHEAD_M`).
    alt : float
        Commanded altitude above the seafloor, m (:func:`method_altitude`).
    spacing : float
        Nominal strip spacing, m (:func:`strip_spacing`).
    v_max : float
        Vehicle speed limit, m s-1 (the scan-time prediction).
    """
    budget: float   # speed budget through the water, m s-1
    kp: float       # approach gain, s-1
    look: float     # line-of-sight lookahead, m
    alt: float      # commanded altitude above the seafloor, m
    spacing: float  # nominal strip spacing, m
    v_max: float    # vehicle speed limit, m s-1 (the scan-time prediction)


def method_altitude(tier: dict, method: str) -> float:
    """Commanded altitude above the seafloor: the same for every method.

    Parameters
    ----------
    tier : dict
        Tier parameters; reads ``max_altitude_m``, the sensor's maximum altitude, m.
    method : str
        The method (unused: every method flies the same altitude).

    Returns
    -------
    float
        ``ALT_FRAC * max_altitude_m``, m.
    """
    return ALT_FRAC * float(tier["max_altitude_m"])


def strip_spacing(tier: dict, method: str) -> float:
    """Lawnmower strip spacing at the commanded altitude: the same for every method.

    Parameters
    ----------
    tier : dict
        Tier parameters; reads ``max_altitude_m`` (m) and ``half_angle_deg`` (the sensor's
        half swath angle, degrees).
    method : str
        The method (unused).

    Returns
    -------
    float
        ``2 a_c tan(half_angle) (1 - OVERLAP)``, m, with ``a_c`` the :func:`method_altitude`.
    """
    return (2.0 * method_altitude(tier, method)
            * math.tan(math.radians(float(tier["half_angle_deg"]))) * (1.0 - OVERLAP))


def params(method: str, tier: dict, vehicle) -> ASPolicy:
    """The policy's params: the same for the heuristic and the oracle.

    They differ in what they know only (``LoopParams.sens``, read by :func:`prepare`).

    Parameters
    ----------
    method : str
        The fused method, ``"heuristic"`` or ``"oracle"``
        (:data:`oneocean.methods.heuristic.SENSING`).
    tier : dict
        The cell's tier parameters plus ``dt_s`` and ``v_max``
        (:attr:`oneocean.tasks.Cell.params`).
    vehicle : Vehicle
        The task's vehicle (:class:`oneocean.engine.dynamics.Vehicle`).

    Returns
    -------
    ASPolicy
        Budget and ``v_max`` the vehicle's, :data:`KP`, :data:`LOOKAHEAD_M`, the tier's
        :func:`method_altitude` and :func:`strip_spacing`.
    """
    v_max = float(vehicle.v_max)
    return ASPolicy(v_max, KP, LOOKAHEAD_M, method_altitude(tier, method),
                    strip_spacing(tier, method), v_max)


# ------------------------------------------------------------------------------ planning

def _n_strips(width: float, spacing: float, n_agents: int) -> int:
    return max(1, int(math.ceil(width / spacing - 1e-9)), int(n_agents))


def plan_lawnmower(box, axis: int, spacing: float, n_agents: int, seam: float = 0.0):
    """Boustrophedon waypoints (x, z) per agent over ``box``, strips along ``axis``.

    ``n = max(ceil((W + (n_agents - 1) seam) / spacing), n_agents)`` strips (every agent gets
    at least one; a large team flies narrower, overlapping strips rather than idling or
    crowding), split into contiguous blocks, one per agent; every block starts at the strips'
    low end. The strips lie at ``(k + 1/2) U / n`` over the width unrolled to
    ``U = W + (n_agents - 1) seam``, block ``i`` shifted back by ``i seam``: neighbouring
    agents' swaths overlap by an extra ``seam`` m at the seam between their blocks
    (:func:`team_seam`; 0: evenly spaced strips).

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
            b = offs[s] - i * seam
            for a in ends:
                wps[i, k] = (a, b) if axis == 0 else (b, a)
                k += 1
        count[i] = k
    return wps, count


def nav_sigma(SP, dx: float, dz: float, nx: float, nz: float, t: float) -> float:
    """Standard deviation of the dead-reckoning position error along a unit normal.

    At a point ``(dx, dz)`` from the start fix reached ``t`` s after it, from the navigation
    model's own figures: the start fix, plus the constant scale factor's error along the
    displacement and the constant heading bias's across it (the error of dead reckoning on a
    constant scale factor and heading bias is ``(g R - I)`` times the displacement from the
    fix, whatever the path), plus the DVL velocity noise's random walk, counted in steps of
    1 s (the task's ``dt_s``).

    Parameters
    ----------
    SP : SensingParams
        The method's navigation model (:class:`oneocean.sensing.SensingParams`, the sensor
        table's figures).
    dx, dz : float
        Displacement from the start fix, east and north, m.
    nx, nz : float
        Unit normal along which the error is measured.
    t : float
        Time since the fix, s.

    Returns
    -------
    float
        The standard deviation, m; 0 for a method that knows its true position
        (``SP.true_position``).
    """
    if SP.true_position != 0:
        return 0.0
    along = dx * nx + dz * nz      # displacement along the normal (scale factor)
    across = dx * nz - dz * nx     # across it (heading bias)
    steps = max(t, 0.0)            # steps of dt = 1 s (AS.yaml dt_s): t s
    var = (SP.start_fix_std ** 2 + (SP.scale_std * along) ** 2
           + (SP.heading_bias_std * across) ** 2 + SP.vel_noise ** 2 * steps)
    return math.sqrt(var)


def nav_margins(SP, box, starts, duration: float, k: float | None = None):
    """Margins by which a survey planner extends the region ``box`` on each side.

    ``k`` times the navigation error normal to that side (:func:`nav_sigma`) at its corner
    farthest from the agents' start fixes, after the whole mission. The strips are flown on the
    navigation estimate while the footprint falls on the true seafloor: the margin keeps the
    region's edges imaged through the expected drift. Zeros for a method that knows its
    position (the rule is shared; only the information differs).

    Parameters
    ----------
    SP : SensingParams
        The method's navigation model (:class:`oneocean.sensing.SensingParams`, the sensor
        table's figures).
    box : tuple of float
        The region ``(x_lo, z_lo, x_hi, z_hi)``, m.
    starts : (n, 2) array_like
        The agents' start fixes (x, z), m.
    duration : float
        Mission duration, s.
    k : float, optional
        Standard deviations of margin (default :data:`NAV_K`).

    Returns
    -------
    tuple of float
        The margins ``(west, south, east, north)``, m.
    """
    x_lo, z_lo, x_hi, z_hi = box
    sides = ((-1.0, 0.0, ((x_lo, z_lo), (x_lo, z_hi))),   # west
             (0.0, -1.0, ((x_lo, z_lo), (x_hi, z_lo))),   # south
             (1.0, 0.0, ((x_hi, z_lo), (x_hi, z_hi))),    # east
             (0.0, 1.0, ((x_lo, z_hi), (x_hi, z_hi))))    # north
    k = NAV_K if k is None else float(k)
    out = []
    for nx, nz, corners in sides:
        s = 0.0
        for sx, sz in np.asarray(starts, dtype=np.float64).reshape(-1, 2):
            for cx, cz in corners:
                s = max(s, nav_sigma(SP, cx - sx, cz - sz, nx, nz, duration))
        out.append(k * s)
    return tuple(out)


def team_seam(SP, box, starts, duration: float, axis: int, k: float | None = None) -> float:
    """Extra overlap between neighbouring agents' blocks of strips along ``axis`` over ``box``.

    ``k`` times the standard deviation of the difference of two vehicles' independent
    dead-reckoning errors across the strips (``sqrt(2)`` times :func:`nav_sigma`, normal to the
    strips) at the box's corner farthest from the start fixes.

    Parameters
    ----------
    SP : SensingParams or None
        The method's navigation model (:class:`oneocean.sensing.SensingParams`); None: no seam.
    box : tuple of float
        The region ``(x_lo, z_lo, x_hi, z_hi)``, m.
    starts : (n, 2) array_like or None
        The agents' start fixes (x, z), m; None: no seam.
    duration : float
        Mission duration, s.
    axis : int
        Strip orientation: 0 along x, 1 along z.
    k : float, optional
        Standard deviations of overlap (default :data:`NAV_K`).

    Returns
    -------
    float
        The seam, m; 0 for a single agent or a method that knows its position.
    """
    pts = np.asarray(starts, dtype=np.float64).reshape(-1, 2) if starts is not None else None
    if SP is None or pts is None or pts.shape[0] < 2:
        return 0.0
    k = NAV_K if k is None else float(k)
    nx, nz = (0.0, 1.0) if axis == 0 else (1.0, 0.0)
    x_lo, z_lo, x_hi, z_hi = box
    s = 0.0
    for sx, sz in pts:
        for cx, cz in ((x_lo, z_lo), (x_hi, z_lo), (x_lo, z_hi), (x_hi, z_hi)):
            s = max(s, nav_sigma(SP, cx - sx, cz - sz, nx, nz, duration))
    return k * math.sqrt(2.0) * s


def margin_bound(tier: dict, region) -> float:
    """An upper bound of :func:`nav_margins` over a tier's regions.

    Starts within ``SPAWN_REACH_M`` of a region's corner, every error at the sensor table's
    values: what the plan-token array must leave room for.

    Parameters
    ----------
    tier : dict
        Tier parameters; reads ``time_limit_s``, s.
    region : (E, 4) array_like
        The episodes' regions ``(x_lo, z_lo, x_hi, z_hi)``, m.

    Returns
    -------
    float
        The bound, m (0 without regions).
    """
    from ...sensing import sensing_params

    SP = sensing_params("sensors", 1.0)
    region = np.asarray(region, dtype=np.float64).reshape(-1, 4)
    if region.size == 0:
        return 0.0
    d = float(np.hypot(region[:, 2] - region[:, 0], region[:, 3] - region[:, 1]).max())
    d += SPAWN_REACH_M
    return NAV_K * math.sqrt(SP.start_fix_std ** 2
                             + (SP.scale_std ** 2 + SP.heading_bias_std ** 2) * d * d
                             + SP.vel_noise ** 2 * max(float(tier["time_limit_s"]), 0.0))


def plan_tokens(grid, tier: dict, init: dict) -> dict:
    """The size of the plan the task carries for this policy (:func:`oneocean.tasks.as_.make`).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    tier : dict
        The cell's tier parameters plus ``dt_s`` and ``v_max``.
    init : dict
        The cell's episodes (:func:`oneocean.tasks.as_.reset`).
        Reads ``region`` (E, 4) and ``pos0`` (E, N, 3).

    Returns
    -------
    dict
        ``max_waypoints``: waypoints per agent (:func:`max_waypoints`).
    """
    return {"max_waypoints": max_waypoints(tier, init["region"], init["pos0"].shape[1])}


def max_waypoints(tier: dict, region, n_agents: int) -> int:
    """Waypoints per agent that every method's plan fits in: the size of the plan-token array.

    Either strip orientation, the navigation margins (:func:`margin_bound`) and a team's seams
    included.

    Parameters
    ----------
    tier : dict
        Tier parameters (``max_altitude_m``, ``half_angle_deg``, ``time_limit_s``).
    region : (E, 4) array_like
        The episodes' regions ``(x_lo, z_lo, x_hi, z_hi)``, m.
    n_agents : int
        Team size N.

    Returns
    -------
    int
        Waypoints per agent, the run-in waypoint included.
    """
    region = np.asarray(region, dtype=np.float64).reshape(-1, 4)
    sides = np.concatenate([region[:, 2] - region[:, 0], region[:, 3] - region[:, 1]])
    mb = margin_bound(tier, region)
    width = ((float(sides.max()) if sides.size else 0.0) + 2.0 * mb
             + (int(n_agents) - 1) * math.sqrt(2.0) * mb)
    n = max(_n_strips(width, strip_spacing(tier, m), n_agents) for m in SENSING)
    return 2 * (-(-n // int(n_agents))) + 1


@hot_kernel(inline="always")
def _pymax(a, b):
    """Python's ``max(a, b)``: ``b`` only if it is larger (``a`` on a tie or a NaN)."""
    return b if b > a else a


@hot_kernel(inline="always")
def _along_speed(ce, cn, ux, uz, v):
    """Largest ground speed along unit (ux, uz) with ``|a| <= v`` through current (ce, cn)."""
    c_par = ce * ux + cn * uz
    q2 = ce * ce + cn * cn - c_par * c_par
    if q2 >= v * v:
        return 0.0
    return _pymax(0.0, c_par + math.sqrt(v * v - q2))


@hot_kernel
def _scan_kernel(cur, L, W, n, ux, uz, v):
    """:func:`scan_times` along one axis: the mean over the samples ``cur`` (k, 2) of the
    scan of ``n`` strips of length ``L`` over the width ``W`` along (ux, uz)."""
    tot = 0.0
    for s in range(cur.shape[0]):
        ce = cur[s, 0]
        cn = cur[s, 1]
        strips = 0.5 * L * (1.0 / _pymax(_along_speed(ce, cn, ux, uz, v), 1e-3)
                            + 1.0 / _pymax(_along_speed(ce, cn, -ux, -uz, v), 1e-3))
        cross = W / n / _pymax(_along_speed(ce, cn, uz, ux, v), 1e-3)
        tot += n * strips + (n - 1) * cross
    return tot / max(1, cur.shape[0])


def scan_times(cur, box, v: float, spacing: float, n_agents: int = 1):
    """Predicted scan time of the lawnmower over ``box``, strips along x and along z.

    A scan along an axis has ``n = max(ceil(W / spacing), n_agents)`` strips of length ``L``
    flown alternately each way and ``n - 1`` cross legs of ``W / n``; each leg's time uses the
    fastest ground speed along it through the current (at least 1e-3 m s-1), averaged over the
    current samples. The time is the team's total (not divided between the agents).

    Parameters
    ----------
    cur : (n, 2) array_like
        Current samples over the episode (east, north), m s-1.
    box : tuple of float
        The region ``(x_lo, z_lo, x_hi, z_hi)``, m.
    v : float
        Speed through the water, m s-1.
    spacing : float
        Strip spacing, m.
    n_agents : int, optional
        Team size N (the least number of strips; default 1).

    Returns
    -------
    list of float
        ``[along x, along z]`` scan times, s.
    """
    x_lo, z_lo, x_hi, z_hi = (float(b) for b in box)
    cur = np.ascontiguousarray(cur, dtype=np.float64).reshape(-1, 2)
    cost = []
    for axis, (L, W) in enumerate(((x_hi - x_lo, z_hi - z_lo), (z_hi - z_lo, x_hi - x_lo))):
        ux, uz = (1.0, 0.0) if axis == 0 else (0.0, 1.0)
        cost.append(float(_scan_kernel(cur, L, W, _n_strips(W, spacing, n_agents), ux, uz,
                                       float(v))))
    return cost


def known_currents(grid, box, depth: float, t0: float, duration: float, fc=None, e: int = 0,
                   n_times: int = N_TIMES):
    """The currents at the centre of ``box`` over the episode as the method knows them.

    The true field, or given ``fc`` episode ``e``'s forecast of it
    (:func:`oneocean.tasks.routing.forecast_field`).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    box : tuple of float
        The region ``(x_lo, z_lo, x_hi, z_hi)``, m.
    depth : float
        Sampling depth, m (positive down).
    t0 : float
        Episode start time, s since the grid's ``time0_unix_s``.
    duration : float
        Episode duration, s: samples at ``n_times`` even times over ``[t0, t0 + duration]``.
    fc : (E, 5) float64, optional
        The episodes' forecast errors (``LoopState.fc``); None: the truth.
    e : int, optional
        Episode index into ``fc`` (default 0).
    n_times : int, optional
        Number of sample times (default :data:`N_TIMES`).

    Returns
    -------
    (n_times, 2) float64
        Currents (east, north), m s-1.
    """
    from ...engine.grid import sample_currents
    from ...tasks.routing import forecast_field

    x_lo, z_lo, x_hi, z_hi = box
    ts = float(t0) + np.linspace(0.0, float(duration), int(n_times))
    xyz = np.tile([0.5 * (x_lo + x_hi), float(depth), 0.5 * (z_lo + z_hi)], (ts.size, 1))
    cur = np.ascontiguousarray(sample_currents(grid, xyz, ts), dtype=np.float64)
    if fc is not None:
        cur = forecast_field(cur.reshape(ts.size, 1, 1, 2), fc, e).reshape(ts.size, 2)
    return cur


def scan_axis(cur, box, v: float, spacing: float, n_agents: int = 1) -> int:
    """Strip orientation with the shorter predicted scan (:func:`scan_times`).

    Parameters
    ----------
    cur : (n, 2) array_like
        Current samples (east, north), m s-1.
    box : tuple of float
        The region ``(x_lo, z_lo, x_hi, z_hi)``, m.
    v : float
        Speed through the water, m s-1.
    spacing : float
        Strip spacing, m.
    n_agents : int, optional
        Team size N (default 1).

    Returns
    -------
    int
        0 for strips along x (also on a tie), 1 along z.
    """
    cost = scan_times(cur, box, v, spacing, n_agents)
    return int(np.argmin(cost))


def plan_episode(grid, M: ASPolicy, box, t0: float, duration: float, n_agents: int,
                 starts=None, SP=None, fc=None, e: int = 0):
    """The method's lawnmower over one episode's region and its predicted duration.

    The strips are oriented by the shorter predicted scan (:func:`scan_times`) on the currents
    the method knows (:func:`known_currents`: ``fc`` its forecast, else the truth) and laid
    over the region extended by the navigation margins (:func:`nav_margins`, from the agents'
    known start fixes and the navigation model ``SP``; none when ``SP`` is None or the method
    knows its position), a team's blocks overlapping by :func:`team_seam`: the widest margin,
    ``NAV_K`` standard deviations down to 0 in steps of ``K_STEP``, whose predicted scan fits
    the episode's time limit less ``TIME_RESERVE`` (:func:`predicted_time`), as a survey
    planner fits its line plan to the time it has.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    M : ASPolicy
        The policy's params (:func:`params`).
    box : tuple of float
        The region ``(x_lo, z_lo, x_hi, z_hi)``, m.
    t0 : float
        Episode start time, s since the grid's ``time0_unix_s``.
    duration : float
        The episode's time limit, s.
    n_agents : int
        Team size N.
    starts : (N, 2) array_like, optional
        The agents' known start positions (x, z), m; None: no margins.
    SP : SensingParams, optional
        The method's navigation model; None: no margins.
    fc : (E, 5) float64, optional
        The episodes' forecast errors (``LoopState.fc``); None: plan on the true currents.
    e : int, optional
        Episode index into ``fc`` (default 0).

    Returns
    -------
    wps : (n_agents, n_max, 2) float64
        Waypoints (x, z) per agent, m, run-in first (:func:`with_runin`).
    count : (n_agents,) int64
        Waypoints of each agent.
    t_pred : float
        The plan's predicted duration, s.
    """
    depth = float(-sample_elevation_points(
        grid, np.array([[0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])]]),
        np.empty(1))[0]) - M.alt
    cur = known_currents(grid, box, max(depth, MIN_DEPTH_M), t0, duration, fc, e)
    n_k = int(round(NAV_K / K_STEP))
    for j in range(n_k, -1, -1):
        bx = box
        if SP is not None and starts is not None:
            m = nav_margins(SP, box, starts, duration, j * K_STEP)
            bx = (box[0] - m[0], box[1] - m[1], box[2] + m[2], box[3] + m[3])
        seam = [team_seam(SP, bx, starts, duration, ax, j * K_STEP) for ax in (0, 1)]
        # each orientation's scan over the width its seams add (strips along x: z widens)
        cost = [scan_times(cur, (bx[0], bx[1], bx[2], bx[3] + (n_agents - 1) * seam[0]),
                           M.v_max, M.spacing, n_agents)[0],
                scan_times(cur, (bx[0], bx[1], bx[2] + (n_agents - 1) * seam[1], bx[3]),
                           M.v_max, M.spacing, n_agents)[1]]
        axis = int(np.argmin(cost))
        wps, cnt = with_runin(*plan_lawnmower(bx, axis, M.spacing, n_agents, seam[axis]))
        t_pred = predicted_time(wps, cnt, cost[axis], starts, M.v_max, n_agents)
        if (t_pred <= (1.0 - TIME_RESERVE) * duration or j == 0
                or (bx == box and seam[axis] == 0.0)):
            return wps, cnt, t_pred
    raise AssertionError("unreachable")


def predicted_time(wps, count, scan: float, starts, v: float, n_agents: int) -> float:
    """Predicted duration of a plan.

    Its scan (:func:`scan_times`, the team's strips shared between ``n_agents``; the turns at
    the strip ends and the terrain following are left out), plus the longest transit from an
    agent's start to its run-in waypoint and the run-in, at ``v``.

    Parameters
    ----------
    wps : (n_agents, n_max, 2) float64
        The plan's waypoints (x, z), m, run-in first.
    count : (n_agents,) int64
        Waypoints of each agent (unused).
    scan : float
        The team's scan time, s (:func:`scan_times`).
    starts : (N, 2) array_like or None
        The agents' start positions (x, z), m; None: the run-in only.
    v : float
        Speed, m s-1.
    n_agents : int
        Team size N.

    Returns
    -------
    float
        Predicted duration, s.
    """
    t = scan / max(1, int(n_agents))
    lead = 0.0
    for i in range(wps.shape[0]):
        d = RUNIN_M
        if starts is not None:
            s = np.asarray(starts, dtype=np.float64).reshape(-1, 2)[min(i, len(starts) - 1)]
            d += float(np.hypot(*(wps[i, 0] - s)))
        lead = max(lead, d / max(v, 1e-3))
    return t + lead


def with_runin(wps, count, runin: float = RUNIN_M):
    """The waypoints with a run-in waypoint prepended per agent.

    The run-in lies ``runin`` m before the first strip's start, on the strip's line (outside
    the region, inside its water margin).

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


def prepare(grid, P, W, M: ASPolicy, t0, LP=None, LS=None, X=None) -> None:
    """The Python planner: write the plan tokens of every episode not yet planned.

    Before the episode's first step: ``W.wps``, ``W.wcount``, ``W.widx = 0`` and ``W.tgt`` (the
    first waypoint at the commanded altitude), from what the method knows (``LP.sens``): the
    currents (the truth, else its forecast ``LS.fc``), the agents' start positions (``X``: the
    known state) and its navigation model (the margins; none given the true position). Without
    ``LP`` / ``LS`` the truth. Idempotent (``W.planned``).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : ASParams
        The task's params (:func:`oneocean.tasks.as_.make`).
    W : ASWork
        The task's per-episode work arrays; the plan tokens are written in place.
    M : ASPolicy
        This policy's params (:func:`params`).
    t0 : (E,) float64
        Episode start times, s since the grid's ``time0_unix_s``.
    LP : LoopParams, optional
        The loop's params (:class:`oneocean.tasks.loop.LoopParams`); ``LP.sens`` says what the
        method knows. None: the truth.
    LS : LoopState, optional
        The loop's state (:class:`oneocean.tasks.loop.LoopState`); ``LS.fc`` (E, 5) is each
        episode's forecast error. None: the truth.
    X : (E, N, STATE_DIM) float64, optional
        The agents' state as the method knows it before the first step
        (:attr:`oneocean.tasks.episodes.Episodes.known_state`).

    Raises
    ------
    RuntimeError
        If a plan has more waypoints per agent than the plan-token array holds.
    """
    todo = np.flatnonzero(W.planned == 0)
    if todo.size == 0:
        return
    n_ag = W.wcount.shape[1]
    SP = None if LP is None else LP.sens
    use_fc = SP is not None and LS is not None and SP.true_current == 0
    for e in todo:
        starts = None if X is None else np.asarray(X[e, :, :][:, [0, 2]], dtype=np.float64)
        wps, cnt, _ = plan_episode(grid, M, tuple(W.region[e]), t0[e], P.t_lim, n_ag,
                                   starts, SP, LS.fc if use_fc else None, int(e))
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
    """Agent ``i``'s action: line-of-sight strip tracking, terrain following, teammate repulsion.

    The carrot of its waypoint list (:func:`~oneocean.tasks.common.waypoint_carrot`) at
    ``M.alt`` above the seafloor (never shallower than ``MIN_DEPTH_M``) is written to
    ``W.tgt[e, i]`` and sought with :func:`~oneocean.tasks.common.seek_max`; teammates closer
    than ``SEP_M`` add a horizontal repulsion.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : ASParams
        The task's params (:func:`oneocean.tasks.as_.make`).
    W : ASWork
        The task's per-episode work arrays (:func:`oneocean.tasks.as_.make`); reads the plan tokens
        ``wps`` / ``wcount``, advances ``widx`` and writes ``tgt``.
    M : ASPolicy
        This policy's params (:func:`params`).
    state : (E, N, STATE_DIM) float64
        Vehicle states as the method knows them (its navigation estimate; the truth for the
        oracle); layout in :mod:`oneocean.engine.dynamics`.
    e : int
        Episode index.
    k : int
        Step index.
    i : int
        Agent index.
    t : float
        Time of the step, s since the grid's ``time0_unix_s`` (``t0[e] + k dt``).
    pe, pn : float
        The method's current estimate at the agent, east and north, m s-1 (the true current
        for the oracle).

    Returns
    -------
    ax, ay, az : float
        Desired velocity relative to the water, world frame (x east, y down, z north), m s-1;
        the loop clips it to ``v_max``.
    psi : float
        Commanded heading, rad (NaN: free).
    """
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
