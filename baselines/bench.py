"""Timing of the CAMPC control step, an OSQP replay of the same QP sequence, and the closed-loop real-time factor.

* :func:`benchmark_env_campc` runs the ``campc`` baseline on the simulator (``uvdms/CircleTrack-v0``, Case 1),
  times every control step (kinematics + distances + ``J_dis`` + QP build + warm-started ProxSuite solve, as
  :meth:`~baselines.mpc.campc.MPCController.step` measures it) and replays the recorded QP sequence with OSQP (set up
  once, warm-started, matrices updated in place) at the same absolute tolerance;
* :func:`benchmark_mpc` does the same on the *kinematic* model alone (the command integrated exactly with
  ``pin.integrate``, no simulator);
* :func:`real_time_factor` runs ``campc-nndi`` on ``uvdms/Transport-v0`` (simulated seconds / wall seconds);
* :func:`benchmark_all` is what ``uvdms bench mpc`` prints.

:class:`OSQPReplay` is also the independent solver used by the tests.
"""

from __future__ import annotations

import time

import numpy as np
import osqp
import scipy.sparse as sp

from baselines.mpc.config import INF, MPCConfig, MPCProblem, QPMatrices
from baselines.mpc.kinematic import KinematicMPC

_OSQP_INF = 1e30


def _csc_values(mat: np.ndarray, pattern: sp.csc_matrix) -> np.ndarray:
    """Values of a dense matrix in the order of a CSC pattern's data array."""
    cols = np.repeat(np.arange(pattern.shape[1]), np.diff(pattern.indptr))
    return np.ascontiguousarray(mat[pattern.indices, cols])


class OSQPReplay:
    """OSQP on the same QP sequence: set up once on a fixed structural pattern, then update + solve.

    The constraint matrix is ``[A; C; I]`` (equalities as ``l = u`` rows, the box as identity rows).
    """

    def __init__(self, mpc: KinematicMPC, eps_abs: float, eps_rel: float = 0.0, **settings: object) -> None:
        """Derive the sparsity patterns from an all-ones problem and store the settings.

        Args:
            mpc: the controller whose QPs are replayed (for dimensions and structure).
            eps_abs: OSQP absolute tolerance.
            eps_rel: OSQP relative tolerance.
            **settings: further OSQP settings (e.g. ``polishing=True``, ``max_iter``).
        """
        cfg = mpc.config
        ones = MPCProblem(
            e0=np.ones((cfg.n_p, mpc.m)),
            j_y=np.ones((mpc.m, 18)),
            q=np.zeros(12),
            j_dis=np.ones((18, 18)),
            d=np.ones(18),
            j_eq=np.ones((cfg.n_eq_rows, 18)),
        )
        probe = KinematicMPC(cfg, mpc.params, mpc.m)
        mats = probe.qp_matrices(ones)
        self.n = mats.H.shape[0]
        self.p_pattern = sp.csc_matrix(np.triu(mats.H != 0).astype(float))
        self.a_pattern = sp.csc_matrix(self._stack(mats)[0] != 0)
        self.settings = {"eps_abs": eps_abs, "eps_rel": eps_rel, "verbose": False, "warm_starting": True, **settings}
        self.solver: osqp.OSQP | None = None

    def _stack(self, m: QPMatrices) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        c, lo, up = m.full_inequalities(include_box=True)
        a = np.vstack([m.A, c])
        lo = np.concatenate([m.b, lo])
        up = np.concatenate([m.b, up])
        lo = np.where(lo <= -INF, -_OSQP_INF, lo)
        up = np.where(up >= INF, _OSQP_INF, up)
        return a, lo, up

    def solve(self, m: QPMatrices) -> tuple[np.ndarray, str, int, float]:
        """Solve one QP of the sequence (the first call sets OSQP up).

        Args:
            m: the step's matrices.

        Returns:
            ``(x, status, iterations, wall time of update + solve in µs)``.
        """
        a, lo, up = self._stack(m)
        px = _csc_values(np.triu(m.H), self.p_pattern)
        ax = _csc_values(a, self.a_pattern)
        t0 = time.perf_counter()
        if self.solver is None:
            p = self.p_pattern.copy()
            p.data = px
            amat = self.a_pattern.copy().astype(float)
            amat.data = ax
            self.solver = osqp.OSQP()
            self.solver.setup(p, m.g, amat, lo, up, **self.settings)
        else:
            self.solver.update(q=m.g, l=lo, u=up, Px=px, Ax=ax)
        res = self.solver.solve(raise_error=False)
        dt = (time.perf_counter() - t0) * 1e6
        return np.array(res.x), str(res.info.status), int(res.info.iter), dt


