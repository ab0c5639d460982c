"""UPL heuristic and oracle: greedy slot assignment, slot seeking, then a held cooperative lift.

Assignment (``plan`` at step 0): greedy nearest (agent, slot) pairs; an agent whose slot was
taken by another retargets the nearest free slot (``act``). Unattached agents seek their slot
with P-control (``KP``, capped at the speed budget), feed-forward of the sensed current and of
the object's last velocity (``heuristic``: :func:`~oneocean.tasks.common.seek`; ``oracle``:
crab steering, :func:`~oneocean.tasks.common.seek_max`). Attached agents hold their slot until
the quorum is attached, then lift: desired ground velocity = slot tracking + hold (P toward the
site, ``KP_HOLD``, capped at ``HOLD_SPEED_MS``; computed once per step by ``plan``) + full
upward speed; the horizontal part (incl. the current feed-forward) has priority and the
vertical part gets the rest of the speed budget.

Both: speed budget ``v_max``, crab steering (:func:`~oneocean.tasks.common.seek_max`) toward
the slot. ``heuristic``: the sensor models of :mod:`oneocean.sensing` (USBL-aided navigation,
filtered current estimate). ``oracle``: true current and position, same logic.

Policy state lives in the task's work arrays (:class:`oneocean.tasks.upl.UPLWork`):
``target`` (E, 5) the slot assigned to every agent, ``hold`` (E, 2) the step's hold velocity.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...tasks.common import seek_max
from . import SENSING  # noqa: F401

#: Slot-tracking proportional gain, s-1.
KP = 0.6
#: Hold (object over the site) proportional gain, s-1, and its speed cap, m s-1.
KP_HOLD = 0.1
HOLD_SPEED_MS = 0.5


class UPLPolicy(NamedTuple):
    speed: float        # speed budget through the water, m s-1
    kp: float           # slot-tracking gain, s-1
    kp_hold: float      # hold gain, s-1
    hold_v: float       # hold speed cap, m s-1


def params(method: str, tier: dict, vehicle) -> UPLPolicy:
    v_max = float(vehicle.v_max)
    return UPLPolicy(v_max, KP, KP_HOLD, HOLD_SPEED_MS)


@hot_kernel(inline="always")
def plan(grid, P, W, M, state, e, k, t):
    n = state.shape[1]
    S = state[e]
    TG = W.target[e]
    off = W.slot_off[e]
    ox = W.obj[e, 0]
    oy = W.obj[e, 1]
    oz = W.obj[e, 2]
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
                    d2 = ((S[i, 0] - ox - off[j, 0]) ** 2 + (S[i, 1] - oy - off[j, 1]) ** 2
                          + (S[i, 2] - oz - off[j, 2]) ** 2)
                    if d2 < best:
                        best = d2
                        bi = i
                        bj = j
            TG[bi] = bj
    # hold: desired horizontal velocity of the assembly toward the site
    kph = M.kp_hold
    hold_v = M.hold_v
    hx = kph * (W.site[e, 0] - ox)
    hz = kph * (W.site[e, 2] - oz)
    hn = math.sqrt(hx * hx + hz * hz)
    if hn > hold_v:
        hx *= hold_v / hn
        hz *= hold_v / hn
    W.hold[e, 0] = hx
    W.hold[e, 1] = hz


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    n = state.shape[1]
    speed = M.speed
    kp = M.kp
    A = W.att[e]
    O = W.owner[e]
    TG = W.target[e]
    off = W.slot_off[e]
    ox = W.obj[e, 0]
    oy = W.obj[e, 1]
    oz = W.obj[e, 2]
    px = state[e, i, 0]
    py = state[e, i, 1]
    pz = state[e, i, 2]
    j = A[i]
    if j < 0:
        j = TG[i]
        if O[j] >= 0 and O[j] != i:  # taken by a teammate: nearest free slot
            best = np.inf
            for j2 in range(n):
                if O[j2] < 0:
                    d2 = ((px - ox - off[j2, 0]) ** 2 + (py - oy - off[j2, 1]) ** 2
                          + (pz - oz - off[j2, 2]) ** 2)
                    if d2 < best:
                        best = d2
                        j = j2
            TG[i] = j
    gx = ox + off[j, 0]
    gy = oy + off[j, 1]
    gz = oz + off[j, 2]
    if A[i] >= 0 and W.n_att[e] >= P.quorum:  # lifting
        ax = kp * (gx - px) + W.hold[e, 0] - pe
        az = kp * (gz - pz) + W.hold[e, 1] - pn
        vy = kp * (gy - py) - speed
        ah = math.sqrt(ax * ax + az * az)
        if ah >= speed:
            ax *= speed / ah
            az *= speed / ah
            ay = 0.0
        else:
            vb = math.sqrt(speed * speed - ah * ah)
            ay = min(max(vy, -vb), vb)
    else:
        ax, ay, az = seek_max(px, py, pz, gx, gy, gz, speed, kp, pe - W.vobj[e, 0],
                              pn - W.vobj[e, 2])
        ay += W.vobj[e, 1]
    return ax, ay, az, math.nan
