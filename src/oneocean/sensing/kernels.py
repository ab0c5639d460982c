"""Kernels of the sensing and navigation models (:mod:`oneocean.sensing`), inlined into the
one episode loop (:mod:`oneocean.tasks.loop`).

Per-episode state lives in the loop's :class:`~oneocean.tasks.loop.LoopState`:
``fc`` (E, 5) the episode's forecast error (1 + gain, cos and sin of the direction error,
bias east, bias north); ``cb`` (E, N, 2) each vehicle's filtered forecast correction, m s-1;
``navc`` (E, N, 3) its dead-reckoning constants (1 + scale factor, cos and sin of the heading
bias); ``nerr`` (E, N, 2) its horizontal position error (estimate - truth, x east and z
north), m. Every draw is counter-based (:func:`oneocean.engine.rng.normal`), so the models do
not depend on thread count or episode order, and an observation computed between segments
(:func:`current_estimate` with ``commit=0``) equals what the loop then uses.

Trigonometry of the error angles is the engine's :func:`~oneocean.engine.dynamics.sincos`
(fdlibm's polynomials in plain arithmetic: the same bits on every CPU, which libm's ``sin`` /
``cos`` with their FMA variants may not give).
"""

from __future__ import annotations

import math
from pathlib import Path

from ..engine._jit import ensure_fresh_cache, hot_kernel
from ..engine.dynamics import sincos
from ..engine.rng import PURPOSE_TASK, normal

#: Random-stream purposes (part of every seeded result: keep stable). The in-situ current
#: noise keeps the task layer's probe stream (``PURPOSE_TASK + 1``).
PURPOSE_MEAS = PURPOSE_TASK + 1
PURPOSE_NAV_CONST = PURPOSE_TASK + 4
PURPOSE_NAV_STEP = PURPOSE_TASK + 5
PURPOSE_FORECAST = PURPOSE_TASK + 6
PURPOSE_NAV_FIX = PURPOSE_TASK + 7
PURPOSE_PERCEPTION = PURPOSE_TASK + 8

#: Error draws are truncated at this many standard deviations.
TRUNC = 3.0


@hot_kernel(inline="always")
def draw(seed, e, purpose, counter, std):
    """A zero-mean normal draw of standard deviation ``std``, truncated at :data:`TRUNC` sigma.

    Parameters
    ----------
    seed : int
        Run seed.
    e : int
        The stream's episode (the cell's episode number, ``e0 + e`` of a batch row).
    purpose : int
        The stream's purpose (``PURPOSE_*``).
    counter : int
        Counter within the stream.
    std : float
        Standard deviation, in the unit of the draw.

    Returns
    -------
    float
        ``std * z`` with ``z`` a standard normal clipped to ``[-TRUNC, TRUNC]``.
    """
    z = normal(seed, e, purpose, counter)
    if z > TRUNC:
        z = TRUNC
    elif z < -TRUNC:
        z = -TRUNC
    return std * z


