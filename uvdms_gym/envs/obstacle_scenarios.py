"""Random outer-obstacle scenarios of ``uvdms/TransportObstacles-v1`` (``obstacles="random"``).

[D] A scenario is 1 to :data:`MAX_RANDOM_OBSTACLES` obstacles, each crossing the transport. A candidate picks a
crossing time ``t_c`` in :data:`CROSSING_WINDOW` times ``move_time`` and a target point that the *nominal robot*
(the object on its reference, all joints at zero, the vehicle placed accordingly) occupies at ``t_c``: a point on
the object, or the midpoint of a distal arm link. It moves with a constant velocity (speed in
:data:`SPEED_RANGE`, direction across the path's tangent at ``t_c`` and across the part: an obstacle moving
along the path could only be fled from, one moving along the part takes long to clear it) past that point, its
path shifted sideways (across the part and the motion) so that it overlaps the part by up to :data:`MAX_DEPTH`,
and keeps going. Spheres are debris; capsules are drifting pipes, broadside to their motion and alongside the
part they pass.

A candidate is kept only if, against the nominal robot over the whole episode (:func:`random_obstacles`'s
``nominal_gaps``): it starts at least :data:`START_CLEARANCE` away; it touches the nominal robot (a controller
that tracks the reference and ignores obstacles makes contact), but no deeper than :data:`MAX_DEPTH` (a
glancing pass that a small evasion clears); it comes within :data:`EVASION_ZONE` of neither the hull nor both arms (it
brushes the object and at most one arm from outside, rather than threading the ring that the arms, the object and
the hull form, from which no evasion frees it); it stays within :data:`EVASION_ZONE` for at most
:data:`MAX_INTERACTION` (it crosses, rather than travelling along the path, where no local evasion lets it pass);
and it is at least :data:`HOLD_CLEARANCE` away during the hold, where success is judged. Obstacles also start
:data:`START_CLEARANCE` apart. Everything is drawn from the environment's seeded generator: a seed fixes the
scenario.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from uvdms_gym.physics.frames import euler_to_rot
from uvdms_gym.physics.obstacles import Obstacle

MAX_RANDOM_OBSTACLES = 3
CROSSING_WINDOW = (0.25, 0.65)
"""Crossing time as a fraction of ``move_time``: obstacles are gone before the hold, where success is judged."""
SPEED_RANGE = (0.08, 0.2)
"""Obstacle speed, m/s."""
SPHERE_RADIUS = (0.05, 0.1)
CAPSULE_RADIUS = (0.03, 0.06)
CAPSULE_LENGTH = (0.2, 0.4)
SPHERE_PROBABILITY = 0.6
OBJECT_TARGET_PROBABILITY = 0.6
"""Probability that an obstacle aims at the object (else at a distal arm link)."""
START_CLEARANCE = 0.3
"""Smallest gap between a new obstacle at ``t = 0`` and the robot or another obstacle, m."""
MAX_DEPTH = 0.05
"""Deepest overlap with the nominal robot an obstacle may reach, m: the pass glances (an evasion of about this)."""
EVASION_ZONE = 0.1
MAX_INTERACTION = 3.0
"""Longest time an obstacle may spend within :data:`EVASION_ZONE` of the nominal robot, s."""
HOLD_CLEARANCE = 0.4
"""Smallest gap to the nominal robot during the hold (``t >= move_time``), where success is judged, m."""
MAX_ATTEMPTS = 500


def _unit_across(rng: np.random.Generator, axis: np.ndarray) -> np.ndarray:
    """A random unit vector perpendicular to ``axis``."""
    while True:
        v = rng.normal(size=3)
        v -= (v @ axis) * axis
        n = np.linalg.norm(v)
        if n > 1e-6:
            return v / n


def _target(rng: np.random.Generator, pose: np.ndarray, nominal_links: Callable[[np.ndarray], np.ndarray], radii):
    """A point on the axis of a part the nominal robot has at the object pose ``pose``, the axis, the part's radius."""
    rot = euler_to_rot(pose[3:])
    if rng.uniform() < OBJECT_TARGET_PROBABILITY:
        return pose[:3] + rng.uniform(-0.2, 0.2) * rot[:, 1], rot[:, 1], radii[0]
    seg = nominal_links(pose)  # (2, 7, 2, 3)
    a, b = seg[int(rng.integers(2)), int(rng.integers(4, 7))]
    return 0.5 * (a + b), (b - a) / max(float(np.linalg.norm(b - a)), 1e-9), radii[1]


