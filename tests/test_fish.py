"""Fish school kernel: cohesion, drift with currents, fleeing, speed bounds, determinism."""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from oneocean.errors import ConfigError
from oneocean.models import fish as F

PARAMS = F.fish_params()
VMAX = PARAMS[F.FISH_PARAM_NAMES.index("max_speed")]
NONE = np.empty(0)


def _run(n=50, steps=300, seed=1, dt=1.0, current=None, agents=None, params=PARAMS,
         check_speed=False):
    """Roll the school out; ``current(fx, fz) -> (cx, cz)``, ``agents(t) -> (ax, az)``."""
    fx, fz, vx, vz = F.init_school(n, (0.0, 0.0), 8.0, seed)
    ox, oz, ovx, ovz = (np.empty(n) for _ in range(4))
    zeros = np.zeros(n)
    for step in range(steps):
        cx, cz = current(fx, fz) if current else (zeros, zeros)
        ax, az = agents(step * dt) if agents else (NONE, NONE)
        F.step_school(fx, fz, vx, vz, ax, az, cx, cz, params, seed, step, dt, ox, oz, ovx, ovz)
        if check_speed:
            swim = np.hypot((ox - fx) / dt - cx, (oz - fz) / dt - cz)
            assert swim.max() <= VMAX * (1 + 1e-12)
            assert np.hypot(ovx, ovz).max() <= VMAX * (1 + 1e-12)
        fx, ox = ox, fx
        fz, oz = oz, fz
        vx, ovx = ovx, vx
        vz, ovz = ovz, vz
    return fx, fz, vx, vz


@pytest.mark.parametrize("n", [50, 200])
def test_school_stays_cohesive_and_still_without_vehicles_or_current(n):
    fx0, fz0, _, _ = F.init_school(n, (0.0, 0.0), 8.0, 1)
    fx, fz, vx, vz = _run(n=n, steps=300)
    assert np.isfinite(fx).all() and np.isfinite(vx).all()
    cx, cz = F.school_centroid(fx, fz)
    assert np.hypot(cx, cz) < 3.0  # started at the origin; 300 s of jitter only
    spread = F.school_spread(fx, fz)
    assert spread < 1.2 * F.school_spread(fx0, fz0)  # bounded
    assert F.fraction_inside_circle(fx, fz, cx, cz, 15.0) == 1.0  # no stragglers
    # separation keeps a school, not a point
    d = np.hypot(fx[:, None] - fx[None, :], fz[:, None] - fz[None, :])
    np.fill_diagonal(d, np.inf)
    assert d.min(axis=1).mean() > 0.3


def test_uniform_current_drifts_the_centroid_at_the_current_velocity():
    cur = (0.3, -0.2)
    n, steps = 50, 200
    uniform = lambda fx, fz: (np.full(fx.shape, cur[0]), np.full(fx.shape, cur[1]))  # noqa: E731
    fx, fz, _, _ = _run(n=n, steps=steps, current=uniform)
    cx, cz = F.school_centroid(fx, fz)
    assert cx == pytest.approx(cur[0] * steps, abs=3.0)  # 60 m of drift, 3 m of jitter walk
    assert cz == pytest.approx(cur[1] * steps, abs=3.0)
    # Galilean invariance: a uniform current only translates the school (checked over 20
    # steps: the many-body dynamics is chaotic, so round-off differences grow after that)
    short = 20
    fx, fz, vx, vz = _run(n=n, steps=short, current=uniform)
    fx_still, fz_still, vx_still, vz_still = _run(n=n, steps=short)
    np.testing.assert_allclose(fx - cur[0] * short, fx_still, atol=1e-9)
    np.testing.assert_allclose(fz - cur[1] * short, fz_still, atol=1e-9)
    np.testing.assert_allclose(vx, vx_still, atol=1e-9)


