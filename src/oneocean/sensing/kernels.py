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
    """A zero-mean normal draw of ``std``, truncated at :data:`TRUNC` sigma."""
    z = normal(seed, e, purpose, counter)
    if z > TRUNC:
        z = TRUNC
    elif z < -TRUNC:
        z = -TRUNC
    return std * z


@hot_kernel(inline="always")
def init_episode(SP, seed, e, state, fc, cb, navc, nerr):
    """Draw episode ``e``'s forecast error and every vehicle's navigation constants and start
    fix; zero the filter corrections."""
    n_ag = state.shape[1]
    fc[e, 0] = 1.0 + draw(seed, e, PURPOSE_FORECAST, 0, SP.fc_gain_std)
    s, c = sincos(draw(seed, e, PURPOSE_FORECAST, 1, SP.fc_dir_std))
    fc[e, 1] = c
    fc[e, 2] = s
    fc[e, 3] = draw(seed, e, PURPOSE_FORECAST, 2, SP.fc_bias_std)
    fc[e, 4] = draw(seed, e, PURPOSE_FORECAST, 3, SP.fc_bias_std)
    for i in range(n_ag):
        cb[e, i, 0] = 0.0
        cb[e, i, 1] = 0.0
        navc[e, i, 0] = 1.0 + draw(seed, e, PURPOSE_NAV_CONST, 4 * i, SP.scale_std)
        s, c = sincos(draw(seed, e, PURPOSE_NAV_CONST, 4 * i + 1, SP.heading_bias_std))
        navc[e, i, 1] = c
        navc[e, i, 2] = s
        std = SP.gnss_std if state[e, i, 1] <= SP.surface_depth else SP.start_fix_std
        if SP.true_position != 0:
            std = 0.0
        nerr[e, i, 0] = draw(seed, e, PURPOSE_NAV_CONST, 4 * i + 2, std)
        nerr[e, i, 1] = draw(seed, e, PURPOSE_NAV_CONST, 4 * i + 3, std)


@hot_kernel(inline="always")
def forecast(fc, e, ce, cn):
    """The forecast current (m s-1) where the true current is ``(ce, cn)``: the true vector
    scaled by ``1 + gamma``, turned clockwise by the direction error, plus the bias."""
    g = fc[e, 0]
    c = fc[e, 1]
    s = fc[e, 2]
    return g * (c * ce + s * cn) + fc[e, 3], g * (c * cn - s * ce) + fc[e, 4]


@hot_kernel(inline="always")
def current_estimate(SP, seed, cb, fc, e, k, i, n_ag, ce, cn, commit):
    """What the method knows of the current (east, north) m s-1 at agent ``i`` at step
    ``k``, where the truth is ``(ce, cn)``: the truth with ``SP.true_current``; otherwise the
    forecast plus the filter's correction after this step's in-situ sample (the update is
    stored when ``commit``: the loop; the step API's observation computes it only)."""
    if SP.true_current != 0:
        return ce, cn
    fe, fn = forecast(fc, e, ce, cn)
    cnt = 2 * (k * n_ag + i)
    ze = ce + SP.meas_std * normal(seed, e, PURPOSE_MEAS, cnt)
    zn = cn + SP.meas_std * normal(seed, e, PURPOSE_MEAS, cnt + 1)
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
    """The navigation estimate of agent ``i``: its true state with the horizontal position
    error added (depth and attitude are measured)."""
    for j in range(state.shape[2]):
        nav[e, i, j] = state[e, i, j]
    nav[e, i, 0] += nerr[e, i, 0]
    nav[e, i, 2] += nerr[e, i, 1]


@hot_kernel(inline="always")
def steady_gain(q, r):
    """Steady-state gain of a scalar Kalman filter tracking a random walk of variance ``q``
    per update from white measurements of variance ``r``: the prior variance ``M`` solves
    ``M^2 = q M + q r``; gain ``M / (M + r)`` (1 for an exact measurement, 0 without process
    noise). The one formula of :func:`oneocean.sensing.kalman_gain` (Python, ``py_func``) and
    of the in-turn USBL fix in :func:`nav_update` (whose period depends on the team size)."""
    if r <= 0.0:
        return 1.0
    if q <= 0.0:
        return 0.0
    m = 0.5 * (q + math.sqrt(q * q + 4.0 * q * r))
    return m / (m + r)


