"""The cooperative CAMPC (baseline ``campc-coop``): CAMPC for an object held by friction, with a grip-force law.

On ``uvdms/CooperativeTransport-v1`` (``grasp="friction"``) each hand holds the cylinder by friction along and about
its axis (:mod:`uvdms_gym.physics.grip`); a disagreement of the hands' motions is an internal wrench, and beyond the
friction ellipse the object slips. :class:`CooperativeCAMPC` is CAMPC (:class:`~baselines.mpc_baselines.
MPCVelocityController`) in the cooperative task space, plus three loops:

* **absolute motion**: the MPC tracks the object's reference through the right arm's object frame, as CAMPC does,
  with two corrections of its error: the offset between the object pose the kinematic model predicts (rigid grasp)
  and the measured one (``info["y"]``: what slip has moved), and an integrator on the measured pose error
  (:data:`INTEGRAL_GAIN`, clamped at :data:`INTEGRAL_LIMIT`, running only while the reference is at rest and the
  error within :data:`INTEGRAL_WINDOW`: anti-windup),
  which removes the final offset the velocity loops leave under a hydrodynamic model mismatch;
* **relative motion** (internal-force loop): the closed-chain rows ``(J_o,left - J_o,right) zeta_j = v_rel`` keep
  the hands' relative twist at an admittance command, ``v_rel = K_F f_int a`` and ``w_rel = K_M m_int a``
  (:func:`relative_twist`: ``a`` the object's axis, ``f_int`` and ``m_int`` the measured internal force and
  twisting moment, positive stretching/twisting the right end forward); the hands would give way to the internal
  wrench their tracking errors build. Measured, it slipped more than the plain rigid rows (:data:`K_FORCE`), so its
  gains are zero by default. Instead the rows carry a **relative-displacement loop**: the controller integrates the
  hands' measured relative motion along and about the axis, ``d = int (J_o,left - J_o,right) zeta dt`` (joint
  encoders and the vehicle's velocity through the kinematic model: zero while both hands stick, the difference of
  the two contacts' slips once they slide) and commands ``v_rel = -K_REL d`` (:data:`K_REL`, :data:`K_REL_TWIST`),
  so a hand that starts to slide is driven back to where it held the object instead of drifting with the velocity
  loops' errors;
* **grip**: :func:`grip_law` sizes each hand's grip force from the friction ellipse for the wrench that hand must
  transmit (its measured axial wrist force and moment, and the axial load of the object's model along the
  reference), with a safety factor, a floor, a cap below the crush force, and a slow release.

The controller reads what the robot measures (``info``'s state, the object pose ``y``, each wrist's force-torque
``hand_forces``, the grip forces ``grip``, the current ``current``) and the model/reference (the environment's
``params``, ``grasp_config``, ``reference``) — never ``info["slip"]``, ``dropped`` or the simulator.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from baselines.mpc.campc import MPCController
from baselines.mpc.config import MPCProblem
from baselines.mpc_baselines import OBSTACLE_Q_WEIGHT, OBSTACLE_R_WEIGHT, MPCVelocityController
from uvdms_gym.physics.frames import euler_to_rot, rot_error
from uvdms_gym.physics.grip import FrictionGraspConfig
from uvdms_gym.physics.params import GRAVITY, UVDMSParams

COOP_MPC_SETTINGS: dict[str, Any] = {"q_weight": OBSTACLE_Q_WEIGHT, "r_weight": OBSTACLE_R_WEIGHT}
"""[D] MPC weights of ``campc-coop`` (before any ``mpc_overrides``): the obstacle task's ``Q = 50`` and joints five
times cheaper than the transport default (:data:`~baselines.mpc_baselines.OBSTACLE_R_WEIGHT`). With the transport's
weights the friction grasp let a slow pitch oscillation of the vehicle grow (60-90 mm, period ~3 s) on random goals
with hydro +-30 %: 13 of 20 validation draws; with these, 20 of 20 (the arms take the fine correction)."""
GRIP_SAFETY = 2.0
"""[D] Safety factor of the grip law over the friction ellipse's limit (the issue's suggestion): the hand sticks
while the wrench it transmits doubles between two control steps."""
GRIP_FLOOR = 40.0
"""[D] Smallest grip force commanded, N: the environment's ``grip_initial`` (four times what holding the object
still needs), so a calm hold is as secure as at reset."""
CRUSH_MARGIN = 0.8
"""[D] The grip is capped at this fraction of ``crush_force`` (160 N of 200 N by default): a sensor error of 20 %
never crushes the object."""
GRIP_RELEASE_TIME = 1.0
"""[D] Time constant of the grip's release, s: the grip rises to the law's value at once but falls towards it with
this lag, so a wrench that oscillates faster keeps the grip at its peaks."""
FORCE_FILTER_TIME = 0.08
"""[D] Time constant of the low-pass on the wrist wrenches, s (two control steps): the weld impulses of one physics
step are noisy; the filter keeps the admittance loop from feeding that noise back."""
K_FORCE = 0.0
"""[D] Admittance gain of the internal force, m/s per N: off by default. Measured (random goals, hydro 30 %, 20
validation draws, contact-free successes / largest slip): 0 -> 20/20, 11.3 mm; 2e-4 -> 20/20, 15.1 mm; 2e-3 -> one
draw of 43.8 mm, and on single draws a negative gain slipped as much: the velocity loops already keep the hands'
relative motion consistent, and a velocity admittance integrates any bias of the wrist reading into relative motion,
which the friction contact turns into slip. The loop stays available (set the gain) for a force-controlled inner loop
where it would pay."""
K_MOMENT = 0.0
"""[D] Admittance gain of the internal twisting moment, rad/s per N m: off by default, as :data:`K_FORCE`."""
V_REL_MAX = 0.03
"""[D] Largest relative speed of the hands along the axis commanded by the admittance, m/s."""
W_REL_MAX = 0.15
"""[D] Largest relative turn rate of the hands about the axis commanded by the admittance, rad/s."""
INTEGRAL_GAIN = 0.4
"""[D] Integral gain on the measured object pose error, 1/s (a time constant of 2.5 s, slower than the MPC loop)."""
INTEGRAL_LIMIT = (0.05, np.radians(3.0))
"""[D] Anti-windup clamp of the integrator: position (m, per axis) and orientation (rad, per axis)."""
INTEGRAL_WINDOW = (0.05, np.radians(5.0))
"""[D] The integrator runs only while the position error (m) and the orientation error (rad) are below these: it
removes the small steady offset, not the transient lag of a fast move (conditional integration)."""
N_MOTION = 18
"""Motion values of the action (vehicle 6, arms 12) before the two grip commands."""
REST_STEP = 1.0e-5
"""[D] The reference is at rest (the integrator runs) while it moves less than this in one control step (m, rad):
integrating the lag of the move itself wound the integrator up and overshot the goal (paper goal: 27 mm at the
end against 3 mm without it)."""
K_REL = 10.0
"""[D] Gain of the hands' relative-displacement loop along the axis, 1/s (module docstring; 0 = off). Why: the
velocity loops of the two arms track their joints 0.1-0.5 rad/s behind their commands, and a single-step internal
force spike (up to the friction limit, whatever the grip: a constant 160 N grip slipped 23.4 mm with the first
friction model) starts a hand sliding; without the loop the contact slides on with the hands' relative tracking
error. Measured (random goals, hydro 30 %, 20 validation draws: contact-free successes, largest slip, draws above
5 mm; the paper goal's slip), with the friction model of the release (the damped slide direction,
:func:`uvdms_gym.physics.grip.slide_direction`): 0 -> 20/20, 7.6 mm, 1, 0.8 mm; 5 -> 19/20, 2.3 mm, 0, 0.2 mm;
10 -> 19/20 (one final position error of 20.6 mm, no slip), 1.5 mm, 0, 0.07 mm. With the first model (the slide
direction of the last step alone, whose bounds alternated between the two joints): 0 -> 20/20, 11.3 mm, 7;
3 -> 18/20, 5.4 mm, 1; 8 -> 20/20, 3.0 mm, 0; 10 -> 20/20, 2.1 mm, 0; 15 -> 19/20, 2.1 mm, 0."""
K_REL_TWIST = 10.0
"""[D] Gain of the hands' relative-turn loop about the axis, 1/s, as :data:`K_REL` (measured together)."""
REL_LIMIT = (0.05, 0.5)
"""[D] Clamp of the integrated relative displacement (m: the drop slip) and turn (rad) about the axis."""
AXIAL_DRAG_COEFFICIENT = 1.0
"""[D] Drag coefficient of the cylinder's end faces in axial flow (a blunt cylinder, ~0.8-1.1), for the load."""


