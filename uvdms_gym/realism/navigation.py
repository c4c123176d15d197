"""The vehicle's navigation filter: an EKF of pose, body velocity and sensor biases, plus joint-state filters.

State of the EKF (27 values, then the clones of delayed samples):

======  ====  =============================================================================================
slice   size  content
======  ====  =============================================================================================
0:6     6     ``eta``: NED position ``x, y, z`` and ZYX Euler angles ``phi, theta, psi``
6:12    6     ``nu``: body velocity ``u, v, w, p, q, r``
12:18   6     ``d``: an unknown body acceleration (random walk): the rest of the model's error (added mass off
              by up to 30 %, the arms' drag, the thrusters' dead zone within a step)
18      1     ``beta``: the buoyancy's relative error (every buoyancy force is ``(1 + beta)`` times the nominal)
19      1     ``delta``: the vehicle damping's relative error (``D(nu)`` is ``(1 + delta)`` times the nominal)
20:23   3     the gyro's bias (random walk of the gyro's ``bias_walk``)
23:26   3     the DVL's bias (constant)
26      1     the depth sensor's bias (constant)
======  ====  =============================================================================================

Prediction, every physics substep: ``eta' = J(eta) nu`` and
``nu' = [M_n^-1 (tau - b_n(q, zeta))]_v + beta g_b - (1 + delta) [M_n^-1]_vv D(nu) nu + d`` with the nominal model
(:mod:`uvdms_gym.physics.nominal`: Pinocchio rigid body with added mass, hydrostatics, Coriolis, joint friction)
evaluated once per control step at the estimate, ``g_b = -[M_n^-1 g_buoyancy]_v`` (one unit of buoyancy error),
and the vehicle damping ``D(nu) nu`` at every substep. The arms enter through the full 18-DOF model (their weight,
buoyancy and reaction). The vehicle's wrench ``tau_v`` is the thrusters' at each substep: the step's mean commanded
wrench ``tau_cmd`` is allocated to thrust commands (``B^+``), the dead zone zeroes the small ones, the first-order
rotor lag (the filter keeps each rotor's thrust) makes the thrust of every substep, and the simulator's wrench box
bounds ``B f`` (:mod:`uvdms_gym.realism.actuation`); without thrusters ``tau_cmd`` is applied within the box.
White process noise on ``nu'`` and random walks on ``d``, ``beta``, ``delta`` stand for what the model does not
know.

Measurements are linear in the state (a state plus a bias): AHRS angles, gyro rates plus bias, DVL velocity plus
bias, depth plus bias, the position fix (``x, y, z, psi``), with the angle innovations wrapped. Each is applied at
its sample time. A sample released late (the DVL, the fix) is handled exactly by stochastic cloning: at each of the
sensor's sample times the states it measures are copied into extra state slots (with their covariance), the slots
are carried unchanged while the filter moves on, and the late sample updates its clone, the correlations carrying
the correction to the present. A slot whose sample does not come by its release time (a dropout) is freed.

Joints: one Kalman filter per joint of ``(q, qdot)``, driven by the nominal model's joint acceleration and corrected
by the encoders each control step.

The filter knows its sensors' specifications (the :class:`~uvdms_gym.realism.config.RealismConfig`): rates,
latencies, noise and bias magnitudes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
import pinocchio as pin

from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.nominal import NominalDynamics
from uvdms_gym.physics.params import N_JOINTS, UVDMSParams
from uvdms_gym.realism.actuation import DEFAULT_LAYOUT, Thrusters
from uvdms_gym.realism.config import RealismConfig, to_substeps
from uvdms_gym.realism.ekf import MAX_DIM, N_CORE, _advance, _apply, _prepare

N_BASE = 27
"""States without the clones."""
FILTERED_SENSORS: tuple[str, ...] = ("ahrs", "gyro", "dvl", "depth", "fix")
"""The sensors the EKF fuses, in the order of its tables (the encoders feed the joint filters)."""
MEASURED_STATES: dict[str, tuple[int, ...]] = {
    "ahrs": (3, 4, 5),
    "gyro": (9, 10, 11),
    "dvl": (6, 7, 8),
    "depth": (2,),
    "fix": (0, 1, 2, 5),
}
"""State measured by each component of each sensor."""
BIAS_STATES: dict[str, tuple[int, ...]] = {"gyro": (20, 21, 22), "dvl": (23, 24, 25), "depth": (26,)}
"""Bias state added to each component (sensors not listed have no bias)."""
ANGLE_MEASUREMENTS: dict[str, tuple[int, ...]] = {"ahrs": (0, 1, 2), "fix": (3,)}
"""Components whose innovation is an angle (wrapped to ``[-pi, pi)``)."""

POSITION_PRIOR_SIGMA = 10.0
"""Standard deviation of the initial position before the first fix, m (the first fix sets it)."""
ANGLE_PRIOR_SIGMA = 1.0
"""Standard deviation of the initial attitude before the first AHRS sample, rad."""
VELOCITY_PRIOR_SIGMA = (0.05, 0.05, 0.05, 0.05, 0.05, 0.05)
"""Standard deviation of the initial body velocity, m/s and rad/s (the vehicle starts at rest, unknown drift)."""
DISTURBANCE_PRIOR_SIGMA = (0.2, 0.2, 0.3, 0.2, 0.2, 0.2)
"""Standard deviation of the initial unknown acceleration ``d``, m/s^2 and rad/s^2: heave carries the buoyancy's
30 % (about 190 N standard deviation on some 160 kg of heave inertia)."""
ACCEL_NOISE_DENSITY = (0.002, 0.003, 0.002, 0.01, 0.03, 0.03)
"""White acceleration noise on ``nu'``, m/s^2/sqrt(Hz) and rad/s^2/sqrt(Hz): the fast part of the model's error.
Tuned on the consistency harness (``scripts/filter_consistency.py``, validation seeds) once the thrusters,
buoyancy and damping errors were modelled: what is left is small."""
DISTURBANCE_WALK = (0.008, 0.01, 0.006, 0.05, 0.15, 0.15)
"""Random-walk density of ``d``, m/s^2/sqrt(s) and rad/s^2/sqrt(s): its slow part (tuned as the above)."""
BUOYANCY_PRIOR_SIGMA = 0.2
"""Standard deviation of the buoyancy's relative error ``beta`` (``hydro_randomization=0.3`` draws it uniformly
in ``[-0.3, 0.3]``: 0.17 standard deviation)."""
DAMPING_PRIOR_SIGMA = 0.2
"""Standard deviation of the damping's relative error ``delta`` (as ``beta``)."""
BUOYANCY_WALK = 1.0e-3
"""Random-walk density of ``beta``, 1/sqrt(s) (a constant per episode; a little noise keeps the linearisation
honest)."""
DAMPING_WALK = 1.0e-3
"""Random-walk density of ``delta``, 1/sqrt(s)."""
POSITION_NOISE_DENSITY = 1.0e-4
"""White noise on the position's rate, m/sqrt(s) (the Euler integration's error)."""
ANGLE_NOISE_DENSITY = 6.0e-4
"""White noise on the Euler angles' rates, rad/sqrt(s) (the Euler integration's error over a substep of changing
body rates)."""
JOINT_PRIOR_RATE_SIGMA = 0.05
"""Standard deviation of the initial joint rates, rad/s (the arms start at rest)."""
JOINT_ACCEL_NOISE_DENSITY = 2.0
"""White noise on each joint's acceleration, rad/s^2/sqrt(Hz) (the joints' model is rougher: gear friction)."""
MIN_VARIANCE = 1.0e-12
"""Floor of a measurement's variance (a noiseless sensor would make the update singular)."""
_PADS = tuple([0.0] * k for k in range(MAX_DIM + 1))


