"""AS heuristic and oracle: a lawnmower survey with terrain following and current feed-forward.

A policy of the public view only (:class:`oneocean.tasks.loop.Ctx`): the briefing
(:class:`oneocean.tasks.as_.ASBriefing`: the region, the sensor, the start fixes, the forecast
at the region's centre, the chart) and each step's observation.

Plan
    Made in Python by :func:`prepare` before the first step, into the method's memory
    (:class:`ASMemory`: the waypoint lists per agent and each agent's place on its list).
    Strips at commanded altitude ``a_c = ALT_FRAC * max_altitude`` (so the footprint survives
    terrain-following errors), spacing at most ``2 a_c tan(half_angle) (1 - OVERLAP)`` spread
    evenly over the width (:func:`~oneocean.tasks.as_.plan_lawnmower`); the strips are split
    into contiguous blocks, one per agent (boustrophedon inside a block). Each agent's list
    starts with a run-in waypoint ``RUNIN_M`` before its first strip, on the strip's line
    (:func:`~oneocean.tasks.as_.with_runin`), so a torpedo AUV enters the region aligned with
    the strip. The strips are flown on the vehicle's navigation estimate while its footprint
    falls on the true seafloor, so dead-reckoning drift opens holidays at the region's edges.
    The planner (:func:`plan_episode`) therefore lays the strips over the region extended on
    each side by a navigation margin, ``k`` standard deviations of the dead-reckoning error it
    expects there (:func:`nav_margins`, from the start fixes and the briefing's sensor models:
    start fix, heading bias, scale factor, velocity noise), taking the widest margin, ``k``
    from ``NAV_K`` down to 0, whose predicted scan (:func:`predicted_time`) fits the time
    limit less ``TIME_RESERVE``; it orients the strips along x or z, whichever gives the
    shorter predicted scan through the briefing's current at the region's centre
    (:func:`scan_axis`).
Act
    ``act``, every agent and step, on its observation. The transit to the run-in waypoint
    ends within ``ARRIVE_M`` (wider than the vehicle's turning diameter: an underactuated
    torpedo cannot close on a point inside its turning circles and would orbit it). Strips
    are tracked with line-of-sight guidance (a carrot ``LOOKAHEAD_M`` ahead of the projection
    on the strip, :func:`~oneocean.tasks.waypoints.waypoint_carrot`), terrain-following in depth
    (the carrot's depth is the chart's seafloor depth there minus ``a_c``), crabbing against
    the observed current (:func:`~oneocean.methods.steering.seek_max`: the cross-track current is
    cancelled first); teammates closer than ``SEP_M`` (their observed navigation positions at
    the step's start) repel each other. The observation's cue (the task's own survey plan)
    is not used.

Heuristic and oracle are one policy with the same parameters (the full speed budget
``v_max`` through the water, the same altitude, overlap, planner and rules); they differ in
information only (the briefing and observation they are given). The heuristic plans on the
forecast, from its start fixes, with the margins its dead reckoning needs, and flies on its
navigation estimate and filtered current estimate (:mod:`oneocean.sensing`); the oracle plans
on the true currents from its true position, with zero margins (its position error is 0),
and flies on the truth. Given the truth the heuristic is the oracle, bit for bit.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...engine.grid import sample_elevation
from ...tasks.as_ import n_strips, plan_lawnmower, with_runin  # noqa: F401  (re-exported
from ...tasks.common import O_CE, O_CN, O_DEPTH, O_X, O_Z
from ...tasks.waypoints import ARRIVE_M, waypoint_carrot
from ...tasks.loop import noop_plan as plan  # noqa: F401  (the plan is made in Python
from ..steering import seek_max
from . import SENSING  # noqa: F401

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
# The transit to the plan's first waypoint ends within tasks.waypoints.ARRIVE_M: a torpedo AUV
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


def method_altitude(max_altitude: float) -> float:
    """Commanded altitude above the seafloor: the same for every method.

    Parameters
    ----------
    max_altitude : float
        The sensor's maximum altitude, m (the briefing's ``max_altitude``).

    Returns
    -------
    float
        ``ALT_FRAC * max_altitude``, m.
    """
    return ALT_FRAC * float(max_altitude)


def strip_spacing(max_altitude: float, half_angle_deg: float) -> float:
    """Lawnmower strip spacing at the commanded altitude: the same for every method.

    Parameters
    ----------
    max_altitude : float
        The sensor's maximum altitude, m.
    half_angle_deg : float
        The sensor's half swath angle, degrees.

    Returns
    -------
    float
        ``2 a_c tan(half_angle) (1 - OVERLAP)``, m, with ``a_c`` the :func:`method_altitude`.
    """
    return (2.0 * method_altitude(max_altitude)
            * math.tan(math.radians(float(half_angle_deg))) * (1.0 - OVERLAP))


def params(method: str, B) -> ASPolicy:
    """The policy's params: the same for the heuristic and the oracle.

    They differ in what they know only (the briefing, read by :func:`prepare`, and the
    observation).

    Returns
    -------
    ASPolicy
        Budget and ``v_max`` the vehicle's, :data:`KP`, :data:`LOOKAHEAD_M`, the
        :func:`method_altitude` and :func:`strip_spacing` of the briefing's sensor.
    """
    v_max = float(B.v_max)
    return ASPolicy(v_max, KP, LOOKAHEAD_M, method_altitude(B.max_altitude),
                    strip_spacing(B.max_altitude, B.half_angle_deg), v_max)


class ASMemory(NamedTuple):
    """The method's memory ``H``: its lawnmower
    (:func:`~oneocean.tasks.waypoints.waypoint_carrot`).

    Attributes
    ----------
    wps : (E, N, n_max, 2) float64
        Waypoints (x, z) per agent, m, run-in first.
    wcount : (E, N) int64
        Waypoints of each agent.
    widx : (E, N) int64
        Each agent's current waypoint.
    """
    wps: np.ndarray         # (E, N, n_max, 2) lawnmower waypoints (x, z) per agent, m
    wcount: np.ndarray      # (E, N) int64 waypoints of each agent
    widx: np.ndarray        # (E, N) int64 current waypoint of each agent


def memory(B, M: ASPolicy) -> ASMemory:
    """A fresh memory: room for any plan of the batch (:func:`max_waypoints`), no waypoints
    yet (:func:`prepare` plans).

    Returns
    -------
    ASMemory
    """
    n_ep, n_ag = B.start.shape[:2]
    n_max = max_waypoints(B.region, n_ag, M.spacing, B.sens, B.t_lim)
    return ASMemory(np.zeros((n_ep, n_ag, n_max, 2)), np.zeros((n_ep, n_ag), np.int64),
                    np.zeros((n_ep, n_ag), np.int64))


# ------------------------------------------------------------------------------ planning

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


def margin_bound(SP, t_lim: float, region) -> float:
    """An upper bound of :func:`nav_margins` over a batch's regions.

    Starts within ``SPAWN_REACH_M`` of a region's corner, the navigation model ``SP``'s
    errors over the whole time limit: what the memory must leave room for.

    Parameters
    ----------
    SP : SensingParams
        The method's navigation model (the briefing's ``sens``).
    t_lim : float
        The time limit, s.
    region : (E, 4) array_like
        The episodes' regions ``(x_lo, z_lo, x_hi, z_hi)``, m.

    Returns
    -------
    float
        The bound, m (0 without regions or for a method that knows its position).
    """
    region = np.asarray(region, dtype=np.float64).reshape(-1, 4)
    if region.size == 0 or SP.true_position != 0:
        return 0.0
    d = float(np.hypot(region[:, 2] - region[:, 0], region[:, 3] - region[:, 1]).max())
    d += SPAWN_REACH_M
    return NAV_K * math.sqrt(SP.start_fix_std ** 2
                             + (SP.scale_std ** 2 + SP.heading_bias_std ** 2) * d * d
                             + SP.vel_noise ** 2 * max(float(t_lim), 0.0))


def max_waypoints(region, n_agents: int, spacing: float, SP, t_lim: float) -> int:
    """Waypoints per agent that every plan of the batch fits in: the size of the memory.

    Either strip orientation, the navigation margins (:func:`margin_bound`) and a team's seams
    included.

    Parameters
    ----------
    region : (E, 4) array_like
        The episodes' regions ``(x_lo, z_lo, x_hi, z_hi)``, m.
    n_agents : int
        Team size N.
    spacing : float
        Strip spacing, m (:func:`strip_spacing`).
    SP : SensingParams
        The method's navigation model.
    t_lim : float
        The time limit, s.

    Returns
    -------
    int
        Waypoints per agent, the run-in waypoint included.
    """
    region = np.asarray(region, dtype=np.float64).reshape(-1, 4)
    sides = np.concatenate([region[:, 2] - region[:, 0], region[:, 3] - region[:, 1]])
    mb = margin_bound(SP, t_lim, region)
    width = ((float(sides.max()) if sides.size else 0.0) + 2.0 * mb
             + (int(n_agents) - 1) * math.sqrt(2.0) * mb)
    n = n_strips(width, spacing, n_agents)
    return 2 * (-(-n // int(n_agents))) + 1


@hot_kernel
def _pymax(a, b):
    """Python's ``max(a, b)``: ``b`` only if it is larger (``a`` on a tie or a NaN)."""
    return b if b > a else a


