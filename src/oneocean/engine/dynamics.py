"""Vehicle dynamics of the core backend: kinematic, 3-DoF, 4-DoF and 6-DoF models.

Model ids follow :data:`oneocean.vocab.DYNAMICS`: ``0 kinematic, 1 3dof, 2 4dof, 3 6dof``.

Frames and yaw convention
-------------------------
World frame (task contract): x east, y depth (positive down), z north, metres. It is the
Fossen NED frame with axes relabelled: ``(north, east, down) = (z, x, y)``. Attitude uses
Fossen's zyx Euler angles (roll phi, pitch theta, yaw psi) and the body frame x forward,
y starboard, z down. **Yaw psi is the compass heading: measured from north (+z) clockwise
toward east (+x)**; a vehicle with heading psi points along world ``(sin psi, 0, cos psi)``
and ``dpsi/dt = r`` when level. Pitch theta > 0 is nose up.

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
``M = M_RB + M_A``, the Kirchhoff-form ``C`` of that ``M`` (skew-symmetric; it contains the
Munk moments ``(M_22 - M_11) u v`` etc.), damping ``D`` = diagonal linear + quadratic terms plus
the linear-in-speed lift terms of a finned hull (``Y_uv u v + Y_ur u r``, ``N_uv u v +
N_ur u r`` and their heave/pitch mirror images; the part symmetric in (v, r) is scaled by
``|u_r|`` and must be dissipative, the skew part by ``u_r``), restoring ``g`` (net buoyancy and
BG roll/pitch moments). 3-DoF = surge/sway/yaw at constant depth; 4-DoF adds heave; 6-DoF adds
roll and pitch (passively stable through BG).

Actuators and low-level controller
----------------------------------
Per actuated DOF the controller is model feed-forward + P on velocity,
``tau_i = D_i(|nu_r|) c_i + [C(nu_r) nu_r + lift couplings]_i + g_i + K_i (c_i - nu_r,i)``
with ``K_i = M_i / T_i`` (feedback linearisation: the loops see decoupled DOFs). A thruster
cancels its row's couplings at the new velocities (implicitly, inside the substep's solve, so
a small-inertia DOF such as the ROV's yaw is not kicked by the ``h C`` splitting of fast
sway/surge changes); a fin uses the couplings of the substep's start. The limits:

* thrusters: ``|tau_i| <= thrust_max_i`` (box), or, for a group of four vectored thrusters
  (``thrust_coupling``), the exact capacity set of four thrusters with a common per-thruster
  limit: with ``a_i = tau_i / thrust_max_i`` of the group's three DOFs,
  ``|a_1| + |a_2| <= 1, |a_1| + |a_3| <= 1, |a_2| + |a_3| <= 1``; a demand outside is scaled
  down along its direction;
* control fins (torpedo): rudder (yaw) and stern planes (pitch) whose moment is limited to
  ``|N_uudr| u_r^2 delta_max`` (``|M_uuds| u_r^2 delta_max``) -- no authority at rest -- and
  whose lift also pushes the hull sideways (``Y_uudr / N_uudr`` newton per newton metre).

The commanded body velocity ``c`` depends on the guidance law of the vehicle:

* ``holonomic`` (ROV, test vehicle): ``c`` = body-frame image of the commanded relative
  velocity, plus the heading-loop yaw-rate command and levelling roll/pitch-rate commands;
* ``torpedo`` (underactuated AUV, propeller + fins): surge speed = commanded relative speed
  (body-x projection when a heading is commanded), heading toward the commanded horizontal
  direction, pitch reference ``atan2(-a_down, |a_horizontal|)`` limited to ``pitch_max_deg``
  (it dives by pitching, only with forward speed; 3-DoF/4-DoF torpedoes cannot change depth);
  sway and heave are not actuated, so it cannot crab.

Integration: a step ``dt`` is split into ``ceil(dt / max_substep_s)`` substeps ``h``
(``max_substep_s <= 0.5``); each is linearly implicit in damping and lift (lagged coefficients),
controller gain, Coriolis (``C(nu_r,k) nu_r,k+1``) and the roll/pitch restoring stiffness, then
``eta`` is advanced with the new velocity (symplectic Euler; over ground ``R nu_r + v_c``). The
substeps carry ``nu_r`` itself, whose equation does not depend on a uniform current (Fossen
2011, Property 10.1; tested); the velocity over ground stored in the state is ``nu_r`` plus the
current in the final body frame. With skew ``C`` and dissipative
damping the mechanical energy relative to the water (kinetic + restoring potential) never
increases when thrust is off, for any ``h`` (tested). Actuator limits are handled by an active
set: saturated DOFs (or thruster groups) get their limited force explicitly and the system is
solved again, so actuator forces always stay within their limits (tested with
:func:`step_agent_traced`). The current is sampled once per step and frozen over its substeps.

Unsteady current (the water's acceleration)
-------------------------------------------
Between steps the sampled current jumps and the state carries the velocity over ground, so a
jump ``dv_c`` changes ``nu_r`` by ``-R^T dv_c``: by itself the scheme moves a hull as if the
water's acceleration exerted no force on it. It does. For a body of rigid-body mass ``m``,
displaced mass ``m_d = B / g`` and added mass ``M_A`` in water whose own (material)
acceleration at the body is ``A = DV_c/Dt``, the pressure gradient that accelerates the water
pushes the body with the Froude-Krylov force ``m_d A`` (acting at the centre of buoyancy), and
the added-mass reaction is ``-M_A (dnu/dt - A)`` (Auton, Hunt & Prud'homme 1988, J. Fluid
Mech. 197):

    (M_RB + M_A) dnu/dt = tau - C nu_r - D(nu_r) nu_r - g(eta) + (m_d + M_A) A,

and in relative velocity, for a current uniform in space (``A = dV_c/dt``),

    (M_RB + M_A) dnu_r/dt = tau - C nu_r - D(nu_r) nu_r - g(eta) - (M_RB - m_d) dV_c/dt.

The term vanishes for a neutrally buoyant body (``m_d = m``: it moves with the water); a heavy
body lags; the vehicle's velocity loop and thrust limits still lag a changing current either
way. :func:`step_agent_unsteady` adds the missing force, given ``A`` (east, north; m s-2)
over the step: per linear DOF ``i`` the impulse ``lambda_i R^T A dt`` on the velocity over
ground with ``lambda_i = (m_d + M_A,i) / (m + M_A,i)`` (parameters ``P_ACC``), applied at the
start of the step, where the sampled current jumps (so a uniform current's jump
``dV_c = A dt`` changes ``nu_r`` by exactly ``-kappa_i R^T dV_c``, ``kappa_i = (m - m_d) /
(m + M_A,i) = 1 - lambda_i``), plus, in 6-DoF, the Froude-Krylov moment about the centre of
gravity ``r_b x m_d A = (BG m_d A_v, -BG m_d A_u, 0)`` (``P_ACCM = BG m_d``). The added-mass
matrix is diagonal about the origin, so its reaction has no moment.

:func:`step_agent` (the step the episode loop takes, :func:`oneocean.engine.step.advance_agent`)
is ``step_agent_unsteady`` with ``A = 0``: the loop does not give the dynamics the water's
acceleration. ``A`` is a property of the field, not of the vehicle's samples: it needs the
grid at the agent (``dV/dt`` of the time interpolation plus ``(V . grad) V`` of the spatial
one). The difference of the current sampled at consecutive steps along the vehicle's path is
``dV/dt + (v . grad) V``, which differs from ``A`` by ``(nu_r . grad) V``; using it would make
the term exact in a current uniform in space and wrong by ``(m_d + M_A) (nu_r . grad) V``
elsewhere (on the default region's data about 1.3e-4 s-1 x 2 m s-1 for a transiting AUV,
typically more than the ``(m_d + M_A) A`` it would add), and would need the previous sample
in the agent's state, which every method's navigation copy would then hold: the true
current.
Magnitude on the default region: ``|A|`` below ~2e-4 m s-2 at the 90th percentile (time and
advective parts alike), ~4 mN on the BlueROV2; on SK's oracle, holding a station through the
tide, it moves the vehicle by at most 2e-4 m (8 stations, 900 s; measured by driving
:func:`step_agent_unsteady` with ``A dt = V(x + V dt, t + dt) - V(x, t)`` from the grid).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Mapping

import numpy as np
import yaml

from ..errors import ConfigError
from ..vocab import DYNAMICS, validate_choice
from ._jit import hot_kernel
from . import libm

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
P_TMAX = 20    # 6 thruster limits (0 = no thruster on that DOF)
P_K = 26       # 6 velocity-loop gains K_i = M_i / T_i (N s m-1 | N m s rad-1)
P_WB = 32      # W - B, N (positive: heavier than water)
P_BGB = 33     # BG * B, N m (roll/pitch restoring coefficient)
P_KPSI = 34    # heading gain, s-1
P_RMAX = 35    # yaw-rate (and roll/pitch-rate) command limit, rad s-1
P_VYAW = 36    # heading update threshold, m s-1
P_KATT = 37    # roll/pitch attitude gain, s-1
P_GUIDE = 38   # guidance law: 0 holonomic, 1 torpedo
P_PMAX = 39    # pitch-reference limit, rad (0: keep level)
P_FINQ = 40    # stern-plane moment capacity per u_r^2: |M_uuds| delta_max, kg (N m s2 m-2)
P_FINR = 41    # rudder moment capacity per u_r^2: |N_uudr| delta_max, kg
P_FINZ = 42    # heave force per stern-plane pitch moment: Z_uuds / M_uuds, m-1
P_FINY = 43    # sway force per rudder yaw moment: Y_uudr / N_uudr, m-1
P_LIFT = 44    # 8 lift-damping terms (LHS, per unit u_r): sway/yaw s_vv, s_rr, s_vr, k_vr;
#                heave/pitch s_ww, s_qq, s_wq, k_wq (s: times |u_r|, symmetric; k: times u_r)
P_CPL = 52     # 2 thrust-coupling flags: (surge, sway, yaw) group, (heave, roll, pitch) group
P_RTURN = 54   # smallest commanded turn radius, m (yaw-rate limit |u_r| / R; 0: none)
P_ACC = 55     # 3 shares of the water's acceleration the hull takes, surge/sway/heave:
#                (m_d + M_A,i) / (m + M_A,i), m_d = B / g (Froude-Krylov + added mass)
P_ACCM = 58    # BG * m_d, kg m (Froude-Krylov moment of the water's acceleration)
PARAM_DIM = 59

#: Guidance laws (``guidance`` key of a vehicle), in parameter-vector order.
GUIDANCE = ("holonomic", "torpedo")

#: Upper bound on the integration substep, s (see data/vehicles.yaml).
MAX_SUBSTEP_S = 0.5

#: Length of the actuator trace written by :func:`step_agent_traced`.
TRACE_DIM = 14

_VEHICLE_KEYS = {
    "description": str, "mass_kg": float, "inertia_kg_m2": 3, "added_mass": 6,
    "linear_damping": 6, "quadratic_damping": 6, "thrust_max": 6, "speed_limit_ms": float,
    "net_buoyancy_n": float, "metacentric_height_m": float, "gravity_ms2": float,
    "velocity_time_constant_s": 6, "heading_gain_per_s": float, "yaw_rate_max_rad_s": float,
    "heading_min_speed_ms": float, "max_substep_s": float, "attitude_gain_per_s": float,
    "guidance": str, "pitch_max_deg": float, "thrust_coupling": 2, "lift_coefficients": 8,
    "fin_coefficients": 4, "fin_angle_max_deg": float, "turn_radius_min_m": float,
}

#: Keys that may be left out of a vehicle spec, with the value they then take (a vehicle
#: without lift, fins or thruster coupling, steered holonomically and kept level).
_VEHICLE_DEFAULTS = {
    "guidance": "holonomic", "pitch_max_deg": 0.0, "thrust_coupling": [0.0, 0.0],
    "lift_coefficients": [0.0] * 8, "fin_coefficients": [0.0] * 4, "fin_angle_max_deg": 0.0,
    "turn_radius_min_m": 0.0,
}


def model_id(name: str) -> int:
    """Integer id of a dynamics model name.

    Parameters
    ----------
    name : str
        Model name, one of :data:`oneocean.vocab.DYNAMICS` (``kinematic``, ``3dof``, ``4dof``,
        ``6dof``).

    Returns
    -------
    int
        Model id: ``KINEMATIC`` (0), ``DOF3`` (1), ``DOF4`` (2) or ``DOF6`` (3).

    Raises
    ------
    ConfigError
        If ``name`` is unknown (the message names the options).
    """
    return MODEL_IDS[validate_choice(name, DYNAMICS, "dynamics")]


@dataclass(frozen=True)
class Vehicle:
    """A vehicle's parameters: the documented spec (for manifests) and the kernel vector.

    Attributes
    ----------
    name : str
        Vehicle name (key in ``data/vehicles.yaml``).
    spec : dict
        The vehicle's spec as given (file values with any overrides applied).
    params : (PARAM_DIM,) float64
        Kernel parameter vector built by :func:`vehicle_params`.
    """

    name: str
    spec: dict
    params: np.ndarray = field(repr=False)

    @property
    def v_max(self) -> float:
        """Speed limit, m s-1."""
        return float(self.params[P_VMAX])

    def substeps(self, dt: float) -> int:
        """Number of integration substeps the rigid-body models use for a step ``dt``.

        Parameters
        ----------
        dt : float
            Step, s.

        Returns
        -------
        int
            ``ceil(dt / max_substep_s)``, at least 1.
        """
        return _nsub(self.params, float(dt))


@lru_cache(maxsize=1)
def vehicles_file() -> Path:
    """The vehicle table, ``data/vehicles.yaml`` (shipped in the wheel; located once).

    Returns
    -------
    pathlib.Path
        Path of the packaged vehicle table.
    """
    return Path(str(resources.files("oneocean") / "data" / "vehicles.yaml"))


def vehicle_params(spec: Mapping, name: str = "vehicle") -> np.ndarray:
    """Validate a vehicle spec (see ``data/vehicles.yaml``) and build its parameter vector.

    Parameters
    ----------
    spec : mapping
        Vehicle spec: every key of ``data/vehicles.yaml``'s vehicles (SI units); ``guidance``,
        ``pitch_max_deg``, ``thrust_coupling``, ``lift_coefficients``, ``fin_coefficients``,
        ``fin_angle_max_deg`` and ``turn_radius_min_m`` may be left out (no lift, fins or
        coupling; holonomic and level).
    name : str, default "vehicle"
        Vehicle name, used in error messages.

    Returns
    -------
    (PARAM_DIM,) float64
        Parameter vector for the kernels (layout: the ``P_*`` offsets of this module).

    Raises
    ------
    ConfigError
        If a key is missing or unknown, a value is ill-typed, non-finite or out of range, or the
        lift coefficients are not dissipative.
    """
    missing = [k for k in _VEHICLE_KEYS if k not in spec and k not in _VEHICLE_DEFAULTS]
    unknown = [k for k in spec if k not in _VEHICLE_KEYS]
    if missing:
        raise ConfigError(f"vehicle '{name}': missing keys: {', '.join(missing)}")
    if unknown:
        raise ConfigError(f"vehicle '{name}': unknown keys: {', '.join(unknown)}")
    spec = {**_VEHICLE_DEFAULTS, **spec}
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
    guidance = validate_choice(spec["guidance"], GUIDANCE, f"vehicle '{name}': guidance")
    for k in ("inertia_kg_m2", "added_mass", "linear_damping", "quadratic_damping",
              "thrust_max", "velocity_time_constant_s", "pitch_max_deg", "fin_angle_max_deg",
              "turn_radius_min_m"):
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
    if not vals["pitch_max_deg"] < 80.0:
        raise ConfigError(f"vehicle '{name}': 'pitch_max_deg' must be < 80")
    if not vals["fin_angle_max_deg"] <= 45.0:
        raise ConfigError(f"vehicle '{name}': 'fin_angle_max_deg' must be <= 45")
    cpl = vals["thrust_coupling"]
    if not np.all((cpl == 0.0) | (cpl == 1.0)):
        raise ConfigError(f"vehicle '{name}': 'thrust_coupling' entries must be 0 or 1, "
                          f"got {spec['thrust_coupling']!r}")
    tmax = vals["thrust_max"]
    # fins: [Y_uudr, N_uudr, Z_uuds, M_uuds]; a fin-steered DOF has no thruster
    y_dr, n_dr, z_ds, m_ds = vals["fin_coefficients"]
    dmax = math.radians(float(vals["fin_angle_max_deg"]))
    fin_r = abs(n_dr) * dmax
    fin_q = abs(m_ds) * dmax
    for dof, mom, force, label in ((5, n_dr, y_dr, "rudder (N_uudr, Y_uudr)"),
                                   (4, m_ds, z_ds, "stern planes (M_uuds, Z_uuds)")):
        if force != 0.0 and mom == 0.0:
            raise ConfigError(f"vehicle '{name}': {label}: a fin force needs a fin moment")
        if mom != 0.0 and tmax[dof] > 0.0:
            raise ConfigError(f"vehicle '{name}': {label}: a fin-steered DOF must have "
                              f"thrust_max 0 (got {tmax[dof]})")
    if (fin_r > 0 or fin_q > 0) and not dmax > 0:
        raise ConfigError(f"vehicle '{name}': fins need 'fin_angle_max_deg' > 0")
    tc = vals["velocity_time_constant_s"]
    act = (tmax > 0) | (np.array([0, 0, 0, 0, fin_q, fin_r]) > 0)
    if np.any(act & ~(tc > 0)):
        raise ConfigError(f"vehicle '{name}': 'velocity_time_constant_s' must be > 0 for every "
                          "actuated DOF (thrust_max > 0 or fin-steered), got "
                          f"{spec['velocity_time_constant_s']!r}")
    if guidance == "torpedo" and not tmax[0] > 0:
        raise ConfigError(f"vehicle '{name}': a torpedo needs surge thrust (thrust_max[0] > 0)")
    # lift: [Y_uv, Y_ur, N_uv, N_ur, Z_uw, Z_uq, M_uw, M_uq] (force on the hull, RHS sign)
    lift = vals["lift_coefficients"]
    lift_p = np.zeros(8)
    for j, (yv, yr, nv, nr) in enumerate((lift[:4], lift[4:])):
        s_vv, s_rr, s_vr, k_vr = -yv, -nr, -0.5 * (yr + nv), -0.5 * (yr - nv)
        if s_vv < 0 or s_rr < 0 or s_vr * s_vr > s_vv * s_rr * (1 + 1e-12):
            plane = ("sway/yaw", "heave/pitch")[j]
            raise ConfigError(
                f"vehicle '{name}': lift_coefficients of the {plane} plane are not "
                "dissipative: their part symmetric in the two velocities must be negative "
                f"semi-definite (got {list(lift[4 * j:4 * j + 4])})")
        lift_p[4 * j:4 * j + 4] = s_vv, s_rr, s_vr, k_vr
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
    p[P_GUIDE] = GUIDANCE.index(guidance)
    p[P_PMAX] = math.radians(float(vals["pitch_max_deg"]))
    p[P_FINQ] = fin_q
    p[P_FINR] = fin_r
    p[P_FINZ] = z_ds / m_ds if m_ds != 0.0 else 0.0
    p[P_FINY] = y_dr / n_dr if n_dr != 0.0 else 0.0
    p[P_LIFT:P_LIFT + 8] = lift_p
    p[P_CPL:P_CPL + 2] = cpl
    p[P_RTURN] = vals["turn_radius_min_m"]
    m_disp = buoy / vals["gravity_ms2"]
    p[P_ACC:P_ACC + 3] = (m_disp + vals["added_mass"][:3]) / mass[:3]
    p[P_ACCM] = vals["metacentric_height_m"] * m_disp
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

    Returns
    -------
    Vehicle
        The vehicle's name, spec (with the overrides) and parameter vector.

    Raises
    ------
    ConfigError
        If the file cannot be read or lacks ``vehicles``, the name or an override key is
        unknown, or the spec is invalid (:func:`vehicle_params`).
    """
    f = Path(path) if path is not None else vehicles_file()
    try:
        st = f.stat()
        doc = _vehicle_doc(str(f), st.st_mtime_ns, st.st_size)
    except OSError as exc:
        raise ConfigError(f"{f}: cannot read vehicle file ({exc})") from exc
    if not isinstance(doc, dict) or "vehicles" not in doc:
        raise ConfigError(f"{f}: expected a mapping with key 'vehicles'")
    name = name if name is not None else doc.get("default")
    name = validate_choice(name, tuple(doc["vehicles"]), "vehicle")
    spec = copy.deepcopy(doc["vehicles"][name])
    if overrides:
        unknown = [k for k in overrides if k not in _VEHICLE_KEYS]
        if unknown:
            raise ConfigError(f"vehicle '{name}': unknown override keys: {', '.join(unknown)}")
        spec.update({k: (list(v) if isinstance(v, (list, tuple, np.ndarray)) else v)
                     for k, v in overrides.items()})
    return Vehicle(name=name, spec=spec, params=vehicle_params(spec, name))


