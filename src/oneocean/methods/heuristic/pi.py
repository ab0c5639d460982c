"""PI heuristic and oracle: follow one's pipeline section low over the seafloor, detect plume
events in one's own readings and claim a leak position for each.

A policy of the public view only (:class:`oneocean.tasks.loop.Ctx`): the briefing
(:class:`oneocean.tasks.pi.PIBriefing`: the pipeline chart, the sections, the sensor's
threshold, the nautical chart), each agent's observation (its navigation estimate, depth,
current estimate and its latest reading, the probe) and the report it files (``C.R``, the
task's :data:`~oneocean.tasks.pi.REPORT_DOC`). Its survey plan and event memory are its own
(:class:`PIMemory`).

Survey plan (:func:`survey`, the waypoints; ``act``): agent ``i`` follows the pipeline polyline
of its section (the i-th of N equal arc-length sections) with line-of-sight guidance (carrot
``LOOKAHEAD_M`` ahead, :func:`~oneocean.tasks.waypoints.waypoint_carrot`), terrain-following at a
low commanded altitude over the chart's seafloor (never shallower than ``MIN_DEPTH_M``),
crabbing against the sensed current (:func:`~oneocean.methods.steering.seek_max`, approach gain
``KP``) with the vehicle's full speed budget ``v_max``. The transit to the section start ends
within ``ARRIVE_M`` (beyond a torpedo's turning circle: closer arrival radii make it orbit the
start for ever). Past its last waypoint the agent holds there and its section is finished.
(The plan is the task's mission route, :func:`oneocean.tasks.pi.survey_route`: the task's cue
is the same carrot.)

Event detection (:func:`detect`; both methods, from the agent's own readings only: the
observation's probe, and the method never reads the leaks or the field). While surveying
(from the section's first waypoint until the section is finished), each agent processes the
reading at its position at every decision if it is within ``ALT_BAND_M`` of its commanded
altitude (the plume's vertical profile is steep: the descent to the survey altitude inside a
plume would look like a rise). Idle, it
tracks the trough (smallest reading since its last event); a reading ``r >= thr`` (the
sensor's detection threshold) that rises at least ``RISE_FRAC * thr`` above the trough opens an
*event* (background ``b`` = the trough). The event logs its readings (position, value,
downstream coordinate: the distance from its first reading along the current the agent sensed
at that step, 0 below ``MIN_CURRENT_MS``) and closes when the reading falls back by
``DROP_FRAC`` of its prominence (``r <= peak - DROP_FRAC (peak - b)``) or the agent is more
than ``CLOSE_M`` from the event's peak (a plume carried along the pipe stays high past its
source); the trough restarts at the closing reading, so the next leak's rise on top of a
decaying plume opens a new event.

Claims (:func:`file_claim`, :func:`close_event`): every event files its own claim in the
team's report (``C.R``: x, z, strength = the event's peak reading; the memory counts the
claims filed, ``H.nclaim``, and keeps the report compact: rows ``[0, nclaim)``), updated at
every reading while it is open. When the event closes (or the agent's section is finished), a
claim whose final estimate lies within ``MERGE_M`` of another claim (the same plume seen
twice: a teammate's event at a section boundary, or the agent's own event re-opened on one
plume) merges into it, keeping the stronger event's estimate, and the report is compacted. The
merge is decided on the final estimate, not the first: an event that opens on the decaying
tail of one leak's plume, near that leak's claim, and climbs to the next leak keeps its
own claim. An event still open when the agent's section ends whose estimate lies within
``END_M`` of the agent is withdrawn (the plume was still rising where the survey stopped: its
source lies beyond the section); every agent but the first starts its survey ``OVERLAP_M``
before its section, so a leak just past a boundary is seen rising by the next agent.

Both fly at altitude ``ALT_M`` and claim the event's *upstream edge*
(:func:`onset_estimate`): with ``b`` the event's background, the weighted centroid (weights
``reading - b``) of the readings >= ``b + ONSET_FRAC (peak - b)`` lying within
``ONSET_BAND_M`` (along the current the agent knows) of the most upstream such reading -- the
plume's peak in a cross-current, its onset in an along-pipe current. (:func:`peak_estimate`,
the position of the event's largest reading, is kept as an alternative estimator.)

Both spend the full ``v_max``: they differ in information only. The heuristic's current
estimate and its navigation (so the positions it logs and claims) come from the sensor models
(:mod:`oneocean.sensing`: dead reckoning drifts along the pipe); the oracle's are the truth.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...engine.grid import sample_elevation
from ...tasks.common import O_CE, O_CN, O_DEPTH, O_PROBE, O_X, O_Z
from ...tasks.waypoints import ARRIVE_M, waypoint_carrot
from ..steering import seek_max
from . import SENSING  # noqa: F401

#: Commanded altitude above the seafloor, m: the lowest a survey AUV flies terrain-following
#: (the strongest plume signal), both methods.
ALT_M = 2.5
#: Readings count for detection only within this band around the commanded altitude, m.
ALT_BAND_M = 0.5
#: Line-of-sight lookahead, m; approach gain, s-1; waypoint tolerance, m; shallowest
#: commanded depth, m.
LOOKAHEAD_M = 12.0
KP = 0.5
WP_TOL_M = 1.0
MIN_DEPTH_M = 1.0
# The transit to the section's first waypoint ends within tasks.waypoints.ARRIVE_M: a torpedo AUV
# (remus100: turns no tighter than a 5 m radius) cannot close on a point inside its turning
# circle; with a ``2 WP_TOL_M`` arrival it orbited the section start at ~6 m for ever and never
# surveyed (leaks lie >= ``LEAK_ARC_FRAC`` of the length, >= 64 m, from the pipeline's ends,
# so nothing is missed by starting the survey this far out).
#: Event detection: an event opens at a reading >= thr rising RISE_FRAC * thr above the
#: trough; it closes when the reading falls DROP_FRAC of the event's prominence below its
#: peak, or CLOSE_M (m) past the peak's position.
RISE_FRAC = 0.5
DROP_FRAC = 0.5
CLOSE_M = 60.0
#: Readings an event keeps for its estimate (later ones still move its peak and close it).
MAX_EVENT = 512
#: A closing event whose final estimate lies within MERGE_M (m) of another claim merges into it.
MERGE_M = 50.0
#: A claim still within END_M (m) of the agent when its section ends (the plume rising where
#: the survey stops) is withdrawn; a teammate's survey starts OVERLAP_M (m) before its
#: section so that it sees the rise of a leak just past the boundary.
END_M = 20.0
OVERLAP_M = 60.0
#: Below this sensed current speed (m s-1) a reading's downstream coordinate is 0.
MIN_CURRENT_MS = 0.05
#: Oracle's estimator: readings >= b + ONSET_FRAC (peak - b) whose downstream coordinate is
#: within ONSET_BAND_M (m) of the most upstream one are averaged, weights reading - b.
ONSET_FRAC = 0.5
ONSET_BAND_M = 10.0
#: Leak estimators (``PIPolicy.estimator``).
PEAK, ONSET = 0, 1


class PIPolicy(NamedTuple):
    """Parameters ``M`` of the PI policy (the same for heuristic and oracle).

    Attributes
    ----------
    budget : float
        Speed budget through the water, m s-1 (the vehicle's ``v_max``).
    kp : float
        Approach gain, s-1 (:data:`KP`).
    alt : float
        Commanded altitude above the seafloor, m (:data:`ALT_M`).
    look : float
        Line-of-sight lookahead, m (:data:`LOOKAHEAD_M`).
    estimator : int
        Leak estimator, :data:`PEAK` or :data:`ONSET` (:func:`peak_estimate`,
        :func:`onset_estimate`).
    thr : float
        The sensor's detection threshold, kg m-3 (the briefing's ``thr``).
    """
    budget: float       # speed budget through the water, m s-1
    kp: float           # approach gain, s-1
    alt: float          # commanded altitude above the seafloor, m
    look: float         # line-of-sight lookahead, m
    estimator: int      # PEAK or ONSET
    thr: float          # the sensor's detection threshold, kg m-3


def params(method: str, B) -> PIPolicy:
    """The policy's params: the same for every method (they differ in information only).

    Returns
    -------
    PIPolicy
        Budget ``v_max``, :data:`KP`, :data:`ALT_M`, :data:`LOOKAHEAD_M`, the
        :data:`ONSET` estimator and the threshold.
    """
    return PIPolicy(float(B.v_max), KP, ALT_M, LOOKAHEAD_M, ONSET, float(B.thr))


class PIMemory(NamedTuple):
    """The method's memory ``H``: every agent's survey plan and pointer, its event detector
    and the count of the claims it filed in the report.

    Attributes
    ----------
    wps : (E, N, V, 2) float64
        Survey waypoints [x, z], m (:func:`survey`).
    wcount : (E, N) int64
        Waypoints of each agent.
    widx : (E, N) int64
        Waypoint being followed.
    tgt : (E, N, 3) float64
        The step's carrot, m.
    done : (E, N) int64
        1: the agent has finished its section.
    nclaim : (E,) int64
        Claims filed in the report (its rows ``[0, nclaim)``).
    ev_on : (E, N) int64
        1: a plume event is open.
    ev_lvl : (E, N, 3) float64
        Trough since the last event, event background, peak, kg m-3.
    ev_pos : (E, N, 4) float64
        Event origin [x, z] and peak position [x, z], m.
    ev_n : (E, N) int64
        Readings in the event buffer.
    ev_buf : (E, N, MAX_EVENT, 4) float64
        [x, z, value, downstream coordinate] of the event's readings.
    ev_claim : (E, N) int64
        The report row the open event files into (-1: none yet).
    """
    wps: np.ndarray         # (E, N, V, 2) survey waypoints [x, z], m
    wcount: np.ndarray      # (E, N) int64 waypoints of each agent
    widx: np.ndarray        # (E, N) int64 waypoint being followed
    tgt: np.ndarray         # (E, N, 3) the step's carrot, m
    done: np.ndarray        # (E, N) int64 1: the agent has finished its section
    nclaim: np.ndarray      # (E,) int64 claims filed in the report
    ev_on: np.ndarray       # (E, N) int64 1: a plume event is open
    ev_lvl: np.ndarray      # (E, N, 3) trough since the last event, event background, peak
    ev_pos: np.ndarray      # (E, N, 4) event origin [x, z] and peak position [x, z], m
    ev_n: np.ndarray        # (E, N) int64 readings in the event buffer
    ev_buf: np.ndarray      # (E, N, MAX_EVENT, 4) [x, z, value, downstream coordinate]
    ev_claim: np.ndarray    # (E, N) int64 the report row the open event files into (-1: none)


def survey(B):
    """The survey plan of every agent: its section of the briefing's pipeline as waypoints,
    from ``OVERLAP_M`` before the section's start (the first agent from the start itself) to
    the section's end (:func:`oneocean.tasks.pi.survey_route`).

    Parameters
    ----------
    B : PIBriefing
        The briefing (``pipeline`` (E, V, 2) and ``sections`` (E, N, 2), m).

    Returns
    -------
    wps : (E, N, V, 2) float64
        Waypoints [x, z], m (V: the most any agent has; rows past ``wcount`` are 0).
    wcount : (E, N) int64
        Waypoints of each agent.
    """
    from ...tasks.pi import survey_route  # the task's geometry

    return survey_route(B.pipeline, B.sections, OVERLAP_M)


def memory(B, M: PIPolicy) -> PIMemory:
    """A fresh memory: the survey plan (:func:`survey`), every agent at its transit, no event,
    no claim.

    Returns
    -------
    PIMemory
    """
    wps, wcount = survey(B)
    n_ep, n_ag = wcount.shape
    ev_lvl = np.zeros((n_ep, n_ag, 3))
    ev_lvl[..., 0] = np.inf
    return PIMemory(wps, wcount, np.zeros((n_ep, n_ag), dtype=np.int64),
                    np.zeros((n_ep, n_ag, 3)), np.zeros((n_ep, n_ag), dtype=np.int64),
                    np.zeros(n_ep, dtype=np.int64), np.zeros((n_ep, n_ag), dtype=np.int64),
                    ev_lvl, np.zeros((n_ep, n_ag, 4)), np.zeros((n_ep, n_ag), dtype=np.int64),
                    np.zeros((n_ep, n_ag, MAX_EVENT, 4)),
                    np.full((n_ep, n_ag), -1, dtype=np.int64))


@hot_kernel
def plan(C, e, k):
    """No team-level decision: every agent acts on its own readings (a no-op). Policy hook
    (:mod:`oneocean.tasks.loop`)."""
    return


@hot_kernel
def act(C, e, k, i):
    """Agent ``i``'s action: detect plume events and follow its section low over the seabed.

    While surveying at the survey altitude (within ``ALT_BAND_M`` of it, over the chart's
    seafloor at its navigation estimate) the agent's reading (the observation's probe) goes
    through :func:`detect`; the carrot of its waypoint list
    (:func:`~oneocean.tasks.waypoints.waypoint_carrot`) at ``M.alt`` above the charted seafloor
    (never shallower than ``MIN_DEPTH_M``) is kept in ``H.tgt[e, i]`` and sought with
    :func:`~oneocean.methods.steering.seek_max` against the observed current estimate. Past its
    last waypoint the section is finished (``H.done``) and an open event is closed
    (:func:`close_event` with ``at_end``). Policy hook (:mod:`oneocean.tasks.loop`).

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
    chart = C.B.chart
    o = C.O[e, i]
    px = o[O_X]
    py = o[O_DEPTH]
    pz = o[O_Z]
    pe = o[O_CE]
    pn = o[O_CN]
    # on the survey (past the transit to the section start, not finished) at the survey
    # altitude: the reading at this position (readings are comparable only at one altitude:
    # the plume's vertical profile is steep)
    if (H.widx[e, i] >= 1 and H.done[e, i] == 0
            and abs(-sample_elevation(chart, px, pz) - py - M.alt) <= ALT_BAND_M):
        detect(H, C.R, e, i, px, pz, o[O_PROBE], pe, pn, M.thr, M.estimator)
    gx, gz, w = waypoint_carrot(H.wps, H.widx, H.wcount, e, i, px, pz, M.look, WP_TOL_M,
                                ARRIVE_M)
    H.done[e, i] = 0 if w < H.wcount[e, i] else 1
    if H.done[e, i] == 1 and H.ev_on[e, i] == 1:
        close_event(H, C.R, e, i, px, pz, True)   # the section is finished: the claim is final
    gy = -sample_elevation(chart, gx, gz) - M.alt
    if gy < MIN_DEPTH_M:
        gy = MIN_DEPTH_M
    H.tgt[e, i, 0] = gx
    H.tgt[e, i, 1] = gy
    H.tgt[e, i, 2] = gz
    ax, ay, az = seek_max(px, py, pz, gx, gy, gz, M.budget, M.kp, pe, pn)
    return ax, ay, az, math.nan


