"""Random outer-obstacle scenarios of ``uvdms/TransportObstacles-v1`` (``obstacles="random"``).

[D] A scenario is 1 to :data:`MAX_RANDOM_OBSTACLES` obstacles, each aimed to cross the transport's path: an
obstacle picks a crossing time ``t_c`` in :data:`CROSSING_WINDOW` times ``move_time`` and a target point that
the nominal robot occupies at ``t_c`` (a point on the object's reference pose, or the midpoint of a distal arm
link with the vehicle placed for that pose at ``q = 0``), plus a miss offset smaller than the sum of the radii,
so that a robot that tracks its reference and ignores the obstacle touches it. It moves with a constant velocity
(speed in :data:`SPEED_RANGE`, direction across the object's axis) through that point at ``t_c`` and keeps
going. Spheres are debris; capsules are drifting pipes, broadside to their motion. An obstacle is redrawn when it
would start within :data:`START_CLEARANCE` of the robot or of another obstacle. Everything is drawn from the
environment's seeded generator, so a seed fixes the scenario.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from uvdms_gym.physics.frames import euler_to_rot
from uvdms_gym.physics.obstacles import Obstacle, obstacle_states

MAX_RANDOM_OBSTACLES = 3
CROSSING_WINDOW = (0.25, 0.65)
"""Crossing time as a fraction of ``move_time``: obstacles are gone before the hold, where success is judged."""
SPEED_RANGE = (0.06, 0.12)
"""Obstacle speed, m/s."""
SPHERE_RADIUS = (0.06, 0.14)
CAPSULE_RADIUS = (0.03, 0.06)
CAPSULE_LENGTH = (0.3, 0.8)
SPHERE_PROBABILITY = 0.6
OBJECT_TARGET_PROBABILITY = 0.6
"""Probability that an obstacle aims at the object (else at a distal arm link)."""
START_CLEARANCE = 0.3
"""Smallest gap between a new obstacle at ``t = 0`` and the robot or another obstacle, m."""
MAX_ATTEMPTS = 200


def _unit_across(rng: np.random.Generator, axis: np.ndarray) -> np.ndarray:
    """A random unit vector perpendicular to ``axis``."""
    while True:
        v = rng.normal(size=3)
        v -= (v @ axis) * axis
        n = np.linalg.norm(v)
        if n > 1e-6:
            return v / n


def _target(rng: np.random.Generator, pose: np.ndarray, nominal_links: Callable[[np.ndarray], np.ndarray]):
    """A point the nominal robot occupies at the object pose ``pose``, and the radius of the part there."""
    rot = euler_to_rot(pose[3:])
    if rng.uniform() < OBJECT_TARGET_PROBABILITY:
        return pose[:3] + rng.uniform(-0.2, 0.2) * rot[:, 1], rot[:, 1]
    seg = nominal_links(pose)  # (2, 7, 2, 3)
    a, b = seg[int(rng.integers(2)), int(rng.integers(4, 7))]
    return 0.5 * (a + b), (b - a) / max(float(np.linalg.norm(b - a)), 1e-9)


def _draw_one(rng: np.random.Generator, reference, move_time: float, nominal_links, part_radius: float) -> Obstacle:
    t_c = rng.uniform(*CROSSING_WINDOW) * move_time
    pose = np.asarray(reference(t_c), dtype=float)
    target, across = _target(rng, pose, nominal_links)
    u = _unit_across(rng, across)
    speed = rng.uniform(*SPEED_RANGE)
    if rng.uniform() < SPHERE_PROBABILITY:
        radius, length, axis = rng.uniform(*SPHERE_RADIUS), 0.0, (0.0, 1.0, 0.0)
    else:
        radius, length = rng.uniform(*CAPSULE_RADIUS), rng.uniform(*CAPSULE_LENGTH)
        axis = tuple(_unit_across(rng, u))
    miss = _unit_across(rng, u) * rng.uniform(0.0, 0.5) * (radius + part_radius)
    start = target + miss - speed * t_c * u
    return Obstacle(
        shape="sphere" if length == 0.0 else "capsule",
        radius=float(radius),
        position=tuple(start),
        velocity=tuple(speed * u),
        length=float(length),
        axis=axis,
    )


def random_obstacles(
    rng: np.random.Generator,
    reference,
    move_time: float,
    nominal_links: Callable[[np.ndarray], np.ndarray],
    start_gaps: Callable[[np.ndarray], np.ndarray],
    part_radius: float,
) -> tuple[Obstacle, ...]:
    """A random scenario (module docstring).

    Args:
        rng: the environment's generator.
        reference: the task's object-pose reference ``t -> [x y z phi theta psi]``.
        move_time: the transport's move time, s.
        nominal_links: object pose -> link segments ``(2, 7, 2, 3)`` of the robot holding it at ``q = 0``.
        start_gaps: obstacle states ``(K, 11)`` -> gaps ``(K, n_parts)`` to the robot's initial state.
        part_radius: a typical radius of the robot's parts (the miss offset's scale), m.

    Returns:
        1 to :data:`MAX_RANDOM_OBSTACLES` obstacles.
    """
    n = int(rng.integers(1, MAX_RANDOM_OBSTACLES + 1))
    chosen: list[Obstacle] = []
    for _ in range(MAX_ATTEMPTS):
        if len(chosen) == n:
            break
        ob = _draw_one(rng, reference, move_time, nominal_links, part_radius)
        if start_gaps(obstacle_states([ob], 0.0)).min() < START_CLEARANCE:
            continue
        if any(_start_gap(ob, other) < START_CLEARANCE for other in chosen):
            continue
        chosen.append(ob)
    if not chosen:
        raise RuntimeError("could not place a random obstacle clear of the robot's start")
    return tuple(chosen)


def _start_gap(a: Obstacle, b: Obstacle) -> float:
    """A lower bound of the gap between two obstacles at ``t = 0`` (centres minus bounding radii)."""
    dist = float(np.linalg.norm(np.subtract(a.position, b.position)))
    return dist - (a.radius + a.half_length) - (b.radius + b.half_length)
