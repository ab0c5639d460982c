"""G2G — go-to-goal under currents (1 agent): a transit on an energy allocation.

Objective
    Reach a goal ``goal_distance_m`` metres from the start, at the start's depth, on the
    energy allocated to the transit, before ``time_limit_s``. Start, goal and the straight
    segment between them are in valid water (off land, inside the grid, ``MIN_ALTITUDE_M``
    above the seafloor), so the straight line is always passable; the difficulty is the
    current along the way. With ``current_ms: [lo, hi]`` only episodes whose mean current
    speed (over the straight segment and the still-water transit time at the vehicle's
    cruise speed) lies in ``[lo, hi]`` m/s are drawn: the current is stated in absolute terms
    (it matters relative to the vehicle's speed, not to the region's quantiles).
Energy
    The vehicle's electrical energy is ``P(u_r) = hotel + k u_r^3`` integrated over the
    episode (``u_r`` its speed through the water; the power model of the task's vehicle,
    ``data/vehicles.yaml`` ``power:``). The allocation is ``(1 + energy_reserve) E_ref``:
    ``E_ref`` the least energy of the transit, planned by the task on the true field of the
    rollout (:func:`oneocean.tasks.routing.plan_mission`, the same planner every method
    has), ``energy_reserve`` the mission's reserve. Without ``energy_reserve`` there is no
    allocation.
Success
    The agent comes within ``goal_radius_m`` of the goal (checked after every step; the
    episode stops there) having spent at most its allocation; ``T_s`` is the time to success
    (the time limit on failure). A vehicle past its allocation runs on (its ``energy_ratio``
    says how far past), but can no longer succeed.
Metrics
    ``final_error_m`` (primary: distance to the goal when the episode ends, m),
    ``min_error_m`` (closest approach, m), ``path_length_m`` (ground track length, m),
    ``energy_wh`` (energy used, Wh), ``energy_ratio`` (energy used / ``E_ref``).
Briefing (:class:`G2GBriefing`, after the common fields of :mod:`oneocean.tasks.public`)
    ``start`` (the launch fix), ``goal``, ``radius`` and the forecast of the current at the
    transit's depth on a lattice around start and goal over the episode's window (the
    ``fc_*`` fields, :func:`oneocean.tasks.routing.mission_field`; the truth for the oracle);
    the allocation is the common ``energy_allocation``.
Observation
    The cue is the goal; the task's own fields (:data:`OBS_EXTRA`) are the electrical energy
    used so far and its fraction of the allocation.
Methods
    :mod:`oneocean.methods.heuristic.g2g` (both plan the route and speeds through the
    briefing's field, then fly the plan; heuristic: on the forecast, with the sensor models of
    :mod:`oneocean.sensing`; oracle: on the true field, with the true current and position).

Module layout (the template of every task module; the contract: :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset`` (Python: geometry and start times per episode from
    its own stream, :func:`~oneocean.tasks.spawn.episode_generators` or their compiled
    twins, :mod:`oneocean.engine.streams`); ``Params`` / ``Work`` and ``make``
    (the env's typed scalars and per-episode arrays); the public view: the briefing
    (``<ID>Briefing``, ``BRIEF_FIELDS`` and ``brief``) and the observation's own fields
    (``OBS_EXTRA`` and the ``sense`` hook); the env hooks ``begin``, ``cue``, ``sense``,
    ``post_step``, ``finish`` (``hot_kernel``, no allocation). A task module imports no
    method: its compiled loop with the fused heuristic/oracle
    (:mod:`oneocean.methods.heuristic.g2g`) is :mod:`oneocean.kernels.g2g`.
"""

from __future__ import annotations

import math

import numpy as np

from typing import NamedTuple

from ..engine._jit import hot_kernel
from ..engine.constraints import DEFAULT_LAND_THRESHOLD
from ..errors import ConfigError, NotApplicable
from . import routing
from .common import DEPTH_RANGE_M, MIN_ALTITUDE_M, OBS_DIM, PURPOSE_RESET, STANDARD, current_at
from .regime import site_speeds
from .spawn import sample_routes, start_times
from .tiers import need_tier
from .public import briefing_class, common_brief
from ..engine import libm, streams