def internal_wrench(hand_forces: np.ndarray, axis: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray]:
    """The axial components of the two wrist wrenches and their internal parts.

    Args:
        hand_forces: each hand's wrench on the object ``(2, 6)`` (``info["hand_forces"]``, NED).
        axis: the object's axis (its ``y``) in NED (3).

    Returns:
        ``(f_int, m_int, f_axial, m_axial)``: the internal force (N, + = stretch: half the right hand's axial force
        minus the left's, as ``info["internal_force"]``), the internal twisting moment (N m, same convention), and
        each hand's axial force (2) and twisting moment (2).
    """
    hf = np.asarray(hand_forces, dtype=float)
    f_axial = hf[:, :3] @ axis
    m_axial = hf[:, 3:] @ axis
    return 0.5 * float(f_axial[1] - f_axial[0]), 0.5 * float(m_axial[1] - m_axial[0]), f_axial, m_axial


def relative_twist(f_int: float, m_int: float, axis: np.ndarray) -> np.ndarray:
    """The closed-chain rows' right-hand side: the relative twist of the hands that relieves the internal wrench.

    The rows read ``(J_o,left - J_o,right) zeta``: the left hand's velocity minus the right's. A stretch
    (``f_int > 0``: the right hand pulls along ``+axis``, the left along ``-axis``) is relieved by the hands closing
    in, the left moving along ``+axis`` relative to the right; likewise for the twist.

    Args:
        f_int: internal force, N (+ = stretch).
        m_int: internal twisting moment, N m.
        axis: the object's axis in NED (3).

    Returns:
        ``[v_rel (3); w_rel (3)]`` (m/s, rad/s, NED).
    """
    v = float(np.clip(K_FORCE * f_int, -V_REL_MAX, V_REL_MAX))
    w = float(np.clip(K_MOMENT * m_int, -W_REL_MAX, W_REL_MAX))
    return np.concatenate([v * axis, w * axis])


