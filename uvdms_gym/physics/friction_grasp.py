"""The friction grasp: each hand holds the object through a contact that sticks or slides (:class:`FrictionGrasp`).

The model (stated in :class:`~uvdms_gym.physics.params.GripperParams`, its law in :mod:`uvdms_gym.physics.grip`):
the jaws hold the object against every relative motion but sliding along its axis and turning about it, which
friction alone resists, within the ellipse ``(f / mu F)^2 + (m / mu r_t F)^2 <= 1`` of each hand's grip force ``F``.

How it is simulated: the object is a small multibody. Its base is the cylinder; per hand a prismatic joint (along
the axis) and a continuous joint (about it) carry a sleeve, which a fixed constraint welds to the hand's grasp frame,
as :class:`~uvdms_gym.physics.grasp.RigidGrasp` welds the object itself. Friction is a velocity motor of target speed
zero on each of those joints, whose force bound is the hand's friction limit: PyBullet's direct MLCP solver holds
the joint exactly while the demand fits within the bound (no creep: a held joint's speed is zero to the solver's
precision) and applies the bound while it slides. Before every physics step (:meth:`FrictionGrasp.apply_hydro`) the
bounds are set from the last step: sticking, the full capacities, or the demand scaled onto the ellipse if it left
it (:func:`~uvdms_gym.physics.grip.stick_bounds`); sliding, a point of the ellipse whose direction tends to the
friction of maximum dissipation along the slip (:func:`~uvdms_gym.physics.grip.slide_direction`: the mean of the last
direction and the slip's, which damps the one-step lag of the bounds). ``docs/cooperative.md`` compares this with
Bullet contacts between finger shapes and the object (the other way the issue names) and gives the measurements behind
the choice.

The joints' positions are the slip: the displacement of each hand's contact along the object (m) and its turn about
the axis (rad); a hand whose axial slip reaches ``drop_slip`` has lost the object (:attr:`FrictionGrasp.dropped`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import pybullet as pb
from pybullet_utils.bullet_client import BulletClient

from uvdms_gym.physics import frames
from uvdms_gym.physics.grasp import _GRASP_SIGN, Current, RigidGrasp
from uvdms_gym.physics.grip import STICK_SPEED, FrictionGraspConfig, slide_direction, stick_bounds
from uvdms_gym.physics.hydro import HydroCoefficients
from uvdms_gym.physics.model import TINY_INERTIA, TINY_MASS
from uvdms_gym.physics.obstacle_bodies import OBJECT_GROUP, OBSTACLE_GROUP
from uvdms_gym.physics.params import ARM_SIDES, UVDMSParams

_JOINTS = [0, 1, 2, 3]  # left slide, left twist, right slide, right twist (model.SLEEVE_JOINTS)
_SLEEVE_LINK = {"left": 1, "right": 3}
_VELOCITY = pb.VELOCITY_CONTROL
_ZEROS = [0.0, 0.0, 0.0, 0.0]
_STICK_SPEED2 = STICK_SPEED * STICK_SPEED
_constraint_state = pb.getConstraintState
_joint_states = pb.getJointStates
_motor_array = pb.setJointMotorControlArray


_DIAGONAL = (math.sqrt(0.5), math.sqrt(0.5))


def _demand_direction(f_max: float, m_max: float, f: float, m: float) -> tuple[float, float]:
    """The unit direction of a sticking hand's demand ``(|f| / f_max, |m| / m_max)`` (the diagonal for none)."""
    if f_max <= 0.0:
        return _DIAGONAL
    a, b = abs(f) / f_max, abs(m) / m_max
    n = math.sqrt(a * a + b * b)
    return (a / n, b / n) if n > 0.0 else _DIAGONAL


