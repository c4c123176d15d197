"""The PyBullet plant's API: input validation, saturation, time, errors, close, contacts, state queries."""

from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest

from tests.support.sim import random_state
from uvdms_gym.physics import frames
from uvdms_gym.physics.params import UVDMSParams
from uvdms_gym.physics.sim import UVDMSSim
from uvdms_gym.physics.state import NU_LIMIT, PhysicsError, StepInfo

P = UVDMSParams()


# ---------------------------------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    ("tau", "message"),
    [
        (np.r_[np.nan, np.zeros(17)], "NaN"),
        (np.r_[np.zeros(17), np.inf], "inf"),
        (np.zeros(17), "shape"),
        (np.zeros((2, 18)), "shape"),
        (["a"] * 18, "numeric"),
    ],
)
def test_invalid_tau_raises_value_error(sim, tau, message):
    with pytest.raises(ValueError, match=message):
        sim.step(tau)


def test_saturation_is_reported_and_input_untouched(sim):
    tau = np.zeros(18)
    tau[0] = 1e4
    tau[7] = -1e3
    tau_in = tau.copy()
    info = sim.step(tau)
    assert isinstance(info, StepInfo)
    np.testing.assert_array_equal(tau, tau_in)
    assert info.any_saturated
    assert np.flatnonzero(info.saturated).tolist() == [0, 7]
    assert info.tau[0] == P.tau_max[0] and info.tau[7] == -P.tau_max[7]
    assert not sim.step(np.zeros(18)).any_saturated
    with pytest.raises(ValueError, match="n_substeps"):
        sim.step(np.zeros(18), n_substeps=0)


def test_time_and_substeps(sim):
    sim.reset(np.zeros(6))
    info = sim.step(np.zeros(18), n_substeps=5)
    assert info.n_substeps == 5
    assert info.t == pytest.approx(5 * sim.physics_dt) and sim.t == info.t
    assert sim.reset(np.zeros(6)).t == 0.0


