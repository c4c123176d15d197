"""URDF of the UVDMS generated from :mod:`uvdms_gym.physics.params`: the single source for PyBullet and Pinocchio.

Structure (link names)::

    vehicle (base, hull inertia at r_G; visual box, no collision shape)
    ├── added_mass            fixed, virtual rigid body carrying the isotropic added mass (see params)
    ├── plate_{front,left,right,bottom}   fixed, the frame obstacles: box + 4 edge capsules (rounded edges)
    └── {left,right}_link0    fixed arm base shell at T_B{l,r}
        └── {side}_link1 .. {side}_link6   revolute joints {side}_joint1 .. {side}_joint6 (DH, a_i = 0)
            └── {side}_ee (fixed, tool tip)  and  {side}_grasp (fixed, the gripped object's frame)

Link frame convention: URDF link ``i`` has the frame ``F_{i-1} Rz(q_i)`` (DH frame ``i-1`` turned by its
joint), so joint ``i+1`` sits at ``Tz(d_i) Rx(alpha_i)`` in link ``i``. Each physical link is a capsule
whose axis is the segment returned by :func:`link_segment`. Inertias are those of solid cylinders of the
link's mass, length and radius, written in the link frame (all diagonal), and are loaded as written
(PyBullet flag ``URDF_USE_INERTIA_FROM_FILE``).
"""

from __future__ import annotations

import hashlib
import math
import os
import threading
from functools import lru_cache
from pathlib import Path

import numpy as np

from uvdms_gym.physics.params import ARM_SIDES, FramePlate, UVDMSParams
from uvdms_gym.utils.tempdirs import owned_tempdir

TINY_MASS = 1e-4
"""Mass of frame-only links (PyBullet gives a link without ``<inertial>`` 1 kg)."""
TINY_INERTIA = 1e-8


def rx(a: float) -> np.ndarray:
    """Rotation about x."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rz(a: float) -> np.ndarray:
    """Rotation about z."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_to_rpy(r: np.ndarray) -> tuple[float, float, float]:
    """URDF ``rpy`` (R = Rz(y) Ry(p) Rx(r)) of a rotation matrix, robust at gimbal lock."""
    if abs(r[2, 0]) < 1.0 - 1e-12:
        pitch = -math.asin(r[2, 0])
        roll = math.atan2(r[2, 1], r[2, 2])
        yaw = math.atan2(r[1, 0], r[0, 0])
    elif r[2, 0] < 0.0:  # pitch = +pi/2
        pitch, yaw = math.pi / 2, 0.0
        roll = math.atan2(r[0, 1], r[0, 2])
    else:  # pitch = -pi/2
        pitch, yaw = -math.pi / 2, 0.0
        roll = math.atan2(-r[0, 1], -r[0, 2])
    return roll, pitch, yaw


def mount_rotation(params: UVDMSParams) -> np.ndarray:
    """Rotation body <- arm link-0 frame: DH frame 0 is ``link0 * Rx(alpha_0)``."""
    return params.arm.frame0_rotation @ rx(params.arm.dh_alpha[0]).T


def link_axis(params: UVDMSParams, i: int) -> np.ndarray:
    """Unit direction of link ``i``'s axis in its own link frame."""
    if i % 2 == 1:  # roll links lie on their own joint axis (z of the link frame)
        return np.array([0.0, 0.0, 1.0])
    return rx(params.arm.dh_alpha[i]) @ np.array([0.0, 0.0, 1.0])  # along DH z_i


def link_segment(params: UVDMSParams, i: int) -> tuple[np.ndarray, np.ndarray]:
    """End points ``(A, B)`` of link ``i``'s capsule axis in the link frame (B is farther from the base)."""
    length = params.arm.link_length[i]
    axis = link_axis(params, i)
    if i % 2 == 1:
        d = params.arm.dh_d[i]
        return (d - length) * axis, d * axis
    return np.zeros(3), length * axis


def ee_offset(params: UVDMSParams) -> tuple[np.ndarray, np.ndarray]:
    """Tool-tip frame in link 6: position and rotation (``F_6 Tz(L_6)``)."""
    r = rx(params.arm.dh_alpha[6])
    return r @ np.array([0.0, 0.0, params.arm.link_length[6]]), r


def grasp_offset(params: UVDMSParams, side: str) -> tuple[np.ndarray, np.ndarray]:
    """The gripped object's frame in ``{side}_ee``: position and rotation.

    [D] Defined at ``q = 0`` (both arms straight ahead): the object centre is midway between the two end
    effectors, its axes aligned with the body axes, so its axis (object ``y``) joins the two grippers. Both
    arms then hold it with the same joint angles.
    """
    r0 = params.arm.frame0_rotation  # EE orientation in body at q = 0 equals DH frame 0
    base = np.array(params.arm_base_left if side == "left" else params.arm_base_right)
    mid = 0.5 * (np.array(params.arm_base_left) + np.array(params.arm_base_right))
    return r0.T @ (mid - base), r0.T


