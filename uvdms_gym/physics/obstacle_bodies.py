"""PyBullet bodies of the outer obstacles (:mod:`uvdms_gym.physics.obstacles`), owned by a simulator.

Each obstacle is a heavy PyBullet body (:data:`OBSTACLE_MASS`) with a sphere or capsule collision and visual shape,
moved kinematically: :meth:`ObstacleBodies.place` puts every body at its script's pose and velocity for a time, and
the simulator calls it after every physics step, so a body is always where its script says at the simulator's
time. During a step it moves with its script's velocity and its weight cancelled: it pushes the robot, and the
robot cannot push it measurably.

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
from uvdms_gym.physics.params import GRAVITY

ROBOT_GROUP = 1
"""PyBullet's default collision group of a dynamic multibody's links."""
OBJECT_GROUP = 2
OBSTACLE_GROUP = 4
OBSTACLE_RGBA = (0.85, 0.25, 0.2, 1.0)
OBSTACLE_MASS = 1.0e5
"""Mass of an obstacle's body, kg [D]. A fixed (mass 0) body does not enter the contact solver with a velocity, so
it pushed only by penetration recovery and a fast obstacle passed through the gripped object; a body this heavy,
given its script's velocity before each physics step and put back on its script after it, pushes the robot at
its own speed (the robot weighs about 200 kg with added mass) while the robot moves it by less than 1e-6 m."""
_reset_pose = pb.resetBasePositionAndOrientation
_reset_velocity = pb.resetBaseVelocity
_apply_force = pb.applyExternalForce
_WORLD = pb.WORLD_FRAME
_ZERO = (0.0, 0.0, 0.0)


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
        self._lift = (0.0, 0.0, 0.0)

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
            body = c.createMultiBody(baseMass=OBSTACLE_MASS, baseCollisionShapeIndex=col, baseVisualShapeIndex=vis)
            c.changeDynamics(body, -1, linearDamping=0.0, angularDamping=0.0)
            c.setCollisionFilterGroupMask(body, -1, OBSTACLE_GROUP, ROBOT_GROUP | OBJECT_GROUP)
            ids.append(body)
        self.obstacles = tuple(obstacles)
        self.body_ids = tuple(ids)
        # constant-velocity scripts in plain floats (placed every physics step); waypoint scripts use np.interp
        self._linear = [None if ob.waypoints else (ob.position, ob.velocity) for ob in self.obstacles]
        self._orientations = [axis_quaternion(ob.axis) for ob in self.obstacles]
        self._lift = (0.0, 0.0, OBSTACLE_MASS * GRAVITY)  # cancels the weight during a physics step
        self.place(t)

    def clear(self) -> None:
        """Remove every obstacle body."""
        for body in self.body_ids:
            self._client.removeBody(body)
        self.obstacles, self.body_ids, self._linear, self._orientations = (), (), [], []

    def place(self, t: float) -> None:
        """Put every body at its script's pose and velocity at time ``t`` (z-up world), weight cancelled.

        Called after every physics step: during the next one each body moves with its script's velocity and
        meets the robot in the contact solver as a body :data:`OBSTACLE_MASS` heavy (so the robot is pushed at
        the obstacle's speed and hardly pushes back); then it is put back on its script.
        """
        cid = self._cid
        for body, ob, lin, quat in zip(self.body_ids, self.obstacles, self._linear, self._orientations):
            if lin is not None:
                (x, y, z), (vx, vy, vz) = lin
                pos, vel = (x + t * vx, -(y + t * vy), -(z + t * vz)), (vx, -vy, -vz)
            else:
                p, v = ob.position_at(t), ob.velocity_at(t)
                pos, vel = (p[0], -p[1], -p[2]), (v[0], -v[1], -v[2])
            _reset_pose(body, pos, quat, physicsClientId=cid)
            _reset_velocity(body, vel, _ZERO, physicsClientId=cid)
            _apply_force(body, -1, self._lift, pos, _WORLD, physicsClientId=cid)

    def positions(self) -> np.ndarray:
        """Centres as PyBullet holds them, NED ``(K, 3)`` (for checks against the script)."""
        out = np.empty((len(self.body_ids), 3))
        for k, body in enumerate(self.body_ids):
            out[k] = frames.world_to_ned(np.array(pb.getBasePositionAndOrientation(body, physicsClientId=self._cid)[0]))
        return out