class _StepLog:
    """Per-step records of an MPC benchmark (timings, iterations, status, slack) and the QPs for OSQP."""

    def __init__(self, keep_qps: bool) -> None:
        self.keep_qps = keep_qps
        self.steps: list[float] = []
        self.solves: list[float] = []
        self.builds: list[float] = []
        self.distances: list[float] = []
        self.iters: list[int] = []
        self.statuses: list[str] = []
        self.max_slack = 0.0
        self.mats: list[QPMatrices] = []
        self.xs: list[np.ndarray] = []

    def add(self, rec, mpc: KinematicMPC, problem) -> None:
        """Record one step's :class:`MPCStepRecord` (and its QP, solved by ``mpc``, for the OSQP replay)."""
        self.steps.append(rec.total_us)
        self.solves.append(rec.solve_us)
        self.builds.append(rec.build_us)
        self.distances.append(rec.distance_us)
        self.iters.append(rec.iterations)
        self.statuses.append(rec.status)
        self.max_slack = max(self.max_slack, rec.max_slack)
        if self.keep_qps:
            assert problem is not None
            self.mats.append(mpc.qp_matrices(problem))
            self.xs.append(mpc.qp.results.x.copy())

    def stats(self) -> dict[str, float | int]:
        """Medians of the step and of its parts, iterations, status counts and the largest slack.

        The split: ``model`` (kinematics + outputs + distances + ``J_dis``) = ``distance`` (distances + ``J_dis``)
        + ``kinematics`` (the rest of the model part); ``build`` (QP assembly); ``solve`` (ProxSuite update +
        solve); ``step_excl_distance`` = step - distance. Each is the median over steps of that part.
        """
        steps, solves, builds = np.array(self.steps), np.array(self.solves), np.array(self.builds)
        dist = np.array(self.distances)
        return {
            "step_us_median": float(np.median(steps)),
            "step_us_p90": float(np.percentile(steps, 90)),
            "step_us_max": float(steps.max()),
            "solve_us_median": float(np.median(solves)),
            "build_us_median": float(np.median(builds)),
            "model_us_median": float(np.median(steps - solves - builds)),
            "distance_us_median": float(np.median(dist)),
            "kinematics_us_median": float(np.median(steps - solves - builds - dist)),
            "step_excl_distance_us_median": float(np.median(steps - dist)),
            "iterations_median": float(np.median(self.iters)),
            "iterations_max": int(max(self.iters)),
            "unsolved": int(sum(st != "solved" for st in self.statuses)),
            "max_slack": float(self.max_slack),
        }


