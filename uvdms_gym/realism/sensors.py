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

Randomness: every sensor draws from its own generator (:func:`~uvdms_gym.realism.config.noise_streams`): at reset
the turn-on bias, then the noise of the sample at ``s = 0``; then, per due sample whether or not it is dropped, the
bias increments (with a bias walk), the noise, and the dropout draw (with dropouts), in this order. The same seed
gives the same noise, and one sensor's settings never shift another's samples. A sensor without dropouts draws the
normals of :data:`DRAW_BLOCK` due samples at once (numpy's generator fills an array in order, so these are the
numbers of one draw per sample); one with dropouts draws each batch's samples in turn when it takes them. Samples
taken one at a time (:meth:`Sensor.sample`) equal samples taken in batches (:meth:`Sensor.sample_many`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence

import numpy as np

from uvdms_gym.realism.config import SENSOR_DIMS, SENSOR_NAMES, RealismConfig, SensorSpec, noise_streams, to_substeps
from uvdms_gym.utils.jit import jit

ANGLE_COMPONENTS: dict[str, tuple[int, ...]] = {"ahrs": (0, 1, 2), "fix": (3,)}
"""Components of each sensor that are angles, wrapped to ``(-pi, pi]`` (other sensors: none)."""
TWO_PI = 2.0 * math.pi
"""A full turn, rad."""
DRAW_BLOCK = 256
"""Due samples whose random draws a sensor takes from its generator at once (module docstring: Randomness)."""
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
        angles = ANGLE_COMPONENTS.get(name, ())  # consecutive components
        self._angle_lo, self._angle_hi = (angles[0], angles[-1] + 1) if angles else (0, 0)
        self._sigma_flat = self._sigma
        self._walk_scale = spec.bias_walk * math.sqrt(self.period_steps * physics_dt)
        self._drop_p, self._drop_n = float(spec.dropout_prob), int(spec.dropout_len)
        self._queue: deque[tuple[int, float, np.ndarray]] = deque()
        self._rng: np.random.Generator | None = None
        self._shape: tuple[int, ...] = (self.dim,)
        self._draw_rows = 2 if self._walk_scale > 0.0 else 1
        """Standard normal rows a sample draws: the bias increments (with a walk), then the noise."""
        self._normals = np.zeros((0, self._draw_rows, self.dim))
        self._uniforms = np.zeros(0)
        self._row = 0
        self._bias = np.zeros(self.dim)
        self._dropping = 0
        self.latest: Sample = (0.0, np.zeros(self.dim))
        _warm_up()

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
        self._sigma_flat = np.tile(self._sigma, x.size // self.dim)  # per component of the flattened value
        self._normals, self._uniforms, self._row = np.zeros((0, self._draw_rows, x.size)), np.zeros(0), 0
        self._bias = (self.spec.bias_sigma * rng.standard_normal(x.shape)).reshape(-1)
        self._queue.clear()
        self._dropping = 0
        draws = np.zeros((1, self._draw_rows, x.size))
        draws[0, -1] = rng.standard_normal(x.shape).reshape(-1)
        self.latest = (0.0, self._measure(x[np.newaxis], draws, 0, 0.0)[0])

    def due(self, s: int) -> bool:
        """Whether the sensor samples at substep ``s``."""
        return s % self.period_steps == 0

    def sample(self, s: int, truth: np.ndarray) -> None:
        """Take the sample of due substep ``s > 0`` of the true value ``truth``; queue it unless dropped."""
        x = np.asarray(truth, dtype=float)
        if x.shape != self._shape:
            raise ValueError(f"{self.name} value must have shape {self._shape}, got {x.shape}")
        self.sample_many((s,), x[np.newaxis])

    def sample_many(self, steps: Sequence[int], truths: np.ndarray, *, check: bool = True) -> None:
        """Take the samples of due substeps ``steps`` (increasing, ``> 0``) at once; queue those not dropped.

        The same samples as :meth:`sample` at each substep in turn (module docstring: Randomness).

        Args:
            steps: the due substeps.
            truths: the true values at them, ``(len(steps), *shape)`` (``shape``: the value's at reset).
            check: check the substeps and the shape (``False``: the caller guarantees them, and ``truths`` is a
                float array of that shape, any strides; the environment's per-step path).
        """
        if check:
            if self._rng is None:
                raise ValueError(f"sensor {self.name}: reset() before sample()")
            period = self.period_steps
            for s in steps:
                if s % period != 0 or s <= 0:
                    raise ValueError(f"sensor {self.name}: substep {s} is not a sample (period {period} substeps)")
            truths = np.ascontiguousarray(truths, dtype=float)
            if truths.shape != (len(steps), *self._shape):
                raise ValueError(f"{self.name} value must have shape {self._shape}, got {truths.shape[1:]}")
        k = len(steps)
        if k == 0:
            return
        i = self._row  # (_reserve and _measure inlined for the per-step path)
        if i + k > self._normals.shape[0]:
            i = self._reserve(k)
        else:
            self._row = i + k
        if truths.ndim == 2:
            values = np.empty(truths.shape)
            lo, hi = self._angle_lo, self._angle_hi
            _measure_rows(truths, self._normals, i, self._sigma_flat, self._bias, self._walk_scale, lo, hi, values)
        else:
            values = self._measure(truths, self._normals, i, self._walk_scale)
        latency, dt = self.latency_steps, self.physics_dt
        if self._drop_p > 0.0:
            self._queue.extend((steps[j] + latency, steps[j] * dt, values[j]) for j in self._delivered(i, k))
        else:
            self._queue.extend([(s + latency, s * dt, v) for s, v in zip(steps, values, strict=True)])

    def _delivered(self, i: int, k: int) -> list[int]:
        """The samples of a batch (indices ``0..k-1``; draws from row ``i``) no dropout loses; the dropout state."""
        p, dropping, kept = self._drop_p, self._dropping, []
        for j, u in enumerate(self._uniforms[i : i + k].tolist()):
            if dropping > 0:
                dropping -= 1
            elif u < p:
                dropping = self._drop_n - 1
            else:
                kept.append(j)
        self._dropping = dropping
        return kept

    def _reserve(self, k: int) -> int:
        """The first of the rows of the next ``k`` due samples' draws (``_normals``, ``_uniforms``), drawn if needed.

        Module docstring (Randomness): blocks of :data:`DRAW_BLOCK` samples' normals without dropouts, else exactly
        the ``k`` samples, each its normals then its dropout draw.
        """
        i, normals = self._row, self._normals
        if i + k > normals.shape[0]:
            rng = self._rng
            assert rng is not None
            rows, shape = self._draw_rows, (self._draw_rows, *self._shape)
            if self._drop_p > 0.0:  # (a batch is taken whole: nothing is left of the previous one)
                normals, uniforms = np.empty((k, rows, normals.shape[2])), np.empty(k)
                for j in range(k):
                    normals[j] = rng.standard_normal(shape).reshape(rows, -1)
                    uniforms[j] = rng.random()
                self._uniforms = uniforms
            else:
                parts = [normals[i:]]
                for _ in range(-(-(i + k - normals.shape[0]) // DRAW_BLOCK)):
                    parts.append(rng.standard_normal((DRAW_BLOCK, *shape)).reshape(DRAW_BLOCK, rows, -1))
                normals = np.concatenate(parts)
            self._normals, i = normals, 0
        self._row = i + k
        return i

    def _measure(self, x: np.ndarray, draws: np.ndarray, first: int, walk_scale: float) -> np.ndarray:
        """The measured values ``(k, *shape)`` of the true values ``x`` (draws from row ``first``), a new array."""
        out = np.empty(x.shape)
        k = x.shape[0]
        flat_x, flat_out = (x, out) if x.ndim == 2 else (x.reshape(k, -1), out.reshape(k, -1))  # sonar: (k, K, 6)
        lo, hi = self._angle_lo, self._angle_hi
        _measure_rows(flat_x, draws, first, self._sigma_flat, self._bias, walk_scale, lo, hi, flat_out)
        return out

    def release(self, s_now: int) -> list[Sample]:
        """The queued samples with ``s + latency_steps <= s_now``, oldest first; they leave the queue."""
        queue = self._queue
        if not queue or queue[0][0] > s_now:
            return []
        out: list[Sample] = []
        while queue and queue[0][0] <= s_now:
            _, t, value = queue.popleft()
            out.append((t, value))
        if out:
            self.latest = out[-1]
        return out


@jit
def _measure_rows(x, draws, first, sigma, bias, walk_scale, angle_lo, angle_hi, out):  # pragma: no cover - compiled
    """Rows ``out[j] = sigma * n_j + x[j] + b_j`` of consecutive samples, in place on the bias ``b``.

    ``draws[first + j]``: sample ``j``'s standard normals, the bias increments (row 0, with a walk) and the noises
    ``n_j`` (the last row); with a walk the bias first gains ``walk_scale`` times the increments (``b_j = b_(j-1) +
    walk_scale w_j``). Components ``angle_lo:angle_hi`` outside ``(-pi, pi]`` are wrapped (in-range values keep their
    bits). The operation order of the numpy expressions ``m = sigma * n; m += x; m += b``.
    """
    noise = draws.shape[1] - 1
    for j in range(x.shape[0]):
        r = first + j
        for c in range(x.shape[1]):
            if walk_scale > 0.0:
                bias[c] = bias[c] + walk_scale * draws[r, 0, c]
            v = sigma[c] * draws[r, noise, c] + x[j, c]
            v = v + bias[c]
            if angle_lo <= c < angle_hi and not -math.pi < v <= math.pi:
                v = math.pi - (math.pi - v) % TWO_PI
            out[j, c] = v


def _warm_up() -> None:
    """Compile (or load from numba's cache) the kernel when a sensor is built, not in an environment's step."""
    one, draws, zero = np.zeros((1, 1)), np.zeros((1, 2, 1)), np.zeros(1)
    _measure_rows(one, draws, 0, zero, zero.copy(), 0.0, 0, 1, one.copy())
    _measure_rows(np.zeros((1, 2))[:, 1:], draws, 0, zero, zero.copy(), 0.0, 0, 1, one.copy())  # a column view


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