@lru_cache(maxsize=16)
def _vehicle_doc(path: str, mtime_ns: int, size: int):
    """The parsed vehicle file, once per file version (``load_vehicle`` copies what it hands
    out, so the cached document is never changed)."""
    return yaml.safe_load(Path(path).read_text())


def vehicle_names(path: str | Path | None = None) -> tuple[str, ...]:
    """Names of the vehicles in ``data/vehicles.yaml`` (or ``path``), file order.

    Parameters
    ----------
    path : path-like, optional
        Alternative YAML file with the same layout; default: :func:`vehicles_file`.

    Returns
    -------
    tuple of str
        Vehicle names.
    """
    f = Path(path) if path is not None else vehicles_file()
    return tuple(yaml.safe_load(f.read_text())["vehicles"])


# ----------------------------------------------------------------------------- kernels


@hot_kernel(inline="always")
def clip_action(ax, ay, az, v_max):
    """Clip a velocity vector to Euclidean norm ``v_max`` (direction kept).

    Parameters
    ----------
    ax, ay, az : float
        Velocity components (east, down, north), m s-1.
    v_max : float
        Speed limit, m s-1.

    Returns
    -------
    tuple of float
        ``(ax, ay, az)`` scaled down to norm ``v_max`` if longer, else unchanged, m s-1.
    """
    n2 = ax * ax + ay * ay + az * az
    if n2 > v_max * v_max:
        s = v_max / math.sqrt(n2)
        return ax * s, ay * s, az * s
    return ax, ay, az


