"""The UVDMS multibody in PyBullet: the engine set-up (:func:`configure_engine`) and the body (:func:`load_body`).

Physics set-up [D]:

* gravity ``(0, 0, -9.81)`` in the z-up world, default joint motors disabled, linear/angular damping 0
  on every link (PyBullet's default 0.04 would add an unmodelled damping), joint damping and friction 0;
  no self-collision flag: links pass through each other, contacts are *reported* by distance queries.
* joints in torque control; joint limits are PyBullet's URDF joint-limit constraints.
* constraints (joint limits, the two grasp welds) are solved by PyBullet's direct MLCP solver
  (``CONSTRAINT_SOLVER_LCP_DANTZIG``) with error reduction :data:`CONSTRAINT_ERP` = 0.8. The default
  iterative solver (PGS, 50 iterations, ERP 0.2) converges poorly on the closed chain (a 9.9 kg object,
  added mass included, between two arms whose distal links weigh 1.2-1.6 kg): 3-6 mm of grasp error
  under moderate motion, and no better with 1000 iterations. The direct solver meets the velocity
  constraints exactly; what remains is the second-order drift of the position integration
  (``~ w^2 r dt^2`` per step), removed at 80 % per step: 0.2 mm and 0.02 deg at joint rates up to
  5 rad/s (tested: < 1 mm, < 0.5 deg). Its cost is that of PGS within about 15 %: a physics step with the
  gripped object costs about 45 µs instead of 12 µs, the closed chain's constraint solve either way.
* ``physics_dt = 0.01 s`` by default: the hydrodynamic forces are explicit, and the stiffest explicit
  term is the one-step-lagged residual added mass (ratio 0.24, independent of ``dt``, see
  :mod:`uvdms_gym.physics.hydro`); the damping terms are far below their explicit limit ``dt d / m < 2`` (vehicle
  ``0.01 * 290 / 130``, links ``< 0.1`` below 10 m/s); the 1-DOF surge, heave and yaw responses match
  their ODEs within about 1 % (the surge residue is the pitch coupling of the low centre of gravity,
  unchanged at ``dt = 0.002``); the grasp welds stay within 0.2 mm (tested). Smaller ``dt`` costs
  proportionally more and buys little; larger ``dt`` grows the grasp drift as ``dt^2``.
* cost (``uvdms bench sim``, same states, median): bare ``stepSimulation`` 18-24 µs, one physics step with
  hydrodynamics 2.7x that (3.2x before the compiled link loop), the rest being the state read, the
  arithmetic and the 15 force calls.
* caution for controllers: at straight arms the roll joints 1, 3, 5 have tiny effective inertias
  (``1 / (M^-1)_ii`` = 4e-4 to 8e-4 kg m^2), so torques near ``tau_max`` spin them beyond
  :data:`~uvdms_gym.physics.state.QDOT_LIMIT` within one step
  (:class:`~uvdms_gym.physics.state.PhysicsError`).

Here: :func:`configure_engine` sets gravity and the solver, :func:`load_body` loads the body from
:func:`uvdms_gym.physics.model.build_urdf` with ``URDF_USE_INERTIA_FROM_FILE`` and sets its dynamics (joint-rate
clamp raised to :data:`MAX_JOINT_VELOCITY`, the arms' gear-train friction as joint damping).
"""

from __future__ import annotations

import sys
from types import MappingProxyType
from typing import NamedTuple

import pybullet as pb
from pybullet_utils.bullet_client import BulletClient

from uvdms_gym.physics import model
from uvdms_gym.physics.obstacle_bodies import OBSTACLE_GROUP, ROBOT_GROUP
from uvdms_gym.physics.params import GRAVITY, JOINT_NAMES, UVDMSParams
from uvdms_gym.physics.state import QDOT_LIMIT
from uvdms_gym.utils.io import quiet_c_stream

