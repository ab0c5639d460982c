"""MJCF of a scene and of a vehicle as a MuJoCo rigid body.

Frames
------
Core world frame: x east, y depth (positive DOWN), z north (metres); body frame x forward,
y starboard, z down (FRD); zyx Euler angles (phi roll, theta pitch nose up, psi = compass
heading, clockwise from north). MuJoCo world frame: **x = core x (east), y = core z (north),
z = -core y (up)**; the vehicle body frame in MuJoCo is x forward, y port, z up (FLU). Hence

* positions: ``mj = (x, z, -y)``, :func:`core_to_mj`, :func:`mj_to_core`;
* attitude: with ``R`` the core body-to-NED rotation (Fossen zyx, rows north, east, down), the
  MuJoCo body-to-world rotation is ``R_mj = A R B`` with ``A`` = (north, east, down) -> (east,
  north, up) and ``B = diag(1, -1, -1)`` (FLU -> FRD): :func:`euler_to_quat`,
  :func:`quat_to_euler` (vectorised);
* body velocities: ``(u, v, w) = (u_mj, -v_mj, -w_mj)``, ``(p, q, r) = (p_mj, -q_mj, -r_mj)``
  (a free joint's ``qvel`` holds the world linear velocity and the body-frame angular
  velocity).

The vehicle body
----------------
One free body per model, built from :func:`oneocean.engine.dynamics.load_vehicle`'s spec
(vehicles.yaml, with its sources):

* **mass and inertia**: ``mass_kg`` and ``inertia_kg_m2``, split into the hull (mass
  ``(1 - f) m`` at the body origin, the core's reference point) and a ballast point mass ``f m``
  (``f`` = :data:`BALLAST_FRACTION`) a distance ``BG / f`` below it, so that the centre of
  gravity lies ``BG`` (``metacentric_height_m``) below the origin and the total inertia about
  it equals the table's;
* **buoyancy**: the hull body carries ``gravcomp = m / ((1 - f) m)``: an upward force equal to
  the whole vehicle's weight, applied at the origin (the centre of buoyancy). The vehicle is
  trimmed **neutrally buoyant** (REMUS's table value is 0 N; the ROV's +2.3 N is dropped: the
  velocity interface has no depth integrator) and keeps the core's restoring moment
  ``BG m g sin(angle)`` in roll and pitch. The medium has ``density = viscosity = 0``, so
  MuJoCo's fluid models add neither buoyancy nor drag (see **drag**);
* **added mass**: MuJoCo has no anisotropic added-mass matrix; :func:`build_model` puts the
  table's added mass on the free joint's ``dof_armature``: horizontal world axes
  ``(X_udot + Y_vdot) / 2``, vertical ``Z_wdot``, body rotations ``K_pdot, M_qdot, N_rdot``
  (exact for the rotations and for heave; the horizontal value averages surge and sway:
  REMUS 18.2 kg instead of 0.93 kg surge / 35.5 kg sway, BlueROV2 6.74 vs 6.36 / 7.12 kg);
* **drag**: per-axis damping relative to the water, the core's form: one unlimited "damper"
  actuator per DOF (site transmission at the origin, force ``-d_i (nu_i - nu_c,i)`` with the
  current's body-frame projection ``nu_c`` as its control) whose coefficient
  ``d_i = D_l,i + D_q,i |nu_r,i|`` :mod:`.physics` sets at the start of every control period
  from the relative velocity. This is the core's lagged-coefficient, linearly implicit damping
  (MuJoCo's ``implicitfast`` integrator treats an actuator's velocity term implicitly), so the
  linear and quadratic surge, sway, heave, roll, pitch and yaw damping of vehicles.yaml are
  reproduced per axis (exactly at the period's start; the coefficient lags within a period).
  MuJoCo's own fluid models are **not** used: on MuJoCo 4.0 the ellipsoid model's blunt
  drag acts along the velocity with a direction-dependent area, so an ellipsoid with REMUS's
  hull semi-axes (0.665, 0.095, 0.095 m) has 4.1x its axial drag at 5.7 deg angle of attack
  (14.5 -> 59.8 N at 1 m/s, blunt coefficient 0.5), and a proxy ellipsoid sized to REMUS's
  axial/cross-flow ratio (1.62 vs 131 N s2 m-2: semi-axes 2.57 x 0.032 x 0.032 m) slows a
  1.45 m/s run to 0.53 m/s within 2 s once a small pitch motion (0.007 rad/s) develops; the
  inertia-box model cannot be tuned per axis at all. Not modelled here: the hull lift of REMUS
  (``lift_coefficients``), the fin side forces (``Y_uudr``, ``Z_uuds``) and the Munk moments
  of the core's ``C(nu_r)`` (the MuJoCo torpedo is directionally stable, the core's is not);
* **actuators**: velocity servos on body axes (``general`` actuators, site transmission at the
  origin, force ``kv (ctrl - velocity)``, ``kv = (m + added mass) / T`` with ``T`` from
  ``velocity_time_constant_s``, ``forcerange`` = ``thrust_max`` per DOF); ROV: surge, sway,
  heave, roll, pitch, yaw; torpedo: surge (propeller) and the pitch and yaw moments of the
  stern planes and rudder, whose force ranges :mod:`.physics` sets every control period to
  ``|M_uuds| u_r^2 delta_max`` and ``|N_uudr| u_r^2 delta_max`` (no authority at rest). The
  four-thruster group capacity of the BlueROV2 (``thrust_coupling``) is approximated by its
  pure-axis box (combined demands can exceed the real group's capacity);
* **collisions**: a hull geom (capsule for a torpedo, box for the ROV; dimensions in
  :data:`HULL_GEOMETRY`) collides with the heightfield and the structures (``contype`` 2 /
  ``conaffinity`` 1 against 1 / 2); a ``contact`` sensor (``data="found"``) counts its contacts
  every MuJoCo step; ``actuatorfrc`` sensors record the servo forces. Vehicle-vehicle contacts
  are not simulated (one vehicle per model, so each vehicle has its own current; the tasks count
  near-collisions geometrically).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ...engine import dynamics as dyn
from ...errors import ConfigError
from ...engine import libm

__all__ = ["core_to_mj", "mj_to_core", "euler_to_matrix", "euler_to_quat", "quat_to_euler",
           "quat_to_matrix", "core_to_mj_velocity", "import_mujoco", "VehicleModel",
           "vehicle_model", "scene_xml", "build_model", "HULL_GEOMETRY", "BALLAST_FRACTION",
           "ACTUATORS", "DOF_NAMES"]

#: Share of the mass put in the ballast point that carries the restoring moment.
BALLAST_FRACTION = 0.2

#: Core DOF names in vehicles.yaml order.
DOF_NAMES = ("surge", "sway", "heave", "roll", "pitch", "yaw")

#: Hull shapes for collisions and rendering: ("capsule", length, diameter) or
#: ("box", length, width, height), metres. REMUS 100: 1.33 m x 0.19 m [P01]; BlueROV2 Heavy:
#: 0.457 x 0.575 x 0.254 m (Blue Robotics). Other vehicles: the equivalent inertia box.
HULL_GEOMETRY = {
    "remus100": ("capsule", 1.33, 0.19),
    "bluerov2_heavy": ("box", 0.457, 0.575, 0.254),
}

#: Actuators per guidance law: (name, core DOF index 0..5).
ACTUATORS = {
    "holonomic": (("surge", 0), ("sway", 1), ("heave", 2), ("roll", 3), ("pitch", 4),
                  ("yaw", 5)),
    "torpedo": (("surge", 0), ("pitch", 4), ("yaw", 5)),
}

def import_mujoco():
    """Import MuJoCo, defaulting ``MUJOCO_GL`` to ``egl`` first.

    Offscreen rendering needs the backend chosen before MuJoCo's first import in the process; an
    explicit setting wins.

    Returns
    -------
    module
        The ``mujoco`` module.
    """
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")
    import mujoco

    return mujoco


# core (north, east, down) -> MuJoCo (east, north, up); FLU -> FRD
_A = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
_B = np.diag([1.0, -1.0, -1.0])


# ----------------------------------------------------------------------------- frames


def core_to_mj(xyz) -> np.ndarray:
    """Core world positions to MuJoCo world positions.

    Parameters
    ----------
    xyz : array_like
        (..., 3) core positions ``(x east, y down, z north)``, m.

    Returns
    -------
    (..., 3) float64
        MuJoCo positions ``(x, y, z)`` = (east, north, up), m.
    """
    a = np.asarray(xyz, dtype=np.float64)
    return np.stack([a[..., 0], a[..., 2], -a[..., 1]], axis=-1)


def mj_to_core(xyz) -> np.ndarray:
    """MuJoCo world positions to core world positions.

    Parameters
    ----------
    xyz : array_like
        (..., 3) MuJoCo positions (east, north, up), m.

    Returns
    -------
    (..., 3) float64
        Core positions ``(x east, y down, z north)``, m.
    """
    a = np.asarray(xyz, dtype=np.float64)
    return np.stack([a[..., 0], -a[..., 2], a[..., 1]], axis=-1)


def euler_to_matrix(phi, theta, psi) -> np.ndarray:
    """MuJoCo body (FLU) to world (ENU) rotation matrices of core Euler angles.

    Parameters
    ----------
    phi, theta, psi : array_like
        Core roll, pitch (nose up) and yaw (compass heading), rad; broadcast together.

    Returns
    -------
    (..., 3, 3) float64
        ``R_mj = A R B`` (module docstring).
    """
    phi, theta, psi = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64)
                                            for a in (phi, theta, psi)))
    sf, cf = libm.sin(phi), libm.cos(phi)
    st, ct = libm.sin(theta), libm.cos(theta)
    sp, cp = libm.sin(psi), libm.cos(psi)
    r = np.empty(phi.shape + (3, 3))
    # Fossen zyx, rows (north, east, down)
    r00, r01, r02 = cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st
    r10, r11, r12 = sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf
    r20, r21, r22 = -st, ct * sf, ct * cf
    # R_mj = A R B
    r[..., 0, 0], r[..., 0, 1], r[..., 0, 2] = r10, -r11, -r12
    r[..., 1, 0], r[..., 1, 1], r[..., 1, 2] = r00, -r01, -r02
    r[..., 2, 0], r[..., 2, 1], r[..., 2, 2] = -r20, r21, r22
    return r


def _mat_to_quat(m: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z) (..., 4) of rotation matrices (..., 3, 3) (Shepperd),
    sign fixed to w >= 0."""
    m = np.asarray(m, dtype=np.float64)
    shp = m.shape[:-2]
    m = m.reshape(-1, 3, 3)
    q = np.empty((m.shape[0], 4))
    tr = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    diag = np.stack([tr, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1)
    k = np.argmax(diag, axis=1)
    a = m
    # Shepperd's four formulas, each where its diagonal term is the largest (vectorised)
    s = 2.0 * np.sqrt(np.maximum(np.stack([
        1.0 + tr, 1.0 + a[:, 0, 0] - a[:, 1, 1] - a[:, 2, 2],
        1.0 - a[:, 0, 0] + a[:, 1, 1] - a[:, 2, 2], 1.0 - a[:, 0, 0] - a[:, 1, 1] + a[:, 2, 2]],
        axis=1)[np.arange(m.shape[0]), k], 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        d21, d02, d10 = a[:, 2, 1] - a[:, 1, 2], a[:, 0, 2] - a[:, 2, 0], a[:, 1, 0] - a[:, 0, 1]
        s01, s02, s12 = a[:, 0, 1] + a[:, 1, 0], a[:, 0, 2] + a[:, 2, 0], a[:, 1, 2] + a[:, 2, 1]
        cand = np.stack([
            np.stack([0.25 * s, d21 / s, d02 / s, d10 / s], axis=1),
            np.stack([d21 / s, 0.25 * s, s01 / s, s02 / s], axis=1),
            np.stack([d02 / s, s01 / s, 0.25 * s, s12 / s], axis=1),
            np.stack([d10 / s, s02 / s, s12 / s, 0.25 * s], axis=1)], axis=1)
    q[:] = cand[np.arange(m.shape[0]), k]
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q.reshape(shp + (4,))


def euler_to_quat(phi, theta, psi) -> np.ndarray:
    """MuJoCo body quaternions of core Euler angles.

    Parameters
    ----------
    phi, theta, psi : array_like
        Core roll, pitch (nose up) and yaw (compass heading), rad; broadcast together.

    Returns
    -------
    (..., 4) float64
        Unit quaternions ``(w, x, y, z)``, ``w >= 0``.
    """
    return _mat_to_quat(euler_to_matrix(phi, theta, psi))


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrices of quaternions (normalised here).

    Parameters
    ----------
    q : array_like
        (..., 4) quaternions ``(w, x, y, z)``.

    Returns
    -------
    (..., 3, 3) float64
        Rotation matrices (MuJoCo body to world for a body quaternion).
    """
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    r = np.empty(q.shape[:-1] + (3, 3))
    r[..., 0, 0] = 1 - 2 * (y * y + z * z)
    r[..., 0, 1] = 2 * (x * y - w * z)
    r[..., 0, 2] = 2 * (x * z + w * y)
    r[..., 1, 0] = 2 * (x * y + w * z)
    r[..., 1, 1] = 1 - 2 * (x * x + z * z)
    r[..., 1, 2] = 2 * (y * z - w * x)
    r[..., 2, 0] = 2 * (x * z - w * y)
    r[..., 2, 1] = 2 * (y * z + w * x)
    r[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def quat_to_euler(q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Core Euler angles of MuJoCo body quaternions.

    Parameters
    ----------
    q : array_like
        (..., 4) MuJoCo body quaternions ``(w, x, y, z)``.

    Returns
    -------
    phi, theta, psi : ndarray
        Core roll, pitch and yaw (compass heading, in [-pi, pi]), rad, each of shape ``(...)``.
    """
    m = quat_to_matrix(q)
    # back to Fossen's R (rows north, east, down): r00 = M10, r10 = M00, r20 = -M20,
    # r21 = M21, r22 = M22
    phi = libm.arctan2(m[..., 2, 1], m[..., 2, 2])
    theta = libm.arcsin(np.clip(m[..., 2, 0], -1.0, 1.0))
    psi = libm.arctan2(m[..., 0, 0], m[..., 1, 0])
    return phi, theta, psi


def core_to_mj_velocity(rot: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Free-joint ``qvel`` from core body velocities.

    Parameters
    ----------
    rot : (..., 3, 3) float64
        MuJoCo body-to-world rotations (:func:`euler_to_matrix`).
    nu : array_like
        (..., 6) core body velocities ``(u, v, w, p, q, r)`` (FRD, over ground), m s-1 and
        rad s-1.

    Returns
    -------
    (..., 6) float64
        ``qvel``: world linear velocity (m s-1) and FLU body angular velocity (rad s-1).
    """
    nu = np.asarray(nu, dtype=np.float64)
    flu = nu * np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])
    out = np.empty(nu.shape)
    out[..., :3] = np.einsum("...ij,...j->...i", rot, flu[..., :3])
    out[..., 3:] = flu[..., 3:]
    return out


# ----------------------------------------------------------------------------- vehicle


class VehicleModel:
    """Rigid-body parameters of a vehicle in MuJoCo (derived from the core's vehicle spec).

    Parameters
    ----------
    vehicle : oneocean.engine.dynamics.Vehicle
        The core vehicle.

    Attributes
    ----------
    vehicle : oneocean.engine.dynamics.Vehicle
        The core vehicle.
    guidance : str
        ``"holonomic"`` or ``"torpedo"``.
    actuators : tuple of (name, dof)
        The velocity servos (:data:`ACTUATORS` of the guidance law).
    mass : float
        Rigid-body mass, kg.
    armature : (6,) float
        Added mass on the free joint's DOFs (world x, y, z: kg; body roll, pitch, yaw: kg m2).
    m_eff : (6,) float
        Mass + added mass per core DOF (surge, sway, heave, roll, pitch, yaw) as seen by the
        MuJoCo body (surge and sway: rigid mass + the horizontal armature).
    kv : (6,) float
        Velocity-servo gains ``m_eff / T`` (0 for unactuated DOFs), N s m-1 or N m s rad-1.
    damping_linear, damping_quadratic : (6,) float
        ``D_l``, ``D_q`` of vehicles.yaml (core DOF order).
    bg : float
        Metacentric height, m.

    Raises
    ------
    ConfigError
        If the roll/pitch inertia is too small for the metacentric height in the ballast model.
    """

    def __init__(self, vehicle):
        spec = vehicle.spec
        self.vehicle = vehicle
        self.name = vehicle.name
        p = vehicle.params
        self.guidance = dyn.GUIDANCE[int(p[dyn.P_GUIDE])]
        self.actuators = ACTUATORS[self.guidance]
        self.mass = float(spec["mass_kg"])
        self.inertia = np.asarray(spec["inertia_kg_m2"], dtype=np.float64)
        ma = np.asarray(spec["added_mass"], dtype=np.float64)
        self.added_mass = ma
        self.gravity = float(spec["gravity_ms2"])
        self.bg = float(spec["metacentric_height_m"])
        self.v_max = float(spec["speed_limit_ms"])
        horiz = 0.5 * (ma[0] + ma[1])
        self.armature = np.array([horiz, horiz, ma[2], ma[3], ma[4], ma[5]])
        self.m_eff = np.array([self.mass + horiz, self.mass + horiz, self.mass + ma[2],
                               self.inertia[0] + ma[3], self.inertia[1] + ma[4],
                               self.inertia[2] + ma[5]])
        tc = np.asarray(spec["velocity_time_constant_s"], dtype=np.float64)
        tmax = np.asarray(spec["thrust_max"], dtype=np.float64)
        self.thrust_max = tmax
        act = np.zeros(6, dtype=bool)
        for _, dof in self.actuators:
            act[dof] = True
        self.kv = np.where(act & (tc > 0), self.m_eff / np.where(tc > 0, tc, 1.0), 0.0)
        self.fin_q = float(p[dyn.P_FINQ])
        self.fin_r = float(p[dyn.P_FINR])
        self.damping_linear = np.asarray(spec["linear_damping"], dtype=np.float64)
        self.damping_quadratic = np.asarray(spec["quadratic_damping"], dtype=np.float64)
        # ballast
        f = BALLAST_FRACTION
        self.ballast_mass = f * self.mass
        self.ballast_depth = self.bg / f if self.bg > 0 else 0.0
        m1 = self.mass - self.ballast_mass
        off = m1 * self.bg ** 2 + self.ballast_mass * (self.ballast_depth - self.bg) ** 2
        self.hull_inertia = self.inertia - np.array([off, off, 0.0])
        if np.any(self.hull_inertia <= 0):
            raise ConfigError(f"vehicle '{self.name}': roll/pitch inertia too small for its "
                              "metacentric height in the ballast model")
        self.hull_mass = m1
        self.gravcomp = self.mass / m1
        self.geometry = HULL_GEOMETRY.get(self.name) or _inertia_box(self.mass, self.inertia)

    def servo_index(self, dof: int) -> int:
        """Actuator index of a core DOF.

        Parameters
        ----------
        dof : int
            Core DOF index, 0..5 (surge, sway, heave, roll, pitch, yaw).

        Returns
        -------
        int
            Index in :attr:`actuators`; -1 when the DOF is not actuated.
        """
        for k, (_, d) in enumerate(self.actuators):
            if d == dof:
                return k
        return -1


def _inertia_box(m: float, inertia: np.ndarray) -> tuple:
    ix, iy, iz = inertia
    a = math.sqrt(max(6.0 * (iy + iz - ix) / m, 1e-4))
    b = math.sqrt(max(6.0 * (ix + iz - iy) / m, 1e-4))
    c = math.sqrt(max(6.0 * (ix + iy - iz) / m, 1e-4))
    return ("box", a, b, c)


@lru_cache(maxsize=16)
def _vehicle_model_cached(name: str) -> VehicleModel:
    return VehicleModel(dyn.load_vehicle(name))


def vehicle_model(vehicle) -> VehicleModel:
    """A :class:`VehicleModel` from a vehicle name, a ``Vehicle`` or a ``VehicleModel``.

    Parameters
    ----------
    vehicle : str, Vehicle, VehicleModel or None
        Vehicle name in ``data/vehicles.yaml`` (None: the file's default), a core vehicle, or a
        model (returned as is).

    Returns
    -------
    VehicleModel
        The model; cached per name.
    """
    if isinstance(vehicle, VehicleModel):
        return vehicle
    if isinstance(vehicle, str) or vehicle is None:
        return _vehicle_model_cached(vehicle if vehicle is not None else
                                     dyn.load_vehicle().name)
    return VehicleModel(vehicle)


# ----------------------------------------------------------------------------- MJCF text


def _f(x: float) -> str:
    """Shortest round-trip text of a float (deterministic)."""
    x = float(x)
    if x == 0.0:
        return "0"
    return repr(x)


def _v(*xs) -> str:
    return " ".join(_f(x) for x in xs)


def _hull_geom(vm: VehicleModel, name: str, rgba: str, contact: bool) -> str:
    col = 'contype="2" conaffinity="1"' if contact else 'contype="0" conaffinity="0"'
    g = vm.geometry
    if g[0] == "capsule":
        half = 0.5 * g[1] - 0.5 * g[2]
        return (f'<geom name="{name}" type="capsule" fromto="{_v(-half, 0, 0, half, 0, 0)}" '
                f'size="{_f(0.5 * g[2])}" mass="0" {col} rgba="{rgba}" '
                f'fluidshape="none" condim="3" friction="0.5 0.005 0.0001"/>')
    return (f'<geom name="{name}" type="box" size="{_v(0.5 * g[1], 0.5 * g[2], 0.5 * g[3])}" '
            f'mass="0" {col} rgba="{rgba}" fluidshape="none" condim="3" '
            f'friction="0.5 0.005 0.0001"/>')


def _vehicle_body(vm: VehicleModel, tag: str, rgba: str, physics: bool) -> str:
    """The vehicle's body XML (free joint at the origin; pose set by the caller)."""
    lines = [f'<body name="vehicle{tag}" pos="0 0 0" gravcomp="{_f(vm.gravcomp)}">',
             f'  <freejoint name="vehicle{tag}_joint"/>',
             f'  <inertial pos="0 0 0" mass="{_f(vm.hull_mass)}" '
             f'diaginertia="{_v(*vm.hull_inertia)}"/>',
             "  " + _hull_geom(vm, f"hull{tag}", rgba, physics)]
    if vm.guidance == "torpedo":  # a visible fin cross at the tail
        g = vm.geometry
        tail = -0.5 * g[1] + 0.08
        lines.append(f'  <geom name="fins{tag}" type="box" pos="{_v(tail, 0, 0)}" '
                     f'size="{_v(0.05, 0.18, 0.005)}" mass="0" contype="0" conaffinity="0" '
                     f'rgba="0.2 0.2 0.2 1" fluidshape="none"/>')
        lines.append(f'  <geom name="rudder{tag}" type="box" pos="{_v(tail, 0, 0)}" '
                     f'size="{_v(0.05, 0.005, 0.18)}" mass="0" contype="0" conaffinity="0" '
                     f'rgba="0.2 0.2 0.2 1" fluidshape="none"/>')
    if physics:
        lines.append(f'  <site name="origin{tag}" pos="0 0 0" size="0.02"/>')
    if vm.ballast_depth > 0:
        lines.append(f'  <body name="ballast{tag}" pos="{_v(0, 0, -vm.ballast_depth)}">')
        lines.append(f'    <inertial pos="0 0 0" mass="{_f(vm.ballast_mass)}" '
                     'diaginertia="1e-06 1e-06 1e-06"/>')
        lines.append("  </body>")
    lines.append("</body>")
    return "\n".join(lines)


def _actuators(vm: VehicleModel) -> str:
    gears = {0: (1, 0, 0, 0, 0, 0), 1: (0, 1, 0, 0, 0, 0), 2: (0, 0, 1, 0, 0, 0),
             3: (0, 0, 0, 1, 0, 0), 4: (0, 0, 0, 0, 1, 0), 5: (0, 0, 0, 0, 0, 1)}
    out = []
    for name, dof in vm.actuators:
        kv = vm.kv[dof]
        if dof in (4, 5) and vm.guidance == "torpedo":
            # fins: capacity at the speed limit; :mod:`.physics` sets it from u_r^2 each period
            cap = (vm.fin_q if dof == 4 else vm.fin_r) * vm.v_max ** 2
        else:
            cap = vm.thrust_max[dof]
        out.append(f'<general name="{name}" site="origin" gear="{_v(*gears[dof])}" '
                   f'gaintype="fixed" gainprm="{_f(kv)}" biastype="affine" '
                   f'biasprm="{_v(0, 0, -kv)}" forcelimited="true" '
                   f'forcerange="{_v(-cap, cap)}"/>')
    v_ref = 0.5 * vm.v_max
    for dof, name in enumerate(DOF_NAMES):
        # initial coefficient at half the speed limit (rates: 0.5 rad/s); set every period
        ref = v_ref if dof < 3 else 0.5
        d = vm.damping_linear[dof] + vm.damping_quadratic[dof] * ref
        out.append(f'<general name="drag_{name}" site="origin" gear="{_v(*gears[dof])}" '
                   f'gaintype="fixed" gainprm="{_f(d)}" biastype="affine" '
                   f'biasprm="{_v(0, 0, -d)}"/>')
    return "\n".join(out)


#: Water seen from the camera: MuJoCo's linear fog from ``FOG_START_M`` to ``FOG_END_M`` of
#: range (visual only: no effect on the physics), in the water's blue-green.
FOG_START_M = 60.0
FOG_END_M = 600.0
FOG_RGBA = "0.05 0.28 0.32 1"


def _scene_static(scene) -> list[str]:
    """World-body XML lines of a scene: light, heightfield, surface, structures."""
    g = scene.grid_data
    x0, x1, z0, z1 = scene.extent
    cx, cy = 0.5 * (x0 + x1), 0.5 * (z0 + z1)
    elev = np.asarray(g["elevation"], dtype=np.float64)
    lo = float(elev.min())
    # blue-green light filtered by the water column (the fog in <visual> fades with range)
    lines = [f'<light name="sun" pos="{_v(cx, cy, 200)}" dir="0 0 -1" directional="true" '
             'diffuse="0.7 0.92 0.9" ambient="0.25 0.4 0.42" specular="0.1 0.15 0.15"/>',
             f'<geom name="seafloor" type="hfield" hfield="terrain" pos="{_v(cx, cy, lo)}" '
             'contype="1" conaffinity="2" material="sand" condim="3"/>',
             f'<geom name="surface" type="box" pos="{_v(cx, cy, 0)}" '
             f'size="{_v(0.5 * (x1 - x0), 0.5 * (z1 - z0), 0.001)}" contype="0" '
             'conaffinity="0" group="2" rgba="0.25 0.5 0.85 0.18"/>',
             f'<site name="world_ref" pos="{_v(cx, cy, 0)}" size="0.1"/>']
    for s in scene.structures:
        c = core_to_mj(np.array(s.centre))
        qz = (math.cos(-0.5 * s.yaw_rad), 0.0, 0.0, math.sin(-0.5 * s.yaw_rad))
        lines.append(f'<geom name="{s.name}" type="box" pos="{_v(*c)}" quat="{_v(*qz)}" '
                     f'size="{_v(s.half[0], s.half[2], s.half[1])}" contype="1" '
                     f'conaffinity="2" material="concrete" condim="3"/>')
    return lines


def _assets(scene) -> str:
    elev = np.asarray(scene.grid_data["elevation"], dtype=np.float64)
    ny, nx = elev.shape
    x0, x1, z0, z1 = scene.extent
    lo, hi = float(elev.min()), float(elev.max())
    span = max(hi - lo, 0.01)
    # MuJoCo's hfield rows run from +y (north) to -y: flip the grid's south-first rows
    rows = elev[::-1]
    data = "\n".join(" ".join(_f(v) for v in row) for row in rows)
    base = 1.0
    return "\n".join([
        '<texture name="sky" type="skybox" builtin="gradient" rgb1="0.12 0.42 0.45" '
        'rgb2="0.01 0.09 0.12" width="256" height="256"/>',
        # sand: a speckled texture (MuJoCo's fixed-seed random marks: the same pixels on
        # every build), not a checkerboard
        '<texture name="sandtex" type="2d" builtin="flat" rgb1="0.58 0.55 0.42" '
        'rgb2="0.58 0.55 0.42" mark="random" random="0.3" markrgb="0.3 0.3 0.22" '
        'width="64" height="64"/>',
        '<material name="sand" texture="sandtex" texrepeat="16 16" specular="0.05" '
        'shininess="0.1"/>',
        '<material name="concrete" rgba="0.6 0.6 0.58 1" specular="0.2"/>',
        f'<hfield name="terrain" nrow="{ny}" ncol="{nx}" '
        f'size="{_v(0.5 * (x1 - x0), 0.5 * (z1 - z0), span, base)}" elevation="\n{data}"/>',
    ])


def scene_xml(scene, vehicle=None, *, timestep: float = 0.02, n_vehicles: int | None = None,
              physics: bool = True) -> str:
    """MJCF text of a scene with one vehicle (or none, or ``n_vehicles`` for rendering).

    Parameters
    ----------
    scene : Scene
        The scene (:class:`oneocean.backends.mujoco.scenes.Scene`).
    vehicle : str, Vehicle or VehicleModel, optional
        The vehicle (default: none: the scene alone).
    timestep : float, default 0.02
        MuJoCo integration step, s.
    n_vehicles : int, optional
        Place this many copies of the vehicle (bodies ``vehicle0``, ``vehicle1``, ...; for
        rendering: no actuators or contacts).
    physics : bool, default True
        With one vehicle: include the actuators (servos, dampers) and the contact sensor.

    Returns
    -------
    str
        The MJCF; :func:`build_model` compiles it and applies the runtime-only settings
        (armature per DOF). Deterministic text.

    Raises
    ------
    ConfigError
        If ``timestep <= 0``.
    """
    if not timestep > 0:
        raise ConfigError(f"timestep: must be > 0, got {timestep!r}")
    vm = vehicle_model(vehicle) if vehicle is not None else None
    grav = vm.gravity if vm is not None else 9.81
    head = [f'<mujoco model="oneocean_{scene.name}">',
            f"<!-- {scene.label}; OneOcean scene '{scene.name}' ({scene.kind}). Frames: MuJoCo "
            "x = core x (east), y = core z (north), z = -core y (up). -->",
            '<compiler angle="radian" autolimits="true"/>',
            f'<option timestep="{_f(timestep)}" density="0" viscosity="0" '
            f'integrator="implicitfast" gravity="{_v(0, 0, -grav)}"/>',
            '<visual><global offwidth="1280" offheight="960"/>'
            f'<quality shadowsize="2048"/><map znear="0.01" zfar="5000" '
            f'fogstart="{_f(FOG_START_M)}" fogend="{_f(FOG_END_M)}" haze="0.6"/>'
            f'<rgba fog="{FOG_RGBA}" haze="{FOG_RGBA}"/></visual>',
            "<asset>", _assets(scene), "</asset>", "<worldbody>"]
    body = _scene_static(scene)
    tail = ["</worldbody>"]
    if vm is not None and n_vehicles is None:
        body.append(_vehicle_body(vm, "", "0.95 0.75 0.1 1", physics))
        if physics:
            tail += ["<actuator>", _actuators(vm), "</actuator>",
                     "<sensor>", '<contact name="contact" subtree1="vehicle" data="found"/>']
            tail += [f'<actuatorfrc name="force_{n}" actuator="{n}"/>' for n, _ in vm.actuators]
            tail.append("</sensor>")
    elif vm is not None:
        palette = ("0.95 0.75 0.1 1", "0.9 0.3 0.2 1", "0.2 0.8 0.4 1", "0.3 0.5 0.95 1",
                   "0.85 0.4 0.85 1", "0.1 0.85 0.85 1", "0.95 0.55 0.2 1", "0.6 0.6 0.9 1")
        for k in range(int(n_vehicles)):
            body.append(_vehicle_body(vm, str(k), palette[k % len(palette)], False))
    tail.append("</mujoco>")
    return "\n".join(head + body + tail) + "\n"


def build_model(scene, vehicle, *, timestep: float = 0.02):
    """Compile the one-vehicle model of a scene and apply the runtime-only settings.

    The free joint's ``dof_armature`` gets the added mass (:attr:`VehicleModel.armature`).

    Parameters
    ----------
    scene : Scene
        The scene (:class:`oneocean.backends.mujoco.scenes.Scene`).
    vehicle : str, Vehicle or VehicleModel
        The vehicle (:func:`vehicle_model`).
    timestep : float, default 0.02
        MuJoCo integration step, s.

    Returns
    -------
    model : mujoco.MjModel
        The compiled model.
    vm : VehicleModel
        The vehicle's MuJoCo parameters.
    """
    mujoco = import_mujoco()
    vm = vehicle_model(vehicle)
    model = mujoco.MjModel.from_xml_string(scene_xml(scene, vm, timestep=timestep))
    jnt = model.joint("vehicle_joint")
    adr = int(jnt.dofadr[0])
    model.dof_armature[adr:adr + 6] = vm.armature
    return model, vm
