"""Vehicle dynamics of the core backend: kinematic, 3-DoF, 4-DoF and 6-DoF models.

Model ids follow :data:`oneocean.vocab.DYNAMICS`: ``0 kinematic, 1 3dof, 2 4dof, 3 6dof``.

Frames and yaw convention
-------------------------
World frame (task contract): x east, y depth (positive down), z north, metres. It is the
Fossen NED frame with axes relabelled: ``(north, east, down) = (z, x, y)``. Attitude uses
Fossen's zyx Euler angles (roll phi, pitch theta, yaw psi) and the body frame x forward,
y starboard, z down. **Yaw psi is the compass heading: measured from north (+z) clockwise
toward east (+x)**; a vehicle with heading psi points along world ``(sin psi, 0, cos psi)``
and ``dpsi/dt = r`` when level.

State vector (one row per agent, :data:`STATE_DIM` float64)
-----------------------------------------------------------
``[x, y, z, phi, theta, psi, u, v, w, p, q, r, vx, vy, vz, psi_ref]``: position (m, world),
attitude (rad), body-frame velocity over ground (m s-1) and angular rate (rad s-1), world-frame
ground velocity of the last step (m s-1, all models), heading reference of the yaw loop (rad).
The kinematic model uses only position and the world velocity slots.

Command vector (:data:`CMD_DIM` float64)
----------------------------------------
``[ax, ay, az, psi_cmd, thrust]``: desired velocity **relative to the water** in world
coordinates (m s-1, already clipped to the speed limit), commanded heading (rad; NaN = face the
direction of the commanded horizontal velocity when it exceeds ``heading_min_speed_ms``, else
hold), thrust switch (1 = controller on, 0 = unactuated drift).

Rigid-body models
-----------------
``M nu_r' + C(nu_r) nu_r + D(nu_r) nu_r + g(eta) = tau`` with ``nu_r = nu - nu_c`` (Fossen's
relative-velocity form for an irrotational current, frozen over one step), diagonal
``M = M_RB + M_A``, the Kirchhoff-form ``C`` of that ``M`` (skew-symmetric), linear + quadratic
damping ``D``, restoring ``g`` (net buoyancy and BG roll/pitch moments). The low-level
controller (model feed-forward + P on velocity) produces, per actuated DOF,
``tau_i = D_i(|nu_r,i|) c_i + [C(nu_r) nu_r]_i + g_i + K_i (c_i - nu_r,i)`` with ``K_i = M_i / T_i``,
clipped to ``thrust_max``; ``c`` is the body-frame image of the commanded relative velocity
plus the rate commands of the heading loop (yaw) and of the levelling loops (roll, pitch).
3-DoF = surge/sway/yaw at constant depth; 4-DoF adds heave; 6-DoF adds roll and pitch
(passively stable through BG, levelled when thrust is on).

Integration: a step ``dt`` is split into ``ceil(dt / max_substep_s)`` substeps ``h``
(``max_substep_s <= 0.5``); each is linearly implicit in damping (lagged coefficient), controller
gain, Coriolis (``C(nu_r,k) nu_r,k+1``) and the roll/pitch restoring stiffness, then ``eta`` is
advanced with the new velocity (symplectic Euler). With skew ``C`` and non-negative damping the
mechanical energy relative to the water (kinetic + restoring potential) never increases when
thrust is off, for any ``h`` (tested). Thrust saturation is handled by an active set: saturated
DOFs get the clipped thrust explicitly and the system is solved again, so thrust always stays
within its limits. The current is sampled once per step and frozen over its substeps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Mapping

import numpy as np
import yaml

from ..errors import ConfigError
from ..vocab import DYNAMICS, validate_choice
from ._jit import hot_kernel

# ----------------------------------------------------------------------------- layouts

KINEMATIC, DOF3, DOF4, DOF6 = 0, 1, 2, 3
MODEL_IDS = {name: i for i, name in enumerate(DYNAMICS)}

X, Y, Z, PHI, THETA, PSI, U, V, W, P, Q, R, VX, VY, VZ, PSI_REF = range(16)
STATE_DIM = 16
STATE_NAMES = ("x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r",
               "vx", "vy", "vz", "psi_ref")

C_AX, C_AY, C_AZ, C_PSI, C_THRUST = range(5)
CMD_DIM = 5

# vehicle parameter vector
P_VMAX = 0     # speed limit, m s-1
P_HMAX = 1     # largest substep, s
P_M = 2        # 6 total masses (M_RB + M_A diagonal): kg | kg m2
P_DL = 8       # 6 linear damping
P_DQ = 14      # 6 quadratic damping
P_TMAX = 20    # 6 thrust limits (0 = unactuated)
P_K = 26       # 6 velocity-loop gains K_i = M_i / T_i (N s m-1 | N m s rad-1)
P_WB = 32      # W - B, N (positive: heavier than water)
P_BGB = 33     # BG * B, N m (roll/pitch restoring coefficient)
P_KPSI = 34    # heading gain, s-1
P_RMAX = 35    # yaw-rate command limit, rad s-1
P_VYAW = 36    # heading update threshold, m s-1
P_KATT = 37    # roll/pitch levelling gain, s-1
PARAM_DIM = 38

#: Upper bound on the integration substep, s (see data/vehicles.yaml).
MAX_SUBSTEP_S = 0.5

_VEHICLE_KEYS = {
    "description": str, "mass_kg": float, "inertia_kg_m2": 3, "added_mass": 6,
    "linear_damping": 6, "quadratic_damping": 6, "thrust_max": 6, "speed_limit_ms": float,
    "net_buoyancy_n": float, "metacentric_height_m": float, "gravity_ms2": float,
    "velocity_time_constant_s": 6, "heading_gain_per_s": float, "yaw_rate_max_rad_s": float,
    "heading_min_speed_ms": float, "max_substep_s": float, "attitude_gain_per_s": float,
}


def model_id(name: str) -> int:
    """Integer id of a dynamics model name (``ConfigError`` naming the options if unknown)."""
    return MODEL_IDS[validate_choice(name, DYNAMICS, "dynamics")]


@dataclass(frozen=True)
class Vehicle:
    """A vehicle's parameters: the documented spec (for manifests) and the kernel vector."""

    name: str
    spec: dict
    params: np.ndarray = field(repr=False)

    @property
    def v_max(self) -> float:
        """Speed limit, m s-1."""
        return float(self.params[P_VMAX])

    def substeps(self, dt: float) -> int:
        """Number of integration substeps the rigid-body models use for a step ``dt`` (s)."""
        return _nsub(self.params, float(dt))