@hot_kernel(inline="always")
def init_episode(SP, seed, e, state, fc, cb, navc, nerr, e0=0):
    """Draw episode ``e``'s forecast error and every vehicle's navigation constants and start
    fix; zero the filter corrections.

    The start fix error has the GNSS standard deviation for a vehicle at the surface (depth
    at most ``SP.surface_depth``), else ``SP.start_fix_std``; it is 0 with
    ``SP.true_position``.

    Parameters
    ----------
    SP : SensingParams
        The rollout's sensing models (:class:`oneocean.sensing.SensingParams`).
    seed : int
        Run seed.
    e : int
        Episode index (row of the arrays).
    state : (E, N, STATE_DIM) float64
        True vehicle states at the start (layout: :mod:`oneocean.engine.dynamics`).
    fc : (E, 5) float64
        Forecast errors (1 + gain, cos and sin of the direction error, bias east and north
        m s-1), row ``e`` written.
    cb : (E, N, 2) float64
        Filtered forecast corrections, m s-1, row ``e`` zeroed.
    navc : (E, N, 3) float64
        Dead-reckoning constants (1 + scale factor, cos and sin of the heading bias), row
        ``e`` written.
    nerr : (E, N, 2) float64
        Horizontal position errors (x east, z north), m, row ``e`` set to the start fix's.
    e0 : int
        The cell's episode of row 0: row ``e`` draws the streams of episode ``e0 + e``
        (0 unless the cell runs in shards).
    """
    n_ag = state.shape[1]
    ep = e0 + e
    fc[e, 0] = 1.0 + draw(seed, ep, PURPOSE_FORECAST, 0, SP.fc_gain_std)
    s, c = sincos(draw(seed, ep, PURPOSE_FORECAST, 1, SP.fc_dir_std))
    fc[e, 1] = c
    fc[e, 2] = s
    fc[e, 3] = draw(seed, ep, PURPOSE_FORECAST, 2, SP.fc_bias_std)
    fc[e, 4] = draw(seed, ep, PURPOSE_FORECAST, 3, SP.fc_bias_std)
    for i in range(n_ag):
        cb[e, i, 0] = 0.0
        cb[e, i, 1] = 0.0
        navc[e, i, 0] = 1.0 + draw(seed, ep, PURPOSE_NAV_CONST, 4 * i, SP.scale_std)
        s, c = sincos(draw(seed, ep, PURPOSE_NAV_CONST, 4 * i + 1, SP.heading_bias_std))
        navc[e, i, 1] = c
        navc[e, i, 2] = s
        std = SP.gnss_std if state[e, i, 1] <= SP.surface_depth else SP.start_fix_std
        if SP.true_position != 0:
            std = 0.0
        nerr[e, i, 0] = draw(seed, ep, PURPOSE_NAV_CONST, 4 * i + 2, std)
        nerr[e, i, 1] = draw(seed, ep, PURPOSE_NAV_CONST, 4 * i + 3, std)


@hot_kernel(inline="always")
def forecast(fc, e, ce, cn):
    """The forecast current where the true current is ``(ce, cn)``.

    The true vector scaled by ``1 + gamma``, turned clockwise by the direction error, plus
    the bias (episode ``e``'s forecast error ``fc[e]``).

    Parameters
    ----------
    fc : (E, 5) float64
        Forecast errors (:func:`init_episode`).
    e : int
        Episode index.
    ce, cn : float
        True current, east and north, m s-1.

    Returns
    -------
    fe, fn : float
        Forecast current, east and north, m s-1.
    """
    g = fc[e, 0]
    c = fc[e, 1]
    s = fc[e, 2]
    return g * (c * ce + s * cn) + fc[e, 3], g * (c * cn - s * ce) + fc[e, 4]


@hot_kernel(inline="always")
def current_estimate(SP, seed, cb, fc, e, k, i, n_ag, ce, cn, commit, e0=0):
    """What the method knows of the current at agent ``i`` at step ``k``.

    The truth with ``SP.true_current``; otherwise the forecast plus the filter's correction
    after this step's in-situ sample (noise ``SP.meas_std``, gain ``SP.kf_gain``).

    Parameters
    ----------
    SP : SensingParams
        The rollout's sensing models (:class:`oneocean.sensing.SensingParams`).
    seed : int
        Run seed.
    cb : (E, N, 2) float64
        Filtered forecast corrections, m s-1; entry ``[e, i]`` updated when ``commit``.
    fc : (E, 5) float64
        Forecast errors (:func:`init_episode`).
    e : int
        Episode index.
    k : int
        Step index.
    i : int
        Agent index.
    n_ag : int
        Team size N (the sample's stream counter is ``2 (k N + i)``).
    ce, cn : float
        True current at the agent, east and north, m s-1.
    commit : int
        1: store the filter update (the loop); 0: compute it only (the step API's
        observation between segments, which then equals what the loop uses).
    e0 : int
        The cell's episode of row 0: row ``e`` draws episode ``e0 + e``'s stream
        (:func:`init_episode`).

    Returns
    -------
    pe, pn : float
        The current estimate, east and north, m s-1.
    """
    if SP.true_current != 0:
        return ce, cn
    fe, fn = forecast(fc, e, ce, cn)
    cnt = 2 * (k * n_ag + i)
    ze = ce + SP.meas_std * normal(seed, e0 + e, PURPOSE_MEAS, cnt)
    zn = cn + SP.meas_std * normal(seed, e0 + e, PURPOSE_MEAS, cnt + 1)
    be = cb[e, i, 0]
    bn = cb[e, i, 1]
    be += SP.kf_gain * (ze - fe - be)
    bn += SP.kf_gain * (zn - fn - bn)
    if commit != 0:
        cb[e, i, 0] = be
        cb[e, i, 1] = bn
    return fe + be, fn + bn


