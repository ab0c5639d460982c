"""UPL heuristic and oracle: the object as the team perceives it, greedy slot assignment,
slot seeking (a search when the object is not where the chart says), then a held lift.

Perception (``plan``, every step: the task's perception model,
:func:`oneocean.tasks.upl.perceive`, which the observation cue uses too). The team keeps one
estimate of the object's centre and velocity (``W.oest``, covariance ``W.ocov``): a
constant-velocity Kalman filter per axis (process noise ``QA_REST`` while the object rests or
sinks, ``QA_LIFT`` while the quorum lifts it), started at the site survey's chart (mission
data: ``W.chart``, its stated error ``P.survey_std`` horizontally) and updated with every
sonar fix of every ROV (``W.fix``: the measured offset of the object from the ROV,
:func:`oneocean.tasks.upl._sonar_fixes`) placed at the ROV's navigation estimate; the fix's
variance is the sonar's range and angular noise at its range, the echo centre's offset and
the USBL-aided navigation's error ``NAV_STD_M`` (horizontal). A method that perceives the
target exactly (the oracle; the ``true_target`` ablation) has the object's true centre and
velocity instead. Slot targets are the estimate plus the slots' offsets
(the object's drawing, mission data).

Assignment (``plan`` at step 0): greedy nearest (agent, slot) pairs on the estimate; an agent
whose slot was taken by another retargets the nearest free slot (``act``). Search: when an
agent reaches its charted slot (``SEARCH_ARRIVE_M``) and no ROV has a fix yet, the team
searches: every agent flies a point of a five-armed spiral about the chart (arms at the
slots' bearings, from the sonar's detection range outward by ``SEARCH_PITCH`` ranges per
fifth of a turn, the point moving at ``SEARCH_SPEED_MS``), at the slot depth kept
``SEARCH_ALTITUDE_M`` above the charted seafloor, until the first fix. Unattached agents seek
their slot with crab steering (:func:`~oneocean.tasks.common.seek_max`, P-gain ``KP``, capped
at the speed budget) and
feed-forward of the current estimate and the object's estimated velocity. Attached agents
hold their slot until the quorum is attached, then lift: desired ground velocity = slot
tracking + hold (P toward the team's site estimate -- the object's estimate when the quorum
first held --, ``KP_HOLD``, capped at ``HOLD_SPEED_MS``; computed once per step by ``plan``)
+ full upward speed; the horizontal part (incl. the current feed-forward) has priority and
the vertical part gets the rest of the speed budget.

Both methods: speed budget ``v_max``, the same logic and gains. ``heuristic``: the sensor
models of :mod:`oneocean.sensing` (USBL-aided navigation, filtered current estimate, the
object's sonar model). ``oracle``: true current, position and object (information only).

Policy state lives in the task's work arrays (:class:`oneocean.tasks.upl.UPLWork`):
``target`` (E, 5) the slot assigned to every agent, ``hold`` (E, 2) the step's hold
velocity, ``oest`` / ``ocov`` / ``odet`` the object's filter, ``srch`` the search flag,
``hsite`` the site estimate held during the lift.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...engine.dynamics import sincos
from ...engine.grid import sample_elevation
from ...tasks.common import seek_max
from ...tasks.upl import perceive, perception_setup
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
    """
    speed: float        # speed budget through the water, m s-1
    kp: float           # slot-tracking gain, s-1
    kp_hold: float      # hold gain, s-1
    hold_v: float       # hold speed cap, m s-1


def params(method: str, tier: dict, vehicle) -> UPLPolicy:
    """The policy's params (the same for heuristic and oracle).

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
    UPLPolicy
        Budget ``v_max`` and the module's gains.
    """
    v_max = float(vehicle.v_max)
    return UPLPolicy(v_max, KP, KP_HOLD, HOLD_SPEED_MS)


def prepare(grid, P, W, M: UPLPolicy, t0, LP=None, LS=None, X=None) -> None:
    """Before the first step: set up what the method perceives of the object.

    Writes ``W.pcfg`` (:func:`oneocean.tasks.upl.perception_setup`): the run seed of the
    sonar's error stream and whether the method perceives the object exactly
    (``LP.sens.true_target``: the oracle and the ``true_target`` ablation).

    Parameters
    ----------
    grid : Grid
        The grid export (unused).
    P : UPLParams
        The task's params (unused).
    W : UPLWork
        The task's per-episode work arrays; ``W.pcfg`` is written in place.
    M : UPLPolicy
        This policy's params (unused).
    t0 : (E,) float64
        Episode start times, s since the grid's ``time0_unix_s`` (unused).
    LP : LoopParams, optional
        The loop's params (:class:`oneocean.tasks.loop.LoopParams`): its seed, ``LP.sens`` and
        ``LP.e0``; None: nothing is written.
    LS : LoopState, optional
        The loop's state (unused).
    X : (E, N, STATE_DIM) float64, optional
        The agents' known state (unused).
    """
    perception_setup(W, LP)


@hot_kernel(inline="always")
def _spiral_radius(P, phi):
    """Distance of the search point from the chart after a turn of ``phi`` rad, m."""
    return P.p_range * (1.0 + SEARCH_PITCH * phi * N_SPOKES / (2.0 * math.pi))