def _vehicles_file() -> Path:
    return Path(str(resources.files("oneocean") / "data" / "vehicles.yaml"))


def vehicle_params(spec: Mapping, name: str = "vehicle") -> np.ndarray:
    """Validate a vehicle spec (see ``data/vehicles.yaml``) and build its parameter vector."""
    missing = [k for k in _VEHICLE_KEYS if k not in spec]
    unknown = [k for k in spec if k not in _VEHICLE_KEYS]
    if missing:
        raise ConfigError(f"vehicle '{name}': missing keys: {', '.join(missing)}")
    if unknown:
        raise ConfigError(f"vehicle '{name}': unknown keys: {', '.join(unknown)}")
    vals = {}
    for k, kind in _VEHICLE_KEYS.items():
        if kind is str:
            continue
        try:
            a = np.asarray(spec[k], dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"vehicle '{name}': '{k}' must be numeric, got {spec[k]!r}") from exc
        want = () if kind is float else (kind,)
        if a.shape != want or not np.all(np.isfinite(a)):
            what = "a number" if not want else f"a list of {kind} numbers"
            raise ConfigError(f"vehicle '{name}': '{k}' must be {what} (finite), got {spec[k]!r}")
        vals[k] = a
    for k in ("inertia_kg_m2", "added_mass", "linear_damping", "quadratic_damping",
              "thrust_max", "velocity_time_constant_s"):
        if np.any(vals[k] < 0):
            raise ConfigError(f"vehicle '{name}': '{k}' must be >= 0, got {spec[k]!r}")
    for k in ("mass_kg", "speed_limit_ms", "gravity_ms2", "max_substep_s"):
        if not vals[k] > 0:
            raise ConfigError(f"vehicle '{name}': '{k}' must be > 0, got {spec[k]!r}")
    if vals["max_substep_s"] > MAX_SUBSTEP_S:
        raise ConfigError(f"vehicle '{name}': 'max_substep_s' must be <= {MAX_SUBSTEP_S} s "
                          f"(heading-loop accuracy), got {spec['max_substep_s']!r}")
    if vals["metacentric_height_m"] < 0:
        raise ConfigError(f"vehicle '{name}': 'metacentric_height_m' must be >= 0")
    tc = vals["velocity_time_constant_s"]
    tmax = vals["thrust_max"]
    act = tmax > 0
    if np.any(act & ~(tc > 0)):
        raise ConfigError(f"vehicle '{name}': 'velocity_time_constant_s' must be > 0 for every "
                          "actuated DOF (thrust_max > 0), got "
                          f"{spec['velocity_time_constant_s']!r}")
    m = float(vals["mass_kg"])
    mass = np.concatenate([[m, m, m], vals["inertia_kg_m2"]]) + vals["added_mass"]
    if np.any(mass <= 0):
        raise ConfigError(f"vehicle '{name}': total mass/inertia must be > 0 in every DOF")
    p = np.zeros(PARAM_DIM)
    p[P_VMAX] = vals["speed_limit_ms"]
    p[P_HMAX] = vals["max_substep_s"]
    p[P_M:P_M + 6] = mass
    p[P_DL:P_DL + 6] = vals["linear_damping"]
    p[P_DQ:P_DQ + 6] = vals["quadratic_damping"]
    p[P_TMAX:P_TMAX + 6] = tmax
    p[P_K:P_K + 6] = np.where(act, mass / np.where(tc > 0, tc, 1.0), 0.0)
    weight = m * vals["gravity_ms2"]
    buoy = weight + vals["net_buoyancy_n"]
    p[P_WB] = -vals["net_buoyancy_n"]
    p[P_BGB] = vals["metacentric_height_m"] * buoy
    p[P_KPSI] = vals["heading_gain_per_s"]
    p[P_RMAX] = vals["yaw_rate_max_rad_s"]
    p[P_VYAW] = vals["heading_min_speed_ms"]
    p[P_KATT] = vals["attitude_gain_per_s"]
    return p