@hot_kernel(inline="always")
def nav_fill(state, nerr, nav, e, i):
    """Write the navigation estimate of agent ``i``: its true state with the horizontal
    position error added (depth and attitude are measured).

    Parameters
    ----------
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    nerr : (E, N, 2) float64
        Horizontal position errors (x east, z north), m.
    nav : (E, N, STATE_DIM) float64
        Navigation estimates, entry ``[e, i]`` written.
    e : int
        Episode index.
    i : int
        Agent index.
    """
    for j in range(state.shape[2]):
        nav[e, i, j] = state[e, i, j]
    nav[e, i, 0] += nerr[e, i, 0]
    nav[e, i, 2] += nerr[e, i, 1]


@hot_kernel(inline="always")
def steady_gain(q, r):
    """Steady-state gain of a scalar Kalman filter tracking a random walk from white
    measurements.

    The prior variance ``M`` solves ``M^2 = q M + q r``; the gain is ``M / (M + r)``. The one
    formula of :func:`oneocean.sensing.kalman_gain` (Python, ``py_func``) and of the in-turn
    USBL fix in :func:`nav_update` (whose period depends on the team size).

    Parameters
    ----------
    q : float
        Process variance of the random walk per update.
    r : float
        Measurement variance, in the same unit squared.

    Returns
    -------
    float
        The gain in [0, 1]: 1 for an exact measurement (``r <= 0``), 0 without process
        noise (``q <= 0``).
    """
    if r <= 0.0:
        return 1.0
    if q <= 0.0:
        return 0.0
    m = 0.5 * (q + math.sqrt(q * q + 4.0 * q * r))
    return m / (m + r)


@hot_kernel(inline="always")
def nav_update(SP, seed, navc, nerr, state, prev, e, k, i, n_ag, dt, e0=0):
    """Propagate agent ``i``'s position error over step ``k``.

    At the surface a GNSS fix; underwater, dead reckoning on the DVL-measured ground
    displacement (scale factor and heading bias) plus velocity noise, fused with the task's
    acoustic fix when one is due (every ``SP.fix_every`` steps, gain ``SP.fix_gain``; with
    ``SP.fix_seq`` the aid tracks the team in turn: agent ``i``'s fix every
    ``n_ag * SP.fix_every`` steps, in slot ``i``). Nothing with ``SP.true_position``.

    Parameters
    ----------
    SP : SensingParams
        The rollout's sensing models (:class:`oneocean.sensing.SensingParams`).
    seed : int
        Run seed.
    navc : (E, N, 3) float64
        Dead-reckoning constants (:func:`init_episode`).
    nerr : (E, N, 2) float64
        Horizontal position errors (x east, z north), m; entry ``[e, i]`` updated.
    state : (E, N, STATE_DIM) float64
        True vehicle states after the step (layout: :mod:`oneocean.engine.dynamics`).
    prev : (E, N, 3) float64
        Positions before the step, m.
    e : int
        Episode index.
    k : int
        Step index.
    i : int
        Agent index.
    n_ag : int
        Team size N.
    dt : float
        Step, s.
    e0 : int
        The cell's episode of row 0: row ``e`` draws episode ``e0 + e``'s streams
        (:func:`init_episode`).

    Returns
    -------
    int
        1 if an absolute position fix (GNSS at the surface, the acoustic aid) was fused at
        this step, else 0.
    """
    if SP.true_position != 0:
        return 0
    ep = e0 + e
    cnt = 2 * (k * n_ag + i)
    if state[e, i, 1] <= SP.surface_depth:
        nerr[e, i, 0] = draw(seed, ep, PURPOSE_NAV_STEP, cnt, SP.gnss_std)
        nerr[e, i, 1] = draw(seed, ep, PURPOSE_NAV_STEP, cnt + 1, SP.gnss_std)
        return 1
    fix = 0
    dx = state[e, i, 0] - prev[e, i, 0]
    dz = state[e, i, 2] - prev[e, i, 2]
    g = navc[e, i, 0]
    c = navc[e, i, 1]
    s = navc[e, i, 2]
    mx = g * (c * dx + s * dz)
    mz = g * (c * dz - s * dx)
    ex = nerr[e, i, 0] + mx - dx + dt * draw(seed, ep, PURPOSE_NAV_STEP, cnt, SP.vel_noise)
    ez = nerr[e, i, 1] + mz - dz + dt * draw(seed, ep, PURPOSE_NAV_STEP, cnt + 1, SP.vel_noise)
    if SP.fix_every > 0 and SP.fix_seq != 0:
        # the aid tracks the team in turn: agent i's fix in the i-th slot of every sequence
        # of n_ag slots, fused with the gain of its own fix period (n_ag slots)
        cyc = SP.fix_every * n_ag
        if (k + 1) % cyc == ((i + 1) * SP.fix_every) % cyc:
            K = steady_gain(SP.fix_process_var * cyc * dt, SP.fix_std * SP.fix_std)
            ex = (1.0 - K) * ex + K * draw(seed, ep, PURPOSE_NAV_FIX, cnt, SP.fix_std)
            ez = (1.0 - K) * ez + K * draw(seed, ep, PURPOSE_NAV_FIX, cnt + 1, SP.fix_std)
            fix = 1
    elif SP.fix_every > 0 and (k + 1) % SP.fix_every == 0:   # fuse the acoustic fix
        K = SP.fix_gain
        ex = (1.0 - K) * ex + K * draw(seed, ep, PURPOSE_NAV_FIX, cnt, SP.fix_std)
        ez = (1.0 - K) * ez + K * draw(seed, ep, PURPOSE_NAV_FIX, cnt + 1, SP.fix_std)
        fix = 1
    nerr[e, i, 0] = ex
    nerr[e, i, 1] = ez
    return fix


