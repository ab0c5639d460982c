"""RF — route following under currents (1 agent): a fixed route on an energy allocation.

Objective
    Follow a route of ``n_waypoints`` straight legs of ``leg_m`` metres (consecutive legs
    turn by at most ``MAX_TURN_DEG``) at a constant depth, in order, on the energy allocated
    to it. The route is the mission (a survey line, a cable route): its legs are fixed, and
    the route is in valid water with ``MIN_ALTITUDE_M`` of clearance along every leg; the
    agent starts at rest on its first vertex, facing the first leg. With ``current_ms:
    [lo, hi]`` only routes whose mean current speed (at its vertices and leg midpoints, over
    the still-water time at the vehicle's cruise speed) lies in ``[lo, hi]`` m/s are drawn.
Energy
    As in :mod:`oneocean.tasks.g2g`: the energy ``P(u_r) = hotel + k u_r^3`` integrated over
    the episode, the allocation ``(1 + energy_reserve) E_ref`` with ``E_ref`` the least
    energy of flying the route (the best speed schedule along it on the true field,
    :func:`oneocean.tasks.routing.plan_mission`).
Success
    Every waypoint reached in order (within ``wp_radius_m``, judged on the true position)
    before ``time_limit_s``, within the allocation, AND a mean cross-track error at most
    ``xte_max_m``. The episode stops when the last waypoint is reached (``T_s`` = that time;
    the time limit on failure); a vehicle past its allocation runs on but cannot succeed.
Metrics
    ``cross_track_error_m`` (primary: mean over the steps run of the distance to the route
    near the agent = the nearer of the active leg and the previous leg, as segments, m),
    ``waypoints_reached`` (count), ``max_cross_track_m`` (m), ``energy_wh`` (Wh),
    ``energy_ratio`` (energy used / ``E_ref``).
Briefing (:class:`RFBriefing`, after the common fields of :mod:`oneocean.tasks.public`)
    The ``route`` (vertex 0: where the vehicle starts), the waypoint radius, the cross-track
    bound and the forecast of the current at the route's depth on a lattice around the route
    over the episode's window (the ``fc_*`` fields,
    :func:`oneocean.tasks.routing.mission_field` with ``fixed``; the truth for the oracle);
    the allocation is the common ``energy_allocation``.
Observation
    The cue is the route point ``CUE_LOOKAHEAD_M`` ahead of the agent's known projection on
    the active leg (clamped to the waypoint), the leg as the vehicle's mission computer knows
    it: the task's pointer ``W.nwp`` advances in the cue on the known position
    (:func:`~oneocean.tasks.waypoints.nav_waypoint`), the judge's ``W.wp`` on the truth; once the
    route is done as far as the vehicle knows, the last waypoint. The task's own fields
    (:data:`OBS_EXTRA`) are the electrical energy used so far (J) and its fraction of the
    allocation (0 without one).
Methods
    :mod:`oneocean.methods.heuristic.rf` (both plan the speed schedule along the route
    through the briefing's field, then fly it with line-of-sight guidance; heuristic: on the
    forecast, with the sensor models of :mod:`oneocean.sensing`; oracle: on the true field,
    true current and position).

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset``; ``RFParams`` / ``RFWork`` and ``make``; the briefing
    (``RFBriefing``, ``BRIEF_FIELDS``, ``brief``) and the observation's own fields
    (``OBS_EXTRA``, ``sense``); the env hooks ``begin``, ``cue``, ``sense``, ``post_step``,
    ``finish``; the compiled loop is :mod:`oneocean.kernels.rf`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..engine.constraints import DEFAULT_LAND_THRESHOLD
from ..engine._jit import hot_kernel
from ..errors import ConfigError
from . import routing
from .common import DEPTH_RANGE_M, MIN_ALTITUDE_M, OBS_DIM, STANDARD
from .spawn import sample_routes, start_times
from .tiers import need_tier
from .waypoints import nav_waypoint
from .public import briefing_class, common_brief
from .g2g import draw_in_band, energy_budgets, step_energy, task_power
from .routing import MAX_VERTICES
from ..engine import libm

TASK_ID = "RF"
METRICS = ("cross_track_error_m", "waypoints_reached", "max_cross_track_m", "energy_wh",
           "energy_ratio")
INT_METRICS = ("waypoints_reached",)
COLUMNS = STANDARD + METRICS

#: Largest heading change between consecutive legs, degrees.
MAX_TURN_DEG = 120.0
#: Lookahead of the observation's route cue along the active leg, m.
CUE_LOOKAHEAD_M = 20.0

_C_XTE, _C_WP, _C_XMAX, _C_EWH, _C_ERAT = (len(STANDARD) + i for i in range(len(METRICS)))


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the route and start time of every episode.

    Returns
    -------
    dict
        ``route`` (E, W + 1, 3) vertices, m (vertex 0 = start, 1..W = waypoints);
        ``pos0`` (E, 1, 3) m; ``psi0`` (E, 1) facing the first leg, rad; ``t0`` (E,) s.

    Raises
    ------
    ConfigError
        Wrong team size, missing tier keys or ``n_waypoints < 1``.
    NotApplicable
        No valid route, or too few routes in the tier's ``current_ms`` band.
    """
    if int(n_agents) != 1:
        raise ConfigError(f"task {TASK_ID}: single-agent task, got n_agents={n_agents}")
    need_tier(TASK_ID, tier, "n_waypoints", "leg_m", "time_limit_s")
    n_wp = int(tier["n_waypoints"])
    if n_wp < 1:
        raise ConfigError(f"task {TASK_ID}: n_waypoints must be >= 1, got {n_wp}")
    leg = float(tier["leg_m"])

    def draw(rngs, cands):
        t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
        return (t0,) + sample_routes(grid, rngs, n_wp, leg, DEPTH_RANGE_M, MIN_ALTITUDE_M,
                                     max_turn_rad=math.radians(MAX_TURN_DEG),
                                     land_threshold=DEFAULT_LAND_THRESHOLD,
                                     what=lambda j: f"task {TASK_ID} reset (candidate "
                                                    f"{cands[j]})")

    t0, routes = draw_in_band(grid, tier, n_episodes, seed, draw, regime_points, n_wp * leg,
                              f"task {TASK_ID} reset", TASK_ID)
    t0 = np.array(t0, dtype=np.float64)
    route = np.array(routes, dtype=np.float64).reshape(n_episodes, n_wp + 1, 3)
    d = route[:, 1] - route[:, 0]
    psi0 = libm.arctan2(d[:, 0], d[:, 2])[:, None]
    return {"route": route, "pos0": route[:, :1].copy(), "psi0": psi0, "t0": t0}