def load_vehicle(name: str | None = None, overrides: Mapping | None = None,
                 path: str | Path | None = None) -> Vehicle:
    """Load a vehicle from ``data/vehicles.yaml`` (or ``path``), optionally overriding keys.

    Parameters
    ----------
    name : str, optional
        Vehicle name; default: the file's ``default``.
    overrides : mapping, optional
        Keys replacing the file's values (same units), e.g. ``{"speed_limit_ms": 1.5}``.
    path : path-like, optional
        Alternative YAML file with the same layout.
    """
    f = Path(path) if path is not None else _vehicles_file()
    try:
        doc = yaml.safe_load(f.read_text())
    except OSError as exc:
        raise ConfigError(f"{f}: cannot read vehicle file ({exc})") from exc
    if not isinstance(doc, dict) or "vehicles" not in doc:
        raise ConfigError(f"{f}: expected a mapping with key 'vehicles'")
    name = name if name is not None else doc.get("default")
    name = validate_choice(name, tuple(doc["vehicles"]), "vehicle")
    spec = dict(doc["vehicles"][name])
    if overrides:
        unknown = [k for k in overrides if k not in _VEHICLE_KEYS]
        if unknown:
            raise ConfigError(f"vehicle '{name}': unknown override keys: {', '.join(unknown)}")
        spec.update({k: (list(v) if isinstance(v, (list, tuple, np.ndarray)) else v)
                     for k, v in overrides.items()})
    return Vehicle(name=name, spec=spec, params=vehicle_params(spec, name))


# ----------------------------------------------------------------------------- kernels


@hot_kernel(inline="always")
def clip_action(ax, ay, az, v_max):
    """Clip the vector (ax, ay, az) m s-1 to Euclidean norm ``v_max`` (direction kept)."""
    n2 = ax * ax + ay * ay + az * az
    if n2 > v_max * v_max:
        s = v_max / math.sqrt(n2)
        return ax * s, ay * s, az * s
    return ax, ay, az


