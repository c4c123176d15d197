"""What an environment does at ``realism > 0``: the action path (delay, thrusters, drive limits) and the sensors.

:class:`RealismLayer` sits between the environment and its simulator:

* **Actions.** An action issued at substep ``s`` first acts at substep ``s + d`` (``d``: ``action_delay`` in
  substeps); until then the previous one is held (zero-order hold; before the first action, the zero action). Each
  physics substep turns the action in effect into generalized forces: the built-in velocity loop (velocity mode)
  or ``action * tau_max`` (torque mode) give a body wrench that the thrusters' allocation turns into thrust
  commands, or the action commands the thrusters directly (``action_mode="thrusters"``: 8 normalised thruster
  commands, then 12 joint torques ``action * tau_max``); the rotor dynamics and the dead zone
  (:class:`~uvdms_gym.realism.actuation.Thrusters`) make the wrench that acts, and each arm drive cuts its torque
  beyond its rated speed (:func:`~uvdms_gym.realism.actuation.limit_joint_speed`).
* **Sensors.** The simulator's probe (:meth:`~uvdms_gym.physics.sim.UVDMSSim.set_probe`) hands the vehicle's state
  at every substep; the layer keeps it, and at the end of the control step (:meth:`RealismLayer.measure`) each
  sensor samples the step's due substeps in one batch, the end of the step from the environment's own read
  (the same samples as one at a time: samples are only released at control-step ends).
  :meth:`RealismLayer.measure` releases what arrived by the end of the step and forms the
  *raw measured state*: position from the fix (``x``, ``y``) and the depth sensor (``z``), attitude from the AHRS,
  body velocity from the DVL and the gyro, joint angles from the encoders and joint rates as the difference of the
  last two encoder samples, obstacle centres and velocities from the sonar track; each the newest sample, held
  until the next.

The truth stays in the environment (``env.unwrapped.true_state()``); nothing here changes the physics at
``realism=0``, where the environment never builds this layer.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from uvdms_gym.realism.actuation import DEFAULT_LAYOUT, Thrusters, actuate, limit_joint_speed
from uvdms_gym.realism.config import SENSOR_NAMES, RealismConfig, to_substeps
from uvdms_gym.realism.sensors import Sensor, SensorBank
from uvdms_gym.utils.jit import jit

N_THRUSTER_ACTIONS = 8
"""Thruster commands at the front of a ``action_mode="thrusters"`` action (``uvdms_gym.envs.base.N_THRUSTERS``)."""

Measurements = dict[str, list[tuple[float, np.ndarray]]]

VEHICLE_COLUMNS: dict[str, slice | list[int]] = {
    "ahrs": slice(3, 6),
    "gyro": slice(9, 12),
    "dvl": slice(6, 9),
    "depth": slice(2, 3),
    "fix": [0, 1, 2, 5],
}
"""What each vehicle sensor measures of a row ``[eta (6); nu (6)]`` (:func:`sensor_values`' selections)."""
NO_OBSTACLES = np.zeros((0, 11))
"""The obstacle rows of a task without outer obstacles (read only)."""
NO_OBSTACLES.flags.writeable = False


def vehicle_row(origin: tuple, quat: tuple, nu: tuple) -> list[float]:
    """``[eta; nu]`` (12 floats): NED pose and body velocity from the probe's z-up world origin and quaternion.

    The conversion of :func:`uvdms_gym.physics.state.state_from_raw` for a body-origin read (no centre-of-gravity
    offset), in plain floats.
    """
    x, y, z, w = quat
    r00 = 1.0 - 2.0 * (y * y + z * z)
    r10 = 2.0 * (x * y + z * w)
    r20 = 2.0 * (x * z - y * w)
    r21 = 2.0 * (y * z + x * w)
    r22 = 1.0 - 2.0 * (x * x + y * y)
    phi = math.atan2(-r21, -r22)
    psi = math.atan2(-r10, r00)
    theta = -math.asin(min(max(-r20, -1.0), 1.0))
    return [origin[0], -origin[1], -origin[2], phi, theta, psi, *nu]


PROBE_VALUES = 13
"""Values of one probe: the z-up world origin (3), the quaternion ``xyzw`` (4) and ``nu`` (6)."""


@jit
def _vehicle_table(probes, eta, nu, out):  # pragma: no cover - compiled
    """Rows ``[eta; nu]`` of :func:`vehicle_row` for each probe (``probes``: ``(k, PROBE_VALUES)``), then ``eta, nu``.

    The same float expressions as :func:`vehicle_row`, in the same order.
    """
    k = probes.shape[0]
    for j in range(k):
        x, y, z, w = probes[j, 3], probes[j, 4], probes[j, 5], probes[j, 6]
        r00 = 1.0 - 2.0 * (y * y + z * z)
        r10 = 2.0 * (x * y + z * w)
        r20 = 2.0 * (x * z - y * w)
        r21 = 2.0 * (y * z + x * w)
        r22 = 1.0 - 2.0 * (x * x + y * y)
        out[j, 0], out[j, 1], out[j, 2] = probes[j, 0], -probes[j, 1], -probes[j, 2]
        out[j, 3] = math.atan2(-r21, -r22)
        out[j, 4] = -math.asin(min(max(-r20, -1.0), 1.0))
        out[j, 5] = math.atan2(-r10, r00)
        for c in range(6):
            out[j, 6 + c] = probes[j, 7 + c]
    for c in range(6):
        out[k, c] = eta[c]
        out[k, 6 + c] = nu[c]


def vehicle_truth(origin: tuple, quat: tuple, nu: tuple) -> tuple[np.ndarray, np.ndarray]:
    """NED pose ``eta`` and body velocity ``nu`` from the simulator probe's z-up world origin and quaternion."""
    row = np.array(vehicle_row(origin, quat, nu), dtype=float)
    return row[:6], row[6:]


def sensor_values(names: tuple[str, ...], eta: np.ndarray, nu: np.ndarray, **extra: Any) -> dict[str, np.ndarray]:
    """What each named sensor measures of the true state (``extra``: ``q`` (12), ``obstacles`` (K, 11) rows)."""
    out: dict[str, np.ndarray] = {}
    for name in names:
        if name == "ahrs":
            out[name] = eta[3:6]
        elif name == "gyro":
            out[name] = nu[3:6]
        elif name == "dvl":
            out[name] = nu[0:3]
        elif name == "depth":
            out[name] = eta[2:3]
        elif name == "fix":
            out[name] = np.array([eta[0], eta[1], eta[2], eta[5]])
        elif name == "encoders":
            out[name] = np.asarray(extra["q"], dtype=float)
        elif name == "sonar":
            out[name] = np.asarray(extra["obstacles"], dtype=float)[:, :6]
    return out


class RealismLayer:
    """The action path and the sensors of one environment at ``realism > 0`` (module docstring).

    Args:
        cfg: the realism level.
        action_mode: the environment's action mode.
        zeta_max: the environment's velocity-mode action scale (18).
        tau_max: the environment's torque-mode action scale (18).
        physics_dt: the physics step, s.
        n_substeps: physics steps per control step.
        with_obstacles: the environment has outer obstacles (the sonar is on).
        sensing: the sensors are on (``False``: thrusters mode at ``realism=0``, the action path only).
    """

    def __init__(
        self,
        cfg: RealismConfig,
        *,
        action_mode: str,
        zeta_max: np.ndarray,
        tau_max: np.ndarray,
        physics_dt: float,
        n_substeps: int,
        with_obstacles: bool,
        sensing: bool = True,
    ) -> None:
        self.cfg = cfg
        self.action_mode = action_mode
        self.zeta_max = np.asarray(zeta_max, dtype=float)
        self.tau_max = np.asarray(tau_max, dtype=float)
        self.physics_dt = float(physics_dt)
        self.n_substeps = int(n_substeps)
        self.delay_steps = to_substeps(cfg.action_delay, self.physics_dt)
        """The action delay, substeps."""
        on = cfg.thrusters or action_mode == "thrusters"
        self.thrusters: Thrusters | None = (
            Thrusters(
                cfg.layout or DEFAULT_LAYOUT,
                rotor_time_constant=cfg.rotor_time_constant,
                dead_zone=cfg.dead_zone,
                physics_dt=self.physics_dt,
            )
            if on
            else None
        )
        self.sensing = bool(sensing)
        self.names = tuple(n for n in SENSOR_NAMES if with_obstacles or n != "sonar") if sensing else ()
        self.bank = SensorBank(cfg, physics_dt=self.physics_dt, control_substeps=self.n_substeps, names=self.names)
        self.s = 0
        """Global substep index of the current state (0 at reset)."""
        self._pending: list[tuple[int, np.ndarray]] = []
        self._held = np.zeros(0)
        self._sub = 0
        self._tau_sum = np.zeros(18)
        self._thrust_saturated = False
        self._encoder_prev: tuple[float, np.ndarray] | None = None
        self._qdot = np.zeros(12)
        self._probe_i = 0
        self._probed: list[tuple[float, ...]] = []
        """The step's probes after its first substep, in order: ``origin + quat + nu`` (:data:`PROBE_VALUES`)."""
        self._obstacles_now: Callable[[float], np.ndarray] | None = None
        sensors = self.bank.sensors
        self._vehicle_sensors: list[tuple[Sensor, slice | list[int]]] = [
            (sensors[n], cols) for n, cols in VEHICLE_COLUMNS.items() if n in sensors
        ]
        limit = cfg.joint_speed_limit
        self._limit = np.zeros(0) if limit is None else np.atleast_1d(np.asarray(limit, dtype=float))
        if self.sensing:  # compile (or load from numba's cache) now, not in a step
            _vehicle_table(np.zeros((0, PROBE_VALUES)), np.zeros(6), np.zeros(6), np.empty((1, 12)))

    @property
    def action_dim(self) -> int:
        """Length of an action: 18, or 8 thruster commands and 12 joint torques in thrusters mode."""
        return N_THRUSTER_ACTIONS + 12 if self.action_mode == "thrusters" else 18

    # ------------------------------------------------------------------ episode
    def reset(
        self,
        seed: int,
        episode: int,
        eta: np.ndarray,
        nu: np.ndarray,
        q: np.ndarray,
        obstacles_at: Callable[[float], np.ndarray] | None = None,
    ) -> Measurements:
        """Start an episode at the true state: clear the action queue and the rotors, sample every sensor once.

        Returns:
            The initial measurements (every sensor's sample at ``t = 0``, released at once).
        """
        self.s = 0
        self._pending = []
        self._probed = []
        self._held = np.zeros(self.action_dim)
        if self.thrusters is not None:
            self.thrusters.reset()
        self._obstacles_now = obstacles_at
        if not self.sensing:
            return {}
        extra = {"q": q, "obstacles": obstacles_at(0.0) if obstacles_at is not None else NO_OBSTACLES}
        initial = sensor_values(self.names, eta, nu, **extra)
        self.bank.reset(seed, episode, initial)
        self._encoder_prev = None
        return {name: [self.bank.latest(name)] for name in self.names}

    # ------------------------------------------------------------------ actions
    def begin_step(self, action: np.ndarray) -> None:
        """Queue the action issued now; it first acts ``delay_steps`` substeps later."""
        self._pending.append((self.s + self.delay_steps, np.asarray(action, dtype=float)))
        self._sub = 0
        self._probe_i = 0
        self._probed = []
        self._tau_sum[:] = 0.0
        self._thrust_saturated = False

    def action_at(self, s: int) -> tuple[np.ndarray, bool]:
        """The action in effect at substep ``s`` and whether it changed there."""
        changed = False
        pending = self._pending
        while pending and pending[0][0] <= s:
            self._held = pending.pop(0)[1]
            changed = True
        return self._held, changed

    def feedback(self, torque: Callable[[np.ndarray, np.ndarray, bool], np.ndarray]) -> Callable:
        """The per-substep law the simulator calls: the action in effect, the environment's map, the actuators.

        Args:
            torque: ``(action, zeta, changed) -> tau`` (18): the environment's velocity loop or torque scaling of
                the action in effect (not called in thrusters mode).
        """
        thr, limit, tau_sum = self.thrusters, self._limit, self._tau_sum

        def law(zeta: np.ndarray) -> np.ndarray:
            s = self.s + self._sub
            self._sub += 1
            pending = self._pending
            if pending and pending[0][0] <= s:
                action, changed = self.action_at(s)
            else:  # (action_at without a call: the action in effect holds)
                action, changed = self._held, False
            if self.action_mode == "thrusters":
                return self._thrusters_law(action, zeta)
            tau = torque(action, zeta, changed)
            if thr is None:
                return self._actuate(tau, zeta)
            out = np.empty(18)  # (_actuate inlined: one compiled call, per substep)
            if actuate(thr, tau, zeta[6:], limit, tau_sum, out) < 1.0:
                self._thrust_saturated = True
            return out

        return law

    def _actuate(self, tau: np.ndarray, zeta: np.ndarray) -> np.ndarray:
        """Thrusters (allocation, rotors, dead zone) for the body wrench; the drives' speed limit for the joints."""
        thr = self.thrusters
        out = np.empty(18)
        if thr is not None:  # one compiled call: allocation, rotors, drive limits and the commanded sum
            if actuate(thr, tau, zeta[6:], self._limit, self._tau_sum, out) < 1.0:
                self._thrust_saturated = True
            return out
        self._tau_sum[:6] += tau[:6]
        out[:6] = tau[:6]
        out[6:] = self._joints(tau[6:], zeta)
        return out

    def _thrusters_law(self, action: np.ndarray, zeta: np.ndarray) -> np.ndarray:
        thr = self.thrusters
        assert thr is not None  # thrusters mode always builds them
        cmd = thr.from_normalized(action[:N_THRUSTER_ACTIONS])
        out = np.empty(18)
        self._tau_sum[:6] += thr.matrix @ cmd
        out[:6] = thr.step(cmd)
        out[6:] = self._joints(action[N_THRUSTER_ACTIONS:] * self.tau_max[6:], zeta)
        return out

    def _joints(self, tau_q: np.ndarray, zeta: np.ndarray) -> np.ndarray:
        limit = self.cfg.joint_speed_limit
        tau_q = tau_q if limit is None else limit_joint_speed(tau_q, zeta[6:], limit)
        self._tau_sum[6:] += tau_q
        return tau_q

    def end_step(self) -> dict[str, Any]:
        """Advance the substep index; the step's commanded forces (mean over substeps) and saturation flag."""
        n = max(self._sub, 1)
        self.s += self._sub
        info = {"tau_cmd": self._tau_sum / n, "thrust_saturated": self._thrust_saturated}
        if self.thrusters is not None:
            info["thrust"] = self.thrusters.thrust  # (a copy)
        return info

    # ------------------------------------------------------------------ sensors
    def probe(self, origin: tuple, quat: tuple, nu: tuple) -> None:
        """The simulator's substep probe: keep the state for :meth:`measure` (not the first substep's: see there)."""
        i = self._probe_i
        self._probe_i = i + 1
        if i:  # the step's first substep starts at the state measure() sampled
            self._probed.append(origin + quat + nu)

    def measure(
        self, t: float, eta: np.ndarray, nu: np.ndarray, q: np.ndarray, obstacles: np.ndarray | None
    ) -> Measurements:
        """Sample the step's due substeps (the probes, then the end from the true state); release what has arrived.

        Each sensor takes its samples of the step in one batch (:meth:`~uvdms_gym.realism.sensors.Sensor.sample_many`),
        the same samples as one at a time. Joint angles are read at control-step ends only.
        """
        probed = self._probed
        self._probed = []
        end = self.s
        first = end - len(probed)  # the probes are the substeps after the step's first, then comes its end
        steps = list(range(first, end + 1))
        table = np.empty((len(steps), 12))  # [eta; nu] at each of them (vehicle_row's conversion, compiled)
        _vehicle_table(np.array(probed).reshape(-1, PROBE_VALUES), eta, nu, table)
        for sensor, cols in self._vehicle_sensors:
            period = sensor.period_steps
            if period == 1:
                sensor.sample_many(steps, table[:, cols], check=False)
            elif -(-first // period) * period <= end:  # some substep of the step is due
                due = [j for j, s in enumerate(steps) if s % period == 0]
                sensor.sample_many([steps[j] for j in due], table[due][:, cols], check=False)
        sensors = self.bank.sensors
        encoders = sensors.get("encoders")
        if encoders is not None and end % encoders.period_steps == 0:
            encoders.sample_many((end,), np.array(q, dtype=float)[np.newaxis], check=False)
        sonar = sensors.get("sonar")
        if sonar is not None and -(-first // sonar.period_steps) * sonar.period_steps <= end:
            due = [s for s in steps if s % sonar.period_steps == 0]
            ends = obstacles if obstacles is not None else NO_OBSTACLES
            source = self._obstacles_now
            values = [ends if s == end or source is None else source(s * self.physics_dt) for s in due]
            sonar.sample_many(due, np.array([np.asarray(v, dtype=float)[:, :6] for v in values]), check=False)
        return self.bank.release(end)

    def measured_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The raw measured ``eta, nu, q, qdot`` (module docstring): the newest sample of each sensor."""
        sensors = self.bank.sensors
        eta = np.concatenate((sensors["fix"].latest[1][:2], sensors["depth"].latest[1], sensors["ahrs"].latest[1]))
        nu = np.concatenate((sensors["dvl"].latest[1], sensors["gyro"].latest[1]))
        t_q, q = sensors["encoders"].latest
        prev = self._encoder_prev
        if prev is None or t_q <= prev[0]:
            qdot = np.zeros_like(q) if prev is None else self._qdot
        else:
            qdot = (q - prev[1]) / (t_q - prev[0])
        if prev is None or t_q > prev[0]:
            self._encoder_prev = (t_q, q)
            self._qdot = qdot
        return eta, nu, q.copy(), qdot

    def measured_obstacles(self, true_rows: np.ndarray) -> np.ndarray:
        """The obstacle rows with centre and velocity from the sonar's newest track (shape columns as given)."""
        rows = np.array(true_rows, dtype=float, copy=True)
        if rows.shape[0]:
            rows[:, :6] = self.bank.latest("sonar")[1]
        return rows