@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.0, -1.0), (-0.6, 0.8)])
def test_approaching_vehicle_pushes_the_school_away(direction):
    ux, uz = direction
    start = 30.0

    def vehicle(t):  # comes from -direction at 1.5 m/s and holds 2 m short of the centre
        s = min(-start + 1.5 * t, -2.0)  # (a graded avoidance, w_flee 0.5 m s-2, lets a
        return np.array([s * ux]), np.array([s * uz])  # vehicle driving through split it)

    fx, fz, _, _ = _run(steps=40, agents=vehicle)
    cx, cz = F.school_centroid(fx, fz)
    fx_c, fz_c, _, _ = _run(steps=40)
    bx, bz = F.school_centroid(fx_c, fz_c)
    along = (cx - bx) * ux + (cz - bz) * uz
    across = -(cx - bx) * uz + (cz - bz) * ux
    assert along > 8.0
    assert abs(across) < 0.5 * along


def test_flee_strength_decays_with_distance_and_vanishes_beyond_radius():
    p = F.fish_params({"jitter": 0.0, "damping": 0.0, "w_cohesion_global": 0.0})
    r_flee = p[F.FISH_PARAM_NAMES.index("flee_radius")]
    speeds = []
    for d in (1.0, 5.0, 10.0, 14.0, r_flee + 0.5):
        fx, fz = np.array([0.0]), np.array([0.0])
        out = [np.empty(1) for _ in range(4)]
        F.step_school(fx, fz, np.zeros(1), np.zeros(1), np.array([-d]), np.array([0.0]),
                      np.zeros(1), np.zeros(1), p, 0, 0, 0.1, *out)
        assert out[3][0] == 0.0 and out[2][0] >= 0.0  # straight away from the vehicle
        speeds.append(out[2][0])
    assert all(a > b for a, b in zip(speeds[:-1], speeds[1:]))
    assert speeds[-1] == 0.0


def test_fish_never_exceed_max_speed_plus_current():
    def shear(fx, fz):
        return 0.5 * np.tanh(fz / 10.0), 0.3 * np.sin(fx / 7.0)

    def chasers(t):
        a = 0.3 * t
        return (np.array([20 * np.cos(a), -5.0, 3.0]), np.array([20 * np.sin(a), 2.0, -4.0]))

    fast = F.fish_params({"w_flee": 20.0, "max_accel": 50.0, "jitter": 2.0})
    _run(n=80, steps=100, current=shear, agents=chasers, params=fast, check_speed=True)


def test_deterministic_in_seed():
    a = _run(n=60, steps=50, seed=7)
    b = _run(n=60, steps=50, seed=7)
    c = _run(n=60, steps=50, seed=8)
    assert all(x.tobytes() == y.tobytes() for x, y in zip(a, b))
    # same initial school, different jitter stream
    fx0, fz0, vx0, vz0 = F.init_school(60, (0.0, 0.0), 8.0, 7)
    outs = [np.empty(60) for _ in range(4)]
    outs2 = [np.empty(60) for _ in range(4)]
    F.step_school(fx0, fz0, vx0, vz0, NONE, NONE, vx0, vz0, PARAMS, 7, 0, 1.0, *outs)
    F.step_school(fx0, fz0, vx0, vz0, NONE, NONE, vx0, vz0, PARAMS, 8, 0, 1.0, *outs2)
    assert outs[0].tobytes() != outs2[0].tobytes()
    assert a[0].tobytes() != c[0].tobytes()


def test_counter_uniform_matches_reference_splitmix64():
    mask = (1 << 64) - 1

    def sm(x):
        z = (x + 0x9E3779B97F4A7C15) & mask
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
        return z ^ (z >> 31)

    def ref(seed, step, idx):
        z = sm(seed & mask)
        z = sm(z ^ (step & mask))
        z = sm(z ^ (idx & mask))
        return (z >> 11) * 2.0 ** -53

    for triple in [(0, 0, 0), (1, 2, 3), (-1, 5, 7), (2 ** 62, 3, 9), (12345, 10 ** 6, 399)]:
        assert F.counter_uniform(*triple) == ref(*triple)
    u = np.array([F.counter_uniform(3, s, i) for s in range(50) for i in range(100)])
    assert 0.0 <= u.min() and u.max() < 1.0
    assert u.mean() == pytest.approx(0.5, abs=0.02)
    assert u.var() == pytest.approx(1 / 12, rel=0.05)


