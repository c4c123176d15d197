"""Kinematic model predictive control (MPC / CAMPC) of the UVDMS, docs/MODEL.md section 6 (paper Section 3.1).

:class:`KinematicMPC` is the QP; its settings and one step's data are in :mod:`baselines.mpc.config`, the damper of
the collision rows in :mod:`baselines.mpc.damper`, the ProxSuite build in :mod:`baselines.mpc.solver`. The controller
is split into four parts, each usable on its own:

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
  - transport: the closed-chain equality ``(J_o,left - J_o,right) zeta_j = 0`` for every ``j`` (right-hand side
    ``MPCProblem.eq_rhs`` when given: a commanded relative twist of the hands).

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

import time
from dataclasses import replace
from typing import Any

import numpy as np

from baselines.mpc.config import INF, N_DIS, N_DOF, N_JOINTS, MPCConfig, MPCProblem, MPCStepRecord, QPMatrices
from baselines.mpc.damper import damper_bound, damper_shape
from baselines.mpc.solver import proxsuite
from uvdms_gym.physics.params import UVDMSParams

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


def _dense_qp(cfg: MPCConfig, n: int, n_eq: int, n_in: int) -> Any:
    """A ProxSuite dense QP (``n`` variables, ``n_eq`` equalities, ``n_in`` inequalities) with ``cfg``'s settings."""
    qp = proxsuite.proxqp.dense.QP(n, n_eq, n_in, cfg.box_constraints, proxsuite.proxqp.dense.HessianType.Dense)
    qp.settings.eps_abs = cfg.eps_abs
    qp.settings.eps_rel = cfg.eps_rel
    qp.settings.max_iter = cfg.max_iter
    qp.settings.verbose = False
    return qp


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

        self._allocate_arrays(self._constant_rows())

        self.qp = _dense_qp(cfg, self.n, self.n_eq, self.n_in)
        # ``update(..., mu_in=...)`` overwrites ``settings.default_mu_in``: restored before every cold init so that
        # a reset episode repeats bit for bit
        self._default_mu = (self.qp.settings.default_mu_in, self.qp.settings.default_mu_eq)
        self._initialised = False
        self.n_steps = 0
        self.n_cold_retries = 0
        self.n_infeasible_retries = 0

    def _allocate_arrays(self, r0: int) -> None:
        """The QP's arrays, allocated once and rewritten in place by every build (ProxSuite copies them on ``update``).

        Only what depends on the step is written: the ``U`` block of ``H`` (``R`` on its diagonal), ``g[:n_u]``, the
        ``U`` part of the box, the bounds of the joint-position and collision rows, the ``J_dis`` blocks of ``C``
        (from row ``r0``) and the ``J_eq`` blocks of ``A``; the slack blocks are constant.
        """
        cfg, nc = self.config, self.config.n_c
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
            if p.eq_rhs is None:
                self._b[:] = 0.0
            else:
                self._b.reshape(-1, cfg.n_eq_rows)[:] = np.asarray(p.eq_rhs, dtype=float)
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