@hot_kernel
def wrap_angle(a):
    """Wrap an angle (rad) to [-pi, pi)."""
    return a - _TWO_PI * math.floor((a + math.pi) * _INV_TWO_PI)


_TWO_PI = 2.0 * math.pi
_INV_TWO_PI = 1.0 / _TWO_PI
_TWO_OVER_PI = 2.0 / math.pi
_PIO2_HI = 1.57079632673412561417e+00  # fdlibm pio2_1: first 33 bits of pi/2
_PIO2_LO = 6.07710050650619224932e-11  # pi/2 - _PIO2_HI
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@hot_kernel
def sincos(x):
    """(sin x, cos x) with fdlibm's kernel polynomials after a Cody-Waite quadrant reduction.

    About 3x faster than two libm calls in this kernel; accurate to ~1 ulp for |x| <= 1e5 (the
    engine's angles are wrapped to [-pi, pi)); larger arguments fall back to libm.
    """
    if not abs(x) <= 1e5:
        return math.sin(x), math.cos(x)
    k = math.floor(x * _TWO_OVER_PI + 0.5)
    r = (x - k * _PIO2_HI) - k * _PIO2_LO
    z = r * r
    sr = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    hz = 0.5 * z
    w = 1.0 - hz
    pc = _C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6))))
    cr = w + (((1.0 - w) - hz) + z * z * pc)
    q = int(k) & 3
    if q == 0:
        return sr, cr
    if q == 1:
        return cr, -sr
    if q == 2:
        return -sr, -cr
    return -cr, sr


@hot_kernel
def _nsub(vp, dt):
    n = int(math.ceil(dt / vp[P_HMAX] - 1e-9))
    return n if n > 1 else 1


# Explicit signatures: the DOF index is passed as a literal constant, which would otherwise make
# numba compile one specialisation per value. (LLVM inlines these small functions.)
@hot_kernel("UniTuple(float64, 2)(int64, boolean, float64[::1], float64, float64, float64, "
            "float64, float64, int64, float64)")
def _dof_terms(i, thrust_on, vp, h, nur, c, g, fc, sat, ts):
    """Diagonal ``d`` and rhs ``b`` of DOF ``i`` for one substep ``h``.

    Damping (lagged quadratic coefficient) is implicit; an actuated DOF adds the controller
    ``tau = ff + K (c - x)`` implicitly, or the saturated thrust ``ts`` explicitly when bit
    ``i`` of ``sat`` is set. ``ff = D(|nu_r|) c + g + fc`` is the model feed-forward (the
    damping coefficient at the current relative speed, so that with vanishing inertia the DOF
    reaches ``c`` within one substep; at steady state it equals ``D(c) c``).
    """
    m = vp[P_M + i]
    dk = vp[P_DL + i] + vp[P_DQ + i] * abs(nur)  # damping coefficient, lagged
    d = m + h * dk
    b = m * nur - h * g
    if thrust_on and vp[P_TMAX + i] > 0.0:
        if (sat >> i) & 1:
            b += h * ts
        else:
            k = vp[P_K + i]
            d += h * k
            b += h * (dk * c + g + fc + k * c)
    return d, b


@hot_kernel("Tuple((int64, float64))(int64, boolean, float64[::1], float64, float64, float64, "
            "float64, float64, int64, float64)")
def _check_thrust(i, thrust_on, vp, nur, c, g, fc, x, sat, ts):
    """Thrust of DOF ``i`` implied by solution ``x``; returns (sat, ts), saturating if over."""
    tmax = vp[P_TMAX + i]
    if not thrust_on or tmax <= 0.0 or (sat >> i) & 1:
        return sat, ts
    tau = (vp[P_DL + i] + vp[P_DQ + i] * abs(nur)) * c + g + fc + vp[P_K + i] * (c - x)
    if tau > tmax:
        return sat | (1 << i), tmax
    if tau < -tmax:
        return sat | (1 << i), -tmax
    return sat, ts


