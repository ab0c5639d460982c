"""PI heuristic and oracle: follow one's pipeline section low over the seafloor, then report
every leak from the readings taken near it.

Survey plan (:func:`survey`, the waypoints; ``act``): agent ``i`` follows the pipeline polyline
of its section (the i-th of N equal arc-length sections) with line-of-sight guidance (carrot
``LOOKAHEAD_M`` ahead, :func:`~oneocean.tasks.common.waypoint_carrot`), terrain-following at a
low commanded altitude (never shallower than ``MIN_DEPTH_M``), crabbing against the current
(:func:`~oneocean.tasks.common.seek_max`, approach gain ``KP``). Past its last waypoint the
agent holds there and declares its section finished.

``heuristic``: altitude ``ALT_HEURISTIC_M`` (a safe bottom-following altitude), speed budget
``CRUISE_FRAC * v_max``, NOISY probed current (``probe_noise_ms``); it reports where its
largest reading near the leak was taken (:func:`peak_estimate`: the plume's peak, which an
along-pipe current carries 1-2 cells downstream of the source).

``oracle``: altitude ``ALT_ORACLE_M`` (stronger signal), exact current, full ``v_max``; it
reports the plume's *upstream edge* (:func:`onset_estimate`): with ``b`` the background
(smallest reading near the leak: upstream water, possibly carrying an upstream leak's plume),
the weighted centroid (weights ``reading - b``) of the readings >= ``b + ONSET_FRAC (peak -
b)`` lying within ``ONSET_BAND_M`` (along the current) of the most upstream such reading --
the plume's peak in a cross-current, its onset in an along-pipe current.

Policy state lives in the task's work arrays (:class:`oneocean.tasks.pi.PIWork`): the plan
tokens ``wps`` / ``wcount`` (each agent's survey waypoints, from :func:`survey`), ``widx``
(the waypoint being followed), ``tgt`` (the step's carrot: the observation's goal cue),
``flow`` (the current the agent sensed at its step: the direction of the reading log's
downstream coordinate), ``done`` (section finished: the env ends the survey when every agent's
is) and ``estimator`` (which report the method files: ``PEAK`` / ``ONSET``; the env's
``finish`` calls :func:`estimate` on every detected leak, as the loop has no end-of-episode
policy hook).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...engine.grid import sample_elevation
from ...tasks.common import seek_max, waypoint_carrot
from . import SENSING  # noqa: F401

#: Heuristic speed budget through the water as a fraction of v_max.
CRUISE_FRAC = 0.75
#: Commanded altitude above the seafloor, m (heuristic, oracle).
ALT_HEURISTIC_M = 6.0
ALT_ORACLE_M = 2.5
#: Line-of-sight lookahead, m; approach gain, s-1; waypoint tolerance, m; shallowest
#: commanded depth, m.
LOOKAHEAD_M = 12.0
KP = 0.5
WP_TOL_M = 1.0
MIN_DEPTH_M = 1.0
#: Oracle's estimator: readings >= b + ONSET_FRAC (peak - b) whose downstream coordinate is
#: within ONSET_BAND_M (m) of the most upstream one are averaged, weights reading - b.
ONSET_FRAC = 0.5
ONSET_BAND_M = 10.0
#: Leak estimators (``PIPolicy.estimator``, ``PIWork.estimator``).
PEAK, ONSET = 0, 1


class PIPolicy(NamedTuple):
    budget: float       # speed budget through the water, m s-1
    kp: float           # approach gain, s-1
    alt: float          # commanded altitude above the seafloor, m
    look: float         # line-of-sight lookahead, m
    estimator: int      # PEAK or ONSET


def params(method: str, tier: dict, vehicle) -> PIPolicy:
    v_max = float(vehicle.v_max)
    heur = method == "heuristic"
    return PIPolicy(CRUISE_FRAC * v_max if heur else v_max, KP,
                    ALT_HEURISTIC_M if heur else ALT_ORACLE_M, LOOKAHEAD_M,
                    PEAK if heur else ONSET)


def survey(init: dict):
    """The survey plan of every agent: its section of the pipeline polyline as waypoints.

    Returns
    -------
    wps : (E, N, V, 2) float64
        Waypoints [x, z] m (V: the most any agent has; rows past ``wcount`` are 0).
    wcount : (E, N) int64
        Waypoints of each agent.
    """
    from ...tasks.pi import sub_polyline  # the task's geometry (imports this module)

    poly = np.asarray(init["poly"], dtype=np.float64)
    sections = init["sections"]
    n_ep, n_ag = sections.shape[:2]
    secs = [[sub_polyline(poly[e], *sections[e, i]) for i in range(n_ag)]
            for e in range(n_ep)]
    n_max = max(len(s) for row in secs for s in row)
    wps = np.zeros((n_ep, n_ag, n_max, 2))
    wcount = np.zeros((n_ep, n_ag), dtype=np.int64)
    for e in range(n_ep):
        for i in range(n_ag):
            wps[e, i, :len(secs[e][i])] = secs[e][i]
            wcount[e, i] = len(secs[e][i])
    return wps, wcount


@hot_kernel(inline="always")
def plan(grid, P, W, M, state, e, k, t):
    if k == 0:  # the report this method files at the end (read by the env's finish)
        W.estimator[e] = M.estimator


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    s = state[e, i]
    px = s[0]
    py = s[1]
    pz = s[2]
    gx, gz, w = waypoint_carrot(W.wps, W.widx, W.wcount, e, i, px, pz, M.look, WP_TOL_M)
    W.done[e, i] = 0 if w < W.wcount[e, i] else 1
    gy = -sample_elevation(grid, gx, gz) - M.alt
    if gy < MIN_DEPTH_M:
        gy = MIN_DEPTH_M
    W.tgt[e, i, 0] = gx
    W.tgt[e, i, 1] = gy
    W.tgt[e, i, 2] = gz
    W.flow[e, i, 0] = pe
    W.flow[e, i, 1] = pn
    ax, ay, az = seek_max(px, py, pz, gx, gy, gz, M.budget, M.kp, pe, pn)
    return ax, ay, az, math.nan


@hot_kernel(inline="always")
def peak_estimate(reads, nread, peak, est, e, q):
    """Leak ``q``'s estimate: where the largest reading near it was taken (heuristic)."""
    for m in range(nread[e, q]):
        if reads[e, q, m, 2] >= peak[e, q]:
            est[e, q, 0] = reads[e, q, m, 0]
            est[e, q, 1] = reads[e, q, m, 1]
            return