def axial_load(params: UVDMSParams, axis: np.ndarray, accel: np.ndarray, v_rel_water: np.ndarray) -> float:
    """The axial force (N) the hands together must exert on the object to move it as the reference does.

    Weight minus buoyancy along the axis, the inertia of the reference acceleration (the object's mass; the axial
    added mass of a slender cylinder is negligible) and the end faces' drag in the relative flow.

    Args:
        params: the physical parameters (the object's size and density, the water's).
        axis: the object's axis in NED (3).
        accel: the reference acceleration of the object's centre, NED (3), m/s^2.
        v_rel_water: the object's velocity relative to the water, NED (3), m/s.

    Returns:
        The signed axial force along ``axis``, N.
    """
    obj = params.obj
    net_weight = (obj.density - params.water_density) * obj.volume * GRAVITY  # NED: down is +z
    u = float(v_rel_water @ axis)
    drag = 0.5 * params.water_density * AXIAL_DRAG_COEFFICIENT * np.pi * obj.radius**2 * u * abs(u)
    return float(net_weight * axis[2] + obj.mass * (accel @ axis) + drag)


def grip_law(
    f_axial: np.ndarray,
    m_axial: np.ndarray,
    load: float,
    f_int: float,
    config: FrictionGraspConfig,
) -> np.ndarray:
    """The grip force (N) each hand needs: the friction ellipse of its wrench, with :data:`GRIP_SAFETY`.

    Hand ``k`` must transmit the larger of its measured axial force and its model share ``|load| / 2 + |f_int|``,
    and its measured twisting moment; the grip that puts that wrench on the ellipse is
    ``sqrt((f / mu)^2 + (m / (mu r_t))^2)``, times the safety factor, floored at :data:`GRIP_FLOOR` and capped at
    :data:`CRUSH_MARGIN` times the crush force (and at ``grip_max``).

    Args:
        f_axial: each hand's measured axial force on the object (2), N.
        m_axial: each hand's measured twisting moment (2), N m.
        load: the axial load of the object's model (:func:`axial_load`), N.
        f_int: the measured internal force, N.
        config: the grasp's knobs (``mu``, ``torsion_radius``, ``crush_force``, ``grip_max``).

    Returns:
        The two grip forces, N.
    """
    mu = np.asarray(config.mu, dtype=float)
    r_t = np.asarray(config.torsion_radius, dtype=float)
    f = np.maximum(np.abs(np.asarray(f_axial, dtype=float)), 0.5 * abs(load) + abs(f_int))
    m = np.abs(np.asarray(m_axial, dtype=float))
    need = GRIP_SAFETY * np.hypot(f / mu, m / (mu * r_t))
    cap = min(CRUSH_MARGIN * config.crush_force, config.grip_max)
    return np.clip(need, min(GRIP_FLOOR, cap), cap)


