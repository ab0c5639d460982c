"""FH heuristic and oracle: herd the school from behind, agents on an arc around it.

A policy of the public view only (:class:`oneocean.tasks.loop.Ctx`): the briefing
(:class:`oneocean.tasks.fh.FHBriefing`: the zone, the school's depth), every agent's
observation (its navigation estimate, its current estimate and its sonar reading of the
school, :data:`oneocean.tasks.fh.OBS_EXTRA`) and the team observation
(:class:`oneocean.tasks.fh.FHTeamObs`: the school's velocity and the current at the school,
for a method given the target or the true current).

Steer from behind: the school should move toward the zone centre at the planned ground
velocity ``v = min(PUSH_SPEED_MS, KP_PUSH * distance)``; the needed swim is ``w``. The eight
agents take slots on an arc of ``ARC_RAD`` centred behind the school (opposite to ``w``) at
``standoff + SPREAD_GAIN * spread`` from the centroid, where the standoff shrinks from
``BACKOFF_M`` (no push needed) to ``STANDOFF_M`` (``|w| >= PUSH_SPEED_MS``). Agents are matched
to slots in angular order around the school (no crossings) and travel around it (waypoints at
most 45 degrees of arc ahead on the slot circle), not through it. Each agent seeks its
waypoint with P-control, feed-forward of the school's velocity and of its current estimate.
The push direction is frozen while the centroid is within ``deadband * zone_radius`` of the
centre.

Within ``I_ZONE_M`` of the zone centre an integral action on the school's velocity error
along ``w`` (its swim: ground velocity minus the current ``c`` at the centroid) adapts the
standoff (``STANDOFF_KS``, at least ``STANDOFF_MIN_M``): further back when the school runs
ahead of the plan, closer when it lags. ``w = v - c``, where ``v`` is the fastest ground
velocity toward the zone with ``|w| <= ORACLE_SWIM_MS`` (the school crabs across the current;
same ramp); the arc turns at most ``SLEW_RAD_S``; full ``v_max``, crab steering of the
vehicles (:func:`~oneocean.methods.steering.seek_max`).

What the school is (centroid, velocity, spread: the memory's ``sest``). Given the target
(``B.sens.true_target``: the oracle, the ``true_target`` ablation) the team observation's
exact fix and velocity. Otherwise the team's sonar readings: every step each seen reading is
placed where its agent knows it is (its navigation estimate plus the reading's offset) and
the placements are averaged, and an alpha-beta tracker (steady-state constant-velocity
Kalman filter, :func:`tracker_gains`) filters the centroid and estimates its velocity; the
extent is smoothed with the same alpha. Before the first reading the agents hold still. The
current at the school: given the true current (``B.sens.true_current``) the team
observation's (the truth at the school's last team fix), else the team's mean current
estimate (``cest``, each agent's at its last step; the agents are within a few tens of metres
of the school). Heuristic and oracle have the same params: they differ in information only,
and given the truth the heuristic is the oracle.

Constants (calibrated for the BlueROV2 Heavy, 0.85 m/s, and the fish model's 0.8 m/s
sustained flee with a 15 m reaction radius): the school is pushed gently (``PUSH_SPEED_MS``
0.3 m/s, ramp ``KP_PUSH`` 0.02 s-1 so it slows from 15 m out) so the vehicles keep ~0.5 m/s
for repositioning and can get ahead of it; the slots sit at the edge of the flee radius
(``STANDOFF_M`` 8 m + ``SPREAD_GAIN`` x spread, so the arc stays outside the whole school and
does not split it) and back off to ``BACKOFF_M`` 20 m (outside the 15 m flee radius) when
no push is needed.

The method's memory (:class:`FHMemory`): the school estimate, the arc state (angle behind
the school, integral standoff, slot radius), the angular matching, every agent's waypoint
(``plan`` writes them, ``act`` follows them) and every agent's last current estimate.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...tasks.common import O_CE, O_CN, O_DEPTH, O_X, O_Z
from ...tasks.fh import O_SDX, O_SDZ, O_SEEN, O_SSPREAD
from ..steering import seek_max
from . import SENSING  # noqa: F401

#: Slot-tracking proportional gain, s-1.
KP = 0.5
#: Herding arc: total angle (rad), standoff (m) and its growth with the school's spread.
ARC_RAD = math.radians(200.0)
STANDOFF_M = 8.0
SPREAD_GAIN = 1.0
#: Standoff when no push is needed (the school is where it should be), m.
BACKOFF_M = 20.0
#: Planned school ground speed toward the zone centre: min(PUSH_SPEED_MS, KP_PUSH * distance).
PUSH_SPEED_MS = 0.3
KP_PUSH = 0.02
#: The push direction is frozen while the centroid is within this fraction of the zone radius.
DEADBAND_FRAC = 0.25
#: Largest turn rate of the push direction, rad s-1 (the arc rotates around the school).
SLEW_RAD_S = 0.2
#: Largest swim speed (relative to the water) planned for the school, m s-1 (the fish swim
#: at most 0.8 m s-1).
ORACLE_SWIM_MS = 0.75
#: Rate of the standoff adaptation to the school's swim error along the planned push, m per
#: m s-1 per s.
STANDOFF_KS = 3.0
#: Smallest adapted standoff, m.
STANDOFF_MIN_M = 8.0
#: The integral action is on within this distance of the zone centre, m (beyond the push
#: ramp's ``PUSH_SPEED_MS / KP_PUSH`` = 15 m, so a school that stalls on the ramp against the
#: current is pushed in).
I_ZONE_M = 20.0
#: School tracker (every method that senses the school, :func:`tracker_gains`): the error of
#: one team-fused sonar fix of the centroid it assumes (m) and the school's manoeuvre, white
#: acceleration (m s-2).
FIX_STD_M = 0.5
SCHOOL_ACC_STD = 0.02


class FHPolicy(NamedTuple):
    """Parameters ``M`` of the FH policy (the same for heuristic and oracle).

    Attributes
    ----------
    speed : float
        Speed budget through the water, m s-1 (the vehicle's ``v_max``).
    kp : float
        Slot-tracking gain, s-1 (:data:`KP`).
    arc : float
        Herding arc, rad (:data:`ARC_RAD`).
    stand : float
        Standoff under a full push, m (:data:`STANDOFF_M`).
    sgain : float
        Standoff growth with the school's spread, m per m (:data:`SPREAD_GAIN`).
    back : float
        Standoff when no push is needed, m (:data:`BACKOFF_M`).
    push : float
        Planned school ground speed, m s-1 (:data:`PUSH_SPEED_MS`).
    oswim : float
        Largest planned school swim, m s-1 (:data:`ORACLE_SWIM_MS`).
    kpp : float
        Push ramp gain, s-1 (:data:`KP_PUSH`).
    deadband : float
        The push direction is frozen within this fraction of the zone radius
        (:data:`DEADBAND_FRAC`).
    oks : float
        Standoff adaptation rate, m per m s-1 per s (:data:`STANDOFF_KS`).
    stand_min : float
        Smallest adapted standoff, m (:data:`STANDOFF_MIN_M`).
    slew : float
        Largest turn rate of the push direction, rad s-1 (:data:`SLEW_RAD_S`).
    i_zone : float
        Integral action within this distance of the zone centre, m (:data:`I_ZONE_M`).
    fa : float
        School tracker: position gain (alpha, :func:`tracker_gains`).
    fb : float
        School tracker: velocity gain (beta), per step.
    fs : float
        School tracker: spread smoothing gain (alpha).
    """
    speed: float        # speed budget through the water, m s-1
    kp: float           # slot-tracking gain, s-1
    arc: float          # herding arc, rad
    stand: float        # standoff under a full push, m
    sgain: float        # standoff growth with the school's spread
    back: float         # standoff when no push is needed, m
    push: float         # planned school ground speed, m s-1
    oswim: float        # largest planned school swim, m s-1
    kpp: float          # push ramp gain, s-1
    deadband: float     # push direction frozen within this fraction of the zone radius
    oks: float          # standoff adaptation rate
    stand_min: float    # smallest adapted standoff, m
    slew: float         # largest turn rate of the push direction, rad s-1
    i_zone: float       # integral action within this distance of the zone centre, m
    fa: float           # school tracker: position gain (alpha)
    fb: float           # school tracker: velocity gain (beta), per step
    fs: float           # school tracker: spread smoothing gain


def tracker_gains(acc_std: float, fix_std: float, dt: float) -> tuple[float, float]:
    """Steady-state gains of a constant-velocity Kalman filter (alpha-beta tracker).

    Kalata, "The tracking index", IEEE Trans. Aerosp. Electron. Syst. 20(2), 1984: tracking
    index ``lam = acc_std dt^2 / fix_std``.

    Parameters
    ----------
    acc_std : float
        The target's white acceleration, m s-2.
    fix_std : float
        The error of one position fix, m (> 0).
    dt : float
        Fix interval, s.

    Returns
    -------
    alpha, beta : float
        Position gain and velocity gain (the velocity update is ``beta / dt`` times the
        residual, s-1).
    """
    lam = float(acc_std) * float(dt) ** 2 / float(fix_std)
    r = math.sqrt(lam * lam + 8.0 * lam)
    alpha = -(lam * lam + 8.0 * lam - (lam + 4.0) * r) / 8.0
    beta = (lam * lam + 4.0 * lam - lam * r) / 4.0
    return alpha, beta


def params(method: str, B) -> FHPolicy:
    """The policy's params: the same for every method (they differ in information only).

    Returns
    -------
    FHPolicy
        Budget ``v_max``, the module's constants and the tracker's gains.
    """
    v_max = float(B.v_max)
    fa, fb = tracker_gains(SCHOOL_ACC_STD, FIX_STD_M, float(B.dt))
    return FHPolicy(v_max, KP, ARC_RAD,
                    STANDOFF_M, SPREAD_GAIN, BACKOFF_M, PUSH_SPEED_MS, ORACLE_SWIM_MS, KP_PUSH,
                    DEADBAND_FRAC, STANDOFF_KS, STANDOFF_MIN_M, SLEW_RAD_S, I_ZONE_M, fa, fb, fa)


class FHMemory(NamedTuple):
    """The method's memory ``H`` (N agents)."""
    sest: np.ndarray    # (E, 6) school estimate: centroid x, z (m), velocity (m s-1), spread
                        #   (m), 1 once initialised
    herd: np.ndarray    # (E, 3) angle behind the school (rad), integral standoff (m), slot
                        #   radius (m)
    order: np.ndarray   # (E, N) int64 agents in angular order around the school
    keys: np.ndarray    # (E, N) angle of each agent relative to the arc centre, rad
    rank: np.ndarray    # (E, N) int64 arc slot of each agent
    tgt: np.ndarray     # (E, N, 2) waypoint (x, z) of each agent, m
    cest: np.ndarray    # (E, N, 2) each agent's current estimate at its last step, m s-1


def memory(B, M: FHPolicy) -> FHMemory:
    """A fresh memory: no school estimate yet, no current estimates (zeros).

    Returns
    -------
    FHMemory
    """
    n_ep = B.zone.shape[0]
    n = int(B.n_agents)
    return FHMemory(np.zeros((n_ep, 6)), np.zeros((n_ep, 3)), np.zeros((n_ep, n), np.int64),
                    np.zeros((n_ep, n)), np.zeros((n_ep, n), np.int64), np.zeros((n_ep, n, 2)),
                    np.zeros((n_ep, n, 2)))


@hot_kernel
def _wrap(a):
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@hot_kernel
def plan(C, e, k):
    """The team's herding plan for episode ``e``: school estimate, arc and slot waypoints.

    The school estimate ``H.sest[e]`` (the exact fix given the target, or the team's tracked
    sonar readings); push direction, arc angle and standoff (``H.herd[e]``); agents matched to
    arc slots (``H.order``, ``H.keys``, ``H.rank``); every agent's waypoint ``H.tgt[e]``
    (module doc). Before the first sonar reading every agent's waypoint is its own position.
    Policy hook (:mod:`oneocean.tasks.loop`).
    """
    B = C.B
    M = C.M
    H = C.H
    O = C.O[e]
    n = O.shape[0]
    HD = H.herd[e]
    OR = H.order[e]
    KY = H.keys[e]
    RK = H.rank[e]
    TG = H.tgt[e]
    zx = B.zone[e, 0]
    zz = B.zone[e, 1]
    zr = B.zone_radius
    dt = B.dt
    SE = H.sest[e]
    first = SE[5] == 0.0   # the first plan with a school estimate
    if B.sens.true_target != 0:
        # the school perceived exactly (oracle, true_target ablation): the team's fix
        SE[0] = C.T.fix[e, 0]
        SE[1] = C.T.fix[e, 1]
        SE[2] = C.T.vel[e, 0]
        SE[3] = C.T.vel[e, 1]
        SE[4] = C.T.fix[e, 2]
        SE[5] = 1.0
    else:
        # fuse the team's sonar readings (each agent's offset to the echo centroid from
        # where the agent knows it is) and track the centroid with an alpha-beta filter
        m = 0.0
        mx = 0.0
        mz = 0.0
        ms = 0.0
        for j in range(n):
            if O[j, O_SEEN] != 0.0:
                m += 1.0
                mx += O[j, O_X] + O[j, O_SDX]
                mz += O[j, O_Z] + O[j, O_SDZ]
                ms += O[j, O_SSPREAD]
        if SE[5] == 0.0:
            if m == 0.0:
                for j in range(n):   # nothing seen yet: hold still
                    TG[j, 0] = O[j, O_X]
                    TG[j, 1] = O[j, O_Z]
                return
            SE[0] = mx / m
            SE[1] = mz / m
            SE[2] = 0.0
            SE[3] = 0.0
            SE[4] = ms / m
            SE[5] = 1.0
        else:
            SE[0] += SE[2] * dt
            SE[1] += SE[3] * dt
            if m > 0.0:
                rx = mx / m - SE[0]
                rz = mz / m - SE[1]
                SE[0] += M.fa * rx
                SE[1] += M.fa * rz
                SE[2] += M.fb / dt * rx
                SE[3] += M.fb / dt * rz
                SE[4] += M.fs * (ms / m - SE[4])
    cxs = SE[0]
    czs = SE[1]
    vcx = SE[2]
    vcz = SE[3]
    th_back = HD[0]
    r_int = HD[1]
    push = M.push
    oswim = M.oswim
    kpp = M.kpp
    stand = M.stand
    back = M.back
    slew = M.slew
    arc = M.arc
    spread = SE[4]
    dxz = zx - cxs
    dzz = zz - czs
    dist = math.sqrt(dxz * dxz + dzz * dzz)
    # push direction: the swim ``w`` the school needs: the fastest ground speed toward the
    # zone whose swim, against the current at the centroid, is at most ``oswim`` (crab
    # steering of the school), ramped down near the zone. The current there: the team
    # observation's (the truth at the school's fix) given the true current, or the team's
    # mean current estimate at its last step (the agents are within a few tens of metres of
    # the school)
    ux = dxz / dist if dist > 1e-9 else 0.0
    uz = dzz / dist if dist > 1e-9 else 0.0
    if B.sens.true_current != 0:
        ce = C.T.cur[e, 0]
        cn = C.T.cur[e, 1]
    else:
        ce = 0.0
        cn = 0.0
        for j in range(n):
            ce += H.cest[e, j, 0]
            cn += H.cest[e, j, 1]
        ce /= n
        cn /= n
    cpar = ce * ux + cn * uz
    qx = ce - cpar * ux
    qz = cn - cpar * uz
    q2 = qx * qx + qz * qz
    if q2 >= oswim * oswim:
        f = oswim / math.sqrt(q2)
        wx = -qx * f
        wz = -qz * f
    else:
        vg = cpar + math.sqrt(oswim * oswim - q2)
        if vg > kpp * dist:
            vg = kpp * dist
        wx = ux * vg - ce
        wz = uz * vg - cn
    wn = math.sqrt(wx * wx + wz * wz)
    # compass angle of "behind the school": frozen near the zone centre (dead band) so the
    # arc does not flip around the school when the centroid crosses the centre, and turned
    # at most ``slew`` rad/s so the agents circle around the school, not through it
    if first:
        th_back = math.atan2(-wx, -wz)
    elif dist > M.deadband * zr:
        dth = _wrap(math.atan2(-wx, -wz) - th_back)
        if dth > slew * dt:
            dth = slew * dt
        elif dth < -slew * dt:
            dth = -slew * dt
        th_back = _wrap(th_back + dth)
    # close in when a strong push is needed, back off toward the flee radius otherwise
    g = wn / oswim
    if g > 1.0:
        g = 1.0
    r_adj = stand + (back - stand) * (1.0 - g)
    # integral action on the school's velocity error along w (closer when the school is
    # slower than planned, further back when it runs ahead), on the swim: the school's
    # (estimated) ground velocity minus the current at the centroid
    if dist < M.i_zone and k > 0 and wn > 1e-9:
        r_int += M.oks * ((vcx - ce - wx) * wx + (vcz - cn - wz) * wz) / wn * dt
        if r_int < M.stand_min - r_adj:
            r_int = M.stand_min - r_adj
        elif r_int > back - r_adj:
            r_int = back - r_adj
    else:
        r_int = 0.0
    r_adj += r_int
    r_slot = r_adj + M.sgain * spread
    HD[0] = th_back
    HD[1] = r_int
    HD[2] = r_slot
    # match agents to arc slots in angular order around the school
    for i in range(n):
        OR[i] = i
        KY[i] = _wrap(math.atan2(O[i, O_X] - cxs, O[i, O_Z] - czs) - th_back)
    for i in range(1, n):
        j = i
        while j > 0 and KY[OR[j - 1]] > KY[OR[j]]:
            tmp = OR[j - 1]
            OR[j - 1] = OR[j]
            OR[j] = tmp
            j -= 1
    for r in range(n):
        i = OR[r]
        RK[i] = r
        delta = -0.5 * arc + arc * r / (n - 1)
        # go around the school: at most 45 degrees of arc toward the slot per waypoint
        ang_i = KY[i]
        dang = delta - ang_i
        if dang > 0.25 * math.pi:
            dang = 0.25 * math.pi
        elif dang < -0.25 * math.pi:
            dang = -0.25 * math.pi
        a = th_back + ang_i + dang
        TG[i, 0] = cxs + r_slot * math.sin(a)
        TG[i, 1] = czs + r_slot * math.cos(a)


@hot_kernel
def act(C, e, k, i):
    """Seek the agent's waypoint with feed-forward of the school's velocity and the current.

    Records the agent's current estimate (its observation's) in ``H.cest[e, i]`` (the team's
    current at the school in the next :func:`plan`), then
    :func:`~oneocean.methods.steering.seek_max` toward ``H.tgt[e, i]`` at the school's depth
    ``B.depth``, the school's estimated velocity fed forward with the current. Policy hook
    (:mod:`oneocean.tasks.loop`).

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
    o = C.O[e, i]
    gx = H.tgt[e, i, 0]
    gz = H.tgt[e, i, 1]
    vcx = H.sest[e, 2]
    vcz = H.sest[e, 3]
    pe = o[O_CE]
    pn = o[O_CN]
    H.cest[e, i, 0] = pe
    H.cest[e, i, 1] = pn
    ax, ay, az = seek_max(o[O_X], o[O_DEPTH], o[O_Z], gx, C.B.depth, gz, M.speed, M.kp,
                          pe - vcx, pn - vcz)
    return ax, ay, az, math.nan