@hot_kernel(inline="always")
def nav_update(SP, seed, navc, nerr, state, prev, e, k, i, n_ag, dt):
    """Propagate agent ``i``'s position error over step ``k``: at the surface a GNSS fix;
    underwater, dead reckoning on the DVL-measured ground displacement (scale factor and
    heading bias) plus velocity noise, fused with the task's acoustic fix when one is due
    (every ``SP.fix_every`` steps, gain ``SP.fix_gain``; with ``SP.fix_seq`` the aid tracks
    the team in turn: agent ``i``'s fix every ``n_ag * SP.fix_every`` steps, in slot ``i``)."""
    if SP.true_position != 0:
        return
    cnt = 2 * (k * n_ag + i)
    if state[e, i, 1] <= SP.surface_depth:
        nerr[e, i, 0] = draw(seed, e, PURPOSE_NAV_STEP, cnt, SP.gnss_std)
        nerr[e, i, 1] = draw(seed, e, PURPOSE_NAV_STEP, cnt + 1, SP.gnss_std)
        return
    dx = state[e, i, 0] - prev[e, i, 0]
    dz = state[e, i, 2] - prev[e, i, 2]
    g = navc[e, i, 0]
    c = navc[e, i, 1]
    s = navc[e, i, 2]
    mx = g * (c * dx + s * dz)
    mz = g * (c * dz - s * dx)
    ex = nerr[e, i, 0] + mx - dx + dt * draw(seed, e, PURPOSE_NAV_STEP, cnt, SP.vel_noise)
    ez = nerr[e, i, 1] + mz - dz + dt * draw(seed, e, PURPOSE_NAV_STEP, cnt + 1, SP.vel_noise)
    if SP.fix_every > 0 and SP.fix_seq != 0:
        # the aid tracks the team in turn: agent i's fix in the i-th slot of every sequence
        # of n_ag slots, fused with the gain of its own fix period (n_ag slots)
        cyc = SP.fix_every * n_ag
        if (k + 1) % cyc == ((i + 1) * SP.fix_every) % cyc:
            K = steady_gain(SP.fix_process_var * cyc * dt, SP.fix_std * SP.fix_std)
            ex = (1.0 - K) * ex + K * draw(seed, e, PURPOSE_NAV_FIX, cnt, SP.fix_std)
            ez = (1.0 - K) * ez + K * draw(seed, e, PURPOSE_NAV_FIX, cnt + 1, SP.fix_std)
    elif SP.fix_every > 0 and (k + 1) % SP.fix_every == 0:   # fuse the acoustic fix
        K = SP.fix_gain
        ex = (1.0 - K) * ex + K * draw(seed, e, PURPOSE_NAV_FIX, cnt, SP.fix_std)
        ez = (1.0 - K) * ez + K * draw(seed, e, PURPOSE_NAV_FIX, cnt + 1, SP.fix_std)
    nerr[e, i, 0] = ex
    nerr[e, i, 1] = ez


@hot_kernel(inline="always")
def polar_fix(seed, e, counter, dx, dz, range_std, bearing_std):
    """A range-and-bearing measurement of a target at horizontal offset ``(dx, dz)`` m from
    the sensor (x east, z north): the range with white noise ``range_std`` m, the bearing
    with white noise ``bearing_std`` rad (draws truncated at :data:`TRUNC` sigma, counters
    ``counter`` and ``counter + 1`` of the perception stream). Returns the measured offset.
    A perception model of :mod:`oneocean.sensing` (``sensors.yaml`` ``perception``); the
    caller decides whether the target is seen (range, period) and whether the method is given
    the truth instead (``SensingParams.true_target``)."""
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
def init_sensing(SP, seed, state, fc, cb, navc, nerr):
    """:func:`init_episode` for every episode of ``state`` (E, N, STATE_DIM)."""
    for e in range(state.shape[0]):
        init_episode(SP, seed, e, state, fc, cb, navc, nerr)


# numba keys a cache entry on this file only; drop it when the engine changes
ensure_fresh_cache(init_sensing, ("kernels.",), Path(__file__).resolve())
