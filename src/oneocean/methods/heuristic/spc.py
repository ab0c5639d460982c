"""SPC heuristic and oracle: aerial map, greedy block assignment, drift-compensated seek.

Targets come from a coarse "aerial" map: the field summed over blocks of
``BLOCK_CELLS x BLOCK_CELLS`` cells (mass and mass centroid per block). Justification: oil
spill response relies on periodic surveillance overflights (aircraft / drone SLAR, IR); a
surface vehicle's own sensor only sees the concentration under it. Assignment (greedy,
distinct targets first): N times, take the block with the largest ``mass / (1 + number of
agents already on it)`` (blocks lighter than ``MIN_BLOCK_FRAC`` of the mapped mass excluded)
and give it to the nearest unassigned agent; its target is the block's mass centroid. Between
maps each agent moves its target with the current it probes (the spill drifts with the water).
Steering: through-water velocity ``KP * (target - position)`` capped at the speed budget, plus
a teammate repulsion inside ``SEP_M`` (keeps >= 3 m apart), realised against the (probed)
current by :func:`~oneocean.tasks.common.steer`; depth held at the task's operating depth
(``P.y``, gain ``KP_DEPTH``).

``heuristic``: knows only the spill's reported initial centroid until the first overflight
(targets on a ring of radius ``spill_radius_m / 2`` around the report), then gets the aerial
map every ``aerial_period_s`` (tier; the map is what every non-oracle method gets); its
current estimate and navigation from the sensor models (:mod:`oneocean.sensing`).
``oracle``: the exact map every step (from step 0), true current and position. Both spend the
vehicle's full speed budget ``v_max``: they differ in information (stale map and sensors vs
the true field, current and position), never in speed.

The team-level decision (ring before the first map, aerial map and assignment) is
:func:`plan`; its plan tokens live in the task's work arrays ``W``: ``tgt`` (E, N, 2) targets
(x, z) at the map time, ``tmap`` (E,) the map time (s), and the scratch of the map
(``bm``/``bx``/``bz``/``cnt``/``done``). :func:`act` writes the drifted target it steers to
into ``W.aim`` (the observation's goal cue).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...tasks.common import steer
from . import SENSING  # noqa: F401

#: Aerial-map block size, cells (with the task's 10 m cells: 40 m blocks).
BLOCK_CELLS = 4
#: Target-approach gain, s-1; depth-hold gain, s-1.
KP = 0.5
KP_DEPTH = 0.5
#: Teammate repulsion: active below SEP_M, speed SEP_GAIN * (SEP_M - d) (m s-1).
SEP_M = 4.5
SEP_GAIN = 1.0
#: Blocks lighter than this fraction of the mapped mass are not targets.
MIN_BLOCK_FRAC = 1e-4


class SPCPolicy(NamedTuple):
    """Parameters ``M`` of the SPC policy (heuristic and oracle differ in their map timing).

    Attributes
    ----------
    budget : float
        Speed budget through the water, m s-1 (the vehicle's ``v_max``).
    kp : float
        Target-approach gain, s-1 (:data:`KP`).
    kp_depth : float
        Depth-hold gain, s-1 (:data:`KP_DEPTH`).
    sep : float
        Teammate repulsion radius, m (:data:`SEP_M`).
    sep_gain : float
        Repulsion gain, s-1 (:data:`SEP_GAIN`).
    ring : float
        Radius of the ring targets before the first map, m (``spill_radius_m / 2``).
    map_every : int
        A map every this many steps (heuristic: ``aerial_period_s / dt_s``; oracle: 1) ...
    map_from : int
        ... from this step on (heuristic: 1; oracle: 0).
    block : int
        Aerial-map block size, cells (:data:`BLOCK_CELLS`).
    """
    budget: float       # speed budget through the water, m s-1
    kp: float           # target-approach gain, s-1
    kp_depth: float     # depth-hold gain, s-1
    sep: float          # teammate repulsion radius, m
    sep_gain: float     # repulsion gain, s-1
    ring: float         # radius of the ring targets before the first map, m
    map_every: int      # a map every this many steps ...
    map_from: int       # ... from this step on (oracle: 0, heuristic: 1)
    block: int          # aerial-map block size, cells


def plan_tokens(grid, tier: dict, init: dict) -> dict:
    """The size of the map scratch the task carries for this policy.

    The scratch of :func:`oneocean.tasks.spc.make`: the aerial map's blocks.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    tier : dict
        The cell's tier parameters plus ``dt_s`` and ``v_max``.
    init : dict
        The cell's episodes (:func:`oneocean.tasks.spc.reset`).
        Reads the initial field ``C0`` (E, 1, nz, nx).

    Returns
    -------
    dict
        ``map_blocks``: the aerial map's blocks of the field (:func:`n_blocks`).
    """
    nz, nx = init["C0"].shape[2:]
    return {"map_blocks": n_blocks(int(nz), int(nx))}


def n_blocks(nz: int, nx: int) -> int:
    """Aerial-map blocks of an (nz, nx) field: the size of the map scratch in ``W``.

    Parameters
    ----------
    nz, nx : int
        Field cells along z (north) and x (east).

    Returns
    -------
    int
        Blocks of ``BLOCK_CELLS x BLOCK_CELLS`` cells covering the field (partial blocks at the
        edges included).
    """
    return ((nx + BLOCK_CELLS - 1) // BLOCK_CELLS) * ((nz + BLOCK_CELLS - 1) // BLOCK_CELLS)


def params(method: str, tier: dict, vehicle) -> SPCPolicy:
    """The policy's params: the heuristic maps every aerial period, the oracle every step.

    Both spend the vehicle's full speed budget with the same gains.

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
        Reads ``spill_radius_m`` (m), and for the heuristic ``aerial_period_s`` (s) and
        ``dt_s``.

    Returns
    -------
    SPCPolicy
        Budget ``v_max``, the module's gains, the ring radius and the method's map timing.
    """
    v_max = float(vehicle.v_max)
    ring = 0.5 * float(tier["spill_radius_m"])
    if method == "heuristic":
        every = max(1, int(round(float(tier["aerial_period_s"]) / float(tier["dt_s"]))))
        return SPCPolicy(v_max, KP, KP_DEPTH, SEP_M, SEP_GAIN, ring, every, 1, BLOCK_CELLS)
    return SPCPolicy(v_max, KP, KP_DEPTH, SEP_M, SEP_GAIN, ring, 1, 0, BLOCK_CELLS)


@hot_kernel
def _aerial_map(C, x0, z0, h, bsz, bm, bx, bz):
    """Block masses (kg) and mass centroids (m) of the field; returns the total mass (kg)."""
    nz = C.shape[1]
    nx = C.shape[2]
    nbx = (nx + bsz - 1) // bsz
    nb = bm.shape[0]
    for b in range(nb):
        bm[b] = 0.0
        bx[b] = 0.0
        bz[b] = 0.0
    for j in range(nz):
        for i in range(nx):
            c = C[0, j, i]
            if c > 0.0:
                b = (j // bsz) * nbx + i // bsz
                bm[b] += c
                bx[b] += c * (x0 + i * h)
                bz[b] += c * (z0 + j * h)
    tot = 0.0
    for b in range(nb):
        if bm[b] > 0.0:
            bx[b] /= bm[b]
            bz[b] /= bm[b]
            tot += bm[b]
        bm[b] *= h * h
    return tot * h * h


@hot_kernel
def _assign(S, bm, bx, bz, cnt, tgt, done, tot):
    """Greedy assignment: N times, the block with max mass/(1+count) -> nearest free agent."""
    n_ag = S.shape[0]
    nb = bm.shape[0]
    for b in range(nb):
        cnt[b] = 0
    for i in range(n_ag):
        done[i] = 0
    for _ in range(n_ag):
        best = -1
        score = 0.0
        for b in range(nb):
            if bm[b] > MIN_BLOCK_FRAC * tot:
                sc = bm[b] / (1.0 + cnt[b])
                if sc > score:
                    score = sc
                    best = b
        if best < 0:
            return
        ia = -1
        dmin = np.inf
        for i in range(n_ag):
            if done[i] == 0:
                d = (S[i, 0] - bx[best]) ** 2 + (S[i, 2] - bz[best]) ** 2
                if d < dmin:
                    dmin = d
                    ia = i
        done[ia] = 1
        cnt[best] += 1
        tgt[ia, 0] = bx[best]
        tgt[ia, 1] = bz[best]


@hot_kernel(inline="always")
def plan(grid, P, W, M, state, e, k, t):
    """Ring targets around the report at step 0; the aerial map and greedy assignment at map steps.

    At a map step (``k >= M.map_from`` and ``k % M.map_every == 0``) the field is summed into
    blocks (``W.bm``, ``W.bx``, ``W.bz``) and the agents are assigned to them greedily
    (``W.tgt[e]``); the map time ``W.tmap[e]`` is then ``t``.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : SPCParams
        The task's params (:func:`oneocean.tasks.spc.make`).
    W : SPCWork
        The task's per-episode work arrays (:func:`oneocean.tasks.spc.make`); the plan tokens
        ``tgt`` / ``tmap`` and the map scratch are written in place.
    M : SPCPolicy
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
    tgt = W.tgt[e]
    if k == 0:
        # before the first map: a ring around the reported centroid (the oracle maps at k = 0)
        n_ag = state.shape[1]
        for i in range(n_ag):
            a = 2.0 * math.pi * i / n_ag
            tgt[i, 0] = W.report[e, 0] + M.ring * math.sin(a)
            tgt[i, 1] = W.report[e, 1] + M.ring * math.cos(a)
        W.tmap[e] = t
    if k >= M.map_from and k % M.map_every == 0:
        tot = _aerial_map(W.C[e], W.origin[e, 0], W.origin[e, 1], P.h, M.block, W.bm[e],
                          W.bx[e], W.bz[e])
        _assign(state[e], W.bm[e], W.bx[e], W.bz[e], W.cnt[e], tgt, W.done[e], tot)
        W.tmap[e] = t


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    """Agent ``i``'s action: seek its target drifted with the probed current, apart from teammates.

    The target ``W.tgt[e, i]`` drifted with the current estimate since the map time is
    written to ``W.aim[e, i]`` (the observation's goal cue); the through-water velocity
    ``M.kp (aim - position)`` (capped at ``M.budget``) plus a teammate repulsion inside
    ``M.sep`` is realised against the current by :func:`~oneocean.tasks.common.steer`, with a
    depth hold toward ``P.y`` (gain ``M.kp_depth``).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P : SPCParams
        The task's params (:func:`oneocean.tasks.spc.make`).
    W : SPCWork
        The task's per-episode work arrays (:func:`oneocean.tasks.spc.make`); reads ``tgt`` /
        ``tmap``, writes ``aim``.
    M : SPCPolicy
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
    S = state[e]
    s = S[i]
    px = s[0]
    py = s[1]
    pz = s[2]
    n_ag = S.shape[0]
    age = t - W.tmap[e]
    budget = M.budget
    sep = M.sep
    sep_gain = M.sep_gain
    # the target drifted with the probed current since the map (the observation's cue)
    gx = W.tgt[e, i, 0] + pe * age
    gz = W.tgt[e, i, 1] + pn * age
    W.aim[e, i, 0] = gx
    W.aim[e, i, 1] = gz
    # through-water velocity toward the (drifting) target
    wx = M.kp * (gx - px)
    wz = M.kp * (gz - pz)
    w = math.sqrt(wx * wx + wz * wz)
    if w > budget:
        wx *= budget / w
        wz *= budget / w
    for j in range(n_ag):
        if j != i:
            dx = px - S[j, 0]
            dz = pz - S[j, 2]
            d = math.sqrt(dx * dx + dz * dz)
            if d < sep:
                if d > 1e-6:
                    wx += sep_gain * (sep - d) * dx / d
                    wz += sep_gain * (sep - d) * dz / d
                else:
                    wx += sep_gain * sep * (1.0 if i > j else -1.0)
    ax, ay, az = steer(wx + pe, M.kp_depth * (P.y - py), wz + pn, budget, pe, pn)
    return ax, ay, az, math.nan