@hot_kernel
def _solve3(d0, d1, d5, b0, b1, b5, al, be):
    """Solve [[d0,0,al],[0,d1,be],[-al,-be,d5]] x = b (surge, sway, yaw block)."""
    i0 = 1.0 / d0
    i1 = 1.0 / d1
    x5 = (b5 + al * b0 * i0 + be * b1 * i1) / (d5 + al * al * i0 + be * be * i1)
    return (b0 - al * x5) * i0, (b1 - be * x5) * i1, x5


@hot_kernel
def _solve6(h, d0, d1, d2, d3, d4, d5, b0, b1, b2, b3, b4, b5, a1, a2, a3, c1, c2, c3):
    """Solve (diag(d) + h C) x = b with C the Kirchhoff Coriolis matrix of momenta a, c.

    ``C = [[0, -S(a)], [-S(a), -S(c)]]`` (skew). Schur complement on the diagonal linear
    block, then Cramer's rule on the 3 x 3 angular system.
    """
    i0 = 1.0 / d0
    i1 = 1.0 / d1
    i2 = 1.0 / d2
    hh = h * h
    # P = h * (-S(a)) = h [[0, a3, -a2], [-a3, 0, a1], [a2, -a1, 0]];  S = A22 + P D1^-1 P^T
    s00 = d3 + hh * (a3 * a3 * i1 + a2 * a2 * i2)
    s11 = d4 + hh * (a3 * a3 * i0 + a1 * a1 * i2)
    s22 = d5 + hh * (a2 * a2 * i0 + a1 * a1 * i1)
    q01 = -hh * a1 * a2 * i2
    q02 = -hh * a1 * a3 * i1
    q12 = -hh * a2 * a3 * i0
    s01 = q01 + h * c3
    s10 = q01 - h * c3
    s02 = q02 - h * c2
    s20 = q02 + h * c2
    s12 = q12 + h * c1
    s21 = q12 - h * c1
    r0 = b3 - h * (a3 * b1 * i1 - a2 * b2 * i2)
    r1 = b4 - h * (-a3 * b0 * i0 + a1 * b2 * i2)
    r2 = b5 - h * (a2 * b0 * i0 - a1 * b1 * i1)
    m00 = s11 * s22 - s12 * s21
    m01 = s02 * s21 - s01 * s22
    m02 = s01 * s12 - s02 * s11
    det = s00 * m00 + s10 * m01 + s20 * m02
    idet = 1.0 / det
    x3 = (r0 * m00 + r1 * m01 + r2 * m02) * idet
    x4 = (r0 * (s12 * s20 - s10 * s22) + r1 * (s00 * s22 - s02 * s20)
          + r2 * (s02 * s10 - s00 * s12)) * idet
    x5 = (r0 * (s10 * s21 - s11 * s20) + r1 * (s01 * s20 - s00 * s21)
          + r2 * (s00 * s11 - s01 * s10)) * idet
    x0 = (b0 - h * (a3 * x4 - a2 * x5)) * i0
    x1 = (b1 - h * (-a3 * x3 + a1 * x5)) * i1
    x2 = (b2 - h * (a2 * x3 - a1 * x4)) * i2
    return x0, x1, x2, x3, x4, x5


@hot_kernel(inline="always")
def _surface(s):
    """Keep the vehicle in the water: y >= 0, no upward velocity at the surface."""
    if s[Y] < 0.0:
        s[Y] = 0.0
        if s[VY] < 0.0:
            s[VY] = 0.0
        return True
    return False


@hot_kernel(inline="always")
def _step_kinematic(s, cmd, ce, cn, dt):
    if cmd[C_THRUST] != 0.0:
        ax = cmd[C_AX]
        ay = cmd[C_AY]
        az = cmd[C_AZ]
    else:
        ax = 0.0
        ay = 0.0
        az = 0.0
    vx = ax + ce
    vz = az + cn
    s[X] = s[X] + vx * dt
    s[Y] = s[Y] + ay * dt
    s[Z] = s[Z] + vz * dt
    s[VX] = vx
    s[VY] = ay
    s[VZ] = vz
    _surface(s)