@hot_kernel(inline="always")
def plan(grid, P, W, M, state, e, k, t):
    """The team's step: perceive the object, assign slots, search, hold the lift (module doc).

    Updates the object's estimate (:func:`oneocean.tasks.upl.perceive`); at step 0 the greedy
    nearest (agent, slot) assignment ``W.target[e]``; before the first fix the search flag and
    spiral turn ``W.srch[e]``; the site estimate ``W.hsite[e]`` when the quorum first holds;
    and the step's hold velocity ``W.hold[e]`` toward it (gain ``M.kp_hold``, capped at
    ``M.hold_v``).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : UPLParams
        The task's params (:func:`oneocean.tasks.upl.make`).
    W : UPLWork
        The task's per-episode work arrays (:func:`oneocean.tasks.upl.make`); the policy's state
        (``oest``, ``ocov``, ``odet``, ``target``, ``srch``, ``hsite``, ``hold``) is written in
        place.
    M : UPLPolicy
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
    n = state.shape[1]
    S = state[e]
    TG = W.target[e]
    off = W.slot_off[e]
    O = W.oest[e]
    perceive(P, W, state, e)
    ox = O[0]
    oy = O[1]
    oz = O[2]
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
    if W.odet[e] == 0:
        if W.srch[e, 0] == 0.0:   # arrived at the chart and nothing seen: search
            for i in range(n):
                j = TG[i]
                if ((S[i, 0] - ox - off[j, 0]) ** 2 + (S[i, 2] - oz - off[j, 2]) ** 2
                        <= SEARCH_ARRIVE_M * SEARCH_ARRIVE_M):
                    W.srch[e, 0] = 1.0
        else:   # the spiral's turn advances at the search speed along it
            W.srch[e, 1] += SEARCH_SPEED_MS * P.dt / _spiral_radius(P, W.srch[e, 1])
    if W.n_att[e] >= P.quorum and W.hsite[e, 2] == 0.0:   # the lift starts here
        W.hsite[e, 0] = ox
        W.hsite[e, 1] = oz
        W.hsite[e, 2] = 1.0
    # hold: desired horizontal velocity of the assembly toward the site estimate
    kph = M.kp_hold
    hold_v = M.hold_v
    hx = kph * (W.hsite[e, 0] - ox)
    hz = kph * (W.hsite[e, 1] - oz)
    hn = math.sqrt(hx * hx + hz * hz)
    if hn > hold_v:
        hx *= hold_v / hn
        hz *= hold_v / hn
    W.hold[e, 0] = hx
    W.hold[e, 1] = hz


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    """Agent ``i``'s action: seek its slot (or its search point), or hold and lift once attached.

    An unattached agent whose slot a teammate holds retargets the nearest free slot
    (``W.target``). While the team searches, the slot's horizontal position is replaced by the
    agent's point of the search spiral, at the slot depth but at least ``SEARCH_ALTITUDE_M``
    above the seafloor there (and at least 1 m deep).
    An attached agent, once the quorum is attached, tracks its slot plus the hold velocity
    ``W.hold[e]`` and lifts at full speed (the horizontal part has priority); otherwise
    :func:`~oneocean.tasks.common.seek_max` toward the slot with the object's estimated
    velocity fed forward.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : UPLParams
        The task's params (:func:`oneocean.tasks.upl.make`).
    W : UPLWork
        The task's per-episode work arrays (:func:`oneocean.tasks.upl.make`); reads the attachments
        ``att`` / ``owner``, the object's estimate ``oest`` and the plan tokens, may update
        ``target``.
    M : UPLPolicy
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
    n = state.shape[1]
    speed = M.speed
    kp = M.kp
    A = W.att[e]
    O = W.owner[e]
    TG = W.target[e]
    off = W.slot_off[e]
    ox = W.oest[e, 0]
    oy = W.oest[e, 1]
    oz = W.oest[e, 2]
    vx = W.oest[e, 3]
    vy = W.oest[e, 4]
    vz = W.oest[e, 5]
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
    if W.odet[e] == 0 and W.srch[e, 0] != 0.0:   # search: the agent's point of the spiral
        phi = W.srch[e, 1]
        rho = _spiral_radius(P, phi)
        hr = math.sqrt(off[j, 0] * off[j, 0] + off[j, 2] * off[j, 2])
        if hr > 0.0:
            sn, cs = sincos(phi)
            ux = off[j, 0] / hr
            uz = off[j, 2] / hr
            gx = ox + rho * (ux * cs + uz * sn)
            gz = oz + rho * (uz * cs - ux * sn)
        floor = -sample_elevation(grid, gx, gz)
        if gy > floor - SEARCH_ALTITUDE_M:
            gy = floor - SEARCH_ALTITUDE_M
        if gy < 1.0:
            gy = 1.0
    if A[i] >= 0 and W.n_att[e] >= P.quorum:  # lifting
        ax = kp * (gx - px) + W.hold[e, 0] - pe
        az = kp * (gz - pz) + W.hold[e, 1] - pn
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
