"""Realism levels: the typed knobs of sensing and actuation realism, their four levels, and their validation.

``realism=0`` (the default of every v1 environment) is the oracle: the controller reads the exact state and the
commanded generalized force is applied exactly. Levels ``1``, ``2``, ``3`` (easy, medium, hard) turn on

* the action path: an action delay, the vehicle's eight thrusters (allocation, saturation keeping the wrench's
  direction, first-order rotor dynamics, asymmetric forward/reverse thrust, a dead zone) and the arm drives' speed
  limit (:mod:`uvdms_gym.realism.actuation`);
* the sensors, each with its rate, latency, noise, bias and dropouts (:mod:`uvdms_gym.realism.sensors`).

A level is a :class:`RealismConfig`; :func:`parse_realism` reads what the ``realism`` keyword takes: ``None``,
``0``-``3``, a :class:`RealismConfig`, or a mapping ``{"level": 2, "dvl_sigma": 0.01, ...}`` whose other keys
override single knobs (``<sensor>_<field>`` for a sensor's field, e.g. ``fix_period``, or a nested
``{"dvl": {"sigma": 0.01}}``). Every bad value raises one ``ValueError`` naming the knob.

Times are in seconds and become whole numbers of physics substeps (:func:`to_substeps`): the nearest whole number,
halves rounded up; a period is at least one substep, a latency or delay may be zero. A sensor faster than the
physics rate (the 200 Hz IMU) is sampled at the substep rate with the same noise density
(``sigma_100Hz = sigma_200Hz * sqrt(100 / 200)``). Where each value comes from: ``docs/realism.md``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

SENSOR_NAMES: tuple[str, ...] = ("ahrs", "gyro", "dvl", "depth", "fix", "encoders", "sonar")
"""The sensors, in the order of their random streams (:func:`noise_streams`)."""
SENSOR_DIMS: dict[str, int] = {"ahrs": 3, "gyro": 3, "dvl": 3, "depth": 1, "fix": 4, "encoders": 12, "sonar": 6}
"""Components measured by each sensor: AHRS roll, pitch, yaw (rad); gyro ``p, q, r`` (rad/s); DVL ``u, v, w``
(m/s, over ground); depth ``z`` (m); position fix ``x, y, z`` (m, in the task frame) and heading ``psi`` (rad);
encoders ``q`` (12, rad); sonar track per obstacle: centre (m) and velocity (m/s), NED."""
DEG = math.pi / 180.0


@dataclass(frozen=True)
class SensorSpec:
    """One sensor's model: ``m(t_k) = x(t_k) + b(t_k) + n_k``, released ``latency`` after ``t_k``.

    Attributes:
        period: time between samples, s (``None``: one sample per control step, at its end; the encoders).
        latency: time from a sample to its release to the controller, s.
        sigma: white-noise standard deviation per sample, one value for every component or one per component.
        bias_sigma: standard deviation of the turn-on bias ``b(0)``, drawn once per episode per component.
        bias_walk: random-walk density of the bias, units per sqrt(s): ``b`` gains ``N(0, bias_walk^2 dt)`` over
            ``dt``, so its variance grows by ``bias_walk^2`` per second.
        dropout_prob: probability that a dropout starts at a sample (the sample and the next ones are lost).
        dropout_len: samples lost per dropout (``>= 1`` when ``dropout_prob > 0``).
    """

    period: float | None
    latency: float = 0.0
    sigma: float | tuple[float, ...] = 0.0
    bias_sigma: float = 0.0
    bias_walk: float = 0.0
    dropout_prob: float = 0.0
    dropout_len: int = 0

    def sigma_vector(self, dim: int) -> np.ndarray:
        """``sigma`` as ``dim`` values."""
        s = np.atleast_1d(np.asarray(self.sigma, dtype=float))
        return np.full(dim, float(s[0])) if s.size == 1 else s.copy()


@dataclass(frozen=True)
class ThrusterLayout:
    """Where the vehicle's thrusters sit and how they point (body frame FRD), and their thrust limits.

    Attributes:
        positions: one ``(x, y, z)`` per thruster, m, from the body origin.
        directions: one unit thrust axis per thruster (the force of a positive command).
        max_forward: largest thrust of a positive command, N.
        max_reverse: largest thrust of a negative command, N (a propeller pushes less in reverse).
    """

    positions: tuple[tuple[float, float, float], ...]
    directions: tuple[tuple[float, float, float], ...]
    max_forward: float
    max_reverse: float


@dataclass(frozen=True)
class RealismConfig:
    """One realism level: the action path, the thrusters and the sensors (module docstring; ``docs/realism.md``).

    Attributes:
        level: the level this configuration was built from (0-3).
        action_delay: time from an action to its first effect, s (a whole number of substeps).
        thrusters: the thruster model is on (allocation, rotor dynamics, dead zone); on at every level >= 1.
        rotor_time_constant: first-order lag of each thruster's thrust, s (0: thrust follows the command at once).
        dead_zone: commands with ``|u| < dead_zone`` (normalised, ``u`` in ``[-1, 1]``) produce no thrust.
        joint_speed_limit: the arm drives' rated speed, rad/s: a drive cuts its torque toward faster motion
            beyond it (``None``: no limit, as at level 0).
        layout: the thrusters (``None``: :data:`uvdms_gym.realism.actuation.DEFAULT_LAYOUT`).
        ahrs, gyro, dvl, depth, fix, encoders, sonar: the sensors (:class:`SensorSpec`).
    """

    level: int
    action_delay: float = 0.0
    thrusters: bool = False
    rotor_time_constant: float = 0.0
    dead_zone: float = 0.0
    joint_speed_limit: float | None = None
    layout: ThrusterLayout | None = None
    ahrs: SensorSpec = field(default_factory=lambda: SensorSpec(period=0.01))
    gyro: SensorSpec = field(default_factory=lambda: SensorSpec(period=0.01))
    dvl: SensorSpec = field(default_factory=lambda: SensorSpec(period=0.01))
    depth: SensorSpec = field(default_factory=lambda: SensorSpec(period=0.01))
    fix: SensorSpec = field(default_factory=lambda: SensorSpec(period=0.01))
    encoders: SensorSpec = field(default_factory=lambda: SensorSpec(period=None))
    sonar: SensorSpec = field(default_factory=lambda: SensorSpec(period=0.01))

    def sensor(self, name: str) -> SensorSpec:
        """The :class:`SensorSpec` of sensor ``name`` (one of :data:`SENSOR_NAMES`)."""
        return getattr(self, name)

    def as_dict(self) -> dict[str, Any]:
        """The configuration as plain JSON types (recorded with every run at realism > 0)."""
        return dataclasses.asdict(self)


def _sensors(scale: float, *, rate: int, dropouts: tuple[float, int]) -> dict[str, SensorSpec]:
    """The sensors of a level: noise ``scale`` times the cited specifications, slower and later with ``rate``.

    ``rate`` 0, 1, 2 picks the sample periods and latencies of levels 1, 2, 3; ``dropouts`` is the DVL's, the
    fix's and the sonar's ``(probability, length)``.
    """
    p, n = dropouts
    fix_period, fix_latency = (0.2, 0.5, 1.0)[rate], (0.1, 0.2, 0.3)[rate]
    dvl_period, dvl_latency = (0.1, 0.15, 0.2)[rate], (0.02, 0.05, 0.1)[rate]
    sonar_period, sonar_latency = (0.1, 0.2, 0.4)[rate], (0.1, 0.2, 0.3)[rate]
    imu = math.sqrt(100.0 / 200.0)  # a 200 Hz IMU sampled at 100 Hz with the same noise density
    return {
        "ahrs": SensorSpec(period=0.01, sigma=(scale * 0.2 * DEG, scale * 0.2 * DEG, scale * 1.0 * DEG)),
        "gyro": SensorSpec(
            period=0.01, sigma=scale * 0.0012 * imu, bias_sigma=scale * 0.0039, bias_walk=scale * 1.0e-4
        ),
        "dvl": SensorSpec(
            period=dvl_period,
            latency=dvl_latency,
            sigma=scale * 0.026,
            bias_sigma=scale * 0.002,
            dropout_prob=p,
            dropout_len=n,
        ),
        "depth": SensorSpec(period=0.1, sigma=scale * 0.005, bias_sigma=scale * 0.01),
        "fix": SensorSpec(
            period=fix_period,
            latency=fix_latency,
            sigma=(*(3 * (scale * 0.01,)), scale * 0.5 * DEG),
            dropout_prob=p,
            dropout_len=n,
        ),
        "encoders": SensorSpec(period=None, sigma=scale * 0.0005),
        "sonar": SensorSpec(
            period=sonar_period,
            latency=sonar_latency,
            sigma=(*(3 * (scale * 0.02,)), *(3 * (scale * 0.02,))),
            dropout_prob=p,
            dropout_len=n,
        ),
    }


def _level(level: int, delay: float, rotor: float, dead: float, scale: float, dropouts: tuple[float, int]):
    return RealismConfig(
        level=level,
        action_delay=delay,
        thrusters=True,
        rotor_time_constant=rotor,
        dead_zone=dead,
        joint_speed_limit=1.0,
        **_sensors(scale, rate=level - 1, dropouts=dropouts),
    )


LEVELS: dict[int, RealismConfig] = {
    0: RealismConfig(level=0),
    1: _level(1, delay=0.04, rotor=0.02, dead=0.075, scale=1.0, dropouts=(0.01, 1)),
    2: _level(2, delay=0.08, rotor=0.035, dead=0.1, scale=2.0, dropouts=(0.05, 5)),
    3: _level(3, delay=0.12, rotor=0.05, dead=0.125, scale=4.0, dropouts=(0.1, 10)),
}
"""The four levels (values and sources: ``docs/realism.md``). Level 0 is the oracle (nothing is modelled)."""

_TOP_KNOBS = ("action_delay", "thrusters", "rotor_time_constant", "dead_zone", "joint_speed_limit", "layout")
_SENSOR_FIELDS = tuple(f.name for f in dataclasses.fields(SensorSpec))


def to_substeps(seconds: float, physics_dt: float, *, minimum: int = 0) -> int:
    """``seconds`` as a whole number of physics substeps: the nearest, halves up, at least ``minimum``."""
    return max(minimum, math.floor(seconds / physics_dt + 0.5 + 1e-9))


def parse_realism(value: Any, *, episode_time: float | None = None) -> RealismConfig | None:
    """The :class:`RealismConfig` the ``realism`` keyword names, or ``None`` for the oracle (``None`` or ``0``).

    Args:
        value: ``None``, a level ``0``-``3``, a :class:`RealismConfig`, or a mapping with ``level`` (default 1 when
            other keys are given) and knob overrides (module docstring).
        episode_time: the episode's length, s; a delay or latency at least this long is refused.

    Raises:
        ValueError: one line naming the bad knob (unknown key, NaN, negative, a delay longer than the episode).
    """
    if value is None or (isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value == 0):
        return None
    if isinstance(value, RealismConfig):
        cfg = value
    elif isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        if int(value) not in LEVELS:
            raise ValueError(f"realism must be 0, 1, 2 or 3 (or a mapping of knobs), got {value!r}")
        cfg = LEVELS[int(value)]
    elif isinstance(value, Mapping):
        cfg = _from_mapping(value)
    else:
        raise ValueError(f"realism must be 0, 1, 2, 3, a mapping of knobs or a RealismConfig, got {value!r}")
    check_config(cfg, episode_time=episode_time)
    return None if cfg == LEVELS[0] else cfg


def _from_mapping(value: Mapping[str, Any]) -> RealismConfig:
    """A level from a mapping: ``level`` then single-knob overrides (flat ``dvl_sigma`` or nested ``dvl: {...}``)."""
    items = dict(value)
    level = items.pop("level", 1)
    if isinstance(level, bool) or not isinstance(level, (int, np.integer)) or int(level) not in LEVELS:
        raise ValueError(f"realism: level must be 0, 1, 2 or 3, got {level!r}")
    cfg = LEVELS[int(level)]
    top: dict[str, Any] = {}
    sensors: dict[str, dict[str, Any]] = {}
    for key, v in items.items():
        if key in _TOP_KNOBS:
            top[key] = v
        elif key in SENSOR_NAMES:
            if not isinstance(v, Mapping):
                raise ValueError(f"realism: {key} must be a mapping of {list(_SENSOR_FIELDS)}, got {v!r}")
            for sub, sv in v.items():
                sensors.setdefault(key, {})[_sensor_field(key, sub)] = sv
        else:
            name, _, sub = key.partition("_")
            if name not in SENSOR_NAMES or not sub:
                raise ValueError(f"realism: unknown knob {key!r}; knobs are {_knob_list()}")
            sensors.setdefault(name, {})[_sensor_field(name, sub, key)] = v
    if "layout" in top and isinstance(top["layout"], Mapping):
        top["layout"] = _layout(top["layout"])
    specs = {name: dataclasses.replace(cfg.sensor(name), **fields) for name, fields in sensors.items()}
    return dataclasses.replace(cfg, **top, **specs)


def _sensor_field(sensor: str, sub: str, key: str | None = None) -> str:
    if sub not in _SENSOR_FIELDS:
        raise ValueError(f"realism: unknown knob {key or f'{sensor}.{sub}'!r}; knobs are {_knob_list()}")
    return sub


def _knob_list() -> str:
    sensor_knobs = [f"<sensor>_{f}" for f in _SENSOR_FIELDS]
    return f"level, {', '.join(_TOP_KNOBS)}, {', '.join(sensor_knobs)} with <sensor> in {', '.join(SENSOR_NAMES)}"


def _layout(value: Mapping[str, Any]) -> ThrusterLayout:
    try:
        return ThrusterLayout(
            positions=tuple(tuple(float(c) for c in p) for p in value["positions"]),
            directions=tuple(tuple(float(c) for c in d) for d in value["directions"]),
            max_forward=float(value["max_forward"]),
            max_reverse=float(value["max_reverse"]),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(
            "realism: layout must have positions and directions (one (x, y, z) per thruster), max_forward and "
            f"max_reverse; got {dict(value)!r} ({exc})"
        ) from None


def _number(name: str, v: Any, *, allow_none: bool = False, positive: bool = False) -> None:
    """``ValueError`` naming knob ``name`` unless ``v`` is a finite number ``>= 0`` (``> 0`` with ``positive``)."""
    if v is None and allow_none:
        return
    ok = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and math.isfinite(v)
    if not ok or v < 0 or (positive and v == 0):
        need = "a finite number > 0" if positive else "a finite number >= 0"
        raise ValueError(f"realism: {name} must be {need}, got {v!r}")


def check_config(cfg: RealismConfig, *, episode_time: float | None = None) -> None:
    """Validate every knob of ``cfg`` (one ``ValueError`` naming the first bad one).

    The thruster layout's rank (every wrench direction producible) is checked where the allocation is built
    (:func:`uvdms_gym.realism.actuation.Thrusters`), with the same one-line error.
    """
    _number("action_delay", cfg.action_delay)
    _number("rotor_time_constant", cfg.rotor_time_constant)
    _number("joint_speed_limit", cfg.joint_speed_limit, allow_none=True, positive=True)
    _number("dead_zone", cfg.dead_zone)
    if cfg.dead_zone >= 1.0:
        raise ValueError(f"realism: dead_zone must be below 1 (a fraction of full thrust), got {cfg.dead_zone!r}")
    if not isinstance(cfg.thrusters, bool):
        raise ValueError(f"realism: thrusters must be true or false, got {cfg.thrusters!r}")
    if episode_time is not None and cfg.action_delay >= episode_time:
        delay = cfg.action_delay
        raise ValueError(f"realism: action_delay ({delay} s) must be shorter than the episode ({episode_time} s)")
    for name in SENSOR_NAMES:
        _check_sensor(name, cfg.sensor(name), episode_time)


def _check_sensor(name: str, spec: SensorSpec, episode_time: float | None) -> None:
    _number(f"{name}_period", spec.period, allow_none=True, positive=True)
    _number(f"{name}_latency", spec.latency)
    for knob in ("bias_sigma", "bias_walk", "dropout_prob"):
        _number(f"{name}_{knob}", getattr(spec, knob))
    sig = np.atleast_1d(np.asarray(spec.sigma, dtype=object))
    if sig.size not in (1, SENSOR_DIMS[name]):
        raise ValueError(f"realism: {name}_sigma must be one number or {SENSOR_DIMS[name]}, got {spec.sigma!r}")
    for s in sig.tolist():
        _number(f"{name}_sigma", s)
    if spec.dropout_prob > 1.0:
        raise ValueError(f"realism: {name}_dropout_prob must be at most 1, got {spec.dropout_prob!r}")
    n = spec.dropout_len
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"realism: {name}_dropout_len must be a whole number >= 0, got {n!r}")
    if spec.dropout_prob > 0 and n < 1:
        raise ValueError(f"realism: {name}_dropout_len must be >= 1 when {name}_dropout_prob > 0, got {n!r}")
    for knob in ("latency", "period"):
        value = getattr(spec, knob)
        if episode_time is not None and value is not None and value >= episode_time:
            raise ValueError(f"realism: {name}_{knob} ({value} s) must be shorter than the episode ({episode_time} s)")


def noise_streams(seed: int, episode: int, names: tuple[str, ...]) -> dict[str, np.random.Generator]:
    """One independent generator per name, from the episode's seed: the same seed, the same noise at every level.

    The streams are children of ``SeedSequence(seed)`` keyed by the episode's index since that seed (so that
    episodes after a ``reset()`` without a seed draw new noise) and the name's position in ``names``; nothing is
    drawn from the environment's own generator, so the task a seed draws does not depend on the level.
    """
    return {
        name: np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(int(episode), i)))
        for i, name in enumerate(names)
    }
