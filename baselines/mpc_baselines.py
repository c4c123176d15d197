"""The MPC baselines' controllers: the velocity MPC, the torque cascade, hold-still, and the settings they share.

:mod:`baselines.controllers` names them (``BASELINES``, ``make_baseline``) and re-exports every public name here;
:mod:`baselines.cooperative` builds the cooperative CAMPC on :class:`MPCVelocityController`. The module docstring of
:mod:`baselines.controllers` describes the timing, the information a controller uses and the realism handling.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np

from baselines.inner_loop.delay import DelayPredictor
from baselines.inner_loop.di import DIConfig, DynamicInversionController, UVDMSNominalModel
from baselines.mpc.campc import MPCController, task_config
from baselines.mpc.config import MPCConfig

STATE_SOURCES: dict[str, str] = {
    "filter": "the navigation filter's estimate (uvdms_gym.realism.navigation) from info's measurements, "
    "predicted over the action delay",
    "raw": "info's raw measured state as it is, no delay compensation (the ablation)",
    "truth": "env.unwrapped.true_state(), predicted over the action delay (privileged)",
}
"""Where an MPC baseline reads the state at ``realism > 0``; at ``realism=0`` every source is ``info``'s exact state."""

OUTER_ROWS = 8
"""[D] Outer-obstacle rows of the CAMPC baselines in an environment with obstacles: the nearest robot-obstacle
pairs over the horizon (of up to 3 x 14). Eight cover the parts an obstacle can reach within the horizon at once
(the hull, the object and a few links) at a QP cost well below that of all 42 rows."""

OBSTACLE_R_WEIGHT: tuple[float, ...] = (1.0, 1.0, 1.0, 2.0, 2.0, 2.0) + (0.01,) * 12
"""[D] Velocity weight ``R`` of the MPC baselines in an environment with obstacles: joints five times cheaper
than the transport default (0.05). After an evasion, the default let the vehicle carry the return, whose pitch
moment (near its 150 N m limit while holding the object ahead) then saturated in a sustained pitch oscillation of
1-2 degrees and 20-50 mm; with cheaper joints the arms take the fine correction and the hold settles."""

OBSTACLE_Q_WEIGHT = 50.0
"""[D] Output weight ``Q`` of the collision-avoiding MPC baselines in an environment with obstacles (half the
transport's 100): the return after an evasion is gentler and settles. Measured with ``campc`` over three sets of 20
seeds with ``obstacles="random"``, ``current="random"`` (the leaderboard's 2,000,000,000-2,000,000,019, 100-119 and
300-319): 20, 20 and 18 contact-free successes against 16, 19 and 16 with ``Q = 100``, whose failures ended 2-10 cm
from the goal in a slow pitch oscillation. Plain ``mpc`` keeps ``Q = 100`` (it is the base the learned residual of
this task was trained on)."""

ESCAPE = 0.1
"""[D] ``outer_escape`` (m) of the MPC baselines in an environment with obstacles (see
:attr:`baselines.mpc.config.MPCConfig.outer_escape`)."""

GOVERNOR = 0.1
"""[D] ``max_position_error`` (m) of the MPC baselines in an environment with obstacles: after an evasion the
reference error the MPC sees is capped, so the robot returns at a bounded pace (uncapped, a 0.3-0.5 m return
saturated the vehicle and set off a pitch oscillation that outlasted the episode)."""


def effective_delay(realism: Any) -> float:
    """The delay, s, the CAMPC baselines predict over: the action delay plus the thrusters' rotor time constant.

    [D] The MPC plans velocities as if they acted at once; the velocity loop's own lag it tolerates (the prediction
    models it), but a thruster lag of 0.05 s on top set the vehicle oscillating at 1.2 Hz with bang-bang surge
    commands (random circles, ``realism`` level 1 without delay: 3 of 3 validation draws failed, 54-64 mm).
    Predicting over the lag as if it were a delay of one time constant cured it (4 of 4, 0.4-1.5 mm).
    """
    lag = realism.rotor_time_constant if realism.thrusters else 0.0
    return float(realism.action_delay + lag)


def task_of(env: Any) -> str:
    """``"transport"`` for an environment with a gripped object, else ``"circle"``."""
    return "transport" if getattr(env.unwrapped, "with_object", False) else "circle"


def controller_config(task: str, collision: bool, control_dt: float, **overrides: Any) -> MPCConfig:
    """The MPC settings of a baseline on a task, with ``T_c`` equal to the environment's control period.

    Args:
        task: ``"circle"`` or ``"transport"``.
        collision: CAMPC (``True``) or plain MPC.
        control_dt: the environment's control period (``T_c``).
        **overrides: further :class:`~baselines.mpc.config.MPCConfig` fields.

    Returns:
        The :class:`~baselines.mpc.config.MPCConfig`.
    """
    return task_config(task, collision, t_c=float(control_dt), **overrides)  # type: ignore[arg-type]


