"""``rgb_array`` frames draw what is tracked (:mod:`uvdms_gym.physics.render`), and drawing it changes nothing.

Marker pixels are recognised by colour: magenta paths, cyan current reference points, the green goal ghost and the
red obstacles, none of which the robot's own colours come near (yellow hull, grey plates and arms, blue object).
Where a reference should appear is computed by projecting its NED points with the camera's own matrices.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import uvdms_gym  # noqa: F401
from uvdms_gym.physics import frames
from uvdms_gym.physics.params import UVDMSParams
from uvdms_gym.physics.render import ReferenceScene, camera_matrices
from uvdms_gym.physics.sim import UVDMSSim

WIDTH, HEIGHT = 320, 240  # the environments' default frame
BOX_MARGIN = 4
"""Pixels around a reference's projected bounding box that still count as near it."""


def magenta(img: np.ndarray) -> np.ndarray:
    r, g, b = (img[:, :, k].astype(int) for k in range(3))
    return (r > 100) & (b > 100) & (g < 0.6 * np.minimum(r, b))


def cyan(img: np.ndarray) -> np.ndarray:
    r, g, b = (img[:, :, k].astype(int) for k in range(3))
    return (g > 100) & (b > 100) & (g > 0.7 * b) & (r < 0.5 * np.minimum(g, b))


def green(img: np.ndarray) -> np.ndarray:
    r, g, b = (img[:, :, k].astype(int) for k in range(3))
    return (g > 120) & (g > 1.3 * r) & (g > 1.3 * b)


def red(img: np.ndarray) -> np.ndarray:
    r, g, b = (img[:, :, k].astype(int) for k in range(3))
    return (r > 100) & (r > 2 * g) & (r > 2 * b)


def project(env, points_ned: np.ndarray) -> np.ndarray:
    """Pixel coordinates ``(N, 2)`` (column, row) of NED points in the environment's current frame."""
    u = env.unwrapped
    sim = u._sim
    keep = u._reference_scene().static_points()
    view, proj = camera_matrices(sim.client, sim.state().eta, WIDTH, HEIGHT, keep, u.camera_yaw_deg)
    m = np.array(proj).reshape(4, 4).T @ np.array(view).reshape(4, 4).T  # PyBullet's matrices are column-major
    w = frames.ned_to_world(np.asarray(points_ned, dtype=float))
    clip = np.c_[w, np.ones(len(w))] @ m.T
    ndc = clip[:, :2] / clip[:, 3:]
    return np.c_[(ndc[:, 0] + 1.0) * WIDTH / 2.0, (1.0 - ndc[:, 1]) * HEIGHT / 2.0]