def regime_points(route):
    """Where a route's current is judged: its vertices and leg midpoints.

    Parameters
    ----------
    route : (W + 1, 3) array_like
        Route vertices, world m.

    Returns
    -------
    (2 W + 1, 3) float64
        The vertices, then the leg midpoints, world m.
    """
    r = np.asarray(route, dtype=np.float64)
    return np.concatenate([r, 0.5 * (r[1:] + r[:-1])])


@hot_kernel
def leg_geometry(ax_, ay_, az_, bx, by, bz, px, py, pz):
    """Projection of a point on a 3-D segment.

    Parameters
    ----------
    ax_, ay_, az_ : float
        Segment start a, world m.
    bx, by, bz : float
        Segment end b, world m.
    px, py, pz : float
        The point p, world m.

    Returns
    -------
    along : float
        Along-track position of the projection from a, m (not clamped).
    xt : float
        Distance from p to the segment, m.
    tx, ty, tz : float
        Unit tangent (zeros for a segment shorter than 1e-12 m).
    length : float
        Segment length, m.
    """
    lx = bx - ax_
    ly = by - ay_
    lz = bz - az_
    ln = math.sqrt(lx * lx + ly * ly + lz * lz)
    if ln <= 1e-12:
        return 0.0, math.sqrt((px - ax_) ** 2 + (py - ay_) ** 2 + (pz - az_) ** 2), 0.0, 0.0, \
            0.0, 0.0
    tx = lx / ln
    ty = ly / ln
    tz = lz / ln
    s = (px - ax_) * tx + (py - ay_) * ty + (pz - az_) * tz
    sc = min(max(s, 0.0), ln)
    qx = ax_ + sc * tx - px
    qy = ay_ + sc * ty - py
    qz = az_ + sc * tz - pz
    return s, math.sqrt(qx * qx + qy * qy + qz * qz), tx, ty, tz, ln


