"""Outer obstacles: kinematic spheres and capsules that move along a scripted path (NED).

An :class:`Obstacle` is rigid, keeps its orientation, and moves either with a constant velocity from its initial
position or piecewise linearly through timed waypoints (held after the last one). It is *kinematic*: its
motion is prescribed, it pushes the robot on contact and nothing pushes it. The simulator places it at
``position_at(t)`` after every physics step (:meth:`uvdms_gym.physics.sim.UVDMSSim.set_obstacles`), so the
obstacle seen at time ``t`` is exactly the script's.

A sphere's *core* is its centre; a capsule's core is the segment ``c +- (length / 2) axis``; the surface is the
core swept by a ball of ``radius``. Distances to obstacles are gaps between surfaces
(:mod:`uvdms_gym.distances.outer`).

Specifications come as :class:`Obstacle` objects or as dictionaries with the keys of :data:`SPEC_KEYS`
(``yaml.safe_load`` / ``--env-kwargs`` friendly); :func:`parse_obstacles` checks every value and names the first
problem it finds.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from uvdms_gym.utils.validation import finite_vector

SHAPES = ("sphere", "capsule")
MAX_OBSTACLE_SPEED = 2.0
"""Largest speed of an obstacle (constant velocity or between waypoints), m/s."""
SPEC_KEYS = ("shape", "radius", "length", "position", "velocity", "waypoints", "axis")
"""Keys of a dictionary obstacle specification."""
STATE_COLS = 11
"""Columns of :func:`obstacle_states`: position (3), velocity (3), radius, half length, axis (3)."""
POS, VEL, RADIUS, HALF_LENGTH, AXIS = slice(0, 3), slice(3, 6), 6, 7, slice(8, 11)
"""Column selectors of :func:`obstacle_states`."""


def _finite_number(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(float(value)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Obstacle:
    """A kinematic sphere or capsule (NED, m, s).

    Attributes:
        shape: ``"sphere"`` or ``"capsule"``.
        radius: radius of the ball swept along the core, m (> 0).
        position: centre at ``t = 0``, NED.
        velocity: constant velocity, NED, m/s (ignored when ``waypoints`` are given; must then be zero).
        waypoints: ``(t, x, y, z)`` rows with strictly increasing times ``t > 0``: the centre moves linearly
            from ``position`` at 0 to each waypoint at its time and stays at the last one.
        length: length of a capsule's core segment, m (> 0 for a capsule, 0 for a sphere).
        axis: direction of a capsule's core, NED (normalised on construction).
    """

    shape: str
    radius: float
    position: tuple[float, float, float]
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    waypoints: tuple[tuple[float, float, float, float], ...] = ()
    length: float = 0.0
    axis: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def __post_init__(self) -> None:
        if self.shape not in SHAPES:
            raise ValueError(f"obstacle shape must be one of {SHAPES}, got {self.shape!r}")
        radius = _finite_number(self.radius, "obstacle radius")
        if radius <= 0.0:
            raise ValueError(f"obstacle radius must be > 0, got {self.radius!r}")
        length = _finite_number(self.length, "obstacle length")
        if self.shape == "capsule" and length <= 0.0:
            raise ValueError(f"a capsule obstacle needs length > 0, got {self.length!r}")
        if self.shape == "sphere" and length != 0.0:
            raise ValueError(f"a sphere obstacle has no length, got length={self.length!r}")
        axis = finite_vector(self.axis, 3, "obstacle axis")
        norm = float(np.linalg.norm(axis))
        if norm < 1e-9:
            raise ValueError(f"obstacle axis must be non-zero, got {self.axis!r}")
        velocity = tuple(finite_vector(self.velocity, 3, "obstacle velocity").tolist())
        waypoints = tuple(tuple(finite_vector(w, 4, "obstacle waypoint (t, x, y, z)").tolist()) for w in self.waypoints)
        object.__setattr__(self, "radius", radius)
        object.__setattr__(self, "length", length)
        object.__setattr__(self, "axis", tuple(float(x) for x in axis / norm))
        object.__setattr__(self, "position", tuple(finite_vector(self.position, 3, "obstacle position").tolist()))
        object.__setattr__(self, "velocity", velocity)
        object.__setattr__(self, "waypoints", waypoints)
        self._check_motion()

    def _check_motion(self) -> None:
        if not self.waypoints:
            speed = float(np.linalg.norm(self.velocity))
            if speed > MAX_OBSTACLE_SPEED:
                raise ValueError(f"obstacle speed {speed:.3g} m/s exceeds {MAX_OBSTACLE_SPEED} m/s")
            return
        if any(self.velocity):
            raise ValueError("give an obstacle either a velocity or waypoints, not both")
        times = [0.0] + [w[0] for w in self.waypoints]
        if any(b <= a for a, b in itertools.pairwise(times)):
            raise ValueError(f"obstacle waypoint times must be > 0 and strictly increasing, got {times[1:]}")
        points = np.array([self.position] + [w[1:] for w in self.waypoints])
        speeds = np.linalg.norm(np.diff(points, axis=0), axis=1) / np.diff(times)
        if speeds.max() > MAX_OBSTACLE_SPEED:
            raise ValueError(f"obstacle speed {speeds.max():.3g} m/s between waypoints exceeds {MAX_OBSTACLE_SPEED}")

    @property
    def half_length(self) -> float:
        """Half the core segment's length (0 for a sphere), m."""
        return 0.5 * self.length

    def position_at(self, t: float | np.ndarray) -> np.ndarray:
        """Centre at time(s) ``t`` (s): (3,) or (N, 3)."""
        t_arr = np.asarray(t, dtype=float)
        if not self.waypoints:
            return np.asarray(self.position) + t_arr[..., None] * np.asarray(self.velocity)
        times = np.array([0.0] + [w[0] for w in self.waypoints])
        points = np.array([self.position] + [w[1:] for w in self.waypoints])
        return np.stack([np.interp(t_arr, times, points[:, k]) for k in range(3)], axis=-1)

    def velocity_at(self, t: float) -> np.ndarray:
        """Velocity at time ``t`` (s): the constant velocity, or the current waypoint segment's (0 after the last)."""
        if not self.waypoints:
            return np.asarray(self.velocity, dtype=float)
        times = [0.0] + [w[0] for w in self.waypoints]
        points = [self.position] + [w[1:] for w in self.waypoints]
        for k in range(len(times) - 1):
            if times[k] <= t < times[k + 1]:
                return (np.asarray(points[k + 1]) - np.asarray(points[k])) / (times[k + 1] - times[k])
        return np.zeros(3)

    def as_dict(self) -> dict[str, Any]:
        """The specification as plain lists (the form :func:`parse_obstacles` reads back)."""
        out: dict[str, Any] = {"shape": self.shape, "radius": self.radius, "position": list(self.position)}
        if self.shape == "capsule":
            out.update(length=self.length, axis=list(self.axis))
        if self.waypoints:
            out["waypoints"] = [list(w) for w in self.waypoints]
        else:
            out["velocity"] = list(self.velocity)
        return out