class FrictionGrasp(RigidGrasp):
    """The object held by friction at both hands (the ``grasp="friction"`` keyword).

    Args:
        client: the simulator's ``BulletClient``.
        body: PyBullet id of the UVDMS multibody.
        link_index: link name -> link index of ``body`` (``left_grasp`` and ``right_grasp`` are used).
        params: the physical parameters (the object's size and mass).
        physics_dt: the simulator's physics step, s.
        collision: give the object a collision capsule that collides with outer obstacles only.
        config: the grasp's knobs (:func:`uvdms_gym.physics.grip.parse_grasp`).
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
        config: FrictionGraspConfig,
    ) -> None:
        super().__init__(client, body, link_index, params, physics_dt=physics_dt, collision=collision)
        self.config = config
        self._grip = [config.grip_initial, config.grip_initial]
        self._sliding = [False, False]
        self._direction = [_DIAGONAL, _DIAGONAL]  # each hand's friction direction while sliding (slide_direction)
        self._js: tuple | None = None
        self._bounds: list[float] = []
        self.dropped = False
        """A hand's axial slip reached ``drop_slip`` (the object is lost; set until the next :meth:`attach`)."""

    # ----------------------------------------------------------------- attach / detach
    def attach(self, hydro: HydroCoefficients, current: Current) -> None:
        """Create the object with its sleeves at the grippers, moving with them, and weld each sleeve to its hand.

        Raises:
            ValueError: the two grasp frames differ by more than :data:`~uvdms_gym.physics.grasp.GRASP_TOLERANCE`.
        """
        c = self._client
        right = self._load_object(sleeves=True)
        obj = self.object_id
        for link in range(-1, len(_JOINTS)):
            if self._collision and link == -1:  # the object collides with outer obstacles only, never the arms
                c.setCollisionFilterGroupMask(obj, link, OBJECT_GROUP, OBSTACLE_GROUP)
            else:
                c.setCollisionFilterGroupMask(obj, link, 0, 0)
            c.changeDynamics(obj, link, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0)
        for link in _JOINTS:
            c.changeDynamics(obj, link, mass=TINY_MASS, localInertiaDiagonal=[TINY_INERTIA] * 3)
        self.set_dynamics(hydro)
        c.resetBaseVelocity(obj, right[6], right[7])
        for side in ARM_SIDES:
            self._weld(side, _SLEEVE_LINK[side])
        self._grip = [self.config.grip_initial, self.config.grip_initial]
        self._sliding = [False, False]
        self._direction = [_DIAGONAL, _DIAGONAL]
        self.dropped = False
        self._js = None
        self._set_bounds(self._stick_all())
        self._p_prev = self._axial_momentum(hydro, current)

    def detach(self) -> None:
        """Remove the object, its sleeves and the welds (nothing to do without an object)."""
        super().detach()
        self._js = None

    # ----------------------------------------------------------------- grip and friction
    def set_grip(self, left: float, right: float) -> tuple[float, float]:
        """Command each gripper's force, N; returns the forces applied (clipped to ``[0, grip_max]``)."""
        hi = self.config.grip_max
        self._grip = [min(max(float(left), 0.0), hi), min(max(float(right), 0.0), hi)]
        return self._grip[0], self._grip[1]

    @property
    def grip(self) -> tuple[float, float]:
        """The grip forces ``(left, right)`` applied, N."""
        return self._grip[0], self._grip[1]

    def _stick_all(self) -> list[float]:
        out: list[float] = []
        for side in (0, 1):
            out.extend(self.config.capacity(side, self._grip[side]))
        return out

    def _set_bounds(self, bounds: list[float]) -> None:
        self._bounds = bounds
        _motor_array(self.object_id, _JOINTS, _VELOCITY, targetVelocities=_ZEROS, forces=bounds,
                     physicsClientId=self._cid)  # fmt: skip

    def _joint_read(self) -> tuple:
        js = self._js
        if js is None:
            js = self._js = _joint_states(self.object_id, _JOINTS, self._cid)
        return js

    def apply_hydro(self, hydro: HydroCoefficients, current: Current) -> None:
        """Set each hand's friction bounds for the next physics step, then apply the object's hydrodynamic loads."""
        js = self._joint_read()
        cfg = self.config
        bounds: list[float] = []
        for side in (0, 1):
            (x, v, _, f), (_, w, _, m) = js[2 * side], js[2 * side + 1]
            f_max, m_max = cfg.capacity(side, self._grip[side])
            r_t = cfg.torsion_radius[side]
            sliding = v * v + (r_t * w) ** 2 > _STICK_SPEED2 and f_max > 0.0
            self._sliding[side] = sliding
            if sliding:
                cf, cm = self._direction[side] = slide_direction(self._direction[side], f_max, m_max, v, w)
                bounds.append(cf * f_max)
                bounds.append(cm * m_max)
            else:
                if f_max > 0.0 and (f / f_max) ** 2 + (m / m_max) ** 2 <= 1.0:  # stick_bounds' first case, inlined
                    bounds.append(f_max)
                    bounds.append(m_max)
                else:
                    bounds.extend(stick_bounds(f_max, m_max, f, m))
                self._direction[side] = _demand_direction(f_max, m_max, f, m)
            if abs(x) >= cfg.drop_slip:
                self.dropped = True
        if bounds != self._bounds:  # sticking at a steady grip (the usual case) keeps last step's bounds
            self._set_bounds(bounds)
        super().apply_hydro(hydro, current)

    def invalidate(self) -> None:
        """Forget the cached state reads (the state changed)."""
        self._raw = None
        self._js = None

    # ----------------------------------------------------------------- measurements
    def slip(self) -> np.ndarray:
        """Each hand's slip ``(2, 2)``: rows ``[left; right]``, columns axial displacement (m) and turn (rad).

        The contact's displacement along the object from where it gripped at reset (positive along the object's
        ``y``) and its turn about the axis; zeros without an object.
        """
        if self.object_id is None:
            return np.zeros((2, 2))
        js = self._joint_read()
        return np.array([[js[0][0], js[1][0]], [js[2][0], js[3][0]]])

    def slip_distance(self) -> np.ndarray:
        """How far each hand's contact has moved over the object's surface, ``sqrt(x^2 + (r_t theta)^2)`` (2), m."""
        s = self.slip()
        r_t = np.asarray(self.config.torsion_radius)
        return np.hypot(s[:, 0], r_t * s[:, 1])

    @property
    def sliding(self) -> tuple[bool, bool]:
        """Whether each hand was sliding at the start of the last physics step ``(left, right)``."""
        return self._sliding[0], self._sliding[1]

    def forces(self) -> np.ndarray:
        """Wrenches exerted by the hands on the object, ``(2, 6)`` rows ``[left; right]`` (as the rigid grasp's).

        Each row is ``[force (3); moment (3)]`` in NED from the last physics step's weld impulses, the moment's
        components taken about the sleeve's axes (the grasp frame it is welded to: the object's turned by the twist).
        """
        if self.object_id is None:
            return np.zeros((2, 6))
        _, quat, _, _ = self.read()
        r = frames.quat_xyzw_to_rot(np.array(quat)).tolist()
        js = self._joint_read()
        rows = []
        for k, cid in enumerate(self._constraints):
            fx, fy, fz, mx, my, mz = _constraint_state(cid, self._cid)
            th = js[2 * k + 1][0]
            c, s = math.cos(th), math.sin(th)
            ax, ay, az = c * mx + s * mz, my, c * mz - s * mx  # about the sleeve's axes: the object's turned about y
            wx = r[0][0] * ax + r[0][1] * ay + r[0][2] * az
            wy = r[1][0] * ax + r[1][1] * ay + r[1][2] * az
            wz = r[2][0] * ax + r[2][1] * ay + r[2][2] * az
            g = _GRASP_SIGN
            rows.append((g * fx, -g * fy, -g * fz, g * wx, -g * wy, -g * wz))  # z-up world -> NED
        return np.array(rows)

    def friction_efforts(self) -> np.ndarray:
        """Last physics step's friction ``(2, 2)``: rows ``[left; right]``, axial force (N) and twisting moment (N m).

        What each hand's contact transmits along and about the object's axis (the motors' forces).
        """
        if self.object_id is None:
            return np.zeros((2, 2))
        js = self._joint_read()
        return np.array([[js[0][3], js[1][3]], [js[2][3], js[3][3]]])