TASK_ID = "G2G"
METRICS = ("final_error_m", "min_error_m", "path_length_m", "energy_wh", "energy_ratio")
#: Result-matrix columns written by the kernel (standard columns first).
COLUMNS = STANDARD + METRICS

_C_FINAL, _C_MIN, _C_PATH, _C_EWH, _C_ERAT = (len(STANDARD) + i for i in range(len(METRICS)))
#: Candidate episodes drawn per episode kept before a current band is declared not
#: applicable in a region.
BAND_DRAWS = 60


def task_power(tier: dict | None = None, task_id: str = TASK_ID):
    """The power model of the task's vehicle and its speed limit.

    Parameters
    ----------
    tier : dict, optional
        Tier parameters; its ``v_max`` (m s-1), when given, overrides the vehicle's.
    task_id : str
        Task whose tier table names the vehicle (``vehicle``).

    Returns
    -------
    power : PowerModel
        The vehicle's power model (``data/vehicles.yaml`` ``power:``).
    v_max : float
        Speed limit, m s-1.
    """
    from ..engine import load_vehicle
    from .tiers import shared_task_table

    name = shared_task_table(task_id)["vehicle"]
    v_max = (tier or {}).get("v_max")
    return routing.power_model(name), float(v_max if v_max is not None
                                            else load_vehicle(name).v_max)


def current_band(tier: dict, task_id: str = TASK_ID):
    """The tier's absolute current band ``current_ms: [lo, hi]``.

    Parameters
    ----------
    tier : dict
        Tier parameters.
    task_id : str
        Task id, for the message.

    Returns
    -------
    (lo, hi) or None
        The band, m s-1, with ``0 <= lo < hi``; None without ``current_ms``.

    Raises
    ------
    ConfigError
        A malformed band.
    """
    band = tier.get("current_ms")
    if band is None:
        return None
    try:
        lo, hi = (float(b) for b in band)
    except (TypeError, ValueError):
        raise ConfigError(f"task {task_id}: current_ms: expected [lo, hi] m/s, got "
                          f"{band!r}") from None
    if not 0.0 <= lo < hi:
        raise ConfigError(f"task {task_id}: current_ms: need 0 <= lo < hi, got {band!r}")
    return lo, hi


