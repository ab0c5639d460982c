"""FH heuristic and oracle: herd the school from behind, agents on an arc around it.

Steer from behind: the school should move toward the zone centre at the planned ground
velocity ``v = min(PUSH_SPEED_MS, KP_PUSH * distance)``; the needed swim is ``w``. The eight
agents take slots on an arc of ``ARC_RAD`` centred behind the school (opposite to ``w``) at
``standoff + SPREAD_GAIN * spread`` from the centroid, where the standoff shrinks from
``BACKOFF_M`` (no push needed) to ``STANDOFF_M`` (``|w| >= PUSH_SPEED_MS``). Agents are matched
to slots in angular order around the school (no crossings) and travel around it (waypoints at
most 45 degrees of arc ahead on the slot circle), not through it. Each agent seeks its
waypoint with P-control, feed-forward of the school's velocity (centroid displacement over the
last step, ``W.school``) and of its current probe. The push direction is frozen while the
centroid is within ``deadband * zone_radius_m`` of the centre.

Both methods: within ``I_ZONE`` zone radii an integral action on the school's measured velocity error along ``w`` adapts the standoff
(``STANDOFF_KS``, at least ``STANDOFF_MIN_M``): further back when the school runs ahead of
the plan, closer when it lags.

Both: ``w = v - c`` with the current ``c`` at the centroid, where ``v`` is the fastest ground
velocity toward the zone with ``|w| <= ORACLE_SWIM_MS`` (the school crabs across the current;
same ramp); the arc turns at most ``SLEW_RAD_S`` (``DEADBAND_FRAC``); the integral acts on
the swim (ground velocity minus ``c``); full ``v_max``, crab steering of the vehicles
(:func:`~oneocean.tasks.common.seek_max`). They differ in information only: the oracle takes
``c`` from the true field and knows its position; the heuristic takes the team's mean current
estimate (``W.cest``, each agent's at its last step) and navigates by the sensor models
(:mod:`oneocean.sensing`).

Constants (calibrated for the BlueROV2 Heavy, 0.85 m/s, and the fish model's 0.8 m/s
sustained flee with a 15 m reaction radius): the school is pushed gently (``PUSH_SPEED_MS``
0.3 m/s, ramp ``KP_PUSH`` 0.02 s-1 so it slows from 15 m out) so the vehicles keep ~0.5 m/s
for repositioning and can get ahead of it; the slots sit at the edge of the flee radius
(``STANDOFF_M`` 8 m + ``SPREAD_GAIN`` x spread, so the arc stays outside the whole school and
does not split it) and back off to ``BACKOFF_M`` 20 m (outside the 15 m flee radius) when
no push is needed.

The waypoints are the plan token: ``plan`` writes every agent's waypoint ``W.tgt`` (the
observation's goal cue) from the arc state ``W.herd`` (angle behind the school, integral
standoff, slot radius) and the angular matching ``W.order`` / ``W.keys`` / ``W.rank``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from ...engine._jit import hot_kernel
from ...models.fish import school_spread
from ...tasks.common import current_at, seek_max
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
#: Oracle: largest swim speed (relative to the water) it plans for the school, m s-1 (the
#: fish swim at most 0.8 m s-1).
ORACLE_SWIM_MS = 0.75
#: Rate of the standoff adaptation to the school's speed error along the planned push, m per
#: m s-1 per s (heuristic: ground-velocity error, the drift unknown; oracle: swim error).
STANDOFF_KS = 3.0
#: Smallest adapted standoff, m.
STANDOFF_MIN_M = 8.0
#: The integral action is on within this many zone radii of the zone centre.
I_ZONE = 3.0


class FHPolicy(NamedTuple):
    oracle: int         # 1: crab-steer the school against the exact current, integral standoff
    speed: float        # speed budget through the water, m s-1
    kp: float           # slot-tracking gain, s-1
    arc: float          # herding arc, rad
    stand: float        # standoff under a full push, m
    sgain: float        # standoff growth with the school's spread
    back: float         # standoff when no push is needed, m
    push: float         # planned school ground speed, m s-1
    oswim: float        # oracle: largest planned school swim, m s-1
    kpp: float          # push ramp gain, s-1
    deadband: float     # push direction frozen within this fraction of the zone radius
    oks: float          # standoff adaptation rate
    stand_min: float    # smallest adapted standoff, m
    slew: float         # largest turn rate of the push direction, rad s-1
    i_zone: float       # integral action within this many zone radii


def params(method: str, tier: dict, vehicle) -> FHPolicy:
    v_max = float(vehicle.v_max)
    oracle = method != "heuristic"
    return FHPolicy(int(oracle), v_max, KP, ARC_RAD,
                    STANDOFF_M, SPREAD_GAIN, BACKOFF_M, PUSH_SPEED_MS, ORACLE_SWIM_MS, KP_PUSH,
                    DEADBAND_FRAC, STANDOFF_KS, STANDOFF_MIN_M, SLEW_RAD_S, I_ZONE)


@hot_kernel(inline="always")
def _wrap(a):
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@hot_kernel
def _current(grid, x, y, z, t):
    """:func:`~oneocean.tasks.common.current_at`, not inlined (once per step)."""
    return current_at(grid, x, y, z, t)


@hot_kernel(inline="always")
def plan(grid, P, W, M, state, e, k, t):
    """Push direction, arc angle and standoff; agents matched to arc slots; waypoints."""
    S = state[e]
    n = S.shape[0]
    F = W.fish[e, W.fcur[e]]
    H = W.herd[e]
    OR = W.order[e]
    KY = W.keys[e]
    RK = W.rank[e]
    TG = W.tgt[e]
    zx = W.zone[e, 0]
    zz = W.zone[e, 1]
    zr = P.zone_r
    dt = P.dt
    cxs = W.school[e, 0]
    czs = W.school[e, 1]
    vcx = W.school[e, 2]
    vcz = W.school[e, 3]
    th_back = H[0]
    r_int = H[1]
    push = M.push
    oswim = M.oswim
    kpp = M.kpp
    stand = M.stand
    back = M.back
    slew = M.slew
    arc = M.arc
    spread = school_spread(F[0], F[1])
    dxz = zx - cxs
    dzz = zz - czs
    dist = math.sqrt(dxz * dxz + dzz * dzz)
    # push direction: the swim ``w`` the school needs: the fastest ground speed toward the
    # zone whose swim, against the current at the centroid, is at most ``oswim`` (crab
    # steering of the school), ramped down near the zone. The current there: the truth
    # (oracle), or the team's mean current estimate at its last step (the agents are within
    # a few tens of metres of the school)
    ux = dxz / dist if dist > 1e-9 else 0.0
    uz = dzz / dist if dist > 1e-9 else 0.0
    if M.oracle != 0:
        ce, cn = _current(grid, cxs, P.depth, czs, t)
    else:
        ce = 0.0
        cn = 0.0
        for j in range(n):
            ce += W.cest[e, j, 0]
            cn += W.cest[e, j, 1]
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
    if k == 0:
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
    # slower than planned, further back when it runs ahead): the oracle on the swim
    # (ground velocity minus the exact current), the heuristic on the ground velocity (it
    # does not know the drift)
    if dist < M.i_zone * zr and k > 0 and wn > 1e-9:
        r_int += M.oks * ((vcx - ce - wx) * wx + (vcz - cn - wz) * wz) / wn * dt
        if r_int < M.stand_min - r_adj:
            r_int = M.stand_min - r_adj
        elif r_int > back - r_adj:
            r_int = back - r_adj
    else:
        r_int = 0.0
    r_adj += r_int
    r_slot = r_adj + M.sgain * spread
    H[0] = th_back
    H[1] = r_int
    H[2] = r_slot
    # match agents to arc slots in angular order around the school
    for i in range(n):
        OR[i] = i
        KY[i] = _wrap(math.atan2(S[i, 0] - cxs, S[i, 2] - czs) - th_back)
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


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    """Seek the agent's waypoint with feed-forward of the school's velocity and the current."""
    s = state[e, i]
    gx = W.tgt[e, i, 0]
    gz = W.tgt[e, i, 1]
    vcx = W.school[e, 2]
    vcz = W.school[e, 3]
    W.cest[e, i, 0] = pe
    W.cest[e, i, 1] = pn
    ax, ay, az = seek_max(s[0], s[1], s[2], gx, P.depth, gz, M.speed, M.kp, pe - vcx, pn - vcz)
    return ax, ay, az, math.nan
