"""Physical parameters of the UVDMS: the one typed, documented place for every number of the model.

Sources are given per value: ``[T1]`` paper Table 1, ``[T2]`` paper Table 2, ``[S4]`` paper Section 4 text,
``[MODEL]`` ``docs/MODEL.md``, ``[D]`` a project decision recorded here with its reason.

Frames (see :mod:`uvdms_gym.physics.frames`): body frame FRD (x forward, y starboard/right, z down) with its
origin at the vehicle's geometric centre; inertial frame NED. All values SI, angles in radians.

Everything here is a frozen dataclass; use :func:`dataclasses.replace` to derive a perturbed model
(e.g. for hydrodynamic randomisation or the controller's deliberately imperfect nominal model).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

GRAVITY = 9.81
"""Gravitational acceleration, m/s^2 [D]."""


def _arr(*values: float) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


@dataclass(frozen=True)
class VehicleParams:
    """Vehicle hull: rigid-body, hydrodynamic and hydrostatic parameters (body frame FRD, at the origin)."""

    size: tuple[float, float, float] = _arr(0.92, 0.62, 0.56)
    """Length x width x height of the envelope, m [T1]."""
    mass: float = 106.0
    """Rigid-body mass, kg [T1], [S4] ``M_RB``."""
    inertia: tuple[float, float, float] = _arr(9.5, 10.2, 12.0)
    """Principal moments of inertia about the centre of gravity, kg m^2 [S4] ``M_RB`` diagonal."""
    added_mass: tuple[float, ...] = _arr(63.0, 32.2, 31.3, 5.6, 3.7, 3.4)
    """Added mass ``M_A = diag(X_udot, Y_vdot, Z_wdot, K_pdot, M_qdot, N_rdot)`` (positive), kg / kg m^2 [S4]."""
    linear_damping: tuple[float, ...] = _arr(110.0, 90.0, 140.0, 20.0, 13.0, 17.0)
    """Linear damping coefficients of ``D(nu)`` [S4]."""
    quadratic_damping: tuple[float, ...] = _arr(90.0, 90.0, 110.0, 8.0, 10.0, 12.0)
    """Quadratic damping coefficients of ``D(nu)`` (multiplied by ``|nu_i|``) [S4]."""
    buoyancy: float = 1058.0
    """Buoyancy force of the hull, N [T1]. Weight is ``mass * g = 1039.9 N``: 18.1 N positively buoyant."""
    r_g: tuple[float, float, float] = _arr(0.0, 0.0, 0.1)
    """Centre of gravity in body frame, m [T1]; [D] below the origin (z down positive)."""
    r_b: tuple[float, float, float] = _arr(0.0, 0.0, -0.1)
    """Centre of buoyancy in body frame, m [T1]; [D] above the origin (the paper prints both without sign)."""

    @property
    def weight(self) -> float:
        """Hull weight ``m g``, N."""
        return self.mass * GRAVITY

    @property
    def rigid_added_mass(self) -> float:
        """Isotropic part of the translational added mass, kg.

        [D] The part ``min(X_udot, Y_vdot, Z_wdot)`` of the added mass and the whole rotational added
        inertia are simulated exactly as a rigid virtual body at the origin (a point mass with inertia
        ``diag(K_pdot, M_qdot, N_rdot)``): its rigid-body dynamics equal Fossen's ``M_A nudot + C_A(nu) nu``
        for that part, with no acceleration feedback and so no added-mass instability. Its weight is
        cancelled by an equal upward force. Only the anisotropic remainder (see
        :attr:`residual_added_mass`) is applied as an external force with a lagged acceleration.
        """
        return float(min(self.added_mass[:3]))

    @property
    def residual_added_mass(self) -> tuple[float, ...]:
        """Added mass not represented by the virtual rigid body: ``M_A - diag(m_a, m_a, m_a, K, M, N)``."""
        ma = self.rigid_added_mass
        return (*(a - ma for a in self.added_mass[:3]), 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ArmParams:
    """One 6-DOF manipulator (left and right are identical, see ``frame0_axes``).

    Standard DH with all ``a_i = 0`` [T2]. Physical link ``i`` (``i = 0`` is the fixed base shell)
    is a capsule of radius :attr:`link_radius` whose axis lies on the DH ``z`` axes; the DH offsets
    ``d_1 = 0.193 = 0.116 + 0.077``, ``d_3 = d_5 = 0.2805 = 0.0805 + 0.2`` are split between
    consecutive links exactly as the link lengths of Table 2 say, and link 6 carries the tool: the
    end effector sits 0.19 m along ``z_6`` [D].
    """

    dh_alpha: tuple[float, ...] = _arr(*(math.radians(a) for a in (90, -90, 90, -90, 90, -90, 90)))
    """DH ``alpha_i`` for rows 0 (fixed base) .. 6, rad [T2]."""
    dh_d: tuple[float, ...] = _arr(0.0, 0.193, 0.0, 0.2805, 0.0, 0.2805, 0.0)
    """DH ``d_i`` for rows 0 .. 6, m [T2]."""
    link_length: tuple[float, ...] = _arr(0.116, 0.077, 0.0805, 0.2, 0.0805, 0.2, 0.19)
    """Length of links 0 .. 6, m [T2]."""
    link_mass: tuple[float, ...] = _arr(2.8, 1.3, 1.2, 1.6, 1.2, 1.6, 1.5)
    """Mass of links 0 .. 6, kg [T2]."""
    link_radius: float = 0.025
    """Capsule radius of every link, m [MODEL]: two links touch when their axes are 0.05 m apart."""
    frame0_axes: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 1.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0))
    """Axes ``(x_0, y_0, z_0)`` of DH frame 0 in body coordinates [D].

    ``z_0`` = body ``x``: the arm points forward at ``q = 0``; ``x_0`` = body ``z`` (down), so joints 2, 4, 6
    pitch about the body ``-y`` axis at ``q = 0`` and a positive pitch-joint angle swings the arm down.
    Both arms use the same mount orientation (translated copies, not mirror images): then equal joint
    angles with the roll joints 1, 3, 5 at zero (both arms moving in the vehicle's x-z plane, the end
    effectors turning only about the object's axis) keep a rigidly gripped object consistent, as in the
    paper's transport run; in general the closed-chain equality constraint is what holds. Mirror-symmetric
    motion of the two arms negates the roll joints 1, 3, 5 and keeps the pitch joints 2, 4, 6.
    """
    q_min: tuple[float, ...] = _arr(*(math.radians(a) for a in (-170, -120, -170, -120, -170, -120)))
    """Lower joint limits, rad [D]: roll joints 1, 3, 5 +-170 deg, pitch joints 2, 4, 6 +-120 deg."""
    q_max: tuple[float, ...] = _arr(*(math.radians(a) for a in (170, 120, 170, 120, 170, 120)))
    """Upper joint limits, rad [D]."""
    qdot_max: tuple[float, ...] = _arr(1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    """Joint speed limits, rad/s [D] (typical of electric underwater manipulators)."""
    tau_max: tuple[float, ...] = _arr(60.0, 60.0, 40.0, 40.0, 20.0, 20.0)
    """Joint torque saturation, N m [D]: about 1.5x the worst static gravity load of the outstretched arm."""
    rotor_inertia: float = 0.1
    """Reflected rotor inertia of each joint's drive about its axis, kg m^2 [D] (a motor rotor of ~1e-5 kg m^2
    behind a ~100:1 gear, typical of electric underwater arms). PyBullet has no joint armature, so it is added
    to the driven link as a disk on the joint axis: ``J`` about the axis, ``J/2`` about the transverse axes
    (the URDF inertia, shared by PyBullet and Pinocchio; a bare ``izz`` bump breaks the triangle inequality
    and PyBullet silently zeroes such an inertia).
    Without it a straight arm's roll joints (axial inertia ~5e-4 kg m^2) reach 100 rad/s in one 0.01 s step
    under their torque limit."""
    joint_friction: float = 2.0
    """Viscous friction of each joint's gear train, N m s/rad [D] (PyBullet ``jointDamping``): bounds the joint
    rates a torque command can reach (``tau_max / joint_friction``); explicit integration is stable since
    ``joint_friction * dt / rotor_inertia = 0.2``."""
    drag_coefficient: float = 1.0
    """Cross-flow drag coefficient of a link (Morison, circular cylinder, Re ~ 1e4-1e5) [D]."""
    axial_drag_coefficient: float = 0.1
    """Axial (skin-friction) drag coefficient of a link, on the end-cap area [D]."""

    @property
    def frame0_rotation(self) -> np.ndarray:
        """Rotation matrix body <- DH frame 0 (columns ``x_0, y_0, z_0``)."""
        return np.array(self.frame0_axes, dtype=float).T

    @property
    def n_links(self) -> int:
        """Number of physical links including the fixed base shell (7)."""
        return len(self.link_length)

    def link_volume(self, i: int) -> float:
        """Displaced volume of link ``i``, m^3.

        [D] A cylinder of the link's length: the hemispherical caps of the capsules overlap the
        neighbouring links at the joints, so counting them would count that water twice.
        """
        return math.pi * self.link_radius**2 * self.link_length[i]


@dataclass(frozen=True)
class ObjectParams:
    """The gripped cylinder of the transport task [S4]."""

    length: float = 0.6
    """Cylinder length, m [S4]."""
    radius: float = 0.05
    """Cylinder radius, m [S4]."""
    density: float = 1100.0
    """Material density, kg/m^3 [S4] (1.1 g/cm^3)."""
    added_mass_coefficient: float = 1.0
    """Cross-flow added-mass coefficient ``C_a`` (slender circular cylinder, potential flow) [D]."""
    drag_coefficient: float = 1.0
    """Cross-flow drag coefficient [D]."""
    axial_drag_coefficient: float = 0.1
    """Axial drag coefficient on the end-cap area [D]."""

    @property
    def volume(self) -> float:
        """Displaced volume, m^3."""
        return math.pi * self.radius**2 * self.length

    @property
    def mass(self) -> float:
        """Mass, kg (5.18 kg)."""
        return self.density * self.volume


@dataclass(frozen=True)
class FramePlate:
    """A planar obstacle of the vehicle's outer frame, rigidly attached to the body.

    The plate is the rectangle ``center + s * u + t * v`` with ``|s| <= half_extents[0]``,
    ``|t| <= half_extents[1]``; ``u`` and ``v`` are unit, orthogonal, in body coordinates. Its physical
    (PyBullet) shape is that rectangle swept by a ball of radius ``thickness / 2``: a box of the rectangle and
    :attr:`thickness` plus capsules along its four edges (``model._plate_edges``), so that a link touches it
    exactly when its axis is ``link_radius + thickness / 2`` from the rectangle, edges included.
    """

    name: str
    center: tuple[float, float, float]
    u: tuple[float, float, float]
    v: tuple[float, float, float]
    half_extents: tuple[float, float]
    thickness: float = 0.004

    @property
    def normal(self) -> np.ndarray:
        """Unit normal ``u x v`` in body coordinates."""
        return np.cross(np.asarray(self.u), np.asarray(self.v))


def _default_plates() -> tuple[FramePlate, ...]:
    # [D] Placement is a design parameter (docs/MODEL.md section 2). The arms live in a bay at the front bottom
    # of the vehicle; the side plates cover the rear of the bay beside the shoulders and elbows, the bottom
    # plate closes the bay below, and the front plate is a bumper bar across the lower front edge.
    # Plates are separated by gaps (touching plates make every PyBullet step with self-collision on about 15x
    # slower, measured).
    x, y, z = 1.0, 1.0, 1.0
    return (
        FramePlate("front", (0.62, 0.0, 0.30), (0.0, y, 0.0), (0.0, 0.0, z), (0.30, 0.04)),
        FramePlate("left", (0.12, -0.36, 0.12), (x, 0.0, 0.0), (0.0, 0.0, z), (0.22, 0.16)),
        FramePlate("right", (0.12, 0.36, 0.12), (x, 0.0, 0.0), (0.0, 0.0, z), (0.22, 0.16)),
        FramePlate("bottom", (0.20, 0.0, 0.40), (x, 0.0, 0.0), (0.0, y, 0.0), (0.30, 0.30)),
    )


@dataclass(frozen=True)
class VehicleActuation:
    """Saturation of the vehicle's generalized force ``tau_v`` (body frame) [D]."""

    tau_max: tuple[float, ...] = _arr(500.0, 500.0, 500.0, 150.0, 150.0, 150.0)
    """|force| limits N (surge, sway, heave) and |moment| limits N m (roll, pitch, yaw) [D]:
    enough to carry the ~165 N net weight with margin and to hold roll/pitch against the arms' moments."""
    nu_max: tuple[float, ...] = _arr(0.5, 0.5, 0.5, 0.5, 0.5, 0.5)
    """Vehicle velocity box used by controllers and the velocity action mode, m/s and rad/s [D]."""