def test_blow_up_raises_physics_error_not_nan():
    with UVDMSSim(P) as s:
        s.reset(np.zeros(6), nu=np.r_[5.0 * NU_LIMIT, 0, 0, 0, 0, 0])  # explicit damping overshoots
        with pytest.raises(PhysicsError, match="blew up"):
            s.step(np.zeros(18))
    # a huge time step makes the explicit damping diverge: an exception, never a NaN state
    with UVDMSSim(P, physics_dt=5.0) as s:
        s.reset(np.zeros(6), nu=np.r_[1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
        with pytest.raises(PhysicsError):
            for _ in range(200):
                s.step(np.zeros(18))
                st = s.state()
                assert np.isfinite(np.r_[st.eta, st.zeta]).all()
    assert issubclass(PhysicsError, RuntimeError)


def test_close_is_idempotent_and_disconnects():
    s = UVDMSSim(P)
    cid = s.client._client
    assert pb.getConnectionInfo(physicsClientId=cid)["isConnected"] == 1
    s.close()
    s.close()
    assert s.closed
    assert pb.getConnectionInfo(physicsClientId=cid)["isConnected"] == 0
    for call in (s.state, lambda: s.step(np.zeros(18)), lambda: s.reset(np.zeros(6))):
        with pytest.raises(RuntimeError, match="closed"):
            call()
    with UVDMSSim(P) as s2:
        cid2 = s2.client._client
    assert s2.closed and pb.getConnectionInfo(physicsClientId=cid2)["isConnected"] == 0


# ---------------------------------------------------------------------------------------------- helpers
def test_zeta_matches_state(sim):
    rng = np.random.default_rng(7)
    for _ in range(5):
        st = sim.reset(*random_state(rng))
        np.testing.assert_allclose(sim.zeta(), st.zeta, atol=1e-12)


def test_count_contacts(sim):
    from uvdms_gym.physics.params import CIRCLE_Q0_LEFT_DEG, CIRCLE_Q0_RIGHT_DEG

    sim.reset(np.zeros(6))
    assert sim.count_contacts() == 0
    sim.reset(np.r_[2, 0, 3, 0, 0, 0], q=np.radians(np.array(CIRCLE_Q0_LEFT_DEG + CIRCLE_Q0_RIGHT_DEG)))
    assert sim.count_contacts() == 0
    # right arm rolled towards the left one and pitched down across it / pitched through the frame
    for q in (np.r_[np.zeros(6), 1.57, 1.0, 0, 0, 0, 0], np.tile([0, 0.6, 0, 0, 0, 0], 2)):
        sim.reset(np.zeros(6), q=q)
        n = sim.count_contacts()
        assert n > 0
        # the same pairs from one whole-body query (another PyBullet code path)
        li = sim.link_index
        arm = {li[f"{s}_link{i}"]: s for s in ("left", "right") for i in range(7)}
        plates = {li[f"plate_{p.name}"] for p in P.plates}
        pairs = set()
        for cp in sim.client.getClosestPoints(sim.body_id, sim.body_id, 0.0):
            a, b = cp[3], cp[4]
            cross = a in arm and b in arm and arm[a] != arm[b]
            plate = (a in plates and b in arm and b not in (li["left_link0"], li["right_link0"])) or (
                b in plates and a in arm and a not in (li["left_link0"], li["right_link0"])
            )
            if cross or plate:
                pairs.add(frozenset((a, b)))
        assert n == len(pairs)


def test_render_rgb(sim):
    img = sim.render_rgb(64, 48)
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8
    assert img.std() > 0  # not a blank frame


def test_count_contacts_agrees_with_simulated_self_collision():
    # the same penetrating configurations, reported by closest-point queries (default) and by the contact
    # manifold of a simulator that simulates self-collision
    qs = (np.r_[np.zeros(6), 1.57, 1.0, 0, 0, 0, 0], np.tile([0, 0.6, 0, 0, 0, 0], 2), np.zeros(12))
    with UVDMSSim(P) as a, UVDMSSim(P, self_collision=True) as b:
        for q in qs:
            a.reset(np.zeros(6), q=q)
            b.reset(np.zeros(6), q=q)
            assert a.count_contacts() == b.count_contacts()
        assert a.count_contacts([("right_link1", "left_link1")]) == 0
        with pytest.raises(ValueError, match="unknown link"):
            a.count_contacts([("right_link9", "left_link1")])


def _state_from_pybullet(s: UVDMSSim) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """eta, nu, q, qdot straight from PyBullet's queries and the frames helpers (no simulator code)."""
    c, b = s.client, s.body_id
    p_com, quat = c.getBasePositionAndOrientation(b)
    v_com, w_w = c.getBaseVelocity(b)
    r_wb = frames.quat_xyzw_to_rot(np.array(quat))
    r_g_w = r_wb @ np.array(P.vehicle.r_g)
    eta = np.r_[frames.world_to_ned(np.array(p_com) - r_g_w), frames.rot_to_euler(frames.body_rot_world_to_ned(r_wb))]
    v_o = np.array(v_com) - np.cross(np.array(w_w), r_g_w)
    nu = np.r_[r_wb.T @ v_o, r_wb.T @ np.array(w_w)]
    js = c.getJointStates(b, list(s.joint_indices))
    return eta, nu, np.array([j[0] for j in js]), np.array([j[1] for j in js])


def test_state_and_object_queries_follow_every_step_and_reset(sim):
    """state() and the object queries reuse one PyBullet read per physics state: it must never be stale."""
    rng = np.random.default_rng(11)
    q0 = np.zeros(12)
    sim.reset(np.array([2.0, 0.0, 3.0, 0.1, -0.1, 0.3]), q=q0, with_object=True)
    loop_tau = rng.uniform(-20.0, 20.0, 18)
    for k in range(12):
        if k == 6:  # a reset between steps, after the previous state has been read
            sim.state()
            sim.reset(*random_state(rng, scale=0.3))
        else:
            sim.step(loop_tau, n_substeps=1 + k % 3, feedback=(lambda z: 0.5 * loop_tau) if k % 2 else None)
        st = sim.state()
        for got, expected in zip((st.eta, st.nu, st.q, st.qdot), _state_from_pybullet(sim)):
            np.testing.assert_allclose(got, expected, rtol=0.0, atol=1e-12)
        if sim.object_id is not None:
            p, quat = sim.client.getBasePositionAndOrientation(sim.object_id)
            v, w = sim.client.getBaseVelocity(sim.object_id)
            r = frames.body_rot_world_to_ned(frames.quat_xyzw_to_rot(np.array(quat)))
            pos, rpy, rot = sim.object_pose_rotation()
            np.testing.assert_allclose(pos, frames.world_to_ned(np.array(p)), atol=1e-12)
            np.testing.assert_allclose(rot, r, atol=1e-12)
            np.testing.assert_allclose(rpy, frames.rot_to_euler(r), atol=1e-12)
            np.testing.assert_allclose(sim.object_pose()[1], rpy, atol=0.0)
            np.testing.assert_allclose(
                sim.object_velocity(),
                np.r_[frames.world_to_ned(np.array(v)), frames.world_to_ned(np.array(w))],
                atol=1e-12,
            )
