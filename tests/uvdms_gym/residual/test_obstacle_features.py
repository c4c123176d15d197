"""The obstacle features of ``obstacle_features=True`` (uvdms_gym.residual.ObstacleFeatures).

* Computed from the observation alone (body frame), they equal the formula of the module docstring evaluated
  independently in the world frame from ``info`` (the true pose, joint angles, velocity and obstacles; the numpy
  reference gaps): a check of the decoding of the slots, ``sin q``/``cos q`` and the velocities, and of the frame
  invariance the module relies on.
* Each slot's gap rate is the central finite difference of the gap when the robot moves with its measured velocity
  and the obstacle with its own (pin.integrate); moving along the opening direction opens the gap at ``|G|``.
* Padding slots are zero; the wrapper's observation lies in its space; an environment without obstacle slots and
  bad composition values are refused with errors that name the problem.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pinocchio as pin
import pytest

from baselines.controllers import make_baseline
from uvdms_gym.distances.outer import compute_outer_distances, compute_outer_distances_reference, part_frames
from uvdms_gym.envs import obstacles as env_obstacles
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.residual import (
    FEATURE_CLIP,
    ActionComposition,
    ObstacleFeatureObservation,
    ObstacleFeatures,
    obstacle_feature_space,
)
from uvdms_gym.residual import obstacle_features as F

ENV = "uvdms/TransportObstacles-v1"
SEEDS = (3, 5)
STEPS = 250
N_PARTS = 14  # 12 links, the object, the hull


def _campc_states() -> list[tuple[np.ndarray, dict]]:
    """``(obs, info)`` every 5th step of CAMPC's episodes on random obstacles."""
    env = gym.make(ENV, obstacles="random", current="random", max_episode_steps=STEPS)
    try:
        campc = make_baseline("campc", env)
        states = []
        for seed in SEEDS:
            obs, info = env.reset(seed=seed)
            campc.reset(seed)
            for t in range(STEPS):
                if t % 5 == 0:
                    states.append((obs.copy(), info))
                obs, _, terminated, truncated, info = env.step(campc.predict(obs, info))
                if terminated or truncated:
                    break
        return states
    finally:
        env.close()


@pytest.fixture(scope="module")
def states() -> list[tuple[np.ndarray, dict]]:
    return _campc_states()


@pytest.fixture(scope="module")
def features() -> ObstacleFeatures:
    env = gym.make(ENV)
    try:
        return ObstacleFeatures.for_env(env)
    finally:
        env.close()


def _damper_weight(d: float) -> float:
    """``1 - S(d)`` with the features' thresholds (docs/MODEL.md's velocity damper)."""
    x = min(max((d - F.FEATURE_D1) / (F.FEATURE_D2 - F.FEATURE_D1), 0.0), 1.0)
    return 1.0 - np.sin(0.5 * np.pi * x) ** 2


