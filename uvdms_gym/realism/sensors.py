"""Sensor models: each sensor's rate, latency, white noise, turn-on bias, bias random walk and dropouts.

A sensor with :class:`~uvdms_gym.realism.config.SensorSpec` ``spec`` samples at global physics substep ``s``
(time ``t = s * physics_dt``) when ``s % period_steps == 0`` (``s = 0`` is a sample, taken by :meth:`Sensor.reset`),
and measures

``m = x(t) + b(t) + n``,  ``n ~ N(0, sigma^2)`` per component,

with the turn-on bias ``b(0) ~ N(0, bias_sigma^2)`` drawn at reset and the random walk ``b += N(0, bias_walk^2 dt)``
between consecutive samples ``dt`` apart (dropped samples included: the bias drifts whether or not a sample is
delivered). Angles (the AHRS's three components, the position fix's heading, index 3) are wrapped to ``(-pi, pi]``.

Dropouts: at a due sample outside a dropout, a dropout starts with probability ``dropout_prob``; it loses this sample
and the next ``dropout_len - 1`` due samples. Each sample is thus a renewal step: an eligible sample starts a dropout
(``dropout_len`` samples lost) with probability ``p`` or is delivered (one sample) with probability ``1 - p``, and the
long-run fraction of samples lost is ``p n / (p n + 1 - p) = p n / (1 + p (n - 1))``.

A sample taken at ``s`` is released to the controller at ``s + latency_steps`` (:meth:`Sensor.release`). Periods and
latencies become substeps with :func:`~uvdms_gym.realism.config.to_substeps` (a period of at least one substep);
``period=None`` (the encoders) is one sample per control step.

Randomness: every sensor draws from its own generator (:func:`~uvdms_gym.realism.config.noise_streams`), in a fixed
order per due sample whether or not the sample is dropped (bias increments, then noise, then the dropout draw), so
the same seed gives the same noise and one sensor's settings never shift another's samples.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping

import numpy as np

from uvdms_gym.realism.config import SENSOR_DIMS, SENSOR_NAMES, RealismConfig, SensorSpec, noise_streams, to_substeps

ANGLE_COMPONENTS: dict[str, tuple[int, ...]] = {"ahrs": (0, 1, 2), "fix": (3,)}
"""Components of each sensor that are angles, wrapped to ``(-pi, pi]`` (other sensors: none)."""
TWO_PI = 2.0 * math.pi
"""A full turn, rad."""
MAX_DUE_TABLE = 100_000
"""Longest common period (substeps) for which :class:`SensorBank` tabulates the due sensors of every substep."""

Sample = tuple[float, np.ndarray]
"""A released sample: ``(t_sample, value)``."""


def wrap_pi(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to ``(-pi, pi]`` (``pi`` stays ``pi``, ``-pi`` becomes ``pi``)."""
    return math.pi - np.mod(math.pi - a, TWO_PI)


class Sensor:
    """One sensor (module docstring): sample at due substeps, queue, release after the latency.

    Args:
        name: one of :data:`~uvdms_gym.realism.config.SENSOR_NAMES` (sets the dimension and the angle components).
        spec: the sensor's model.
        physics_dt: the physics substep, s.
        control_substeps: substeps per control step (the period of a sensor with ``period=None``).

    Attributes:
        period_steps: substeps between samples.
        latency_steps: substeps from a sample to its release.
        latest: the newest released sample ``(t_sample, value)``, held between samples.
    """

    def __init__(self, name: str, spec: SensorSpec, *, physics_dt: float, control_substeps: int) -> None:
        if name not in SENSOR_DIMS:
            raise ValueError(f"sensor name must be one of {SENSOR_NAMES}, got {name!r}")
        if not (math.isfinite(physics_dt) and physics_dt > 0):
            raise ValueError(f"physics_dt must be a finite number > 0, got {physics_dt!r}")
        if isinstance(control_substeps, bool) or not isinstance(control_substeps, int) or control_substeps < 1:
            raise ValueError(f"control_substeps must be a whole number >= 1, got {control_substeps!r}")
        self.name, self.spec, self.physics_dt = name, spec, float(physics_dt)
        self.period_steps = control_substeps if spec.period is None else to_substeps(spec.period, physics_dt, minimum=1)
        self.latency_steps = to_substeps(spec.latency, physics_dt)
        self.dim = SENSOR_DIMS[name]
        self._sigma = spec.sigma_vector(self.dim)
        self._angles = list(ANGLE_COMPONENTS.get(name, ()))
        self._walk_scale = spec.bias_walk * math.sqrt(self.period_steps * physics_dt)
        self._drop_p, self._drop_n = float(spec.dropout_prob), int(spec.dropout_len)
        self._queue: deque[tuple[int, float, np.ndarray]] = deque()
        self._rng: np.random.Generator | None = None
        self._shape: tuple[int, ...] = (self.dim,)
        self._draw_shape: tuple[int, ...] = (1, self.dim)
        self._bias = np.zeros(self.dim)
        self._dropping = 0
        self.latest: Sample = (0.0, np.zeros(self.dim))

    def reset(self, rng: np.random.Generator, initial: np.ndarray) -> None:
        """Start an episode: draw the turn-on bias, take the sample at ``s = 0`` and release it at once.

        Args:
            rng: this sensor's generator (all its randomness comes from it).
            initial: the true value at ``t = 0``: ``(dim,)``, or ``(K, 6)`` for the sonar (``K`` obstacles).
        """
        x = np.asarray(initial, dtype=float)
        ok = x.shape == (self.dim,) or (self.name == "sonar" and x.ndim == 2 and x.shape[1] == self.dim)
        if not ok:
            raise ValueError(f"initial {self.name} value must have shape ({self.dim},), got {x.shape}")
        self._rng, self._shape = rng, x.shape
        self._draw_shape = (2 if self._walk_scale > 0.0 else 1, *x.shape)
        self._bias = self.spec.bias_sigma * rng.standard_normal(x.shape)
        self._queue.clear()
        self._dropping = 0
        self.latest = (0.0, self._measure(x, rng.standard_normal(x.shape)))

    def due(self, s: int) -> bool:
        """Whether the sensor samples at substep ``s``."""
        return s % self.period_steps == 0

    def sample(self, s: int, truth: np.ndarray) -> None:
        """Take the sample of due substep ``s > 0`` of the true value ``truth``; queue it unless dropped."""
        rng = self._rng
        if rng is None:
            raise ValueError(f"sensor {self.name}: reset() before sample()")
        if s % self.period_steps != 0 or s <= 0:
            raise ValueError(f"sensor {self.name}: substep {s} is not a sample (period {self.period_steps} substeps)")
        draws = rng.standard_normal(self._draw_shape)  # bias increments (with a walk) then the noise
        if self._walk_scale > 0.0:
            self._bias += self._walk_scale * draws[0]
        noise = draws[-1]
        if self._drop_p > 0.0:
            u = rng.random()
            if self._dropping > 0:
                self._dropping -= 1
                return
            if u < self._drop_p:
                self._dropping = self._drop_n - 1
                return
        value = self._measure(np.asarray(truth, dtype=float), noise)
        self._queue.append((s + self.latency_steps, s * self.physics_dt, value))

    def _measure(self, x: np.ndarray, standard_noise: np.ndarray) -> np.ndarray:
        """``x + b + sigma * noise`` with the angle components wrapped to ``(-pi, pi]``."""
        if x.shape != self._shape:
            raise ValueError(f"{self.name} value must have shape {self._shape}, got {x.shape}")
        m = self._sigma * standard_noise
        m += x
        m += self._bias
        if self._angles:
            if m.ndim == 1:  # on floats: a few numpy calls on a 1-element selection cost several microseconds
                for i in self._angles:
                    v = float(m[i])
                    if not -math.pi < v <= math.pi:
                        m[i] = math.pi - (math.pi - v) % TWO_PI
            else:
                m[:, self._angles] = wrap_pi(m[:, self._angles])
        return m

    def release(self, s_now: int) -> list[Sample]:
        """The queued samples with ``s + latency_steps <= s_now``, oldest first; they leave the queue."""
        out: list[Sample] = []
        queue = self._queue
        while queue and queue[0][0] <= s_now:
            _, t, value = queue.popleft()
            out.append((t, value))
        if out:
            self.latest = out[-1]
        return out


