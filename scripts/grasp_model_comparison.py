"""Compare the two ways of simulating the friction grasp: Bullet contacts between finger pads, and friction motors.

    python -m scripts.grasp_model_comparison [--out /tmp/grasp_model_comparison.json]

Both hold the object (:class:`~uvdms_gym.physics.params.ObjectParams`: 0.6 m x 0.05 m, 1100 kg/m^3) with its axis
vertical, so the axial load is its net weight ``W = (rho_object - rho_water) V g`` (4.62 N), by two hands of equal
friction coefficient ``mu`` (0.5) and grip ``F`` per hand (axial capacity ``mu F`` each: the prediction of slip onset
is ``F* = W / (2 mu)``):

* ``contact``: a plain PyBullet scene, the solver the simulator uses (Dantzig MLCP, the simulator's CFM and ERP) or
  the sequential-impulse solver with many iterations. The object is a free capsule (its buoyancy an external force
  every step); each hand is a fixed base with two box pads on prismatic joints, squeezed against the capsule from
  either side by a joint force ``F / 2`` (so the hand's two pads carry ``2 mu F / 2 = mu F``), Bullet's Coulomb
  friction ``mu`` between pads and capsule (Bullet multiplies the two bodies' coefficients: ``mu`` on the pads, 1 on
  the capsule);
* ``motor``: the chosen model, :class:`~uvdms_gym.physics.friction_grasp.FrictionGrasp` through
  :class:`~uvdms_gym.physics.sim.UVDMSSim` (the vehicle rolled 90 deg, its base welded to the world and its arm
  joints locked by stiff velocity motors).

Measured for each: the creep over 10 s at rest with the capacity twice the load (``2 mu F = 2 W``) after 1 s of
settling, the jitter (RMS of the object's position relative to the hands about its mean over the last 5 s), the
grip at which slip starts (the object's axial displacement exceeds 0.1 mm, and 1 mm: above the contact model's
jitter) as the grip is lowered from ``3 F*`` to ``0.5 F*`` over 8 s (the contact model drops the object at ``1.5 F*``
already), its error against ``F*`` (a displacement
threshold detects late: with the capacity falling at ``2 mu dF/dt``, 1 mm of slip takes about 0.3 s, a bias of
some -8 % for the motor model), and the wall time per physics step (the motor model's includes the
whole vehicle-manipulator plant and its hydrodynamics; the rigid grasp's time on the same plant is given for
reference). Prints a markdown table and writes it as JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as pb
from pybullet_utils.bullet_client import BulletClient

from uvdms_gym.envs.transport import vehicle_pose_for_object
from uvdms_gym.physics.body import CONSTRAINT_CFM, CONSTRAINT_ERP
from uvdms_gym.physics.grip import FrictionGraspConfig
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.params import GRAVITY, UVDMSParams
from uvdms_gym.physics.sim import UVDMSSim

P = UVDMSParams()
MU = 0.5
W_NET = (P.obj.density - P.water_density) * P.obj.volume * GRAVITY
F_STAR = W_NET / (2 * MU)
"""Predicted grip per hand at which slip starts, N."""
ONSET_SLIPS = (1.0e-4, 1.0e-3)
"""Axial displacements of the object that count as slip, m (0.1 mm; 1 mm, above the contact model's jitter)."""
HAND_Z = 0.15
"""Hands at +-0.15 m from the object's centre along its axis."""
PAD_HALF = (0.01, 0.02, 0.03)
"""Half extents of a pad box (x: the squeeze direction), m."""

Reader = Callable[[], np.ndarray]
"""The object's position relative to the hands (3), m."""


# ---------------------------------------------------------------------------------------------- contact scene
class ContactScene:
    """The object squeezed by four pads (two per hand) in a plain PyBullet scene.

    Args:
        dt: the physics step, s.
        solver: ``"dantzig"`` (the simulator's) or ``"si"`` (sequential impulse, 200 iterations).
        grip: each hand's grip force, N (each pad pushes ``grip / 2``).
    """

    def __init__(self, dt: float, solver: str, grip: float) -> None:
        self.c = c = BulletClient(connection_mode=pb.DIRECT)
        c.setGravity(0.0, 0.0, -GRAVITY)
        if solver == "dantzig":
            c.setPhysicsEngineParameter(
                fixedTimeStep=dt,
                constraintSolverType=pb.CONSTRAINT_SOLVER_LCP_DANTZIG,
                globalCFM=CONSTRAINT_CFM,
                erp=CONSTRAINT_ERP,
            )
        else:
            c.setPhysicsEngineParameter(fixedTimeStep=dt, numSolverIterations=200)
        o = P.obj
        shape = c.createCollisionShape(pb.GEOM_CAPSULE, radius=o.radius, height=o.length - 2 * o.radius)
        self.obj = c.createMultiBody(o.mass, shape, -1, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0])
        # Bullet combines two bodies' friction coefficients as their product: the capsule's 1 leaves the pads' mu
        c.changeDynamics(self.obj, -1, lateralFriction=1.0, linearDamping=0.0, angularDamping=0.0)
        self.pads: list[int] = []
        box = c.createCollisionShape(pb.GEOM_BOX, halfExtents=list(PAD_HALF))
        for z in (-HAND_Z, HAND_Z):
            for side in (-1.0, 1.0):  # a hand base at the object's axis, its pad sliding along x towards it
                gap = side * (o.radius + PAD_HALF[0])
                body = c.createMultiBody(
                    0.0, -1, -1, [0.0, 0.0, 1.0 + z], [0, 0, 0, 1],
                    linkMasses=[0.05], linkCollisionShapeIndices=[box], linkVisualShapeIndices=[-1],
                    linkPositions=[[gap, 0.0, 0.0]], linkOrientations=[[0, 0, 0, 1]],
                    linkInertialFramePositions=[[0, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                    linkParentIndices=[0], linkJointTypes=[pb.JOINT_PRISMATIC], linkJointAxis=[[1.0, 0.0, 0.0]],
                )  # fmt: skip
                c.changeDynamics(body, 0, lateralFriction=MU, jointDamping=0.0)
                c.setJointMotorControl2(body, 0, pb.VELOCITY_CONTROL, force=0.0)  # free the joint's default motor
                self.pads.append(body)
        self.sides = [-1.0, 1.0, -1.0, 1.0]
        self.grip = grip
        self.buoyancy = P.water_density * o.volume * GRAVITY

    def set_grip(self, grip: float) -> None:
        """Each hand's grip force, N."""
        self.grip = grip

    def step(self) -> None:
        """One physics step: the pads' squeeze and the object's buoyancy, then ``stepSimulation``."""
        c = self.c
        for body, side in zip(self.pads, self.sides, strict=True):  # a pad at +x pushes towards -x
            c.setJointMotorControl2(body, 0, pb.TORQUE_CONTROL, force=-side * 0.5 * self.grip)
        pos, _ = c.getBasePositionAndOrientation(self.obj)
        c.applyExternalForce(self.obj, -1, [0.0, 0.0, self.buoyancy], pos, pb.WORLD_FRAME)
        c.stepSimulation()

    def relative(self) -> np.ndarray:
        """The object's centre relative to the hands' midpoint (fixed at the origin + 1 m up), m."""
        return np.array(self.c.getBasePositionAndOrientation(self.obj)[0]) - np.array([0.0, 0.0, 1.0])

    def close(self) -> None:
        """Disconnect."""
        self.c.disconnect()


# ---------------------------------------------------------------------------------------------- motor model


def held_plant(
    roll: float, grasp: FrictionGraspConfig | None, *, physics_dt: float = 0.01, current: list[float] | None = None
) -> UVDMSSim:
    """The simulator holding the object at ``roll`` (``pi / 2``: its axis vertical), held still.

    The vehicle's base is welded to the world and the arm joints are locked by velocity motors of 1e4 N m (the
    simulator's torque control applies zero torques and leaves them in place), so the grasp carries the object's
    loads alone.

    Args:
        roll: the vehicle's (and object's) roll, rad.
        grasp: the friction grasp's knobs (``None``: the rigid grasp).
        physics_dt: the physics step, s.
        current: a constant current (NED, m/s), or ``None``.
    """
    sim = UVDMSSim(P, physics_dt=physics_dt, grasp=grasp)
    eta = vehicle_pose_for_object(KinematicModel(P), np.array([2.0, 1.0, 30.0, roll, 0.0, 0.0]))
    sim.reset(eta, with_object=True)
    c, body = sim.client, sim.body_id
    pos, orn = c.getBasePositionAndOrientation(body)
    c.createConstraint(body, -1, -1, -1, pb.JOINT_FIXED, [0, 0, 0], [0, 0, 0], pos, [0, 0, 0, 1], orn)
    joints = list(sim.joint_indices)
    c.setJointMotorControlArray(body, joints, pb.VELOCITY_CONTROL, targetVelocities=[0.0] * 12, forces=[1e4] * 12)
    if current is not None:
        sim.set_current(current)
    return sim


class MotorScene:
    """:class:`FrictionGrasp` (or the rigid grasp, ``grip=None``) on the held plant, the object's axis vertical.

    Args:
        dt: the physics step, s.
        grip: each hand's grip force, N (``None``: the rigid grasp, for the step's cost only).
    """

    def __init__(self, dt: float, grip: float | None) -> None:
        cfg = None if grip is None else FrictionGraspConfig(mu=(MU, MU), grip_initial=grip)
        self.sim = held_plant(math.pi / 2, cfg, physics_dt=dt)
        self._zero = np.zeros(18)

    def set_grip(self, grip: float) -> None:
        """Each hand's grip force, N."""
        self.sim.grasp.set_grip(grip, grip)

    def step(self) -> None:
        """One physics step of the plant."""
        self.sim.step(self._zero)

    def relative(self) -> np.ndarray:
        """The object's centre relative to the left grasp frame (NED), m."""
        return self.sim.object_position() - self.sim.link_pose("left_grasp")[0]

    def close(self) -> None:
        """Close the simulator."""
        self.sim.close()


# ---------------------------------------------------------------------------------------------- measurements
def at_rest(scene: ContactScene | MotorScene, dt: float) -> dict[str, float]:
    """Creep over 10 s after 1 s of settling, jitter over the last 5 s, wall time per step (capacity 2x load)."""
    settle, hold = round(1.0 / dt), round(10.0 / dt)
    for _ in range(settle):
        scene.step()
    start = scene.relative()
    trace = np.empty((hold, 3))
    t0 = time.perf_counter()
    for k in range(hold):
        scene.step()
        trace[k] = scene.relative()
    cost = (time.perf_counter() - t0) / hold
    last = trace[-round(5.0 / dt) :]
    jitter = float(np.sqrt(np.mean(np.sum((last - last.mean(axis=0)) ** 2, axis=1))))
    return {
        "creep_m": float(np.linalg.norm(trace[-1] - start)),
        "axial_creep_m": float(abs(trace[-1, 2] - start[2])),
        "jitter_m": jitter,
        "step_ms": 1e3 * cost,
    }


def onset(scene: ContactScene | MotorScene, dt: float) -> tuple[float, float]:
    """Grips (N) at which the object has slipped ``ONSET_SLIPS`` as the grip is lowered from 3 F* to 0.5 F* in 8 s."""
    for _ in range(round(1.0 / dt)):
        scene.step()
    start = scene.relative()[2]
    found = [math.nan, math.nan]
    for grip in np.linspace(3.0 * F_STAR, 0.5 * F_STAR, round(8.0 / dt)):
        scene.set_grip(float(grip))
        scene.step()
        moved = abs(scene.relative()[2] - start)
        for k, threshold in enumerate(ONSET_SLIPS):
            if math.isnan(found[k]) and moved > threshold:
                found[k] = float(grip)
        if not math.isnan(found[-1]):
            break
    return found[0], found[1]


def measure(name: str, build: Callable[[float], ContactScene | MotorScene], dt: float) -> dict[str, Any]:
    """The row of one model at one step: at rest with capacity 2x load, and the onset ramp."""
    scene = build(2.0 * F_STAR)
    row: dict[str, Any] = {"model": name, "dt": dt, **at_rest(scene, dt)}
    scene.close()
    scene = build(3.0 * F_STAR)
    fine, coarse = onset(scene, dt)
    scene.close()
    row.update(
        predicted_grip_N=F_STAR,
        onset_grip_N=fine,
        onset_error=fine / F_STAR - 1.0,
        onset_grip_1mm_N=coarse,
        onset_error_1mm=coarse / F_STAR - 1.0,
    )
    row["held"] = bool(row["axial_creep_m"] < 0.05)
    return row


def rigid_cost(dt: float) -> float:
    """Wall time per physics step (ms) of the same held plant with the rigid grasp."""
    scene = MotorScene(dt, None)
    n = round(5.0 / dt)
    t0 = time.perf_counter()
    for _ in range(n):
        scene.step()
    scene.close()
    return 1e3 * (time.perf_counter() - t0) / n


def table(rows: list[dict[str, Any]]) -> str:
    """The rows as a markdown table."""
    head = (
        "| model | dt (s) | held | creep in 10 s (mm) | jitter RMS (mm) | onset at 0.1 mm (N) | error vs F* "
        "| onset at 1 mm (N) | error vs F* | ms/step |"
    )
    lines = [head, "|" + "---|" * 10]
    for r in rows:
        lines.append(
            f"| {r['model']} | {r['dt']} | {'yes' if r['held'] else 'no'} | {1e3 * r['creep_m']:.3g} | "
            f"{1e3 * r['jitter_m']:.3g} | {r['onset_grip_N']:.3f} | {100 * r['onset_error']:+.1f} % | "
            f"{r['onset_grip_1mm_N']:.3f} | {100 * r['onset_error_1mm']:+.1f} % | "
            f"{r['step_ms']:.3f} |"
        )
    return "\n".join(lines)


def main() -> None:
    """Run the comparison; print the table, write the JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("/tmp/grasp_model_comparison.json"))
    args = ap.parse_args()
    runs = [
        ("contact (Dantzig)", lambda g, dt: ContactScene(dt, "dantzig", g), 0.01),
        ("contact (Dantzig)", lambda g, dt: ContactScene(dt, "dantzig", g), 0.002),
        ("contact (SI, 200 it.)", lambda g, dt: ContactScene(dt, "si", g), 0.01),
        ("contact (SI, 200 it.)", lambda g, dt: ContactScene(dt, "si", g), 0.002),
        ("motor (FrictionGrasp)", lambda g, dt: MotorScene(dt, g), 0.01),
        ("motor (FrictionGrasp)", lambda g, dt: MotorScene(dt, g), 0.002),
    ]
    rows = [measure(name, lambda g, b=build, d=dt: b(g, d), dt) for name, build, dt in runs]
    rigid = {dt: rigid_cost(dt) for dt in (0.01, 0.002)}
    md = table(rows)
    print(md)
    print(f"\nrigid grasp on the same plant: {rigid[0.01]:.3f} ms/step (dt 0.01), {rigid[0.002]:.3f} (dt 0.002)")
    print(f"load W = {W_NET:.3f} N, mu = {MU}, predicted onset F* = W / (2 mu) = {F_STAR:.3f} N per hand")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    payload = {"rows": rows, "rigid_step_ms": rigid, "load_N": W_NET, "mu": MU, "markdown": md}
    args.out.write_text(json.dumps(payload, indent=2) + "\n")


if __name__ == "__main__":
    main()