@dataclass(frozen=True)
class UVDMSParams:
    """The whole system: vehicle, two arms, frame plates, object, water."""

    vehicle: VehicleParams = field(default_factory=VehicleParams)
    arm: ArmParams = field(default_factory=ArmParams)
    obj: ObjectParams = field(default_factory=ObjectParams)
    actuation: VehicleActuation = field(default_factory=VehicleActuation)
    plates: tuple[FramePlate, ...] = field(default_factory=_default_plates)
    arm_base_right: tuple[float, float, float] = _arr(0.2, 0.2, 0.1)
    """Right arm mount position in body frame, m [T1] ``T_Br``."""
    arm_base_left: tuple[float, float, float] = _arr(0.2, -0.2, 0.1)
    """Left arm mount position in body frame, m [T1] ``T_Bl``; [D] mirror of the right (the paper prints no sign)."""
    water_density: float = 1000.0
    """Water density, kg/m^3 [D] (fresh water, as the paper's buoyancy figures imply)."""

    @property
    def tau_max(self) -> np.ndarray:
        """The 18 generalized-force limits ``[tau_v (6); tau_q left (6); tau_q right (6)]``."""
        return np.array(self.actuation.tau_max + self.arm.tau_max + self.arm.tau_max)

    @property
    def q_min(self) -> np.ndarray:
        """Lower joint limits of both arms ``[left; right]`` (12)."""
        return np.array(self.arm.q_min * 2)

    @property
    def q_max(self) -> np.ndarray:
        """Upper joint limits of both arms ``[left; right]`` (12)."""
        return np.array(self.arm.q_max * 2)

    @property
    def zeta_max(self) -> np.ndarray:
        """Velocity bounds of ``zeta = [nu; qdot_l; qdot_r]`` (18)."""
        return np.array(self.actuation.nu_max + self.arm.qdot_max + self.arm.qdot_max)

    def arm_mass(self) -> float:
        """Mass of one arm, kg."""
        return float(sum(self.arm.link_mass))

    def arm_buoyancy(self) -> float:
        """Buoyancy of one arm (all its link volumes), N."""
        return self.water_density * GRAVITY * sum(self.arm.link_volume(i) for i in range(self.arm.n_links))

    def net_vertical_force(self, with_object: bool = False) -> float:
        """Net hydrostatic force on the whole system at rest, N, positive **up** (buoyant).

        Bare vehicle: +18.1 N. With both arms: about -165 N (the system sinks; heave control carries it).
        """
        f = self.vehicle.buoyancy - self.vehicle.weight
        f += 2.0 * (self.arm_buoyancy() - self.arm_mass() * GRAVITY)
        if with_object:
            f += (self.water_density - self.obj.density) * self.obj.volume * GRAVITY
        return f