@hot_kernel
def wrap_angle(a):
    """Wrap an angle to [-pi, pi).

    Parameters
    ----------
    a : float
        Angle, rad.

    Returns
    -------
    float
        The equivalent angle in [-pi, pi), rad.
    """
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
    """Sine and cosine with fdlibm's kernel polynomials after a Cody-Waite quadrant reduction.

    About 3x faster than two libm calls in this kernel; accurate to ~1 ulp for ``|x| <= 1e5``
    (the engine's angles are wrapped to [-pi, pi)); larger arguments fall back to libm.

    Parameters
    ----------
    x : float
        Angle, rad.

    Returns
    -------
    tuple of float
        ``(sin x, cos x)``.
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


@hot_kernel(inline="always")
def _dof(thrust_on, m, dk, k, cap, h, x, c, g, fc, sat, ts):
    """Diagonal ``d`` and rhs ``b`` of one DOF for a substep ``h``.

    ``x`` is the DOF's relative velocity at the start of the substep, ``dk`` its (lagged)
    damping coefficient. Damping is implicit; an actuated DOF (``cap > 0``) adds the
    controller ``tau = dk c + g + fc + k (c - x)`` implicitly, or the limited force ``ts``
    explicitly when ``sat`` is set. ``fc`` is the feed-forward of the coupling terms: the
    lagged ``[C(nu_r,k) nu_r,k]_i`` for a fin, 0 for a thruster, whose controller cancels the
    row's couplings implicitly (the solvers drop that row's off-diagonal terms). With vanishing
    inertia the DOF reaches ``c`` within one substep; at steady state ``tau`` = ``D(c) c`` +
    couplings + ``g``.
    """
    d = m + h * dk
    b = m * x - h * g
    if thrust_on and cap > 0.0:
        if sat:
            b += h * ts
        else:
            d += h * k
            b += h * (dk * c + g + fc + k * c)
    return d, b


@hot_kernel(inline="always")
def _tau(dk, k, c, g, fc, x):
    """Controller force of an unsaturated DOF for the solution ``x``."""
    return dk * c + g + fc + k * (c - x)


@hot_kernel(inline="always")
def _box(cap, tau, sat, bit, ts):
    """Saturate a DOF whose force ``tau`` exceeds ``cap``: returns (sat, ts)."""
    if tau > cap:
        return sat | bit, cap
    if tau < -cap:
        return sat | bit, -cap
    return sat, ts


@hot_kernel(inline="always")
def _group_load(a, b, c):
    """Load of a four-thruster group, normalised demands a, b, c (feasible iff <= 1)."""
    aa = abs(a)
    bb = abs(b)
    cc = abs(c)
    return max(aa + bb, max(aa + cc, bb + cc))


@hot_kernel(inline="always")
def _limit3(coupled, bit_a, bit_b, bit_c, sat, t_a, t_b, t_c, cap_a, cap_b, cap_c,
            ts_a, ts_b, ts_c):
    """Limit the forces (t_a, t_b, t_c) of three DOFs: one group of four vectored thrusters
    (``coupled``: scaled down together along their direction when the group's load exceeds 1)
    or box limits per DOF. Returns (sat, ts_a, ts_b, ts_c)."""
    if coupled:
        group = bit_a | bit_b | bit_c
        if not sat & group:
            load = _group_load(t_a / cap_a if cap_a > 0.0 else 0.0,
                               t_b / cap_b if cap_b > 0.0 else 0.0,
                               t_c / cap_c if cap_c > 0.0 else 0.0)
            if load > 1.0:
                return sat | group, t_a / load, t_b / load, t_c / load
        return sat, ts_a, ts_b, ts_c
    if not sat & bit_a:
        sat, ts_a = _box(cap_a, t_a, sat, bit_a, ts_a)
    if not sat & bit_b:
        sat, ts_b = _box(cap_b, t_b, sat, bit_b, ts_b)
    if not sat & bit_c:
        sat, ts_c = _box(cap_c, t_c, sat, bit_c, ts_c)
    return sat, ts_a, ts_b, ts_c


@hot_kernel
def _solve3(d0, d1, d5, b0, b1, b5, u0, u1, l0, l1):
    """Solve [[d0, 0, u0], [0, d1, u1], [l0, l1, d5]] x = b (surge, sway, yaw block)."""
    i0 = 1.0 / d0
    i1 = 1.0 / d1
    x5 = (b5 - l0 * b0 * i0 - l1 * b1 * i1) / (d5 - l0 * u0 * i0 - l1 * u1 * i1)
    return (b0 - u0 * x5) * i0, (b1 - u1 * x5) * i1, x5


@hot_kernel
def _solve6(h, d0, d1, d2, d3, d4, d5, b0, b1, b2, b3, b4, b5, a1, a2, a3, c1, c2, c3,
            e15, e51, e24, e42, f15, f24, z0, z1, z2, z3, z4, z5):
    """Solve (diag(d) + Z (h C + E) + F) x = b.

    ``C`` is the Kirchhoff Coriolis matrix of momenta a, c, ``C = [[0, -S(a)], [-S(a), -S(c)]]``
    (skew), ``E`` the lift couplings sway-yaw (``e15`` in the sway row, ``e51`` in the yaw
    row) and heave-pitch (``e24``, ``e42``), ``Z = diag(z)`` keeps (1) or drops (0) each row's
    couplings (a thruster's controller cancels them), ``F`` the fin side forces (``f15``,
    ``f24``). The linear block stays diagonal: Schur complement on it, then Cramer's rule on
    the 3 x 3 angular system.
    """
    i0 = 1.0 / d0
    i1 = 1.0 / d1
    i2 = 1.0 / d2
    ha1 = h * a1
    ha2 = h * a2
    ha3 = h * a3
    # U (rows surge, sway, heave; columns roll, pitch, yaw), L (rows roll, pitch, yaw; columns
    # surge, sway, heave): h (-S(a)) = h [[0, a3, -a2], [-a3, 0, a1], [a2, -a1, 0]] plus E, F
    u01 = z0 * ha3
    u02 = -z0 * ha2
    u10 = -z1 * ha3
    u12 = z1 * (ha1 + e15) + f15
    u20 = z2 * ha2
    u21 = z2 * (e24 - ha1) + f24
    l01 = z3 * ha3
    l02 = -z3 * ha2
    l10 = -z4 * ha3
    l12 = z4 * (ha1 + e42)
    l20 = z5 * ha2
    l21 = z5 * (e51 - ha1)
    # S = A22 - L D1^-1 U with A22 = diag(d3, d4, d5) + Z h (-S(c))
    s00 = d3 - l01 * u10 * i1 - l02 * u20 * i2
    s01 = z3 * h * c3 - l02 * u21 * i2
    s02 = -z3 * h * c2 - l01 * u12 * i1
    s10 = -z4 * h * c3 - l12 * u20 * i2
    s11 = d4 - l10 * u01 * i0 - l12 * u21 * i2
    s12 = z4 * h * c1 - l10 * u02 * i0
    s20 = z5 * h * c2 - l21 * u10 * i1
    s21 = -z5 * h * c1 - l20 * u01 * i0
    s22 = d5 - l20 * u02 * i0 - l21 * u12 * i1
    r0 = b3 - l01 * b1 * i1 - l02 * b2 * i2
    r1 = b4 - l10 * b0 * i0 - l12 * b2 * i2
    r2 = b5 - l20 * b0 * i0 - l21 * b1 * i1
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
    x0 = (b0 - u01 * x4 - u02 * x5) * i0
    x1 = (b1 - u10 * x3 - u12 * x5) * i1
    x2 = (b2 - u20 * x3 - u21 * x4) * i2
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




@hot_kernel(inline="always")
def _rotation(psi, phi, th, six):
    """Roll/pitch sines and cosines and the body -> NED rotation (Fossen zyx) at attitude
    (phi, th, psi); without roll/pitch (``six`` False) the vehicle is level.

    Returns ``(sph, cph, sth, cth, r00, r01, r02, r10, r11, r12, r20, r21, r22)``.
    """
    sps, cps = sincos(psi)
    if six:
        sph, cph = sincos(phi)
        sth, cth = sincos(th)
    else:
        sph = 0.0
        cph = 1.0
        sth = 0.0
        cth = 1.0
    return (sph, cph, sth, cth,
            cps * cth, -sps * cph + cps * sth * sph, sps * sph + cps * cph * sth,
            sps * cth, cps * cph + sph * sth * sps, -cps * sph + sth * sps * cph,
            -sth, cth * sph, cth * cph)


@hot_kernel
def _step_rigid(model, vp, s, cmd, ce, cn, acc_e, acc_n, dt, trace, record):
    nsub = _nsub(vp, dt)
    h = dt / nsub
    thrust_on = cmd[C_THRUST] != 0.0
    an = cmd[C_AZ]  # command in NED order (north, east, down)
    ae = cmd[C_AX]
    ad = cmd[C_AY]
    six = model == DOF6
    heave = model != DOF3
    torpedo = vp[P_GUIDE] != 0.0
    if not heave or (torpedo and not six):
        ad = 0.0  # no heave DOF, or a torpedo without pitch: it cannot change depth
    ah2 = an * an + ae * ae
    psi_free = cmd[C_PSI] != cmd[C_PSI]  # NaN
    # heading reference: explicit command, else direction of the commanded horizontal velocity
    psi_ref = s[PSI_REF]
    if not psi_free:
        psi_ref = cmd[C_PSI]
    elif thrust_on and ah2 >= vp[P_VYAW] * vp[P_VYAW]:
        psi_ref = math.atan2(ae, an)
    s[PSI_REF] = psi_ref
    # torpedo: surge speed = commanded relative speed; pitch toward the commanded direction
    spd = math.sqrt(ah2 + ad * ad)
    pmax = vp[P_PMAX]
    th_ref = 0.0
    if six and pmax > 0.0:
        th_ref = min(max(math.atan2(-ad, math.sqrt(ah2)), -pmax), pmax)
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
    k0 = vp[P_K]
    k1 = vp[P_K + 1]
    k2 = vp[P_K + 2]
    k3 = vp[P_K + 3]
    k4 = vp[P_K + 4]
    k5 = vp[P_K + 5]
    cap0 = vp[P_TMAX]
    cap1 = vp[P_TMAX + 1]
    tmax2 = vp[P_TMAX + 2]
    tmax3 = vp[P_TMAX + 3]
    tmax4 = vp[P_TMAX + 4]
    tmax5 = vp[P_TMAX + 5]
    fin_q = vp[P_FINQ]
    fin_r = vp[P_FINR]
    fin_z = vp[P_FINZ]
    fin_y = vp[P_FINY]
    svv = vp[P_LIFT]
    srr = vp[P_LIFT + 1]
    svr = vp[P_LIFT + 2]
    kvr = vp[P_LIFT + 3]
    sww = vp[P_LIFT + 4]
    sqq = vp[P_LIFT + 5]
    swq = vp[P_LIFT + 6]
    kwq = vp[P_LIFT + 7]
    has_lift = (svv != 0.0 or srr != 0.0 or svr != 0.0 or kvr != 0.0 or sww != 0.0
                or sqq != 0.0 or swq != 0.0 or kwq != 0.0)
    cpl_h = vp[P_CPL] != 0.0
    cpl_v = vp[P_CPL + 1] != 0.0
    rturn = vp[P_RTURN]
    ur = vr = wr = 0.0
    for k in range(nsub):
        sph, cph, sth, cth, r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rotation(
            psi, phi, th, six)
        if k == 0:
            # relative velocity nu_r = nu - R^T v_c (NED current v_c = (cn, ce, 0)); the
            # substeps then carry nu_r itself, whose equation does not depend on a uniform
            # current (Fossen 2011, Property 10.1)
            ur = u - (r00 * cn + r10 * ce)
            vr = v - (r01 * cn + r11 * ce)
            wr = w - (r02 * cn + r12 * ce)
            if acc_e != 0.0 or acc_n != 0.0:
                # the water's acceleration over the step (module docs): Froude-Krylov and
                # added-mass impulse on each linear DOF, Froude-Krylov moment (6-DoF)
                iu = dt * (r00 * acc_n + r10 * acc_e)
                iv = dt * (r01 * acc_n + r11 * acc_e)
                iw = dt * (r02 * acc_n + r12 * acc_e)
                ur += vp[P_ACC] * iu
                vr += vp[P_ACC + 1] * iv
                if heave:
                    wr += vp[P_ACC + 2] * iw
                if six:
                    p += vp[P_ACCM] * iv / m3
                    q -= vp[P_ACCM] * iu / m4
        # commanded relative velocity in body frame; rate commands of the attitude loops
        if torpedo and psi_free:
            cu = spd
        else:
            cu = r00 * an + r10 * ae + r20 * ad
        cv = r01 * an + r11 * ae + r21 * ad
        cw = r02 * an + r12 * ae + r22 * ad
        pc = min(max(-katt * phi, -rmax), rmax)
        qc = min(max(katt * (th_ref - th), -rmax), rmax)
        rlim = rmax
        if rturn > 0.0:  # a turn no tighter than rturn: yaw rate <= |u_r| / rturn
            rlim = min(rmax, abs(ur) / rturn)
        rc = min(max(kpsi * wrap_angle(psi_ref - psi), -rlim), rlim)
        # momenta for the Coriolis term C(nu_r) nu_r (implicit: C(nu_r,k) nu_r,k+1)
        a1 = m0 * ur
        a2 = m1 * vr
        a3 = m2 * wr
        c1 = m3 * p
        c2 = m4 * q
        c3 = m5 * r
        # lift of a finned hull (LHS coefficients, lagged in u_r): symmetric part x |u_r|
        # (dissipative), skew part x u_r
        au = abs(ur)
        l15 = l51 = l24 = l42 = ld1 = ld2 = ld4 = ld5 = 0.0
        if has_lift:
            l15 = au * svr + ur * kvr
            l51 = au * svr - ur * kvr
            l24 = au * swq + ur * kwq
            l42 = au * swq - ur * kwq
            ld1 = au * svv
            ld2 = au * sww
            ld4 = au * sqq
            ld5 = au * srr
        # couplings C(nu_r,k) nu_r,k + lift cross terms of pitch and yaw at the substep's
        # start: the feed-forward of a fin-steered DOF (feedback linearisation: it cancels
        # the Coriolis/Munk/lift terms the vehicle actually feels, within the fin's authority)
        f4 = wr * a1 - ur * a3 + r * c1 - p * c3 + l42 * wr
        f5 = ur * a2 - vr * a1 + p * c2 - q * c1 + l51 * vr
        # damping coefficients (lagged), including the lift diagonal, and actuator capacities
        # (thrusters, plus fins whose lift grows with u_r^2), of the model's DOFs
        u2 = ur * ur
        dk0 = vp[P_DL] + vp[P_DQ] * au
        dk1 = vp[P_DL + 1] + vp[P_DQ + 1] * abs(vr) + ld1
        dk5 = vp[P_DL + 5] + vp[P_DQ + 5] * abs(r) + ld5
        cap5 = tmax5 + fin_r * u2
        dk2 = dk3 = dk4 = cap2 = cap3 = cap4 = 0.0
        if heave:
            dk2 = vp[P_DL + 2] + vp[P_DQ + 2] * abs(wr) + ld2
            cap2 = tmax2
        if six:
            dk3 = vp[P_DL + 3] + vp[P_DQ + 3] * abs(p)
            dk4 = vp[P_DL + 4] + vp[P_DQ + 4] * abs(q) + ld4
            cap3 = tmax3
            cap4 = tmax4 + fin_q * u2
        fin5 = thrust_on and fin_y != 0.0 and cap5 > 0.0
        fin4 = thrust_on and fin_z != 0.0 and cap4 > 0.0
        # restoring forces (body), Fossen g(eta) with r_g = 0, r_b = (0, 0, -BG)
        g0 = wb * sth
        g1 = -wb * cth * sph
        g2 = -wb * cth * cph
        g3 = bgb * cth * sph
        g4 = bgb * sth
        kst = h * h * bgb * cth * cph  # linearised roll/pitch restoring stiffness
        # a thruster DOF's controller cancels its row's couplings implicitly (fins, weak and
        # often saturated, use the lagged feed-forward f_i)
        th0 = thrust_on and cap0 > 0.0
        th1 = thrust_on and cap1 > 0.0
        th2 = thrust_on and cap2 > 0.0
        th3 = thrust_on and cap3 > 0.0
        th4 = thrust_on and tmax4 > 0.0 and six
        th5 = thrust_on and tmax5 > 0.0
        fc4 = 0.0 if th4 else f4
        fc5 = 0.0 if th5 else f5
        sat = 0
        ts0 = ts1 = ts2 = ts3 = ts4 = ts5 = 0.0
        t0 = t1 = t2 = t3 = t4 = t5 = 0.0
        x0 = x1 = x2 = x3 = x4 = x5 = 0.0
        for _pass in range(7):  # active set: each pass saturates >= 1 more DOF or stops
            d0, b0 = _dof(thrust_on, m0, dk0, k0, cap0, h, ur, cu, g0, 0.0, sat & 1, ts0)
            d1, b1 = _dof(thrust_on, m1, dk1, k1, cap1, h, vr, cv, g1, 0.0, sat & 2, ts1)
            d5, b5 = _dof(thrust_on, m5, dk5, k5, cap5, h, r, rc, 0.0, fc5, sat & 32, ts5)
            z0 = 0.0 if th0 and not sat & 1 else 1.0
            z1 = 0.0 if th1 and not sat & 2 else 1.0
            z5 = 0.0 if th5 and not sat & 32 else 1.0
            f15 = 0.0
            if fin5:  # rudder lift also pushes the stern sideways: F_y = fin_y * tau_yaw
                if sat & 32:
                    b1 += h * fin_y * ts5
                else:
                    f15 = h * fin_y * k5
                    b1 += h * fin_y * (dk5 * rc + f5 + k5 * rc)
            if six:
                d2, b2 = _dof(thrust_on, m2, dk2, k2, cap2, h, wr, cw, g2, 0.0, sat & 4, ts2)
                d3, b3 = _dof(thrust_on, m3, dk3, k3, cap3, h, p, pc, g3, 0.0, sat & 8, ts3)
                d4, b4 = _dof(thrust_on, m4, dk4, k4, cap4, h, q, qc, g4, fc4, sat & 16, ts4)
                if kst > 0.0:
                    d3 += kst
                    d4 += kst
                z2 = 0.0 if th2 and not sat & 4 else 1.0
                z3 = 0.0 if th3 and not sat & 8 else 1.0
                z4 = 0.0 if th4 and not sat & 16 else 1.0
                f24 = 0.0
                if fin4:  # stern-plane lift: F_z = fin_z * tau_pitch
                    if sat & 16:
                        b2 += h * fin_z * ts4
                    else:
                        f24 = h * fin_z * k4
                        b2 += h * fin_z * (dk4 * qc + g4 + f4 + k4 * qc)
                if z0 + z1 + z2 + z3 + z4 + z5 == 0.0:  # fully actuated: decoupled
                    x0 = b0 / d0
                    x1 = b1 / d1
                    x2 = b2 / d2
                    x3 = b3 / d3
                    x4 = b4 / d4
                    x5 = b5 / d5
                else:
                    x0, x1, x2, x3, x4, x5 = _solve6(h, d0, d1, d2, d3, d4, d5, b0, b1, b2,
                                                     b3, b4, b5, a1, a2, a3, c1, c2, c3,
                                                     h * l15, h * l51, h * l24, h * l42,
                                                     f15, f24, z0, z1, z2, z3, z4, z5)
            else:
                if z0 + z1 + z5 == 0.0:  # fully actuated: decoupled
                    x0 = b0 / d0
                    x1 = b1 / d1
                    x5 = b5 / d5
                else:
                    x0, x1, x5 = _solve3(d0, d1, d5, b0, b1, b5, -z0 * h * a2,
                                         z1 * h * (a1 + l15) + f15, z5 * h * a2,
                                         z5 * h * (l51 - a1))
                if heave:
                    d2, b2 = _dof(thrust_on, m2, dk2, k2, cap2, h, wr, cw, g2, 0.0, sat & 4,
                                  ts2)
                    x2 = b2 / d2
            if not thrust_on:
                break
            s0 = sat
            # actuator forces implied by x: thrusters with their couplings at the new
            # velocities (momenta lagged), fins with the lagged feed-forward
            t0 = _tau(dk0, k0, cu, g0, a3 * x4 - a2 * x5, x0) if th0 else 0.0
            t1 = _tau(dk1, k1, cv, g1, (a1 + l15) * x5 - a3 * x3, x1) if th1 else 0.0
            if th5:
                t5 = _tau(dk5, k5, rc, 0.0, a2 * x0 + (l51 - a1) * x1 + c2 * x3 - c1 * x4, x5)
            else:
                t5 = _tau(dk5, k5, rc, 0.0, f5, x5) if cap5 > 0.0 else 0.0
            # (surge, sway, yaw): box limits, or one group of four vectored thrusters
            sat, ts0, ts1, ts5 = _limit3(cpl_h, 1, 2, 32, sat, t0, t1, t5, cap0, cap1, cap5,
                                         ts0, ts1, ts5)
            # (heave, roll, pitch)
            if heave:
                t2 = _tau(dk2, k2, cw, g2, a2 * x3 + (l24 - a1) * x4, x2) if th2 else 0.0
                t3 = (_tau(dk3, k3, pc, g3, a3 * x1 - a2 * x2 + c3 * x4 - c2 * x5, x3)
                      if th3 else 0.0)
                if th4:
                    t4 = _tau(dk4, k4, qc, g4,
                              (a1 + l42) * x2 - a3 * x0 + c1 * x5 - c3 * x3, x4)
                else:
                    t4 = _tau(dk4, k4, qc, g4, f4, x4) if cap4 > 0.0 else 0.0
                sat, ts2, ts3, ts4 = _limit3(cpl_v, 4, 8, 16, sat, t2, t3, t4, cap2, cap3,
                                             cap4, ts2, ts3, ts4)
            if sat == s0:
                break
        if record:
            _trace(trace, thrust_on, sat, t0, t1, t2, t3, t4, t5, ts0, ts1, ts2, ts3, ts4, ts5,
                   cap0, cap1, cap2, cap3, cap4, cap5, fin5, fin4, fin_y, fin_z)
        # advance the pose with the new velocity (symplectic Euler): over ground = R nu_r + v_c
        ur = x0
        vr = x1
        if heave:
            wr = x2
        r = x5
        n += h * (r00 * ur + r01 * vr + r02 * wr + cn)
        e += h * (r10 * ur + r11 * vr + r12 * wr + ce)
        if six:
            p = x3
            q = x4
            dd += h * (r20 * ur + r21 * vr + r22 * wr)
            tth = sth / cth
            phi += h * (p + sph * tth * q + cph * tth * r)
            th += h * (cph * q - sph * r)
            psi += h * (sph * q + cph * r) / cth
        else:
            if heave:
                dd += h * wr
            psi += h * r
        psi = wrap_angle(psi)
    # velocity over ground in the final body frame: nu = nu_r + R^T v_c
    sph, cph, sth, cth, r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rotation(
        psi, phi, th, six)
    u = ur + r00 * cn + r10 * ce
    v = vr + r01 * cn + r11 * ce
    w = wr + r02 * cn + r12 * ce
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


@hot_kernel
def _trace(out, thrust_on, sat, t0, t1, t2, t3, t4, t5, ts0, ts1, ts2, ts3, ts4, ts5,
           cap0, cap1, cap2, cap3, cap4, cap5, fin5, fin4, fin_y, fin_z):
    """Actuator forces of a substep (see :func:`step_agent_traced`)."""
    ts = (t0, t1, t2, t3, t4, t5)
    tss = (ts0, ts1, ts2, ts3, ts4, ts5)
    caps = (cap0, cap1, cap2, cap3, cap4, cap5)
    for i in range(6):
        tau = 0.0
        if thrust_on and caps[i] > 0.0:
            tau = tss[i] if (sat >> i) & 1 else ts[i]
        out[i] = tau
        out[6 + i] = caps[i] if thrust_on else 0.0
    out[12] = fin_y * out[5] if fin5 else 0.0
    out[13] = fin_z * out[4] if fin4 else 0.0


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
        _step_rigid(model, vp, s, cmd, ce, cn, 0.0, 0.0, dt, s, False)


@hot_kernel(inline="always")
def step_agent_unsteady(model, vp, s, cmd, ce, cn, acc_e, acc_n, dt):
    """:func:`step_agent` in water accelerating over the step.

    The rigid-body models add the Froude-Krylov and added-mass force of the water's acceleration
    (module docs, *Unsteady current*); ``step_agent`` is this with zero acceleration. The
    kinematic model moves with the water by definition (``p += (a + c) dt``) and ignores it.

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
    acc_e, acc_n : float
        The water's material acceleration ``DV_c/Dt`` at the agent (east, north), m s-2.
    dt : float
        Step, s.
    """
    if model == KINEMATIC:
        _step_kinematic(s, cmd, ce, cn, dt)
    else:
        _step_rigid(model, vp, s, cmd, ce, cn, acc_e, acc_n, dt, s, False)


@hot_kernel
def step_agent_traced(model, vp, s, cmd, ce, cn, dt, trace):
    """:func:`step_agent` of a rigid-body model that also writes its actuator forces.

    For tests and diagnostics.

    Parameters
    ----------
    model : int
        Rigid-body model id (``DOF3``, ``DOF4``, ``DOF6``).
    vp : (PARAM_DIM,) float64
        Vehicle parameters (:func:`vehicle_params`).
    s : (STATE_DIM,) float64
        Agent state, modified in place.
    cmd : (CMD_DIM,) float64
        ``[ax, ay, az, psi_cmd, thrust]``; the velocity must already be clipped.
    ce, cn : float
        Current (east, north) at the agent, m s-1, frozen over the step.
    dt : float
        Step, s. Use ``dt <= max_substep_s`` to see every substep.
    trace : (TRACE_DIM,) float64
        Receives, for the **last substep** of the step: ``[0:6]`` the actuator generalized
        force per DOF (thruster force / moment, or fin moment for a fin-steered DOF; N or N m),
        ``[6:12]`` its limit in that substep (thrust_max, or the fin capacity at the substep's
        u_r; for a coupled thruster group the pure-axis capacity), ``[12]`` the fin sway force
        and ``[13]`` the fin heave force (N).
    """
    _step_rigid(model, vp, s, cmd, ce, cn, 0.0, 0.0, dt, trace, True)


@hot_kernel
def kinetic_energy_rel(model, vp, s, ce, cn):
    """Kinetic energy relative to the water, ``0.5 nu_r^T M nu_r``, of a rigid-body state.

    Parameters
    ----------
    model : int
        Dynamics model id; roll and pitch are used only by ``DOF6``.
    vp : (PARAM_DIM,) float64
        Vehicle parameters (:func:`vehicle_params`).
    s : (STATE_DIM,) float64
        Agent state.
    ce, cn : float
        Current (east, north) at the agent, m s-1.

    Returns
    -------
    float
        Kinetic energy, J.
    """
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
    """Restoring potential energy: ``-(W - B) y + BG B (1 - cos(phi) cos(theta))``.

    Parameters
    ----------
    vp : (PARAM_DIM,) float64
        Vehicle parameters (:func:`vehicle_params`).
    s : (STATE_DIM,) float64
        Agent state.

    Returns
    -------
    float
        Potential energy, J.
    """
    return float(-vp[P_WB] * s[Y] + vp[P_BGB] * (1.0 - libm.cos(s[PHI]) * libm.cos(s[THETA])))


def new_state(n_episodes: int, n_agents: int, positions=None, heading=0.0) -> np.ndarray:
    """A zero-velocity state array at ``positions``.

    Parameters
    ----------
    n_episodes, n_agents : int
        Number of episodes E and agents per episode N.
    positions : array_like, optional
        (E, N, 3) positions ``(x, y, z)``, m, world frame; default: all zero.
    heading : float or array_like, default 0.0
        Heading, rad, compass convention: a scalar or an (E, N) array; it also sets the yaw
        loop's heading reference.

    Returns
    -------
    (E, N, STATE_DIM) float64
        Vehicle states.

    Raises
    ------
    ConfigError
        If ``positions`` does not have shape (E, N, 3).
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
    """A command vector ``[ax, ay, az, psi_cmd, thrust]`` (see module docs).

    Parameters
    ----------
    ax, ay, az : float, default 0.0
        Desired velocity relative to the water (east, down, north), m s-1.
    psi : float, default nan
        Commanded heading, rad; NaN: face the commanded horizontal velocity.
    thrust : bool, default True
        Controller on (True) or unactuated drift (False).

    Returns
    -------
    (CMD_DIM,) float64
        The command vector.
    """
    return np.array([ax, ay, az, psi, 1.0 if thrust else 0.0], dtype=np.float64)
