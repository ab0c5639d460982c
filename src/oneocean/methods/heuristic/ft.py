"""FT heuristic and oracle: a paced virtual centre, every agent tracking its slot around it.

A virtual centre advances along the route (start centroid to goal) at
``pace * V_NOM_FRAC * budget``, where ``pace = clip(1 - (e_max - PACE_E0_M) / PACE_E1_M, 0, 1)``
slows it when the worst agent lags (``e_max`` = largest distance of an agent to its slot
around the virtual centre at the start of the step); for a vehicle that cannot hover (torpedo
guidance) the pace never drops below ``PACE_MIN_TORPEDO``. Each agent tracks its slot (around the
virtual centre at the start of the step) with feed-forward of the virtual centre's velocity
over the step plus P-control ``KP`` (capped at ``P_CAP_MS``) through
:func:`~oneocean.tasks.common.steer`.

Both: ``budget = v_max``, the same logic and gains; they differ in information only
(:mod:`oneocean.sensing`): the heuristic's state is its navigation estimate (USBL fixes in
turn fused with dead reckoning) and its current the filtered estimate; the oracle's are the
truth. Given the truth the heuristic is the oracle bit for bit (tests/test_information_only.py).

The virtual centre is the plan token: ``plan`` writes its position at the start of the step
(``W.vc``, the observation's goal cue is the agent's slot around it), its velocity over the
step (``W.vff``) and its distance along the route (``W.sigma``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

from ...engine._jit import hot_kernel
from ...tasks.common import steer
from ...tasks.ft import CUE_LEAD_S
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


def params(method: str, tier: dict, vehicle) -> FTPolicy:
    """The policy's params: the same for every method (they differ in information only).

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
        Reads ``dt_s`` and the vehicle's ``guidance`` (``"torpedo"``: cannot hover).

    Returns
    -------
    FTPolicy
        Budget ``v_max``, the module's gains and pacing, the tier's step.
    """
    v_max = float(vehicle.v_max)
    budget = v_max
    torpedo = vehicle.spec.get("guidance", "holonomic") == "torpedo"
    return FTPolicy(budget, V_NOM_FRAC * budget, KP, P_CAP_MS, PACE_E0_M, PACE_E1_M,
                    float(tier["dt_s"]), PACE_MIN_TORPEDO if torpedo else 0.0)


@hot_kernel(inline="always")
def plan(grid, P, W, M, state, e, k, t):
    """Pace the virtual centre by the worst slot lag around it; advance it over the step.

    Writes the plan tokens of episode ``e``: the virtual centre at the start of the step
    ``W.vc[e]``, its velocity over the step ``W.vff[e]`` and its distance along the route
    ``W.sigma[e]`` (never past the goal).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : FTParams
        The task's params (:func:`oneocean.tasks.ft.make`).
    W : FTWork
        The task's per-episode work arrays (:func:`oneocean.tasks.ft.make`).
    M : FTPolicy
        This policy's params (:func:`params`).
    state : (E, N, STATE_DIM) float64
        Vehicle states as the method knows them (its navigation estimate; the truth for the
        oracle); layout in :mod:`oneocean.engine.dynamics`.
    e : int
        Episode index.
    k : int
        Step index.
    t : float
        Time of the step, s since the grid's ``time0_unix_s`` (``t0[e] + k dt``).
    """
    st_e = state[e]
    n = st_e.shape[0]
    offsets = W.offsets
    sx = W.start[e, 0]
    sy = W.start[e, 1]
    sz = W.start[e, 2]
    lx = W.goal[e, 0] - sx
    ly = W.goal[e, 1] - sy
    lz = W.goal[e, 2] - sz
    length = math.sqrt(lx * lx + ly * ly + lz * lz)
    tx = lx / length
    ty = ly / length
    tz = lz / length
    sigma = W.sigma[e]
    dt = M.dt
    vcx = sx + sigma * tx
    vcy = sy + sigma * ty
    vcz = sz + sigma * tz
    lag = 0.0
    for i in range(n):
        d = math.sqrt((st_e[i, 0] - vcx - offsets[e, i, 0]) ** 2
                      + (st_e[i, 1] - vcy - offsets[e, i, 1]) ** 2
                      + (st_e[i, 2] - vcz - offsets[e, i, 2]) ** 2)
        if d > lag:
            lag = d
    pace = min(max(1.0 - (lag - M.e0) / M.e1, M.pace_min), 1.0)
    step = min(pace * M.v_nom * dt, length - sigma)
    W.sigma[e] = sigma + step
    W.vc[e, 0] = vcx
    W.vc[e, 1] = vcy
    W.vc[e, 2] = vcz
    W.vff[e, 0] = step / dt * tx
    W.vff[e, 1] = step / dt * ty
    W.vff[e, 2] = step / dt * tz


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    """Track slot ``i`` around the virtual centre: feed-forward plus capped P-control.

    The desired ground velocity ``W.vff[e] + kp (slot - position)`` (the P part capped at
    ``M.p_cap``) is realised against the current estimate by
    :func:`~oneocean.tasks.common.steer` within ``M.budget``.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : FTParams
        The task's params (:func:`oneocean.tasks.ft.make`).
    W : FTWork
        The task's per-episode work arrays (:func:`oneocean.tasks.ft.make`); reads the slot offsets
        ``W.offsets`` and the plan tokens ``W.vc`` / ``W.vff``.
    M : FTPolicy
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
    s = state[e, i]
    px = s[0]
    py = s[1]
    pz = s[2]
    kp = M.kp
    p_cap = M.p_cap
    qx = kp * (W.vc[e, 0] + W.offsets[e, i, 0] - px)
    qy = kp * (W.vc[e, 1] + W.offsets[e, i, 1] - py)
    qz = kp * (W.vc[e, 2] + W.offsets[e, i, 2] - pz)
    qn = math.sqrt(qx * qx + qy * qy + qz * qz)
    if qn > p_cap:
        f = p_cap / qn
        qx *= f
        qy *= f
        qz *= f
    ax, ay, az = steer(W.vff[e, 0] + qx, W.vff[e, 1] + qy, W.vff[e, 2] + qz, M.budget, pe, pn)
    return ax, ay, az, math.nan
