"""Kinematic model predictive control (MPC / CAMPC) of the UVDMS, docs/MODEL.md section 6 (paper Section 3.1).

The controller is split into four parts, each usable on its own:

* **model** — the frozen-Jacobian prediction ``ybar(j) = y(k) + T_c J_y sum_{i<j} zeta_i`` (``j = 1..N_p``) with
  the decision ``U = [zeta_0 .. zeta_{N_c-1}]`` (``18 N_c``) and ``zeta_i = zeta_{N_c-1}`` for ``i >= N_c``. In
  matrix form ``sum_{i<j} zeta_i = (c_j^T kron I_18) U`` with the *hold matrix* ``C_hold`` (:func:`hold_matrix`,
  ``N_p x N_c``): ``c_{j,i} = 1`` for ``i < min(j, N_c - 1)`` and ``c_{j,N_c-1} = max(0, j - N_c + 1)``.
* **cost** — ``sum_{j=1..N_p} |y_d(k+j) - ybar(j)|^2_Q + sum_{j=0..N_c-1} |zeta_j|^2_R`` plus the slack penalty.
  The caller gives the *reference error* ``e0(j) = y_d(k+j) - y(k)`` (``N_p x m``) with angles already
  wrapped (for an orientation: the rotation-error vector of :func:`uvdms_gym.physics.frames.rot_error_batch`, which the
  angular
  rows of ``J_y`` integrate to first order), so the predicted error is ``e0(j) - T_c J_y sum_{i<j} zeta_i``.
* **constraints** (all on the frozen state at time ``k``):

  - joint positions ``q_min <= q + T_c sum_{i<j} qdot_i <= q_max`` for ``j = 1..N_c`` and ``j = N_p``
    (beyond ``N_c`` the prediction is affine in ``j``, so the end points cover the whole horizon); a joint
    already outside its limits gets the limit relaxed just enough to stay feasible (never tightened);
  - the velocity box ``max(-qdot_max, eps_v (q_min - q)) <= qdot_j <= min(qdot_max, eps_v (q_max - q))`` and
    ``|nu_j| <= nu_max`` for every ``j``;
  - CAMPC only: the 18 collision rows ``J_dis zeta_j - s <= S(d) vbar - k_esc max(0, d1 - d)`` (``d`` optionally
    shortened by the measured approach over a lookahead time, see below) for
    ``j = 0 .. collision_steps - 1`` (default: the whole control horizon), with **one slack per distance
    row** ``s >= 0`` shared across the steps and penalised by ``rho_1 sum s + rho_2 |s|^2 / 2`` (an exact
    penalty: ``s = 0`` whenever the hard rows are feasible and ``rho_1`` exceeds their multipliers). The
    frozen ``S(d_k)`` is used at every step ``j``; only ``zeta_0`` is applied, and its row is exact under the
    linearisation. ``k_esc`` is the optional escape velocity gain inside the collision zone (docs/MODEL.md section 4).
  - transport: the closed-chain equality ``(J_o,left - J_o,right) zeta_j = 0`` for every ``j``.

* **solver** — one ProxSuite dense QP per controller, allocated once with fixed dimensions (the mode fixes
  them: plain MPC has no collision rows and no slacks, CAMPC has both), initialised on the first step and
  then ``update`` + ``solve`` with ``InitialGuess.WARM_START_WITH_PREVIOUS_RESULT`` (``mu_in`` reset to
  ``warm_mu_in`` at each update: with the previous step's tiny ``mu_in`` ProxSuite occasionally reported a
  feasible warm-started problem as primal infeasible). If a warm solve does not reach ``"solved"``, the step is
  re-solved cold on the same object (``init`` + ``solve``), counted in ``n_cold_retries``. The velocity box is
  passed either as ProxSuite box constraints (``box_constraints=True``, the default; it works with this warm
  start, unlike an explicit ``solve(x, y, z)`` warm start) or as identity rows of ``C``.

Discrete-time safety of the damper: with ``d_{k+1} = d_k - T_c v_dis`` and ``v_dis <= S(d_k) vbar`` the
distance can never jump below ``d1`` if ``T_c vbar max_x S(x)/(x - d1) <= 1``, i.e.
``T_c vbar <= (d2 - d1) / (0.7246 pi / 2) ~= 0.88 (d2 - d1)`` (0.061 m for the defaults; the defaults give
``T_c vbar = 0.012 m``). On the real plant the command is followed with a lag (the environment's velocity loop,
or the dynamic inversion's reference model), and the approach already under way continues during it: with the
measured velocity the damper is evaluated at the distance that remains after ``lookahead`` seconds of the
current approach (:attr:`MPCConfig.lookahead`), which restores the margin on the simulator.

QP form (ProxSuite): ``min 1/2 x^T H x + g^T x`` s.t. ``A x = b``, ``l <= C x <= u`` (and ``l_box <= x <=
u_box``), ``x = [U; s]``; the objective is half the cost above (plus a constant) plus the slack penalty
``rho_1 sum s + rho_2 |s|^2 / 2``. Sizes for ``N_c = 5``, ``N_p = 10``: ``n = 108`` (90 + 18 slacks) and
``n_in = 72 + 90`` for CAMPC, ``n = 90`` and ``n_in = 72`` for plain MPC, ``n_eq = 30`` with the closed chain.
"""

