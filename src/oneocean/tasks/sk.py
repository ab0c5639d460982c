"""SK — station keeping under currents (1 agent).

Objective
    Hold position at a station (valid water, ``DEPTH_RANGE_M`` deep, ``MIN_ALTITUDE_M`` above
    the seafloor) and the station heading for the whole operation, ``time_limit_s``. The
    vehicle is released at rest over ground, facing the station heading, ``start_offset_m``
    (tier key, metres, horizontal, random bearing; 0: on the station) from the station, as a
    dynamic-positioning (DP) system takes over a vehicle that has drifted off its set-point.
    The station heading is set into the local current at the start time, as a DP operator
    would (random when the current is below ``CALM_MS``), and then held.
Start time (a changing current)
    Of ``START_DRAWS`` start times drawn uniformly from the episode's stream over the grid's
    time span, the episode starts at the one where the current at the station changes most
    over the episode (the vector difference between ``t0`` and ``t0 + time_limit_s``): a
    station kept through the turn or the build-up of the tidal stream, not in a frozen one.
    On a grid whose data do not vary in time all draws tie and the first is kept (changes
    within 1e-6 m s-1, the data's float32 precision, tie). The draws
    come after the station's, so the station, its heading and the release are deterministic
    per (seed, episode); ``Cell.reset``'s current band then judges the mean speed at the
    station and the release point over the episode (``regime_points``).
Success
    The agent stays within ``hold_radius_m`` of the station for ``hold_time_s`` CONTIGUOUS
    seconds before ``time_limit_s`` (it may be pushed out and recover: the window restarts).
    ``T_s`` is the end of the first complete hold window (time to success; ``E`` and the
    violations also stop there, :mod:`oneocean.tasks.loop`'s ``REACHED``), but the episode
    runs on to its time limit, the task's metric horizon, so that every episode -- success or
    failure -- is measured over the same station-keeping window.
Metrics (distances are 3-D, sampled after every step)
    With ``H = ceil(hold_time_s / dt)`` and ``S = ceil(SETTLE_S / dt)``:
    ``rms_error_m`` (primary: the station-keeping RMS position error over the station-keeping
    window, ``(SETTLE_S, time_limit_s]``: the RMS distance to the station after steps
    ``S .. n_steps - 1``, for EVERY episode, failures included, so a cell's mean is the mean
    over all its episodes). Why this window: a DP engineer's station-keeping error is the
    deviation from the set-point while the system is holding it (the footprint over the
    operation), not the transient of a set-point change; ``SETTLE_S`` (60 s) is the settling
    allowance for the release offset (at most ~10 m, covered at the vehicle's speed budget in
    well under a minute wherever the current lets it hold at all), after which every metre
    counts, whether the vehicle is holding, recovering or being carried away. A fixed window
    (not "from the first time within the radius") is defined for an episode that never
    reaches the station and does not reward a slow arrival; the approach a method needs
    beyond the allowance counts as error.
    ``hold_rms_m`` (secondary: the RMS distance over the hold window, the ``H`` steps of the
    first complete hold, so at most ``hold_radius_m``; NaN for an episode that never completed
    a hold: precision while holding),
    ``heading_rms_deg`` (RMS heading error over the same hold window, deg; NaN likewise),
    ``max_error_m`` (largest distance over the station-keeping window, m), ``hold_s`` (longest
    contiguous in-radius time over the episode, s), ``final_rms_m`` (RMS distance over the
    episode's last ``H`` steps: the last ``hold_time_s`` before the time limit, m).
Briefing (:class:`SKBriefing`, after the common fields of :mod:`oneocean.tasks.public`)
    The ``station`` and its ``heading``, the hold radius, the hold time and the settling
    allowance.
Observation
    The cue is the station; the task has no observation fields of its own.
Methods
    :mod:`oneocean.methods.heuristic.sk` (P-control plus current feed-forward with the full
    ``v_max``, heading commanded to the briefing's station heading; heuristic: the sensor
    models of :mod:`oneocean.sensing`; oracle: true current and position).

Module layout (as :mod:`oneocean.tasks.g2g`; the contract is :mod:`oneocean.tasks.loop`)
    ``TASK_ID``, ``METRICS``; ``reset``; ``SKParams`` / ``SKWork`` and ``make``; the briefing
    (``SKBriefing``, ``BRIEF_FIELDS``, ``brief``); the env hooks ``begin``, ``cue``,
    ``post_step``, ``finish``; the compiled loop is :mod:`oneocean.kernels.sk`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..engine.constraints import DEFAULT_LAND_THRESHOLD
from ..engine.dynamics import PSI, wrap_angle
from ..engine._jit import hot_kernel
from ..engine.grid import sample_currents
from ..engine import status as st
from ..engine import streams
from ..errors import ConfigError, NotApplicable
from .common import DEPTH_RANGE_M, MIN_ALTITUDE_M, PURPOSE_RESET, STANDARD
from .spawn import feasible_codes, sample_routes, start_times
from .tiers import need_tier
from .public import briefing_class, common_brief
from .loop import GO, REACHED
from ..engine import libm

TASK_ID = "SK"
METRICS = ("rms_error_m", "hold_rms_m", "heading_rms_deg", "max_error_m", "hold_s",
           "final_rms_m")
COLUMNS = STANDARD + METRICS

#: Below this current speed (m s-1) at the start the station heading is drawn at random.
CALM_MS = 0.05
#: Settling allowance after the release, s: the station-keeping window is (SETTLE_S, T].
SETTLE_S = 60.0
#: Start-time draws per episode; the one whose current changes most over the episode is kept.
START_DRAWS = 4
#: Bearings tried for the release point before the station is declared unable to host it.
_RELEASE_TRIES = 64
#: Current changes (m s-1) closer than this tie (the data are float32).
_TIE_MS = 1e-6

(_C_RMS, _C_HRMS, _C_HDG, _C_MAX, _C_HOLD, _C_FIN) = (len(STANDARD) + i
                                                      for i in range(len(METRICS)))


def _check_times(tier: dict) -> None:
    T = float(tier["time_limit_s"])
    if float(tier["hold_time_s"]) > T:
        raise ConfigError(f"task {TASK_ID}: hold_time_s={tier['hold_time_s']} exceeds "
                          f"time_limit_s={tier['time_limit_s']}")
    if not T > SETTLE_S:
        raise ConfigError(f"task {TASK_ID}: time_limit_s={tier['time_limit_s']} must exceed "
                          f"the settling allowance SETTLE_S={SETTLE_S:g} s")


def reset(grid, tier: dict, n_agents: int, n_episodes: int, seed: int) -> dict:
    """Sample the station, its heading, the start time and the release point of every episode.

    See the module docstring; ``start_offset_m`` defaults to 0 (released on the station).

    Returns
    -------
    dict
        ``pos0`` (E, 1, 3) release point, m; ``station`` (E, 3) m; ``psi0`` (E, 1) and
        ``heading`` (E,) station heading, rad (compass); ``t0`` (E,) start times, s;
        ``regime_points`` (E, 2, 3) the station and the release point (``Cell.reset``).

    Raises
    ------
    ConfigError
        Wrong team size, missing tier keys, ``hold_time_s > time_limit_s``,
        ``time_limit_s <= SETTLE_S`` or a negative ``start_offset_m``.
    NotApplicable
        No valid station, or no release point ``start_offset_m`` from it in valid water.
    """
    if int(n_agents) != 1:
        raise ConfigError(f"task {TASK_ID}: single-agent task, got n_agents={n_agents}")
    need_tier(TASK_ID, tier, "time_limit_s", "hold_time_s")
    _check_times(tier)
    offset = float(tier.get("start_offset_m", 0.0))
    if not offset >= 0.0:
        raise ConfigError(f"task {TASK_ID}: start_offset_m must be >= 0, got "
                          f"{tier.get('start_offset_m')!r}")
    T = float(tier["time_limit_s"])
    rngs = streams.episode_states(seed, n_episodes, PURPOSE_RESET)    # one stream per episode
    t_first = start_times(grid, rngs, T)
    routes, failed = sample_routes(grid, rngs, 0, 0.0, DEPTH_RANGE_M, MIN_ALTITUDE_M,
                                   land_threshold=DEFAULT_LAND_THRESHOLD,
                                   what=lambda e: f"task {TASK_ID} reset (episode {e})")
    if failed:
        raise failed[min(failed)]
    station = routes[:, 0].copy()
    psi_rand = streams.uniform_rows(rngs, -math.pi, math.pi)[:, 0]
    # the start time: of START_DRAWS draws, the one where the station's current changes most
    t_lo, t_hi = float(grid.time_s[0]), float(grid.time_s[-1]) - T
    cand = np.repeat(t_first[:, None], START_DRAWS, axis=1)
    if t_hi > t_lo:
        cand[:, 1:] = streams.uniform_rows(rngs, t_lo, t_hi, START_DRAWS - 1)
    pts = np.repeat(station, START_DRAWS, axis=0)
    c_a = sample_currents(grid, pts, cand.reshape(-1)).astype(np.float64)
    c_b = sample_currents(grid, pts, cand.reshape(-1) + T).astype(np.float64)
    change = np.hypot(*(c_b - c_a).T).reshape(n_episodes, START_DRAWS)
    # changes within the data's float32 precision tie: the earliest draw wins
    best = np.argmax(change >= change.max(axis=1, keepdims=True) - _TIE_MS, axis=1)
    t0 = cand[np.arange(n_episodes), best]
    c = sample_currents(grid, station, t0)
    calm = np.hypot(c[:, 0], c[:, 1]) < CALM_MS
    heading = np.where(calm, psi_rand, libm.arctan2(-c[:, 0], -c[:, 1]))
    # the release point: start_offset_m from the station on a random bearing, in valid water
    # (a bearing per try from each episode's stream until one is: all episodes at a time)
    pos0 = station.copy()
    if offset > 0.0:
        todo = np.arange(n_episodes)
        for _ in range(_RELEASE_TRIES):
            if not todo.size:
                break
            b = streams.uniform_rows(rngs, -math.pi, math.pi, 1, todo)[:, 0]
            p = station[todo].copy()
            p[:, 0] += offset * libm.sin(b)
            p[:, 1] += offset * 0.0
            p[:, 2] += offset * libm.cos(b)
            ok = feasible_codes(grid, p, DEFAULT_LAND_THRESHOLD, MIN_ALTITUDE_M) == st.OK
            pos0[todo[ok]] = p[ok]
            todo = todo[~ok]
        if todo.size:
            raise NotApplicable(f"task {TASK_ID} reset (episode {todo[0]}): no release point "
                                f"{offset:g} m from the station in valid water")
    return {"pos0": pos0[:, None, :].copy(), "station": station, "psi0": heading[:, None],
            "heading": heading, "t0": t0,
            "regime_points": np.stack([station, pos0], axis=1)}


class SKParams(NamedTuple):
    """SK's params (one rollout).

    Attributes
    ----------
    radius : float
        Hold radius around the station, m.
    hold_steps : int
        Contiguous in-radius steps needed, ``H = ceil(hold_time_s / dt)``.
    settle_steps : int
        Steps of the settling allowance, ``ceil(SETTLE_S / dt)``.
    dt : float
        Step, s.
    """
    radius: float           # hold radius around the station, m
    hold_steps: int         # contiguous in-radius steps needed (ceil(hold_time_s / dt))
    settle_steps: int       # steps of the settling allowance (ceil(SETTLE_S / dt))
    dt: float               # step, s


class SKWork(NamedTuple):
    """SK's per-episode work arrays.

    Attributes
    ----------
    station : (E, 3) float64
        Station positions, m.
    heading : (E,) float64
        Station heading, rad (compass).
    acc : (E, 6) float64
        Sums of squared distance (m2) and squared heading error (rad2) over the current
        in-radius run; max distance (m) and sum of squared distance over the station-keeping
        window; the same two sums as the first over the first complete hold window.
    cnt : (E, 3) int64
        Current in-radius run, longest run (steps), success flag.
    ring : (E, H) float64
        Squared distance of the last H steps, m2 (step k at ``k % H``).
    """
    station: np.ndarray     # (E, 3) station positions, m
    heading: np.ndarray     # (E,) station heading, rad (compass)
    acc: np.ndarray         # (E, 6) sums of squared distance and squared heading error over
                            # the current in-radius run; max distance and sum of squared
                            # distance over the station-keeping window; the same two sums
                            # over the first complete hold window
    cnt: np.ndarray         # (E, 3) int64 current in-radius run, longest run, success flag
    ring: np.ndarray        # (E, H) squared distance of the last H steps (step k at k % H)


def make(grid, tier: dict, init: dict):
    """The task's params and per-episode work arrays (:mod:`oneocean.tasks.loop`).

    Returns
    -------
    P : SKParams
        The env's typed scalars.
    W : SKWork
        The env's per-episode work arrays.

    Raises
    ------
    ConfigError
        Missing tier parameters, ``hold_time_s > time_limit_s`` or
        ``time_limit_s <= SETTLE_S``.
    """
    need_tier(TASK_ID, tier, "time_limit_s", "hold_time_s", "hold_radius_m", "dt_s")
    _check_times(tier)
    dt = float(tier["dt_s"])
    n_ep = init["station"].shape[0]
    hold = max(1, int(math.ceil(float(tier["hold_time_s"]) / dt - 1e-9)))
    settle = int(math.ceil(SETTLE_S / dt - 1e-9))
    return (SKParams(float(tier["hold_radius_m"]), hold, settle, dt),
            SKWork(np.ascontiguousarray(init["station"], dtype=np.float64),
                   np.ascontiguousarray(init["heading"], dtype=np.float64),
                   np.zeros((n_ep, 6)), np.zeros((n_ep, 3), np.int64), np.zeros((n_ep, hold))))


#: The task's own observation fields: none (the cue is the station).
OBS_EXTRA_DOCS: dict = {}
OBS_EXTRA = ()
#: What the cue is (the observation's ``goal_d*`` fields).
CUE_DOC = ("the station")

#: The briefing's own fields (after :data:`oneocean.tasks.public.COMMON`): name -> (shape,
#: unit, meaning).
BRIEF_FIELDS = {
    "station": ("(E, 3)", "m", "the station (world x east, y depth, z north)"),
    "heading": ("(E,)", "rad", "the station heading to hold (compass, from north, clockwise)"),
    "radius": ("", "m", "hold radius around the station"),
    "hold_s": ("", "s", "success: within the radius for this long, contiguously"),
    "settle_s": ("", "s", "settling allowance after the release: the station-keeping window "
                 "(the primary metric) starts after it"),
}


SKBriefing = briefing_class("SK", BRIEF_FIELDS, __name__)


def brief(P: SKParams, W: SKWork, init: dict, m) -> SKBriefing:
    """The briefing of every episode of a batch (:class:`oneocean.tasks.public.Mission`
    ``m``): the station, its heading, the hold radius and time, the settling allowance.

    Returns
    -------
    SKBriefing
    """
    return SKBriefing(**common_brief(m), station=W.station.copy(), heading=W.heading.copy(),
                      radius=P.radius, hold_s=float(m.tier["hold_time_s"]),
                      settle_s=SETTLE_S)


@hot_kernel
def begin(ctx, e):
    """Reset the accumulators and counters.

    Env hook (:mod:`oneocean.tasks.loop`), before step 0; ``ctx.state`` holds the start.

    Returns
    -------
    bool
        False: the episode starts.
    """
    W = ctx.W
    for j in range(W.acc.shape[1]):
        W.acc[e, j] = 0.0
    W.cnt[e, 0] = 0
    W.cnt[e, 1] = 0
    W.cnt[e, 2] = 0
    return False


@hot_kernel
def cue(ctx, e, k, i):
    """The goal cue: the station.

    Env hook (:mod:`oneocean.tasks.loop`): the observation's goal cue and probe.

    Returns
    -------
    gx, gy, gz : float
        The goal cue, world m.
    probe : float
        NaN (the task has no field).
    """
    W = ctx.W
    return W.station[e, 0], W.station[e, 1], W.station[e, 2], math.nan


@hot_kernel
def post_step(ctx, e, k):
    """Distance and heading error after step ``k``, and the hold check.

    Env hook (:mod:`oneocean.tasks.loop`), after every agent moved in step ``k``.

    Updates the station-keeping window's sums (from step ``settle_steps`` on), the in-radius
    run and its sums (frozen as the hold window when the first hold completes) and the ring
    of the last H steps' squared distances.

    Returns
    -------
    int
        ``REACHED`` once the first hold window is complete (the episode runs on to its time
        limit), else ``GO``.
    """
    P, W, state = ctx.P, ctx.W, ctx.state
    s = state[e, 0]
    g = W.station[e]
    a = W.acc[e]
    c = W.cnt[e]
    d = math.sqrt((s[0] - g[0]) ** 2 + (s[1] - g[1]) ** 2 + (s[2] - g[2]) ** 2)
    h = wrap_angle(s[PSI] - W.heading[e])
    W.ring[e, k % W.ring.shape[1]] = d * d
    if k >= P.settle_steps:
        a[3] += d * d
        if d > a[2]:
            a[2] = d
    if d <= P.radius:
        c[0] += 1
        a[0] += d * d
        a[1] += h * h
        if c[0] > c[1]:
            c[1] = c[0]
        if c[0] >= P.hold_steps and c[2] == 0:
            c[2] = 1
            a[4] = a[0]
            a[5] = a[1]
    else:
        c[0] = 0
        a[0] = 0.0
        a[1] = 0.0
    return REACHED if c[2] != 0 else GO


@hot_kernel
def finish(ctx, e, k):
    """Write the SK metrics.

    Env hook (:mod:`oneocean.tasks.loop`), once at the end of the episode.

    The station-keeping RMS over steps ``settle_steps .. k - 1`` (every episode; NaN when the
    episode ended before the window); the hold window's RMS distance and heading error (NaN if
    no hold was completed); the RMS over the last H steps.

    Returns
    -------
    bool
        Success: a hold window was completed.
    """
    P, W = ctx.P, ctx.W
    row = ctx.res[e]
    a = W.acc[e]
    held = W.cnt[e, 2] != 0
    n_win = k - P.settle_steps
    row[_C_RMS] = math.sqrt(a[3] / n_win) if n_win > 0 else math.nan
    if held:
        row[_C_HRMS] = math.sqrt(a[4] / P.hold_steps)
        row[_C_HDG] = math.degrees(math.sqrt(a[5] / P.hold_steps))
    else:
        row[_C_HRMS] = math.nan
        row[_C_HDG] = math.nan
    row[_C_MAX] = a[2] if n_win > 0 else math.nan
    row[_C_HOLD] = W.cnt[e, 1] * P.dt
    H = W.ring.shape[1]
    n = k if k < H else H
    ss = 0.0
    for j in range(n):
        ss += W.ring[e, j]
    row[_C_FIN] = math.sqrt(ss / n) if n > 0 else math.nan
    return held