@hot_kernel
def detect(H, R, e, i, x, z, r, fe, fn, thr, estimator):
    """Agent ``i``'s event detector: one reading ``r`` at ``(x, z)`` (module doc).

    Opens, extends and closes events; an open event's estimate is filed as a claim at every
    reading (:func:`file_claim`).

    Parameters
    ----------
    H : PIMemory
        The method's memory; the event memory ``ev_*`` and ``nclaim`` are updated in place.
    R : (E, MAX_CLAIMS, 3) float64
        The report (:data:`oneocean.tasks.pi.REPORT_DOC`), updated in place.
    e : int
        Episode index.
    i : int
        Agent index.
    x, z : float
        Where the reading was taken, as the agent knows it, m (east, north).
    r : float
        The reading, kg m-3.
    fe, fn : float
        The current the agent senses there, east and north, m s-1 (the reading's downstream
        coordinate is along it).
    thr : float
        The sensor's detection threshold, kg m-3 (the briefing's ``thr``).
    estimator : int
        :data:`PEAK` or :data:`ONSET`: how the event's claim position is estimated.
    """
    lvl = H.ev_lvl[e, i]   # trough, background, peak
    pos = H.ev_pos[e, i]   # origin x, z; peak x, z
    if H.ev_on[e, i] == 0:
        if r < lvl[0]:
            lvl[0] = r
        if not (r >= thr and r - lvl[0] >= RISE_FRAC * thr):
            return
        H.ev_on[e, i] = 1
        H.ev_n[e, i] = 0
        H.ev_claim[e, i] = -1
        lvl[1] = lvl[0]
        lvl[2] = r
        pos[0] = x
        pos[1] = z
        pos[2] = x
        pos[3] = z
    n = H.ev_n[e, i]
    if n < H.ev_buf.shape[2]:
        cs = math.sqrt(fe * fe + fn * fn)
        dn = 0.0
        if cs > MIN_CURRENT_MS:
            dn = ((x - pos[0]) * fe + (z - pos[1]) * fn) / cs
        b = H.ev_buf[e, i, n]
        b[0] = x
        b[1] = z
        b[2] = r
        b[3] = dn
        H.ev_n[e, i] = n + 1
    if r > lvl[2]:
        lvl[2] = r
        pos[2] = x
        pos[3] = z
    if estimator == ONSET:
        ex, ez = onset_estimate(H.ev_buf[e, i], H.ev_n[e, i], lvl[1], lvl[2])
    else:
        ex = pos[2]
        ez = pos[3]
    file_claim(H, R, e, i, ex, ez, lvl[2])
    if (r <= lvl[2] - DROP_FRAC * (lvl[2] - lvl[1])
            or (x - pos[2]) ** 2 + (z - pos[3]) ** 2 > CLOSE_M * CLOSE_M):
        close_event(H, R, e, i, x, z, False)
        lvl[0] = r