from __future__ import annotations

import importlib
import sys
import time
import types
import warnings
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from uvdms_gym.physics.params import D1, D2, UVDMSParams

PORTABLE_PROXSUITE_BUILD = "proxsuite_pywrap"
"""Name of ProxSuite's Python module compiled for the base instruction set (SSE2 on x86-64), see
:func:`import_portable_proxsuite`."""


def import_portable_proxsuite() -> types.ModuleType:
    """Import ``proxsuite`` with its portable build rather than the widest SIMD build the CPU supports.

    ``proxsuite/__init__.py`` loads ``proxsuite_pywrap_avx512`` or ``proxsuite_pywrap_avx2`` when
    ``proxsuite.instructionset`` reports the instructions. Those builds are not bit-repeatable across processes:
    some of the solver's work buffers are plain ``malloc`` memory (16-byte aligned) that Eigen's AVX/AVX-512
    kernels read through unaligned maps, peeling a different number of leading elements depending on the
    address modulo 32/64 bytes, which changes the order of floating-point sums. Whether those buffers (1 to 4 MiB
    for the CAMPC transport QP) come from ``mmap`` (fixed alignment) or from the heap (any 16-byte boundary)
    depends on glibc's dynamic mmap threshold, which rises once the process has freed a large mapped block
    (importing ``scipy.stats``, ``matplotlib.pyplot`` or ``torch`` does); so the solution depended on the
    process's history and on each QP object's allocation. The portable build uses 16-byte vectors only, which
    every ``malloc`` block satisfies, and its arithmetic is the same on every x86-64 CPU (docs/REPRODUCTION.md, QP).

    The choice is made by answering ``proxsuite``'s import-time question with a stand-in
    ``proxsuite.instructionset`` module (replaced by the real one afterwards). A Python process can hold only one of the
    builds: if ``proxsuite`` was imported before this module, it is kept and a warning says which build it is.

    Returns:
        The ``proxsuite`` package.
    """
    if "proxsuite" not in sys.modules:
        stub = types.ModuleType("proxsuite.instructionset")
        stub.has_AVX512F = stub.has_AVX2 = lambda: False  # type: ignore[attr-defined]
        sys.modules[stub.__name__] = stub
        try:
            import proxsuite
        finally:
            if sys.modules.get(stub.__name__) is stub:
                del sys.modules[stub.__name__]
        importlib.import_module(stub.__name__)  # the real one, as ``proxsuite.instructionset`` for other users
    import proxsuite

    build = proxsuite_build(proxsuite)
    if build != PORTABLE_PROXSUITE_BUILD:
        warnings.warn(
            f"proxsuite was imported before baselines.mpc and uses its {build} build: MPC results are not "
            "bit-repeatable across processes (import baselines first; docs/REPRODUCTION.md, QP)",
            RuntimeWarning,
            stacklevel=2,
        )
    return proxsuite


def proxsuite_build(module: types.ModuleType) -> str:
    """Name of the compiled module behind the ``proxsuite`` package (``"proxsuite_pywrap"``, ``..._avx2``, ...)."""
    return module.proxqp.dense.QP.__module__.split(".")[1]