def _world_rows(kin: KinematicModel, info: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference gaps, ``J_dis`` rows and obstacle rates in the world frame, in the slots' order."""
    kin.set_state(info["eta"], info["q"])
    obstacles = np.asarray(info["obstacles"])
    gaps = compute_outer_distances_reference(kin, obstacles, True).reshape(-1, N_PARTS)
    order = np.argsort(gaps.min(axis=1), kind="stable")
    obstacles = obstacles[order]
    res = compute_outer_distances(kin, obstacles, True)
    np.testing.assert_allclose(res.d, gaps[order].ravel(), atol=1e-7)
    jac = _jacobian_rows(kin, res)
    rate = np.einsum("ij,ij->i", res.normals, np.repeat(obstacles[:, 3:6], N_PARTS, axis=0))
    return res.d, jac, rate


def _jacobian_rows(kin: KinematicModel, res) -> np.ndarray:
    """``n^T J_P`` of each row by central finite differences of the closest point's motion (pin.integrate)."""
    eps = 1e-6
    config = kin.config.copy()
    frames = part_frames(True)
    rows = np.zeros((res.d.size, 18))
    for r in range(res.d.size):
        frame = frames[r % N_PARTS]
        kin.set_configuration(config)
        pos, rot = kin.frame_placement(frame)
        local = rot.T @ (res.p[r] - pos)  # the material point, fixed in its part's frame
        for j in range(18):
            step = np.zeros(18)
            step[j] = eps
            moved = []
            for sign in (1.0, -1.0):
                kin.set_configuration(pin.integrate(kin.model, config, sign * step))
                p, R = kin.frame_placement(frame)
                moved.append(p + R @ local)
            rows[r, j] = res.normals[r] @ (moved[0] - moved[1]) / (2 * eps)
    kin.set_configuration(config)
    return rows


def _reference_features(features: ObstacleFeatures, kin: KinematicModel, info: dict) -> np.ndarray:
    """The module docstring's formula, from ``info`` in the world frame."""
    d, jac, rate = _world_rows(kin, info)
    zeta = np.concatenate([info["nu"], info["qdot"]])
    out = np.zeros(features.size)
    total = np.zeros(18)
    for r in range(d.size):
        gain = jac[r] * features.zeta_max
        g = np.linalg.norm(gain)
        d_dot = rate[r] - jac[r] @ zeta
        d_pred = d[r] + min(d_dot, 0.0) * F.LOOKAHEAD
        w = _damper_weight(d_pred)
        total += -w * gain / g
        k = r // N_PARTS
        if r != k * N_PARTS + int(np.argmin(d[k * N_PARTS : (k + 1) * N_PARTS])):
            continue
        base = F.PER_SLOT * k
        out[base : base + 4] = [d[r] / F.GAP_SCALE, rate[r] / F.RATE_SCALE, d_dot / F.RATE_SCALE, d_pred / F.GAP_SCALE]
        out[base + 4 : base + 22] = -w * gain / g
        out[base + 22] = g / F.RATE_SCALE
        out[base + 26] = 1.0
    out[F.PER_SLOT * features.n_slots :] = total
    return np.clip(out, -FEATURE_CLIP, FEATURE_CLIP)


def test_the_constants_are_the_environments(features):
    assert (F.SLOT_SIZE, F.SLOT_POS_SCALE) == (env_obstacles.OBSTACLE_SLOT, env_obstacles.OBSTACLE_POS_SCALE)
    assert (F.SLOT_VEL_SCALE, F.SLOT_SIZE_SCALE) == (
        env_obstacles.OBSTACLE_VEL_SCALE,
        env_obstacles.OBSTACLE_SIZE_SCALE,
    )
    assert features.size == 3 * F.PER_SLOT + 18 and features.n_slots == 3


def test_features_from_the_observation_equal_the_world_frame_formula(states, features):
    kin = KinematicModel()
    near = 0
    for obs, info in states[::3]:
        got = features(obs)
        assert got.shape == (features.size,) and got.dtype == np.float64
        want = _reference_features(features, kin, info)
        # the observation is float32: the decoded pose and slots carry its rounding (about 1e-7 relative)
        compared = np.ones(features.size, bool)
        for k in range(features.n_slots):
            compared[F.PER_SLOT * k + 23 : F.PER_SLOT * k + 26] = False  # the escape direction, checked below
        np.testing.assert_allclose(got[compared], want[compared], atol=2e-4, rtol=1e-4)
        # the escape direction (not in the reference): a unit vector times the weight of the nearest pair
        for k in range(int(np.sum(got[F.PER_SLOT - 1 :: F.PER_SLOT][:3]))):
            weight = np.linalg.norm(got[F.PER_SLOT * k + 4 : F.PER_SLOT * k + 22])
            assert np.linalg.norm(got[F.PER_SLOT * k + 23 : F.PER_SLOT * k + 26]) == pytest.approx(weight, abs=1e-6)
        near += bool(np.any(got[4:22] != 0.0))
    assert near >= 3, "no state had an obstacle within the features' reach: the weights were not exercised"


def _gaps_moved(kin: KinematicModel, info: dict, step: np.ndarray, dt: float) -> list[np.ndarray]:
    """Each obstacle's smallest gap with the robot moved by ``+step`` and the obstacles by ``+dt`` of their motion,
    then by ``-step`` and ``-dt``."""
    obstacles = np.asarray(info["obstacles"])
    kin.set_state(info["eta"], info["q"])
    config = kin.config.copy()
    gaps = []
    for sign in (1.0, -1.0):
        kin.set_configuration(pin.integrate(kin.model, config, sign * step))
        moved = obstacles.copy()
        moved[:, :3] += sign * dt * obstacles[:, 3:6]
        gaps.append(compute_outer_distances(kin, moved, True).per_obstacle().min(axis=1))
    return gaps


def test_the_gap_rate_is_the_finite_difference_of_the_gap(states, features):
    eps = 1e-5
    kin = KinematicModel()
    checked = 0
    for obs, info in states[::4]:
        got = features(obs)
        zeta = np.concatenate([info["nu"], info["qdot"]])
        gap = _gaps_moved(kin, info, eps * zeta, eps)
        order = np.argsort(np.minimum(gap[0], gap[1]), kind="stable")
        fd = ((gap[0] - gap[1]) / (2 * eps))[order]
        for k in range(len(gap[0])):
            assert got[F.PER_SLOT * k + 2] * F.RATE_SCALE == pytest.approx(fd[k], abs=2e-4)
            checked += 1
    assert checked >= 10


def test_moving_along_the_opening_direction_opens_the_nearest_gap_at_its_rate(states, features):
    eps = 1e-6
    kin = KinematicModel()
    checked = 0
    for obs, info in states:
        got = features(obs)
        direction = got[4:22]
        weight = np.linalg.norm(direction)
        if weight < 1e-3:
            continue
        zeta = direction / weight * features.zeta_max  # the normalised action along the unit opening direction
        gap = _gaps_moved(kin, info, eps * zeta, 0.0)  # the obstacles held still
        assert (gap[0].min() - gap[1].min()) / (2 * eps) == pytest.approx(got[22] * F.RATE_SCALE, rel=1e-3, abs=1e-4)
        checked += 1
    assert checked >= 3


def test_padding_slots_and_an_empty_scene_give_zeros(states, features):
    obs, _ = states[0]
    empty = obs.copy()
    empty[-F.SLOT_SIZE * 3 :] = 0.0
    np.testing.assert_array_equal(features(empty), np.zeros(features.size))
    one = obs.copy()
    one[-F.SLOT_SIZE * 2 :] = 0.0  # slots 2 and 3 padded
    got = features(one)
    np.testing.assert_array_equal(got[F.PER_SLOT : 3 * F.PER_SLOT], np.zeros(2 * F.PER_SLOT))
    assert got[F.PER_SLOT - 1] == 1.0


def test_the_wrapper_observes_the_features_within_its_space(features):
    env = ObstacleFeatureObservation(gym.make(ENV, max_episode_steps=20))
    try:
        assert env.observation_space.shape == (119 + features.size,)
        obs, _ = env.reset(seed=2)
        for _ in range(5):
            assert env.observation_space.contains(obs)
            np.testing.assert_array_equal(obs[119:], features(obs[:119]).astype(np.float32))
            obs, *_ = env.step(env.action_space.sample() * 0.1)
    finally:
        env.close()
    space = obstacle_feature_space(gym.spaces.Box(-1.0, 1.0, (119,), np.float32), features)
    assert space.shape == (119 + features.size,) and space.dtype == np.float32


def test_an_environment_without_obstacle_slots_is_refused():
    env = gym.make("uvdms/Transport-v1")
    try:
        with pytest.raises(ValueError, match="obstacle_features=True needs an environment whose observation has"):
            ObstacleFeatureObservation(env)
    finally:
        env.close()


def test_the_composition_records_the_flag_and_refuses_bad_values():
    composition = ActionComposition(obstacle_features=True, frame_stack=2)
    assert composition.to_record()["obstacle_features"] is True
    assert ActionComposition.from_record(composition.to_record()) == composition
    assert ActionComposition.from_record({"residual_base": None}).obstacle_features is False
    with pytest.raises(ValueError, match="obstacle_features must be true or false, got 1"):
        ActionComposition(obstacle_features=1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="obstacle_features is for a policy that outputs the whole command"):
        ActionComposition("mpc", 0.3, obstacle_features=True)