@hot_kernel
def file_claim(H, R, e, i, x, z, strength):
    """File (or update) the claim of agent ``i``'s open event in the team's report.

    The event's own claim (a new one at its first reading, dropped when the report is full)
    holds its latest estimate; a claim keeps the estimate of its strongest event.

    Parameters
    ----------
    H : PIMemory
        The method's memory; ``nclaim`` and ``ev_claim`` are updated in place.
    R : (E, MAX_CLAIMS, 3) float64
        The report, updated in place.
    e : int
        Episode index.
    i : int
        Agent index.
    x, z : float
        The event's current estimate of the leak position, m (east, north).
    strength : float
        The event's peak reading, kg m-3.
    """
    j = H.ev_claim[e, i]
    claims = R[e]
    if j < 0:
        j = H.nclaim[e]
        if j >= claims.shape[0]:
            return
        H.nclaim[e] = j + 1
        claims[j, 2] = -math.inf
        H.ev_claim[e, i] = j
    if strength >= claims[j, 2]:
        claims[j, 0] = x
        claims[j, 1] = z
        claims[j, 2] = strength


@hot_kernel
def close_event(H, R, e, i, px, pz, at_end):
    """Close agent ``i``'s open event and settle its claim; the report is kept compact.

    The claim, at the event's final estimate, merges into the nearest other final claim (not
    an open event's) within ``MERGE_M`` if there is one (the same plume seen twice: a
    teammate's at a section boundary, or the agent's own event re-opened on one plume),
    keeping the stronger event's estimate.

    Parameters
    ----------
    H : PIMemory
        The method's memory; ``ev_on``, ``ev_claim`` and ``nclaim`` are updated in place.
    R : (E, MAX_CLAIMS, 3) float64
        The report, updated in place.
    e : int
        Episode index.
    i : int
        Agent index.
    px, pz : float
        The agent's position as it knows it, m (east, north).
    at_end : bool
        The section is finished with the event open: a claim within ``END_M`` of the agent is
        withdrawn -- the plume was still rising where the survey stopped, so its source lies
        beyond the section (a teammate's, whose survey overlaps ``OVERLAP_M``).
    """
    H.ev_on[e, i] = 0
    j = H.ev_claim[e, i]
    H.ev_claim[e, i] = -1
    if j < 0:
        return
    claims = R[e]
    if at_end and (claims[j, 0] - px) ** 2 + (claims[j, 1] - pz) ** 2 <= END_M * END_M:
        drop_claim(H, R, e, j)
        return
    c_best = -1
    d_best = MERGE_M * MERGE_M
    for c in range(H.nclaim[e]):
        if c == j:
            continue
        open_ = False
        for a in range(H.ev_claim.shape[1]):
            if H.ev_claim[e, a] == c:
                open_ = True
        if open_:
            continue
        d = (claims[c, 0] - claims[j, 0]) ** 2 + (claims[c, 1] - claims[j, 1]) ** 2
        if d <= d_best:
            d_best = d
            c_best = c
    if c_best < 0:
        return
    if claims[j, 2] > claims[c_best, 2]:
        claims[c_best, 0] = claims[j, 0]
        claims[c_best, 1] = claims[j, 1]
        claims[c_best, 2] = claims[j, 2]
    drop_claim(H, R, e, j)