def parse_obstacle(spec: Obstacle | Mapping[str, Any], index: int = 0) -> Obstacle:
    """One obstacle from an :class:`Obstacle` or a dictionary (unknown keys and bad values name the problem)."""
    if isinstance(spec, Obstacle):
        return spec
    if not isinstance(spec, Mapping):
        raise ValueError(f"obstacles[{index}] must be a mapping with keys {SPEC_KEYS}, got {spec!r}")
    unknown = sorted(set(spec) - set(SPEC_KEYS))
    if unknown:
        raise ValueError(f"obstacles[{index}]: unknown key(s) {unknown}; allowed: {list(SPEC_KEYS)}")
    for key in ("shape", "radius", "position"):
        if key not in spec:
            raise ValueError(f"obstacles[{index}]: missing key {key!r}")
    kwargs = dict(spec)
    if "waypoints" in kwargs:
        kwargs["waypoints"] = tuple(tuple(w) if isinstance(w, Sequence) else w for w in kwargs["waypoints"])
    try:
        return Obstacle(**kwargs)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"obstacles[{index}]: {exc}") from None


def parse_obstacles(spec: Sequence[Obstacle | Mapping[str, Any]]) -> tuple[Obstacle, ...]:
    """A tuple of obstacles from a list of specifications (see :func:`parse_obstacle`)."""
    if isinstance(spec, (str, bytes, Mapping)) or not isinstance(spec, Sequence):
        raise ValueError(f"obstacles must be 'random', None or a list of obstacle specifications, got {spec!r}")
    return tuple(parse_obstacle(s, i) for i, s in enumerate(spec))


def obstacle_states(obstacles: Sequence[Obstacle], t: float) -> np.ndarray:
    """The obstacles at time ``t`` as one ``(K, STATE_COLS)`` array (what ``info["obstacles"]`` reports).

    Columns: centre (3, NED), velocity (3, NED), radius, half length of the core, core axis (3, NED).
    """
    out = np.zeros((len(obstacles), STATE_COLS))
    for k, ob in enumerate(obstacles):
        out[k, POS] = ob.position_at(t)
        out[k, VEL] = ob.velocity_at(t)
        out[k, RADIUS] = ob.radius
        out[k, HALF_LENGTH] = ob.half_length
        out[k, AXIS] = ob.axis
    return out


def core_segments(states: np.ndarray) -> np.ndarray:
    """Core segments ``(K, 2, 3)`` (``A``, ``B``, NED) of obstacles given as :func:`obstacle_states` rows."""
    states = np.asarray(states, dtype=float).reshape(-1, STATE_COLS)
    half = states[:, HALF_LENGTH, None] * states[:, AXIS]
    return np.stack([states[:, POS] - half, states[:, POS] + half], axis=1)
