"""The kinematic MPC's data: its settings (:class:`MPCConfig`), one step's problem, QP and record.

The MPC itself is :class:`baselines.mpc.kinematic.KinematicMPC` (the model, cost and constraints in its module's
docstring); the model-based front end that fills an :class:`MPCProblem` is :class:`baselines.mpc.campc.MPCController`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from uvdms_gym.physics.params import D1, D2

N_DOF = 18
N_JOINTS = 12
N_DIS = 18
INF = 1e20
"""Bound used for "no bound" (ProxSuite and OSQP both treat it as infinite)."""


def _default_r() -> tuple[float, ...]:
    return (1.0, 1.0, 1.0, 2.0, 2.0, 2.0) + (0.05,) * N_JOINTS


@dataclass(frozen=True)
class MPCConfig:
    """Settings of the kinematic MPC (documented defaults; ``dataclasses.replace`` to vary them).

    Attributes:
        n_c: control horizon ``N_c`` (decision blocks) [MODEL: 5].
        n_p: prediction horizon ``N_p >= N_c`` [MODEL: 10].
        t_c: control period ``T_c`` in s. [D] 0.04 s (25 Hz), the environments' ``control_dt``: the MPC runs once
            per environment step and the horizon previews 0.4 s; the damper's discrete-time safety condition holds
            with margin (module docstring).
        q_weight: output weight ``Q`` (scalar or one per output row), 1/m^2 or 1/rad^2. [D] 1e3: with
            ``T_c^2 Q ~ 2.5`` the Hessian is well scaled and tracking dominates the velocity penalty.
        r_weight: velocity weight ``R`` (18): ``[nu (6); qdot (12)]``. [D] vehicle 1 (linear) and 2 (angular),
            joints 0.05: the redundancy is resolved mainly by the arms, the vehicle moves when the arms can't.
        collision: include the 18 collision rows and their slacks (CAMPC); ``False`` is plain MPC.
        collision_steps: number of control steps ``j = 0..collision_steps-1`` carrying collision rows;
            ``None`` means all ``N_c`` [D] (the applied ``zeta_0`` is always constrained).
        vbar: maximum approach speed ``vbar`` of the damper, m/s [D] 0.3.
        d1: collision-zone threshold, m [MODEL 0.05].
        d2: anti-collision-zone threshold, m [MODEL 0.12].
        k_escape: escape gain inside the collision zone, 1/s: the row becomes ``v_dis <= -k_esc (d1 - d)``
            [D] 1.0 (docs/MODEL.md's optional improvement; 0 disables it).
        lookahead: collision lookahead ``T_look``, s: when the problem carries the *measured* distance rates
            ``v_now = J_dis zeta_measured``, the damper is evaluated at ``d_eff = d - T_look max(0, v_now)``
            instead of ``d``. The low-level velocity loop (or the dynamic inversion's reference model) does not
            follow a new command at once; during its lag the current approach continues, and the damper must
            brake that much earlier. [D] 0.3 s (about three time constants of the velocity loops it covers; see
            ``docs/REPRODUCTION.md``); it only acts when the caller passes the measured velocity.
        slack_linear: linear slack penalty ``rho_1`` per unit slack (m/s) [D] 1e4 (exact penalty).
        slack_quadratic: quadratic slack penalty ``rho_2`` [D] 1e4 (keeps the QP strictly convex).
        eps_v: joint-limit velocity gain ``eps_v`` in 1/s [D] 1.0: velocity towards a limit is at most
            ``eps_v`` times the remaining range.
        joint_position_rows: include the joint-position rows over the horizon.
        closed_chain: include the closed-chain equality (transport).
        n_eq_rows: rows of the closed-chain matrix (6).
        distance_method: ``"exact"`` or ``"sampled"`` (paper Algorithm 1) for :mod:`uvdms_gym.distances`.
        distance_samples: samples per link for ``"sampled"`` [MODEL: n >= 20].
        box_constraints: pass the velocity box and ``s >= 0`` as ProxSuite box constraints (else as rows).
        eps_abs: ProxSuite absolute tolerance [D] 1e-6.
        eps_rel: ProxSuite relative tolerance [D] 0.
        max_iter: ProxSuite iteration cap.
        warm_mu_in: if set, the proximal parameter ``mu_in`` is reset to this value at every warm update [D] 1e-2
            (``None``: ProxSuite keeps the previous step's value).
        attitude_weight: weight of the vehicle roll/pitch regulation outputs added by
            :class:`baselines.mpc.campc.MPCController` (0 disables them) [D] 100 /rad^2 (the task settings of
            :func:`baselines.mpc.campc.task_config` use 0 for the circles and 10 for transport).
        posture_weight: weight of joint-posture outputs ``q -> q_nominal`` (the joint angles at the episode's
            first step) added by :class:`baselines.mpc.campc.MPCController` (0 disables them) [D] 0; a small value
            keeps the redundant arms near their initial posture (used for transport).
        outer_rows: number of velocity-damper rows for outer obstacles (CAMPC only; 0: none, the default). The
            problem's outer rows (the robot-obstacle gaps of :mod:`uvdms_gym.distances.outer`, nearest first) fill
            them; unused rows are inactive. Each has its own slack, like the inner rows.
        outer_d1: collision-zone threshold of the outer rows, m (a surface gap) [D] 0.02.
        outer_d2: anti-collision-zone threshold of the outer rows, m [D] 0.15: wider than the inner rows' because
            an obstacle approaches on its own and the vehicle, which must carry the evasion, follows slowly.
        outer_vbar: the outer rows' ``vbar``, m/s [D] 0.5: beyond ``outer_d2`` the rows must not slow the
            transport (up to 0.2 m/s).
        outer_lookahead: the outer rows' lookahead on the measured approach, s [D] 0.8: the vehicle's velocity
            loop brakes from a few tenths of a metre per second in about that time.
        max_position_error: if set, a reference governor: each row of the reference error ``e0`` is scaled down so
            that its position part is at most this long (m), so that after a large deviation (an evasion) the
            plan returns at a bounded pace instead of saturating the vehicle [D] ``None`` (off; the baselines
            set 0.1 m in environments with outer obstacles).
        outer_escape: evasion bias, m: with outer rows, each obstacle inside the outer damper's zone adds
            ``outer_escape (1 - S(gap))`` times the unit direction out of its swept path to the object's position
            error (:meth:`baselines.mpc.campc.MPCController.make_problem`) [D] 0 (off).
    """

    n_c: int = 5
    n_p: int = 10
    t_c: float = 0.04
    q_weight: float | tuple[float, ...] = 1.0e3
    r_weight: tuple[float, ...] = field(default_factory=_default_r)
    collision: bool = True
    collision_steps: int | None = None
    vbar: float = 0.3
    d1: float = D1
    d2: float = D2
    k_escape: float = 1.0
    lookahead: float = 0.3
    slack_linear: float = 1.0e4
    slack_quadratic: float = 1.0e4
    eps_v: float = 1.0
    joint_position_rows: bool = True
    closed_chain: bool = False
    n_eq_rows: int = 6
    distance_method: Literal["exact", "sampled"] = "exact"
    distance_samples: int = 20
    box_constraints: bool = True
    eps_abs: float = 1.0e-6
    eps_rel: float = 0.0
    max_iter: int = 1000
    warm_mu_in: float | None = 1.0e-2
    attitude_weight: float = 100.0
    posture_weight: float = 0.0
    outer_rows: int = 0
    outer_d1: float = 0.02
    outer_d2: float = 0.15
    outer_vbar: float = 0.5
    outer_lookahead: float = 0.8
    max_position_error: float | None = None
    outer_escape: float = 0.0

    def __post_init__(self) -> None:
        if self.n_c < 1 or self.n_p < self.n_c:
            raise ValueError(f"need 1 <= n_c <= n_p, got n_c={self.n_c}, n_p={self.n_p}")
        if self.t_c <= 0.0:
            raise ValueError("t_c must be positive")
        if len(self.r_weight) != N_DOF:
            raise ValueError(f"r_weight needs {N_DOF} entries")
        if not 0.0 <= self.d1 < self.d2:
            raise ValueError("need 0 <= d1 < d2")
        if self.collision_steps is not None and not 1 <= self.collision_steps <= self.n_c:
            raise ValueError("collision_steps must be in 1..n_c")
        if self.outer_rows < 0:
            raise ValueError(f"outer_rows must be >= 0, got {self.outer_rows}")
        if not 0.0 <= self.outer_d1 < self.outer_d2:
            raise ValueError("need 0 <= outer_d1 < outer_d2")

    @property
    def n_outer(self) -> int:
        """Number of outer-obstacle rows per collision step (0 without collision rows)."""
        return self.outer_rows if self.collision else 0

    @property
    def n_collision_steps(self) -> int:
        """Number of control steps carrying collision rows (0 for plain MPC)."""
        if not self.collision:
            return 0
        return self.n_c if self.collision_steps is None else self.collision_steps


@dataclass
class MPCProblem:
    """The data of one MPC step (everything frozen at time ``k``).

    Attributes:
        e0: reference error ``y_d(k+j) - y(k)`` for ``j = 1..N_p``, shape ``(N_p, m)`` (angles wrapped /
            rotation-error vectors).
        j_y: output Jacobian ``J_y`` (m, 18).
        q: current joint angles (12).
        j_dis: distance Jacobian ``J_dis`` (18, 18), ``v_dis = J_dis zeta`` (CAMPC only).
        d: the 18 distances, m (CAMPC only).
        j_eq: closed-chain matrix ``J_o,left - J_o,right`` (n_eq_rows, 18) (transport only).
        v_dis: measured distance rates ``J_dis zeta_measured`` (18), positive approaching (optional; used with
            ``config.lookahead``).
        outer_j_dis: outer-obstacle rows ``n^T J_P`` (``config.outer_rows``, 18), inactive rows zero.
        outer_d: their surface gaps, m (inactive rows: ``inf``).
        outer_rate: ``n^T v_obs`` per row, m/s (the gap's growth from the obstacle's own motion).
        outer_v: measured approach ``J zeta_measured - n^T v_obs`` per row (optional; lookahead).
        eq_rhs: right-hand side of the closed-chain rows, ``(J_o,left - J_o,right) zeta_j = eq_rhs`` for every
            ``j`` (n_eq_rows; ``None``: zero, the rigid chain). The cooperative CAMPC
            (:mod:`baselines.cooperative`) commands a relative twist of the hands through it.
    """

    e0: np.ndarray
    j_y: np.ndarray
    q: np.ndarray
    j_dis: np.ndarray | None = None
    d: np.ndarray | None = None
    j_eq: np.ndarray | None = None
    v_dis: np.ndarray | None = None
    outer_j_dis: np.ndarray | None = None
    outer_d: np.ndarray | None = None
    outer_rate: np.ndarray | None = None
    outer_v: np.ndarray | None = None
    eq_rhs: np.ndarray | None = None


@dataclass
class QPMatrices:
    """One step's QP ``min 1/2 x^T H x + g^T x, A x = b, l <= C x <= u, l_box <= x <= u_box``.

    When the controller uses rows instead of box constraints, ``l_box``/``u_box`` are still given (they are
    then also the first ``n`` rows of ``C``). Infinite bounds are :data:`INF`.
    """

    H: np.ndarray
    g: np.ndarray
    A: np.ndarray
    b: np.ndarray
    C: np.ndarray
    l: np.ndarray  # noqa: E741 (ProxSuite's name)
    u: np.ndarray
    l_box: np.ndarray
    u_box: np.ndarray

    def full_inequalities(self, include_box: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(C, l, u)`` with the box appended as identity rows if it is not already in ``C``.

        Args:
            include_box: append the box when ``C`` does not contain it.

        Returns:
            The stacked inequality rows and bounds.
        """
        n = self.H.shape[0]
        has_box = self.C.shape[0] >= n and np.array_equal(self.C[:n], np.eye(n))
        if has_box or not include_box:
            return self.C, self.l, self.u
        return (
            np.vstack([np.eye(n), self.C]),
            np.concatenate([self.l_box, self.l]),
            np.concatenate([self.u_box, self.u]),
        )


@dataclass
class MPCStepRecord:
    """What one MPC step returns (and what a log records).

    Attributes:
        zeta_cmd: the command ``zeta_0`` (18), clipped to the velocity box.
        status: ProxSuite status (``"solved"``, ``"max_iter"``, ...; ``"failed"`` if the solution was unusable
            and the command fell back to zero).
        solved: ``status == "solved"``.
        iterations: ProxSuite iterations (warm attempt plus the cold retry, if any).
        max_slack: largest collision slack (m/s); 0 without collision rows.
        slack: the 18 slacks (zeros without collision rows).
        solve_us: wall time of ``update`` + ``solve``, µs.
        build_us: wall time to assemble the QP, µs.
        total_us: wall time of the whole step (including kinematics and distances if the caller measured
            them), µs.
        distance_us: wall time of the distances and ``J_dis`` inside ``total_us`` (0 if the caller did not
            compute them), µs; ``total_us - solve_us - build_us - distance_us`` is the rest of the model part
            (kinematics, outputs, reference errors).
        objective: QP objective value.
        plan: the optimal ``U`` reshaped ``(N_c, 18)``.
        retried: the warm-started solve did not converge and the step was re-solved cold.
        d: the distances used (CAMPC with a model), else ``None``.
    """

    zeta_cmd: np.ndarray
    status: str
    solved: bool
    iterations: int
    max_slack: float
    slack: np.ndarray
    solve_us: float
    build_us: float
    total_us: float
    objective: float
    plan: np.ndarray
    retried: bool = False
    d: np.ndarray | None = None
    distance_us: float = 0.0

    def as_dict(self) -> dict[str, float | int | str | bool]:
        """Scalar fields for logging (``info`` dicts, JSON)."""
        return {
            "status": self.status,
            "solved": self.solved,
            "iterations": self.iterations,
            "max_slack": self.max_slack,
            "solve_us": self.solve_us,
            "build_us": self.build_us,
            "total_us": self.total_us,
            "distance_us": self.distance_us,
            "objective": self.objective,
        }