def _draw_one(rng: np.random.Generator, reference, move_time: float, nominal_links, radii) -> Obstacle:
    t_c = rng.uniform(*CROSSING_WINDOW) * move_time
    pose = np.asarray(reference(t_c), dtype=float)
    target, across, part_radius = _target(rng, pose, nominal_links, radii)
    tangent = np.asarray(reference(t_c + 0.5), dtype=float)[:3] - np.asarray(reference(t_c - 0.5), dtype=float)[:3]
    u = np.cross(across, tangent)  # across the path and across the part: it clears both quickly
    norm = float(np.linalg.norm(u))
    u = u / norm * rng.choice((-1.0, 1.0)) if norm > 1e-6 else _unit_across(rng, across)
    speed = rng.uniform(*SPEED_RANGE)
    if rng.uniform() < SPHERE_PROBABILITY:
        radius, length, axis = rng.uniform(*SPHERE_RADIUS), 0.0, (0.0, 1.0, 0.0)
    else:
        radius, length = rng.uniform(*CAPSULE_RADIUS), rng.uniform(*CAPSULE_LENGTH)
        axis = tuple(across)  # alongside the part it passes (broadside to its motion, as u is across the part)
    side = np.cross(across, u)  # across the part and across the motion: a glancing pass, |miss| from the axis
    side_norm = float(np.linalg.norm(side))
    side = side / side_norm if side_norm > 1e-6 else _unit_across(rng, u)
    miss = side * rng.choice((-1.0, 1.0)) * (radius + part_radius - rng.uniform(0.005, MAX_DEPTH))
    start = target + miss - speed * t_c * u
    return Obstacle(
        shape="sphere" if length == 0.0 else "capsule",
        radius=float(radius),
        position=tuple(start),
        velocity=tuple(speed * u),
        length=float(length),
        axis=axis,
    )


PART_GROUPS: tuple[slice, ...] = (slice(0, 6), slice(6, 12), slice(12, 13), slice(13, 14))
"""The robot's parts in the gap rows, grouped: left arm, right arm, object, hull."""


def _acceptable(times: np.ndarray, gaps: np.ndarray, move_time: float) -> bool:
    """Whether a candidate's gaps to the nominal robot ``(T, 14)`` make a crossing worth keeping."""
    closest = gaps.min(axis=1)
    dt = float(times[1] - times[0])
    left, right, _, hull = (bool(gaps[:, g].min() < EVASION_ZONE) for g in PART_GROUPS)
    return bool(
        closest[0] >= START_CLEARANCE
        and -MAX_DEPTH <= closest.min() < 0.0
        and not hull
        and not (left and right)  # it brushes the object and/or one arm from outside, not into the frame
        and np.count_nonzero(closest < EVASION_ZONE) * dt <= MAX_INTERACTION
        and closest[times >= move_time].min() >= HOLD_CLEARANCE
    )


def random_obstacles(
    rng: np.random.Generator,
    reference,
    move_time: float,
    nominal_links: Callable[[np.ndarray], np.ndarray],
    nominal_gaps: Callable[[Obstacle], tuple[np.ndarray, np.ndarray]],
    radii: tuple[float, float],
) -> tuple[Obstacle, ...]:
    """A random scenario (module docstring).

    Args:
        rng: the environment's generator.
        reference: the task's object-pose reference ``t -> [x y z phi theta psi]``.
        move_time: the transport's move time, s.
        nominal_links: object pose -> link segments ``(2, 7, 2, 3)`` of the robot holding it at ``q = 0``.
        nominal_gaps: obstacle -> ``(times, gaps)``: its gaps ``(T, n_parts)`` to the nominal robot (the object on
            its reference, ``q = 0``) on an even time grid over the episode.
        radii: the object's and the arm links' radii, m.

    Returns:
        1 to :data:`MAX_RANDOM_OBSTACLES` obstacles.
    """
    n = int(rng.integers(1, MAX_RANDOM_OBSTACLES + 1))
    chosen: list[Obstacle] = []
    for _ in range(MAX_ATTEMPTS):
        if len(chosen) == n:
            break
        ob = _draw_one(rng, reference, move_time, nominal_links, radii)
        if any(_start_gap(ob, other) < START_CLEARANCE for other in chosen):
            continue
        if _acceptable(*nominal_gaps(ob), move_time):
            chosen.append(ob)
    if not chosen:
        raise RuntimeError("could not place a random obstacle crossing the transport")
    return tuple(chosen)


def _start_gap(a: Obstacle, b: Obstacle) -> float:
    """A lower bound of the gap between two obstacles at ``t = 0`` (centres minus bounding radii)."""
    dist = float(np.linalg.norm(np.subtract(a.position, b.position)))
    return dist - (a.radius + a.half_length) - (b.radius + b.half_length)
