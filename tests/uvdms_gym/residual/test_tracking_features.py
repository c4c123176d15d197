"""The tracking features of ``tracking_features=True`` (uvdms_gym.residual.TrackingFeatures).

* Inverted (``artanh``, times the scale of success), the features' norms equal the errors the environment reports
  in ``info`` (``tracking_error``, ``orientation_error``), which it computes from the true pose in the world frame:
  on the transport the position and the orientation, on the circles the mean of the two end effectors'.
* An error at the success radius observes as ``tanh(1)``; the constant that decodes the observation is the
  environment's.
* The wrapper's observation lies in its space and keeps the obstacle features where their wrapper put them; bad
  environments and composition values are refused with errors that name the problem.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from baselines.controllers import make_baseline
from uvdms_gym.envs import tracking
from uvdms_gym.residual import (
    TRACKING_ORIENTATION,
    TRACKING_POSITION,
    ActionComposition,
    ObstacleFeatureObservation,
    TrackingFeatureObservation,
    TrackingFeatures,
)
from uvdms_gym.residual import tracking_features as T

STEPS = 40
SATURATED = 0.999
"""Features beyond this are too near +-1 to invert to the error they came from (float32 observations)."""


def _small_error_states(env_id: str, seed: int, **kwargs) -> list[tuple[np.ndarray, dict]]:
    """``(obs, info)`` of an episode under plain ``mpc``: errors of millimetres to centimetres."""
    env = gym.make(env_id, max_episode_steps=STEPS, **kwargs)
    try:
        mpc = make_baseline("mpc", env)
        obs, info = env.reset(seed=seed)
        mpc.reset(seed)
        states = [(obs, info)]
        for _ in range(STEPS - 1):
            obs, _, terminated, truncated, info = env.step(mpc.predict(obs, info))
            states.append((obs, info))
            if terminated or truncated:
                break
        return states
    finally:
        env.close()


def _decoded(values: np.ndarray, scale: float) -> float:
    """The norm of the error that ``tanh(e / scale)`` came from."""
    return float(np.linalg.norm(scale * np.arctanh(values)))


@pytest.mark.parametrize("env_id", ["uvdms/Transport-v1", "uvdms/TransportObstacles-v1"])
def test_the_transport_features_decode_to_the_errors_of_info(env_id):
    env = gym.make(env_id)
    features = TrackingFeatures.for_env(env)
    env.close()
    assert features.orientation is True
    checked = 0
    for obs, info in _small_error_states(env_id, seed=7, current="random"):
        f = features(obs)
        if np.max(np.abs(f)) > SATURATED or info["tracking_error"] < 1e-4:
            continue
        assert _decoded(f[:3], TRACKING_POSITION) == pytest.approx(info["tracking_error"], rel=1e-4, abs=1e-7)
        assert _decoded(f[3:], TRACKING_ORIENTATION) == pytest.approx(info["orientation_error"], rel=1e-4, abs=1e-7)
        checked += 1
    assert checked > 10


def test_the_circle_features_are_the_two_end_effector_errors():
    env_id = "uvdms/CircleTrack-v1"
    env = gym.make(env_id)
    features = TrackingFeatures.for_env(env)
    env.close()
    assert features.orientation is False
    checked = 0
    for obs, info in _small_error_states(env_id, seed=3):
        f = features(obs)
        if np.max(np.abs(f)) > SATURATED:
            continue
        mean = 0.5 * (_decoded(f[:3], TRACKING_POSITION) + _decoded(f[3:], TRACKING_POSITION))
        assert mean == pytest.approx(info["tracking_error"], rel=1e-4, abs=1e-7)
        checked += 1
    assert checked > 5


def test_an_error_at_the_success_radius_observes_as_tanh_one():
    assert T.POS_SCALE == tracking.POS_SCALE
    obs = np.zeros(80, np.float32)
    obs[0] = TRACKING_POSITION / tracking.POS_SCALE  # 2 cm along x
    obs[5] = -TRACKING_ORIENTATION  # -2 degrees about z
    f = TrackingFeatures(orientation=True)(obs)
    np.testing.assert_allclose(f, [np.tanh(1.0), 0, 0, 0, 0, -np.tanh(1.0)], rtol=1e-6, atol=1e-12)
    assert TrackingFeatures(orientation=False)(obs)[5] == pytest.approx(-np.tanh(TRACKING_ORIENTATION / 0.04))


def test_the_wrapper_appends_the_features_after_the_obstacle_features():
    inner = ObstacleFeatureObservation(gym.make("uvdms/TransportObstacles-v1", obstacles="random"))
    env = TrackingFeatureObservation(inner)
    try:
        obs, _ = env.reset(seed=2)
        assert env.observation_space.contains(obs)
        assert obs.shape == (inner.featured_dim + T.TRACKING_SIZE,) and env.featured_dim == obs.shape[0]
        expected = env.features(obs[: inner.featured_dim]).astype(obs.dtype)
        np.testing.assert_array_equal(obs[-T.TRACKING_SIZE :], expected)
        assert env.get_wrapper_attr("opening_index") == inner.opening_index  # the evasion term's columns: unchanged
    finally:
        env.close()


def test_bad_environments_and_values_are_refused():
    with pytest.raises(ValueError, match="tracking_features=True needs a UVDMS circle or transport environment"):
        TrackingFeatures.for_env(gym.make("CartPole-v1"))
    with pytest.raises(ValueError, match="orientation must be true or false"):
        TrackingFeatures(orientation=1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="tracking_features must be true or false"):
        ActionComposition(tracking_features="yes")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="tracking_features is for a policy that outputs the whole command"):
        ActionComposition(residual_base="mpc", residual_scale=0.5, tracking_features=True)
    record = ActionComposition(obstacle_features=True, tracking_features=True).to_record()
    assert ActionComposition.from_record(record).tracking_features is True
    assert ActionComposition.from_record({}).tracking_features is False  # records written before the key