@hot_kernel
def _along_speed(ce, cn, ux, uz, v):
    """Largest ground speed along unit (ux, uz) with ``|a| <= v`` through current (ce, cn)."""
    c_par = ce * ux + cn * uz
    q2 = ce * ce + cn * cn - c_par * c_par
    if q2 >= v * v:
        return 0.0
    return _pymax(0.0, c_par + math.sqrt(v * v - q2))


@hot_kernel
def _scan_kernel(cur, L, width, n, ux, uz, v):
    """:func:`scan_times` along one axis: the mean over the samples ``cur`` (k, 2) of the
    scan of ``n`` strips of length ``L`` over ``width`` along (ux, uz)."""
    tot = 0.0
    for s in range(cur.shape[0]):
        ce = cur[s, 0]
        cn = cur[s, 1]
        strips = 0.5 * L * (1.0 / _pymax(_along_speed(ce, cn, ux, uz, v), 1e-3)
                            + 1.0 / _pymax(_along_speed(ce, cn, -ux, -uz, v), 1e-3))
        cross = width / n / _pymax(_along_speed(ce, cn, uz, ux, v), 1e-3)
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
    for axis, (L, width) in enumerate(((x_hi - x_lo, z_hi - z_lo),
                                       (z_hi - z_lo, x_hi - x_lo))):
        ux, uz = (1.0, 0.0) if axis == 0 else (0.0, 1.0)
        cost.append(float(_scan_kernel(cur, L, width, n_strips(width, spacing, n_agents), ux,
                                       uz, float(v))))
    return cost


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