def test_summaries():
    fx = np.array([0.0, 2.0, 4.0, 10.0])
    fz = np.array([0.0, 0.0, 0.0, 4.0])
    assert F.school_centroid(fx, fz) == (4.0, 1.0)
    assert F.school_spread(fx, fz) == pytest.approx(np.sqrt((17 + 5 + 1 + 45) / 4))
    assert F.fraction_inside_circle(fx, fz, 0.0, 0.0, 2.0) == 0.5
    assert F.fraction_inside_circle(fx, fz, 10.0, 4.0, 0.1) == 0.25
    assert F.fraction_inside_circle(NONE, NONE, 0.0, 0.0, 1.0) == 0.0


def test_params_and_init():
    p = F.fish_params({"max_speed": 2.5})
    assert p.shape == (F.N_FISH_PARAMS,)
    assert p[0] == 2.5
    assert p[F.FISH_PARAM_NAMES.index("flee_radius")] == F.FISH_PARAM_DEFAULTS["flee_radius"]
    with pytest.raises(ConfigError, match="Valid options"):
        F.fish_params({"speed": 1.0})
    with pytest.raises(ConfigError, match="jitter"):
        F.fish_params({"jitter": -1.0})
    fx, fz, vx, vz = F.init_school(100, (5.0, -3.0), 4.0, [1, 2, 3])
    assert np.hypot(fx - 5.0, fz + 3.0).max() <= 4.0 and not vx.any() and not vz.any()
    fx2, _, _, _ = F.init_school(100, (5.0, -3.0), 4.0, [1, 2, 3])
    assert fx.tobytes() == fx2.tobytes()
    with pytest.raises(ValueError, match="alias"):
        F.step_school(fx, fz, vx, vz, NONE, NONE, vx, vz, p, 0, 0, 1.0,
                      np.empty(100), np.empty(100), vx, np.empty(100))
    with pytest.raises(ValueError, match="inconsistent"):
        F.step_school(fx, fz, vx, vz, NONE, NONE, vx, vz[:5], p, 0, 0, 1.0,
                      *(np.empty(100) for _ in range(4)))


def _one_step(fx, fz, vx, vz, p, ax=NONE, az=NONE, dt=0.5):
    n = len(fx)
    out = [np.empty(n) for _ in range(4)]
    F.step_school(np.array(fx, float), np.array(fz, float), np.array(vx, float),
                  np.array(vz, float), ax, az, np.zeros(n), np.zeros(n), p, 0, 0, dt, *out)
    return out


ISOLATED = {name: 0.0 for name in ("w_cohesion", "w_cohesion_global", "w_separation",
                                   "w_alignment", "damping", "w_flee", "jitter")}


