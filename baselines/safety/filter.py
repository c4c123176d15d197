"""Safety filter: any velocity-mode controller's command projected onto the velocity-damper rows.

:class:`SafetyFilter` wraps a controller of the velocity track (a trained agent, ``mpc``, anything with
``reset`` and ``predict``) and changes its action as little as possible so that the 18 collision rows of CAMPC
hold for the command:

    min_u  1/2 |u - a|^2 + rho_1 sum s + rho_2 |s|^2 / 2
    s.t.   J_dis diag(zeta_max) u - s <= v + (b - v) / alpha,   -1 <= u <= 1,   s >= 0
           b = S(d) vbar - k_esc max(0, d1 - d),   v = J_dis zeta_measured

``a`` is the wrapped controller's action (normalised, ``zeta_cmd = a * zeta_max``), ``u`` the filtered one,
``J_dis`` the distance Jacobian and ``d`` the 18 distances of the measured state (``info`` and the environment's
kinematic model), the bound the one of :meth:`baselines.mpc.kinematic.KinematicMPC.collision_bound` with the same
parameters as CAMPC (``vbar``, ``d1``, ``d2``, ``k_escape``, and the measured approach over ``lookahead``),
and ``alpha`` (:attr:`SafetyFilterConfig.tracking_fraction`) the share of a velocity change the plant completes
within a step: CAMPC constrains a whole horizon of consistent commands, a one-step filter only the next one,
and the plant's lag must be paid for in the bound.
One slack per row keeps the problem feasible when no command in the box satisfies every row (it then violates
them as little as the penalty allows). Far from every obstacle (all distances beyond ``d2`` and no approach
that brings one within it over ``lookahead``) every row is inactive and ``u = a`` exactly; the QP is not even
solved.

The QP is one ProxSuite dense problem of 36 variables (18 + 18 slacks) and 18 rows, allocated once per filter
and warm-started. On transport the closed-chain equality is not imposed (the wrapped controller's command may
not satisfy it either; the environment's velocity loop follows whatever it gets). ``last_record`` reports
``filter_active`` (the QP changed the action), ``filter_change`` (``max |u - a|``), ``filter_slack`` and the
wrapped controller's own record.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from baselines.mpc.config import INF, MPCConfig
from baselines.mpc.damper import damper_bound
from baselines.mpc.solver import proxsuite
from uvdms_gym.distances import compute_distances, distance_jacobian
from uvdms_gym.evaluation import Controller, check_action_mode

N = 18
_SOLVED = proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED


@dataclass(frozen=True)
class SafetyFilterConfig:
    """Settings of :class:`SafetyFilter` (the damper's come from :class:`baselines.mpc.config.MPCConfig`).

    Attributes:
        tracking_fraction: ``alpha``, the share of a velocity change the plant completes within one control step.
            The rows bound the command by ``v_now + (bound - v_now) / alpha`` (``v_now``: the measured approach
            rate), so that a plant that closes only ``alpha`` of the gap still stays within the damper's bound.
            1 assumes the command is followed at once. [D] 0.25: on Case 1 and Case 2 plain ``mpc`` then runs
            contact-free; with 1, 0.6 or 0.4 it still hit the frame after 120-135 steps (the environment's
            velocity loop lags the command by 0.3-0.8 rad/s on the joints during the manoeuvre).
        rho_1: linear slack penalty (exact penalty: no slack while the rows are feasible).
        rho_2: quadratic slack penalty.
        eps_abs: ProxSuite's absolute accuracy.
    """

    tracking_fraction: float = 0.25
    rho_1: float = 1.0e3
    rho_2: float = 1.0e4
    eps_abs: float = 1.0e-9

    def __post_init__(self) -> None:
        if not 0.0 < self.tracking_fraction <= 1.0:
            raise ValueError(f"tracking_fraction must be in (0, 1], got {self.tracking_fraction}")
        if not (self.rho_1 > 0.0 and self.rho_2 > 0.0 and self.eps_abs > 0.0):
            raise ValueError("rho_1, rho_2 and eps_abs must be positive")


class SafetyFilter:
    """A velocity-mode controller whose every action is projected onto the collision rows (module docstring).

    Args:
        controller: The wrapped controller (velocity action mode).
        env: The environment it drives (wrapped or not): its ``zeta_max`` and kinematic model.
        config: Filter settings.
        damper: The damper's parameters (default :class:`~baselines.mpc.config.MPCConfig`'s, as CAMPC).
    """

    action_mode = "velocity"

    def __init__(
        self,
        controller: Controller,
        env: Any,
        config: SafetyFilterConfig | None = None,
        damper: MPCConfig | None = None,
    ) -> None:
        check_action_mode("safety filter", env, "velocity")
        self.controller = controller
        self.config = config or SafetyFilterConfig()
        self.damper = damper or MPCConfig()
        unwrapped = env.unwrapped
        self.zeta_max = np.asarray(unwrapped.zeta_max, dtype=float)
        self.kin = unwrapped.kinematic_model
        cfg = self.config
        n = 2 * N
        self.qp = proxsuite.proxqp.dense.QP(n, 0, N, True, proxsuite.proxqp.dense.HessianType.Dense)
        self.qp.settings.eps_abs = cfg.eps_abs
        self.qp.settings.verbose = False
        self._h = np.zeros((n, n))
        self._h[:N, :N] = np.eye(N)
        self._h[N:, N:] = cfg.rho_2 * np.eye(N)
        self._g = np.zeros(n)
        self._g[N:] = cfg.rho_1
        self._c = np.zeros((N, n))
        self._c[:, N:] = -np.eye(N)
        self._lo = np.full(N, -INF)
        self._up = np.zeros(N)
        self._box_lo = np.concatenate([-np.ones(N), np.zeros(N)])
        self._box_hi = np.concatenate([np.ones(N), np.full(N, INF)])
        self._initialised = False
        self.last_record: dict[str, Any] = {}

    def reset(self, seed: int | None = None) -> None:
        """Start an episode (the wrapped controller's ``reset``; the next QP is solved cold)."""
        self.controller.reset(seed)
        self._initialised = False
        self.last_record = {}

    def bound(self, info: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
        """``(J_dis diag(zeta_max), bound)`` of the collision rows at the state in ``info``."""
        kin = self.kin
        kin.set_state(np.asarray(info["eta"], dtype=float), np.asarray(info["q"], dtype=float))
        res = compute_distances(kin, self.damper.distance_method, self.damper.distance_samples)
        j_dis = distance_jacobian(kin, res)
        v_now = j_dis @ np.concatenate([info["nu"], info["qdot"]])
        bound = damper_bound(self.damper, res.d, v_now)
        alpha = self.config.tracking_fraction
        if alpha < 1.0:  # the command the loop must get so that it reaches ``bound`` within the step
            bound = v_now + (bound - v_now) / alpha
        return j_dis * self.zeta_max[None, :], bound

    def predict(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The wrapped controller's action, projected onto the collision rows."""
        a = np.clip(np.asarray(self.controller.predict(obs, info), dtype=float), -1.0, 1.0)
        inner = dict(getattr(self.controller, "last_record", {}) or {})
        t0 = time.perf_counter()
        rows, bound = self.bound(info)
        if np.all(rows @ a <= bound):  # every row holds (far from the obstacles, all of them): no change
            u, slack, status = a, 0.0, "inactive"
        else:
            u, slack, status = self._project(a, rows, bound)
        change = float(np.max(np.abs(u - a)))
        self.last_record = {
            **inner,
            "filter_active": status != "inactive",
            "filter_change": change,
            "filter_slack": slack,
            "filter_status": status,
            "filter_us": (time.perf_counter() - t0) * 1e6,
        }
        return u.astype(np.float32)

    def _project(self, a: np.ndarray, rows: np.ndarray, bound: np.ndarray) -> tuple[np.ndarray, float, str]:
        self._g[:N] = -a
        self._c[:, :N] = rows
        self._up[:] = bound
        qp = self.qp
        if self._initialised:
            qp.update(self._h, self._g, None, None, self._c, self._lo, self._up, self._box_lo, self._box_hi)
            qp.solve()
        else:  # cold; warm starts only once a previous result exists (ProxSuite crashes warm-starting from none)
            qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.NO_INITIAL_GUESS
            qp.init(self._h, self._g, None, None, self._c, self._lo, self._up, self._box_lo, self._box_hi)
            qp.solve()
            qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            self._initialised = True
        if qp.results.info.status != _SOLVED:  # keep the command inside the box at least; report the status
            self._initialised = False
            return a, float("nan"), str(qp.results.info.status)
        x = qp.results.x
        u = np.clip(x[:N], -1.0, 1.0)
        return u, float(np.max(x[N:])), "solved"