@hot_kernel(inline="always")
def polar_fix(seed, e, counter, dx, dz, range_std, bearing_std):
    """A range-and-bearing measurement of a target at a horizontal offset from the sensor.

    Draws truncated at :data:`TRUNC` sigma, counters ``counter`` and ``counter + 1`` of the
    perception stream. A perception model of :mod:`oneocean.sensing` (``sensors.yaml``
    ``perception``); the caller decides whether the target is seen (range, period) and
    whether the method is given the truth instead (``SensingParams.true_target``).

    Parameters
    ----------
    seed : int
        Run seed.
    e : int
        The stream's episode (the cell's episode number).
    counter : int
        First counter of the two draws in the perception stream.
    dx, dz : float
        True offset of the target from the sensor, x east and z north, m.
    range_std : float
        White range noise, m.
    bearing_std : float
        White bearing noise, rad.

    Returns
    -------
    mx, mz : float
        Measured offset (x east, z north), m; the measured range is at least 0, and
        ``(0, 0)`` for a target at the sensor.
    """
    r = (dx * dx + dz * dz) ** 0.5
    rm = r + draw(seed, e, PURPOSE_PERCEPTION, counter, range_std)
    if rm < 0.0:
        rm = 0.0
    if r <= 0.0:
        return 0.0, 0.0
    s, c = sincos(draw(seed, e, PURPOSE_PERCEPTION, counter + 1, bearing_std))
    ux = dx / r
    uz = dz / r
    return rm * (c * ux + s * uz), rm * (c * uz - s * ux)


@hot_kernel
def init_sensing(SP, seed, state, fc, cb, navc, nerr, e0=0):
    """:func:`init_episode` for every episode of ``state``.

    Parameters
    ----------
    SP : SensingParams
        The rollout's sensing models (:class:`oneocean.sensing.SensingParams`).
    seed : int
        Run seed.
    state : (E, N, STATE_DIM) float64
        True vehicle states at the start (layout: :mod:`oneocean.engine.dynamics`).
    fc : (E, 5) float64
        Forecast errors, written.
    cb : (E, N, 2) float64
        Filtered forecast corrections, m s-1, zeroed.
    navc : (E, N, 3) float64
        Dead-reckoning constants, written.
    nerr : (E, N, 2) float64
        Horizontal position errors, m, set to the start fixes'.
    e0 : int
        The cell's episode of row 0: row ``e`` is the cell's episode ``e0 + e``.
    """
    for e in range(state.shape[0]):
        init_episode(SP, seed, e, state, fc, cb, navc, nerr, e0)


# numba keys a cache entry on this file only; drop it when the engine changes
ensure_fresh_cache(init_sensing, ("kernels.",), Path(__file__).resolve())
