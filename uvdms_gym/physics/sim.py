"""The "true" plant: PyBullet rigid-body dynamics of the UVDMS plus the hydrodynamics of :mod:`uvdms_gym.physics.hydro`.

One :class:`UVDMSSim` owns exactly one PyBullet client (``DIRECT``, or ``GUI``) and one multibody: the
vehicle base with the virtual ``added_mass`` link, the frame plates and both 6-joint arms, loaded from
:func:`uvdms_gym.physics.model.build_urdf` with ``URDF_USE_INERTIA_FROM_FILE``. Every public quantity is NED/FRD
(:mod:`uvdms_gym.physics.frames`); PyBullet's world is z-up (``p_W = diag(1, -1, -1) p_NED``).

Physics set-up [D] (gravity, damping, the constraint solver, the physics step, and why): the module docstring of
:mod:`uvdms_gym.physics.body`. The gripped object and its closed chain: :mod:`uvdms_gym.physics.grasp`; contact
counts: :mod:`uvdms_gym.physics.contacts`; the state and its sanity bounds: :mod:`uvdms_gym.physics.state`.

The physics step (:meth:`UVDMSSim.step`, the hot path) is in :mod:`uvdms_gym.physics.stepping`, with what it does
per physics step and why it reads the state once per physics state.

Failures are never silent: an invalid ``tau`` raises :class:`ValueError`, saturation is reported in
:class:`~uvdms_gym.physics.state.StepInfo`, and a state that is non-finite or beyond the sanity bounds of
:mod:`uvdms_gym.physics.state` raises :class:`~uvdms_gym.physics.state.PhysicsError` (the simulator must then be
reset).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from types import MappingProxyType, TracebackType

import numpy as np
import pybullet as pb
from pybullet_utils import bullet_client

from uvdms_gym.physics import frames, render
from uvdms_gym.physics.body import configure_engine, load_body
from uvdms_gym.physics.contacts import ContactMonitor
from uvdms_gym.physics.friction_grasp import FrictionGrasp
from uvdms_gym.physics.grasp import Grasp, RigidGrasp
from uvdms_gym.physics.grip import FrictionGraspConfig
from uvdms_gym.physics.hydro import (
    HydroCoefficients,
    HydroScale,
    link_forces_world,
)
from uvdms_gym.physics.obstacle_bodies import ObstacleBodies
from uvdms_gym.physics.obstacles import Obstacle
from uvdms_gym.physics.params import UVDMSParams
from uvdms_gym.physics.state import (
    SimState,
    base_state,
    state_from_raw,
)
from uvdms_gym.physics.stepping import Stepping, SubstepProbe
from uvdms_gym.physics.water import Water
from uvdms_gym.utils.display import require_display
from uvdms_gym.utils.io import quiet_c_stream
from uvdms_gym.utils.legacy import MOVED_NAMES, moved_names
from uvdms_gym.utils.validation import finite_vector

_get_link_states = pb.getLinkStates
_joint_states = pb.getJointStates
_arctan2 = np.arctan2
_arcsin = np.arcsin


class UVDMSSim(Stepping):
    """PyBullet simulation of the UVDMS with hydrodynamics (the benchmark's plant).

    Args:
        params: physical parameters (default :class:`UVDMSParams`).
        physics_dt: physics time step, s.
        gui: open PyBullet's GUI instead of a headless ``DIRECT`` client
            (:class:`~uvdms_gym.utils.display.DisplayUnavailableError` where no display is available).
        arms: ``False`` loads the bare vehicle (no arms; ``tau`` then has 6 components).
        hydro_scale: model-mismatch factors (see :meth:`set_hydro_scale`).
        self_collision: simulate contact forces between non-adjacent robot links (arm-arm, arm-plate). Off by
            default: the links pass through each other and contacts are *reported* by closest-point queries
            (:meth:`count_contacts`); simulating them costs 10-30 µs per physics step (``docs/DECISIONS.md``).
        outer_collisions: give the hull a collision box and the gripped object a collision capsule, so that outer
            obstacles (:meth:`set_obstacles`) collide with the links, the object and the vehicle. Off by default
            (nothing outside the robot exists, and the hull and object need no collision shape).
        grasp: ``None`` welds the object to both hands (:class:`~uvdms_gym.physics.grasp.RigidGrasp`); a
            :class:`~uvdms_gym.physics.grip.FrictionGraspConfig` holds it by friction
            (:class:`~uvdms_gym.physics.friction_grasp.FrictionGrasp`).

    Use as a context manager or call :meth:`close` (idempotent).
    """

    def __init__(
        self,
        params: UVDMSParams | None = None,
        *,
        physics_dt: float = 0.01,
        gui: bool = False,
        arms: bool = True,
        hydro_scale: HydroScale | None = None,
        self_collision: bool = False,
        outer_collisions: bool = False,
        grasp: FrictionGraspConfig | None = None,
    ) -> None:
        if not (math.isfinite(physics_dt) and physics_dt > 0.0):
            raise ValueError(f"physics_dt must be finite and > 0, got {physics_dt!r}")
        self._params = params or UVDMSParams()
        self._arms = bool(arms)
        self._self_collision = bool(self_collision)
        self._outer = bool(outer_collisions)
        self._grasp_config = grasp
        self._dt = float(physics_dt)
        self._inv_dt = 1.0 / self._dt
        self._closed = True
        if gui:
            require_display()  # without a display PyBullet's GUI connect calls exit(): raise instead
            self._client = bullet_client.BulletClient(connection_mode=pb.GUI)
        else:
            with quiet_c_stream(sys.stdout):  # DIRECT connect prints "argv[0]=" on the C stdout
                self._client = bullet_client.BulletClient(connection_mode=pb.DIRECT)
        self._closed = False
        try:
            self._setup(hydro_scale)
        except BaseException:
            self.close()
            raise

    def _setup(self, hydro_scale: HydroScale | None) -> None:
        """Load the body and configure PyBullet (called once by the constructor)."""
        self._cid: int = self._client._client
        c = self._client
        configure_engine(c, self._dt)
        robot = load_body(c, self._params, arms=self._arms, outer=self._outer, self_collision=self._self_collision)
        self._body, self._link_index, self._joints = robot
        names = self._link_index
        self._n_joints = len(self._joints)
        self._tau_max = np.asarray(self._params.tau_max, dtype=float)[: 6 + self._n_joints]
        self._am_link = names["added_mass"]
        # moving links in the order of q (their link index equals their joint index)
        self._state_links = [self._am_link, *self._joints]
        self._r_g = np.array(self._params.vehicle.r_g, dtype=float)
        if self._grasp_config is None:
            self._grasp: Grasp = RigidGrasp(
                c, self._body, self._link_index, self._params, physics_dt=self._dt, collision=self._outer
            )
        else:
            self._grasp = FrictionGrasp(
                c,
                self._body,
                self._link_index,
                self._params,
                physics_dt=self._dt,
                collision=self._outer,
                config=self._grasp_config,
            )
        self._contacts = ContactMonitor(c, robot, self._params, self_collision=self._self_collision)
        self._obstacle_bodies = ObstacleBodies(c)
        self._markers: render.ReferenceMarkers | None = None  # created by show_reference (rendering only)
        self._has_obstacles = False
        self._t = 0.0
        self._raw: tuple | None = None  # cached raw state read, see _read_state
        self._probe: SubstepProbe | None = None  # see set_probe
        self._water = wa = Water(c, self._body, self._am_link, self._params, arms=self._arms)
        self.set_hydro_scale(hydro_scale or HydroScale())
        # compile (or load from numba's disk cache) the link-force kernel now rather than in the first step
        link_forces_world(np.zeros(7 * wa.link_table.shape[0]), wa.link_table, wa.link_forces)
        self.reset(np.zeros(6))

    # ------------------------------------------------------------------ properties
    @property
    def params(self) -> UVDMSParams:
        """The physical parameters."""
        return self._params

    @property
    def client(self) -> bullet_client.BulletClient:
        """The PyBullet client (read-only use: queries such as ``getClosestPoints``)."""
        self._check_open()
        return self._client

    @property
    def body_id(self) -> int:
        """PyBullet unique id of the UVDMS multibody."""
        return self._body

    @property
    def object_id(self) -> int | None:
        """PyBullet unique id of the gripped object, or ``None``."""
        return self._grasp.object_id

    @property
    def grasp(self) -> Grasp:
        """The gripped object and its grasp (rigid, or :class:`~uvdms_gym.physics.friction_grasp.FrictionGrasp`)."""
        return self._grasp

    @property
    def link_index(self) -> MappingProxyType[str, int]:
        """Link name -> PyBullet link index (``"vehicle"`` is the base, -1)."""
        return self._link_index

    @property
    def joint_indices(self) -> tuple[int, ...]:
        """PyBullet joint indices in the order of ``q``."""
        return tuple(self._joints)

    @property
    def n_joints(self) -> int:
        """Number of arm joints (12, or 0 for the bare vehicle)."""
        return self._n_joints

    @property
    def physics_dt(self) -> float:
        """Physics time step, s."""
        return self._dt

    @property
    def t(self) -> float:
        """Simulated time since the last reset, s."""
        return self._t

    @property
    def hydro_scale(self) -> HydroScale:
        """The current model-mismatch factors."""
        return self._water.scale

    @property
    def hydro(self) -> HydroCoefficients:
        """The hydrodynamic coefficients in use."""
        return self._water.hydro

    @property
    def current(self) -> np.ndarray:
        """The ocean current ``v_c`` (NED, m/s; zeros without a current), see :meth:`set_current`."""
        return np.array(self._water.current_ned)

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._closed

    # ------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        """Disconnect the PyBullet client (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            self._client.disconnect()  # the wrapper also forgets its id, so its __del__ will not reuse it
        except pb.error:
            pass

    def __getstate__(self) -> dict:
        """Refuse pickling and copying (``pickle``, ``cloudpickle``, ``copy.copy``, ``copy.deepcopy``).

        A copy would hold the same PyBullet client id: stepping it would move the original, and closing or
        garbage-collecting it would disconnect the original's client. Build a new simulator from the same
        arguments instead; an environment pickles by its constructor's arguments (``gymnasium.utils.EzPickle``).
        """
        raise TypeError(
            "a UVDMSSim cannot be pickled or copied: it owns a PyBullet client, which a copy would share; build a new "
            "UVDMSSim from the same arguments (environments pickle by their constructor's arguments)"
        )

    def __enter__(self) -> UVDMSSim:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("UVDMSSim is closed")

    # ------------------------------------------------------------------ hydrodynamic model
    def set_hydro_scale(self, scale: HydroScale) -> None:
        """Change the hydrodynamic model-mismatch factors (e.g. once per episode).

        Recomputes every coefficient and updates the virtual added-mass link (and the object, if present)
        with ``changeDynamics``; takes effect at the next physics step.
        """
        self._check_open()
        if not isinstance(scale, HydroScale):
            raise TypeError(f"scale must be a HydroScale, got {type(scale).__name__}")
        self._raw = None
        self._grasp.invalidate()
        self._water.set_scale(scale)
        if self._grasp.object_id is not None:
            self._grasp.set_dynamics(self._water.hydro)

    def set_current(self, v_c_ned: Sequence[float] | np.ndarray | None) -> None:
        """Set a uniform, irrotational ocean current ``v_c`` (NED, m/s); ``None`` or zeros: no current.

        From the next physics step every hydrodynamic load acts on the velocity relative to the water
        (:mod:`uvdms_gym.physics.hydro`, Current): the vehicle's damping and residual added mass on
        ``nu_r = nu - [R_NB^T v_c; 0]``, the links' and the object's Morison drag on ``v - v_c``, the object's
        axial added momentum and Munk moment on ``v_r = v - v_c``. Buoyancy and weight do not change. The current
        stays set across :meth:`reset`.

        The rigid virtual added-mass links (vehicle and object) need no change: their momentum is ``m_a v`` and,
        with ``v_c`` constant in NED, ``d/dt (m_a v_r) = m_a dv/dt``. When the current changes (a slowly varying
        current, set once per control step), its own acceleration ``m_a dv_c/dt`` is neglected, as Fossen does for
        slowly varying currents; for consistency the lagged residual terms neglect it too: the stored previous
        relative velocity and axial momentum are shifted by the change of ``v_c`` (evaluated at the present
        orientation, which differs from the previous physics step's by one step's rotation).

        Raises:
            ValueError: not a finite 3-vector.
        """
        self._check_open()
        v = (0.0, 0.0, 0.0) if v_c_ned is None else tuple(finite_vector(v_c_ned, 3, "current").tolist())
        dv_world = self._water.set_current(v)
        if dv_world is None:
            return
        _, quat, _, _, _ = self._read_state()
        self._water.shift_lag(dv_world, quat)
        if self._grasp.object_id is not None:
            self._grasp.shift_lag(dv_world, self._water.hydro)

    def set_probe(self, probe: SubstepProbe | None) -> None:
        """Call ``probe(origin, quat, nu)`` at the start of every physics substep (``None``: no call).

        ``origin`` is the body origin in PyBullet's z-up world (single precision, as ``getLinkStates`` returns it),
        ``quat`` the body's orientation ``(x, y, z, w)`` in that world and ``nu`` the body velocity
        ``(u, v, w, p, q, r)`` the substep computes anyway: the state at the substep's start time, read at no
        extra cost (the sensors of :mod:`uvdms_gym.realism` sample it). The probe must not change the simulation.
        """
        self._probe = probe

    # ------------------------------------------------------------------ reset / state
    def reset(
        self,
        eta: np.ndarray,
        nu: np.ndarray | None = None,
        q: np.ndarray | None = None,
        qdot: np.ndarray | None = None,
        *,
        with_object: bool = False,
    ) -> SimState:
        """Set the full state (NED/FRD) and the time to 0; optionally weld the object to both grippers.

        Args:
            eta: vehicle pose ``[x y z phi theta psi]``.
            nu: body velocity (default 0).
            q: joint angles ``[q_l; q_r]`` (default 0).
            qdot: joint rates (default 0).
            with_object: create the cylinder at the ``right_grasp`` frame, moving with it, and weld it to
                both ``left_grasp`` and ``right_grasp`` (two fixed constraints). The two grasp frames must
                coincide within :data:`~uvdms_gym.physics.grasp.GRASP_TOLERANCE` (e.g. equal joint angles, as at
                ``q = 0``). Without it, any existing object and its constraints are removed.

        Outer obstacles (:meth:`set_obstacles`) are removed too, before the object, so that a caller that sets them
        again after the reset (as ``uvdms/TransportObstacles-v1`` does for every episode) builds the bodies in the
        same order every episode: PyBullet's solver order follows it, and the episodes repeat bit for bit.

        Returns:
            The state after the reset.
        """
        self._check_open()
        nj = self._n_joints
        eta = finite_vector(eta, 6, "eta")
        nu = np.zeros(6) if nu is None else finite_vector(nu, 6, "nu")
        q = np.zeros(nj) if q is None else finite_vector(q, nj, "q")
        qdot = np.zeros(nj) if qdot is None else finite_vector(qdot, nj, "qdot")
        if with_object and not self._arms:
            raise ValueError("with_object=True needs the arms (arms=False was given)")
        if self._has_obstacles:  # removed before the object, re-added after it: the same body order every episode
            self._obstacle_bodies.clear()
            self._has_obstacles = False
        self._grasp.detach()
        c = self._client
        p_com, quat, v_com, w_w, r_wb = base_state(eta, nu, self._r_g)
        c.resetBasePositionAndOrientation(self._body, p_com.tolist(), quat.tolist())
        c.resetBaseVelocity(self._body, v_com.tolist(), w_w.tolist())
        for k, j in enumerate(self._joints):
            c.resetJointState(self._body, j, float(q[k]), float(qdot[k]))
        self._t = 0.0
        self._raw = None
        self._grasp.invalidate()
        self._water.reset_lag(nu, r_wb)
        if with_object:
            self._grasp.attach(self._water.hydro, self._water.current)
        self._contacts.needs_pass = True
        return self.state()

    def state(self) -> SimState:
        """The current state in NED/FRD, converted from PyBullet's base (COM) pose and velocity.

        (Double precision: ``getLinkStates`` would be one query but returns single-precision values;
        :func:`uvdms_gym.physics.state.state_from_raw` converts.)
        """
        self._check_open()
        return state_from_raw(self._read_state(), self._r_g, self._t)

    def link_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """NED position and rotation matrix (``R_N,link``) of a link frame (e.g. ``"right_grasp"``)."""
        self._check_open()
        idx = self._link_index[name]
        if idx < 0:
            st = self.state()
            return st.eta[:3], frames.euler_to_rot(st.eta[3:])
        ls = self._client.getLinkState(self._body, idx, computeForwardKinematics=1)
        r_w = frames.quat_xyzw_to_rot(np.array(ls[5]))
        return frames.world_to_ned(np.array(ls[4])), frames.body_rot_world_to_ned(r_w)

    def object_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Object pose: NED position of its centre (3) and ZYX Euler angles ``[phi, theta, psi]`` (3)."""
        p, rpy, _ = self.object_pose_rotation()
        return p, rpy

    def object_position(self) -> np.ndarray:
        """NED position of the object's centre (3)."""
        self._check_open()
        return self._grasp.position()

    def object_rotation(self) -> np.ndarray:
        """Object orientation as a rotation matrix ``R_N,object`` (NED)."""
        self._check_open()
        return self._grasp.rotation()

    def object_pose_rotation(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`object_pose` and :meth:`object_rotation` from one conversion: ``(p, rpy, R_N,object)``.

        The Euler angles are :func:`uvdms_gym.physics.frames.rot_to_euler` of the matrix, with its numpy functions.
        """
        r = self.object_rotation()
        (r00, _, _), (r10, _, _), (r20, r21, r22) = r.tolist()
        phi, psi = _arctan2(np.array([r21, r10]), np.array([r22, r00])).tolist()
        theta = -float(_arcsin(min(max(r20, -1.0), 1.0)))
        return self.object_position(), np.array([phi, theta, psi]), r

    def object_velocity(self) -> np.ndarray:
        """Object twist ``[v; w]`` (6): velocity of its centre and angular velocity, both in NED."""
        self._check_open()
        return self._grasp.velocity()

    def grasp_forces(self) -> np.ndarray:
        """Wrenches exerted by the end effectors on the object, ``(2, 6)`` rows ``[left; right]``.

        Each row is ``[force (3); moment (3)]`` in NED about the object's centre, the paper's ``F_e``
        (:meth:`uvdms_gym.physics.grasp.RigidGrasp.forces`). Zeros without an object.
        """
        self._check_open()
        return self._grasp.forces()

    def zeta(self) -> np.ndarray:
        """System velocity ``[nu; qdot]`` (a cheaper :meth:`state` for velocity loops)."""
        self._check_open()
        cid = self._cid
        ls = _get_link_states(self._body, [self._am_link], 1, 1, cid)[0]  # body frame at the origin
        r_wb = frames.quat_xyzw_to_rot(np.array(ls[1]))
        out = np.empty(6 + self._n_joints)
        out[:3] = r_wb.T @ np.array(ls[6])
        out[3:6] = r_wb.T @ np.array(ls[7])
        if self._joints:
            out[6:] = [s[1] for s in _joint_states(self._body, self._joints, cid)]
        return out

    def count_contacts(self, pairs: Sequence[tuple[str, str]] | None = None) -> int:
        """Number of touching robot-part pairs (:meth:`uvdms_gym.physics.contacts.ContactMonitor.count`).

        Args:
            pairs: link-name pairs to check (e.g. the pairs whose exact distance is near contact); default: all
                monitored pairs, i.e. right-arm vs left-arm links and arm links 1-6 vs frame plates (97 pairs,
                the pairs the 18 distances of docs/MODEL.md section 4 watch).
        """
        self._check_open()
        return self._contacts.count(pairs)

    def render_rgb(
        self, width: int = 320, height: int = 240, *, camera_yaw_deg: float = render.CAMERA_YAW_OFFSET_DEG
    ) -> np.ndarray:
        """An ``(height, width, 3)`` uint8 image from a camera beside and above the vehicle (headless).

        Translucent visuals (the hull) are composed over what lies behind them, and the reference of
        :meth:`show_reference` is drawn and kept in view when one was given (:mod:`uvdms_gym.physics.render`).

        Args:
            width: image width, pixels.
            height: image height, pixels.
            camera_yaw_deg: the camera's yaw relative to the vehicle's heading, degrees.
        """
        self._check_open()
        keep = None if self._markers is None else self._markers.keep_in_view
        eta = self.state().eta
        view, proj = render.camera_matrices(self._client, eta, int(width), int(height), keep, camera_yaw_deg)
        return render.render_frame(self._client, view, proj, int(width), int(height))

    def show_reference(self, scene: render.ReferenceScene) -> None:
        """Draw a task's reference in the frames of :meth:`render_rgb` (NED paths, points and goal pose).

        The markers are visual-only bodies (no collision shape, mass 0), created at the first call: they change no
        contact, distance or state. They stay across :meth:`reset`; a new scene replaces them.
        """
        self._check_open()
        if self._markers is None:
            self._markers = render.ReferenceMarkers(self._client, self._params.obj)
        self._markers.show(scene)

    @property
    def marker_ids(self) -> tuple[int, ...]:
        """PyBullet ids of the reference markers' bodies (empty until :meth:`show_reference`)."""
        return () if self._markers is None else self._markers.body_ids

    # ------------------------------------------------------------------ outer obstacles
    def set_obstacles(self, obstacles: Sequence[Obstacle]) -> None:
        """Replace the outer obstacles (kinematic bodies, placed at their script's pose at the current time).

        Needs ``outer_collisions=True``. An empty sequence removes them.
        """
        self._check_open()
        if obstacles and not self._outer:
            raise ValueError("obstacles need a simulator built with outer_collisions=True")
        self._obstacle_bodies.set(tuple(obstacles), self._t)
        self._has_obstacles = bool(obstacles)

    @property
    def obstacles(self) -> tuple[Obstacle, ...]:
        """The outer obstacles (empty without)."""
        return self._obstacle_bodies.obstacles

    @property
    def obstacle_ids(self) -> tuple[int, ...]:
        """PyBullet body ids of the obstacles, in the order of :attr:`obstacles`."""
        return self._obstacle_bodies.body_ids

    def obstacle_positions(self) -> np.ndarray:
        """Obstacle centres as PyBullet holds them, NED ``(K, 3)``."""
        self._check_open()
        return self._obstacle_bodies.positions()

    def count_obstacle_contacts(self, pairs: Sequence[tuple[str, int]]) -> int:
        """Number of touching (robot part, obstacle) pairs (one zero-distance ``getClosestPoints`` each).

        A part is a link name (``"vehicle"``: the hull) or ``"object"``; an obstacle is its index in :attr:`obstacles`.
        """
        self._check_open()
        return self._contacts.count_obstacles(pairs, self._obstacle_bodies.body_ids, self._grasp.require)


# Names this module held before 0.4.0 that live in other modules now: one line naming their module (utils/legacy.py).
__getattr__ = moved_names(__name__, MOVED_NAMES[__name__])