# Standard joint names, in the order of ``q = [q_l; q_r]`` (docs/MODEL.md section 1).
ARM_SIDES: tuple[str, str] = ("left", "right")
JOINT_NAMES: tuple[str, ...] = tuple(f"{s}_joint{i}" for s in ARM_SIDES for i in range(1, 7))
N_JOINTS = 12
N_DOF = 18

D1 = 0.05
"""Collision-zone threshold d1 of docs/MODEL.md section 4 (m): a distance below it is in the collision zone
(``info["cost_zone"]``; the velocity damper's bound reaches zero there). The one definition: the environments,
the MPC defaults, the distance kernels, the leaderboard plots and ``uvdms reproduce`` import it."""
D2 = 0.12
"""Anti-collision-zone threshold d2 of docs/MODEL.md section 4 (m): the velocity damper acts below it."""

# Initial joint angles of the collision tasks [S4], with the signs fixed by the project [D] so that the
# initial configuration is collision-free and mirror-symmetric motion negates roll joints 1, 3, 5. With these
# signs the shoulder pitches up, elbow and wrist down: both end effectors start about 0.8 m ahead of their
# bases, slightly above them, with 0.26 m between the arms and 0.16 m to the nearest frame plate (the
# all-positive choice curls both arms down through the bottom plate).
CIRCLE_Q0_LEFT_DEG: tuple[float, ...] = (-10.0, -50.0, -15.0, 50.0, -15.0, 10.0)
CIRCLE_Q0_RIGHT_DEG: tuple[float, ...] = (20.0, -60.0, 20.0, 55.0, 20.0, 25.0)