MAX_JOINT_VELOCITY = 10.0 * QDOT_LIMIT
"""PyBullet's joint-rate clamp (default 100 rad/s, a silent non-physical cap) is raised above
:data:`~uvdms_gym.physics.state.QDOT_LIMIT` so that the sanity check, not the clamp, decides."""
CONSTRAINT_ERP = 0.8
"""Error reduction parameter of the (non-contact) constraints: the fraction of a position error of the
grasp welds and joint limits removed per physics step [D] (PyBullet's default 0.2 leaves several times
more drift, see the module docstring)."""
CONSTRAINT_CFM = 1.0e-9
"""Global constraint force mixing: a tiny regularisation for the direct solver at singular (e.g.
straight-arm) configurations of the closed chain."""


class LoadedBody(NamedTuple):
    """The UVDMS multibody as loaded by :func:`load_body`.

    Attributes:
        body: PyBullet unique id of the multibody.
        link_index: link name -> link index (``"vehicle"`` is the base, -1).
        joints: joint indices in the order of ``q`` (empty without arms).
    """

    body: int
    link_index: MappingProxyType[str, int]
    joints: list[int]


def configure_engine(client: BulletClient, physics_dt: float) -> None:
    """Gravity, the fixed time step and the constraint solver of ``client``."""
    client.setGravity(0.0, 0.0, -GRAVITY)
    with quiet_c_stream(sys.stdout):  # switching the solver prints two lines on the C stdout
        client.setPhysicsEngineParameter(
            fixedTimeStep=physics_dt,
            constraintSolverType=pb.CONSTRAINT_SOLVER_LCP_DANTZIG,
            globalCFM=CONSTRAINT_CFM,
            erp=CONSTRAINT_ERP,
        )


def load_body(
    client: BulletClient, params: UVDMSParams, *, arms: bool, outer: bool, self_collision: bool
) -> LoadedBody:
    """Load the UVDMS into ``client`` and set its dynamics (see the module docstring).

    Args:
        client: a ``BulletClient``.
        params: the physical parameters.
        arms: ``False`` loads the bare vehicle.
        outer: give the hull a collision box and put the robot's links in the robot's collision group.
        self_collision: simulate contacts between non-adjacent links.
    """
    c = client
    path = model.write_urdf(model.build_urdf(params, arms=arms, hull_collision=outer))
    # With self_collision, contacts between non-adjacent links are simulated (physical contact forces) and
    # count_contacts() reads them from the contact manifold PyBullet builds during each step.
    flags = pb.URDF_USE_INERTIA_FROM_FILE
    if self_collision:
        flags |= pb.URDF_USE_SELF_COLLISION | pb.URDF_USE_SELF_COLLISION_EXCLUDE_PARENT
    body = c.loadURDF(str(path), flags=flags)
    names = {"vehicle": -1}
    for j in range(c.getNumJoints(body)):
        names[c.getJointInfo(body, j)[12].decode()] = j
    joint_names = JOINT_NAMES if arms else ()
    by_joint = {c.getJointInfo(body, j)[1].decode(): j for j in range(c.getNumJoints(body))}
    joints = [by_joint[n] for n in joint_names]
    if joints:
        c.setJointMotorControlArray(body, joints, pb.VELOCITY_CONTROL, forces=[0.0] * len(joints))
    for link in names.values():
        c.changeDynamics(body, link, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0)
    for j in joints:  # gear-train viscous friction (params.ArmParams.joint_friction)
        c.changeDynamics(body, j, jointDamping=params.arm.joint_friction)
    for j in joints:  # PyBullet silently clamps joint rates at 100 rad/s: let PhysicsError see them
        c.changeDynamics(body, j, maxJointVelocity=MAX_JOINT_VELOCITY)
    if outer:  # the robot's collision group, explicitly (obstacle_bodies.py)
        for link in names.values():
            c.setCollisionFilterGroupMask(body, link, ROBOT_GROUP, ROBOT_GROUP | OBSTACLE_GROUP)
    return LoadedBody(body, MappingProxyType(names), joints)