def test_each_rule_in_isolation():
    dt = 0.5
    # alignment: exact relaxation toward the neighbours' mean swim velocity
    p = F.fish_params({**ISOLATED, "w_alignment": 0.4})
    _, _, vx, vz = _one_step([0.0, 3.0], [0.0, 0.0], [0.0, 0.8], [0.0, 0.0], p, dt=dt)
    assert vx[0] == pytest.approx((1 - np.exp(-0.4 * dt)) * 0.8, rel=1e-12)
    assert vx[1] == pytest.approx(0.8 * np.exp(-0.4 * dt), rel=1e-12) and vz[0] == 0.0
    # local cohesion: toward the neighbours' centroid (inside perception, outside separation)
    p = F.fish_params({**ISOLATED, "w_cohesion": 0.05})
    _, _, vx, _ = _one_step([0.0, 4.0, 40.0], [0.0, 0.0, 0.0], [0.0] * 3, [0.0] * 3, p, dt=dt)
    assert vx[0] == pytest.approx(0.05 * 4.0 * dt, rel=1e-12)
    assert vx[2] == 0.0  # no neighbour within the perception radius
    # global cohesion: toward the whole school's centroid
    p = F.fish_params({**ISOLATED, "w_cohesion_global": 0.01})
    _, _, vx, _ = _one_step([0.0, 4.0, 40.0], [0.0, 0.0, 0.0], [0.0] * 3, [0.0] * 3, p, dt=dt)
    assert vx[2] == pytest.approx(0.01 * (44.0 / 3 - 40.0) * dt, rel=1e-12)
    # separation: linear in overlap, equal and opposite
    p = F.fish_params({**ISOLATED, "w_separation": 1.0})
    _, _, vx, _ = _one_step([0.0, 1.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], p, dt=dt)
    assert vx[0] == pytest.approx(-1.0 * (1 - 1.0 / 1.5) * dt, rel=1e-12) and vx[1] == -vx[0]
    # damping
    p = F.fish_params({**ISOLATED, "damping": 0.3})
    _, _, vx, _ = _one_step([0.0], [0.0], [0.5], [0.0], p, dt=dt)
    assert vx[0] == pytest.approx(0.5 * np.exp(-0.3 * dt), rel=1e-12)
    # the acceleration norm is capped
    p = F.fish_params({**ISOLATED, "w_flee": 100.0, "max_accel": 3.0})
    _, _, vx, vz = _one_step([0.0], [0.0], [0.0], [0.0], p, np.array([-0.1]), np.array([0.0]),
                             dt=0.1)
    assert vx[0] == pytest.approx(0.3, rel=1e-12) and vz[0] == 0.0


@numba.njit(cache=True)
def _jitted_rollout(fx, fz, vx, vz, p, seed, n_steps):
    """A task-style loop: double-buffered school, a vehicle sweeping in from the west."""
    n = fx.shape[0]
    ox, oz, ovx, ovz = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    cx = np.full(n, 0.1)
    cz = np.zeros(n)
    ax = np.array([-20.0])
    az = np.array([0.0])
    for k in range(n_steps):
        F.step_school(fx, fz, vx, vz, ax, az, cx, cz, p, seed, k, 1.0, ox, oz, ovx, ovz)
        fx, ox = ox, fx
        fz, oz = oz, fz
        vx, ovx = ovx, vx
        vz, ovz = ovz, vz
        ax[0] += 1.0
    return F.school_centroid(fx, fz)


def test_kernel_composes_inside_a_jitted_rollout_loop():
    fx, fz, vx, vz = F.init_school(50, (0.0, 0.0), 8.0, 3)
    cx, cz = _jitted_rollout(fx, fz, vx, vz, PARAMS, 3, 30)
    assert cx > 3.0 + 5.0  # 3 m of current drift plus the push of the vehicle