def plan_episode(M: ASPolicy, box, cur, duration: float, n_agents: int, starts=None,
                 SP=None):
    """The method's lawnmower over one episode's region and its predicted duration.

    The strips are oriented by the shorter predicted scan (:func:`scan_times`) on the currents
    ``cur`` the method knows (the briefing's ``forecast_centre``: the forecast, the truth for
    the oracle) and laid over the region extended by the navigation margins
    (:func:`nav_margins`, from the agents' start fixes and the navigation model ``SP``; none
    when ``SP`` is None or the method knows its position), a team's blocks overlapping by
    :func:`team_seam`: the widest margin, ``NAV_K`` standard deviations down to 0 in steps of
    ``K_STEP``, whose predicted scan fits the episode's time limit less ``TIME_RESERVE``
    (:func:`predicted_time`), as a survey planner fits its line plan to the time it has.

    Parameters
    ----------
    M : ASPolicy
        The policy's params (:func:`params`).
    box : tuple of float
        The region ``(x_lo, z_lo, x_hi, z_hi)``, m.
    cur : (n, 2) array_like
        Current samples over the episode (east, north), m s-1.
    duration : float
        The episode's time limit, s.
    n_agents : int
        Team size N.
    starts : (N, 2) array_like, optional
        The agents' start fixes (x, z), m; None: no margins.
    SP : SensingParams, optional
        The method's navigation model (the briefing's ``sens``); None: no margins.

    Returns
    -------
    wps : (n_agents, n_max, 2) float64
        Waypoints (x, z) per agent, m, run-in first (:func:`~oneocean.tasks.as_.with_runin`).
    count : (n_agents,) int64
        Waypoints of each agent.
    t_pred : float
        The plan's predicted duration, s.
    """
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
        wps, cnt = with_runin(*plan_lawnmower(bx, axis, M.spacing, n_agents, seam[axis]),
                              RUNIN_M)
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