@hot_kernel
def drop_claim(H, R, e, j):
    """Remove claim ``j`` from the report: the last claim moves into its slot.

    An open event filing into the moved claim follows it (``H.ev_claim``); the freed last row
    is set to NaN.

    Parameters
    ----------
    H : PIMemory
        The method's memory; ``nclaim`` and ``ev_claim`` are updated in place.
    R : (E, MAX_CLAIMS, 3) float64
        The report, updated in place.
    e : int
        Episode index.
    j : int
        Row of the claim in the report ``R[e]``.
    """
    claims = R[e]
    last = H.nclaim[e] - 1
    if j != last:
        claims[j, 0] = claims[last, 0]
        claims[j, 1] = claims[last, 1]
        claims[j, 2] = claims[last, 2]
        for a in range(H.ev_claim.shape[1]):
            if H.ev_claim[e, a] == last:
                H.ev_claim[e, a] = j
    claims[last, 0] = math.nan
    claims[last, 1] = math.nan
    claims[last, 2] = math.nan
    H.nclaim[e] = last


@hot_kernel
def peak_estimate(buf, n):
    """Where the largest of an event's readings was taken (the first of equal ones).

    Parameters
    ----------
    buf : (n_max, 4) float64
        The event's readings [x (m), z (m), value (kg m-3), downstream coordinate (m)].
    n : int
        Readings in ``buf`` (>= 1).

    Returns
    -------
    x, z : float
        Position of the largest reading, m.
    """
    m_best = 0
    for m in range(1, n):
        if buf[m, 2] > buf[m_best, 2]:
            m_best = m
    return buf[m_best, 0], buf[m_best, 1]


