"""FT heuristic and oracle: a paced virtual centre, every agent tracking its slot around it.

A policy of the public view only (:class:`oneocean.tasks.loop.Ctx`): the briefing
(:class:`oneocean.tasks.ft.FTBriefing`: the route, the slots) and the team's observations
(each agent's navigation estimate and current estimate).

A virtual centre (the method's memory, :class:`FTMemory`) advances along the route (start
centroid to goal) at ``pace * V_NOM_FRAC * budget``, where
``pace = clip(1 - (e_max - PACE_E0_M) / PACE_E1_M, 0, 1)`` slows it when the worst agent lags
(``e_max`` = largest distance of an agent to its slot around the virtual centre at the start
of the step); for a vehicle that cannot hover (torpedo guidance) the pace never drops below
``PACE_MIN_TORPEDO``. Each agent tracks its slot (around the virtual centre at the start of
the step) with feed-forward of the virtual centre's velocity over the step plus P-control
``KP`` (capped at ``P_CAP_MS``) through :func:`~oneocean.methods.steering.steer`.

Both: ``budget = v_max``, the same logic and gains; they differ in information only
(:mod:`oneocean.sensing`): the heuristic's positions are its navigation estimates (USBL fixes
in turn fused with dead reckoning) and its current the filtered estimate; the oracle's are
the truth. Given the truth the heuristic is the oracle bit for bit
(tests/test_information_only.py).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...tasks.common import O_CE, O_CN, O_DEPTH, O_X, O_Z
from ...tasks.ft import CUE_LEAD_S
from ..steering import steer
from . import SENSING  # noqa: F401

#: Virtual-centre nominal speed as a fraction of the method's speed budget.
V_NOM_FRAC = 0.8
#: Pacing: the virtual centre slows once the worst slot lag exceeds PACE_E0_M and stops at
#: PACE_E0_M + PACE_E1_M, m.
PACE_E0_M = 1.0
PACE_E1_M = 3.0
#: Least pace for a vehicle that cannot hover (torpedo guidance): a stopped virtual centre
#: leaves a lagging torpedo orbiting its slot on its turning circle (>= 5 m for the REMUS,
#: beyond PACE_E0_M + PACE_E1_M), which would stop the centre for good.
PACE_MIN_TORPEDO = 0.4
#: Slot-tracking gain (s-1): the inverse of the lead of the task's slot cue
#: (:data:`oneocean.tasks.ft.CUE_LEAD_S`), so a policy that tracks the cue tracks the slot
#: with this gain; and the cap of the P part of the ground-velocity request (m s-1).
KP = 1.0 / CUE_LEAD_S
P_CAP_MS = 0.6


class FTPolicy(NamedTuple):
    """Parameters ``M`` of the FT policy (the same for heuristic and oracle).

    Attributes
    ----------
    budget : float
        Speed budget through the water, m s-1 (the vehicle's ``v_max``).
    v_nom : float
        Virtual-centre nominal speed (``V_NOM_FRAC * budget``), m s-1.
    kp : float
        Slot-tracking gain, s-1 (:data:`KP`).
    p_cap : float
        Cap of the P part of the ground-velocity request, m s-1 (:data:`P_CAP_MS`).
    e0 : float
        Pacing: lag where the virtual centre starts slowing, m (:data:`PACE_E0_M`).
    e1 : float
        Pacing: extra lag where it stops, m (:data:`PACE_E1_M`).
    dt : float
        Step, s.
    pace_min : float
        Least pace: 0 (may stop), :data:`PACE_MIN_TORPEDO` for vehicles that cannot hover.
    """
    budget: float   # speed budget through the water, m s-1
    v_nom: float    # virtual-centre nominal speed (V_NOM_FRAC * budget), m s-1
    kp: float       # slot-tracking gain, s-1
    p_cap: float    # cap of the P part of the ground-velocity request, m s-1
    e0: float       # pacing: lag where the virtual centre starts slowing, m
    e1: float       # pacing: extra lag where it stops, m
    dt: float       # step, s
    pace_min: float  # least pace (0: may stop; > 0 for vehicles that cannot hover)


def params(method: str, B) -> FTPolicy:
    """The policy's params: the same for every method (they differ in information only).

    Returns
    -------
    FTPolicy
        Budget ``v_max``, the module's gains and pacing, the step.
    """
    budget = float(B.v_max)
    return FTPolicy(budget, V_NOM_FRAC * budget, KP, P_CAP_MS, PACE_E0_M, PACE_E1_M,
                    float(B.dt), PACE_MIN_TORPEDO if B.guidance == 1 else 0.0)


class FTMemory(NamedTuple):
    """The method's memory ``H``: its virtual centre."""
    sigma: np.ndarray   # (E,) distance along the route, m
    vc: np.ndarray      # (E, 3) position at the start of the step, m
    vff: np.ndarray     # (E, 3) velocity over the step, m s-1


def memory(B, M: FTPolicy) -> FTMemory:
    """A fresh memory: the virtual centre at the route's start, at rest.

    Returns
    -------
    FTMemory
    """
    n_ep = B.start.shape[0]
    return FTMemory(np.zeros(n_ep), B.start.copy(), np.zeros((n_ep, 3)))


@hot_kernel
def plan(C, e, k):
    """Pace the virtual centre by the worst slot lag around it; advance it over the step.

    Writes the memory of episode ``e``: the virtual centre at the start of the step
    ``H.vc[e]``, its velocity over the step ``H.vff[e]`` and its distance along the route
    ``H.sigma[e]`` (never past the goal). Policy hook (:mod:`oneocean.tasks.loop`).
    """
    B = C.B
    M = C.M
    H = C.H
    O = C.O[e]
    n = O.shape[0]
    offsets = B.offsets
    sx = B.start[e, 0]
    sy = B.start[e, 1]
    sz = B.start[e, 2]
    lx = B.goal[e, 0] - sx
    ly = B.goal[e, 1] - sy
    lz = B.goal[e, 2] - sz
    length = math.sqrt(lx * lx + ly * ly + lz * lz)
    tx = lx / length
    ty = ly / length
    tz = lz / length
    sigma = H.sigma[e]
    dt = M.dt
    vcx = sx + sigma * tx
    vcy = sy + sigma * ty
    vcz = sz + sigma * tz
    lag = 0.0
    for i in range(n):
        d = math.sqrt((O[i, O_X] - vcx - offsets[e, i, 0]) ** 2
                      + (O[i, O_DEPTH] - vcy - offsets[e, i, 1]) ** 2
                      + (O[i, O_Z] - vcz - offsets[e, i, 2]) ** 2)
        if d > lag:
            lag = d
    pace = min(max(1.0 - (lag - M.e0) / M.e1, M.pace_min), 1.0)
    step = min(pace * M.v_nom * dt, length - sigma)
    H.sigma[e] = sigma + step
    H.vc[e, 0] = vcx
    H.vc[e, 1] = vcy
    H.vc[e, 2] = vcz
    H.vff[e, 0] = step / dt * tx
    H.vff[e, 1] = step / dt * ty
    H.vff[e, 2] = step / dt * tz


@hot_kernel
def act(C, e, k, i):
    """Track slot ``i`` around the virtual centre: feed-forward plus capped P-control.

    The desired ground velocity ``H.vff[e] + kp (slot - position)`` (the P part capped at
    ``M.p_cap``) is realised against the observed current estimate by
    :func:`~oneocean.methods.steering.steer` within ``M.budget``. Policy hook
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
    off = C.B.offsets
    o = C.O[e, i]
    kp = M.kp
    p_cap = M.p_cap
    qx = kp * (H.vc[e, 0] + off[e, i, 0] - o[O_X])
    qy = kp * (H.vc[e, 1] + off[e, i, 1] - o[O_DEPTH])
    qz = kp * (H.vc[e, 2] + off[e, i, 2] - o[O_Z])
    qn = math.sqrt(qx * qx + qy * qy + qz * qz)
    if qn > p_cap:
        f = p_cap / qn
        qx *= f
        qy *= f
        qz *= f
    ax, ay, az = steer(H.vff[e, 0] + qx, H.vff[e, 1] + qy, H.vff[e, 2] + qz, M.budget,
                       o[O_CE], o[O_CN])
    return ax, ay, az, math.nan