proxsuite = import_portable_proxsuite()
PROXSUITE_BUILD = proxsuite_build(proxsuite)
"""The ProxSuite build this process solves with."""

N_DOF = 18
N_JOINTS = 12
N_DIS = 18
INF = 1e20
"""Bound used for "no bound" (ProxSuite and OSQP both treat it as infinite)."""

_SOLVED = proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
_INFEASIBLE = proxsuite.proxqp.QPSolverOutput.PROXQP_PRIMAL_INFEASIBLE
_STATUS_NAMES = {
    proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED: "solved",
    proxsuite.proxqp.QPSolverOutput.PROXQP_MAX_ITER_REACHED: "max_iter",
    proxsuite.proxqp.QPSolverOutput.PROXQP_PRIMAL_INFEASIBLE: "primal_infeasible",
    proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE: "closest_primal_feasible",
    proxsuite.proxqp.QPSolverOutput.PROXQP_DUAL_INFEASIBLE: "dual_infeasible",
    proxsuite.proxqp.QPSolverOutput.PROXQP_NOT_RUN: "not_run",
}


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
            :class:`baselines.campc.MPCController` (0 disables them) [D] 100 /rad^2 (the task settings of
            :func:`baselines.campc.task_config` use 0 for the circles and 10 for transport).
        posture_weight: weight of joint-posture outputs ``q -> q_nominal`` (the joint angles at the episode's
            first step) added by :class:`baselines.campc.MPCController` (0 disables them) [D] 0; a small value
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
            error (:meth:`baselines.campc.MPCController.make_problem`) [D] 0 (off).
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