@hot_kernel
def _step_rigid(model, vp, s, cmd, ce, cn, dt):
    nsub = _nsub(vp, dt)
    h = dt / nsub
    thrust_on = cmd[C_THRUST] != 0.0
    an = cmd[C_AZ]  # command in NED order (north, east, down)
    ae = cmd[C_AX]
    ad = cmd[C_AY]
    six = model == DOF6
    heave = model != DOF3
    if not heave:
        ad = 0.0
    # heading reference: explicit command, else direction of the commanded horizontal velocity
    psi_ref = s[PSI_REF]
    if cmd[C_PSI] == cmd[C_PSI]:  # not NaN
        psi_ref = cmd[C_PSI]
    elif thrust_on and an * an + ae * ae >= vp[P_VYAW] * vp[P_VYAW]:
        psi_ref = math.atan2(ae, an)
    s[PSI_REF] = psi_ref
    n = s[Z]
    e = s[X]
    dd = s[Y]
    psi = s[PSI]
    u = s[U]
    v = s[V]
    r = s[R]
    phi = 0.0
    th = 0.0
    p = 0.0
    q = 0.0
    w = 0.0
    if six:
        phi = s[PHI]
        th = s[THETA]
        p = s[P]
        q = s[Q]
    if heave:
        w = s[W]
    wb = vp[P_WB]
    bgb = vp[P_BGB]
    katt = vp[P_KATT]
    kpsi = vp[P_KPSI]
    rmax = vp[P_RMAX]
    m0 = vp[P_M]
    m1 = vp[P_M + 1]
    m2 = vp[P_M + 2]
    m3 = vp[P_M + 3]
    m4 = vp[P_M + 4]
    m5 = vp[P_M + 5]
    cph = 1.0
    sph = 0.0
    cth = 1.0
    sth = 0.0
    r00 = r01 = r02 = r10 = r11 = r12 = r20 = r21 = r22 = 0.0
    for _ in range(nsub):
        sps, cps = sincos(psi)
        if six:
            sph, cph = sincos(phi)
            sth, cth = sincos(th)
        # rotation body -> NED (Fossen zyx)
        r00 = cps * cth
        r01 = -sps * cph + cps * sth * sph
        r02 = sps * sph + cps * cph * sth
        r10 = sps * cth
        r11 = cps * cph + sph * sth * sps
        r12 = -cps * sph + sth * sps * cph
        r20 = -sth
        r21 = cth * sph
        r22 = cth * cph
        # current in body frame (NED current = (cn, ce, 0)) and relative velocity
        ncu = r00 * cn + r10 * ce
        ncv = r01 * cn + r11 * ce
        ncw = r02 * cn + r12 * ce
        ur = u - ncu
        vr = v - ncv
        wr = w - ncw
        # commanded relative velocity in body frame; rate commands of the attitude loops
        cu = r00 * an + r10 * ae + r20 * ad
        cv = r01 * an + r11 * ae + r21 * ad
        cw = r02 * an + r12 * ae + r22 * ad
        pc = min(max(-katt * phi, -rmax), rmax)
        qc = min(max(-katt * th, -rmax), rmax)
        rc = min(max(kpsi * wrap_angle(psi_ref - psi), -rmax), rmax)
        # momenta for the Coriolis term C(nu_r) nu_r (implicit: C(nu_r,k) nu_r,k+1)
        a1 = m0 * ur
        a2 = m1 * vr
        a3 = m2 * wr
        c1 = m3 * p
        c2 = m4 * q
        c3 = m5 * r
        # controller feed-forward of C(nu_r,k) nu_r,k (feedback linearisation: cancels the
        # Coriolis/Munk terms the vehicle actually feels, so the loops see decoupled DOFs)
        f0 = q * a3 - r * a2
        f1 = r * a1 - p * a3
        f2 = p * a2 - q * a1
        f3 = vr * a3 - wr * a2 + q * c3 - r * c2
        f4 = wr * a1 - ur * a3 + r * c1 - p * c3
        f5 = ur * a2 - vr * a1 + p * c2 - q * c1
        # restoring forces (body), Fossen g(eta) with r_g = 0, r_b = (0, 0, -BG)
        g0 = wb * sth
        g1 = -wb * cth * sph
        g2 = -wb * cth * cph
        g3 = bgb * cth * sph
        g4 = bgb * sth
        kst = h * h * bgb * cth * cph  # linearised roll/pitch restoring stiffness
        sat = 0
        ts0 = ts1 = ts2 = ts3 = ts4 = ts5 = 0.0
        x0 = x1 = x2 = x3 = x4 = x5 = 0.0
        for _pass in range(7):  # active set: each pass saturates >= 1 more DOF or stops
            d0, b0 = _dof_terms(0, thrust_on, vp, h, ur, cu, g0, f0, sat, ts0)
            d1, b1 = _dof_terms(1, thrust_on, vp, h, vr, cv, g1, f1, sat, ts1)
            d5, b5 = _dof_terms(5, thrust_on, vp, h, r, rc, 0.0, f5, sat, ts5)
            if six:
                d2, b2 = _dof_terms(2, thrust_on, vp, h, wr, cw, g2, f2, sat, ts2)
                d3, b3 = _dof_terms(3, thrust_on, vp, h, p, pc, g3, f3, sat, ts3)
                d4, b4 = _dof_terms(4, thrust_on, vp, h, q, qc, g4, f4, sat, ts4)
                if kst > 0.0:
                    d3 += kst
                    d4 += kst
                x0, x1, x2, x3, x4, x5 = _solve6(h, d0, d1, d2, d3, d4, d5, b0, b1, b2, b3,
                                                 b4, b5, a1, a2, a3, c1, c2, c3)
            else:
                x0, x1, x5 = _solve3(d0, d1, d5, b0, b1, b5, -h * a2, h * a1)
                if heave:
                    d2, b2 = _dof_terms(2, thrust_on, vp, h, wr, cw, g2, f2, sat, ts2)
                    x2 = b2 / d2
            if not thrust_on:
                break
            s0 = sat
            sat, ts0 = _check_thrust(0, thrust_on, vp, ur, cu, g0, f0, x0, sat, ts0)
            sat, ts1 = _check_thrust(1, thrust_on, vp, vr, cv, g1, f1, x1, sat, ts1)
            sat, ts5 = _check_thrust(5, thrust_on, vp, r, rc, 0.0, f5, x5, sat, ts5)
            if heave:
                sat, ts2 = _check_thrust(2, thrust_on, vp, wr, cw, g2, f2, x2, sat, ts2)
            if six:
                sat, ts3 = _check_thrust(3, thrust_on, vp, p, pc, g3, f3, x3, sat, ts3)
                sat, ts4 = _check_thrust(4, thrust_on, vp, q, qc, g4, f4, x4, sat, ts4)
            if sat == s0:
                break
        # back to velocity over ground, then advance the pose (symplectic Euler)
        u = x0 + ncu
        v = x1 + ncv
        if heave:
            w = x2 + ncw
        r = x5
        n += h * (r00 * u + r01 * v + r02 * w)
        e += h * (r10 * u + r11 * v + r12 * w)
        if six:
            p = x3
            q = x4
            dd += h * (r20 * u + r21 * v + r22 * w)
            tth = sth / cth
            phi += h * (p + sph * tth * q + cph * tth * r)
            th += h * (cph * q - sph * r)
            psi += h * (sph * q + cph * r) / cth
        else:
            if heave:
                dd += h * w
            psi += h * r
        psi = wrap_angle(psi)
    s[X] = e
    s[Y] = dd
    s[Z] = n
    s[PHI] = phi
    s[THETA] = th
    s[PSI] = psi
    s[U] = u
    s[V] = v
    s[W] = w
    s[P] = p
    s[Q] = q
    s[R] = r
    s[VX] = r10 * u + r11 * v + r12 * w
    s[VY] = r20 * u + r21 * v + r22 * w
    s[VZ] = r00 * u + r01 * v + r02 * w
    vd = s[VY]
    if _surface(s) and vd < 0.0:
        # remove the upward part of the body velocity (down axis in body = 3rd row of R)
        s[U] = u - vd * r20
        s[V] = v - vd * r21
        s[W] = w - vd * r22


