"""PyBullet bodies of the outer obstacles (:mod:`uvdms_gym.physics.obstacles`), owned by a simulator.

Each obstacle is a static (mass 0) PyBullet body with a sphere or capsule collision and visual shape, moved
kinematically: :meth:`ObstacleBodies.place` puts every body at its script's pose for a time, and the
simulator calls it after every physics step, so a body is always where its script says at the simulator's time.
During a step the contact solver treats it as immovable: it pushes the robot, nothing pushes it.

Collision groups [D]: the robot keeps PyBullet's defaults (group 1); obstacles are group :data:`OBSTACLE_GROUP`
and collide with the robot and the object (mask ``1 | OBJECT_GROUP``) but not with each other; the gripped object
(group :data:`OBJECT_GROUP`) collides with obstacles only, never with the arms that hold it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pybullet as pb

from uvdms_gym.physics import frames
from uvdms_gym.physics.obstacles import Obstacle

ROBOT_GROUP = 1
"""PyBullet's default collision group of a dynamic multibody's links."""
OBJECT_GROUP = 2
OBSTACLE_GROUP = 4
OBSTACLE_RGBA = (0.85, 0.25, 0.2, 1.0)
_reset_pose = pb.resetBasePositionAndOrientation


def axis_quaternion(axis_ned: Sequence[float]) -> list[float]:
    """World (z-up) quaternion ``xyzw`` turning the local ``z`` axis (PyBullet's capsule axis) onto ``axis_ned``."""
    a = frames.ned_to_world(np.asarray(axis_ned, dtype=float))
    a = a / np.linalg.norm(a)
    z = np.array([0.0, 0.0, 1.0])
    c = float(z @ a)
    if c < -1.0 + 1e-12:  # opposite: a half turn about x
        return [1.0, 0.0, 0.0, 0.0]
    v = np.cross(z, a)
    q = np.array([v[0], v[1], v[2], 1.0 + c])
    return (q / np.linalg.norm(q)).tolist()


class ObstacleBodies:
    """The obstacle bodies of one PyBullet client (created by :meth:`set`, moved by :meth:`place`).

    Args:
        client: the simulator's ``BulletClient``.
    """

    def __init__(self, client) -> None:
        self._client = client
        self._cid: int = client._client
        self.obstacles: tuple[Obstacle, ...] = ()
        self.body_ids: tuple[int, ...] = ()
        self._linear: list[tuple[tuple[float, ...], tuple[float, ...]] | None] = []
        self._orientations: list[list[float]] = []

    def set(self, obstacles: Sequence[Obstacle], t: float) -> None:
        """Remove the previous bodies, create one per obstacle and place them at time ``t``."""
        self.clear()
        c = self._client
        ids = []
        for ob in obstacles:
            if ob.shape == "sphere":
                col = c.createCollisionShape(pb.GEOM_SPHERE, radius=ob.radius)
                vis = c.createVisualShape(pb.GEOM_SPHERE, radius=ob.radius, rgbaColor=OBSTACLE_RGBA)
            else:
                col = c.createCollisionShape(pb.GEOM_CAPSULE, radius=ob.radius, height=ob.length)
                vis = c.createVisualShape(pb.GEOM_CAPSULE, radius=ob.radius, length=ob.length, rgbaColor=OBSTACLE_RGBA)
            body = c.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=col, baseVisualShapeIndex=vis)
            c.setCollisionFilterGroupMask(body, -1, OBSTACLE_GROUP, ROBOT_GROUP | OBJECT_GROUP)
            ids.append(body)
        self.obstacles = tuple(obstacles)
        self.body_ids = tuple(ids)
        # constant-velocity scripts in plain floats (placed every physics step); waypoint scripts use np.interp
        self._linear = [None if ob.waypoints else (ob.position, ob.velocity) for ob in self.obstacles]
        self._orientations = [axis_quaternion(ob.axis) for ob in self.obstacles]
        self.place(t)

    def clear(self) -> None:
        """Remove every obstacle body."""
        for body in self.body_ids:
            self._client.removeBody(body)
        self.obstacles, self.body_ids, self._linear, self._orientations = (), (), [], []

    def place(self, t: float) -> None:
        """Put every body at its script's position at time ``t`` (z-up world).

        A PyBullet body of mass 0 is fixed: its velocity does not enter the contact solver (and
        ``resetBasePositionAndOrientation`` zeroes it), so only the pose is set; a robot part the obstacle moves
        into is pushed out by the solver's penetration recovery in the next physics step.
        """
        cid = self._cid
        for body, ob, lin, quat in zip(self.body_ids, self.obstacles, self._linear, self._orientations):
            if lin is not None:
                (x, y, z), (vx, vy, vz) = lin
                pos = (x + t * vx, -(y + t * vy), -(z + t * vz))
            else:
                p = ob.position_at(t)
                pos = (p[0], -p[1], -p[2])
            _reset_pose(body, pos, quat, physicsClientId=cid)

    def positions(self) -> np.ndarray:
        """Centres as PyBullet holds them, NED ``(K, 3)`` (for checks against the script)."""
        out = np.empty((len(self.body_ids), 3))
        for k, body in enumerate(self.body_ids):
            out[k] = frames.world_to_ned(np.array(pb.getBasePositionAndOrientation(body, physicsClientId=self._cid)[0]))
        return out