def benchmark_mpc(
    n_steps: int = 200,
    case: int = 1,
    config: MPCConfig | None = None,
    osqp_compare: bool = True,
    warmup: int = 20,
    osqp_eps_abs: float | None = None,
) -> dict[str, float | int | str]:
    """Median cost of a CAMPC control step on the circle task, and the OSQP replay for a ratio.

    Args:
        n_steps: timed control steps (closed loop on the kinematic model, ``T_c`` apart).
        case: circle case (1 or 2).
        config: MPC settings (default: CAMPC, ``N_c = 5``, ``N_p = 10``).
        osqp_compare: also replay the QP sequence with OSQP at the same ``eps_abs``.
        warmup: untimed steps before the timed ones (start-up transient, caches).
        osqp_eps_abs: OSQP's absolute tolerance; ``None`` means ProxSuite's ``eps_abs`` (equal tolerance).

    Returns:
        A flat dict (JSON-ready): ``step_us_median`` (kinematics + distances + build + solve),
        ``step_us_p90``, ``step_us_max``, ``solve_us_median`` (ProxSuite update + solve), ``build_us_median``,
        ``model_us_median`` (kinematics + distances + ``J_dis``) split into ``distance_us_median`` and
        ``kinematics_us_median``, ``step_excl_distance_us_median``, ``iterations_median``, ``iterations_max``,
        ``unsolved`` (steps not ``"solved"``), ``cold_retries``, QP sizes, and with OSQP ``osqp_us_median``,
        ``osqp_iterations_median``, ``osqp_unsolved``, ``osqp_over_proxsuite`` (ratio of median solve times)
        and ``max_solution_diff`` (largest ``|x_osqp - x_proxsuite|_inf`` over the sequence).
    """
    import pinocchio as pin

    from baselines.mpc.campc import MPCController, task_config
    from uvdms_gym.envs.references import make_circle_task
    from uvdms_gym.physics.frames import quat_xyzw_to_rot, rot_to_euler

    cfg = config or task_config("circle")
    task = make_circle_task(case)
    ctl = MPCController("ee_positions", cfg)
    kin = ctl.kin
    eta = np.array(task.vehicle_start, dtype=float)
    q = task.q0.copy()
    config_vec = kin.configuration(eta, q)
    log = _StepLog(osqp_compare)
    for k in range(warmup + n_steps):
        y_ref = task.reference(ctl.reference_times(k * cfg.t_c))
        rec = ctl.step(eta, q, y_ref)
        if k >= warmup:
            log.add(rec, ctl.mpc, ctl.last_problem)
        config_vec = pin.integrate(kin.model, config_vec, rec.zeta_cmd * cfg.t_c)
        eta = np.concatenate([config_vec[:3], rot_to_euler(quat_xyzw_to_rot(config_vec[3:7]))])
        q = config_vec[7:].copy()
    out: dict[str, float | int | str] = {
        "case": case,
        "n_steps": n_steps,
        "n": ctl.mpc.n,
        "n_eq": ctl.mpc.n_eq,
        "n_in": ctl.mpc.n_in,
        "box_constraints": int(cfg.box_constraints),
        "eps_abs": cfg.eps_abs,
        **log.stats(),
        "cold_retries": int(ctl.mpc.n_cold_retries),
    }
    if osqp_compare:
        eps = cfg.eps_abs if osqp_eps_abs is None else osqp_eps_abs
        out.update(_osqp_replay(ctl.mpc, log.mats, log.xs, eps, cfg.eps_rel))
        out["osqp_over_proxsuite"] = out["osqp_us_median"] / out["solve_us_median"]
    return out


def benchmark_di(n_steps: int = 500, use_nn: bool = True) -> dict[str, float | int]:
    """Median cost of one dynamic-inversion tick on the UVDMS nominal model (model + network + update).

    Args:
        n_steps: timed ticks (random states near the circle task's start).
        use_nn: include the RBF network.

    Returns:
        ``{"di_us_median", "di_us_p90", "n_steps"}``.
    """
    from baselines.inner_loop.di import DIConfig, DynamicInversionController
    from uvdms_gym.physics.params import CIRCLE_Q0_LEFT_DEG, CIRCLE_Q0_RIGHT_DEG

    ctl = DynamicInversionController(DIConfig(use_nn=use_nn))
    rng = np.random.default_rng(0)
    q0 = np.radians(np.r_[CIRCLE_Q0_LEFT_DEG, CIRCLE_Q0_RIGHT_DEG])
    eta0 = np.array([2.0, 0.0, 3.0, 0.0, 0.0, 0.0])
    times = []
    for _ in range(n_steps + 10):
        eta = eta0 + rng.normal(size=6) * 0.01
        q = q0 + rng.normal(size=12) * 0.01
        zeta = rng.normal(size=18) * 0.05
        t0 = time.perf_counter()
        ctl.step(np.zeros(18), eta, q, zeta)
        times.append((time.perf_counter() - t0) * 1e6)
    arr = np.array(times[10:])
    return {"di_us_median": float(np.median(arr)), "di_us_p90": float(np.percentile(arr, 90)), "n_steps": n_steps}


