"""Kinematics and rigid-body dynamics of the UVDMS on Pinocchio, in NED (docs/MODEL.md sections 1 and 4).

:class:`KinematicModel` wraps the free-flyer Pinocchio model of :func:`uvdms_gym.physics.model.pinocchio_model`:

* configuration ``[x y z (NED), quat xyzw of R_NB, q_l (6), q_r (6)]`` (19);
* velocity ``zeta = [nu (body FRD: linear at the body origin, angular); qdot_l; qdot_r]`` (18), which is
  exactly Pinocchio's ``v`` for the free flyer (``pin.integrate(model, config, zeta * dt)`` moves along it).

Usage: call :meth:`KinematicModel.set_state` once per control step (one forward-kinematics pass with all
joint Jacobians); every accessor then reads the cached result. All Jacobians are ``LOCAL_WORLD_ALIGNED``:
rows give velocities (linear of the named point, angular) expressed in NED, columns act on ``zeta``.
Dynamics (:meth:`~KinematicModel.mass_matrix`, :meth:`~KinematicModel.nonlinear_effects`,
:meth:`~KinematicModel.gravity`) are computed lazily on a separate ``pin.Data`` and cached per state.

PyBullet's ``calculateMassMatrix`` for this body (measured, see ``tests/uvdms_gym/physics/test_kinematics.py``) uses the
velocity coordinates ``[omega_B; v_C; qdot]``: body angular velocity, then the linear velocity of the
vehicle's centre of gravity ``r_G``, both in body (FRD) axes, then the joints in PyBullet link order. It
ignores the base pose (evaluates at the identity), which is consistent with body-axis coordinates. With
``T`` such that ``[omega_B; v_C; qdot] = T zeta`` (``omega_B = omega``, ``v_C = v_O - [r_G]x omega``),
``M_pinocchio = T^T M_pybullet T`` (:func:`pybullet_velocity_map`).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from uvdms_gym.physics.model import link_segment, pinocchio_model
from uvdms_gym.physics.params import ARM_SIDES, GRAVITY, JOINT_NAMES, N_DOF, N_JOINTS, UVDMSParams
from uvdms_gym.utils.validation import finite_vector

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_N_CONFIG = 7 + N_JOINTS
_STRICT_LOWER = np.tri(N_DOF, k=-1, dtype=bool)


def _skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``[v]x`` with ``[v]x w = v x w``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def euler_to_quat_xyzw(rpy: np.ndarray) -> np.ndarray:
    """ZYX Euler angles -> unit quaternion ``[x, y, z, w]`` with ``w >= 0``, in closed form.

    Equal to ``frames.rot_to_quat_xyzw(frames.euler_to_rot(rpy))`` (tested) and several times faster
    (it runs in every :meth:`KinematicModel.set_state`).
    """
    hr, hp, hy = 0.5 * float(rpy[0]), 0.5 * float(rpy[1]), 0.5 * float(rpy[2])
    cr, sr = math.cos(hr), math.sin(hr)
    cp, sp = math.cos(hp), math.sin(hp)
    cy, sy = math.cos(hy), math.sin(hy)
    q = np.array(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ]
    )
    return q if q[3] >= 0.0 else -q


def pybullet_velocity_map(params: UVDMSParams | None = None, joint_order: np.ndarray | None = None) -> np.ndarray:
    """Linear map ``T`` (18x18) from ``zeta`` to PyBullet's floating-base velocity coordinates.

    PyBullet's ``calculateMassMatrix`` coordinates are ``[omega_B (3); v_C (3); qdot (12)]``: body angular
    velocity, linear velocity of the centre of gravity ``r_G`` (the base link's inertial frame), both in
    body axes, then the joint rates in PyBullet's link order. Hence ``M_pin = T^T M_pb T``.

    Args:
        params: physical parameters (for ``r_G``); defaults to :class:`UVDMSParams`.
        joint_order: ``joint_order[k]`` is the index in ``q = [q_l; q_r]`` of PyBullet's ``k``-th revolute
            joint; ``None`` means the same order (true for :func:`uvdms_gym.physics.model.build_urdf`).

    Returns:
        ``T`` with ``[omega_B; v_C; qdot_pb] = T zeta``.
    """
    params = params or UVDMSParams()
    t = np.zeros((N_DOF, N_DOF))
    t[0:3, 3:6] = np.eye(3)
    t[3:6, 0:3] = np.eye(3)
    t[3:6, 3:6] = -_skew(np.asarray(params.vehicle.r_g, dtype=float))
    order = np.arange(N_JOINTS) if joint_order is None else np.asarray(joint_order)
    t[6 + np.arange(N_JOINTS), 6 + order] = 1.0
    return t


class KinematicModel:
    """Forward kinematics, Jacobians and rigid-body dynamics of the UVDMS at one state.

    Attributes:
        params: the physical parameters the model was built from.
        model: the (shared, read-only) Pinocchio model.
        data: this instance's ``pin.Data`` holding the kinematics of the last :meth:`set_state`.
        virtual_added_mass: whether the model contains the isotropic added mass as a rigid virtual body
            (then :meth:`mass_matrix` and :meth:`nonlinear_effects` include that part of ``M_A`` and
            ``C_A``; its fictitious weight is removed from :meth:`gravity`, as the simulator cancels it).
        config: Pinocchio configuration (19) of the current state.
        zeta: current system velocity (18), or ``None`` if :meth:`set_state` got none.
    """

    def __init__(self, params: UVDMSParams | None = None, *, virtual_added_mass: bool = True) -> None:
        """Build the model and set the neutral state (``eta = 0``, ``q = 0``, no velocity).

        Args:
            params: physical parameters; defaults to :class:`UVDMSParams`.
            virtual_added_mass: include the ``added_mass`` virtual body (as the simulator does).
        """
        self.params = params or UVDMSParams()
        self.virtual_added_mass = virtual_added_mass
        self.model = pinocchio_model(self.params, virtual_added_mass=virtual_added_mass)
        self.data = self.model.createData()
        self._dyn = self.model.createData()
        m = self.model
        if m.nq != _N_CONFIG or m.nv != N_DOF:
            raise RuntimeError(f"unexpected Pinocchio model size nq={m.nq}, nv={m.nv}")
        for k, name in enumerate(JOINT_NAMES):  # zeta = [nu; q_l; q_r] must be Pinocchio's v ordering
            jid = m.getJointId(name)
            if m.idx_vs[jid] != 6 + k or m.idx_qs[jid] != 7 + k:
                raise RuntimeError(f"joint {name} is not at velocity index {6 + k} of the Pinocchio model")

        self._fid: dict[str, int] = {f.name: i for i, f in enumerate(m.frames)}
        self._ee_ids = tuple(self._fid[f"{s}_ee"] for s in ARM_SIDES)
        self._grasp_ids = {s: self._fid[f"{s}_grasp"] for s in ARM_SIDES}
        self._vehicle_id = self._fid["vehicle"]
        n_links = self.params.arm.n_links
        self._link_ids = [self._fid[f"{s}_link{i}"] for s in ARM_SIDES for i in range(n_links)]
        seg = np.array([link_segment(self.params, i) for i in range(n_links)])  # (7, 2, 3) in link frames
        seg_h = np.concatenate([seg, np.ones((n_links, 2, 1))], axis=2)  # homogeneous points
        self._seg_local_h = np.ascontiguousarray(np.broadcast_to(seg_h, (2, n_links, 2, 4)).reshape(-1, 2, 4))
        self._n_links = n_links
        pls = self.params.plates
        # rows: centres, then u, then v of all plates (body frame)
        self._plate_vecs = np.array([pl.center for pl in pls] + [pl.u for pl in pls] + [pl.v for pl in pls], float)
        self._plate_half = [(float(pl.half_extents[0]), float(pl.half_extents[1])) for pl in pls]
        # Column mask of each joint's Jacobian (the joints supporting it) for point Jacobians from data.J.
        self._support_mask = np.zeros((m.njoints, N_DOF), dtype=bool)
        for jid in range(1, m.njoints):
            for j in m.supports[jid]:
                if j > 0:
                    self._support_mask[jid, m.idx_vs[j] : m.idx_vs[j] + m.nvs[j]] = True
        self._parent_joint = np.array([f.parentJoint for f in m.frames], dtype=int)
        self._added_weight = self.params.vehicle.rigid_added_mass * GRAVITY if virtual_added_mass else 0.0

        self.config = pin.neutral(m)
        self.zeta: np.ndarray | None = None
        self._cache: dict[str, np.ndarray] = {}
        self.set_configuration(self.config)

    # ------------------------------------------------------------------ state
    @staticmethod
    def configuration(eta: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Pinocchio configuration ``[x y z, quat xyzw of R_NB, q_l, q_r]`` (19).

        Args:
            eta: vehicle pose ``[x y z phi theta psi]`` (NED position, ZYX Euler angles).
            q: joint angles ``[q_l; q_r]`` (12).

        Returns:
            The configuration vector.
        """
        eta = np.asarray(eta, dtype=float)
        out = np.empty(_N_CONFIG)
        out[:3] = eta[:3]
        out[3:7] = euler_to_quat_xyzw(eta[3:6])
        out[7:] = q
        return out

    def set_state(self, eta: np.ndarray, q: np.ndarray, zeta: np.ndarray | None = None) -> None:
        """Set the state and compute the kinematics once (placements of all frames, all joint Jacobians).

        Args:
            eta: vehicle pose (6), NED + ZYX Euler.
            q: joint angles (12).
            zeta: system velocity ``[nu; qdot]`` (18); needed only by :meth:`nonlinear_effects`.

        Raises:
            ValueError: an argument has the wrong shape or non-finite entries (the message names it).
        """
        eta = finite_vector(eta, 6, "eta")
        q = finite_vector(q, N_JOINTS, "q")
        self._update(self.configuration(eta, q), None if zeta is None else finite_vector(zeta, N_DOF, "zeta"))

    def set_configuration(self, config: np.ndarray, zeta: np.ndarray | None = None) -> None:
        """Like :meth:`set_state`, from a Pinocchio configuration (e.g. the result of ``pin.integrate``).

        Args:
            config: ``[x y z, quat xyzw, q_l, q_r]`` (19) with a unit quaternion.
            zeta: system velocity (18) or ``None``.

        Raises:
            ValueError: wrong shape, non-finite entries, or a quaternion that is not unit (to 1e-6).
        """
        config = finite_vector(config, _N_CONFIG, "config")
        if abs(float(config[3:7] @ config[3:7]) - 1.0) > 1e-6:
            raise ValueError(f"config quaternion is not unit: {config[3:7]}")
        self._update(config.copy(), None if zeta is None else finite_vector(zeta, N_DOF, "zeta"))

    def _update(self, config: np.ndarray, zeta: np.ndarray | None) -> None:
        self.config = config
        self.zeta = None if zeta is None else zeta.copy()
        self._cache.clear()
        pin.computeJointJacobians(self.model, self.data, config)  # includes forward kinematics
        pin.updateFramePlacements(self.model, self.data)

    # ------------------------------------------------------------------ poses
    def frame_placement(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (3) and rotation (3x3, frame -> NED) of the named model frame.

        Args:
            name: a Pinocchio frame name (link, joint or fixed-joint name of the URDF).

        Returns:
            ``(p, R)`` in NED.
        """
        m = self.data.oMf[self._frame_id(name)]
        return m.translation.copy(), m.rotation.copy()

    def ee_positions(self) -> np.ndarray:
        """Tool-tip positions (2, 3): row 0 left, row 1 right, NED."""
        omf = self.data.oMf
        return np.array([omf[i].translation for i in self._ee_ids])

    def ee_rotations(self) -> np.ndarray:
        """Tool-tip orientations (2, 3, 3): ``R_N,ee`` for left and right."""
        omf = self.data.oMf
        return np.array([omf[i].rotation for i in self._ee_ids])

    def object_pose(self, side: str = "right") -> tuple[np.ndarray, np.ndarray]:
        """Pose of the gripped object's frame as carried by one arm (``{side}_grasp``).

        Args:
            side: ``"left"`` or ``"right"``.

        Returns:
            ``(p, R)``: object centre in NED and rotation object -> NED.
        """
        m = self.data.oMf[self._grasp_id(side)]
        return m.translation.copy(), m.rotation.copy()

    def link_segments(self) -> np.ndarray:
        """Capsule axes of all links in NED: shape (2, 7, 2, 3) = [side][link 0..6][A, B][xyz].

        Side 0 is left, 1 right; ``A`` is the end nearer the arm base (see
        :func:`uvdms_gym.physics.model.link_segment`). Computed once per state and returned read-only (the
        environment's inner and outer distances both read it); copy it to modify it.
        """
        seg = self._cache.get("seg")
        if seg is None:
            # oMf.tolist() (~0.1 µs per frame) instead of oMf[i] (~1 µs per item access, measured)
            omf = self.data.oMf.tolist()
            h = np.array([omf[i].homogeneous for i in self._link_ids])  # (14, 4, 4)
            pts = self._seg_local_h @ h[:, :3].transpose(0, 2, 1)  # (14, 2, 3): rows [A 1], [B 1] mapped to NED
            seg = pts.reshape(2, self._n_links, 2, 3)  # C-contiguous (the compiled distance kernel's fast path)
            seg.flags.writeable = False
            self._cache["seg"] = seg
        return seg

    def plates(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, tuple[float, float]]]:
        """The frame plates in NED, in the order of ``params.plates``.

        Returns:
            One ``(center, u, v, half_extents)`` per plate: the rectangle ``center + s u + t v``,
            ``|s| <= half_extents[0]``, ``|t| <= half_extents[1]``.
        """
        m = self.data.oMf[self._vehicle_id]
        w = self._plate_vecs @ m.rotation.T
        n = len(self._plate_half)
        w[:n] += m.translation
        return [(w[k], w[n + k], w[2 * n + k], he) for k, he in enumerate(self._plate_half)]

    # -------------------------------------------------------------- Jacobians
    def frame_jacobian(self, name: str) -> np.ndarray:
        """Jacobian (6, 18) ``[linear; angular]`` of the named frame, ``LOCAL_WORLD_ALIGNED``.

        Args:
            name: a Pinocchio frame name.

        Returns:
            The Jacobian: NED linear velocity of the frame origin and NED angular velocity, w.r.t. ``zeta``.
        """
        return pin.getFrameJacobian(self.model, self.data, self._frame_id(name), _LWA)

    def ee_jacobian(self) -> np.ndarray:
        """End-effector Jacobian ``J`` (12, 18) = ``[J_lin_l; J_ang_l; J_lin_r; J_ang_r]`` (docs/MODEL.md section 1)."""
        out = np.empty((12, N_DOF))
        out[:6] = pin.getFrameJacobian(self.model, self.data, self._ee_ids[0], _LWA)
        out[6:] = pin.getFrameJacobian(self.model, self.data, self._ee_ids[1], _LWA)
        return out

    def object_jacobian(self, side: str = "right") -> np.ndarray:
        """Object Jacobian ``J_o`` (6, 18) ``[linear; angular]`` of the ``{side}_grasp`` frame.

        Args:
            side: ``"left"`` or ``"right"`` (the arm through which the object's twist is computed).

        Returns:
            The Jacobian, ``LOCAL_WORLD_ALIGNED``.
        """
        return pin.getFrameJacobian(self.model, self.data, self._grasp_id(side), _LWA)

    def point_jacobian(self, frame: str, point: np.ndarray) -> np.ndarray:
        """Linear Jacobian (3, 18) of a material point rigidly attached to the body carrying ``frame``.

        Args:
            frame: a frame name; the point moves with that frame's body (e.g. ``"right_link3"``;
                ``"vehicle"`` or ``"plate_left"`` for points fixed to the hull or the frame plates).
            point: the point's current NED position (3).

        Returns:
            ``J_P`` with ``pdot = J_P zeta`` (NED).
        """
        jid = self._parent_joint[self._frame_id(frame)]
        j = self.data.J  # WORLD convention: spatial velocity at the NED origin, in NED axes
        p = np.asarray(point, dtype=float)
        lin = j[:3] - _skew(p) @ j[3:]  # v_p = v_0 + w x p
        lin *= self._support_mask[jid]
        return lin

    def point_jacobians(self, frame_names: list[str] | tuple[str, ...], points: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`point_jacobian` for ``n`` points.

        Args:
            frame_names: ``n`` frame names (each point's carrying body).
            points: NED positions, shape (n, 3).

        Returns:
            Jacobians, shape (n, 3, 18).
        """
        mask = self._support_mask[self._parent_joint[[self._frame_id(f) for f in frame_names]]]  # (n, 18)
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        j = self.data.J
        w = j[3:]
        # v_p = v_0 + w x p = v_0 - p x w, for every point (n) and column (18): (n, 3, 18)
        pxw = p[:, [1, 2, 0], None] * w[[2, 0, 1]][None] - p[:, [2, 0, 1], None] * w[[1, 2, 0]][None]
        return (j[:3][None] - pxw) * mask[:, None, :]

    # --------------------------------------------------------------- dynamics
    def mass_matrix(self) -> np.ndarray:
        """Joint-space inertia matrix ``M`` (18, 18) of the rigid bodies (CRBA), symmetric.

        Coordinates are ``zeta``; with the virtual added-mass body it includes the isotropic part of ``M_A``.
        """
        m = self._cache.get("M")
        if m is None:
            pin.crba(self.model, self._dyn, self.config)  # fills the upper triangle only
            upper = self._dyn.M
            m = upper.copy()
            np.copyto(m, upper.T, where=_STRICT_LOWER)  # mirror (one masked copy; np.triu twice is 8x slower)
            m += 0.0  # -0.0 -> +0.0, as the former triu sum did: the same bits downstream
            self._cache["M"] = m
        return m.copy()

    def gravity(self) -> np.ndarray:
        """Generalized gravity ``g`` (18) of the rigid bodies (base rows: body-frame wrench at the origin).

        ``tau = M zetadot + C zeta + g``; buoyancy is not included (see ``hydro``). The virtual added-mass
        body is weightless here (the simulator cancels its weight).
        """
        g = self._cache.get("g")
        if g is None:
            g = pin.computeGeneralizedGravity(self.model, self._dyn, self.config).copy()
            self._remove_added_weight(g)
            self._cache["g"] = g
        return g.copy()

    def nonlinear_effects(self) -> np.ndarray:
        """Coriolis/centrifugal plus gravity ``C(q, zeta) zeta + g`` (18) of the rigid bodies.

        Base rows are the body-frame wrench at the origin. Requires ``zeta`` in :meth:`set_state`.

        Raises:
            RuntimeError: the current state has no velocity.
        """
        if self.zeta is None:
            raise RuntimeError("nonlinear_effects() needs zeta: call set_state(eta, q, zeta)")
        h = self._cache.get("nle")
        if h is None:
            h = pin.nonLinearEffects(self.model, self._dyn, self.config, self.zeta).copy()
            self._remove_added_weight(h)
            self._cache["nle"] = h
        return h.copy()

    # ---------------------------------------------------------------- helpers
    def _remove_added_weight(self, tau: np.ndarray) -> None:
        """Cancel the weight of the virtual added-mass body (at the origin): ``tau[:3] += R_NB^T W e_z``."""
        if self._added_weight:
            tau[:3] += self._added_weight * self.data.oMi[1].rotation[2]

    def _frame_id(self, name: str) -> int:
        try:
            return self._fid[name]
        except KeyError:
            raise ValueError(f"unknown frame {name!r}") from None

    def _grasp_id(self, side: str) -> int:
        try:
            return self._grasp_ids[side]
        except KeyError:
            raise ValueError(f"side must be 'left' or 'right', got {side!r}") from None