@hot_kernel(inline="always")
def onset_estimate(reads, nread, peak, est, e, q):
    """Leak ``q``'s position estimate from the readings taken near it (oracle).

    A point source sits at the upstream edge of its plume. With ``b`` the smallest reading
    near the leak (the background: upstream water, possibly carrying other leaks' plumes) and
    ``lim = b + ONSET_FRAC (peak - b)``, the estimate is the concentration-weighted centroid
    of the readings >= ``lim`` lying within ``ONSET_BAND_M`` (along the probed current) of
    the most upstream of them: the plume's peak in a cross-current, its onset in an along-pipe
    current."""
    n = nread[e, q]
    b = peak[e, q]
    for m in range(n):
        if reads[e, q, m, 2] < b:
            b = reads[e, q, m, 2]
    lim = b + ONSET_FRAC * (peak[e, q] - b)
    d_min = 1e300
    for m in range(n):
        if reads[e, q, m, 2] >= lim and reads[e, q, m, 3] < d_min:
            d_min = reads[e, q, m, 3]
    wx = 0.0
    wz = 0.0
    ws = 0.0
    for m in range(n):
        r = reads[e, q, m, 2] - b
        if reads[e, q, m, 2] >= lim and reads[e, q, m, 3] <= d_min + ONSET_BAND_M:
            wx += r * reads[e, q, m, 0]
            wz += r * reads[e, q, m, 1]
            ws += r
    if ws > 0.0:
        est[e, q, 0] = wx / ws
        est[e, q, 1] = wz / ws
    else:  # flat signal: the position of the peak-level readings
        for m in range(n):
            if reads[e, q, m, 2] >= lim:
                est[e, q, 0] = reads[e, q, m, 0]
                est[e, q, 1] = reads[e, q, m, 1]
                break


@hot_kernel(inline="always")
def estimate(W, e, q):
    """Write ``W.est[e, q]``: the method's position estimate of leak ``q`` from the readings
    the env logged near it (``W.reads``), with the estimator it declared (``W.estimator``)."""
    if W.estimator[e] == ONSET:
        onset_estimate(W.reads, W.nread, W.peak, W.est, e, q)
    else:
        peak_estimate(W.reads, W.nread, W.peak, W.est, e, q)
