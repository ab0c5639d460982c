"""FT — formation transit under currents (2–10 agents; default 10 as in the paper's Table V).

Objective
    Move a formation of N agents ``route_m`` metres along a straight route at one depth while
    keeping its shape: a wedge ("V") of slots ``SPACING_M`` apart along each arm
    (``WEDGE_HALF_ANGLE_DEG`` off the route axis), apex forward, offsets centred on the
    formation centroid and oriented along the route. Every slot's own straight path from start
    to goal is in valid water with ``MIN_ALTITUDE_M`` of clearance. Agents start at rest in
    their slots, facing the route.
Formation error (method-independent)
    With offsets ``o_i`` (centred) and the agents' centroid ``p_bar``, agent i's slot error is
    ``e_i = ||p_i - (p_bar + o_i)||``: the shape error, independent of any virtual leader.
Success (team, never best-of-N)
    Before ``time_limit_s``: the centroid comes within ``goal_radius_m`` of the goal while
    EVERY agent is within ``slot_tol_m`` of its slot, and during the transit, after the
    form-up allowance ``SETTLE_S`` (60 s) from the release, no agent's slot error ever
    exceeded ``max_error_m`` (exceeding it ends the episode as a failure). The allowance
    covers the release: torpedoes released at rest in a cross current are turned by it before
    their fins bite (6dof), and the team forms up on its first navigation fixes.
Navigation (every non-oracle method; ``data/sensors.yaml``, docs/sensing.md)
    The escort vessel's USBL interrogates the vehicles' transponders in turn, one per 1 s ping
    cycle (``navigation: {aid: usbl, period_s: 1, sequential: true}``): with N vehicles each
    gets a fix every N s, fused with its DVL dead reckoning. The slot error is the SHAPE
    error, so what counts is the spread of the vehicles' independent position errors (~0.6 m
    RMS for 10 vehicles); the tiers tighten the tolerances against it over a longer route.
Metrics
    ``formation_error_m`` (primary: time mean over the steps run of the RMS over agents of
    e_i, m), ``max_slot_error_m`` (largest e_i seen, m), ``final_centroid_error_m`` (centroid
    to goal when the episode ends, m). ``coll_ratio`` counts steps with the minimum pairwise
    distance <= ``R_COLL_M`` (eq. 4). It is 0 by construction while every slot error stays
    below ``(SPACING_M - R_COLL_M) / 2 = 3 m``: slots are >= ``SPACING_M`` apart, so
    ``|p_i - p_j| >= SPACING_M - e_i - e_j`` (measured closest pairs, calibration seeds,
    T1 / T2 / T3: heuristic 10th percentile 5.6 / 5.5 / 5.8 m, least 4.0 / 1.7 / 2.8 m;
    oracle least 6.6 / 6.6 / 7.2 m).
Briefing (:class:`FTBriefing`)
    The route (``start``, ``goal``: the centroid's), every agent's slot offset, the success
    radius, the slot tolerance, the slot-error bound and the form-up allowance.
Observation
    The cue is the task's formation reference: agent i's slot around the team's navigated
    centroid, led ``CUE_LEAD_S`` at the transit speed ``TRANSIT_FRAC * v_max`` toward the goal
    (stateless: a follower that closes its cue offset in ``CUE_LEAD_S`` moves the formation
    at the transit speed while it corrects its slot). The team's navigation states are shared
    (the escort's USBL tracks every vehicle): every agent's observation row.
Methods
    :mod:`oneocean.methods.heuristic.ft` (a virtual centre paced by the worst slot lag, slot
    tracking with feed-forward; heuristic: the sensor models of :mod:`oneocean.sensing`;
    oracle: true current and position).

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``wedge_offsets`` and ``reset`` (Python: route, formation frame
    and start times per episode); ``FTParams`` / ``FTWork`` and ``make``; the briefing
    (``FTBriefing``, ``BRIEF_FIELDS``, ``brief``); the env hooks ``begin``, ``cue``,
    ``post_step``, ``finish``; the compiled loop is :mod:`oneocean.kernels.ft`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..engine.constraints import DEFAULT_LAND_THRESHOLD, DEFAULT_R_COLL_M
from ..engine._jit import hot_kernel
from ..errors import ConfigError, NotApplicable
from .common import DEPTH_RANGE_M, MIN_ALTITUDE_M, PURPOSE_RESET, STANDARD
from .spawn import paths_clear, sample_routes, start_times
from .tiers import need_tier
from .public import briefing_class, common_brief
from ..engine import libm, streams

TASK_ID = "FT"
METRICS = ("formation_error_m", "max_slot_error_m", "final_centroid_error_m")
COLUMNS = STANDARD + METRICS

#: Distance between consecutive slots along a wedge arm, m.
SPACING_M = 8.0
#: Angle of the wedge arms off the (backward) route axis, degrees.
WEDGE_HALF_ANGLE_DEG = 50.0
#: Near-collision radius, m (task contract: 2 m).
R_COLL_M = DEFAULT_R_COLL_M
#: Form-up allowance after the release, s: the error bound ``max_error_m`` applies from then
#: on (the team is released at rest in its slots and forms up on its first navigation fixes).
SETTLE_S = 60.0

#: Lead of the observation's slot cue, s: the slot as it will be after this long at the
#: transit speed (a policy closing its cue offset with gain 1 / CUE_LEAD_S moves the
#: formation at that speed; the fused heuristic's slot-tracking gain is the same).
CUE_LEAD_S = 10.0 / 3.0
#: The transit speed of the task's formation reference (the cue), as a fraction of v_max.
TRANSIT_FRAC = 0.8

_C_FERR, _C_EMAX, _C_FINAL = (len(STANDARD) + i for i in range(len(METRICS)))


def wedge_offsets(n: int, spacing: float = SPACING_M,
                  half_angle_deg: float = WEDGE_HALF_ANGLE_DEG) -> np.ndarray:
    """Slot offsets of a wedge formation, apex first, centred on 0.

    Slot 0 is the apex; slots 1, 2 are the first rank (right, left), 3, 4 the second, ...

    Parameters
    ----------
    n : int
        Number of slots (agents), >= 1.
    spacing : float
        Distance between consecutive slots along an arm, m.
    half_angle_deg : float
        Angle of the arms off the backward route axis, degrees.

    Returns
    -------
    (n, 2) float64
        Offsets ``[forward, right]``, m, centred on their mean.

    Raises
    ------
    ConfigError
        If ``n < 1``.
    """
    if n < 1:
        raise ConfigError(f"task {TASK_ID}: need at least 1 agent, got {n}")
    a = math.radians(half_angle_deg)
    off = np.zeros((n, 2))
    for i in range(1, n):
        rank = (i + 1) // 2
        side = 1.0 if i % 2 == 1 else -1.0
        off[i] = (-rank * spacing * math.cos(a), side * rank * spacing * math.sin(a))
    return off - off.mean(axis=0)


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the route (start centroid, goal), the formation frame and start times.

    Returns
    -------
    dict
        ``pos0`` (E, N, 3) agents in their start slots, m; ``offsets`` (E, N, 3) world-frame
        slot offsets (centred), m; ``start`` and ``goal`` (E, 3) centroid start / goal, m;
        ``psi0`` (E, N) heading along the route, rad; ``t0`` (E,) s; ``regime_points``
        (E, 3, 3) the start, midpoint and goal of the centroid's route, m (``Cell.reset``).

    Raises
    ------
    ConfigError
        Fewer than 2 agents or missing tier keys.
    NotApplicable
        No route along which every slot path is clear.
    """
    n = int(n_agents)
    if n < 2:
        raise ConfigError(f"task {TASK_ID}: team task needs n_agents >= 2, got {n}")
    need_tier(TASK_ID, tier, "route_m", "time_limit_s")
    route_m = float(tier["route_m"])
    rngs = streams.episode_states(seed, n_episodes, PURPOSE_RESET)    # one stream per episode
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    off2 = wedge_offsets(n)
    pos0 = np.empty((n_episodes, n, 3))
    offsets = np.empty((n_episodes, n, 3))
    start = np.empty((n_episodes, 3))
    goal = np.empty((n_episodes, 3))
    psi = np.empty(n_episodes)
    tries = 2000
    # every episode's tries from its own stream, all pending episodes a try at a time: a
    # start point, a heading, the slots' paths; the first episode that fails raises
    todo = np.arange(n_episodes)
    errors = {}
    for _ in range(tries):
        if not todo.size:
            break
        c0, failed = sample_routes(grid, rngs, 0, 0.0, DEPTH_RANGE_M, MIN_ALTITUDE_M,
                                   rows=todo, land_threshold=DEFAULT_LAND_THRESHOLD,
                                   what=lambda j: f"task {TASK_ID} reset (episode {todo[j]})")
        errors.update({int(todo[j]): exc for j, exc in failed.items()})
        alive = np.ones(todo.size, dtype=bool)
        alive[list(failed)] = False
        todo, c0 = todo[alive], c0[alive, 0]
        h = streams.uniform_rows(rngs, -math.pi, math.pi, 1, todo)[:, 0]
        sin_h, cos_h = libm.sin(h), libm.cos(h)
        fwd = np.stack([sin_h, np.zeros_like(h), cos_h], axis=1)
        right = np.stack([cos_h, np.zeros_like(h), -sin_h], axis=1)
        o = off2[None, :, :1] * fwd[:, None] + off2[None, :, 1:] * right[:, None]
        g = c0 + route_m * fwd
        done = paths_clear(grid, c0[:, None] + o, g[:, None] + o, MIN_ALTITUDE_M,
                           DEFAULT_LAND_THRESHOLD).reshape(todo.size, n).all(axis=1)
        e = todo[done]
        start[e], goal[e], offsets[e] = c0[done], g[done], o[done]
        pos0[e] = c0[done][:, None] + o[done]
        psi[e] = h[done]
        todo = todo[~done]
    for e in todo:
        errors[int(e)] = NotApplicable(
            f"task {TASK_ID} reset (episode {e}): no {route_m:g} m route clear for all {n} "
            f"slots found in {tries} tries; the grid is too small or too shallow for this tier")
    if errors:
        raise errors[min(errors)]
    return {"pos0": pos0, "offsets": offsets, "start": start, "goal": goal,
            "psi0": np.repeat(psi[:, None], n, axis=1), "t0": t0,
            "regime_points": np.stack([start, 0.5 * (start + goal), goal], axis=1)}