class SensorBank:
    """The sensors of a :class:`~uvdms_gym.realism.config.RealismConfig`, one generator each.

    Args:
        cfg: the realism level (its sensor specs).
        physics_dt: the physics substep, s.
        control_substeps: substeps per control step.
        names: the sensors to simulate (default: all of :data:`~uvdms_gym.realism.config.SENSOR_NAMES`).
    """

    def __init__(
        self,
        cfg: RealismConfig,
        *,
        physics_dt: float,
        control_substeps: int,
        names: tuple[str, ...] = SENSOR_NAMES,
    ) -> None:
        self.sensors: dict[str, Sensor] = {
            n: Sensor(n, cfg.sensor(n), physics_dt=physics_dt, control_substeps=control_substeps) for n in names
        }
        cycle = math.lcm(*(sensor.period_steps for sensor in self.sensors.values())) if names else 1
        self._cycle = cycle if cycle <= MAX_DUE_TABLE else 0
        self._table = [self._due_names(s) for s in range(self._cycle)]

    def _due_names(self, s: int) -> tuple[str, ...]:
        return tuple(n for n, sensor in self.sensors.items() if s % sensor.period_steps == 0)

    def reset(self, seed: int, episode: int, initial: Mapping[str, np.ndarray]) -> None:
        """Start an episode: streams from ``noise_streams(seed, episode, SENSOR_NAMES)``, the samples at ``s = 0``.

        Args:
            seed: the episode's seed.
            episode: the episode's index since that seed.
            initial: the true value of every sensor at ``t = 0``.
        """
        missing = [n for n in self.sensors if n not in initial]
        if missing:
            raise ValueError(f"initial values missing for sensors {missing}")
        streams = noise_streams(seed, episode, SENSOR_NAMES)
        for name, sensor in self.sensors.items():
            sensor.reset(streams[name], initial[name])

    def initial(self) -> dict[str, list[Sample]]:
        """The samples taken at reset, as :meth:`release` would report them (one per sensor)."""
        return {name: [sensor.latest] for name, sensor in self.sensors.items()}

    def due(self, s: int) -> tuple[str, ...]:
        """Names of the sensors sampling at substep ``s``."""
        return self._table[s % self._cycle] if self._cycle else self._due_names(s)

    def sample(self, s: int, values: Mapping[str, np.ndarray]) -> None:
        """Take the samples of substep ``s``: ``values`` holds the true value of each due sensor."""
        sensors = self.sensors
        for name, value in values.items():
            sensor = sensors.get(name)
            if sensor is None:
                raise ValueError(f"unknown sensor {name!r}; the bank has {tuple(sensors)}")
            sensor.sample(s, value)

    def release(self, s_now: int) -> dict[str, list[Sample]]:
        """Every sensor's samples released up to substep ``s_now`` since the last call (lists may be empty)."""
        return {name: sensor.release(s_now) for name, sensor in self.sensors.items()}

    def latest(self, name: str) -> Sample:
        """The newest released sample of sensor ``name``."""
        return self.sensors[name].latest