class RFParams(NamedTuple):
    """RF's params (one rollout).

    Attributes
    ----------
    radius : float
        Waypoint radius, m.
    xte_max : float
        Bound on the mean cross-track error for success, m.
    look : float
        Lookahead of the observation's route cue, m.
    t_lim : float
        Time limit, s (the planners' field window).
    dt : float
        Step, s.
    hotel_w, pk : float
        Power model of the task's vehicle: ``P = hotel_w + pk u_r^3`` W (``pk`` in W s3 m-3).
    """
    radius: float           # waypoint radius, m
    xte_max: float          # bound on the mean cross-track error for success, m
    look: float             # lookahead of the observation's route cue, m
    t_lim: float            # time limit, s (the planners' field window)
    dt: float               # step, s
    hotel_w: float          # power model of the task's vehicle: P = hotel_w + pk u_r^3, W
    pk: float


class RFWork(NamedTuple):
    """RF's per-episode work arrays.

    Attributes
    ----------
    route : (E, W + 1, 3) float64
        Route vertices, m.
    wp : (E,) int64
        The judge's active waypoint (true position; 1..W; W + 1 when the route is done).
    nwp : (E,) int64
        The mission computer's (known position; :func:`~oneocean.tasks.waypoints.nav_waypoint`):
        the observation's route cue.
    acc : (E, 3) float64
        Sum and max of the cross-track error (m), energy used (J).
    budget : (E,) float64
        Energy allocation, J (inf: none).
    eref : (E,) float64
        Least energy of the route (the task's schedule), J.
    """
    route: np.ndarray       # (E, W + 1, 3) route vertices, m
    wp: np.ndarray          # (E,) int64 the judge's active waypoint (true position; 1..W;
                            #        W + 1 when the route is done)
    nwp: np.ndarray         # (E,) int64 the mission computer's (known position; nav_waypoint):
                            #        the observation's route cue
    acc: np.ndarray         # (E, 3) sum and max of the cross-track error (m), energy used (J)
    budget: np.ndarray      # (E,) energy allocation, J (inf: none)
    eref: np.ndarray        # (E,) least energy of the route (the task's schedule), J


def reference_energy(grid, tier: dict, route, t0: float, power=None) -> float:
    """``E_ref``: the least energy of flying a route on ``grid``'s true field.

    The best speed schedule along it (:func:`oneocean.tasks.routing.plan_mission`,
    ``fixed=True``).

    Parameters
    ----------
    grid : Grid
        The grid export.
    tier : dict
        Tier parameters (``time_limit_s``, optional ``v_max``).
    route : (W + 1, 3) array_like
        Route vertices, world m (the depth is vertex 0's).
    t0 : float
        Start time, s since the grid's ``time0``.
    power : (PowerModel, float), optional
        :func:`~oneocean.tasks.g2g.task_power`'s result, if at hand.

    Returns
    -------
    float
        ``E_ref``, J; inf off the grid or where no schedule holds the route.
    """
    pw, v_max = power if power is not None else task_power(tier, TASK_ID)
    pts = np.ascontiguousarray(np.asarray(route)[:, [0, 2]])
    if not routing.within_grid(grid, pts):
        return math.inf
    r = routing.plan_mission(grid, pts, float(route[0][1]), t0, float(tier["time_limit_s"]),
                             v_max, pw, fixed=True)
    return float(r.cost)