def _reference_step(fx, fz, vx, vz, ax_a, az_a, cx, cz, p, dt):
    """The school step written one fish at a time in plain Python floats (no jitter: the
    model's arithmetic without libm), in the order of the module docstring."""
    n = len(fx)
    vmax, r_per, r_sep, w_coh, w_cohg, w_sep, w_ali, damp, r_flee, w_flee, _, amax = \
        (float(v) for v in p)
    gcx, gcz = F.school_centroid(np.asarray(fx), np.asarray(fz))
    f_ali = 1.0 - math.exp(-w_ali * dt)
    f_damp = math.exp(-damp * dt)
    out = [[0.0] * n for _ in range(4)]
    for i in range(n):
        cnt = sx = sz = svx = svz = ax = az = 0.0
        for k in range(n):
            dx = fx[i] - fx[k]
            dz = fz[i] - fz[k]
            d2 = dx * dx + dz * dz
            w = 1.0 if d2 < r_per * r_per else 0.0
            cnt += w
            sx += w * fx[k]
            sz += w * fz[k]
            svx += w * vx[k]
            svz += w * vz[k]
            if r_sep * r_sep > d2 > 0.0:
                d = math.sqrt(d2)
                g = w_sep * (1.0 - d / r_sep) / d
                ax += g * dx
                az += g * dz
        m = int(cnt - 1.0 + 0.5)
        sx -= fx[i]
        sz -= fz[i]
        svx -= vx[i]
        svz -= vz[i]
        ux, uz = vx[i], vz[i]
        if m > 0:
            ux += f_ali * (svx * (1.0 / m) - ux)
            uz += f_ali * (svz * (1.0 / m) - uz)
            ax += w_coh * (sx * (1.0 / m) - fx[i])
            az += w_coh * (sz * (1.0 / m) - fz[i])
        ux *= f_damp
        uz *= f_damp
        ax += w_cohg * (gcx - fx[i])
        az += w_cohg * (gcz - fz[i])
        for a in range(len(ax_a)):
            dx = fx[i] - ax_a[a]
            dz = fz[i] - az_a[a]
            d2 = dx * dx + dz * dz
            if d2 < r_flee * r_flee:
                d = math.sqrt(d2)
                g = w_flee * (1.0 - d / r_flee) / d
                ax += g * dx
                az += g * dz
        an = math.sqrt(ax * ax + az * az)
        if an > amax:
            ax *= amax / an
            az *= amax / an
        ux += ax * dt
        uz += az * dt
        sp = math.sqrt(ux * ux + uz * uz)
        if sp > vmax:
            ux *= vmax / sp
            uz *= vmax / sp
        c_x = cx[i] if math.isfinite(cx[i]) else 0.0
        c_z = cz[i] if math.isfinite(cz[i]) else 0.0
        out[0][i] = fx[i] + (ux + c_x) * dt
        out[1][i] = fz[i] + (uz + c_z) * dt
        out[2][i] = ux
        out[3][i] = uz
    return np.array(out)


@pytest.mark.parametrize("n", [1, 3, 17, 40])
def test_the_step_is_the_models_arithmetic_to_the_bit(n):
    """Each fish's neighbour sums run over the school in index order, whatever the loop
    order of the compiled step (and with or without a caller's scratch)."""
    rng = np.random.default_rng(n)
    p = F.fish_params({"jitter": 0.0, "separation_radius": 3.0, "w_separation": 2.0})
    for trial in range(5):
        fx, fz = rng.normal(0.0, 4.0, n), rng.normal(0.0, 4.0, n)
        if n > 2:
            fx[2], fz[2] = fx[1], fz[1]                      # two fish at one place
        vx, vz = rng.normal(0.0, 0.3, n), rng.normal(0.0, 0.3, n)
        ax, az = rng.normal(0.0, 12.0, 3), rng.normal(0.0, 12.0, 3)
        ax[1] = np.nan                                     # an agent without a position
        cx, cz = rng.normal(0.0, 0.2, n), rng.normal(0.0, 0.2, n)
        cx[0] = np.nan                                     # no current at the first fish
        want = _reference_step(fx, fz, vx, vz, ax, az, cx, cz, p, 0.5)
        for work in (None, np.full((7, n + 2), np.nan)):
            got = [np.empty(n) for _ in range(4)]
            if work is None:
                F.step_school(fx, fz, vx, vz, ax, az, cx, cz, p, 7, trial, 0.5, *got)
            else:
                F.step_school_into(fx, fz, vx, vz, ax, az, cx, cz, p, 7, trial, 0.5, *got, work)
            assert np.array(got).tobytes() == want.tobytes()
    with pytest.raises(ValueError, match="work"):
        F.step_school_into(fx, fz, vx, vz, ax, az, cx, cz, p, 7, 0, 0.5, *got, np.zeros((6, n)))