def draw_in_band(grid, tier: dict, n_episodes: int, seed: int, draw, points, length: float,
                 what: str, task_id: str = TASK_ID):
    """Draw candidate episodes until enough meet the tier's absolute current band.

    Candidates ``c = 0, 1, ...`` of ``seed``, each from its own reset stream
    (``SeedSequence([seed, c, PURPOSE_RESET])``), are drawn in batches; the first
    ``n_episodes`` whose mean current speed at their points over the still-water transit of
    ``length`` m at the cruise speed lies in the tier's ``current_ms`` are kept (all of them
    without a band; at most ``BAND_DRAWS`` candidates per episode with one). A candidate that
    cannot be drawn ends the scan with its ``NotApplicable`` when it is reached before enough
    are kept; candidates after the last one kept never matter, so neither the episodes nor
    whether the reset succeeds depends on the batch sizes.

    Parameters
    ----------
    grid : Grid
        The grid export.
    tier : dict
        Tier parameters.
    n_episodes : int
        Episodes to keep.
    seed : int
        Run seed.
    draw : callable
        ``draw(rngs, cands) -> (t0, geometry, failed)``: the candidates ``cands`` from their
        streams ``rngs`` (:func:`oneocean.engine.streams.episode_states`): start times
        ``(k,)``, geometries (indexable by row) and ``{row: NotApplicable}`` for those that
        cannot be drawn (:func:`~oneocean.tasks.spawn.sample_routes`).
    points : callable
        ``points(geometry) -> (n, 3)`` world m: where the candidate's current is judged.
    length : float
        Path length of the mission, m.
    what : str
        What is being drawn, for the error message.
    task_id : str
        Task whose vehicle and band apply.

    Returns
    -------
    t0 : list of float
        Start times of the kept candidates, s since the grid's ``time0``.
    geometry : list
        Their geometries.

    Raises
    ------
    NotApplicable
        If fewer than ``n_episodes`` candidates meet the band, or a candidate the scan
        reaches cannot be drawn (``draw`` raised it).
    """
    band = current_band(tier, task_id)
    pw, v_max = task_power(tier, task_id)
    window = float(length) / routing.cruise_speed(v_max, pw)
    t0s, geos = [], []
    n_max = int(n_episodes) * (BAND_DRAWS if band is not None else 1)
    c = 0
    while len(geos) < n_episodes and c < n_max:
        k = min(32, n_max - c, _batch_size(n_episodes - len(geos), len(geos), c))
        cands = np.arange(c, c + k)
        t0, geo, failures = draw(streams.episode_states(seed, cands, PURPOSE_RESET), cands)
        # the scan reaches the candidates before the first that cannot be drawn, and that one
        ok_n = min(failures) if failures else k
        failed = failures[ok_n] if failures else None
        batch = [(float(t0[j]), geo[j]) for j in range(ok_n)]
        c += ok_n
        if batch and band is not None:
            pts = np.stack([points(b[1]) for b in batch])
            sp = site_speeds(grid, pts, [b[0] for b in batch], window)
            keep = (sp >= band[0]) & (sp <= band[1])
        else:
            keep = [True] * len(batch)
        for b, ok in zip(batch, keep):
            if ok and len(geos) < n_episodes:
                t0s.append(b[0])
                geos.append(b[1])
        if failed is not None and len(geos) < n_episodes:
            raise failed
    if len(geos) < n_episodes:
        raise NotApplicable(f"{what}: only {len(geos)} of {c} candidate episodes meet a mean "
                            f"current of {band[0]:g}-{band[1]:g} m/s; {n_episodes} needed")
    return t0s, geos