def _fmt(v) -> str:
    return " ".join(f"{float(x):.12g}" for x in v)


def _inertial(mass: float, xyz, diag) -> str:
    ixx, iyy, izz = diag
    return (
        f'<inertial><origin xyz="{_fmt(xyz)}" rpy="0 0 0"/><mass value="{mass:.12g}"/>'
        f'<inertia ixx="{ixx:.12g}" ixy="0" ixz="0" iyy="{iyy:.12g}" iyz="0" izz="{izz:.12g}"/></inertial>'
    )


def _tiny_link(name: str) -> str:
    return f'<link name="{name}">{_inertial(TINY_MASS, (0, 0, 0), (TINY_INERTIA,) * 3)}</link>'


def _fixed(name: str, parent: str, child: str, xyz, rpy) -> str:
    return (
        f'<joint name="{name}" type="fixed"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/></joint>'
    )


def _cylinder_inertia(mass: float, radius: float, length: float, axis: np.ndarray) -> tuple[float, ...]:
    axial = 0.5 * mass * radius**2
    transverse = mass * (3.0 * radius**2 + length**2) / 12.0
    return tuple(axial if abs(a) > 0.5 else transverse for a in axis)


def _plate_edges(plate) -> str:
    """Collision capsules of radius ``t/2`` along the four edges of a plate (in the plate's frame).

    Box plus edge capsules is exactly the plate's mid-surface rectangle swept by a ball of radius ``t/2``,
    so a capsule link touches the plate exactly when its axis is ``r + t/2`` from the rectangle, also beside
    the edges (a bare box touches there at ``r``; measured in ``tests/uvdms_gym/distances/test_distances.py``).
    """
    hx, hy = plate.half_extents
    rho = 0.5 * plate.thickness
    out = []
    for xyz, rpy, length in (
        ((0.0, hy, 0.0), (0.0, math.pi / 2, 0.0), 2 * hx),
        ((0.0, -hy, 0.0), (0.0, math.pi / 2, 0.0), 2 * hx),
        ((hx, 0.0, 0.0), (math.pi / 2, 0.0, 0.0), 2 * hy),
        ((-hx, 0.0, 0.0), (math.pi / 2, 0.0, 0.0), 2 * hy),
    ):
        out.append(
            f'<collision><origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>'
            f'<geometry><capsule radius="{rho:.12g}" length="{length:.12g}"/></geometry></collision>'
        )
    return "".join(out)


def _plate_parts(plate: FramePlate, shapes: bool) -> list[str]:
    """The link of a frame plate and its fixed joint to the vehicle (URDF elements)."""
    parts = []
    u, w, n = np.array(plate.u), np.array(plate.v), plate.normal
    rot = np.column_stack([u, w, n])
    size = (2 * plate.half_extents[0], 2 * plate.half_extents[1], plate.thickness)
    geom = f'<geometry><box size="{_fmt(size)}"/></geometry>'
    edges = _plate_edges(plate) if shapes else ""  # Pinocchio's URDF parser rejects capsules
    parts.append(
        f'<link name="plate_{plate.name}">{_inertial(TINY_MASS, (0, 0, 0), (TINY_INERTIA,) * 3)}'
        f'<visual><origin xyz="0 0 0" rpy="0 0 0"/>{geom}<material name="plate"/></visual>'
        f'<collision><origin xyz="0 0 0" rpy="0 0 0"/>{geom}</collision>{edges}</link>'
    )
    parts.append(_fixed(f"plate_{plate.name}_joint", "vehicle", f"plate_{plate.name}", plate.center, rot_to_rpy(rot)))
    return parts