# ----------------------------------------------------------------------------------------------- the filter
def _vector(values: Any, n: int) -> np.ndarray:
    return np.asarray(values, dtype=float) * np.ones(n)


class NavigationFilter:
    """EKF of ``(eta, nu)`` with biases and an unknown acceleration, joint filters (module docstring).

    Args:
        cfg: the realism level (the sensors' specifications the vehicle's software knows).
        params: the nominal physical parameters.
        control_dt: the control step, s (:meth:`update` is called once per control step).
        physics_dt: the physics substep, s (the sensors' clock; samples are taken at its multiples).
    """

    def __init__(self, cfg: RealismConfig, params: UVDMSParams, *, control_dt: float, physics_dt: float) -> None:
        if not (math.isfinite(physics_dt) and physics_dt > 0):
            raise ValueError(f"physics_dt must be a finite number > 0, got {physics_dt!r}")
        n_sub = round(control_dt / physics_dt)
        if n_sub < 1 or abs(n_sub * physics_dt - control_dt) > 1e-9:
            raise ValueError(f"control_dt ({control_dt}) must be a whole multiple of physics_dt ({physics_dt})")
        self.cfg, self.params = cfg, params
        self.control_dt, self.physics_dt, self.n_substeps = float(control_dt), float(physics_dt), n_sub
        self._kin = KinematicModel(params)
        self._nominal = NominalDynamics(self._kin)
        self._model, self._data = self._kin.model, self._kin.model.createData()
        self._bmodel = self._nominal._bmodel
        self._bdata = self._bmodel.createData()
        veh = params.vehicle
        self._added = self._nominal._base_added.copy()
        self._added_weight = float(self._kin._added_weight)
        self._friction = float(params.arm.joint_friction)
        self._lin, self._quad = np.array(veh.linear_damping), np.array(veh.quadratic_damping)
        self._build_tables(cfg)
        self._qdiag = np.r_[
            np.full(3, POSITION_NOISE_DENSITY**2),
            np.full(3, ANGLE_NOISE_DENSITY**2),
            _vector(ACCEL_NOISE_DENSITY, 6) ** 2,
            _vector(DISTURBANCE_WALK, 6) ** 2,
            np.full(1, BUOYANCY_WALK**2),
            np.full(1, DAMPING_WALK**2),
            np.full(3, cfg.gyro.bias_walk**2),
        ]
        enc = cfg.encoders.sigma_vector(N_JOINTS)
        self._enc_var = np.maximum(enc**2, MIN_VARIANCE)
        self._box = np.asarray(params.tau_max[:6], dtype=float)
        self._thr = (
            Thrusters(
                cfg.layout or DEFAULT_LAYOUT,
                rotor_time_constant=cfg.rotor_time_constant,
                dead_zone=cfg.dead_zone,
                physics_dt=physics_dt,
            )
            if cfg.thrusters
            else None
        )
        if self._thr is None:  # no thrusters: the identity "allocation" without limits, lag or dead zone
            eye = np.eye(6)
            self._thr_args = (eye, eye, np.zeros(6), math.inf, math.inf, 0.0, 1.0)
        else:
            t_ = self._thr
            self._thr_args = (
                t_.pinv,
                t_.matrix,
                np.zeros(t_.n),
                t_.max_forward,
                t_.max_reverse,
                t_.dead_zone,
                t_.alpha,
            )
        self._thrust = self._thr_args[2]
        self._config, self._zeta, self._tau_eff = np.zeros(7 + N_JOINTS), np.zeros(18), np.zeros(18)
        self._model_consts = (self._added, self._added_weight, self._friction, self._lin, self._quad)
        self._qvar = JOINT_ACCEL_NOISE_DENSITY**2
        self._no_encoders = np.zeros(0)
        self._a = np.zeros((12, N_CORE))
        self._t = 0.0
        self._s = 0
        self.restarts = 0
        """Restarts after a divergence (:meth:`_restart_if_diverged`)."""
        self._latest: dict[str, tuple[float, np.ndarray]] = {}
        self.x = np.zeros(self._n)
        self.P = np.eye(self._n)
        self._q, self._qd = np.zeros(N_JOINTS), np.zeros(N_JOINTS)
        self._pj = [np.zeros(N_JOINTS), np.zeros(N_JOINTS), np.zeros(N_JOINTS)]

    def _build_tables(self, cfg: RealismConfig) -> None:
        """Per fused sensor: measured states, bias states, variances, angle flags, period, latency; clone slots."""
        k = len(FILTERED_SENSORS)
        idx, bias = np.full((k, MAX_DIM), -1, np.int64), np.full((k, MAX_DIM), -1, np.int64)
        var, angle = np.ones((k, MAX_DIM)), np.zeros((k, MAX_DIM), np.bool_)
        period, latency = np.zeros(k, np.int64), np.zeros(k, np.int64)
        slots: list[list[int]] = []
        n = N_BASE
        for j, name in enumerate(FILTERED_SENSORS):
            spec, states = cfg.sensor(name), MEASURED_STATES[name]
            dim = len(states)
            idx[j, :dim] = states
            bias[j, : len(BIAS_STATES.get(name, ()))] = BIAS_STATES.get(name, ())
            var[j, :dim] = np.maximum(spec.sigma_vector(dim) ** 2, MIN_VARIANCE)
            angle[j, list(ANGLE_MEASUREMENTS.get(name, ()))] = True
            period[j] = to_substeps(spec.period, self.physics_dt, minimum=1)
            latency[j] = to_substeps(spec.latency, self.physics_dt)
            if latency[j] > 0:
                for _ in range((latency[j] + self.n_substeps) // period[j] + 1):
                    slots.append([j, -1, *range(n, n + dim), *([-1] * (MAX_DIM - dim))])
                    n += dim
        self._n = n
        clone_angles = [row[2 + c] for row in slots for c in range(MAX_DIM) if angle[row[0], c]]
        angle_states = np.array([3, 4, 5, *clone_angles], np.int64)
        self._tab = (idx, bias, var, angle, period, latency, angle_states)
        self._slots_template = np.array(slots, np.int64).reshape(-1, 2 + MAX_DIM)
        self._slots = self._slots_template.copy()
        self._prior = np.r_[
            np.full(3, POSITION_PRIOR_SIGMA),
            np.full(3, ANGLE_PRIOR_SIGMA),
            _vector(VELOCITY_PRIOR_SIGMA, 6),
            _vector(DISTURBANCE_PRIOR_SIGMA, 6),
            np.full(1, BUOYANCY_PRIOR_SIGMA),
            np.full(1, DAMPING_PRIOR_SIGMA),
            np.full(3, cfg.gyro.bias_sigma),
            np.full(3, cfg.dvl.bias_sigma),
            np.full(1, cfg.depth.bias_sigma),
            np.ones(n - N_BASE),
        ]

    # ----------------------------------------------------------------------------------------- public API
    def reset(self, t: float, measurements: Mapping[str, list[tuple[float, np.ndarray]]]) -> None:
        """Start from the prior and the initial samples (taken at ``t``, released at once)."""
        self._t, self._s = float(t), round(t / self.physics_dt)
        self.x = np.zeros(self._n)
        self.P = np.diag(np.maximum(self._prior, math.sqrt(MIN_VARIANCE)) ** 2)
        self._slots = self._slots_template.copy()
        self._thrust[:] = 0.0
        enc = measurements.get("encoders") or []
        if not enc:
            raise ValueError("reset needs the initial encoder sample in measurements['encoders']")
        self._q = np.array(enc[-1][1], dtype=float)
        self._qd = np.zeros(N_JOINTS)
        self._pj = [self._enc_var.copy(), np.zeros(N_JOINTS), np.full(N_JOINTS, JOINT_PRIOR_RATE_SIGMA**2)]
        tab = self._tab
        self._keep_latest(measurements)
        for row in self._pack(measurements):
            _apply(self.x, self.P, row, tab[0][int(row[0])], tab[1], tab[2], tab[3], tab[6])

    def _keep_latest(self, measurements: Mapping[str, list[tuple[float, np.ndarray]]]) -> None:
        """Remember each sensor's newest sample (what a restart after a divergence starts from)."""
        latest = self._latest
        for name, samples in measurements.items():
            if samples:
                latest[name] = samples[-1]

    def _restart_if_diverged(self, t: float) -> None:
        """Start again from each sensor's newest sample if the estimate or its variances became non-finite.

        A controller far outside the model's validity (a torque cascade tumbling the vehicle) can drive the EKF's
        linearisation to overflow; the vehicle's software then re-initialises its navigation, as a real one would,
        rather than handing out NaN. :attr:`restarts` counts it.
        """
        core = N_CORE
        if np.isfinite(self.x[:core]).all() and np.isfinite(np.diagonal(self.P)[:core]).all():
            return
        self.restarts += 1
        self.reset(t, {name: [(t, value)] for name, (_, value) in self._latest.items()})

    def update(self, t: float, measurements: Mapping[str, list[tuple[float, np.ndarray]]], tau_cmd: np.ndarray) -> None:
        """Advance to ``t`` with the commanded force of the step just ended and fuse the samples released in it.

        Args:
            t: the time at the end of the control step, s.
            measurements: sensor name -> the samples released during the step, ``(t_sample, value)``.
            tau_cmd: the 18 commanded generalized forces of the step, mean over its substeps.
        """
        tau = np.asarray(tau_cmd, dtype=float)
        if tau.shape != (18,) or not np.isfinite(tau).all():
            raise ValueError(f"tau_cmd must be 18 finite values, got {tau_cmd!r}")
        s_to = round(t / self.physics_dt)
        if s_to < self._s:
            raise ValueError(f"t ({t}) is before the filter's time ({self._t})")
        wrench = _prepare(
            self.x,
            self._q,
            self._qd,
            tau,
            *self._thr_args,
            self._box,
            s_to - self._s,
            self._config,
            self._zeta,
            self._tau_eff,
        )
        config, zeta = self._config, self._zeta
        pin.crba(self._model, self._data, config)
        nle = pin.nonLinearEffects(self._model, self._data, config, zeta)
        buoy = pin.computeGeneralizedGravity(self._bmodel, self._bdata, config)
        model = (self._data.M, nle, buoy, *self._model_consts)
        enc = measurements.get("encoders")
        z = enc[-1][1] if enc else self._no_encoders
        meas = self._pack(measurements)
        _advance(
            self.x,
            self.P,
            self._s,
            s_to,
            self.physics_dt,
            model,
            zeta,
            self._tau_eff,
            wrench,
            self._qdiag,
            meas,
            self._tab,
            self._slots,
            self._a,
            (self._q, self._qd, *self._pj, self._qvar, self._enc_var),
            z,
        )
        self._t, self._s = float(t), s_to
        self._keep_latest(measurements)
        self._restart_if_diverged(t)

    def _pack(self, measurements: Mapping[str, list[tuple[float, np.ndarray]]]) -> np.ndarray:
        """The fused samples as rows ``(sensor index, substep, v0..v3)``."""
        flat: list[float] = []
        extend, inv_dt, n = flat.extend, 1.0 / self.physics_dt, 0
        for j, name in enumerate(FILTERED_SENSORS):
            samples = measurements.get(name)
            if samples:
                pad = _PADS[MAX_DIM - len(samples[0][1])]
                for t, v in samples:
                    flat.append(j)
                    flat.append(round(t * inv_dt))
                    extend(v.tolist())
                    extend(pad)
                n += len(samples)
        return np.array(flat, dtype=float).reshape(n, 2 + MAX_DIM)

    def state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The estimates ``eta, nu, q, qdot`` at the filter's time."""
        return self.x[:6].copy(), self.x[6:12].copy(), self._q.copy(), self._qd.copy()

    def covariance(self) -> np.ndarray:
        """The 12 x 12 covariance of the ``(eta, nu)`` estimate (angle errors are wrapped)."""
        return self.P[:12, :12].copy()

    @property
    def t(self) -> float:
        """The filter's time, s."""
        return self._t


class NavigationFilterWrapper(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Puts the navigation filter's estimate where the oracle state was (observation and ``info`` state keys).

    The environment (at a realism level) reports ``info["measurements"]`` (the samples released during the step,
    and at reset the initial samples) and ``info["tau_cmd"]`` (the step's mean commanded force); the wrapper runs
    the filter on them and asks the environment to observe the estimate (``observe_estimate``).

    Args:
        env: a UVDMS environment built with a realism level.
        cfg: that level (default: the environment's ``realism`` attribute).
    """

    def __init__(self, env: gym.Env, cfg: RealismConfig | None = None) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, cfg=cfg)  # the spec can rebuild it (check_env)
        gym.Wrapper.__init__(self, env)
        base = env.unwrapped
        cfg = cfg if cfg is not None else base.realism
        if cfg is None:
            raise ValueError("NavigationFilterWrapper needs a realism level > 0 (the environment's realism is None)")
        self.filter = NavigationFilter(cfg, base.params, control_dt=base.control_dt, physics_dt=base.physics_dt)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the environment and start the filter from its initial samples."""
        _, info = self.env.reset(**kwargs)
        self.filter.reset(info.get("t", 0.0), info["measurements"])
        return self._observe(info)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Step the environment, update the filter, observe the estimate."""
        _, reward, terminated, truncated, info = self.env.step(action)
        self.filter.update(info["t"], info["measurements"], info["tau_cmd"])
        obs, info = self._observe(info)
        return obs, reward, terminated, truncated, info

    def _observe(self, info: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
        # the obstacles as measured (the sonar's track in info), never the true rows
        obs, state_keys = self.env.unwrapped.observe_estimate(*self.filter.state(), info.get("obstacles"))
        info.update(state_keys)
        return obs, info


class FilteredController:
    """A controller fed the navigation filter's estimate where the oracle state was: the wrapper's job, per controller.

    For a controller evaluated on an unwrapped environment (the leaderboard's, ``uvdms evaluate``'s): at each
    ``predict`` the filter takes ``info["measurements"]`` and ``info["tau_cmd"]``, and the controller receives the
    observation and ``info`` state keys of the estimate (``env.unwrapped.observe_estimate``, with the obstacles as
    measured). At ``realism=0`` it passes ``obs`` and ``info`` through unchanged.

    Args:
        controller: anything with ``reset(seed)`` and ``predict(obs, info)``.
        env: the environment the controller drives (wrapped or not).
    """

    def __init__(self, controller: Any, env: gym.Env) -> None:
        self.controller = controller
        self._env = env.unwrapped
        cfg = self._env.realism
        self.filter = (
            None
            if cfg is None
            else NavigationFilter(
                cfg, self._env.params, control_dt=self._env.control_dt, physics_dt=self._env.physics_dt
            )
        )
        self._started = False

    def __getattr__(self, name: str) -> Any:
        """The wrapped controller's attributes (``last_record``, ``last_di``, ``action_mode``, ...)."""
        if name == "controller":  # not set yet (unpickling): no recursion
            raise AttributeError(name)
        return getattr(self.controller, name)

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: the filter starts at the next ``predict``'s initial samples."""
        self._started = False
        self.controller.reset(seed)

    def predict(self, obs: Any, info: dict[str, Any]) -> Any:
        """The controller's action for the estimated state's observation and ``info``."""
        if self.filter is None:
            return self.controller.predict(obs, info)
        if self._started:
            self.filter.update(float(info["t"]), info["measurements"], info["tau_cmd"])
        else:
            self.filter.reset(float(info["t"]), info["measurements"])
            self._started = True
        obs_hat, keys = self._env.observe_estimate(*self.filter.state(), info.get("obstacles"))
        return self.controller.predict(obs_hat, {**info, **keys})
