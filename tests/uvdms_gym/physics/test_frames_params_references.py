import math

import gymnasium as gym
import numpy as np
import pytest

from uvdms_gym.envs import references
from uvdms_gym.physics import frames
from uvdms_gym.physics.model import mount_rotation, rot_to_rpy
from uvdms_gym.physics.params import GRAVITY, UVDMSParams

RNG = np.random.default_rng(0)


def _rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def test_ned_world_roundtrip_is_exact():
    p = RNG.normal(size=(100, 3)) * 50
    assert np.array_equal(frames.world_to_ned(frames.ned_to_world(p)), p)
    assert np.array_equal(frames.ned_to_world(p)[:, 1:], -p[:, 1:])
    for _ in range(20):
        r = frames.euler_to_rot(RNG.uniform(-1.5, 1.5, 3))
        assert np.array_equal(frames.body_rot_world_to_ned(frames.body_rot_ned_to_world(r)), r)
        assert np.array_equal(frames.rot_world_to_ned(frames.rot_ned_to_world(r)), r)
        assert np.isclose(np.linalg.det(frames.body_rot_ned_to_world(r)), 1.0)


def test_euler_matches_independent_composition_and_inverts():
    for _ in range(200):
        rpy = np.array([RNG.uniform(-np.pi, np.pi), RNG.uniform(-1.5, 1.5), RNG.uniform(-np.pi, np.pi)])
        r = frames.euler_to_rot(rpy)
        assert np.allclose(r, _rz(rpy[2]) @ _ry(rpy[1]) @ _rx(rpy[0]), atol=1e-14)
        assert np.allclose(frames.rot_to_euler(r), rpy, atol=1e-10)
        q = frames.rot_to_quat_xyzw(r)
        assert np.allclose(frames.quat_xyzw_to_rot(q), r, atol=1e-12)


def test_euler_rate_matrix_matches_finite_difference():
    rpy = np.array([0.3, -0.4, 1.1])
    w_body = np.array([0.2, -0.1, 0.5])
    h = 1e-6
    r = frames.euler_to_rot(rpy)
    # rotate by the body rate for h seconds and read the Euler angles back
    wx = np.array([[0, -w_body[2], w_body[1]], [w_body[2], 0, -w_body[0]], [-w_body[1], w_body[0], 0]])
    from scipy.linalg import expm

    fd = (frames.rot_to_euler(r @ expm(wx * h)) - frames.rot_to_euler(r @ expm(-wx * h))) / (2 * h)
    assert np.allclose(frames.euler_rate_matrix(rpy) @ w_body, fd, atol=1e-7)


def test_rot_error_is_axis_angle():
    for _ in range(50):
        r = frames.euler_to_rot(RNG.uniform(-1, 1, 3))
        axis = RNG.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = RNG.uniform(0, 3.0)
        from scipy.spatial.transform import Rotation

        r_des = Rotation.from_rotvec(axis * angle).as_matrix() @ r
        assert np.allclose(frames.rot_error(r_des, r), axis * angle, atol=1e-8)


def test_rot_to_rpy_handles_gimbal_lock():
    for r in (mount_rotation(UVDMSParams()), _ry(np.pi / 2) @ _rx(0.3), _ry(-np.pi / 2) @ _rx(-1.2)):
        roll, pitch, yaw = rot_to_rpy(r)
        assert np.allclose(_rz(yaw) @ _ry(pitch) @ _rx(roll), r, atol=1e-12)


def test_parameter_hydrostatics_match_the_spec():
    p = UVDMSParams()
    assert math.isclose(p.vehicle.buoyancy - p.vehicle.weight, 1058 - 106 * GRAVITY)
    assert math.isclose(p.vehicle.buoyancy - p.vehicle.weight, 18.14, abs_tol=0.01)
    # docs/MODEL.md section 2: arm weight makes the whole system negatively buoyant by about 165 N
    assert -170 < p.net_vertical_force() < -160
    assert math.isclose(p.obj.mass, 1100 * math.pi * 0.05**2 * 0.6)
    assert math.isclose(p.obj.mass, 5.18, abs_tol=0.01)
    assert p.vehicle.rigid_added_mass + p.vehicle.residual_added_mass[0] == p.vehicle.added_mass[0]
    assert p.tau_max.shape == (18,) and p.zeta_max.shape == (18,)


def test_circle_reference_geometry():
    task = references.make_circle_task(1)
    t = np.linspace(0, task.period, 101)
    y = task.reference(t)
    assert y.shape == (101, 6)
    left, right = y[:, :3], y[:, 3:]
    assert np.allclose(np.linalg.norm(right - task.right_center, axis=1), task.radius)
    assert np.allclose(np.linalg.norm(left - task.left_center, axis=1), task.radius)
    assert np.allclose(left[:, 0], 2.4) and np.allclose(right[:, 0], 2.4)  # plane normal to the vehicle x
    # mirror symmetry about the plane y = (yl + yr)/2 and both move inward together
    mid = 0.5 * (task.left_center[1] + task.right_center[1])
    assert np.allclose(left[:, 1] - mid, -(right[:, 1] - mid))
    assert np.allclose(left[:, 2], right[:, 2])
    assert np.allclose(y[0], task.reference(task.period))  # periodic
    assert task.reference(0.0).shape == (6,)