@hot_kernel(inline="always")
def step_agent(model, vp, s, cmd, ce, cn, dt):
    """Advance one agent by one step ``dt`` (s), in place.

    Parameters
    ----------
    model : int
        Dynamics model id (``KINEMATIC``, ``DOF3``, ``DOF4``, ``DOF6``).
    vp : (PARAM_DIM,) float64
        Vehicle parameters (:func:`vehicle_params`); unused by the kinematic model.
    s : (STATE_DIM,) float64
        Agent state, modified in place.
    cmd : (CMD_DIM,) float64
        ``[ax, ay, az, psi_cmd, thrust]``; the velocity must already be clipped.
    ce, cn : float
        Current (east, north) at the agent, m s-1, frozen over the step.
    dt : float
        Step, s.

    Notes
    -----
    The kinematic update is exactly ``p += (a + c) dt``. All models keep the vehicle in the
    water (``y >= 0``, upward velocity removed at the surface); the constraint check against
    land / seafloor / grid extent is the caller's (:func:`oneocean.engine.constraints.check_move`).
    """
    if model == KINEMATIC:
        _step_kinematic(s, cmd, ce, cn, dt)
    else:
        _step_rigid(model, vp, s, cmd, ce, cn, dt)


@hot_kernel
def kinetic_energy_rel(model, vp, s, ce, cn):
    """Kinetic energy relative to the water, ``0.5 nu_r^T M nu_r`` (J), of a rigid-body state."""
    cps = math.cos(s[PSI])
    sps = math.sin(s[PSI])
    if model == DOF6:
        cph = math.cos(s[PHI])
        sph = math.sin(s[PHI])
        cth = math.cos(s[THETA])
        sth = math.sin(s[THETA])
    else:
        cph = 1.0
        sph = 0.0
        cth = 1.0
        sth = 0.0
    r00 = cps * cth
    r01 = -sps * cph + cps * sth * sph
    r02 = sps * sph + cps * cph * sth
    r10 = sps * cth
    r11 = cps * cph + sph * sth * sps
    r12 = -cps * sph + sth * sps * cph
    ur = s[U] - (r00 * cn + r10 * ce)
    vr = s[V] - (r01 * cn + r11 * ce)
    wr = s[W] - (r02 * cn + r12 * ce)
    return 0.5 * (vp[P_M] * ur * ur + vp[P_M + 1] * vr * vr + vp[P_M + 2] * wr * wr
                  + vp[P_M + 3] * s[P] * s[P] + vp[P_M + 4] * s[Q] * s[Q]
                  + vp[P_M + 5] * s[R] * s[R])