def _osqp_replay(mpc: KinematicMPC, mats: list[QPMatrices], xs: list[np.ndarray], eps_abs: float, eps_rel: float):
    """Replay a recorded QP sequence with OSQP; return its timing/accuracy figures."""
    rep = OSQPReplay(mpc, eps_abs=eps_abs, eps_rel=eps_rel, polishing=False, max_iter=20000)
    o_us, o_it, o_bad, diff = [], [], 0, 0.0
    for m, x in zip(mats, xs):
        xo, status, it, us = rep.solve(m)
        o_us.append(us)
        o_it.append(it)
        err = float(np.max(np.abs(xo - x)))
        o_bad += status != "solved" or not np.isfinite(err)
        diff = max(diff, err) if np.isfinite(err) else diff
    return {
        "osqp_eps_abs": eps_abs,
        "osqp_us_median": float(np.median(o_us[1:] if len(o_us) > 1 else o_us)),
        "osqp_iterations_median": float(np.median(o_it)),
        "osqp_unsolved": int(o_bad),
        "max_solution_diff": diff,
    }


def benchmark_env_campc(n_steps: int = 500, case: int = 1, warmup: int = 10, osqp_compare: bool = True) -> dict:
    """CAMPC control-step cost in closed loop on the simulator, and the same QP sequence on OSQP.

    Args:
        n_steps: environment steps (at most one episode, 500).
        case: circle case.
        warmup: first steps left out of the timing (cold start).
        osqp_compare: replay the recorded QPs with OSQP at ProxSuite's ``eps_abs``.

    Returns:
        ``step_us_median`` (kinematics + distances + ``J_dis`` + QP build + solve), ``step_us_p90``,
        ``solve_us_median``, ``build_us_median``, ``model_us_median`` (= ``distance_us_median`` +
        ``kinematics_us_median``), ``step_excl_distance_us_median``, ``iterations_median``, ``unsolved``,
        ``max_slack``, QP sizes, and the OSQP figures with ``osqp_over_proxsuite`` (ratio of median solve times).
    """
    import gymnasium as gym

    import uvdms_gym  # noqa: F401
    from baselines.controllers import make_baseline

    env = gym.make("uvdms/CircleTrack-v0", case=case, action_mode="velocity", terminate_on_contact=False)
    try:
        ctl = make_baseline("campc", env)
        obs, info = env.reset(seed=0)
        ctl.reset(0)
        mpc = ctl.mpc
        log = _StepLog(osqp_compare)
        for k in range(min(n_steps + warmup, 500)):
            action = ctl.predict(obs, info)
            if k >= warmup:
                log.add(ctl.last_mpc, mpc.mpc, mpc.last_problem)
            obs, _, term, trunc, info = env.step(action)
            if term or trunc:
                break
    finally:
        env.close()
    cfg = mpc.config
    out: dict = {
        "case": case,
        "n_steps": len(log.steps),
        "n_c": cfg.n_c,
        "n_p": cfg.n_p,
        "n": mpc.mpc.n,
        "n_eq": mpc.mpc.n_eq,
        "n_in": mpc.mpc.n_in,
        "eps_abs": cfg.eps_abs,
        **log.stats(),
    }
    if osqp_compare:
        out.update(_osqp_replay(mpc.mpc, log.mats, log.xs, cfg.eps_abs, cfg.eps_rel))
        out["osqp_over_proxsuite"] = out["osqp_us_median"] / out["solve_us_median"]
    return out