def test_circle_infeasible_requests_raise():
    with pytest.raises(ValueError, match="radius"):
        references.make_circle_task(1, radius=0.0)
    with pytest.raises(ValueError, match="radius"):
        references.make_circle_task(1, radius=-0.1)
    with pytest.raises(ValueError, match="left_center"):
        references.make_circle_task(1, left_center=(1.0, float("nan"), 3.0))
    with pytest.raises(ValueError, match="within"):
        references.make_circle_task(1, left_center=(2.4, 0.1, 3.08), right_center=(2.4, 0.2, 3.08))
    bases = (np.array(UVDMSParams().arm_base_left), np.array(UVDMSParams().arm_base_right))
    with pytest.raises(ValueError, match="reach"):
        references.make_circle_task(1, right_center=(6.0, 0.25, 3.08), arm_bases_body=bases)
    with pytest.raises(ValueError, match="unknown circle case"):
        references.make_circle_task(3)
    references.make_circle_task(2, arm_bases_body=bases)  # the paper's cases are feasible


def test_random_circles_are_seeded_and_feasible():
    bases = (np.array(UVDMSParams().arm_base_left), np.array(UVDMSParams().arm_base_right))
    a = [references.make_circle_task("random", np.random.default_rng(7), arm_bases_body=bases) for _ in range(2)]
    assert np.array_equal(a[0].right_center, a[1].right_center) and a[0].radius == a[1].radius
    for seed in range(50):
        references.make_circle_task("random", np.random.default_rng(seed), arm_bases_body=bases)


def test_mixed_circles_draw_the_paper_cases_and_random_circles_in_equal_parts():
    bases = (np.array(UVDMSParams().arm_base_left), np.array(UVDMSParams().arm_base_right))
    drawn = []
    for seed in range(300):
        rng = np.random.default_rng(seed)
        task = references.make_circle_task("mix", rng, arm_bases_body=bases)
        pick = references.MIXED_CASES[int(np.random.default_rng(seed).integers(3))]  # the draw, made independently
        replay = np.random.default_rng(seed)
        replay.integers(3)
        expected = references.make_circle_task(pick, replay, arm_bases_body=bases)
        assert np.array_equal(task.right_center, expected.right_center) and task.radius == expected.radius
        drawn.append(pick)
    counts = {case: drawn.count(case) for case in (1, 2, "random")}
    assert all(70 <= n <= 130 for n in counts.values()), counts  # 100 each expected (binomial sd 8)
    with pytest.raises(ValueError, match="'mix' needs"):
        references.make_circle_task("mix", arm_bases_body=bases)
    env = gym.make("uvdms/CircleTrack-v1", case="mix")
    try:
        radii = set()
        for seed in range(12):
            env.reset(seed=seed)
            radii.add(env.unwrapped.task.radius)
        assert {0.18, 0.14} <= radii and len(radii) > 2  # both paper cases and random radii
    finally:
        env.close()


@pytest.mark.portability
def test_transport_reference_kernel_equals_scipy_spline_bit_for_bit():
    """The compiled evaluation gives the bits of scipy's CubicSpline at the clipped times, edges and NaN included."""
    rng = np.random.default_rng(5)
    for goal in ("paper", "random"):
        task = references.make_transport_task(goal, rng)
        mt = task.move_time
        t = np.concatenate([rng.uniform(-5.0, mt + 10.0, 2000), [0.0, -0.0, mt / 2, mt, np.nextafter(mt, 0), np.nan]])
        expected = task._spline(np.clip(t, 0.0, mt))
        got = task.reference(t)
        assert got.shape == (t.size, 6)
        assert np.array_equal(got, expected, equal_nan=True)
        assert np.array_equal(task.reference(3.25), task._spline(3.25))
        grid = rng.uniform(0.0, mt, (4, 3))  # other shapes go to the spline itself
        assert np.array_equal(task.reference(grid), task._spline(grid))


def test_transport_reference_passes_waypoints_and_holds():
    task = references.make_transport_task()
    start, goal = task.reference(0.0), task.reference(task.move_time)
    assert np.allclose(start, [2, 1, 30, 0, 0, 0])
    assert np.allclose(goal, [3, 0.5, 28, 0, 0, np.pi / 2])
    assert np.allclose(task.reference(task.move_time / 2), 0.5 * (start + goal))
    assert np.allclose(task.reference(task.move_time + 5.0), goal)
    h = 1e-4  # zero velocity at both ends (clamped spline)
    assert np.allclose((task.reference(h) - task.reference(0.0)) / h, 0.0, atol=1e-3)
    assert np.allclose((task.reference(task.move_time) - task.reference(task.move_time - h)) / h, 0, atol=1e-3)
    with pytest.raises(ValueError, match="goal_pose"):
        references.make_transport_task(goal_pose=(1, 2, 3))
    with pytest.raises(ValueError, match="unknown goal"):
        references.make_transport_task(goal="moon")
    r1 = references.make_transport_task("random", np.random.default_rng(3))
    r2 = references.make_transport_task("random", np.random.default_rng(3))
    assert np.array_equal(r1.goal, r2.goal)
