"""The physics step of :class:`uvdms_gym.physics.sim.UVDMSSim`, which inherits it from :class:`Stepping`.

Per physics step (:meth:`Stepping.step` runs ``n_substeps`` of them with the same ``tau``): one
``getLinkStates`` call reads the body origin (the ``added_mass`` link sits there) and the 12 moving links
with ``computeLinkVelocity=1, computeForwardKinematics=1``; the vehicle's loads are evaluated in plain float
arithmetic, the 12 links' in one compiled call (:func:`uvdms_gym.physics.hydro.link_forces_world`); the vehicle
wrench (control ``tau_v`` plus hydrodynamics, converted from the body frame) is applied at the body origin as
a force and a torque in ``WORLD_FRAME``, each link's drag and buoyancy at its midpoint; joint torques via
``TORQUE_CONTROL``; then ``stepSimulation``. PyBullet clears external forces *and* joint torques after every
``stepSimulation``, so all are reapplied every physics step. Every PyBullet state query copies its whole
state buffer, so the state is read once per physics state: the sanity check at the end of :meth:`Stepping.step`
caches its read, and :meth:`uvdms_gym.physics.sim.UVDMSSim.state`, the object queries and the first substep's
velocity loop reuse it until the next ``stepSimulation`` or reset (``docs/ARCHITECTURE.md``, Performance). With an
ocean current (:meth:`uvdms_gym.physics.sim.UVDMSSim.set_current`) the same loads act on the velocities relative
to the water; without one the step runs exactly the formulas above (one flag test per load group, no extra
arithmetic).

:class:`Stepping` holds only methods: it reads and writes the attributes the simulator's constructor sets (the
PyBullet ids, the joints, the :class:`~uvdms_gym.physics.water.Water`, the grasp, the obstacle bodies, the time and
the cached state read), declared below. One class keeps the hot path free of calls between objects.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np
import pybullet as pb

from uvdms_gym.physics.contacts import ContactMonitor
from uvdms_gym.physics.grasp import Grasp
from uvdms_gym.physics.hydro import link_forces_world
from uvdms_gym.physics.obstacle_bodies import ObstacleBodies
from uvdms_gym.physics.state import NU_LIMIT, StepInfo, blew_up, check_bounds, saturate
from uvdms_gym.physics.water import Water
from uvdms_gym.utils.validation import finite_vector

_WORLD = pb.WORLD_FRAME
_TORQUE = pb.TORQUE_CONTROL
_get_link_states = pb.getLinkStates
_apply_force = pb.applyExternalForce
_apply_torque = pb.applyExternalTorque
_motor_array = pb.setJointMotorControlArray
_step_simulation = pb.stepSimulation
_joint_states = pb.getJointStates
_base_pose = pb.getBasePositionAndOrientation
_base_velocity = pb.getBaseVelocity
_chain = itertools.chain.from_iterable
_fromiter = np.fromiter

SubstepProbe = Callable[[tuple, tuple, tuple], None]
"""``probe(origin, quat_xyzw, nu)`` at the start of a physics substep (:meth:`UVDMSSim.set_probe`)."""


class Stepping:
    """Stepping of the simulator: :meth:`step`, :meth:`bare_step` and the physics step they run."""

    _cid: int
    _body: int
    _joints: list[int]
    _state_links: list[int]
    _tau_max: np.ndarray
    _dt: float
    _inv_dt: float
    _t: float
    _raw: tuple | None
    _r_g: np.ndarray
    _water: Water
    _grasp: Grasp
    _contacts: ContactMonitor
    _obstacle_bodies: ObstacleBodies
    _has_obstacles: bool
    _fb_tau: np.ndarray
    _fb_saturated: np.ndarray
    _probe: SubstepProbe | None

    def _check_open(self) -> None:  # pragma: no cover - the simulator's
        raise NotImplementedError

    def _read_state(self) -> tuple:
        """Raw PyBullet state ``(p_com, quat, v_com, w, joint_states)``, read once per physics state.

        The read is cached until the state changes (a physics step or a reset): :meth:`step` reads it for its
        sanity check, and the :meth:`~uvdms_gym.physics.sim.UVDMSSim.state` that follows, and the velocity loop of
        the next step's first substep, reuse it instead of querying PyBullet again.
        """
        raw = self._raw
        if raw is None:
            cid, body = self._cid, self._body
            p_com, quat = _base_pose(body, cid)
            v_com, w_w = _base_velocity(body, cid)
            js = _joint_states(body, self._joints, cid) if self._joints else ()
            raw = self._raw = (p_com, quat, v_com, w_w, js)
        return raw

    def bare_step(self) -> None:
        """One ``stepSimulation`` with no hydrodynamics and no inputs (for benchmarks; advances ``t``)."""
        _step_simulation(self._cid)
        self._raw = None
        self._grasp.invalidate()
        self._t += self._dt
        if self._has_obstacles:
            self._obstacle_bodies.place(self._t)

    def step(
        self,
        tau: np.ndarray,
        n_substeps: int = 1,
        feedback: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> StepInfo:
        """Apply the generalized force ``tau`` for ``n_substeps`` physics steps.

        Args:
            tau: ``[tau_v (6, body-frame wrench about the body origin); tau_q left (6); tau_q right (6)]``
                (6 components for the bare vehicle). Saturated at ``params.tau_max``.
            n_substeps: number of physics steps (``>= 1``) with this input.
            feedback: optional ``zeta -> tau`` law evaluated at every physics step on the velocity the step
                reads anyway (a velocity loop at the physics rate without a second state query). ``tau`` is
                then only the input of a controller that ignores it (pass zeros); the returned ``tau`` is the
                last substep's and ``saturated`` the union over substeps.

        Returns:
            What was applied (saturated components are reported, never silently clipped).

        Raises:
            ValueError: ``tau`` has the wrong shape or contains NaN/inf; bad ``n_substeps``.
            PhysicsError: the state became non-finite or left the sanity bounds (reset required).
        """
        self._check_open()
        tau_max = self._tau_max
        try:
            tau = np.array(tau, dtype=float)  # a copy: the caller's array is never modified
        except (TypeError, ValueError):
            pass  # finite_vector below names the problem
        if not isinstance(tau, np.ndarray) or tau.shape != tau_max.shape:
            tau = finite_vector(tau, tau_max.size, "tau")  # raises the detailed ValueError
        if int(n_substeps) != n_substeps or n_substeps < 1:
            raise ValueError(f"n_substeps must be an integer >= 1, got {n_substeps!r}")
        clipped = saturate(tau, tau_max)
        if clipped is None:
            finite_vector(tau, tau_max.size, "tau")  # raises the ValueError naming the NaN and inf entries
        tau, saturated = clipped
        tau_list = tau.tolist()
        tau_v, tau_q = tau_list[:6], tau_list[6:]
        self._fb_saturated = saturated
        substep = self._substep
        for _ in range(int(n_substeps)):
            substep(tau_v, tau_q, feedback)
        self._contacts.needs_pass = False
        if feedback is not None:
            tau, saturated = self._fb_tau, self._fb_saturated
        self._check_state()
        return StepInfo(tau=tau, saturated=saturated, t=self._t, n_substeps=int(n_substeps))

    def _feedback(
        self, feedback: Callable[[np.ndarray], np.ndarray], nu: tuple[float, ...]
    ) -> tuple[list[float], list[float]]:
        """Evaluate a per-substep feedback law at ``zeta = [nu; qdot]``; validate and saturate its output.

        ``qdot`` comes from the cached state read when there is one (the first substep of a step follows the
        previous step's state check), else from one ``getJointStates``.
        """
        if self._joints:
            raw = self._raw
            js = raw[4] if raw is not None else _joint_states(self._body, self._joints, self._cid)
            z = np.array([*nu, *[s[1] for s in js]])
        else:
            z = np.array(nu)
        t = np.asarray(feedback(z), dtype=float)
        tau_max = self._tau_max
        if t.shape != tau_max.shape:
            raise ValueError(f"feedback must return a finite tau of shape {tau_max.shape}, got {t!r}")
        clipped = saturate(t, tau_max)
        if clipped is None:
            raise ValueError(f"feedback must return a finite tau of shape {tau_max.shape}, got {t!r}")
        if clipped[0] is not t:  # saturated
            t = clipped[0]
            self._fb_saturated = self._fb_saturated | clipped[1]
        self._fb_tau = t
        t_list = t.tolist()
        return t_list[:6], t_list[6:]

    # hot path: over 80 lines, one function so that every physics step runs without a Python call per load group
    def _substep(
        self, tau_v: list[float], tau_q: list[float], feedback: Callable[[np.ndarray], np.ndarray] | None = None
    ) -> None:
        """One physics step: read state, evaluate hydrodynamics (see :mod:`uvdms_gym.physics.hydro`), apply, step.

        The vehicle in plain float arithmetic on the tuples PyBullet returns (numpy's per-call overhead exceeds
        the arithmetic on these 3-vectors), the links in one compiled call; both in the operation order of
        :mod:`uvdms_gym.physics.hydro`'s reference functions.
        """
        cid, body = self._cid, self._body
        st = _get_link_states(body, self._state_links, 1, 1, cid)
        origin, (qx, qy, qz, qw), _, _, _, _, (vx, vy, vz), (wx, wy, wz) = st[0]
        # R_WB of the body (the added_mass link's frame is the body frame at the origin)
        xx, yy, zz, xy, xz, yz = qx * qx, qy * qy, qz * qz, qx * qy, qx * qz, qy * qz
        sx, sy, sz = qw * qx, qw * qy, qw * qz
        r00, r01, r02 = 1.0 - 2.0 * (yy + zz), 2.0 * (xy - sz), 2.0 * (xz + sy)
        r10, r11, r12 = 2.0 * (xy + sz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - sx)
        r20, r21, r22 = 2.0 * (xz - sy), 2.0 * (yz + sx), 1.0 - 2.0 * (xx + yy)
        # body velocity nu = R^T v (velocity of the origin, angular velocity)
        u = r00 * vx + r10 * vy + r20 * vz
        v = r01 * vx + r11 * vy + r21 * vz
        w = r02 * vx + r12 * vy + r22 * vz
        p = r00 * wx + r10 * wy + r20 * wz
        q = r01 * wx + r11 * wy + r21 * wz
        r = r02 * wx + r12 * wy + r22 * wz
        if not abs(u) + abs(v) + abs(w) + abs(p) + abs(q) + abs(r) < 6.0 * NU_LIMIT:
            self._fail(f"body velocity out of bounds or non-finite: nu = {[u, v, w, p, q, r]}")
        if self._probe is not None:
            self._probe(origin, (qx, qy, qz, qw), (u, v, w, p, q, r))
        if feedback is not None:
            tau_v, tau_q = self._feedback(feedback, (u, v, w, p, q, r))
        wa = self._water
        if wa.has_current:  # from here on (u, v, w) is relative to the water: nu_r = nu - [R_NB^T v_c; 0]
            kx, ky, kz = wa.current_world  # R_WB^T v_c,W = R_NB^T v_c,NED
            u, v, w = (
                u - (r00 * kx + r10 * ky + r20 * kz),
                v - (r01 * kx + r11 * ky + r21 * kz),
                w - (r02 * kx + r12 * ky + r22 * kz),
            )
        # vehicle: damping + residual added mass (hydro.vehicle_wrench, inlined) + control
        inv_dt = self._inv_dt
        u0, v0, w0 = wa.nu_prev
        wa.nu_prev = (u, v, w)
        dl0, dl1, dl2, dl3, dl4, dl5, dq0, dq1, dq2, dq3, dq4, dq5, a1, a2, a3, up, cx, cy, cz = wa.vehicle_consts
        p1, p2, p3 = a1 * u, a2 * v, a3 * w
        t0, t1, t2, t3, t4, t5 = tau_v
        fx = t0 - (dl0 + dq0 * abs(u)) * u - a1 * (u - u0) * inv_dt + (p2 * r - p3 * q)
        fy = t1 - (dl1 + dq1 * abs(v)) * v - a2 * (v - v0) * inv_dt + (p3 * p - p1 * r)
        fz = t2 - (dl2 + dq2 * abs(w)) * w - a3 * (w - w0) * inv_dt + (p1 * q - p2 * p)
        mx = t3 - (dl3 + dq3 * abs(p)) * p + (p2 * w - p3 * v)
        my = t4 - (dl4 + dq4 * abs(q)) * q + (p3 * u - p1 * w)
        mz = t5 - (dl5 + dq5 * abs(r)) * r + (p1 * v - p2 * u)
        # upward hydrostatic force up at its body-fixed centroid c (world z up)
        ox = r00 * cx + r01 * cy + r02 * cz
        oy = r10 * cx + r11 * cy + r12 * cz
        apply_force = _apply_force
        apply_force(
            body,
            -1,
            (r00 * fx + r01 * fy + r02 * fz, r10 * fx + r11 * fy + r12 * fz, r20 * fx + r21 * fy + r22 * fz + up),
            origin,
            _WORLD,
            cid,
        )
        _apply_torque(
            body,
            -1,
            (
                r00 * mx + r01 * my + r02 * mz + oy * up,
                r10 * mx + r11 * my + r12 * mz - ox * up,
                r20 * mx + r21 * my + r22 * mz,
            ),
            _WORLD,
            cid,
        )
        # arm links: buoyancy at the midpoint (= COM) + Morison drag (hydro.link_forces_world, compiled)
        if tau_q:
            links = st[1:]
            forces = wa.link_forces
            states = _fromiter(_chain([ls[1] + ls[6] for ls in links]), float, wa.n_link_state)
            if wa.has_current:  # Morison drag on the midpoint velocity relative to the water
                states.reshape(-1, 7)[:, 4:] -= wa.current_world
            link_forces_world(states, wa.link_table, forces)
            world = _WORLD
            for link, force, ls in zip(self._joints, forces.tolist(), links):
                apply_force(body, link, force, ls[0], world, cid)
            _motor_array(body, self._joints, _TORQUE, forces=tau_q, physicsClientId=cid)
        grasp = self._grasp
        if grasp.object_id is not None:
            grasp.apply_hydro(wa.hydro, wa.current)
        _step_simulation(cid)
        self._raw = None
        grasp.invalidate()
        self._t += self._dt
        if self._has_obstacles:
            self._obstacle_bodies.place(self._t)

    def _fail(self, message: str) -> None:
        raise blew_up(self._t, message)

    def _check_state(self) -> None:
        """Raise :class:`~uvdms_gym.physics.state.PhysicsError` if the state is non-finite or beyond the bounds."""
        raw_object = self._grasp.read() if self._grasp.object_id is not None else None
        check_bounds(self._read_state(), self._r_g, self._t, raw_object)  # the read is cached for state()
