"""Model-based front end of the kinematic MPC: state + reference window -> :class:`~baselines.mpc.config.MPCProblem`.

:class:`MPCController` owns a :class:`~uvdms_gym.physics.kinematics.KinematicModel` and a
:class:`~baselines.mpc.kinematic.KinematicMPC`; each :meth:`MPCController.step` runs kinematics, (CAMPC) distances and
``J_dis``, builds the QP and solves it. Tracked outputs:

* ``"ee_positions"`` (circle tasks): ``y = [p_left; p_right]`` (6), ``J_y`` = the linear rows of ``J``;
* ``"object_pose"`` (transport): ``y = [p_o; orientation]`` with the reference given as ZYX Euler angles; the
  orientation error is the rotation-error vector ``rot_error(R_d, R_o)`` (wrapped, in NED) and ``J_y`` is the
  object Jacobian ``J_o`` (through the right arm) whose angular rows integrate it. The closed-chain equality
  uses ``J_o,left - J_o,right``.

With ``config.attitude_weight > 0`` two outputs are appended: vehicle roll and pitch regulated to zero
(``[phi, theta]_dot = T(eta2)[0:2] nu2``), as in the paper's transport run.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Literal

import numpy as np

from baselines.mpc.config import MPCConfig, MPCProblem, MPCStepRecord
from baselines.mpc.damper import damper_shape
from baselines.mpc.kinematic import KinematicMPC
from uvdms_gym import distances
from uvdms_gym.distances.outer import OuterDistances, compute_outer_distances, outer_distance_jacobian
from uvdms_gym.physics.frames import euler_rate_matrix, euler_to_rot_batch, rot_error_batch
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.params import UVDMSParams

OutputKind = Literal["ee_positions", "object_pose"]
N_JOINTS_POSTURE = 12
"""Posture outputs (one per joint) added with ``posture_weight > 0``."""


class MPCController:
    """Kinematic MPC (``config.collision=False``) or CAMPC (``True``) on the UVDMS kinematic model.

    Attributes:
        output: the tracked output kind.
        config: the MPC settings.
        kin: the kinematic model (its state is the last step's).
        mpc: the QP core (one ProxSuite object, allocated once).
        last_distances: the :class:`~uvdms_gym.distances.DistanceResult` of the last CAMPC step.
        last_distance_us: wall time of the last step's distances and ``J_dis``, µs (0 for plain MPC).
    """

    def __init__(
        self,
        output: OutputKind = "ee_positions",
        config: MPCConfig | None = None,
        params: UVDMSParams | None = None,
        kin: KinematicModel | None = None,
    ) -> None:
        """Build the controller.

        Args:
            output: ``"ee_positions"`` (circle tasks) or ``"object_pose"`` (transport).
            config: MPC settings; for ``"object_pose"`` the closed-chain equality is switched on.
            params: physical parameters; defaults to :class:`UVDMSParams`.
            kin: a kinematic model to reuse (its state is overwritten every step); built if ``None``.
        """
        if output not in ("ee_positions", "object_pose"):
            raise ValueError(f"output must be 'ee_positions' or 'object_pose', got {output!r}")
        cfg = config or MPCConfig()
        if output == "object_pose" and not cfg.closed_chain:
            cfg = replace(cfg, closed_chain=True)
        self.output = output
        self.config = cfg
        self.params = params or UVDMSParams()
        self.kin = kin or KinematicModel(self.params)
        self.n_att = 2 if cfg.attitude_weight > 0.0 else 0
        self.n_post = N_JOINTS_POSTURE if cfg.posture_weight > 0.0 else 0
        m = 6 + self.n_att + self.n_post
        qw = np.ones(m)
        qw[:6] = np.broadcast_to(np.asarray(cfg.q_weight, dtype=float), (6,))
        qw[6 : 6 + self.n_att] = cfg.attitude_weight
        qw[6 + self.n_att :] = cfg.posture_weight
        self.q_nominal: np.ndarray | None = None
        # constant rows of J_y (the posture outputs' identity); copied and completed at every step
        self._j_y_template = np.zeros((m, 18))
        if self.n_post:
            self._j_y_template[6 + self.n_att :, 6:] = np.eye(N_JOINTS_POSTURE)
        self.mpc = KinematicMPC(replace(cfg, q_weight=tuple(qw)), self.params, n_outputs=m)
        self.last_distances: distances.DistanceResult | None = None
        self.last_problem: MPCProblem | None = None
        self.last_distance_us = 0.0
        self.last_outer: OuterDistances | None = None

    def reset(self) -> None:
        """Start a new episode (the next solve is cold; the QP object is kept)."""
        self.mpc.reset()
        self.q_nominal = None
        self.last_distances = None
        self.last_problem = None

    def output_and_jacobian(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Current output ``y`` (positions; for a pose the rotation is returned separately) and ``J_y``.

        Returns:
            ``(y, J_y, R)``: ``y`` (6) with the orientation part zero for ``"object_pose"`` (its error is
            computed from ``R``), ``J_y`` (6, 18), ``R`` the object rotation or ``None``.
        """
        kin = self.kin
        if self.output == "ee_positions":
            j = kin.ee_jacobian()
            return kin.ee_positions().ravel(), j[[0, 1, 2, 6, 7, 8]], None
        p, r = kin.object_pose("right")
        y = np.concatenate([p, np.zeros(3)])
        return y, kin.object_jacobian("right"), r

    def make_problem(
        self,
        eta: np.ndarray,
        q: np.ndarray,
        y_ref: np.ndarray,
        zeta: np.ndarray | None = None,
        obstacles: np.ndarray | None = None,
    ) -> MPCProblem:
        """Set the kinematic state and assemble the step's problem (kinematics, distances, ``J_dis``).

        Args:
            eta: vehicle pose (6).
            q: joint angles (12).
            y_ref: reference at ``t + j T_c``, ``j = 1..N_p``, shape ``(N_p, 6)``: ``[p_l; p_r]`` or
                ``[x y z phi theta psi]`` (ZYX Euler, rad) for ``"object_pose"``.
            zeta: measured velocity (18), optional: gives the measured distance rates for the collision
                lookahead (:attr:`~baselines.mpc.config.MPCConfig.lookahead`).
            obstacles: measured outer obstacles, ``info["obstacles"]`` rows (``(K, 11)``: centre, velocity, radius,
                half length, axis); used with ``config.outer_rows > 0``.

        Returns:
            The problem (also kept as :attr:`last_problem`).
        """
        cfg = self.config
        eta = np.asarray(eta, dtype=float)
        q = np.asarray(q, dtype=float)
        y_ref = np.asarray(y_ref, dtype=float)
        if y_ref.shape != (cfg.n_p, 6):
            raise ValueError(f"y_ref must have shape ({cfg.n_p}, 6), got {y_ref.shape}")
        kin = self.kin
        kin.set_state(eta, q)
        y, jy, rot = self.output_and_jacobian()
        m = 6 + self.n_att + self.n_post
        e0 = np.empty((cfg.n_p, m))
        j_y = self._j_y_template.copy()
        j_y[:6] = jy
        if rot is None:
            e0[:, :6] = y_ref - y[None, :]
        else:
            e0[:, :3] = y_ref[:, :3] - y[None, :3]
            e0[:, 3:6] = rot_error_batch(euler_to_rot_batch(y_ref[:, 3:6]), rot)
        if self.n_att:
            t = euler_rate_matrix(eta[3:6])
            j_y[6:8, 3:6] = t[:2]
            e0[:, 6:8] = -eta[None, 3:5]
        if self.n_post:
            if self.q_nominal is None:
                self.q_nominal = q.copy()
            e0[:, 6 + self.n_att :] = (self.q_nominal - q)[None, :]
        if cfg.max_position_error is not None:
            _govern(e0, cfg.max_position_error, rot is None)
        problem = MPCProblem(e0=e0, j_y=j_y, q=q)
        if cfg.collision:
            self._collision_rows(problem, zeta, obstacles)
        if cfg.closed_chain:  # J_o,left - J_o,right; for "object_pose" J_y's first rows are J_o,right already
            j_right = jy if rot is not None else kin.object_jacobian("right")
            problem.j_eq = kin.object_jacobian("left") - j_right
        self.last_problem = problem
        return problem

    def _collision_rows(self, problem: MPCProblem, zeta: np.ndarray | None, obstacles: np.ndarray | None) -> None:
        """The inner rows (distances, ``J_dis``, measured rates) and, with ``outer_rows``, the outer ones."""
        cfg, kin = self.config, self.kin
        t0 = time.perf_counter()
        res = distances.compute_distances(kin, cfg.distance_method, cfg.distance_samples)
        problem.d = res.d
        problem.j_dis = distances.distance_jacobian(kin, res)
        self.last_distance_us = (time.perf_counter() - t0) * 1e6
        if zeta is not None:
            problem.v_dis = problem.j_dis @ np.asarray(zeta, dtype=float)
        self.last_distances = res
        if cfg.n_outer:
            self._outer_rows(problem, obstacles, zeta)

    def _outer_rows(self, problem: MPCProblem, obstacles: np.ndarray | None, zeta: np.ndarray | None) -> None:
        """Fill the problem's outer rows: the ``outer_rows`` robot-obstacle pairs nearest over the horizon.

        Pairs are ranked by the gap the obstacle's own motion leaves at the end of the control horizon plus the
        lookahead, ``d + min(0, n^T v_obs) (N_c T_c + T_look)``; unused rows stay inactive (``d = inf``).
        """
        cfg, m = self.config, self.config.n_outer
        problem.outer_j_dis = np.zeros((m, 18))
        problem.outer_d = np.full(m, np.inf)
        problem.outer_rate = np.zeros(m)
        self.last_outer = None
        if obstacles is None or len(obstacles) == 0:
            return
        res = compute_outer_distances(self.kin, obstacles, self.output == "object_pose")
        jac, rate = outer_distance_jacobian(self.kin, res, obstacles)
        horizon = cfg.n_c * cfg.t_c + cfg.outer_lookahead
        pick = np.argsort(res.d + np.minimum(rate, 0.0) * horizon, kind="stable")[:m]
        k = pick.size
        problem.outer_j_dis[:k] = jac[pick]
        problem.outer_d[:k] = res.d[pick]
        problem.outer_rate[:k] = rate[pick]
        if zeta is not None:
            problem.outer_v = problem.outer_j_dis @ np.asarray(zeta, dtype=float) - problem.outer_rate
            problem.outer_v[k:] = 0.0
        self.last_outer = res
        if cfg.outer_escape > 0.0 and self.output == "object_pose":
            approach = None if zeta is None else jac @ np.asarray(zeta, dtype=float) - rate
            problem.e0[:, :3] += self._escape(res, obstacles, approach)

    def _escape(self, res: OuterDistances, obstacles: np.ndarray, approach: np.ndarray | None = None) -> np.ndarray:
        """The evasion bias added to the object's position error (m, NED).

        For each obstacle whose nearest row lies inside the outer damper's zone, the direction that leaves its
        swept path fastest: the part of ``p - e`` (from the obstacle toward the robot) across the obstacle's
        velocity, weighted by ``1 - S``, the outer damper's shape at that row (with the lookahead on the measured
        ``approach`` of every row, when given); scaled by ``outer_escape``. Without it the reference, which the
        obstacle has just crossed, pulls the robot back in front of the obstacle, and the robot is carried along
        while it slides around (module docstring of :mod:`baselines.controllers`).
        """
        cfg = self.config
        bias = np.zeros(3)
        gaps = res.per_obstacle()
        states = np.asarray(obstacles, dtype=float).reshape(gaps.shape[0], -1)
        for k in range(gaps.shape[0]):
            i = k * res.n_parts + int(np.argmin(gaps[k]))
            v_now = None if approach is None else approach[i : i + 1]
            shape = damper_shape(self.mpc._outer_cfg, res.d[i : i + 1], v_now)[0][0]
            if shape >= 1.0:
                continue
            away = res.p[i] - res.e[i]
            v = states[k, 3:6]
            speed = float(np.linalg.norm(v))
            if speed > 1e-6:
                away = away - (away @ v) / speed**2 * v
            norm = float(np.linalg.norm(away))
            if norm > 1e-9:
                bias += (1.0 - shape) * away / norm
        return cfg.outer_escape * bias

    def step(
        self,
        eta: np.ndarray,
        q: np.ndarray,
        y_ref: np.ndarray,
        zeta: np.ndarray | None = None,
        obstacles: np.ndarray | None = None,
    ) -> MPCStepRecord:
        """One control step: kinematics, distances, QP build and warm-started solve.

        Args:
            eta: vehicle pose (6).
            q: joint angles (12).
            y_ref: the reference window (see :meth:`make_problem`).
            zeta: measured velocity (18), optional (collision lookahead).
            obstacles: measured outer obstacles (see :meth:`make_problem`), optional.

        Returns:
            The step record; ``total_us`` covers the whole step, ``distance_us`` its distances and ``J_dis``
            (CAMPC), ``d`` the distances used (CAMPC).
        """
        t0 = time.perf_counter()
        self.last_distance_us = 0.0
        problem = self.make_problem(eta, q, y_ref, zeta, obstacles)
        rec = self.mpc.solve(problem)
        rec.total_us = (time.perf_counter() - t0) * 1e6
        rec.distance_us = self.last_distance_us
        rec.d = problem.d
        return rec

    def reference_times(self, t: float) -> np.ndarray:
        """Times ``t + j T_c``, ``j = 1..N_p``, at which :meth:`step` expects the reference."""
        return t + self.config.t_c * np.arange(1, self.config.n_p + 1)


def _govern(e0: np.ndarray, max_error: float, two_points: bool) -> None:
    """Scale each row of ``e0`` in place so that its position error is at most ``max_error`` long.

    The position error is the first 3 columns (object pose), or the longer of the two end-effector errors.
    """
    if two_points:
        norm = np.maximum(np.linalg.norm(e0[:, :3], axis=1), np.linalg.norm(e0[:, 3:6], axis=1))
    else:
        norm = np.linalg.norm(e0[:, :3], axis=1)
    e0 *= np.minimum(1.0, max_error / np.maximum(norm, 1e-12))[:, None]


CIRCLE_R_WEIGHT: tuple[float, ...] = (1.0, 1.0, 1.0, 200.0, 200.0, 200.0) + (0.001, 0.5, 5.0, 0.005, 2.0, 0.005) * 2
"""[D] Velocity weight ``R`` of the circle tasks, ``[nu (6); qdot_l (6); qdot_r (6)]``, per arm
``[shoulder roll, shoulder pitch, elbow roll, elbow pitch, wrist roll, wrist pitch]``.

The vehicle translates freely (1) but hardly turns (200: its attitude stays level); each arm resolves its
redundancy with the cheap shoulder roll (0.001) and elbow/wrist pitch joints (0.005), uses the shoulder pitch
moderately (0.5) and keeps the elbow and wrist roll joints nearly still (5, 2). The arms then swing sideways about
their shoulders to follow the circles. Chosen on the simulator (``docs/REPRODUCTION.md``) among weightings that
track to the millimetre: with it, plain MPC reproduces both collisions of the paper's Fig. 6 and 9 (Case 1: right
link 3 into the right frame; Case 2: right link 5 into the left arm), which the earlier weighting (vehicle 1/2,
joints 0.05, resolving the redundancy mostly with the vehicle) did not; CAMPC avoids both with the same weights."""

TRANSPORT_Q_WEIGHT = 100.0
"""[D] Output weight ``Q`` of the transport task (1/m^2, 1/rad^2). Lower than the circle tasks' 1e3: the
transport is carried by the vehicle, whose velocity loop is slow (bandwidth 3-4 rad/s in velocity mode, the
reference model ``K_rm`` in torque mode), and a high-gain kinematic loop on top of it oscillates in pitch."""

TRANSPORT_ATTITUDE_WEIGHT = 10.0
"""[D] Weight of the vehicle roll/pitch regulation outputs in transport (the paper regulates both to zero)."""


def task_config(task: Literal["circle", "transport"], collision: bool = True, **overrides: object) -> MPCConfig:
    """The MPC settings used for a task (docs/MODEL.md section 5); ``overrides`` replace any field.

    * ``"circle"``: end-effector positions, ``Q = 1e3``, ``R =`` :data:`CIRCLE_R_WEIGHT`, no attitude or posture
      outputs, no closed chain.
    * ``"transport"``: object pose with the closed-chain equality, ``Q =`` :data:`TRANSPORT_Q_WEIGHT`, vehicle roll
      and pitch regulated (:data:`TRANSPORT_ATTITUDE_WEIGHT`) and a weak posture term (``posture_weight = 1``) so
      that the vehicle carries the object and the arms correct its pose.

    Both tuned on the simulator at ``T_c = 0.04`` s (``docs/REPRODUCTION.md``).

    Args:
        task: ``"circle"`` or ``"transport"``.
        collision: CAMPC (``True``) or plain MPC.
        **overrides: further :class:`MPCConfig` fields.

    Returns:
        The configuration.
    """
    if task == "circle":
        cfg = MPCConfig(collision=collision, r_weight=CIRCLE_R_WEIGHT, attitude_weight=0.0)
    elif task == "transport":
        cfg = MPCConfig(
            collision=collision,
            closed_chain=True,
            q_weight=TRANSPORT_Q_WEIGHT,
            attitude_weight=TRANSPORT_ATTITUDE_WEIGHT,
            posture_weight=1.0,
        )
    else:
        raise ValueError(f"task must be 'circle' or 'transport', got {task!r}")
    return replace(cfg, **overrides)  # type: ignore[arg-type]


def make_mpc_controller(
    task: Literal["circle", "transport"],
    collision: bool = True,
    params: UVDMSParams | None = None,
    **overrides: object,
) -> MPCController:
    """An :class:`MPCController` for a task (``"circle"``: end-effector positions; ``"transport"``: object pose).

    Args:
        task: ``"circle"`` or ``"transport"``.
        collision: CAMPC (``True``) or plain MPC.
        params: physical parameters.
        **overrides: :class:`MPCConfig` fields (e.g. ``t_c`` to match an environment's control period).

    Returns:
        The controller.
    """
    output: OutputKind = "ee_positions" if task == "circle" else "object_pose"
    return MPCController(output, task_config(task, collision, **overrides), params)