def damper_shape(cfg: MPCConfig, d: np.ndarray, v_now: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The damper's shape ``S(d_eff)`` and the distance it is evaluated at, ``d_eff``.

    Args:
        cfg: The damper's parameters (``d1``, ``d2``, ``lookahead``).
        d: the distances, m.
        v_now: measured distance rates (positive approaching); with ``cfg.lookahead > 0``,
            ``d_eff = d - lookahead max(0, v_now)``, else ``d_eff = d``.

    Returns:
        ``(S, d_eff)``.
    """
    d = np.asarray(d, dtype=float)
    if v_now is not None and cfg.lookahead > 0.0:
        d = d - cfg.lookahead * np.maximum(0.0, np.asarray(v_now, dtype=float))
    x = np.minimum(np.maximum((d - cfg.d1) / (cfg.d2 - cfg.d1), 0.0), 1.0)  # np.clip's values, cheaper
    return np.sin(0.5 * np.pi * x) ** 2, d


def damper_bound(cfg: MPCConfig, d: np.ndarray, v_now: np.ndarray | None = None) -> np.ndarray:
    """The velocity damper's bound on the approach rates: ``S(d) vbar - k_esc max(0, d1 - d)`` (18).

    Args:
        cfg: The damper's parameters (``vbar``, ``d1``, ``d2``, ``k_escape``, ``lookahead``).
        d: the distances, m.
        v_now: measured distance rates (18, positive approaching); with ``cfg.lookahead > 0`` the bound is
            evaluated at ``d - lookahead max(0, v_now)``.

    Returns:
        The bound on ``v_dis = J_dis zeta`` for each row, m/s.
    """
    s, d_eff = damper_shape(cfg, d, v_now)
    return s * cfg.vbar - cfg.k_escape * np.maximum(0.0, cfg.d1 - d_eff)


def hold_matrix(n_p: int, n_c: int) -> np.ndarray:
    """Hold matrix ``C_hold`` (N_p x N_c): ``sum_{i<j} zeta_i = sum_k C_hold[j-1, k] zeta_k`` (input held).

    Args:
        n_p: prediction horizon.
        n_c: control horizon.

    Returns:
        The matrix of counts ``c_{j,i}``.
    """
    c = np.zeros((n_p, n_c))
    for j in range(1, n_p + 1):
        c[j - 1, : min(j, n_c - 1)] = 1.0
        c[j - 1, n_c - 1] = max(0, j - n_c + 1)
    return c


class KinematicMPC:
    """The MPC/CAMPC QP: construction from an :class:`MPCProblem` and a warm-started ProxSuite solve.

    The QP object is created once in the constructor (fixed ``n``, ``n_eq``, ``n_in``) and reused; see
    :attr:`qp`.
    """

    def __init__(self, config: MPCConfig | None = None, params: UVDMSParams | None = None, n_outputs: int = 6):
        """Allocate the QP for one mode.

        Args:
            config: MPC settings; defaults to :class:`MPCConfig`.
            params: physical parameters (joint limits, velocity limits); defaults to :class:`UVDMSParams`.
            n_outputs: dimension ``m`` of the tracked output ``y`` (6 for both tasks, more with extra
                regulated outputs such as vehicle roll/pitch).
        """
        self.config = cfg = config or MPCConfig()
        self.params = params = params or UVDMSParams()
        self.m = int(n_outputs)
        qw = np.broadcast_to(np.asarray(cfg.q_weight, dtype=float), (self.m,))
        self.q_weight = np.array(qw)
        self.r_weight = np.asarray(cfg.r_weight, dtype=float)
        self.q_min = params.q_min
        self.q_max = params.q_max
        self.zeta_max = params.zeta_max

        nc, n_p = cfg.n_c, cfg.n_p
        self.n_u = N_DOF * nc
        self.n_outer = cfg.n_outer
        self._outer_cfg = replace(  # the damper of the outer rows
            cfg, d1=cfg.outer_d1, d2=cfg.outer_d2, vbar=cfg.outer_vbar, lookahead=cfg.outer_lookahead
        )
        self.n_rows_step = N_DIS + self.n_outer  # collision rows per step: the 18 inner, then the outer rows
        self.n_s = self.n_rows_step if cfg.collision else 0
        self.n = self.n_u + self.n_s
        self.n_eq = cfg.n_eq_rows * nc if cfg.closed_chain else 0
        self.hold = hold_matrix(n_p, nc)
        self._k = self.hold.T @ self.hold  # N_c x N_c
        self._k_tc2 = cfg.t_c**2 * self._k
        # Joint-position prediction steps: j = 1..N_c and N_p (affine in j beyond N_c).
        steps = list(range(1, nc + 1)) + ([n_p] if n_p > nc else [])
        self._pos_counts = self.hold[np.array(steps) - 1]  # (n_pos_steps, N_c)
        self._pos_horizon = cfg.t_c * self._pos_counts.sum(axis=1)  # time to each constrained step
        self.n_pos = N_JOINTS * len(steps) if cfg.joint_position_rows else 0
        self.n_col = self.n_rows_step * cfg.n_collision_steps
        self.n_box_rows = 0 if cfg.box_constraints else self.n
        self.n_in = self.n_box_rows + self.n_pos + self.n_col

        r0 = self._constant_rows()
        # The QP's arrays, allocated once and rewritten in place by every build (ProxSuite copies them on
        # ``update``). Only what depends on the step is written: the ``U`` block of ``H`` (``R`` on its diagonal),
        # ``g[:n_u]``, the ``U`` part of the box, the bounds of the joint-position and collision rows, the
        # ``J_dis`` blocks of ``C`` and the ``J_eq`` blocks of ``A``; the slack blocks are constant.
        self._H = np.zeros((self.n, self.n))
        if self.n_s:
            self._H[self.n_u :, self.n_u :] = cfg.slack_quadratic * np.eye(self.n_s)
        self._hu4 = self._H[: self.n_u, : self.n_u].reshape(nc, N_DOF, nc, N_DOF)  # a view of the U block
        self._hu_diag = self._H.reshape(-1)[: self.n_u * (self.n + 1) : self.n + 1]  # a view of its diagonal
        self._r_diag = np.tile(self.r_weight, nc)
        self._k_tc2_4 = np.ascontiguousarray(self._k_tc2[:, None, :, None])
        self._g = np.empty(self.n)
        self._g[self.n_u :] = cfg.slack_linear
        self._lo_box = np.zeros(self.n)
        self._hi_box = np.full(self.n, INF)  # slacks: 0 <= s
        self._lo_box_u = self._lo_box[: self.n_u].reshape(nc, N_DOF)
        self._hi_box_u = self._hi_box[: self.n_u].reshape(nc, N_DOF)
        self._lo_box_u[:, :6] = -self.zeta_max[:6]
        self._hi_box_u[:, :6] = self.zeta_max[:6]
        self._qd_max = np.array(self.zeta_max[6:], dtype=float)
        self._neg_qd_max = -self._qd_max
        self._l_pos = self._l[self._pos_rows].reshape(-1, N_JOINTS)
        self._u_pos = self._u[self._pos_rows].reshape(-1, N_JOINTS)
        self._u_col = self._u[self._col_rows].reshape(-1, self.n_rows_step)
        self._col_blocks = [
            self._C[r0 + self.n_rows_step * j : r0 + self.n_rows_step * (j + 1), N_DOF * j : N_DOF * (j + 1)]
            for j in range(cfg.n_collision_steps)
        ]
        ne = cfg.n_eq_rows
        n_eq_blocks = nc if self.n_eq else 0
        self._eq_blocks = [self._A[ne * j : ne * (j + 1), N_DOF * j : N_DOF * (j + 1)] for j in range(n_eq_blocks)]

        self.qp = proxsuite.proxqp.dense.QP(
            self.n, self.n_eq, self.n_in, cfg.box_constraints, proxsuite.proxqp.dense.HessianType.Dense
        )
        self.qp.settings.eps_abs = cfg.eps_abs
        self.qp.settings.eps_rel = cfg.eps_rel
        self.qp.settings.max_iter = cfg.max_iter
        self.qp.settings.verbose = False
        # ``update(..., mu_in=...)`` overwrites ``settings.default_mu_in``: restored before every cold init so that
        # a reset episode repeats bit for bit
        self._default_mu = (self.qp.settings.default_mu_in, self.qp.settings.default_mu_eq)
        self._initialised = False
        self.n_steps = 0
        self.n_cold_retries = 0
        self.n_infeasible_retries = 0

    def _constant_rows(self) -> int:
        """Allocate ``C``, its bounds and ``A``, ``b``, with their constant parts; return the first collision row.

        Rows of ``C``: the velocity box (when not ProxSuite box constraints), the joint-position rows, then per
        collision step the inner and outer collision rows with their slack columns ``-I``.
        """
        cfg = self.config
        self._C = np.zeros((self.n_in, self.n))
        self._l = np.full(self.n_in, -INF)
        self._u = np.full(self.n_in, INF)
        r0 = 0
        if self.n_box_rows:
            self._C[: self.n, : self.n] = np.eye(self.n)
            r0 = self.n
        self._pos_rows = slice(r0, r0 + self.n_pos)
        if self.n_pos:
            sel = np.zeros((N_JOINTS, N_DOF))
            sel[:, 6:] = np.eye(N_JOINTS)
            self._C[self._pos_rows, : self.n_u] = cfg.t_c * np.kron(self._pos_counts, sel)
        r0 += self.n_pos
        self._col_rows = slice(r0, r0 + self.n_col)
        for j in range(cfg.n_collision_steps):
            rows = slice(r0 + self.n_rows_step * j, r0 + self.n_rows_step * (j + 1))
            self._C[rows, self.n_u :] = -np.eye(self.n_rows_step)
        self._A = np.zeros((self.n_eq, self.n))
        self._b = np.zeros(self.n_eq)
        return r0

    # ------------------------------------------------------------------ reset
    def reset(self) -> None:
        """Forget the previous solution: the next step re-initialises the (same) QP object cold."""
        self._initialised = False
        self.n_steps = 0

    # ------------------------------------------------------------------ bounds
    def velocity_bounds(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Velocity box of one ``zeta`` at joint angles ``q`` (18 each).

        Joint rates: ``max(-qdot_max, eps_v (q_min - q)) <= qdot <= min(qdot_max, eps_v (q_max - q))``, each
        bound kept inside ``[-qdot_max, qdot_max]`` so that the box is never empty (outside the limits the
        joint is allowed to move back at most at full speed). Vehicle: ``|nu| <= nu_max``.

        Args:
            q: joint angles (12).

        Returns:
            ``(lo, hi)``.
        """
        lo = np.empty(N_DOF)
        hi = np.empty(N_DOF)
        lo[:6], hi[:6] = -self.zeta_max[:6], self.zeta_max[:6]
        self._joint_bounds_into(self.q_min - q, self.q_max - q, lo[6:], hi[6:])
        return lo, hi

    def _joint_bounds_into(self, to_min: np.ndarray, to_max: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
        """The joint-rate bounds of :meth:`velocity_bounds` from ``q_min - q``, ``q_max - q``, into ``lo``, ``hi``."""
        eps = self.config.eps_v
        qd_max = self._qd_max
        np.multiply(to_min, eps, out=lo)
        np.maximum(lo, self._neg_qd_max, out=lo)
        np.multiply(to_max, eps, out=hi)
        np.minimum(hi, qd_max, out=hi)
        # Out of limits (e.g. q > q_max) the raw bounds cross: keep the joint free to move back at full speed.
        np.minimum(lo, qd_max, out=lo)
        np.maximum(hi, self._neg_qd_max, out=hi)

    def collision_bound(self, d: np.ndarray, v_now: np.ndarray | None = None) -> np.ndarray:
        """Right-hand side of the collision rows: ``S(d) vbar - k_esc max(0, d1 - d)`` (18).

        Args:
            d: the 18 distances, m.
            v_now: measured distance rates (18, positive approaching); with ``config.lookahead > 0`` the bound is
                evaluated at ``d - lookahead max(0, v_now)``.

        Returns:
            The bound on ``v_dis`` for each row, m/s.
        """
        return damper_bound(self.config, d, v_now)

    # ------------------------------------------------------------------ QP
    def qp_matrices(self, problem: MPCProblem) -> QPMatrices:
        """Assemble the QP of one step (copies; the controller's own buffers are not exposed).

        Args:
            problem: the frozen data of the step.

        Returns:
            The matrices, with the velocity box both in ``l_box``/``u_box`` and, when the controller uses rows,
            in the first ``n`` rows of ``C``.
        """
        h, g, lo_box, hi_box = self._build(problem)
        return QPMatrices(
            H=h.copy(),
            g=g.copy(),
            A=self._A.copy(),
            b=self._b.copy(),
            C=self._C.copy(),
            l=self._l.copy(),
            u=self._u.copy(),
            l_box=lo_box.copy(),
            u_box=hi_box.copy(),
        )

    def _build(self, p: MPCProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Write the step's data into the preallocated QP arrays; return ``(H, g, l_box, u_box)`` (the buffers)."""
        cfg = self.config
        e0 = np.asarray(p.e0, dtype=float)
        jy = np.asarray(p.j_y, dtype=float)
        if e0.shape != (cfg.n_p, self.m) or jy.shape != (self.m, N_DOF):
            raise ValueError(f"e0 must be ({cfg.n_p}, {self.m}) and j_y ({self.m}, {N_DOF})")
        q = np.asarray(p.q, dtype=float)
        jq = jy.T * self.q_weight  # J^T Q (18, m)
        # H_u = kron(K, T_c^2 J^T Q J) + R, written in place (the slack block is constant)
        np.multiply(self._k_tc2_4, (jq @ jy)[None, :, None, :], out=self._hu4)
        self._hu_diag += self._r_diag
        g = self._g
        g[: self.n_u] = (-cfg.t_c * (jq @ (e0.T @ self.hold))).T.ravel()  # block i: -T_c J^T Q sum_j c_ji e0_j

        to_min, to_max = self.q_min - q, self.q_max - q
        lo, hi = self._lo_box_u[0], self._hi_box_u[0]  # block 0 (the vehicle part is constant), copied to the others
        self._joint_bounds_into(to_min, to_max, lo[6:], hi[6:])
        self._lo_box_u[1:] = lo
        self._hi_box_u[1:] = hi
        if self.n_box_rows:
            self._l[: self.n] = self._lo_box
            self._u[: self.n] = self._hi_box

        if self.n_pos:
            # Relax the limits just enough that the all-"v*" plan (v* = velocity nearest to zero in the box)
            # stays feasible when q is already outside its limits (never tighter than the true limits).
            v_star = np.minimum(np.maximum(0.0, lo[6:]), hi[6:])
            disp = self._pos_horizon[:, None] * v_star[None, :]  # (steps, 12)
            np.minimum(to_min, disp - 1e-9, out=self._l_pos)
            np.maximum(to_max, disp + 1e-9, out=self._u_pos)

        if self.n_col:
            self._build_collision(p)

        if self.n_eq:
            if p.j_eq is None:
                raise ValueError("closed_chain needs j_eq in the problem")
            je = np.asarray(p.j_eq, dtype=float)
            for block in self._eq_blocks:
                block[:] = je
        return self._H, g, self._lo_box, self._hi_box

    def _build_collision(self, p: MPCProblem) -> None:
        """The inner collision rows of every collision step (the same ``J_dis`` and bound), then the outer rows."""
        if p.j_dis is None or p.d is None:
            raise ValueError("CAMPC needs j_dis and d in the problem")
        jd = np.asarray(p.j_dis, dtype=float)
        for block in self._col_blocks:
            block[:N_DIS] = jd
        self._u_col[:, :N_DIS] = self.collision_bound(p.d, p.v_dis)
        if self.n_outer:
            self._build_outer(p)

    def _build_outer(self, p: MPCProblem) -> None:
        """The outer rows of every collision step ``j``: ``n^T J_P zeta_j - s <= S vbar + (1 - S) n^T v_obs - esc``.

        ``S = S(d_j)`` is the damper's shape at ``d_j = d + j T_c n^T v_obs``, the gap the obstacle's own motion
        leaves at the start of step ``j`` (predicted from its measured velocity), with ``outer_d1``, ``outer_d2``
        and the lookahead on the measured approach; ``esc = k_esc max(0, outer_d1 - d_j)``. Far from the obstacle
        (``S = 1``) the robot's own approach is limited to ``outer_vbar`` and the obstacle's motion is ignored;
        at ``outer_d1`` (``S = 0``) the robot must give way at the obstacle's approach speed, so the gap stops
        shrinking. The gap's rate is then at least ``-S (outer_vbar - n^T v_obs)``. Rows without data are
        inactive (zero row, bound ``INF``).
        """
        cfg, m = self.config, self.n_outer
        if p.outer_j_dis is None or p.outer_d is None or p.outer_rate is None:
            for block in self._col_blocks:
                block[N_DIS:] = 0.0
            self._u_col[:, N_DIS:] = INF
            return
        jo = np.asarray(p.outer_j_dis, dtype=float)
        d = np.asarray(p.outer_d, dtype=float)
        rate = np.asarray(p.outer_rate, dtype=float)
        if jo.shape != (m, N_DOF) or d.shape != (m,) or rate.shape != (m,):
            raise ValueError(f"outer rows must be ({m}, {N_DOF}), ({m},), ({m},)")
        active = np.isfinite(d)
        outer_cfg = self._outer_cfg
        for j, block in enumerate(self._col_blocks):
            block[N_DIS:] = jo
            d_j = np.where(active, d + j * cfg.t_c * rate, 0.0)
            shape, d_eff = damper_shape(outer_cfg, d_j, p.outer_v)
            bound = shape * cfg.outer_vbar + (1.0 - shape) * rate - cfg.k_escape * np.maximum(0.0, cfg.outer_d1 - d_eff)
            self._u_col[j, N_DIS:] = np.where(active, bound, INF)

    def solve(self, problem: MPCProblem) -> MPCStepRecord:
        """Build and solve one step (warm-started from the previous step's solution).

        Args:
            problem: the frozen data of the step.

        Returns:
            The step record; ``zeta_cmd`` is ``zeta_0`` clipped to the velocity box (zero if the solver
            returned no usable point).
        """
        t0 = time.perf_counter()
        h, g, lo_box, hi_box = self._build(problem)
        t1 = time.perf_counter()
        qp = self.qp
        box = (lo_box, hi_box) if self.config.box_constraints else ()
        a = self._A if self.n_eq else None
        b = self._b if self.n_eq else None
        c = self._C if self.n_in else None
        lo = self._l if self.n_in else None
        up = self._u if self.n_in else None
        iterations = 0
        retried = False
        if self._initialised:
            qp.update(h, g, a, b, c, lo, up, *box, mu_in=self.config.warm_mu_in)
            qp.solve()
            info = qp.results.info
            iterations = int(info.iter)
            if info.status != _SOLVED:
                self._initialised = False  # retry cold below (ProxSuite may misreport infeasibility warm)
                retried = True
        if not self._initialised:
            qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.NO_INITIAL_GUESS
            qp.settings.default_mu_in, qp.settings.default_mu_eq = self._default_mu
            qp.init(h, g, a, b, c, lo, up, *box)
            qp.solve()
            iterations += int(qp.results.info.iter)
            if qp.results.info.status == _INFEASIBLE:  # (the problem never is: the slacks make it feasible)
                iterations += self._solve_closest_feasible(h, g, a, b, c, lo, up, box)
            qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            self._initialised = True
        t2 = time.perf_counter()
        results = qp.results
        info = results.info
        status = _STATUS_NAMES.get(info.status, str(info.status))
        self.n_cold_retries += int(retried)
        x = results.x
        lo_v, hi_v = lo_box[:N_DOF], hi_box[:N_DOF]
        if status in ("solved", "max_iter", "closest_primal_feasible") and np.isfinite(x).all():
            zeta = np.minimum(np.maximum(x[:N_DOF], lo_v), hi_v)  # np.clip's values, cheaper
            plan = x[: self.n_u].reshape(self.config.n_c, N_DOF).copy()
            slack = x[self.n_u :].copy() if self.n_s else np.zeros(self.n_rows_step)
        else:
            status = "failed"
            zeta = np.clip(np.zeros(N_DOF), lo_v, hi_v)
            plan = np.tile(zeta, (self.config.n_c, 1))
            slack = np.zeros(self.n_rows_step)
            self._initialised = False  # do not warm start from garbage
        if status != "solved":
            self._initialised = False
        self.n_steps += 1
        return MPCStepRecord(
            zeta_cmd=zeta,
            status=status,
            solved=status == "solved",
            iterations=iterations,
            retried=retried,
            max_slack=float(max(0.0, slack.max())) if self.n_s else 0.0,
            slack=np.maximum(slack, 0.0),
            solve_us=(t2 - t1) * 1e6,
            build_us=(t1 - t0) * 1e6,
            total_us=(t2 - t0) * 1e6,
            objective=float(info.objValue),
            plan=plan,
        )

    def _solve_closest_feasible(self, h, g, a, b, c, lo, up, box) -> int:
        """Re-solve cold with ProxSuite's ``primal_infeasibility_solving``; return its iterations.

        With collision rows every problem is feasible (each row has a slack), yet ProxSuite's infeasibility test
        sometimes fires on a cold start when a row demands a fast retreat (an outer obstacle closing in; measured:
        a falling sphere 4 cm above the object, reported infeasible after 2 iterations). The setting makes it
        solve the closest feasible problem instead, which for a feasible one is the problem itself; it is turned on
        only for this retry, so the problems that solve at once are solved exactly as before.
        """
        qp = self.qp
        qp.settings.primal_infeasibility_solving = True
        try:
            qp.settings.default_mu_in, qp.settings.default_mu_eq = self._default_mu
            qp.init(h, g, a, b, c, lo, up, *box)
            qp.solve()
        finally:
            qp.settings.primal_infeasibility_solving = False
        self.n_infeasible_retries += 1
        return int(qp.results.info.iter)

    # ------------------------------------------------------------------ prediction helpers
    def predict_outputs(self, y0: np.ndarray, j_y: np.ndarray, plan: np.ndarray) -> np.ndarray:
        """Predicted outputs ``ybar(j) = y0 + T_c J_y sum_{i<j} zeta_i`` for ``j = 1..N_p`` (N_p, m).

        Args:
            y0: current output (m).
            j_y: output Jacobian (m, 18).
            plan: ``U`` as (N_c, 18).

        Returns:
            The predicted outputs.
        """
        sums = self.hold @ plan  # (N_p, 18)
        return y0[None, :] + self.config.t_c * sums @ np.asarray(j_y).T

    def predict_distances(self, d: np.ndarray, j_dis: np.ndarray, plan: np.ndarray) -> np.ndarray:
        """Linearised predicted distances ``d(j) = d - T_c J_dis sum_{i<j} zeta_i``, ``j = 1..N_p`` (N_p, 18).

        Args:
            d: current distances (18).
            j_dis: distance Jacobian (18, 18).
            plan: ``U`` as (N_c, 18).

        Returns:
            The predicted distances.
        """
        return self.predict_outputs(np.asarray(d, dtype=float), -np.asarray(j_dis), plan)