def prepare(B, M: ASPolicy, H: ASMemory) -> None:
    """The Python planner: plan every episode (:func:`plan_episode`) into the memory ``H``.

    From the briefing only: the region, the current at its centre (``forecast_centre``), the
    time limit, the start fixes and the sensor models (the margins; none given the true
    position). Run once, before the first step.

    Raises
    ------
    RuntimeError
        If a plan has more waypoints per agent than the memory holds.
    """
    n_ag = H.wcount.shape[1]
    for e in range(B.region.shape[0]):
        starts = np.asarray(B.start[e][:, [0, 2]], dtype=np.float64)
        wps, cnt, _ = plan_episode(M, tuple(B.region[e]), B.forecast_centre[e], B.t_lim, n_ag,
                                   starts, B.sens)
        if wps.shape[1] > H.wps.shape[2]:
            raise RuntimeError(f"AS plan of episode {e}: {wps.shape[1]} waypoints per agent, "
                               f"the memory holds {H.wps.shape[2]}")
        H.wps[e] = 0.0
        H.wps[e, :, :wps.shape[1]] = wps
        H.wcount[e] = cnt
        H.widx[e] = 0


# ------------------------------------------------------------------------------ acting

@hot_kernel
def _repulsion(O, i, n_ag):
    """Horizontal velocity (m s-1) pushing agent ``i`` away from teammates closer than
    ``SEP_M`` (their observed navigation positions, ``O`` one episode's observation rows):
    ``K_REP_MS (SEP_M - d) / SEP_M`` per teammate, along the separation."""
    rx = 0.0
    rz = 0.0
    px = O[i, O_X]
    pz = O[i, O_Z]
    for j in range(n_ag):
        if j == i:
            continue
        dx = px - O[j, O_X]
        dz = pz - O[j, O_Z]
        d = math.sqrt(dx * dx + dz * dz)
        if d < SEP_M and d > 1e-9:
            f = K_REP_MS * (SEP_M - d) / (SEP_M * d)
            rx += dx * f
            rz += dz * f
    return rx, rz


@hot_kernel
def act(C, e, k, i):
    """Agent ``i``'s action: line-of-sight strip tracking, terrain following, teammate repulsion.

    The carrot of its waypoint list in the memory
    (:func:`~oneocean.tasks.waypoints.waypoint_carrot` from the observed position) at ``M.alt``
    above the chart's seafloor (never shallower than ``MIN_DEPTH_M``), sought with
    :func:`~oneocean.methods.steering.seek_max` against the observed current; teammates closer
    than ``SEP_M`` add a horizontal repulsion. Policy hook (:mod:`oneocean.tasks.loop`).

    Returns
    -------
    ax, ay, az : float
        Desired velocity relative to the water, world frame (x east, y down, z north), m s-1;
        the loop clips it to ``v_max``.
    psi : float
        Commanded heading, rad (NaN: free).
    """
    M = C.M
    H = C.H
    O = C.O[e]
    n_ag = O.shape[0]
    o = O[i]
    px = o[O_X]
    py = o[O_DEPTH]
    pz = o[O_Z]
    gx, gz, w = waypoint_carrot(H.wps, H.widx, H.wcount, e, i, px, pz, M.look, WP_TOL_M,
                                ARRIVE_M)
    # terrain following: the carrot's depth is the seafloor there minus a_c
    gy = -sample_elevation(C.B.chart, gx, gz) - M.alt
    if gy < MIN_DEPTH_M:
        gy = MIN_DEPTH_M
    ax, ay, az = seek_max(px, py, pz, gx, gy, gz, M.budget, M.kp, o[O_CE], o[O_CN])
    if n_ag > 1:  # keep clear of teammates (their observed positions)
        rx, rz = _repulsion(O, i, n_ag)
        ax += rx
        az += rz
    return ax, ay, az, math.nan