@hot_kernel
def onset_estimate(buf, n, b, peak):
    """A source's position from its plume event's readings: the plume's upstream edge.

    A point source sits at the upstream edge of its plume. With ``lim = b + ONSET_FRAC (peak -
    b)``, the estimate is the weighted centroid (weights ``reading - b``) of the readings >=
    ``lim`` lying within ``ONSET_BAND_M`` (along the sensed current) of the most upstream of
    them: the plume's peak in a cross-current, its onset in an along-pipe current. The
    estimator of both methods (:data:`ONSET`).

    Parameters
    ----------
    buf : (n_max, 4) float64
        The event's readings [x (m), z (m), value (kg m-3), downstream coordinate (m)].
    n : int
        Readings in ``buf`` (>= 1).
    b : float
        The event's background reading, kg m-3.
    peak : float
        The event's peak reading, kg m-3.

    Returns
    -------
    x, z : float
        Estimated source position, m (a flat signal: the first reading at or above ``lim``).
    """
    lim = b + ONSET_FRAC * (peak - b)
    d_min = 1e300
    for m in range(n):
        if buf[m, 2] >= lim and buf[m, 3] < d_min:
            d_min = buf[m, 3]
    wx = 0.0
    wz = 0.0
    ws = 0.0
    for m in range(n):
        r = buf[m, 2] - b
        if buf[m, 2] >= lim and buf[m, 3] <= d_min + ONSET_BAND_M:
            wx += r * buf[m, 0]
            wz += r * buf[m, 1]
            ws += r
    if ws > 0.0:
        return wx / ws, wz / ws
    for m in range(n):   # flat signal: the first peak-level reading
        if buf[m, 2] >= lim:
            return buf[m, 0], buf[m, 1]
    return buf[0, 0], buf[0, 1]
