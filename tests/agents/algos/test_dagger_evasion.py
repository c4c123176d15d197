"""DAgger's evasion term (``evasion_weight``): the squared error along each obstacle's opening direction.

* The term equals a direct numpy evaluation at the columns the features document (the observation, then 27 per slot
  with the weighted opening direction at 4..21, then 18), and is zero for a batch far from every obstacle.
* A policy that does not observe the features as the training wrapper gives them (none, or a frame stack around
  them) is refused by name.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3.common.vec_env import DummyVecEnv

from agents.algos.dagger import DAgger
from agents.common.history import FrameStack
from uvdms_gym.residual import ObstacleFeatureObservation

ENV = "uvdms/TransportObstacles-v1"
OBS_DIM = 119  # Transport-v1's 80 and three obstacle slots of 13
SLOTS, PER_SLOT = 3, 27


def _model(wrap) -> DAgger:
    env = DummyVecEnv([lambda: wrap(gym.make(ENV, max_episode_steps=10))])
    return DAgger("MlpPolicy", env, seed=0, evasion_weight=2.0, policy_kwargs={"net_arch": [8]})


def test_the_evasion_term_is_the_squared_error_along_each_opening_direction():
    model = _model(ObstacleFeatureObservation)
    dim = model.observation_space.shape[0]
    assert dim == OBS_DIM + SLOTS * PER_SLOT + 18
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(64, dim))
    actions, labels = rng.uniform(-1, 1, (64, 18)), rng.uniform(-1, 1, (64, 18))
    expected = np.zeros(64)
    for k in range(SLOTS):
        first = OBS_DIM + PER_SLOT * k + 4
        expected += np.einsum("bj,bj->b", obs[:, first : first + 18], actions - labels) ** 2
    got = model.evasion_loss(*(torch.as_tensor(x) for x in (obs, actions, labels)))
    assert float(got) == pytest.approx(expected.mean(), rel=1e-12)
    far = obs.copy()
    for k in range(SLOTS):
        far[:, OBS_DIM + PER_SLOT * k + 4 : OBS_DIM + PER_SLOT * k + 22] = 0.0  # w = 0: no obstacle within reach
    assert float(model.evasion_loss(*(torch.as_tensor(x) for x in (far, actions, labels)))) == 0.0


@pytest.mark.parametrize("wrap", [lambda env: env, lambda env: FrameStack(ObstacleFeatureObservation(env), 2)])
def test_a_policy_without_the_features_last_is_refused_by_name(wrap):
    model = _model(wrap)
    dim = model.observation_space.shape[0]
    batch = torch.zeros((4, dim)), torch.zeros((4, 18)), torch.zeros((4, 18))
    with pytest.raises(ValueError, match="evasion_weight needs a policy that observes the obstacle features"):
        model.evasion_loss(*batch)