def real_time_factor(controller: str = "campc-nndi", env_id: str = "uvdms/Transport-v0", steps: int | None = None):
    """Closed-loop real-time factor: simulated seconds / wall seconds of controller + environment steps.

    Args:
        controller: baseline name.
        env_id: environment.
        steps: number of steps (``None``: one whole episode).

    Returns:
        ``{"controller", "env_id", "steps", "sim_s", "wall_s", "real_time_factor", "controller_ms_median",
        "env_ms_median", "controller_distance_us_median"}``: the controller's median cost per control step (MPC
        + dynamic inversion), the environment step's, and the distances + ``J_dis`` inside the controller's
        (so that each part can be combined with a new cost of the other).
    """
    import time

    import gymnasium as gym

    import uvdms_gym  # noqa: F401
    from baselines.controllers import BASELINES, make_baseline

    env = gym.make(env_id, action_mode=BASELINES[controller]["action_mode"])
    try:
        ctl = make_baseline(controller, env)
        obs, info = env.reset(seed=0)
        ctl.reset(0)
        c_ms, e_ms, d_us = [], [], []
        t_start = time.perf_counter()
        n = 0
        while steps is None or n < steps:
            t0 = time.perf_counter()
            action = ctl.predict(obs, info)
            t1 = time.perf_counter()
            obs, _, term, trunc, info = env.step(action)
            t2 = time.perf_counter()
            c_ms.append((t1 - t0) * 1e3)
            e_ms.append((t2 - t1) * 1e3)
            last = getattr(ctl, "last_mpc", None)
            d_us.append(last.distance_us if last is not None else 0.0)
            n += 1
            if term or trunc:
                break
        wall = time.perf_counter() - t_start
        sim_s = float(info["t"])
    finally:
        env.close()
    return {
        "controller": controller,
        "env_id": env_id,
        "steps": n,
        "sim_s": sim_s,
        "wall_s": wall,
        "real_time_factor": sim_s / wall,
        "controller_ms_median": float(np.median(c_ms)),
        "env_ms_median": float(np.median(e_ms)),
        "controller_distance_us_median": float(np.median(d_us)),
    }


def benchmark_all(quick: bool = False) -> dict:
    """What ``uvdms bench mpc --json`` prints: CAMPC step cost, OSQP ratio, DI cost and the real-time factor.

    Args:
        quick: fewer steps (150 CAMPC steps, 200 DI ticks, 200 transport steps instead of whole episodes).

    Returns:
        ``{"campc_env": ..., "campc_kinematic": ..., "di": ..., "di_nn": ..., "real_time_factor": ...}`` plus the
        headline numbers at the top level: ``campc_step_us_median`` and its split (``campc_distance_us_median``,
        ``campc_kinematics_us_median``, ``campc_build_us_median``, ``campc_solve_us_median``,
        ``campc_step_excl_distance_us_median``), ``osqp_over_proxsuite``, ``campc_nndi_transport_real_time_factor``
        and ``campc_nndi_controller_us_median`` (the controller's own cost per transport step).
    """
    env_res = benchmark_env_campc(n_steps=150 if quick else 490)
    kin_res = benchmark_mpc(n_steps=100 if quick else 300)
    di_res = benchmark_di(n_steps=200 if quick else 1000, use_nn=False)
    nn_res = benchmark_di(n_steps=200 if quick else 1000, use_nn=True)
    rtf = real_time_factor(steps=200 if quick else None)
    return {
        "campc_step_us_median": env_res["step_us_median"],
        "campc_distance_us_median": env_res["distance_us_median"],
        "campc_kinematics_us_median": env_res["kinematics_us_median"],
        "campc_build_us_median": env_res["build_us_median"],
        "campc_solve_us_median": env_res["solve_us_median"],
        "campc_step_excl_distance_us_median": env_res["step_excl_distance_us_median"],
        "osqp_solve_us_median": env_res.get("osqp_us_median"),
        "osqp_over_proxsuite": env_res.get("osqp_over_proxsuite"),
        "campc_nndi_transport_real_time_factor": rtf["real_time_factor"],
        "campc_nndi_controller_us_median": rtf["controller_ms_median"] * 1e3,
        "campc_env": env_res,
        "campc_kinematic": kin_res,
        "di": di_res,
        "di_nn": nn_res,
        "real_time_factor": rtf,
        "quick": quick,
    }
