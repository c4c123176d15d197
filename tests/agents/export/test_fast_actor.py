"""The direct actor call (agents/export/fast_actor.py) gives SB3's ``policy.predict`` action, to the bit.

Checked on a TD3 actor with ReLU and with Tanh hidden layers (applied layer by layer) and with another activation
(called as a module), on an asymmetric action box, on batches and on single observations; a policy it cannot call
directly (SAC's Gaussian actor) is left to ``policy.predict``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium import spaces
from stable_baselines3 import SAC, TD3

from agents.export.controller import AgentController
from agents.export.fast_actor import FastActor


class _BoxEnv(gym.Env):
    observation_space = spaces.Box(-5.0, 5.0, (7,), np.float32)
    action_space = spaces.Box(np.array([-1.0, -2.0, 0.0], np.float32), np.array([1.0, 0.5, 3.0], np.float32))

    def reset(self, *, seed=None, options=None):
        return np.zeros(7, np.float32), {}

    def step(self, action):
        return np.zeros(7, np.float32), 0.0, False, False, {}


@pytest.mark.parametrize("activation", [torch.nn.ReLU, torch.nn.Tanh])
def test_the_direct_actor_matches_sb3_predict_to_the_bit(activation):
    model = TD3("MlpPolicy", _BoxEnv(), seed=0, policy_kwargs={"net_arch": [32, 16], "activation_fn": activation})
    with torch.no_grad():  # spread the weights so that the tanh output covers its range
        for p in model.policy.actor.parameters():
            p.mul_(3.0)
    actor = FastActor.from_policy(model.policy)
    assert actor is not None and actor.steps is not None and len(actor.steps) == 6  # 3 layers, 3 activations
    obs = np.random.default_rng(0).uniform(-5.0, 5.0, (200, 7)).astype(np.float32)
    expected, _ = model.policy.predict(obs, deterministic=True)
    got = actor(obs)
    assert got.dtype == np.float32 and got.shape == expected.shape
    np.testing.assert_array_equal(got, expected)
    assert np.ptp(expected[:, 2]) > 1.0  # the box mapping was exercised
    for o in obs[:10]:  # one observation: SB3's (1, n) batch (a row of a larger batch may round differently)
        np.testing.assert_array_equal(actor(o), model.policy.predict(o, deterministic=True)[0])
    controller = AgentController(model.policy, algo="td3")
    assert controller.fast_actor is not None
    np.testing.assert_array_equal(controller.predict(obs[0]), model.policy.predict(obs[0], deterministic=True)[0])


def test_an_actor_with_another_activation_is_called_as_a_module_with_the_same_bits():
    model = TD3("MlpPolicy", _BoxEnv(), seed=0, policy_kwargs={"net_arch": [16], "activation_fn": torch.nn.LeakyReLU})
    actor = FastActor.from_policy(model.policy)
    assert actor is not None and actor.steps is None
    obs = np.random.default_rng(1).uniform(-5.0, 5.0, (50, 7)).astype(np.float32)
    np.testing.assert_array_equal(actor(obs), model.policy.predict(obs, deterministic=True)[0])


def test_a_policy_it_cannot_read_keeps_sb3_predict():
    model = SAC("MlpPolicy", _BoxEnv(), seed=0, policy_kwargs={"net_arch": [8]})
    assert FastActor.from_policy(model.policy) is None
    controller = AgentController(model.policy, algo="sac")
    obs = np.ones(7, np.float32)
    np.testing.assert_array_equal(controller.predict(obs), model.policy.predict(obs, deterministic=True)[0])