def reference_energies(grid, tier: dict, routes, t0, power=None) -> np.ndarray:
    """:func:`reference_energy` of every route, the same bits, in one compiled call.

    Parameters
    ----------
    grid : Grid
        The grid export.
    tier : dict
        Tier parameters.
    routes : (E, W + 1, 3) array_like
        Route vertices, world m.
    t0 : (E,) array_like
        Start times, s since the grid's ``time0``.
    power : (PowerModel, float), optional
        :func:`~oneocean.tasks.g2g.task_power`'s result, if at hand.

    Returns
    -------
    (E,) float64
        ``E_ref`` per episode, J (:func:`oneocean.tasks.routing.mission_costs`).
    """
    pw, v_max = power if power is not None else task_power(tier, TASK_ID)
    r = np.asarray(routes, dtype=np.float64)
    return routing.mission_costs(grid, r[:, :, [0, 2]], r[:, 0, 1], t0,
                                 float(tier["time_limit_s"]), v_max, pw, fixed=True)


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    With an ``energy_reserve`` the allocation of every episode (:func:`reference_energies`
    on the rollout's ``grid``).

    Returns
    -------
    P : RFParams
        The env's typed scalars.
    W : RFWork
        The env's per-episode work arrays.

    Raises
    ------
    ConfigError
        Missing tier parameters, more than ``MAX_VERTICES - 1`` waypoints (a stored plan's
        capacity, :data:`oneocean.tasks.routing.MAX_VERTICES`) or a negative
        ``energy_reserve``.
    """
    need_tier(TASK_ID, tier, "wp_radius_m", "xte_max_m", "time_limit_s", "dt_s")
    route = np.ascontiguousarray(init["route"], dtype=np.float64)
    n_ep, n_v = route.shape[:2]
    if n_v > MAX_VERTICES:
        raise ConfigError(f"task {TASK_ID}: at most {MAX_VERTICES - 1} waypoints")
    pw, v_max = task_power(tier, TASK_ID)
    eref, budget = energy_budgets(
        TASK_ID, tier, n_ep,
        batch=lambda: reference_energies(grid, tier, route, init["t0"], (pw, v_max)))
    P = RFParams(float(tier["wp_radius_m"]), float(tier["xte_max_m"]), CUE_LOOKAHEAD_M,
                 float(tier["time_limit_s"]), float(tier["dt_s"]), pw.hotel_w, pw.k)
    W = RFWork(route, np.ones(n_ep, np.int64), np.ones(n_ep, np.int64), np.zeros((n_ep, 3)),
               budget, eref)
    return P, W


#: The task's own observation fields (after :data:`oneocean.tasks.common.OBS_FIELDS`): the
#: electrical energy the vehicle used so far (J) and its fraction of the allocation (0 without
#: one).
OBS_EXTRA_DOCS = {
    "energy_j": ("J", "the electrical energy the vehicle used so far (its power model over its "
                      "speed through the water)"),
    "energy_frac": ("", "that energy over the episode's allocation (0 without one): above 1 the "
                        "episode fails"),
}
OBS_EXTRA = tuple(OBS_EXTRA_DOCS)
#: What the cue is (the observation's ``goal_d*`` fields).
CUE_DOC = ("the route point 20 m ahead of the vehicle's known projection on the active leg, the "
           "leg as its mission computer sequences it on the navigation estimate (the last "
           "waypoint once the route is done)")

#: The briefing's own fields (after :data:`oneocean.tasks.public.COMMON`): name -> (shape,
#: unit, meaning).
BRIEF_FIELDS = {
    "route": ("(E, W + 1, 3)", "m", "the route's vertices (world x east, y depth, z north): "
              "vertex 0 where the vehicle starts, then the waypoints in order"),
    "radius": ("", "m", "waypoint radius (3-D)"),
    "xte_max": ("", "m", "success: mean cross-track error at most this"),
    **routing.FIELD_DOCS,
}


RFBriefing = briefing_class("RF", BRIEF_FIELDS, __name__)


def brief(P: RFParams, W: RFWork, init: dict, m) -> RFBriefing:
    """The briefing of every episode of a batch.

    The forecast (the truth for a method given the true current) at the route's depth on the
    lattice around its vertices (:func:`oneocean.tasks.routing.mission_field` with
    ``fixed``), where the route lies on the grid.

    Returns
    -------
    RFBriefing
    """
    fc = m.forecast
    fields = []
    for e in range(W.route.shape[0]):
        pts = np.ascontiguousarray(W.route[e][:, [0, 2]])
        fields.append(routing.mission_field(m.grid, pts, float(W.route[e, 0, 1]),
                                            float(m.t0[e]), P.t_lim, fixed=True, fc=fc, e=e)
                      if routing.within_grid(m.grid, pts) else None)
    return RFBriefing(**common_brief(m, W.budget), route=W.route.copy(), radius=P.radius,
                      xte_max=P.xte_max, **routing.pack_fields(fields))


@hot_kernel
def begin(ctx, e):
    """Reset the waypoint pointers and accumulators.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``ctx.state`` holds the start.

    Returns
    -------
    bool
        True (the episode ends) for a route without waypoints.
    """
    W = ctx.W
    W.wp[e] = 1
    W.nwp[e] = 1
    W.acc[e, 0] = 0.0
    W.acc[e, 1] = 0.0
    W.acc[e, 2] = 0.0
    return W.wp[e] > W.route.shape[1] - 1


@hot_kernel
def cue(ctx, e, k, i):
    """The route point ``P.look`` m ahead of the agent's known projection on the active leg.

    Env hook (:mod:`oneocean.tasks.loop`): the observation's goal cue and probe.

    The leg is the mission computer's: its pointer ``W.nwp`` is advanced here, on the
    known position (:func:`~oneocean.tasks.waypoints.nav_waypoint`); the point is clamped to the
    waypoint, and once the route is done the cue is the last waypoint.

    Returns
    -------
    gx, gy, gz : float
        The goal cue, world m.
    probe : float
        NaN (the task has no field).
    """
    P, W, X = ctx.P, ctx.W, ctx.X
    s = X[e, i]
    wp = nav_waypoint(W.route, W.nwp, e, s[0], s[1], s[2], P.radius, 0)
    if wp > W.route.shape[1] - 1:   # route done as far as the vehicle knows: the last waypoint
        g = W.route[e, wp - 1]
        return g[0], g[1], g[2], math.nan
    a0 = W.route[e, wp - 1]
    b0 = W.route[e, wp]
    al, _, tx, ty, tz, ln = leg_geometry(a0[0], a0[1], a0[2], b0[0], b0[1], b0[2],
                                         s[0], s[1], s[2])
    sl = min(max(al, 0.0) + P.look, ln)
    return a0[0] + sl * tx, a0[1] + sl * ty, a0[2] + sl * tz, math.nan


@hot_kernel
def sense(ctx, e, k):
    """The task's observation fields (:data:`OBS_EXTRA`): the energy used and its fraction
    of the allocation. Env hook (:mod:`oneocean.tasks.loop`), before the step's cues.
    """
    W, O = ctx.W, ctx.O
    used = W.acc[e, 2]
    o = O[e, 0]
    o[OBS_DIM] = used
    o[OBS_DIM + 1] = used / W.budget[e] if W.budget[e] < math.inf else 0.0


@hot_kernel
def post_step(ctx, e, k):
    """Cross-track error, energy and the judge's waypoint after the step.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``.

    Returns
    -------
    bool
        True (STOP) once the last waypoint is reached (on the true position).
    """
    grid, P, W, state, prev = ctx.grid, ctx.P, ctx.W, ctx.state, ctx.prev
    t = ctx.t0[e] + k * ctx.dt
    s = state[e, 0]
    wp = W.wp[e]
    a0 = W.route[e, wp - 1]
    b0 = W.route[e, wp]
    _, xt, _, _, _, _ = leg_geometry(a0[0], a0[1], a0[2], b0[0], b0[1], b0[2],
                                     s[0], s[1], s[2])
    if wp >= 2:  # just past a waypoint the previous leg is still the route nearby
        z0 = W.route[e, wp - 2]
        _, xp, _, _, _, _ = leg_geometry(z0[0], z0[1], z0[2], a0[0], a0[1], a0[2],
                                         s[0], s[1], s[2])
        if xp < xt:
            xt = xp
    a = W.acc[e]
    a[0] += xt
    if xt > a[1]:
        a[1] = xt
    a[2] += step_energy(grid, P, s, prev[e, 0], t)
    if (s[0] - b0[0]) ** 2 + (s[1] - b0[1]) ** 2 + (s[2] - b0[2]) ** 2 <= P.radius * P.radius:
        wp += 1
        W.wp[e] = wp
    return wp > W.route.shape[1] - 1


@hot_kernel
def finish(ctx, e, k):
    """Write the RF metrics.

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Returns
    -------
    bool
        Success: every waypoint reached, mean cross-track error at most ``xte_max_m`` and
        energy within the allocation.
    """
    P, W = ctx.P, ctx.W
    row = ctx.res[e]
    a = W.acc[e]
    wp = W.wp[e]
    xte = a[0] / k if k > 0 else 0.0
    row[_C_XTE] = xte
    row[_C_WP] = wp - 1
    row[_C_XMAX] = a[1]
    row[_C_EWH] = a[2] / 3600.0
    row[_C_ERAT] = a[2] / W.eref[e]
    return wp > W.route.shape[1] - 1 and xte <= P.xte_max and a[2] <= W.budget[e]
