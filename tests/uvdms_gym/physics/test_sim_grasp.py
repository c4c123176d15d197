"""The gripped object of the PyBullet plant: the closed chain holds it, forces balance, reset removes it."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from tests.support.sim import mass_matrix, pin_config, random_state
from uvdms_gym.physics import frames, model
from uvdms_gym.physics.hydro import HydroScale
from uvdms_gym.physics.params import GRAVITY, UVDMSParams
from uvdms_gym.physics.sim import UVDMSSim

P = UVDMSParams()


# ---------------------------------------------------------------------------------------------- object / grasp
def _grasp_errors(s: UVDMSSim) -> tuple[float, float]:
    p_o, r_o = s.object_pose()[0], s.object_rotation()
    worst_p, worst_a = 0.0, 0.0
    for side in ("left", "right"):
        p, r = s.link_pose(f"{side}_grasp")
        worst_p = max(worst_p, float(np.linalg.norm(p - p_o)))
        worst_a = max(worst_a, float(np.linalg.norm(frames.rot_error(r, r_o))))
    return worst_p, worst_a


def test_closed_chain_holds_the_object(sim):
    # 10 s of disturbed motion: random vehicle wrenches and random joint torques (random accelerations through a
    # computed-torque PD about q = 0); the object must stay on both grasp frames.
    pm = model.pinocchio_model(P)
    pd = pm.createData()
    rng = np.random.default_rng(1)
    sim.reset(np.r_[2, 1, 30, 0, 0, 0], with_object=True)
    worst_p, worst_a, max_qdot = 0.0, 0.0, 0.0
    for _ in range(100):
        a_noise = rng.uniform(-3, 3, 18)
        wrench = rng.uniform(-1, 1, 6) * P.tau_max[:6] * 0.3 + np.r_[0, 0, -170.0, 0, 0, 0]
        for _ in range(10):
            st = sim.state()
            qp = pin_config(st.eta, st.q)
            mm = mass_matrix(pm, pd, qp)
            h = pin.nonLinearEffects(pm, pd, qp, st.zeta)
            tau_q = mm[6:, 6:] @ (a_noise[6:] - 25.0 * st.q - 10.0 * st.qdot) + h[6:] + P.arm.joint_friction * st.qdot
            sim.step(np.r_[wrench, tau_q])
            ep, ea = _grasp_errors(sim)
            worst_p, worst_a = max(worst_p, ep), max(worst_a, ea)
            max_qdot = max(max_qdot, np.abs(st.qdot).max())
    assert max_qdot > 1.0  # the arms really moved
    assert worst_p < 1e-3, f"{worst_p * 1e3:.3f} mm"
    assert worst_a < math.radians(0.5), f"{math.degrees(worst_a):.3f} deg"


def test_object_is_created_on_the_grasp_frames_and_moves_with_them(sim):
    rng = np.random.default_rng(2)
    eta, nu, _, _ = random_state(rng)
    # pitch-only arm motions keep the two grasp frames coincident (the grasp is defined at q = 0)
    q_arm = rng.uniform(-0.5, 0.5, 6) * np.array([0, 1, 0, 1, 0, 1])
    qd_arm = rng.normal(size=6) * 0.3 * np.array([0, 1, 0, 1, 0, 1])
    sim.reset(eta, nu, np.r_[q_arm, q_arm], np.r_[qd_arm, qd_arm], with_object=True)
    assert sim.object_id is not None
    ep, ea = _grasp_errors(sim)
    assert ep < 1e-9 and ea < 1e-7
    p_r, r_r = sim.link_pose("right_grasp")
    pos, rpy = sim.object_pose()
    np.testing.assert_allclose(pos, p_r, atol=1e-12)
    np.testing.assert_allclose(frames.euler_to_rot(rpy), r_r, atol=1e-9)
    np.testing.assert_allclose(sim.object_rotation(), r_r, atol=1e-9)
    ls = sim.client.getLinkState(sim.body_id, sim.link_index["right_grasp"], computeLinkVelocity=1)
    np.testing.assert_allclose(sim.object_velocity(), np.r_[frames.world_to_ned(ls[6]), frames.world_to_ned(ls[7])])


def test_grasp_forces_balance_the_object_momentum(sim):
    # Sum of both end-effector wrenches on the object = (object + added mass) acceleration minus the external
    # loads (gravity on the body mass, buoyancy and weight cancellation of the added mass), from rest.
    sim.reset(np.r_[2, 1, 30, 0.2, 0.1, 0.5], with_object=True)
    c, obj = sim.client, sim.object_id
    mass, _, inertia = c.getDynamicsInfo(obj, -1)[:3]
    assert mass == pytest.approx(P.obj.mass + sim.hydro.obj_added_mass)
    tau = np.zeros(18)
    tau[[0, 8, 14]] = [50.0, 3.0, -2.0]
    v0 = sim.object_velocity()
    sim.step(tau)
    acc = (sim.object_velocity() - v0) / sim.physics_dt
    r = sim.object_rotation()
    f_e = sim.grasp_forces()
    assert f_e.shape == (2, 6)
    external = np.array([0.0, 0.0, P.obj.mass * GRAVITY - sim.hydro.obj_buoyancy])  # NED, down positive
    np.testing.assert_allclose(f_e[:, :3].sum(0), mass * acc[:3] - external, rtol=1e-3, atol=1e-3)
    np.testing.assert_allclose(f_e[:, 3:].sum(0), r @ np.diag(inertia) @ r.T @ acc[3:], rtol=0.05, atol=1e-3)
    assert np.abs(f_e[:, :3]).max() > 1.0  # both arms carry real load


def test_object_requires_coincident_grasps_and_is_removed_on_reset(sim):
    c = sim.client
    with pytest.raises(ValueError, match="grasp frames differ"):
        sim.reset(np.zeros(6), q=np.r_[np.zeros(6), 0.3, np.zeros(5)], with_object=True)
    sim.reset(np.zeros(6), with_object=True)
    assert c.getNumBodies() == 2 and c.getNumConstraints() == 2
    sim.reset(np.zeros(6))
    assert sim.object_id is None
    assert c.getNumBodies() == 1 and c.getNumConstraints() == 0
    np.testing.assert_array_equal(sim.grasp_forces(), np.zeros((2, 6)))
    with pytest.raises(RuntimeError, match="no object"):
        sim.object_pose()
    with UVDMSSim(P, arms=False) as s, pytest.raises(ValueError, match="arms"):
        s.reset(np.zeros(6), with_object=True)


def test_hydro_scale_updates_the_object(sim):
    sim.reset(np.zeros(6), with_object=True)
    sim.set_hydro_scale(HydroScale(added_mass=0.5))
    mass = sim.client.getDynamicsInfo(sim.object_id, -1)[0]
    assert mass == pytest.approx(P.obj.mass + 0.5 * P.obj.added_mass_coefficient * P.water_density * P.obj.volume)
    with pytest.raises(TypeError):
        sim.set_hydro_scale(2.0)  # type: ignore[arg-type]