@dataclass(frozen=True)
class GripperParams:
    """The friction grasp's gripper and contact [D] (``grasp="friction"``, :mod:`uvdms_gym.physics.grip`).

    Each hand closes jaws that conform to the cylinder: the jaws' shape holds the object against every relative
    motion but two, sliding along its axis and turning about it, which only friction resists. Each hand's contact
    is a uniformly pressed band of the cylinder's surface, so its limit surface is the ellipse
    ``(f / (mu F))^2 + (m / (mu r_t F))^2 <= 1`` in the axial force ``f`` and the twisting moment ``m`` it
    transmits (``F``: the grip force; ``r_t``: the torsional radius, the object's radius for a band on its
    surface). ``mu`` absorbs the jaws' wedge factor: the axial capacity is ``mu F``.
    """

    mu: float = 0.5
    """Effective friction coefficient of each hand (rubber pads on a wet plastic pipe, 0.4-0.6) [D]."""
    torsion_radius: float = 0.05
    """Torsional radius ``r_t`` of each hand's contact band, m (the object's radius) [D]."""
    grip_max: float = 300.0
    """Largest grip force a gripper can command, N (underwater parallel-jaw grippers: 200-600 N) [D]."""
    crush_force: float = 200.0
    """Squeeze limit of the object: a grip force above it crushes the object (the episode ends), N [D]."""
    drop_slip: float = 0.05
    """Axial slip at which a hand has lost the object (the band leaves its 0.1 m of pipe beyond the hand), m [D]."""
    grip_initial: float = 40.0
    """Grip force of both hands at reset, N [D] (about four times what holding the object still needs)."""