class CooperativeMPC(MPCController):
    """The transport MPC with a bias on the object's pose error and a right-hand side for the closed-chain rows."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.bias = np.zeros(6)
        """Added to the pose error of every prediction step (position m; rotation vector rad, NED)."""
        self.eq_rhs = np.zeros(6)
        """The commanded relative twist of the hands (:func:`relative_twist`)."""

    def make_problem(self, *args: Any, **kwargs: Any) -> MPCProblem:
        """:meth:`MPCController.make_problem` with :attr:`bias` and :attr:`eq_rhs` applied."""
        problem = super().make_problem(*args, **kwargs)
        problem.e0[:, :6] += self.bias[None, :]
        problem.eq_rhs = self.eq_rhs.copy()
        return problem


class CooperativeCAMPC(MPCVelocityController):
    """``campc-coop``: the cooperative CAMPC with its internal-force loop and grip law (module docstring).

    The action is CAMPC's 18 velocity values followed by the two grip commands ``a = 2 F / grip_max - 1``.

    Args:
        env: an environment with the friction grasp (``env.unwrapped.grasp_config`` set) in velocity mode.
        integral: with the integrator on the measured pose error (``False``: the offset correction only).
        **kwargs: as :class:`~baselines.mpc_baselines.MPCVelocityController` (``mpc_overrides``, ``outer``,
            ``state``).

    Raises:
        ValueError: the environment holds its object rigidly (no ``grasp_config``).
    """

    def __init__(self, env: Any, integral: bool = True, **kwargs: Any) -> None:
        u = env.unwrapped
        cfg = getattr(u, "grasp_config", None)
        if cfg is None:
            raise ValueError(
                "campc-coop needs an environment with the friction grasp (grasp='friction', e.g. "
                "uvdms/CooperativeTransport-v1); this one holds its object rigidly: use 'campc'"
            )
        kwargs["mpc_overrides"] = {**COOP_MPC_SETTINGS, **(kwargs.get("mpc_overrides") or {})}
        super().__init__(env, collision=True, **kwargs)
        self.grasp = cfg
        self.integral = integral
        old = self.mpc
        self.mpc = CooperativeMPC(old.output, old.config, self.params, kin=old.kin)
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: integrators, filters and grip memory cleared; the QP solved cold."""
        super().reset(seed)
        self._integ = np.zeros(6)
        self._wrench: np.ndarray | None = None
        self._grip = np.full(2, self.grasp.grip_initial)
        self._rel = np.zeros(2)

    def _filtered_wrench(self, hand_forces: np.ndarray) -> np.ndarray:
        """The wrist wrenches through the low-pass of :data:`FORCE_FILTER_TIME`."""
        hf = np.asarray(hand_forces, dtype=float)
        if self._wrench is None:
            self._wrench = hf.copy()
        else:
            alpha = self.control_dt / (FORCE_FILTER_TIME + self.control_dt)
            self._wrench += alpha * (hf - self._wrench)
        return self._wrench

    def _pose_bias(self, info: dict[str, Any], t: float) -> np.ndarray:
        """Kinematic-minus-measured offset of the object pose plus the integrator (module docstring)."""
        kin = self.mpc.kin
        y = np.asarray(info["y"], dtype=float)
        r_meas = euler_to_rot(y[3:])
        p_kin, r_kin = kin.object_pose("right")  # the state the last make_problem set
        offset = np.concatenate([p_kin - y[:3], rot_error(r_kin, r_meas)])
        if self.integral:
            ref = np.asarray(self._env.reference(t), dtype=float)
            err = np.concatenate([ref[:3] - y[:3], rot_error(euler_to_rot(ref[3:]), r_meas)])
            ahead = np.asarray(self._env.reference(t + self.control_dt), dtype=float)
            at_rest = np.abs(ahead - ref).max() < REST_STEP
            near = np.linalg.norm(err[:3]) < INTEGRAL_WINDOW[0] and np.linalg.norm(err[3:]) < INTEGRAL_WINDOW[1]
            if at_rest and near:
                self._integ += INTEGRAL_GAIN * self.control_dt * err
            lim = np.repeat(INTEGRAL_LIMIT, 3)
            np.clip(self._integ, -lim, lim, out=self._integ)
        return offset + self._integ

    def _grip_command(self, info: dict[str, Any], axis: np.ndarray, f_int: float, fa, ma, t: float) -> np.ndarray:
        """The two grip commands in ``[-1, 1]`` from :func:`grip_law` with the slow release."""
        ts = t + self.control_dt * np.array([0.0, 1.0, 2.0])
        p = np.asarray(self._env.reference(ts), dtype=float)[:, :3]
        accel = (p[2] - 2.0 * p[1] + p[0]) / self.control_dt**2
        vel = (p[1] - p[0]) / self.control_dt
        current = np.asarray(info.get("current", np.zeros(3)), dtype=float)
        load = axial_load(self.params, axis, accel, vel - current)
        need = grip_law(fa, ma, load, f_int, self.grasp)
        decay = self.control_dt / (GRIP_RELEASE_TIME + self.control_dt)
        self._grip = np.where(need >= self._grip, need, self._grip + decay * (need - self._grip))
        return 2.0 * self._grip / self.grasp.grip_max - 1.0

    def _relative_correction(self, zeta: np.ndarray, axis: np.ndarray) -> np.ndarray:
        """The relative-displacement loop's part of the closed-chain rows' right-hand side (module docstring).

        Integrates the hands' measured relative velocity along and about the axis, ``(J_o,left - J_o,right) zeta``
        with the closed-chain matrix of the last problem (one control step old: it changes slowly), clamped at
        :data:`REL_LIMIT`, and returns ``[-K_REL d_axial axis; -K_REL_TWIST d_twist axis]`` within
        :data:`V_REL_MAX` and :data:`W_REL_MAX`.

        Args:
            zeta: the measured velocity (18) the MPC plans from.
            axis: the object's axis in NED (3).

        Returns:
            ``[v_rel (3); w_rel (3)]`` (m/s, rad/s, NED); zeros at the first step.
        """
        prev = self.mpc.last_problem
        if prev is None or prev.j_eq is None:
            return np.zeros(6)
        rel = np.asarray(prev.j_eq, dtype=float) @ np.asarray(zeta, dtype=float)
        self._rel += self.control_dt * np.array([rel[:3] @ axis, rel[3:] @ axis])
        lim = np.asarray(REL_LIMIT, dtype=float)
        np.clip(self._rel, -lim, lim, out=self._rel)
        v = float(np.clip(-K_REL * self._rel[0], -V_REL_MAX, V_REL_MAX))
        w = float(np.clip(-K_REL_TWIST * self._rel[1], -W_REL_MAX, W_REL_MAX))
        return np.concatenate([v * axis, w * axis])

    def predict(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The 18 velocity values and the two grip commands."""
        t0 = time.perf_counter()
        state = self.state(info)
        eta, q, _, t = state
        self.mpc.kin.set_state(eta, q)
        y = np.asarray(info["y"], dtype=float)
        axis = euler_to_rot(y[3:])[:, 1]
        f_int, m_int, _, _ = internal_wrench(self._filtered_wrench(info["hand_forces"]), axis)
        f_raw, _, fa, ma = internal_wrench(info["hand_forces"], axis)  # the grip reacts to the unfiltered peaks
        self.mpc.bias = self._pose_bias(info, float(info["t"]))
        rhs = relative_twist(f_int, m_int, axis) + self._relative_correction(state[2], axis)
        self.mpc.eq_rhs = rhs
        rec = self._mpc_step(info, state)
        raw = rec.zeta_cmd / self.zeta_max
        vel = np.clip(raw, -1.0, 1.0)
        grip = self._grip_command(info, axis, f_raw, fa, ma, t)
        self._record(
            rec, (time.perf_counter() - t0) * 1e6, clipped=bool(np.max(np.abs(vel - raw)) > 1e-9),
            zeta_cmd=rec.zeta_cmd, grip=self._grip.copy(), f_int=f_int, m_int=m_int, rel=self._rel.copy(),
        )  # fmt: skip
        return np.concatenate([vel, np.clip(grip, -1.0, 1.0)]).astype(np.float32)


class ConstantGrip:
    """A baseline of the rigid grasp run on a friction-grasp environment: its action plus a constant grip command.

    The ablation of ``campc-coop``: ``campc``, ``mpc``, ``hold`` (and the torque baselines) move as they would with
    the object welded, and both grippers hold ``grip_initial`` of the environment's grasp (40 N by default).

    Args:
        controller: the baseline (its action's first 18 values are used).
        config: the environment's grasp knobs.
    """

    def __init__(self, controller: Any, config: FrictionGraspConfig) -> None:
        self.controller = controller
        self.grip = np.full(2, 2.0 * config.grip_initial / config.grip_max - 1.0, dtype=np.float32)
        self.action_mode = getattr(controller, "action_mode", None)

    @property
    def last_record(self) -> dict[str, Any]:
        """The wrapped controller's record."""
        return getattr(self.controller, "last_record", {})

    @property
    def last_di(self) -> Any:
        """The wrapped controller's dynamic-inversion output (``None`` without one)."""
        return getattr(self.controller, "last_di", None)

    def reset(self, seed: int | None = None) -> None:
        """Reset the wrapped controller."""
        self.controller.reset(seed)

    def predict(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The wrapped controller's 18 values, then the two constant grip commands."""
        a = np.asarray(self.controller.predict(obs, info), dtype=np.float32)[:N_MOTION]
        return np.concatenate([a, self.grip])
