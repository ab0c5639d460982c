"""A fish school (boids-style) that coheres, flees vehicles and drifts with the currents.

State of ``N`` fish (2-D horizontal, world metres, x east, z north): positions ``fx, fz`` and
swim velocities ``fvx, fvz`` (relative to the water), each (N,) float64. One step of
:func:`step_school` reads the old state and writes the new one into separate output arrays
(synchronous update), so a rollout loop double-buffers.

Per fish ``i`` the swim velocity is updated by, in this order,

1. alignment: relax toward the mean swim velocity of neighbours within ``perception_radius``
   with rate ``w_alignment`` (exact exponential relaxation over ``dt``);
2. damping: ``v *= exp(-damping * dt)`` (a loitering school does not cruise away);
3. acceleration ``a`` (norm capped at ``max_accel``) summed from

   - local cohesion ``w_cohesion * (neighbour centroid - x)``,
   - global cohesion ``w_cohesion_global * (school centroid - x)``,
   - separation ``w_separation * (1 - d / separation_radius)`` away from each fish closer
     than ``separation_radius``,
   - flee ``w_flee * (1 - d / flee_radius)`` away from each vehicle closer than
     ``flee_radius`` (linear decay with distance),
   - jitter: ``jitter * (g_x, g_z)`` with standard normals from a counter-based hash of
     ``(seed, step, fish index)`` (no global RNG state; deterministic on any thread count);

   ``v += a * dt``;
4. speed cap ``|v| <= max_speed``;

then the fish moves with the water: ``x += (v + current at the fish) * dt``.

Parameter vector (float64, this order; build it with :func:`fish_params`):

== ===================== ======== ============================================================
 #  name                  unit     meaning
== ===================== ======== ============================================================
 0  max_speed             m s-1    cap on the swim speed (relative to the water)
 1  perception_radius     m        neighbours for local cohesion and alignment
 2  separation_radius     m        fish closer than this repel each other
 3  w_cohesion            s-2      gain toward the neighbours' centroid
 4  w_cohesion_global     s-2      gain toward the whole school's centroid
 5  w_separation          m s-2    separation acceleration at zero distance
 6  w_alignment           s-1      relaxation rate toward neighbours' mean velocity
 7  damping               s-1      relaxation rate of the swim velocity toward 0
 8  flee_radius           m        vehicles closer than this scare a fish
 9  w_flee                m s-2    flee acceleration at zero distance (per vehicle)
10  jitter                m s-2    standard deviation of the random acceleration per axis
11  max_accel             m s-2    cap on the norm of the summed acceleration
== ===================== ======== ============================================================
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..errors import ConfigError
from ..engine import libm

__all__ = [
    "FISH_PARAM_NAMES", "FISH_PARAM_DEFAULTS", "N_FISH_PARAMS",
    "step_school", "step_school_into", "school_centroid", "school_spread",
    "fraction_inside_circle", "counter_uniform", "fish_params", "init_school",
]

#: Parameter names in vector order (see module docstring for units).
FISH_PARAM_NAMES: tuple[str, ...] = (
    "max_speed", "perception_radius", "separation_radius", "w_cohesion", "w_cohesion_global",
    "w_separation", "w_alignment", "damping", "flee_radius", "w_flee", "jitter", "max_accel",
)
#: Defaults: a loitering school (RMS radius ~3 m at N = 50, ~6 m at N = 200) that avoids
#: vehicles within 15 m. ``max_speed`` 0.8 m/s: the sustained (aerobic) swimming speed of
#: 20-30 cm schooling fish is ~2-3 body lengths/s, 0.5-0.9 m/s (Beamish 1978, "Swimming
#: capacity", Fish Physiology VII; Videler 1993, "Fish Swimming"); the model's cap stands for a
#: sustained avoidance, not the second-long burst escape (~10 body lengths/s). ``w_flee``
#: 0.5 m/s2: a graded avoidance of a slow, quiet electric vehicle (one vehicle at 10 m drives
#: ~0.5 m/s rather than an all-out escape at the edge of the reaction distance; fish mostly
#: show weak or gradual avoidance of ROVs: Stoner et al. 2008, Rev. Fish Biol. Fish. 18:1-20).
#: With these a ~0.85 m/s ROV team can herd a school (it is slightly faster than the school's
#: sustained flee), as a herder must be.
FISH_PARAM_DEFAULTS: dict[str, float] = {
    "max_speed": 0.8,
    "perception_radius": 6.0,
    "separation_radius": 1.5,
    "w_cohesion": 0.05,
    "w_cohesion_global": 0.01,
    "w_separation": 1.0,
    "w_alignment": 0.3,
    "damping": 0.3,
    "flee_radius": 15.0,
    "w_flee": 0.5,
    "jitter": 0.1,
    "max_accel": 3.0,
}
N_FISH_PARAMS = len(FISH_PARAM_NAMES)

_P_VMAX, _P_RPER, _P_RSEP, _P_COH, _P_COHG, _P_SEP, _P_ALI, _P_DAMP, _P_RFLEE, _P_FLEE, \
    _P_JIT, _P_AMAX = range(N_FISH_PARAMS)

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_INV53 = 1.0 / 9007199254740992.0  # 2**-53


@numba.njit(cache=True)
def _splitmix64(x):
    z = x + _GOLDEN
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


@numba.njit(cache=True)
def counter_uniform(seed, step, index):
    """Counter-based uniform in [0, 1) from integers ``(seed, step, index)`` (splitmix64).

    Pure function: the same triple always gives the same number, in any process or thread.

    Parameters
    ----------
    seed : int
        Stream seed.
    step : int
        Step index.
    index : int
        Draw index within the step (e.g. ``2 i`` and ``2 i + 1`` for fish ``i``).

    Returns
    -------
    float
        The draw, in [0, 1) (53 random bits).
    """
    z = _splitmix64(np.uint64(seed))
    z = _splitmix64(z ^ np.uint64(step))
    z = _splitmix64(z ^ np.uint64(index))
    return np.float64(z >> _S11) * _INV53


@numba.njit(cache=True)
def school_centroid(fx, fz):
    """Mean fish position.

    Parameters
    ----------
    fx, fz : (N,) float64
        Fish positions (world x east, z north), m.

    Returns
    -------
    tuple of float
        ``(x, z)``, m; NaN for an empty school.
    """
    n = fx.shape[0]
    if n == 0:
        return np.nan, np.nan
    sx = 0.0
    sz = 0.0
    for i in range(n):
        sx += fx[i]
        sz += fz[i]
    return sx / n, sz / n


@numba.njit(cache=True)
def school_spread(fx, fz):
    """RMS distance of the fish from the school centroid.

    Parameters
    ----------
    fx, fz : (N,) float64
        Fish positions (world x east, z north), m.

    Returns
    -------
    float
        RMS distance, m; NaN for an empty school.
    """
    n = fx.shape[0]
    if n == 0:
        return np.nan
    cx, cz = school_centroid(fx, fz)
    acc = 0.0
    for i in range(n):
        acc += (fx[i] - cx) ** 2 + (fz[i] - cz) ** 2
    return math.sqrt(acc / n)


@numba.njit(cache=True)
def fraction_inside_circle(fx, fz, cx, cz, radius):
    """Fraction of fish within ``radius`` of ``(cx, cz)`` (inclusive).

    Parameters
    ----------
    fx, fz : (N,) float64
        Fish positions (world x east, z north), m.
    cx, cz : float
        Circle centre, m.
    radius : float
        Circle radius, m.

    Returns
    -------
    float
        Fraction in [0, 1]; 0 for an empty school.
    """
    n = fx.shape[0]
    if n == 0:
        return 0.0
    r2 = radius * radius
    k = 0
    for i in range(n):
        if (fx[i] - cx) ** 2 + (fz[i] - cz) ** 2 <= r2:
            k += 1
    return k / n


@numba.njit(cache=True, error_model="numpy")
def step_school_into(fx, fz, fvx, fvz, agents_x, agents_z, cur_x, cur_z, params, seed, step,
                     dt, out_x, out_z, out_vx, out_vz, work):
    """:func:`step_school` with the caller's scratch ``work`` (a kernel compiled without
    reference counting cannot allocate): the same values.

    Parameters
    ----------
    fx, fz, fvx, fvz, agents_x, agents_z, cur_x, cur_z, params, seed, step, dt
        As for :func:`step_school`.
    out_x, out_z, out_vx, out_vz : (N,) float64
        As for :func:`step_school`: written.
    work : (7, M) float64, M >= N
        Scratch for the neighbour sums, overwritten.

    Raises
    ------
    ValueError
        As :func:`step_school`, and when ``work`` is smaller than (7, N).
    """
    n = fx.shape[0]
    m = agents_x.shape[0]
    if params.shape[0] < N_FISH_PARAMS:
        raise ValueError("step_school: params needs 12 values (see fish_params)")
    if (fz.shape[0] != n or fvx.shape[0] != n or fvz.shape[0] != n or cur_x.shape[0] != n
            or cur_z.shape[0] != n or out_x.shape[0] != n or out_z.shape[0] != n
            or out_vx.shape[0] != n or out_vz.shape[0] != n or agents_z.shape[0] != m):
        raise ValueError("step_school: fish/agent arrays have inconsistent lengths")
    if n > 0:
        for o in (out_x.ctypes.data, out_z.ctypes.data, out_vx.ctypes.data, out_vz.ctypes.data):
            if (o == fx.ctypes.data or o == fz.ctypes.data or o == fvx.ctypes.data
                    or o == fvz.ctypes.data):
                raise ValueError("step_school: output arrays must not alias the input state")
    vmax = params[_P_VMAX]
    r_per = params[_P_RPER]
    r_sep = params[_P_RSEP]
    w_coh = params[_P_COH]
    w_cohg = params[_P_COHG]
    w_sep = params[_P_SEP]
    w_ali = params[_P_ALI]
    damp = params[_P_DAMP]
    r_flee = params[_P_RFLEE]
    w_flee = params[_P_FLEE]
    jit = params[_P_JIT]
    amax = params[_P_AMAX]
    r_per2 = r_per * r_per
    r_sep2 = r_sep * r_sep
    r_flee2 = r_flee * r_flee
    f_ali = 1.0 - math.exp(-w_ali * dt)
    f_damp = math.exp(-damp * dt)
    gcx, gcz = school_centroid(fx, fz)
    self_w = 1.0 if r_per2 > 0.0 else 0.0  # fish i counts itself in the neighbour loop
    two_pi = 2.0 * math.pi

    # neighbour sums of every fish (fish i itself included, removed below), one fish k at a
    # time across the school: each fish's sums over k in the order of k, as a loop over k
    # per fish takes them (the same bits), while the loop over the school's fish has no
    # branch and runs in vector lanes. Separation: the few fish too close; the other lanes
    # add 0.0, which leaves a sum unchanged (a sum that starts at +0.0 is never -0.0)
    if work.shape[0] < 7 or work.shape[1] < n:
        raise ValueError("step_school: work needs shape (7, N) or larger")
    for j in range(7):
        for i in range(n):
            work[j, i] = 0.0
    cnt_s = work[0]
    sx_s = work[1]
    sz_s = work[2]
    svx_s = work[3]
    svz_s = work[4]
    ax_s = work[5]
    az_s = work[6]
    for k in range(n):
        xk = fx[k]
        zk = fz[k]
        uk = fvx[k]
        vk = fvz[k]
        for i in range(n):
            dx = fx[i] - xk
            dz = fz[i] - zk
            d2 = dx * dx + dz * dz
            w = 1.0 if d2 < r_per2 else 0.0
            cnt_s[i] += w
            sx_s[i] += w * xk
            sz_s[i] += w * zk
            svx_s[i] += w * uk
            svz_s[i] += w * vk
            close = d2 < r_sep2 and d2 > 0.0
            d = math.sqrt(d2)
            g = w_sep * (1.0 - d / r_sep) / d
            ax_s[i] += g * dx if close else 0.0
            az_s[i] += g * dz if close else 0.0
    for i in range(n):
        xi = fx[i]
        zi = fz[i]
        vx = fvx[i]
        vz = fvz[i]
        cntf = cnt_s[i]
        sx = sx_s[i]
        sz = sz_s[i]
        svx = svx_s[i]
        svz = svz_s[i]
        ax = ax_s[i]
        az = az_s[i]
        cnt = int(cntf - self_w + 0.5)
        sx -= self_w * xi
        sz -= self_w * zi
        svx -= self_w * vx
        svz -= self_w * vz
        # 1. alignment, 2. damping
        if cnt > 0:
            inv = 1.0 / cnt
            vx += f_ali * (svx * inv - vx)
            vz += f_ali * (svz * inv - vz)
            ax += w_coh * (sx * inv - xi)
            az += w_coh * (sz * inv - zi)
        vx *= f_damp
        vz *= f_damp
        # 3. accelerations: global cohesion, flee, jitter
        ax += w_cohg * (gcx - xi)
        az += w_cohg * (gcz - zi)
        for a in range(m):
            dx = xi - agents_x[a]
            dz = zi - agents_z[a]
            d2 = dx * dx + dz * dz
            if d2 < r_flee2:  # False for NaN positions
                d = math.sqrt(d2)
                if d > 0.0:
                    g = w_flee * (1.0 - d / r_flee) / d
                    ax += g * dx
                    az += g * dz
                else:  # on top of the fish: flee in a hashed direction
                    th = two_pi * counter_uniform(seed, step, 2 * n + i)
                    ax += w_flee * math.cos(th)
                    az += w_flee * math.sin(th)
        if jit > 0.0:
            u1 = 1.0 - counter_uniform(seed, step, 2 * i)  # (0, 1]
            u2 = counter_uniform(seed, step, 2 * i + 1)
            rr = math.sqrt(-2.0 * math.log(u1))
            ax += jit * rr * math.cos(two_pi * u2)
            az += jit * rr * math.sin(two_pi * u2)
        an = math.sqrt(ax * ax + az * az)
        if an > amax:
            ax *= amax / an
            az *= amax / an
        vx += ax * dt
        vz += az * dt
        # 4. speed cap
        sp = math.sqrt(vx * vx + vz * vz)
        if sp > vmax:
            vx *= vmax / sp
            vz *= vmax / sp
        cx = cur_x[i]
        cz = cur_z[i]
        if not math.isfinite(cx):
            cx = 0.0
        if not math.isfinite(cz):
            cz = 0.0
        out_vx[i] = vx
        out_vz[i] = vz
        out_x[i] = xi + (vx + cx) * dt
        out_z[i] = zi + (vz + cz) * dt


@numba.njit(cache=True, error_model="numpy")
def step_school(fx, fz, fvx, fvz, agents_x, agents_z, cur_x, cur_z, params, seed, step, dt,
                out_x, out_z, out_vx, out_vz):
    """Advance the school by one step of ``dt`` (synchronous update, O(N^2 + N M)).

    Parameters
    ----------
    fx, fz : (N,) float64, m
        Fish positions (world).
    fvx, fvz : (N,) float64, m s-1
        Fish swim velocities relative to the water.
    agents_x, agents_z : (M,) float64, m
        Vehicle positions (M may be 0); non-finite entries are ignored.
    cur_x, cur_z : (N,) float64, m s-1
        Current (east, north) at each fish, sampled by the caller (NaN read as 0).
    params : (12,) float64
        Parameter vector (order in the module docstring; see :func:`fish_params`).
    seed, step : int
        Jitter stream key: the random acceleration of fish ``i`` is a pure function of
        ``(seed, step, i)``.
    dt : float
        Time step, s.
    out_x, out_z, out_vx, out_vz : (N,) float64
        New positions (m) and swim velocities (m s-1). Must not share memory with the inputs
        (an output that starts at an input's address raises ValueError).

    Raises
    ------
    ValueError
        If ``params`` has fewer than 12 values, the arrays' lengths disagree, or an output
        aliases the input state.

    Notes
    -----
    The ground speed of every fish is at most ``max_speed + |current|``. Each fish's
    neighbour sums run over the school in index order (:func:`step_school_into`, which
    takes them for every fish at once).
    """
    step_school_into(fx, fz, fvx, fvz, agents_x, agents_z, cur_x, cur_z, params, seed, step,
                     dt, out_x, out_z, out_vx, out_vz, np.empty((7, fx.shape[0])))


def fish_params(overrides: dict | None = None) -> np.ndarray:
    """Parameter vector for :func:`step_school` from a dict over :data:`FISH_PARAM_DEFAULTS`.

    Parameters
    ----------
    overrides : dict, optional
        Any of :data:`FISH_PARAM_NAMES`; unknown keys or negative values raise ConfigError.

    Returns
    -------
    (12,) float64
        Parameter vector, order of :data:`FISH_PARAM_NAMES`.

    Raises
    ------
    ConfigError
        If a key is unknown, a value is negative or non-finite, or ``max_speed``,
        ``perception_radius``, ``separation_radius``, ``flee_radius`` or ``max_accel`` is 0.
    """
    vals = dict(FISH_PARAM_DEFAULTS)
    for key, val in (overrides or {}).items():
        if key not in FISH_PARAM_DEFAULTS:
            opts = ", ".join(repr(k) for k in FISH_PARAM_NAMES)
            raise ConfigError(f"fish params: invalid key {key!r}. Valid options are ({opts}).")
        vals[key] = float(val)
    for key in FISH_PARAM_NAMES:
        if not (vals[key] >= 0.0 and np.isfinite(vals[key])):
            raise ConfigError(f"fish params: {key} must be finite and >= 0, got {vals[key]!r}")
    for key in ("max_speed", "perception_radius", "separation_radius", "flee_radius",
                "max_accel"):
        if vals[key] <= 0.0:
            raise ConfigError(f"fish params: {key} must be > 0, got {vals[key]!r}")
    return np.array([vals[k] for k in FISH_PARAM_NAMES], dtype=np.float64)


def init_school(n: int, centre, radius: float, seed):
    """Fish uniformly in a disc, at rest.

    Parameters
    ----------
    n : int
        Number of fish (>= 1).
    centre : (2,) float, m
        Disc centre ``(x, z)`` (world).
    radius : float, m
        Disc radius (> 0).
    seed : int, sequence of int, numpy.random.SeedSequence or numpy.random.Generator
        Randomness source; ints and sequences go through ``SeedSequence`` (e.g.
        ``[seed, episode, purpose]``).

    Returns
    -------
    fx, fz, fvx, fvz : (n,) float64
        Positions (m) and swim velocities (m s-1, zero).

    Raises
    ------
    ConfigError
        If ``n < 1`` or ``radius <= 0``.
    """
    if int(n) < 1 or not radius > 0:
        raise ConfigError(f"init_school: need n >= 1 and radius > 0 (got {n}, {radius})")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(
        seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed))
    r = radius * np.sqrt(rng.uniform(0.0, 1.0, n))
    th = rng.uniform(0.0, 2.0 * np.pi, n)
    fx = float(centre[0]) + r * libm.cos(th)
    fz = float(centre[1]) + r * libm.sin(th)
    return fx, fz, np.zeros(n), np.zeros(n)