class _MPCBase:
    """Shared MPC part: reference window, kinematics, distances, QP (see module docstring)."""

    def __init__(
        self,
        env: Any,
        collision: bool,
        mpc_overrides: dict[str, Any] | None = None,
        outer: bool = True,
        state: str = "filter",
    ) -> None:
        u = env.unwrapped
        if state not in STATE_SOURCES:
            raise ValueError(f"state must be one of {sorted(STATE_SOURCES)}, got {state!r}")
        self.realism = getattr(u, "realism", None)
        self.state_source = state if self.realism is not None else "info"
        self.delay = None
        if self.realism is not None and state != "raw":
            d = round(effective_delay(self.realism) / u.physics_dt)
            self.delay = DelayPredictor(d, u.physics_dt, u.n_substeps)
        self.nav = self._navigation_filter(u) if self.state_source == "filter" else None
        self.task = task_of(env)
        self.params = u.params
        self.control_dt = float(u.control_dt)
        self.zeta_max = np.asarray(u.zeta_max, dtype=float)
        self.tau_max = np.asarray(u.tau_max, dtype=float)
        self._env = u
        self.has_obstacles = hasattr(u, "obstacles")
        obstacle_settings = {
            "outer_rows": OUTER_ROWS if (collision and outer) else 0,
            "max_position_error": GOVERNOR,
            "r_weight": OBSTACLE_R_WEIGHT,
            "outer_escape": ESCAPE,
            **({"q_weight": OBSTACLE_Q_WEIGHT} if collision else {}),
        }
        overrides = {**(obstacle_settings if self.has_obstacles else {}), **(mpc_overrides or {})}
        cfg = controller_config(self.task, collision, self.control_dt, **overrides)
        output = "object_pose" if self.task == "transport" else "ee_positions"
        self.mpc = MPCController(output, cfg, self.params, kin=u.kinematic_model)
        self.last_record: dict[str, Any] = {}
        self.last_mpc = None

    @staticmethod
    def _navigation_filter(u: Any) -> Any:
        from uvdms_gym.realism.navigation import NavigationFilter

        return NavigationFilter(u.realism, u.params, control_dt=u.control_dt, physics_dt=u.physics_dt)

    def _reset_state(self) -> None:
        """Start an episode: the filter starts at the first measurements, the delay queue empty."""
        self._nav_started = False
        if self.delay is not None:
            self.delay.reset()

    def state(self, info: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """``(eta, q, zeta, t)`` the MPC plans from: read from :data:`STATE_SOURCES`, predicted over the delay."""
        src = self.state_source
        if src == "truth":
            info = {**info, **self._env.true_state()}
        elif src == "filter":
            nav = self.nav
            if not getattr(self, "_nav_started", False):
                nav.reset(float(info["t"]), info["measurements"])
                self._nav_started = True
            else:
                nav.update(float(info["t"]), info["measurements"], info["tau_cmd"])
            eta, nu, q, qdot = nav.state()
            info = {**info, "eta": eta, "nu": nu, "q": q, "qdot": qdot}
        zeta = np.concatenate([info["nu"], info["qdot"]]).astype(float)
        eta, q = np.asarray(info["eta"], dtype=float), np.asarray(info["q"], dtype=float)
        t = float(info["t"])
        if self.delay is not None:
            eta, q, zeta = self.delay.predict(eta, q, zeta)
            t += self.delay.delay
        return eta, q, zeta, t

    def _mpc_step(self, info: dict[str, Any], state: tuple | None = None):
        cfg = self.mpc.config
        eta, q, zeta, t = state if state is not None else self.state(info)
        y_ref = self._env.reference(t + cfg.t_c * np.arange(1, cfg.n_p + 1))
        rec = self.mpc.step(eta, q, y_ref, zeta, info.get("obstacles"))
        self.last_mpc = rec
        if self.delay is not None:
            self.delay.record(rec.zeta_cmd)
        return rec

    def _record(self, rec, wall_us: float, **extra: Any) -> None:
        self.last_record = {
            "status": rec.status,
            "solved": rec.solved,
            "iterations": rec.iterations,
            "max_slack": rec.max_slack,
            "retried": rec.retried,
            "mpc_us": rec.total_us,
            "wall_us": wall_us,
            **extra,
        }


class MPCVelocityController(_MPCBase):
    """``mpc`` / ``campc``: the MPC command is the velocity action, ``a = zeta_cmd / zeta_max``.

    The command already lies in the MPC's velocity box, which is the action space's box, so clipping to
    ``[-1, 1]`` only removes rounding; ``last_record["clipped"]`` flags a step where it changed anything by more
    than 1e-9.
    """

    action_mode = "velocity"

    def __init__(
        self,
        env: Any,
        collision: bool = True,
        mpc_overrides: dict[str, Any] | None = None,
        outer: bool = True,
        state: str = "filter",
    ) -> None:
        """Build the controller for ``env`` (its action mode must be ``"velocity"``).

        Args:
            env: the environment (wrapped or not).
            collision: CAMPC (``True``) or plain MPC.
            mpc_overrides: :class:`~baselines.mpc.config.MPCConfig` fields replacing the task's defaults.
            outer: with collision rows, add :data:`OUTER_ROWS` outer-obstacle rows when the environment has
                obstacles (``False``: the inner rows only).
            state: where the state comes from at ``realism > 0`` (:data:`STATE_SOURCES`).
        """
        super().__init__(env, collision, mpc_overrides, outer, state)

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: the next QP is solved cold (the QP object is kept)."""
        self.mpc.reset()
        self._reset_state()
        self.last_record = {}

    def predict(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Action for the current state (``obs`` is unused: the MPC reads the state from ``info``)."""
        t0 = time.perf_counter()
        rec = self._mpc_step(info)
        raw = rec.zeta_cmd / self.zeta_max
        action = np.clip(raw, -1.0, 1.0)
        clipped = bool(np.max(np.abs(action - raw)) > 1e-9)
        self._record(rec, (time.perf_counter() - t0) * 1e6, clipped=clipped, zeta_cmd=rec.zeta_cmd)
        return action.astype(np.float32)


class CascadeTorqueController(_MPCBase):
    """``campc-di`` / ``campc-nndi``: CAMPC command tracked by dynamic inversion, ``a = tau / tau_max``.

    Both loops run once per environment step (module docstring). The nominal model is
    :class:`~baselines.inner_loop.di.UVDMSNominalModel` of the environment's parameters (with the gripped object as a
    payload for transport): the simulator's link drag, object hydrodynamics and any hydrodynamic randomisation
    are the model error the network compensates.
    """

    action_mode = "torque"

    def __init__(
        self,
        env: Any,
        use_nn: bool = True,
        collision: bool = True,
        mpc_overrides: dict[str, Any] | None = None,
        di_overrides: dict[str, Any] | None = None,
        outer: bool = True,
        state: str = "filter",
    ) -> None:
        """Build the controller for ``env`` (its action mode must be ``"torque"``).

        Args:
            env: the environment (wrapped or not).
            use_nn: with the RBF network (``campc-nndi``) or without (``campc-di``).
            collision: collision rows in the MPC.
            mpc_overrides: :class:`~baselines.mpc.config.MPCConfig` fields replacing the task's defaults.
            di_overrides: :class:`~baselines.inner_loop.di.DIConfig` fields replacing the defaults.
            outer: outer-obstacle rows when the environment has obstacles (see :class:`MPCVelocityController`).
            state: where the state comes from at ``realism > 0`` (:data:`STATE_SOURCES`).
        """
        super().__init__(env, collision, mpc_overrides, outer, state)
        di_cfg = replace(DIConfig(), **{"dt": self.control_dt, "use_nn": use_nn, **(di_overrides or {})})
        model = UVDMSNominalModel(self.params, payload=self.task == "transport")
        self.di = DynamicInversionController(di_cfg, model, self.params, tau_max=self.tau_max, zeta_max=self.zeta_max)
        self.last_di = None
        self._first = True

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: MPC cold, network weights and integrators zero (``tau_prev`` set at the first step)."""
        self.mpc.reset()
        self.di.reset()
        self._reset_state()
        self._first = True
        self.last_record = {}
        self.last_di = None

    def predict(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Torque action for the current state."""
        t0 = time.perf_counter()
        state = self.state(info)
        eta, q, zeta = state[0], state[1], state[2]
        if self._first:
            # the network input's tau_prev starts at the static holding force of the nominal model
            self.di.tau_prev = self.di.model.evaluate(eta, q, np.zeros(18))[1]
            self._first = False
        rec = self._mpc_step(info, state)
        a_eq = self.mpc.last_problem.j_eq if self.task == "transport" else None
        out = self.di.step(rec.zeta_cmd, eta, q, zeta, a_eq)
        self.last_di = out
        raw = out.tau / self.tau_max
        action = np.clip(raw, -1.0, 1.0)
        self._record(
            rec,
            (time.perf_counter() - t0) * 1e6,
            clipped=bool(np.max(np.abs(action - raw)) > 1e-9),
            zeta_cmd=rec.zeta_cmd,
            nn_output=out.delta_hat,
            tau_saturated=bool(out.saturated.any()),
        )
        return action.astype(np.float32)


class HoldStill:
    """The zero velocity command at every step: the vehicle and both arms hold still (baseline ``hold``).

    The floor a controller must beat: on the circles the hands stay where they start, on transport the object
    does (until the reference has left it 2 m behind and the episode ends). It needs no model and no QP.
    """

    def __init__(self, env: Any) -> None:
        self.action = np.zeros(env.action_space.shape, dtype=np.float32)
        self.last_record: dict[str, Any] = {}

    def reset(self, seed: int | None = None) -> None:
        """Nothing to reset: the command does not depend on the episode."""

    def predict(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The zero action (a copy, so a caller may modify it)."""
        return self.action.copy()
