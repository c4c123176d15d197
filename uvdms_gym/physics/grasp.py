"""The gripped object and its closed chain: a cylinder welded to both grippers (:class:`RigidGrasp`).

A simulator (:class:`uvdms_gym.physics.sim.UVDMSSim`) holds one grasp and reaches the object only through the
interface :class:`Grasp`: :meth:`~Grasp.attach` creates the object at the grippers and closes the chain,
:meth:`~Grasp.detach` removes both, :meth:`~Grasp.apply_hydro` applies the object's hydrodynamic loads before each
physics step, :meth:`~Grasp.read` and the pose and velocity queries read the object, :meth:`~Grasp.forces` reads the
constraint. A grasp that is not rigid (friction at the grippers) replaces :class:`RigidGrasp` behind the same
interface.

:class:`RigidGrasp` welds the object to ``left_grasp`` and ``right_grasp`` with two fixed constraints of maximum
force :data:`GRASP_MAX_FORCE`, solved with the joint limits by PyBullet's direct MLCP solver (the module docstring
of :mod:`uvdms_gym.physics.body` says why). The object's added mass is rigid (added to its mass and transverse
inertia); its Morison drag, the lift that cancels the weight of the added mass, the rate of its axial added momentum
(one physics step lagged) and its Munk moment are applied as external loads
(:func:`uvdms_gym.physics.hydro.object_wrench`, inlined in :meth:`RigidGrasp.apply_hydro`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Protocol

import numpy as np
import pybullet as pb
from pybullet_utils.bullet_client import BulletClient

from uvdms_gym.physics import frames, model
from uvdms_gym.physics.hydro import HydroCoefficients
from uvdms_gym.physics.obstacle_bodies import OBJECT_GROUP, OBSTACLE_GROUP
from uvdms_gym.physics.params import ARM_SIDES, GRAVITY, UVDMSParams

GRASP_MAX_FORCE = 1.0e6
"""Maximum force of each grasp constraint (PyBullet's default 500 N could let the chain slip), N."""
GRASP_TOLERANCE = (1.0e-3, math.radians(0.5))
"""Largest position (m) and angle (rad) mismatch between the two grasp frames accepted by
``reset(..., with_object=True)``: the object is welded to both, so they must coincide."""
_GRASP_SIGN = -1.0
"""``getConstraintState`` reports the constraint force on the parent (the grasp link); the force on the
object (the child) is its opposite (checked against the object's momentum balance in the tests)."""

_WORLD = pb.WORLD_FRAME
_apply_force = pb.applyExternalForce
_apply_torque = pb.applyExternalTorque
_base_pose = pb.getBasePositionAndOrientation
_base_velocity = pb.getBaseVelocity

Current = tuple[float, float, float] | None
"""The ocean current in PyBullet's z-up world frame, or ``None`` without one."""


class Grasp(Protocol):
    """What a simulator needs from the gripped object and its grasp.

    Attributes:
        object_id: PyBullet id of the object's body, or ``None`` while nothing is held.
    """

    object_id: int | None

    def attach(self, hydro: HydroCoefficients, current: Current) -> None:
        """Create the object at the grippers, moving with them, and close the chain."""

    def detach(self) -> None:
        """Remove the object and its constraints (nothing to do without an object)."""

    def set_dynamics(self, hydro: HydroCoefficients) -> None:
        """Give the object the mass and inertia of ``hydro`` (its added mass included)."""

    def apply_hydro(self, hydro: HydroCoefficients, current: Current) -> None:
        """Apply the object's hydrodynamic loads for the next physics step."""

    def shift_lag(self, dv_world: np.ndarray, hydro: HydroCoefficients) -> None:
        """Re-express the lagged hydrodynamic state relative to a current changed by ``dv_world``."""

    def invalidate(self) -> None:
        """Forget the cached state read (the state changed)."""

    def require(self) -> int:
        """The object's id (``RuntimeError`` while nothing is held)."""

    def read(self) -> tuple:
        """Raw PyBullet object state ``(p, quat, v, w)`` (z-up world), cached until :meth:`invalidate`."""

    def position(self) -> np.ndarray:
        """NED position of the object's centre (3)."""

    def rotation(self) -> np.ndarray:
        """Object orientation ``R_N,object`` (NED)."""

    def velocity(self) -> np.ndarray:
        """Object twist ``[v; w]`` (6), NED."""

    def forces(self) -> np.ndarray:
        """Wrenches of the end effectors on the object, ``(2, 6)`` rows ``[left; right]`` (NED)."""


class RigidGrasp:
    """The object welded to both grippers (two fixed constraints): the closed chain of the benchmark.

    Args:
        client: the simulator's ``BulletClient``.
        body: PyBullet id of the UVDMS multibody.
        link_index: link name -> link index of ``body`` (``left_grasp`` and ``right_grasp`` are used).
        params: the physical parameters (the object's size and mass).
        physics_dt: the simulator's physics step, s (the rate of the lagged axial added momentum).
        collision: give the object a collision capsule that collides with outer obstacles only.
    """

    def __init__(
        self,
        client: BulletClient,
        body: int,
        link_index: Mapping[str, int],
        params: UVDMSParams,
        *,
        physics_dt: float,
        collision: bool,
    ) -> None:
        self._client = client
        self._cid: int = client._client
        self._body = body
        self._link_index = link_index
        self._params = params
        self._inv_dt = 1.0 / physics_dt
        self._collision = collision
        self.object_id: int | None = None
        self._constraints: list[int] = []
        self._raw: tuple | None = None
        self._p_prev = (0.0, 0.0, 0.0)  # previous physics step's axial added momentum (world frame)

    @property
    def constraint_ids(self) -> tuple[int, ...]:
        """PyBullet ids of the two welds ``(left, right)`` (empty without an object)."""
        return tuple(self._constraints)

    def detach(self) -> None:
        """Remove the object and its constraints (nothing to do without an object)."""
        for cid in self._constraints:
            self._client.removeConstraint(cid)
        self._constraints = []
        if self.object_id is not None:
            self._client.removeBody(self.object_id)
            self.object_id = None
        self._raw = None

    def attach(self, hydro: HydroCoefficients, current: Current) -> None:
        """Create the object at ``right_grasp``, moving with it, and weld it to both grasp frames.

        Raises:
            ValueError: the two grasp frames differ by more than :data:`GRASP_TOLERANCE`.
        """
        c = self._client
        right = self._load_object(sleeves=False)
        obj = self.object_id
        if self._collision:  # the object collides with outer obstacles only, never with the arms holding it
            c.setCollisionFilterGroupMask(obj, -1, OBJECT_GROUP, OBSTACLE_GROUP)
        else:
            c.setCollisionFilterGroupMask(obj, -1, 0, 0)
        self.set_dynamics(hydro)
        c.resetBaseVelocity(obj, right[6], right[7])
        for side in ARM_SIDES:
            self._weld(side, -1)
        self._p_prev = self._axial_momentum(hydro, current)

    def _load_object(self, *, sleeves: bool) -> tuple:
        """Load the object at ``right_grasp`` (both grasp frames checked to coincide); the right frame's link state."""
        c = self._client
        grasp = {
            side: c.getLinkState(
                self._body, self._link_index[f"{side}_grasp"], computeLinkVelocity=1, computeForwardKinematics=1
            )
            for side in ARM_SIDES
        }
        self._check_frames(grasp["left"][4:6], grasp["right"][4:6])
        pr, orr = grasp["right"][4:6]
        path = model.write_urdf(model.build_object_urdf(self._params, collision=self._collision, sleeves=sleeves))
        self.object_id = c.loadURDF(
            str(path), basePosition=pr, baseOrientation=orr, flags=pb.URDF_USE_INERTIA_FROM_FILE
        )
        return grasp["right"]

    def _weld(self, side: str, object_link: int) -> None:
        """Weld link ``object_link`` of the object (``-1``: its base) to the grasp frame of ``side``."""
        cid = self._client.createConstraint(
            self._body,
            self._link_index[f"{side}_grasp"],
            self.object_id,
            object_link,
            pb.JOINT_FIXED,
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [0.0, 0.0, 0.0, 1.0],
        )
        self._client.changeConstraint(cid, maxForce=GRASP_MAX_FORCE)
        self._constraints.append(cid)

    @staticmethod
    def _check_frames(left: tuple, right: tuple) -> None:
        """Raise ``ValueError`` unless the grasp frames ``(position, quaternion)`` coincide within tolerance."""
        (pl, ol), (pr, orr) = left, right
        dp = float(np.linalg.norm(np.subtract(pl, pr)))
        r_rel = frames.quat_xyzw_to_rot(np.array(ol)).T @ frames.quat_xyzw_to_rot(np.array(orr))
        dang = float(np.arccos(np.clip((np.trace(r_rel) - 1.0) / 2.0, -1.0, 1.0)))
        if dp > GRASP_TOLERANCE[0] or dang > GRASP_TOLERANCE[1]:
            raise ValueError(
                f"with_object=True: the grasp frames differ by {dp * 1e3:.3f} mm and {math.degrees(dang):.3f} deg "
                f"(tolerance {GRASP_TOLERANCE[0] * 1e3:.1f} mm, {math.degrees(GRASP_TOLERANCE[1]):.1f} deg); "
                "give joint angles at which both grippers hold the object (e.g. q_left == q_right)"
            )

    def set_dynamics(self, hydro: HydroCoefficients) -> None:
        """Mass and inertia of the object plus its (rigid) added mass; no PyBullet damping."""
        o, h = self._params.obj, hydro
        m = o.mass
        i_t = m * (3.0 * o.radius**2 + o.length**2) / 12.0
        i_ax = 0.5 * m * o.radius**2
        self._client.changeDynamics(
            self.object_id,
            -1,
            mass=m + h.obj_added_mass,
            localInertiaDiagonal=[i_t + h.obj_added_inertia, i_ax, i_t + h.obj_added_inertia],
            linearDamping=0.0,
            angularDamping=0.0,
        )

    def _axial_momentum(self, hydro: HydroCoefficients, current: Current) -> tuple[float, float, float]:
        """Axial added momentum ``m_a (v_r . e) e`` of the object (world frame; ``v_r = v - v_c``)."""
        _, (qx, qy, qz, qw) = _base_pose(self.object_id, self._cid)
        (vx, vy, vz), _ = _base_velocity(self.object_id, self._cid)
        if current is not None:  # relative to the water
            cx, cy, cz = current
            vx, vy, vz = vx - cx, vy - cy, vz - cz
        ex, ey, ez = 2.0 * (qx * qy - qz * qw), 1.0 - 2.0 * (qx * qx + qz * qz), 2.0 * (qy * qz + qx * qw)
        k = hydro.obj_added_mass * (vx * ex + vy * ey + vz * ez)
        return (k * ex, k * ey, k * ez)

    def apply_hydro(self, hydro: HydroCoefficients, current: Current) -> None:
        """Apply the object's hydrodynamic wrench (:func:`uvdms_gym.physics.hydro.object_wrench`, inlined)."""
        cid, obj, h = self._cid, self.object_id, hydro
        pos, (qx, qy, qz, qw) = _base_pose(obj, cid)
        (vx, vy, vz), _ = _base_velocity(obj, cid)
        if current is not None:  # every term below acts on the velocity relative to the water
            cx, cy, cz = current
            vx, vy, vz = vx - cx, vy - cy, vz - cz
        ex, ey, ez = 2.0 * (qx * qy - qz * qw), 1.0 - 2.0 * (qx * qx + qz * qz), 2.0 * (qy * qz + qx * qw)
        vt = vx * ex + vy * ey + vz * ez
        k = h.obj_added_mass * vt
        p_ax = (k * ex, k * ey, k * ez)  # axial added momentum
        p0x, p0y, p0z = self._p_prev
        self._p_prev = p_ax
        inv_dt = self._inv_dt
        # Morison drag (hydro.morison_force), lift = buoyancy + weight cancel of the added mass, + dP_ax/dt
        nx, ny, nz = vx - vt * ex, vy - vt * ey, vz - vt * ez
        kvn = h.obj_kn * math.sqrt(nx * nx + ny * ny + nz * nz)
        kvt = h.obj_kt * abs(vt) * vt
        lift = h.obj_buoyancy + h.obj_added_mass * GRAVITY
        force = (
            (-kvn * nx - kvt * ex) + lift * 0.0 + (p_ax[0] - p0x) * inv_dt,
            (-kvn * ny - kvt * ey) + lift * 0.0 + (p_ax[1] - p0y) * inv_dt,
            (-kvn * nz - kvt * ez) + lift * 1.0 + (p_ax[2] - p0z) * inv_dt,
        )
        moment = (k * (vy * ez - vz * ey), k * (vz * ex - vx * ez), k * (vx * ey - vy * ex))
        _apply_force(obj, -1, force, pos, _WORLD, cid)
        _apply_torque(obj, -1, moment, _WORLD, cid)

    @property
    def lagged_momentum(self) -> tuple[float, float, float]:
        """The previous physics step's axial added momentum (world frame), the lag state of :meth:`apply_hydro`."""
        return self._p_prev

    def shift_lag(self, dv_world: np.ndarray, hydro: HydroCoefficients) -> None:
        """Re-express the lagged axial momentum relative to a current changed by ``dv_world`` (z-up world)."""
        _, oquat, _, _ = self.read()
        e = frames.quat_xyzw_to_rot(np.array(oquat))[:, 1]  # object axis (its y) in the world
        dp = hydro.obj_added_mass * float(dv_world @ e) * e
        self._p_prev = tuple((np.array(self._p_prev) - dp).tolist())

    def invalidate(self) -> None:
        """Forget the cached state read (called after every physics step and reset)."""
        self._raw = None

    def require(self) -> int:
        """The object's id (``RuntimeError`` without an object)."""
        if self.object_id is None:
            raise RuntimeError("no object: reset(..., with_object=True) first")
        return self.object_id

    def read(self) -> tuple:
        """Raw PyBullet object state ``(p, quat, v, w)`` (world frame), read once per physics state."""
        raw = self._raw
        if raw is None:
            obj = self.require()
            p, quat = _base_pose(obj, self._cid)
            v, w = _base_velocity(obj, self._cid)
            raw = self._raw = (p, quat, v, w)
        return raw

    def position(self) -> np.ndarray:
        """NED position of the object's centre (3)."""
        p, _, _, _ = self.read()
        return np.array([p[0], -p[1], -p[2]])  # frames.world_to_ned

    def rotation(self) -> np.ndarray:
        """Object orientation as a rotation matrix ``R_N,object`` (NED)."""
        _, quat, _, _ = self.read()
        return frames.body_rot_world_to_ned(frames.quat_xyzw_to_rot(quat))

    def velocity(self) -> np.ndarray:
        """Object twist ``[v; w]`` (6): velocity of its centre and angular velocity, both in NED."""
        _, _, v, w = self.read()
        return np.concatenate([frames.world_to_ned(np.array(v)), frames.world_to_ned(np.array(w))])

    def forces(self) -> np.ndarray:
        """Wrenches exerted by the end effectors on the object, ``(2, 6)`` rows ``[left; right]``.

        Each row is ``[force (3); moment (3)]`` in NED, about the object's centre (the grasp point), from
        the last physics step's constraint impulses (``getConstraintState``, impulse / dt). These are the
        paper's ``F_e``. Zeros without an object.
        """
        out = np.zeros((2, 6))
        for k, cid in enumerate(self._constraints):
            f = np.array(self._client.getConstraintState(cid), dtype=float)
            side = ARM_SIDES[k]
            ls = self._client.getLinkState(self._body, self._link_index[f"{side}_grasp"], computeForwardKinematics=1)
            r_w = frames.quat_xyzw_to_rot(np.array(ls[5]))  # angular rows act about the grasp frame's axes
            out[k, :3] = frames.S @ (_GRASP_SIGN * f[:3])
            out[k, 3:] = frames.S @ (r_w @ (_GRASP_SIGN * f[3:6]))
        return out
