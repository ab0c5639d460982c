"""SPC heuristic and oracle: greedy block assignment on the aerial map, drift-compensated seek.

A policy of the public view only (:class:`oneocean.tasks.loop.Ctx`): the briefing
(:class:`oneocean.tasks.spc.SPCBriefing`: the spill report, the operating depth), the team
observation (:class:`oneocean.tasks.spc.SPCTeamObs`: the task's aerial map, its blocks'
masses and mass centroids and its time) and the agents' observations (navigation estimate,
current estimate, time).

Assignment (greedy, distinct targets first), at every new aerial map: N times, take the block
with the largest ``mass / (1 + number of agents already on it)`` (blocks lighter than
``MIN_BLOCK_FRAC`` of the mapped mass excluded) and give it to the nearest unassigned agent
(navigation estimates at the step start); its target is the block's mass centroid. Before the
first map the targets lie on a ring of radius ``spill_radius / 2`` around the spill report.
Between maps each agent moves its target with the current it estimates (the spill drifts with
the water). Steering: through-water velocity ``KP * (target - position)`` capped at the speed
budget, plus a teammate repulsion inside ``SEP_M`` (keeps >= 3 m apart; teammates' navigation
estimates at the step start), realised against the current estimate by
:func:`~oneocean.methods.steering.steer`; depth held at the briefing's operating depth (gain
``KP_DEPTH``).

Both spend the vehicle's full speed budget ``v_max`` with the same logic: they differ in
information (the heuristic: the periodic survey and the sensor models of
:mod:`oneocean.sensing`; the oracle: the exact map every step, the true current and
position), never in speed. The assignment, the targets and their time are the method's
memory (:class:`SPCMemory`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...tasks.common import O_CE, O_CN, O_DEPTH, O_T, O_X, O_Z
from ..steering import steer
from . import SENSING  # noqa: F401

#: Target-approach gain, s-1; depth-hold gain, s-1.
KP = 0.5
KP_DEPTH = 0.5
#: Teammate repulsion: active below SEP_M, speed SEP_GAIN * (SEP_M - d) (m s-1).
SEP_M = 4.5
SEP_GAIN = 1.0
#: Blocks lighter than this fraction of the mapped mass are not targets.
MIN_BLOCK_FRAC = 1e-4


class SPCPolicy(NamedTuple):
    """Parameters ``M`` of the SPC policy (the same for heuristic and oracle).

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
        Radius of the ring targets before the first map, m (``spill_radius / 2``).
    depth : float
        Operating depth, m.
    """
    budget: float       # speed budget through the water, m s-1
    kp: float           # target-approach gain, s-1
    kp_depth: float     # depth-hold gain, s-1
    sep: float          # teammate repulsion radius, m
    sep_gain: float     # repulsion gain, s-1
    ring: float         # radius of the ring targets before the first map, m
    depth: float        # operating depth, m


def params(method: str, B) -> SPCPolicy:
    """The policy's params: the same for every method (they differ in information only; the
    oracle's map is the task's, every step).

    Returns
    -------
    SPCPolicy
        Budget ``v_max``, the module's gains, the ring radius and the depth.
    """
    return SPCPolicy(float(B.v_max), KP, KP_DEPTH, SEP_M, SEP_GAIN,
                     0.5 * float(B.spill_radius), float(B.depth))


class SPCMemory(NamedTuple):
    """The method's memory ``H``: its targets and the assignment's scratch."""
    tgt: np.ndarray     # (E, N, 2) targets (x, z) at their time, m
    tmap: np.ndarray    # (E,) the targets' time (the start, then the map's), s since time0
    seen: np.ndarray    # (E,) time of the last map assigned from (NaN: none)
    cnt: np.ndarray     # (E, nb) int64 agents per block
    done: np.ndarray    # (E, N) int64 agent assigned


def memory(B, M: SPCPolicy) -> SPCMemory:
    """A fresh memory: no targets, no map seen.

    Returns
    -------
    SPCMemory
    """
    n_ep = B.t0.shape[0]
    n_ag = int(B.n_agents)
    nb = int(B.map_nbx) * int(B.map_nbz)
    return SPCMemory(np.zeros((n_ep, n_ag, 2)), np.zeros(n_ep), np.full(n_ep, np.nan),
                     np.zeros((n_ep, nb), np.int64), np.zeros((n_ep, n_ag), np.int64))


@hot_kernel
def _assign(O, bm, bx, bz, cnt, tgt, done, tot):
    """Greedy assignment: N times, the block with max mass/(1+count) -> nearest free agent
    (``O`` (N, D) the team's observation rows: navigation estimates)."""
    n_ag = O.shape[0]
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
                d = (O[i, O_X] - bx[best]) ** 2 + (O[i, O_Z] - bz[best]) ** 2
                if d < dmin:
                    dmin = d
                    ia = i
        done[ia] = 1
        cnt[best] += 1
        tgt[ia, 0] = bx[best]
        tgt[ia, 1] = bz[best]


@hot_kernel
def plan(C, e, k):
    """Ring targets around the spill report at step 0; the greedy assignment at every new
    aerial map (the team observation's ``t_map`` changed).

    Writes the memory of episode ``e``: the targets ``H.tgt[e]`` and their time
    ``H.tmap[e]`` (the step's time at step 0, then the map's). Policy hook
    (:mod:`oneocean.tasks.loop`).
    """
    B = C.B
    H = C.H
    T = C.T
    O = C.O[e]
    tgt = H.tgt[e]
    if k == 0:
        # before the first map: a ring around the reported centroid (the oracle maps at k = 0)
        n_ag = O.shape[0]
        ring = C.M.ring
        for i in range(n_ag):
            a = 2.0 * math.pi * i / n_ag
            tgt[i, 0] = B.report[e, 0] + ring * math.sin(a)
            tgt[i, 1] = B.report[e, 1] + ring * math.cos(a)
        H.tmap[e] = B.t0[e] + O[0, O_T]
    tm = T.t_map[e]
    if tm == tm and tm != H.seen[e]:   # a new map
        _assign(O, T.mass[e], T.x[e], T.z[e], H.cnt[e], tgt, H.done[e], T.total[e])
        H.tmap[e] = tm
        H.seen[e] = tm


@hot_kernel
def act(C, e, k, i):
    """Agent ``i``'s action: seek its target drifted with the estimated current, apart from
    teammates.

    The target ``H.tgt[e, i]`` drifted with the current estimate since its time; the
    through-water velocity ``M.kp (target - position)`` (capped at ``M.budget``) plus a
    teammate repulsion inside ``M.sep`` is realised against the current by
    :func:`~oneocean.methods.steering.steer`, with a depth hold toward ``M.depth`` (gain
    ``M.kp_depth``). Policy hook (:mod:`oneocean.tasks.loop`).

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
    o = O[i]
    px = o[O_X]
    py = o[O_DEPTH]
    pz = o[O_Z]
    pe = o[O_CE]
    pn = o[O_CN]
    n_ag = O.shape[0]
    age = C.B.t0[e] + o[O_T] - H.tmap[e]
    budget = M.budget
    sep = M.sep
    sep_gain = M.sep_gain
    # the target drifted with the estimated current since its time
    gx = H.tgt[e, i, 0] + pe * age
    gz = H.tgt[e, i, 1] + pn * age
    # through-water velocity toward the (drifting) target
    wx = M.kp * (gx - px)
    wz = M.kp * (gz - pz)
    w = math.sqrt(wx * wx + wz * wz)
    if w > budget:
        wx *= budget / w
        wz *= budget / w
    for j in range(n_ag):
        if j != i:
            dx = px - O[j, O_X]
            dz = pz - O[j, O_Z]
            d = math.sqrt(dx * dx + dz * dz)
            if d < sep:
                if d > 1e-6:
                    wx += sep_gain * (sep - d) * dx / d
                    wz += sep_gain * (sep - d) * dz / d
                else:
                    wx += sep_gain * sep * (1.0 if i > j else -1.0)
    ax, ay, az = steer(wx + pe, M.kp_depth * (M.depth - py), wz + pn, budget, pe, pn)
    return ax, ay, az, math.nan