def potential_energy(vp: np.ndarray, s: np.ndarray) -> float:
    """Restoring potential energy (J): ``-(W - B) y + BG B (1 - cos(phi) cos(theta))``."""
    return float(-vp[P_WB] * s[Y] + vp[P_BGB] * (1.0 - np.cos(s[PHI]) * np.cos(s[THETA])))


def new_state(n_episodes: int, n_agents: int, positions=None, heading=0.0) -> np.ndarray:
    """A zero-velocity state array (episodes, agents, STATE_DIM) at ``positions`` (E, A, 3) m.

    ``heading`` (rad, compass convention) may be a scalar or an (E, A) array; it also sets the
    yaw loop's heading reference.
    """
    s = np.zeros((int(n_episodes), int(n_agents), STATE_DIM))
    if positions is not None:
        pos = np.asarray(positions, dtype=np.float64)
        if pos.shape != (n_episodes, n_agents, 3):
            raise ConfigError(f"positions: expected shape ({n_episodes}, {n_agents}, 3), "
                              f"got {pos.shape}")
        s[..., X:Z + 1] = pos
    s[..., PSI] = heading
    s[..., PSI_REF] = heading
    return s


def make_cmd(ax=0.0, ay=0.0, az=0.0, psi=np.nan, thrust=True) -> np.ndarray:
    """A command vector ``[ax, ay, az, psi_cmd, thrust]`` (see module docs)."""
    return np.array([ax, ay, az, psi, 1.0 if thrust else 0.0], dtype=np.float64)