def _arm_parts(params: UVDMSParams, side: str, shapes: bool) -> list[str]:
    """The links and joints of one arm, its end-effector and grasp frames (URDF elements)."""
    parts = []
    arm = params.arm
    mount_rpy = rot_to_rpy(mount_rotation(params))
    base = params.arm_base_left if side == "left" else params.arm_base_right
    for i in range(arm.n_links):
        a, b = link_segment(params, i)
        axis = link_axis(params, i)
        mid = 0.5 * (a + b)
        inertia = _cylinder_inertia(arm.link_mass[i], arm.link_radius, arm.link_length[i], axis)
        if i > 0:  # the drive's rotor (a disk on the joint axis, link-frame z): J about z, J/2 transverse
            j_rot = arm.rotor_inertia  # (a physical tensor: PyBullet zeroes one that breaks the triangle rule)
            inertia = (inertia[0] + 0.5 * j_rot, inertia[1] + 0.5 * j_rot, inertia[2] + j_rot)
        # PyBullet's capsule (and cylinder) lies along the local z axis of its origin.
        cap_rpy = (0.0, 0.0, 0.0) if abs(axis[2]) > 0.5 else (math.copysign(math.pi / 2, -axis[1]), 0.0, 0.0)
        geom = f'<geometry><capsule radius="{arm.link_radius:.12g}" length="{arm.link_length[i]:.12g}"/></geometry>'
        shape = (
            f'<visual><origin xyz="{_fmt(mid)}" rpy="{_fmt(cap_rpy)}"/>{geom}<material name="arm"/></visual>'
            f'<collision><origin xyz="{_fmt(mid)}" rpy="{_fmt(cap_rpy)}"/>{geom}</collision>'
        )
        inertial = _inertial(arm.link_mass[i], mid, inertia)
        parts.append(f'<link name="{side}_link{i}">{inertial}{shape if shapes else ""}</link>')
        if i == 0:
            parts.append(_fixed(f"{side}_mount", "vehicle", f"{side}_link0", base, mount_rpy))
        else:
            lo, hi = arm.q_min[i - 1], arm.q_max[i - 1]
            parts.append(
                f'<joint name="{side}_joint{i}" type="revolute"><parent link="{side}_link{i - 1}"/>'
                f'<child link="{side}_link{i}"/>'
                f'<origin xyz="0 0 {arm.dh_d[i - 1]:.12g}" rpy="{arm.dh_alpha[i - 1]:.12g} 0 0"/>'
                f'<axis xyz="0 0 1"/><limit lower="{lo:.12g}" upper="{hi:.12g}" '
                f'effort="{arm.tau_max[i - 1]:.12g}" velocity="{arm.qdot_max[i - 1]:.12g}"/>'
                f'<dynamics damping="{arm.joint_friction:.12g}" friction="0"/></joint>'
            )
    p_ee, r_ee = ee_offset(params)
    parts.append(_tiny_link(f"{side}_ee"))
    parts.append(_fixed(f"{side}_ee_joint", f"{side}_link6", f"{side}_ee", p_ee, rot_to_rpy(r_ee)))
    p_g, r_g = grasp_offset(params, side)
    parts.append(_tiny_link(f"{side}_grasp"))
    parts.append(_fixed(f"{side}_grasp_joint", f"{side}_ee", f"{side}_grasp", p_g, rot_to_rpy(r_g)))
    return parts


def build_urdf(
    params: UVDMSParams,
    *,
    virtual_added_mass: bool = True,
    shapes: bool = True,
    arms: bool = True,
    hull_collision: bool = False,
) -> str:
    """URDF text of the vehicle, frame plates and both arms.

    Args:
        params: the physical parameters.
        virtual_added_mass: include the ``added_mass`` link (the isotropic added mass as a rigid body at
            the origin). The simulator always includes it; a bare rigid-body model omits it.
        shapes: include visual and collision shapes (Pinocchio's parser cannot read capsules, so the
            kinematic model is built without them; distances are computed analytically).
        arms: include both arms (``False``: the bare vehicle with its frame plates, used by the
            simulator's hydrostatics and 1-DOF hydrodynamics tests).
        hull_collision: give the hull a collision box of its visual size (outer obstacles collide with it; the
            robot's own links never do, self-collision being off).
    """
    v = params.vehicle
    hull_box = f'<geometry><box size="{_fmt(v.size)}"/></geometry>'
    hull_col = f'<collision><origin xyz="0 0 0" rpy="0 0 0"/>{hull_box}</collision>' if hull_collision else ""
    parts = [
        '<?xml version="1.0"?>',
        '<robot name="uvdms">',
        '<material name="hull"><color rgba="1 0.8 0.1 0.35"/></material>',
        '<material name="arm"><color rgba="0.3 0.3 0.35 1"/></material>',
        '<material name="plate"><color rgba="0.6 0.6 0.65 0.8"/></material>',
    ]
    parts.append(
        f'<link name="vehicle">{_inertial(v.mass, v.r_g, v.inertia)}'
        f'<visual><origin xyz="0 0 0" rpy="0 0 0"/>{hull_box}'
        f'<material name="hull"/></visual>{hull_col}</link>'
    )
    if virtual_added_mass:
        ma = v.rigid_added_mass
        parts.append(f'<link name="added_mass">{_inertial(ma, (0, 0, 0), v.added_mass[3:])}</link>')
        parts.append(_fixed("added_mass_joint", "vehicle", "added_mass", (0, 0, 0), (0, 0, 0)))
    for plate in params.plates:
        parts.extend(_plate_parts(plate, shapes))
    for side in ARM_SIDES if arms else ():
        parts.extend(_arm_parts(params, side, shapes))
    parts.append("</robot>")
    return "\n".join(parts)


