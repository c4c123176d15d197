"""Tests of uvdms_gym.physics.kinematics against finite differences, closed forms and PyBullet."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pybullet as p
import pytest
from pybullet_utils import bullet_client

from uvdms_gym.physics import frames
from uvdms_gym.physics.kinematics import KinematicModel, euler_to_quat_xyzw, pybullet_velocity_map
from uvdms_gym.physics.model import build_urdf, link_segment, write_urdf
from uvdms_gym.physics.params import GRAVITY, JOINT_NAMES, UVDMSParams

H = 1e-6
N_CONFIGS = 50


@pytest.fixture(scope="module")
def km() -> KinematicModel:
    return KinematicModel()


def random_state(rng: np.random.Generator, params: UVDMSParams) -> tuple[np.ndarray, np.ndarray]:
    eta = np.concatenate([rng.uniform([-5, -5, 0], [5, 5, 35]), rng.uniform(-np.pi, np.pi, 3) * np.array([1, 0.45, 1])])
    q = rng.uniform(params.q_min, params.q_max)
    return eta, q


def fd_twist(km: KinematicModel, config: np.ndarray, pose_fn) -> np.ndarray:
    """Central finite differences (6, 18) of [position; orientation] returned by pose_fn() along zeta."""
    out = np.empty((6, 18))
    for k in range(18):
        dz = np.zeros(18)
        dz[k] = H
        km.set_configuration(pin.integrate(km.model, config, dz))
        p_plus, r_plus = pose_fn()
        km.set_configuration(pin.integrate(km.model, config, -dz))
        p_minus, r_minus = pose_fn()
        out[:3, k] = (p_plus - p_minus) / (2 * H)
        out[3:, k] = pin.log3(r_plus @ r_minus.T) / (2 * H)
    km.set_configuration(config)
    return out


def fd_points(km: KinematicModel, config: np.ndarray, frames_: list[str], points: np.ndarray) -> np.ndarray:
    """Central finite differences (n, 3, 18) of material points rigidly attached to the given frames."""
    km.set_configuration(config)
    local = []
    for f, pt in zip(frames_, points):
        pf, rf = km.frame_placement(f)
        local.append(rf.T @ (pt - pf))
    out = np.empty((len(points), 3, 18))
    for k in range(18):
        dz = np.zeros(18)
        dz[k] = H
        world = []
        for sign in (1.0, -1.0):
            km.set_configuration(pin.integrate(km.model, config, sign * dz))
            world.append(np.array([pf + rf @ loc for (pf, rf), loc in zip(map(km.frame_placement, frames_), local)]))
        out[:, :, k] = (world[0] - world[1]) / (2 * H)
    km.set_configuration(config)
    return out


def assert_jac_close(j: np.ndarray, j_fd: np.ndarray) -> None:
    err = np.abs(j - j_fd).max()
    assert err <= 1e-6 * max(1.0, np.abs(j).max()), err


def test_jacobians_match_finite_differences(km: KinematicModel) -> None:
    rng = np.random.default_rng(1234)
    params = km.params
    for _ in range(N_CONFIGS):
        eta, q = random_state(rng, params)
        km.set_state(eta, q)
        config = km.config.copy()

        j = km.ee_jacobian()
        assert j.shape == (12, 18)
        for s, name in enumerate(("left_ee", "right_ee")):
            j_fd = fd_twist(km, config, lambda name=name: km.frame_placement(name))
            assert_jac_close(j[6 * s : 6 * s + 6], j_fd)
        # ee_positions / ee_rotations agree with the frames the Jacobian differentiates
        np.testing.assert_allclose(km.ee_positions()[1], km.frame_placement("right_ee")[0], atol=0)
        np.testing.assert_allclose(km.ee_rotations()[0], km.frame_placement("left_ee")[1], atol=0)

        for side in ("left", "right"):
            j_o = km.object_jacobian(side)
            assert j_o.shape == (6, 18)
            assert_jac_close(j_o, fd_twist(km, config, lambda side=side: km.object_pose(side)))

        # random material points near random links, plus a point fixed to the vehicle
        names = []
        pts = []
        for _ in range(4):
            side = ("left", "right")[rng.integers(2)]
            i = int(rng.integers(7))
            name = f"{side}_link{i}"
            a, b = link_segment(params, i)
            pf, rf = km.frame_placement(name)
            names.append(name)
            pts.append(pf + rf @ (a + rng.uniform() * (b - a) + rng.normal(scale=0.03, size=3)))
        pv, rv = km.frame_placement("vehicle")
        names.append("vehicle")
        pts.append(pv + rv @ rng.uniform(-0.5, 0.5, 3))
        pts = np.array(pts)
        j_fd = fd_points(km, config, names, pts)
        j_batch = km.point_jacobians(names, pts)
        for n in range(len(names)):
            j_p = km.point_jacobian(names[n], pts[n])
            assert j_p.shape == (3, 18)
            assert_jac_close(j_p, j_fd[n])
            np.testing.assert_allclose(j_batch[n], j_p, atol=1e-12)


def test_base_columns_closed_form(km: KinematicModel) -> None:
    rng = np.random.default_rng(7)
    for _ in range(10):
        eta, q = random_state(rng, km.params)
        km.set_state(eta, q)
        r_nb = frames.euler_to_rot(eta[3:])
        j_lin = km.point_jacobian("vehicle", eta[:3])
        np.testing.assert_allclose(j_lin[:, :3], r_nb, atol=1e-12)
        np.testing.assert_allclose(j_lin[:, 3:], 0.0, atol=1e-12)
        j_ang = km.frame_jacobian("vehicle")[3:]
        np.testing.assert_allclose(j_ang[:, 3:6], r_nb, atol=1e-12)
        np.testing.assert_allclose(j_ang[:, :3], 0.0, atol=1e-12)
        np.testing.assert_allclose(j_ang[:, 6:], 0.0, atol=1e-12)
        # a point of the vehicle: v = R (v_O + w x r), r its body-frame offset
        r_body = rng.uniform(-0.5, 0.5, 3)
        pt = eta[:3] + r_nb @ r_body
        j_pt = km.point_jacobian("plate_left", pt)
        np.testing.assert_allclose(j_pt[:, 3:6], -r_nb @ pin.skew(r_body), atol=1e-12)
        # arm columns: left EE ignores right joints and vice versa
        j = km.ee_jacobian()
        assert np.all(j[:6, 12:] == 0) and np.all(j[6:, 6:12] == 0)
        assert np.abs(j[:6, 6:12]).max() > 0.01 and np.abs(j[6:, 12:]).max() > 0.01
        # relative velocity of two points along their separation is independent of the base motion
        pa, pb = km.link_segments()[1, 3, 1], km.link_segments()[0, 5, 0]
        n = (pb - pa) / np.linalg.norm(pb - pa)
        j_rel = n @ (km.point_jacobian("right_link3", pa) - km.point_jacobian("left_link5", pb))
        np.testing.assert_allclose(j_rel[:6], 0.0, atol=1e-12)


def test_configuration_and_geometry(km: KinematicModel) -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        rpy = rng.uniform(-np.pi, np.pi, 3) * np.array([1, 0.49, 1])
        q_ref = frames.rot_to_quat_xyzw(frames.euler_to_rot(rpy))
        np.testing.assert_allclose(euler_to_quat_xyzw(rpy), q_ref, atol=1e-12)
        eta, q = random_state(rng, km.params)
        km.set_state(eta, q)
        r_nb = frames.euler_to_rot(eta[3:])
        pv, rv = km.frame_placement("vehicle")
        np.testing.assert_allclose(pv, eta[:3], atol=1e-12)
        np.testing.assert_allclose(rv, r_nb, atol=1e-12)
        segs = km.link_segments()
        assert segs.shape == (2, 7, 2, 3)
        for s in range(2):
            base = np.array(km.params.arm_base_left if s == 0 else km.params.arm_base_right)
            np.testing.assert_allclose(segs[s, 0, 0], eta[:3] + r_nb @ base, atol=1e-12)  # link 0 starts at mount
            lengths = np.linalg.norm(segs[s, :, 1] - segs[s, :, 0], axis=1)
            np.testing.assert_allclose(lengths, km.params.arm.link_length, atol=1e-12)
            # consecutive capsule axes are chained (links 1.. start at the previous link's end, a_i = 0)
            np.testing.assert_allclose(segs[s, 1:, 0], segs[s, :-1, 1], atol=1e-12)
            np.testing.assert_allclose(km.ee_positions()[s], segs[s, 6, 1], atol=1e-12)
        for (c, u, v, he), pl in zip(km.plates(), km.params.plates):
            np.testing.assert_allclose(c, eta[:3] + r_nb @ np.array(pl.center), atol=1e-12)
            np.testing.assert_allclose(u, r_nb @ np.array(pl.u), atol=1e-12)
            np.testing.assert_allclose(v, r_nb @ np.array(pl.v), atol=1e-12)
            assert he == tuple(pl.half_extents)
            # agrees with PyBullet-facing plate link frame of the URDF
            p_pl, r_pl = km.frame_placement(f"plate_{pl.name}")
            np.testing.assert_allclose(p_pl, c, atol=1e-12)
            np.testing.assert_allclose(r_pl[:, :2], np.column_stack([u, v]), atol=1e-12)
        # both arms hold the object consistently with equal joint angles if the roll joints are zero
        # (the arms are translated copies: then the grasp offsets agree; in general they do not)
        q_same = np.tile(q[:6] * np.array([0, 1, 0, 1, 0, 1]), 2)
        km.set_state(eta, q_same)
        (pl_, rl_), (pr_, rr_) = km.object_pose("left"), km.object_pose("right")
        np.testing.assert_allclose(pl_, pr_, atol=1e-12)
        np.testing.assert_allclose(rl_, rr_, atol=1e-12)


@pytest.fixture(scope="module")
def bullet():
    client = bullet_client.BulletClient(p.DIRECT)
    body = client.loadURDF(str(write_urdf(build_urdf(UVDMSParams()))), flags=p.URDF_USE_INERTIA_FROM_FILE)
    yield client, body
    client.disconnect()


def test_mass_matrix_matches_pybullet(km: KinematicModel, bullet) -> None:
    client, body = bullet
    revolute = [
        (j, client.getJointInfo(body, j)[1].decode())
        for j in range(client.getNumJoints(body))
        if client.getJointInfo(body, j)[2] == p.JOINT_REVOLUTE
    ]
    order = np.array([JOINT_NAMES.index(name) for _, name in revolute])
    t = pybullet_velocity_map(km.params, order)
    # the map must be what it claims: [omega_B; v_C; qdot_pb] = T zeta for a rigid motion of the hull
    rng = np.random.default_rng(11)
    zeta = rng.normal(size=18)
    r_g = np.array(km.params.vehicle.r_g)
    np.testing.assert_allclose((t @ zeta)[3:6], zeta[:3] + np.cross(zeta[3:6], r_g), atol=1e-14)

    for trial in range(6):
        eta, q = random_state(rng, km.params)
        q_pb = q[order]
        # PyBullet's base pose and joint state should not matter (body-axis coordinates, explicit q)
        client.resetBasePositionAndOrientation(
            body,
            frames.ned_to_world(eta[:3]).tolist(),
            frames.rot_to_quat_xyzw(frames.body_rot_ned_to_world(frames.euler_to_rot(eta[3:]))).tolist(),
        )
        for k, (j, _) in enumerate(revolute):
            client.resetJointState(body, j, q_pb[k])
        m_pb = np.array(client.calculateMassMatrix(body, q_pb.tolist()))
        km.set_state(eta, q)
        m = km.mass_matrix()
        assert m.shape == (18, 18)
        np.testing.assert_array_equal(m, m.T)
        assert np.linalg.eigvalsh(m).min() > 0
        np.testing.assert_allclose(m, t.T @ m_pb @ t, rtol=0, atol=1e-9)
        if trial == 0:  # the naive reading (no reordering, no COM shift) is wrong: the test can fail
            assert np.abs(m - m_pb).max() > 1.0

    # body-frame mass matrix does not depend on the vehicle pose
    km.set_state(np.array([1.0, 2.0, 3.0, 0.4, -0.3, 2.0]), q)
    m_other = km.mass_matrix()
    km.set_state(np.zeros(6), q)
    np.testing.assert_allclose(km.mass_matrix(), m_other, atol=1e-12)


def test_gravity_and_coriolis(km: KinematicModel) -> None:
    params = km.params
    rng = np.random.default_rng(5)
    for _ in range(5):
        eta, q = random_state(rng, params)
        zeta = rng.normal(scale=0.5, size=18)
        km.set_state(eta, q, zeta)
        # independent gravity: -sum J_com^T m g e_z over the real bodies (no weight for the virtual added mass)
        bodies = [("vehicle", np.array(params.vehicle.r_g), params.vehicle.mass)]
        for side in ("left", "right"):
            for i in range(7):
                a, b = link_segment(params, i)
                bodies.append((f"{side}_link{i}", 0.5 * (a + b), params.arm.link_mass[i]))
            bodies += [(f"{side}_ee", np.zeros(3), 1e-4), (f"{side}_grasp", np.zeros(3), 1e-4)]
        bodies += [(f"plate_{pl.name}", np.zeros(3), 1e-4) for pl in params.plates]
        g_ref = np.zeros(18)
        for name, com, mass in bodies:
            pf, rf = km.frame_placement(name)
            g_ref -= km.point_jacobian(name, pf + rf @ com).T @ np.array([0.0, 0.0, mass * GRAVITY])
        np.testing.assert_allclose(km.gravity(), g_ref, rtol=0, atol=1e-9)
        # zeta^T C zeta = zeta^T Mdot zeta / 2 (skew-symmetry of Mdot - 2C), Mdot by central differences
        c_zeta = km.nonlinear_effects() - km.gravity()
        config = km.config.copy()
        h = 1e-6
        km.set_configuration(pin.integrate(km.model, config, zeta * h))
        m_plus = km.mass_matrix()
        km.set_configuration(pin.integrate(km.model, config, -zeta * h))
        m_minus = km.mass_matrix()
        mdot = (m_plus - m_minus) / (2 * h)
        assert abs(zeta @ c_zeta - 0.5 * zeta @ mdot @ zeta) <= 1e-6 * max(1.0, np.abs(c_zeta).max())
        # quadratic in zeta
        km.set_configuration(config, 2.0 * zeta)
        np.testing.assert_allclose(km.nonlinear_effects() - km.gravity(), 4.0 * c_zeta, atol=1e-9)
        km.set_configuration(config, np.zeros(18))
        np.testing.assert_allclose(km.nonlinear_effects(), km.gravity(), atol=1e-12)
    km.set_state(eta, q)
    with pytest.raises(RuntimeError, match="zeta"):
        km.nonlinear_effects()


def test_set_state_validation(km: KinematicModel) -> None:
    eta, q, zeta = np.zeros(6), np.zeros(12), np.zeros(18)
    km.set_state(eta, q, zeta)
    bad_eta = eta.copy()
    bad_eta[2] = np.nan
    with pytest.raises(ValueError, match="eta"):
        km.set_state(bad_eta, q)
    with pytest.raises(ValueError, match="eta"):
        km.set_state(np.zeros(5), q)
    with pytest.raises(ValueError, match="q"):
        km.set_state(eta, np.zeros(13))
    bad_q = q.copy()
    bad_q[7] = np.inf
    with pytest.raises(ValueError, match="q"):
        km.set_state(eta, bad_q)
    with pytest.raises(ValueError, match="zeta"):
        km.set_state(eta, q, np.zeros(17))
    bad_zeta = zeta.copy()
    bad_zeta[0] = np.nan
    with pytest.raises(ValueError, match="zeta"):
        km.set_state(eta, q, bad_zeta)
    with pytest.raises(ValueError, match="config"):
        km.set_configuration(np.zeros(19))  # zero quaternion
    with pytest.raises(ValueError, match="frame"):
        km.frame_jacobian("no_such_frame")
    with pytest.raises(ValueError, match="side"):
        km.object_pose("middle")
