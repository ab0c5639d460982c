"""UPL heuristic and oracle: greedy slot assignment, slot seeking (a search when the object is
not where the chart says), then a held lift.

A policy of the public view only (:class:`oneocean.tasks.loop.Ctx`): the briefing
(:class:`oneocean.tasks.upl.UPLBriefing`: the slots, the quorum, the sonar's range, the
chart), the team observation (:class:`oneocean.tasks.upl.UPLTeamObs`: the team's estimate of
the object, fused by the task from every ROV's sonar fixes, and whether it has a fix) and the
team's observation rows (each agent's navigation estimate, current estimate and attached
slot). Slot targets are the object's estimate plus the slots' offsets.

Assignment (``plan`` at step 0): greedy nearest (agent, slot) pairs on the estimate; an agent
whose slot was taken by another retargets the nearest free slot (``act``). Search: when an
agent reaches its charted slot (``SEARCH_ARRIVE_M``) and no ROV has a fix yet, the team
searches: every agent flies a point of a five-armed spiral about the chart (arms at the
slots' bearings, from the sonar's detection range outward by ``SEARCH_PITCH`` ranges per
fifth of a turn, the point moving at ``SEARCH_SPEED_MS``), at the slot depth kept
``SEARCH_ALTITUDE_M`` above the charted seafloor, until the first fix. Unattached agents seek
their slot with crab steering (:func:`~oneocean.methods.steering.seek_max`, P-gain ``KP``, capped
at the speed budget) and feed-forward of the current estimate and the object's estimated
velocity. Attached agents hold their slot until the quorum is attached, then lift: desired
ground velocity = slot tracking + hold (P toward the team's site estimate -- the object's
estimate when the quorum first held --, ``KP_HOLD``, capped at ``HOLD_SPEED_MS``; computed
once per step by ``plan``) + full upward speed; the horizontal part (incl. the current
feed-forward) has priority and the vertical part gets the rest of the speed budget.

Both methods: speed budget ``v_max``, the same logic and gains. ``heuristic``: the sensor
models of :mod:`oneocean.sensing` (USBL-aided navigation, filtered current estimate, the
object's sonar model). ``oracle``: true current, position and object (information only).

The method's memory (:class:`UPLMemory`): the slot assigned to every agent, the search's
state, the site held during the lift and the step's hold velocity.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...engine.dynamics import sincos
from ...engine.grid import sample_elevation
from ...tasks.common import O_CE, O_CN, O_DEPTH, O_X, O_Z, OBS_DIM
from ..steering import seek_max
from . import SENSING  # noqa: F401

#: Slot-tracking proportional gain, s-1.
KP = 0.6
#: Hold (object over the site) proportional gain, s-1, and its speed cap, m s-1.
KP_HOLD = 0.1
HOLD_SPEED_MS = 0.5
#: An agent within this horizontal distance of its charted slot with no fix starts the
#: search, m.
SEARCH_ARRIVE_M = 3.0
#: The search spiral: every agent's search point turns about the chart at this speed, m s-1,
#: starting at the sonar's detection range from the chart and moving out by
#: ``SEARCH_PITCH`` detection ranges per fifth of a turn (a teammate's pass at the same
#: bearing is then 1.6 ranges further in: the swaths, two ranges wide, overlap).
SEARCH_SPEED_MS = 0.5
SEARCH_PITCH = 1.6
#: Least altitude of the search above the charted seafloor at the spoke's end, m.
SEARCH_ALTITUDE_M = 3.0
#: Agents of the search (one per slot: the spiral's arms are the slots' bearings).
N_SPOKES = 5
#: Column of the agent's attached slot in its observation row (the task's ``slot`` field,
#: :data:`oneocean.tasks.upl.OBS_EXTRA`).
O_SLOT = OBS_DIM + 7


class UPLPolicy(NamedTuple):
    """Parameters ``M`` of the UPL policy (the same for heuristic and oracle).

    Attributes
    ----------
    speed : float
        Speed budget through the water, m s-1 (the vehicle's ``v_max``).
    kp : float
        Slot-tracking gain, s-1 (:data:`KP`).
    kp_hold : float
        Hold gain (object over the site), s-1 (:data:`KP_HOLD`).
    hold_v : float
        Hold speed cap, m s-1 (:data:`HOLD_SPEED_MS`).
    dt : float
        Step, s.
    quorum : int
        Attached agents needed to lift.
    p_range : float
        The sonar's detection range, m: the search spiral's first radius.
    """
    speed: float        # speed budget through the water, m s-1
    kp: float           # slot-tracking gain, s-1
    kp_hold: float      # hold gain, s-1
    hold_v: float       # hold speed cap, m s-1
    dt: float           # step, s
    quorum: int         # attached agents needed to lift
    p_range: float      # the sonar's detection range (the spiral's first radius), m


def params(method: str, B) -> UPLPolicy:
    """The policy's params (the same for heuristic and oracle).

    Returns
    -------
    UPLPolicy
        Budget ``v_max`` and the module's gains.
    """
    return UPLPolicy(float(B.v_max), KP, KP_HOLD, HOLD_SPEED_MS, float(B.dt), int(B.quorum),
                     float(B.p_range))


class UPLMemory(NamedTuple):
    """The method's memory ``H``.

    Attributes
    ----------
    target : (E, N) int64
        Slot assigned to each agent (-1: none yet).
    srch : (E, 2) float64
        1 while the team searches (arrived, no fix); the search spiral's turn, rad.
    hsite : (E, 3) float64
        Where the team holds the lift: its site estimate (x, z) m, set (third entry 1) when
        the quorum first holds.
    hold : (E, 2) float64
        The step's hold velocity of the assembly (x, z), m s-1.
    """
    target: np.ndarray  # (E, N) int64 slot assigned to each agent (-1: none yet)
    srch: np.ndarray    # (E, 2) 1 while the team searches; the search spiral's turn, rad
    hsite: np.ndarray   # (E, 3) the lift's site estimate (x, z) m; 1 once set
    hold: np.ndarray    # (E, 2) the step's hold velocity of the assembly (x, z), m s-1


def memory(B, M: UPLPolicy) -> UPLMemory:
    """A fresh memory: no slot assigned, no search, no lift.

    Returns
    -------
    UPLMemory
    """
    n_ep, n = B.slot_off.shape[:2]
    return UPLMemory(np.full((n_ep, n), -1, dtype=np.int64), np.zeros((n_ep, 2)),
                     np.zeros((n_ep, 3)), np.zeros((n_ep, 2)))


@hot_kernel
def _spiral_radius(M, phi):
    """Distance of the search point from the chart after a turn of ``phi`` rad, m."""
    return M.p_range * (1.0 + SEARCH_PITCH * phi * N_SPOKES / (2.0 * math.pi))


@hot_kernel
def _n_attached(O):
    """Attached agents of the team (its observation rows ``O`` (N, D): slot >= 0)."""
    n_att = 0
    for i in range(O.shape[0]):
        if O[i, O_SLOT] >= 0.0:
            n_att += 1
    return n_att


@hot_kernel
def plan(C, e, k):
    """The team's step: assign slots, search, hold the lift (module docstring).

    Writes the memory of episode ``e``: at step 0 the greedy nearest (agent, slot)
    assignment ``H.target[e]``; before the first fix the search flag and spiral turn
    ``H.srch[e]``; the site estimate ``H.hsite[e]`` when the quorum first holds; and the
    step's hold velocity ``H.hold[e]`` toward it (gain ``M.kp_hold``, capped at
    ``M.hold_v``). Policy hook (:mod:`oneocean.tasks.loop`).
    """
    M = C.M
    H = C.H
    O = C.O[e]
    n = O.shape[0]
    TG = H.target[e]
    off = C.B.slot_off[e]
    ox = C.T.obj_est[e, 0]
    oy = C.T.obj_est[e, 1]
    oz = C.T.obj_est[e, 2]
    if k == 0:
        # greedy nearest (agent, slot) assignment
        for i in range(n):
            TG[i] = -1
        for _r in range(n):
            best = np.inf
            bi = -1
            bj = -1
            for i in range(n):
                if TG[i] >= 0:
                    continue
                for j in range(n):
                    taken = False
                    for i2 in range(n):
                        if TG[i2] == j:
                            taken = True
                    if taken:
                        continue
                    d2 = ((O[i, O_X] - ox - off[j, 0]) ** 2
                          + (O[i, O_DEPTH] - oy - off[j, 1]) ** 2
                          + (O[i, O_Z] - oz - off[j, 2]) ** 2)
                    if d2 < best:
                        best = d2
                        bi = i
                        bj = j
            TG[bi] = bj
    if C.T.obj_det[e] == 0:
        if H.srch[e, 0] == 0.0:   # arrived at the chart and nothing seen: search
            for i in range(n):
                j = TG[i]
                if ((O[i, O_X] - ox - off[j, 0]) ** 2 + (O[i, O_Z] - oz - off[j, 2]) ** 2
                        <= SEARCH_ARRIVE_M * SEARCH_ARRIVE_M):
                    H.srch[e, 0] = 1.0
        else:   # the spiral's turn advances at the search speed along it
            H.srch[e, 1] += SEARCH_SPEED_MS * M.dt / _spiral_radius(M, H.srch[e, 1])
    if _n_attached(O) >= M.quorum and H.hsite[e, 2] == 0.0:   # the lift starts here
        H.hsite[e, 0] = ox
        H.hsite[e, 1] = oz
        H.hsite[e, 2] = 1.0
    # hold: desired horizontal velocity of the assembly toward the site estimate
    kph = M.kp_hold
    hold_v = M.hold_v
    hx = kph * (H.hsite[e, 0] - ox)
    hz = kph * (H.hsite[e, 1] - oz)
    hn = math.sqrt(hx * hx + hz * hz)
    if hn > hold_v:
        hx *= hold_v / hn
        hz *= hold_v / hn
    H.hold[e, 0] = hx
    H.hold[e, 1] = hz


@hot_kernel(inline="always")
def act(C, e, k, i):
    """Agent ``i``'s action: seek its slot (or its search point), or hold and lift once
    attached.

    An unattached agent whose slot a teammate holds (a teammate's observed ``slot``)
    retargets the nearest free slot (``H.target``). While the team searches, the slot's
    horizontal position is replaced by the agent's point of the search spiral, at the slot
    depth but at least ``SEARCH_ALTITUDE_M`` above the charted seafloor there (and at least
    1 m deep). An attached agent, once the quorum is attached, tracks its slot plus the hold
    velocity ``H.hold[e]`` and lifts at full speed (the horizontal part has priority);
    otherwise :func:`~oneocean.methods.steering.seek_max` toward the slot with the object's
    estimated velocity fed forward. Policy hook (:mod:`oneocean.tasks.loop`).

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
    n = O.shape[0]
    speed = M.speed
    kp = M.kp
    TG = H.target[e]
    off = C.B.slot_off[e]
    est = C.T.obj_est[e]
    ox = est[0]
    oy = est[1]
    oz = est[2]
    vx = est[3]
    vy = est[4]
    vz = est[5]
    o = O[i]
    px = o[O_X]
    py = o[O_DEPTH]
    pz = o[O_Z]
    pe = o[O_CE]
    pn = o[O_CN]
    att = int(o[O_SLOT])
    j = att
    if j < 0:
        j = TG[i]
        # the agent holding slot j, if any (-1: free)
        own = -1
        for i2 in range(n):
            if int(O[i2, O_SLOT]) == j:
                own = i2
        if own >= 0 and own != i:  # taken by a teammate: nearest free slot
            best = np.inf
            for j2 in range(n):
                free = True
                for i2 in range(n):
                    if int(O[i2, O_SLOT]) == j2:
                        free = False
                if free:
                    d2 = ((px - ox - off[j2, 0]) ** 2 + (py - oy - off[j2, 1]) ** 2
                          + (pz - oz - off[j2, 2]) ** 2)
                    if d2 < best:
                        best = d2
                        j = j2
            TG[i] = j
    gx = ox + off[j, 0]
    gy = oy + off[j, 1]
    gz = oz + off[j, 2]
    if C.T.obj_det[e] == 0 and H.srch[e, 0] != 0.0:   # search: the agent's point of the spiral
        phi = H.srch[e, 1]
        rho = _spiral_radius(M, phi)
        hr = math.sqrt(off[j, 0] * off[j, 0] + off[j, 2] * off[j, 2])
        if hr > 0.0:
            sn, cs = sincos(phi)
            ux = off[j, 0] / hr
            uz = off[j, 2] / hr
            gx = ox + rho * (ux * cs + uz * sn)
            gz = oz + rho * (uz * cs - ux * sn)
        floor = -sample_elevation(C.B.chart, gx, gz)
        if gy > floor - SEARCH_ALTITUDE_M:
            gy = floor - SEARCH_ALTITUDE_M
        if gy < 1.0:
            gy = 1.0
    if att >= 0 and _n_attached(O) >= M.quorum:  # lifting
        ax = kp * (gx - px) + H.hold[e, 0] - pe
        az = kp * (gz - pz) + H.hold[e, 1] - pn
        vy_ = kp * (gy - py) - speed
        ah = math.sqrt(ax * ax + az * az)
        if ah >= speed:
            ax *= speed / ah
            az *= speed / ah
            ay = 0.0
        else:
            vb = math.sqrt(speed * speed - ah * ah)
            ay = min(max(vy_, -vb), vb)
    else:
        ax, ay, az = seek_max(px, py, pz, gx, gy, gz, speed, kp, pe - vx, pn - vz)
        ay += vy
    return ax, ay, az, math.nan