def _batch_size(need: int, kept: int, drawn: int) -> int:
    """Candidates to draw next when ``need`` more are wanted and ``kept`` of the ``drawn``
    so far were: ``need`` over the acceptance so far (all of them at first, at least 1 in 32
    after), with a quarter to spare. Which candidates are kept does not depend on it: they are
    judged in order and the first ones that pass are kept."""
    rate = 1.0 if drawn == 0 else max(kept / drawn, 1.0 / 32.0)
    return max(1, int(math.ceil(1.25 * need / rate)))


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample start, goal and start time of every episode.

    Returns
    -------
    dict
        ``pos0`` (E, 1, 3) start positions, m; ``goal`` (E, 3) goal positions, m;
        ``psi0`` (E, 1) initial heading (facing the goal), rad; ``t0`` (E,) start times, s.

    Raises
    ------
    ConfigError
        Wrong team size or missing tier keys.
    NotApplicable
        No valid geometry, or too few episodes in the tier's ``current_ms`` band.
    """
    if int(n_agents) != 1:
        raise ConfigError(f"task {TASK_ID}: single-agent task, got n_agents={n_agents}")
    need_tier(TASK_ID, tier, "goal_distance_m", "time_limit_s")
    dist = float(tier["goal_distance_m"])

    def draw(rngs, cands):
        t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
        return (t0,) + sample_routes(grid, rngs, 1, dist, DEPTH_RANGE_M, MIN_ALTITUDE_M,
                                     land_threshold=DEFAULT_LAND_THRESHOLD,
                                     what=lambda j: f"task {TASK_ID} reset (candidate "
                                                    f"{cands[j]})")

    t0, routes = draw_in_band(grid, tier, n_episodes, seed, draw,
                              lambda r: np.linspace(r[0], r[1], 5), dist,
                              f"task {TASK_ID} reset")
    t0 = np.array(t0, dtype=np.float64)
    pos0 = np.array([r[:1] for r in routes], dtype=np.float64).reshape(n_episodes, 1, 3)
    goal = np.array([r[1] for r in routes], dtype=np.float64).reshape(n_episodes, 3)
    d = goal - pos0[:, 0]
    psi0 = libm.arctan2(d[:, 0], d[:, 2])[:, None]
    return {"pos0": pos0, "goal": goal, "psi0": psi0, "t0": t0}


class G2GParams(NamedTuple):
    """G2G's params (one rollout).

    Attributes
    ----------
    radius : float
        Success radius around the goal, m.
    t_lim : float
        Time limit, s (the planners' field window).
    dt : float
        Step, s.
    hotel_w, pk : float
        Power model of the task's vehicle: ``P = hotel_w + pk u_r^3`` W (``pk`` in W s3 m-3).
    """
    radius: float           # success radius around the goal, m
    t_lim: float            # time limit, s (the planners' field window)
    dt: float               # step, s
    hotel_w: float          # power model of the task's vehicle: P = hotel_w + pk u_r^3, W
    pk: float


class G2GWork(NamedTuple):
    """G2G's per-episode work arrays.

    Attributes
    ----------
    goal : (E, 3) float64
        Goal positions, m.
    start : (E, 3) float64
        Start positions, m.
    acc : (E, 4) float64
        Distance to the goal, closest approach, path length (m), energy used (J).
    budget : (E,) float64
        Energy allocation, J (inf: none).
    eref : (E,) float64
        Least energy of the transit (the task's plan), J.
    """
    goal: np.ndarray        # (E, 3) goal positions, m
    start: np.ndarray       # (E, 3) start positions, m
    acc: np.ndarray         # (E, 4) distance to the goal, closest approach, path length (m),
                            #        energy used (J)
    budget: np.ndarray      # (E,) energy allocation, J (inf: none)
    eref: np.ndarray        # (E,) least energy of the transit (the task's plan), J


def reference_energy(grid, tier: dict, start, goal, depth: float, t0: float,
                     power=None) -> float:
    """``E_ref``: the least energy of one transit on ``grid``'s true field.

    The task's plan with the planner every method has
    (:func:`oneocean.tasks.routing.plan_mission`).

    Parameters
    ----------
    grid : Grid
        The grid export.
    tier : dict
        Tier parameters (``time_limit_s``, optional ``v_max``).
    start, goal : (3,) array_like
        Start and goal, world m.
    depth : float
        Depth of the transit, m.
    t0 : float
        Start time, s since the grid's ``time0``.
    power : (PowerModel, float), optional
        :func:`task_power`'s result, if at hand.

    Returns
    -------
    float
        ``E_ref``, J; inf when the goal is off the grid or no passable route exists.
    """
    pw, v_max = power if power is not None else task_power(tier)
    pts = np.array([start, goal], dtype=np.float64)
    if not routing.within_grid(grid, pts):
        return math.inf
    r = routing.plan_mission(grid, pts, depth, t0, float(tier["time_limit_s"]), v_max, pw)
    return float(r.cost)


def energy_budgets(task: str, tier: dict, n_ep: int, reference=None, *, batch=None) -> tuple:
    """Each episode's least transit energy and its energy allocation.

    Parameters
    ----------
    task : str
        Task id, for the message.
    tier : dict
        Tier parameters (optional ``energy_reserve`` >= 0).
    n_ep : int
        Number of episodes E.
    reference : callable, optional
        ``reference(e) -> float``: episode ``e``'s least energy, J.
    batch : callable, optional
        ``batch() -> (E,)``: all of them at once, J (used instead of ``reference``).

    Returns
    -------
    eref : (E,) float64
        Least transit energy, J.
    budget : (E,) float64
        Allocation ``(1 + energy_reserve) * eref``, J. Both inf without an
        ``energy_reserve`` (the transits G2G and RF).

    Raises
    ------
    ConfigError
        A negative ``energy_reserve``.
    """
    eref = np.full(n_ep, math.inf)
    budget = np.full(n_ep, math.inf)
    reserve = tier.get("energy_reserve")
    if reserve is not None:
        if not float(reserve) >= 0.0:
            raise ConfigError(f"task {task}: energy_reserve must be >= 0, got {reserve!r}")
        if batch is not None:
            eref[:] = batch()
        else:
            for e in range(n_ep):
                eref[e] = reference(e)
        budget = (1.0 + float(reserve)) * eref
    return eref, budget


def reference_energies(grid, tier: dict, start, goal, t0, power=None) -> np.ndarray:
    """:func:`reference_energy` of every episode, the same bits, in one compiled call.

    Parameters
    ----------
    grid : Grid
        The grid export.
    tier : dict
        Tier parameters.
    start, goal : (E, 3) array_like
        Starts and goals, world m (the depth is the goal's).
    t0 : (E,) array_like
        Start times, s since the grid's ``time0``.
    power : (PowerModel, float), optional
        :func:`task_power`'s result, if at hand.

    Returns
    -------
    (E,) float64
        ``E_ref`` per episode, J (:func:`oneocean.tasks.routing.mission_costs`).
    """
    pw, v_max = power if power is not None else task_power(tier)
    start = np.asarray(start, dtype=np.float64)
    goal = np.asarray(goal, dtype=np.float64)
    routes = np.stack([start[:, [0, 2]], goal[:, [0, 2]]], axis=1)
    return routing.mission_costs(grid, routes, goal[:, 1], t0, float(tier["time_limit_s"]),
                                 v_max, pw)


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    With an ``energy_reserve`` the allocation of every episode (:func:`reference_energies`
    on the rollout's ``grid``).

    Returns
    -------
    P : G2GParams
        The env's typed scalars.
    W : G2GWork
        The env's per-episode work arrays.

    Raises
    ------
    ConfigError
        Missing tier parameters or a negative ``energy_reserve``.
    """
    need_tier(TASK_ID, tier, "goal_radius_m", "time_limit_s", "dt_s")
    goal = np.ascontiguousarray(init["goal"], dtype=np.float64)
    start = np.ascontiguousarray(init["pos0"][:, 0], dtype=np.float64)
    n_ep = goal.shape[0]
    pw, v_max = task_power(tier)
    eref, budget = energy_budgets(
        TASK_ID, tier, n_ep,
        batch=lambda: reference_energies(grid, tier, start, goal, init["t0"], (pw, v_max)))
    P = G2GParams(float(tier["goal_radius_m"]), float(tier["time_limit_s"]),
                  float(tier["dt_s"]), pw.hotel_w, pw.k)
    W = G2GWork(goal, start, np.zeros((n_ep, 4)), budget, eref)
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
CUE_DOC = ("the goal")

#: The briefing's own fields (after :data:`oneocean.tasks.public.COMMON`): name -> (shape,
#: unit, meaning).
BRIEF_FIELDS = {
    "start": ("(E, 3)", "m", "the launch fix: where the vehicle starts, as its navigation "
              "knows it"),
    "goal": ("(E, 3)", "m", "the goal (world x east, y depth, z north)"),
    "radius": ("", "m", "success radius around the goal"),
    **routing.FIELD_DOCS,
}


G2GBriefing = briefing_class("G2G", BRIEF_FIELDS, __name__)


def brief(P: G2GParams, W: G2GWork, init: dict, m) -> G2GBriefing:
    """The briefing of every episode of a batch.

    The forecast (the truth for a method given the true current) on the transit's lattice
    from the launch fix to the goal (:func:`oneocean.tasks.routing.mission_field`), where
    both lie on the grid.

    Returns
    -------
    G2GBriefing
    """
    start = np.ascontiguousarray(m.X0[:, 0, :3])
    fc = m.forecast
    fields = []
    for e in range(W.goal.shape[0]):
        pts = np.array([[start[e, 0], start[e, 2]], [W.goal[e, 0], W.goal[e, 2]]])
        fields.append(routing.mission_field(m.grid, pts, float(W.goal[e, 1]), float(m.t0[e]),
                                            P.t_lim, fc=fc, e=e)
                      if routing.within_grid(m.grid, pts) else None)
    return G2GBriefing(**common_brief(m, W.budget), start=start, goal=W.goal.copy(),
                       radius=P.radius, **routing.pack_fields(fields))


@hot_kernel
def _dist(s, g):
    return math.sqrt((s[0] - g[0]) ** 2 + (s[1] - g[1]) ** 2 + (s[2] - g[2]) ** 2)


@hot_kernel
def begin(ctx, e):
    """Reset the episode's accumulators.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``ctx.state`` holds the start.

    Returns
    -------
    bool
        True (the episode ends) if the start is within the goal radius.
    """
    P, W, state = ctx.P, ctx.W, ctx.state
    d = _dist(state[e, 0], W.goal[e])
    W.acc[e, 0] = d
    W.acc[e, 1] = d
    W.acc[e, 2] = 0.0
    W.acc[e, 3] = 0.0
    return d <= P.radius


@hot_kernel
def cue(ctx, e, k, i):
    """The goal cue: the goal itself.

    Env hook (:mod:`oneocean.tasks.loop`): the observation's goal cue and probe.

    Returns
    -------
    gx, gy, gz : float
        The goal cue, world m.
    probe : float
        NaN (the task has no field).
    """
    W = ctx.W
    return W.goal[e, 0], W.goal[e, 1], W.goal[e, 2], math.nan


@hot_kernel
def sense(ctx, e, k):
    """The task's observation fields (:data:`OBS_EXTRA`): the energy used and its fraction
    of the allocation. Env hook (:mod:`oneocean.tasks.loop`)."""
    W, O = ctx.W, ctx.O
    used = W.acc[e, 3]
    o = O[e, 0]
    o[OBS_DIM] = used
    o[OBS_DIM + 1] = used / W.budget[e] if W.budget[e] < math.inf else 0.0


@hot_kernel
def step_energy(grid, P, s, p, t):
    """Energy of the step that took the vehicle from ``p`` to ``s``.

    The power at its speed through the water (ground velocity minus the current where it was)
    over one step.

    Parameters
    ----------
    grid : Grid
        The grid export.
    P : G2GParams or RFParams
        Params with ``hotel_w``, ``pk`` and ``dt``.
    s : (STATE_DIM,) float64
        The vehicle's state after the step.
    p : (3,) float64
        Its position before the step, world m.
    t : float
        Time at the start of the step, s since the grid's ``time0``.

    Returns
    -------
    float
        Energy, J.
    """
    ce, cn = current_at(grid, p[0], p[1], p[2], t)
    ux = s[12] - ce
    uy = s[13]
    uz = s[14] - cn
    ur = math.sqrt(ux * ux + uy * uy + uz * uz)
    return (P.hotel_w + P.pk * ur * ur * ur) * P.dt


@hot_kernel
def post_step(ctx, e, k):
    """Path length, energy, distance to the goal and closest approach after the step.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``.

    Returns
    -------
    bool
        True (STOP) when the agent is within the goal radius.
    """
    grid, P, W, state, prev = ctx.grid, ctx.P, ctx.W, ctx.state, ctx.prev
    t = ctx.t0[e] + k * ctx.dt
    s = state[e, 0]
    p = prev[e, 0]
    a = W.acc[e]
    a[2] += math.sqrt((s[0] - p[0]) ** 2 + (s[1] - p[1]) ** 2 + (s[2] - p[2]) ** 2)
    a[3] += step_energy(grid, P, s, p, t)
    d = _dist(s, W.goal[e])
    a[0] = d
    if d < a[1]:
        a[1] = d
    return d <= P.radius


@hot_kernel
def finish(ctx, e, k):
    """Write the G2G metrics.

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    Returns
    -------
    bool
        Success: within the goal radius at the end, on at most the energy allocation.
    """
    P, W = ctx.P, ctx.W
    row = ctx.res[e]
    a = W.acc[e]
    row[_C_FINAL] = a[0]
    row[_C_MIN] = a[1]
    row[_C_PATH] = a[2]
    row[_C_EWH] = a[3] / 3600.0
    row[_C_ERAT] = a[3] / W.eref[e]
    return a[0] <= P.radius and a[3] <= W.budget[e]