def build_object_urdf(params: UVDMSParams, *, collision: bool = False, sleeves: bool = False) -> str:
    """URDF of the gripped cylinder: axis along the object's ``y``, frame at its centre.

    Args:
        params: the physical parameters.
        collision: add a collision capsule of the object's radius whose total length is the cylinder's (core
            segment ``length - 2 radius``), the shape outer obstacles collide with; without it the object has
            no collision shape.
        sleeves: add each hand's sleeve and the two joints that connect it to the object (:data:`SLEEVE_JOINTS`),
            for the friction grasp; without them the object is one rigid body (the rigid grasp's).
    """
    o = params.obj
    inertia = _cylinder_inertia(o.mass, o.radius, o.length, np.array([0.0, 1.0, 0.0]))
    col = ""
    if collision:
        core = o.length - 2.0 * o.radius
        col = (
            f'<collision><origin xyz="0 0 0" rpy="{math.pi / 2:.12g} 0 0"/>'
            f'<geometry><capsule radius="{o.radius:.12g}" length="{core:.12g}"/></geometry></collision>'
        )
    sleeves = _sleeves() if sleeves else ""
    return (
        '<?xml version="1.0"?><robot name="object">'
        f'<link name="object">{_inertial(o.mass, (0, 0, 0), inertia)}'
        f'<visual><origin xyz="0 0 0" rpy="{math.pi / 2:.12g} 0 0"/>'
        f'<geometry><cylinder radius="{o.radius:.12g}" length="{o.length:.12g}"/></geometry>'
        '<material name="obj"><color rgba="0.1 0.5 0.9 1"/></material></visual>'
        f"{col}</link>{sleeves}</robot>"
    )


SLEEVE_JOINTS: tuple[str, ...] = ("left_slide", "left_twist", "right_slide", "right_twist")
"""The friction grasp's object joints, in their PyBullet index order: per hand, sliding along the object's axis (m)
and turning about it (rad); the sleeve after them is welded to the hand."""


def _sleeves() -> str:
    """Per hand, a prismatic then a continuous joint along the object's axis, and the sleeve after them.

    The sleeve sits at the object's centre (the grasp frame): the two joints are the two motions the friction grasp
    leaves to friction (:mod:`uvdms_gym.physics.grip`).
    """
    parts = []
    for side in ("left", "right"):
        parts.append(_tiny_link(f"{side}_carriage"))
        parts.append(_tiny_link(f"{side}_sleeve"))
        parts.append(
            f'<joint name="{side}_slide" type="prismatic"><parent link="object"/><child link="{side}_carriage"/>'
            '<origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>'
            '<limit lower="-1" upper="1" effort="1e9" velocity="1e3"/></joint>'
        )
        parts.append(
            f'<joint name="{side}_twist" type="continuous"><parent link="{side}_carriage"/>'
            f'<child link="{side}_sleeve"/><origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/></joint>'
        )
    return "".join(parts)


_URDF_DIRS: dict[int, Path] = {}
"""This process's folder of URDF files (by process id: a forked worker makes its own), removed at exit."""


def _cache_dir() -> Path:
    """This process's URDF folder: PyBullet loads from a path, and the process (a worker too) leaves nothing behind."""
    folder = _URDF_DIRS.get(os.getpid())
    if folder is None or not folder.is_dir():
        folder = _URDF_DIRS[os.getpid()] = owned_tempdir("uvdms_gym_urdf-")
    return folder


def write_urdf(text: str) -> Path:
    """Write URDF text to a content-addressed file of this process's URDF folder (PyBullet loads from a path)."""
    path = _cache_dir() / f"{hashlib.sha1(text.encode()).hexdigest()[:16]}.urdf"
    if not path.exists():
        tmp = path.with_suffix(f".tmp{threading.get_ident()}")
        tmp.write_text(text)
        tmp.replace(path)
    return path


@lru_cache(maxsize=8)
def _pinocchio_model_cached(params: UVDMSParams, virtual_added_mass: bool):
    import pinocchio as pin

    text = build_urdf(params, virtual_added_mass=virtual_added_mass, shapes=False)
    model = pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
    model.gravity.linear = np.array([0.0, 0.0, 9.81])  # NED: gravity points +z (down)
    return model


def pinocchio_model(params: UVDMSParams | None = None, *, virtual_added_mass: bool = True):
    """Pinocchio model (free-flyer root at the body origin) in NED, built from the same URDF text.

    Configuration ``[x y z (NED), quat xyzw (R_NB), q_l, q_r]``; velocity ``zeta = [nu (body); qdot]``.
    The returned model is shared (cached): do not modify it.
    """
    return _pinocchio_model_cached(params or UVDMSParams(), virtual_added_mass)