class FTParams(NamedTuple):
    """FT's params (one rollout).

    Attributes
    ----------
    radius : float
        Success radius of the centroid around the goal, m.
    slot_tol : float
        Arrival: every agent within this of its slot, m.
    e_bound : float
        A slot error above this ends the episode as a failure, m.
    settle_k : int
        The bound applies from this step on (``SETTLE_S / dt``).
    lead : float
        The cue's lead toward the goal, m (``CUE_LEAD_S * TRANSIT_FRAC * v_max``).
    """
    radius: float           # success radius of the centroid around the goal, m
    slot_tol: float         # arrival: every agent within this of its slot, m
    e_bound: float          # a slot error above this ends the episode as a failure, m
    settle_k: int           # the bound applies from this step on (SETTLE_S / dt)
    lead: float             # the cue's lead toward the goal, m


class FTWork(NamedTuple):
    """FT's per-episode work arrays.

    Attributes
    ----------
    offsets : (E, N, 3) float64
        World-frame slot offsets (centred), m.
    start : (E, 3) float64
        Centroid start, m.
    goal : (E, 3) float64
        Centroid goal, m.
    cen : (E, 3) float64
        Agents' centroid after the last step (the start before the first), m.
    acc : (E, 2) float64
        Sum over steps of the RMS slot error, largest slot error seen, m.
    won : (E,) int64
        1 once the team arrived in shape.
    """
    offsets: np.ndarray     # (E, N, 3) world-frame slot offsets (centred), m
    start: np.ndarray       # (E, 3) centroid start, m
    goal: np.ndarray        # (E, 3) centroid goal, m
    cen: np.ndarray         # (E, 3) agents' centroid after the last step (start before), m
    acc: np.ndarray         # (E, 2) sum over steps of the RMS slot error, largest e_i seen, m
    won: np.ndarray         # (E,) int64 1 once the team arrived in shape


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    Returns
    -------
    P : FTParams
        The env's typed scalars.
    W : FTWork
        The env's per-episode work arrays.

    Raises
    ------
    ConfigError
        Missing tier parameters.
    """
    need_tier(TASK_ID, tier, "goal_radius_m", "slot_tol_m", "max_error_m", "dt_s")
    start = np.ascontiguousarray(init["start"], dtype=np.float64)
    n_ep = start.shape[0]
    return (FTParams(float(tier["goal_radius_m"]), float(tier["slot_tol_m"]),
                     float(tier["max_error_m"]),
                     int(math.ceil(SETTLE_S / float(tier["dt_s"]) - 1e-9)),
                     CUE_LEAD_S * TRANSIT_FRAC * _v_max(tier)),
            FTWork(np.ascontiguousarray(init["offsets"], dtype=np.float64), start,
                   np.ascontiguousarray(init["goal"], dtype=np.float64), start.copy(),
                   np.zeros((n_ep, 2)), np.zeros(n_ep, np.int64)))


def _v_max(tier: dict) -> float:
    """The cell's speed limit (``v_max`` of :attr:`oneocean.tasks.Cell.params`), else the task
    table's vehicle's, m s-1."""
    if tier.get("v_max") is not None:
        return float(tier["v_max"])
    from ..engine import load_vehicle
    from .tiers import shared_task_table

    return float(load_vehicle(shared_task_table(TASK_ID)["vehicle"]).v_max)


OBS_EXTRA_DOCS: dict = {}
OBS_EXTRA = ()
#: What the cue is (the observation's ``goal_d*`` fields).
CUE_DOC = ("the agent's slot around the team's navigated centroid, led 10/3 s at the transit "
           "speed (0.8 v_max) toward the goal")

#: The briefing's own fields (after :data:`oneocean.tasks.public.COMMON`): name -> (shape,
#: unit, meaning).
BRIEF_FIELDS = {
    "start": ("(E, 3)", "m", "the route's start: the formation centroid's"),
    "goal": ("(E, 3)", "m", "the route's goal: the formation centroid's"),
    "offsets": ("(E, N, 3)", "m", "every agent's slot offset from the centroid (world frame, "
                "centred: a wedge along the route, apex forward)"),
    "radius": ("", "m", "success radius of the centroid around the goal"),
    "slot_tol": ("", "m", "arrival: every agent within this of its slot"),
    "e_bound": ("", "m", "a slot error above this ends the episode as a failure (after "
                "settle_s)"),
    "settle_s": ("", "s", "the form-up allowance from the release"),
}


FTBriefing = briefing_class("FT", BRIEF_FIELDS, __name__)


def brief(P: FTParams, W: FTWork, init: dict, m) -> FTBriefing:
    """The briefing of every episode of a batch (:class:`oneocean.tasks.public.Mission`
    ``m``): the route, the slots, the tolerances.

    Returns
    -------
    FTBriefing
    """
    return FTBriefing(**common_brief(m), start=W.start.copy(), goal=W.goal.copy(),
                      offsets=W.offsets.copy(), radius=P.radius, slot_tol=P.slot_tol,
                      e_bound=P.e_bound, settle_s=SETTLE_S)


@hot_kernel
def begin(ctx, e):
    """Reset the centroid and the accumulators.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``ctx.state`` holds the start.

    Returns
    -------
    bool
        False: the episode starts.
    """
    W = ctx.W
    for j in range(3):
        W.cen[e, j] = W.start[e, j]
    W.acc[e, 0] = 0.0
    W.acc[e, 1] = 0.0
    W.won[e] = 0
    return False


@hot_kernel
def cue(ctx, e, k, i):
    """Agent ``i``'s cue: its slot around the team's navigated centroid, led ``P.lead`` m
    toward the goal (at most the centroid's distance to it): the task's formation reference.
    Env hook (:mod:`oneocean.tasks.loop`).

    Returns
    -------
    gx, gy, gz : float
        The cue, world m.
    probe : float
        NaN (no probe).
    """
    P, W, X = ctx.P, ctx.W, ctx.X
    n = X.shape[1]
    cx = 0.0
    cy = 0.0
    cz = 0.0
    for j in range(n):
        cx += X[e, j, 0]
        cy += X[e, j, 1]
        cz += X[e, j, 2]
    cx /= n
    cy /= n
    cz /= n
    dx = W.goal[e, 0] - cx
    dy = W.goal[e, 1] - cy
    dz = W.goal[e, 2] - cz
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    f = min(P.lead, d) / d if d > 1e-9 else 0.0
    return (cx + W.offsets[e, i, 0] + f * dx, cy + W.offsets[e, i, 1] + f * dy,
            cz + W.offsets[e, i, 2] + f * dz, math.nan)


@hot_kernel
def post_step(ctx, e, k):
    """Shape error around the centroid, the error bound, arrival.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``.

    Returns
    -------
    bool
        True (STOP) when a slot error exceeds ``e_bound`` from step ``settle_k`` on (failure),
        or when every agent is within ``slot_tol`` of its slot and the centroid within
        ``radius`` of the goal (``W.won`` set).
    """
    P, W, state = ctx.P, ctx.W, ctx.state
    st_e = state[e]
    n = st_e.shape[0]
    offsets = W.offsets
    cx = 0.0
    cy = 0.0
    cz = 0.0
    for i in range(n):
        cx += st_e[i, 0]
        cy += st_e[i, 1]
        cz += st_e[i, 2]
    cx /= n
    cy /= n
    cz /= n
    W.cen[e, 0] = cx
    W.cen[e, 1] = cy
    W.cen[e, 2] = cz
    sq = 0.0
    emax = 0.0
    for i in range(n):
        d2 = ((st_e[i, 0] - cx - offsets[e, i, 0]) ** 2
              + (st_e[i, 1] - cy - offsets[e, i, 1]) ** 2
              + (st_e[i, 2] - cz - offsets[e, i, 2]) ** 2)
        sq += d2
        if d2 > emax:
            emax = d2
    emax = math.sqrt(emax)
    a = W.acc[e]
    a[0] += math.sqrt(sq / n)
    if emax > a[1]:
        a[1] = emax
    if emax > P.e_bound and k >= P.settle_k:
        return True
    if emax <= P.slot_tol:
        dg = math.sqrt((cx - W.goal[e, 0]) ** 2 + (cy - W.goal[e, 1]) ** 2
                       + (cz - W.goal[e, 2]) ** 2)
        if dg <= P.radius:
            W.won[e] = 1
            return True
    return False


@hot_kernel
def finish(ctx, e, k):
    """Write the FT metrics.

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Returns
    -------
    bool
        Success: the team arrived in shape (``W.won``).
    """
    W = ctx.W
    row = ctx.res[e]
    kk = k if k > 0 else 1
    row[_C_FERR] = W.acc[e, 0] / kk
    row[_C_EMAX] = W.acc[e, 1]
    row[_C_FINAL] = math.sqrt((W.cen[e, 0] - W.goal[e, 0]) ** 2
                              + (W.cen[e, 1] - W.goal[e, 1]) ** 2
                              + (W.cen[e, 2] - W.goal[e, 2]) ** 2)
    return W.won[e] == 1