def near_box(mask: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """The part of ``mask`` inside the bounding box of ``pixels``, grown by :data:`BOX_MARGIN`."""
    lo = np.floor(pixels.min(axis=0)).astype(int) - BOX_MARGIN
    hi = np.ceil(pixels.max(axis=0)).astype(int) + BOX_MARGIN
    box = np.zeros_like(mask)
    box[max(lo[1], 0) : hi[1] + 1, max(lo[0], 0) : hi[0] + 1] = True
    return mask & box


def inside_frame(pixels: np.ndarray) -> bool:
    return bool(((pixels >= 0.0) & (pixels <= [WIDTH, HEIGHT])).all())


def test_circle_frame_draws_both_circles_and_the_reference_points_where_they_project():
    env = gym.make("uvdms/CircleTrack-v0", case=1, render_mode="rgb_array")
    try:
        env.reset(seed=0)
        u = env.unwrapped
        bare = u._sim.render_rgb(WIDTH, HEIGHT, camera_yaw_deg=u.camera_yaw_deg)  # the same state, nothing drawn
        img = env.render()
        scene = u._reference_scene()
        assert img.shape == (HEIGHT, WIDTH, 3)
        assert not magenta(bare).any() and not cyan(bare).any()
        drawn, union = magenta(img), np.zeros((HEIGHT, WIDTH), bool)
        for circle in scene.paths:
            px = project(env, circle)
            assert inside_frame(px)
            assert near_box(drawn, px).sum() > 40  # each circle is drawn where it projects
            union |= near_box(np.ones_like(drawn), px)
        assert (drawn & ~union).sum() <= 0.05 * drawn.sum()  # and nowhere else
        points = project(env, scene.points)
        assert near_box(cyan(img), points).sum() >= 2 * len(points)
    finally:
        env.close()


def test_transport_frame_shows_the_path_and_the_goal_ghost():
    env = gym.make("uvdms/Transport-v0", render_mode="rgb_array")
    try:
        env.reset(seed=0)
        img = env.render()
        u = env.unwrapped
        scene = u._reference_scene()
        assert inside_frame(project(env, scene.static_points()))  # the camera keeps the path and the goal in view
        p, r_no = scene.goal
        half = 0.5 * u.params.obj.length * r_no[:, 1]  # the object's axis is its y
        goal_px = project(env, np.array([p - half, p + half]))
        ghost = green(img)
        assert near_box(ghost, goal_px).sum() > 20
        assert (ghost & ~near_box(np.ones_like(ghost), goal_px)).sum() == 0
        assert near_box(magenta(img), project(env, scene.paths[0])).sum() > 20
    finally:
        env.close()


def test_goal_ghost_at_the_objects_pose_coincides_with_the_object():
    with UVDMSSim(UVDMSParams()) as sim:
        sim.reset(np.array([1.0, -2.0, 5.0, 0.1, -0.2, 0.7]), with_object=True)
        p, _, r_no = sim.object_pose_rotation()
        sim.show_reference(ReferenceScene(goal=(p, r_no)))
        c = sim.client

        def visual_pose(body: int) -> tuple[np.ndarray, np.ndarray]:
            pos, quat = c.getBasePositionAndOrientation(body)
            vis = c.getVisualShapeData(body)[0]
            r = frames.quat_xyzw_to_rot(np.array(quat))
            return np.array(pos) + r @ np.array(vis[5]), r @ frames.quat_xyzw_to_rot(np.array(vis[6]))

        (ghost,) = sim.marker_ids
        for a, b in zip(visual_pose(ghost), visual_pose(sim.object_id)):
            np.testing.assert_allclose(a, b, atol=1e-6)


def test_obstacles_are_in_the_frame():
    env = gym.make("uvdms/TransportObstacles-v1", render_mode="rgb_array")
    try:
        env.reset(seed=0)
        assert red(env.render()).sum() > 10
    finally:
        env.close()


def test_markers_are_visual_only_and_exist_only_once_rendered():
    plain = gym.make("uvdms/Transport-v0")
    env = gym.make("uvdms/Transport-v0", render_mode="rgb_array")
    try:
        plain.reset(seed=0)
        env.reset(seed=0)
        assert plain.unwrapped._sim.marker_ids == () and env.unwrapped._sim.marker_ids == ()
        env.render()
        sim = env.unwrapped._sim
        assert len(sim.marker_ids) > 10
        for body in sim.marker_ids:
            assert sim.client.getCollisionShapeData(body, -1) == ()
            assert sim.client.getDynamicsInfo(body, -1)[0] == 0.0  # mass 0: a fixed base
        assert plain.unwrapped._sim.client.getNumBodies() == sim.client.getNumBodies() - len(sim.marker_ids)
    finally:
        plain.close()
        env.close()


# an obstacle that rises into the object from below, so that the runs below include obstacle contacts
RISING_SPHERE = [{"shape": "sphere", "radius": 0.1, "position": [2.0, 1.0, 30.6], "velocity": [0.0, 0.0, -1.0]}]


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        ("uvdms/CircleTrack-v0", {"case": "mix"}),  # a new task (new markers) per seed
        ("uvdms/Transport-v1", {"goal": "random"}),
        ("uvdms/TransportObstacles-v1", {"obstacles": RISING_SPHERE, "terminate_on_contact": False}),
    ],
)
def test_rendering_every_step_leaves_the_trajectory_bit_identical(env_id, kwargs):
    def run(render_mode: str | None) -> list:
        env = gym.make(env_id, render_mode=render_mode, **kwargs)
        rng = np.random.default_rng(7)
        out = []
        try:
            for seed in (0, 1):
                obs, info = env.reset(seed=seed)
                if render_mode:
                    env.render()
                out.append((obs, info))
                for _ in range(25):
                    obs, reward, terminated, truncated, info = env.step(rng.uniform(-0.5, 0.5, 18))
                    if render_mode:
                        env.render()
                    out.append((obs, reward, terminated, info))
                    if terminated or truncated:
                        break
        finally:
            env.close()
        return out

    plain, rendered = run(None), run("rgb_array")
    assert len(plain) == len(rendered)
    for a, b in zip(plain, rendered):
        assert np.array_equal(a[0], b[0]) and a[1:-1] == b[1:-1]
        assert a[-1].keys() == b[-1].keys()
        for key, value in a[-1].items():
            assert np.array_equal(value, b[-1][key]), key
    if "obstacles" in kwargs:
        assert any(step[-1].get("obstacle_contacts", 0) > 0 for step in plain)  # contacts were compared too
