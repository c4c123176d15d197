"""TD3-prior (agents/algos/td3_prior.py): the actor loss, faithfulness to SB3's TD3, the pull toward zero, configs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml
from stable_baselines3 import TD3

from agents.algos.td3_prior import TD3Prior, actor_loss
from agents.config import ConfigError, load_config

KW = {"learning_starts": 20, "policy_delay": 1, "batch_size": 16, "policy_kwargs": {"net_arch": [16]}, "seed": 4}


def _params(module: torch.nn.Module) -> list[np.ndarray]:
    return [p.detach().cpu().numpy().copy() for p in module.parameters()]


def test_actor_loss_is_the_normalised_q_plus_the_prior_term():
    rng = np.random.default_rng(0)
    q, a = rng.normal(3.0, 2.0, (32, 1)), rng.uniform(-1.0, 1.0, (32, 4))
    expected = -q.mean() / np.abs(q).mean() + 0.7 * (a**2).mean()
    got = actor_loss(torch.tensor(q), torch.tensor(a), 0.7)
    assert float(got) == pytest.approx(expected, rel=1e-12)
    # the normalisation is detached: d loss / d q = -1 / (n mean|q|), not the derivative of the ratio
    qt = torch.tensor(q, requires_grad=True)
    actor_loss(qt, torch.tensor(a), 0.7).backward()
    np.testing.assert_allclose(qt.grad.numpy(), -1.0 / (q.size * np.abs(q).mean()), rtol=1e-12)


def test_with_no_prior_the_first_update_is_sb3_td3s():
    """Same seed, prior_coef 0: critics equal to the bit, actor equal after Adam's first (scale-free) step."""
    steps = KW["learning_starts"] + 1  # one gradient step: one critic and one actor update
    # each model is built and trained before the next is built: SB3 seeds the global RNGs at construction, and the
    # replay buffer samples from the global numpy RNG
    ours = TD3Prior("MlpPolicy", gym.make("Pendulum-v1"), prior_coef=0.0, **KW)
    initial_actor = _params(ours.actor)
    ours.learn(steps)
    reference = TD3("MlpPolicy", gym.make("Pendulum-v1"), **KW)
    reference.learn(steps)
    assert ours._n_updates == reference._n_updates == 1
    for a, b in zip(_params(ours.critic), _params(reference.critic), strict=True):
        np.testing.assert_array_equal(a, b)
    moved = 0
    for a, b, c in zip(_params(ours.actor), _params(reference.actor), initial_actor, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-5)  # Adam's first step lr g / (|g| + eps): eps differs
        moved += int(np.any(a != c))
    assert moved > 0


def test_a_large_prior_coef_keeps_the_actor_near_zero():
    obs = np.random.default_rng(1).uniform(-1.0, 1.0, (256, 3)).astype(np.float32)
    mean_square = {}
    for coef in (0.0, 50.0):
        model = TD3Prior("MlpPolicy", gym.make("Pendulum-v1"), prior_coef=coef, **KW)
        model.learn(400)
        actions = model.actor(torch.as_tensor(obs)).detach().numpy()
        mean_square[coef] = float((actions**2).mean())
    assert mean_square[50.0] < 0.05 < mean_square[0.0], mean_square


def test_prior_coef_survives_save_and_load(tmp_path):
    model = TD3Prior("MlpPolicy", gym.make("Pendulum-v1"), prior_coef=1.25, **KW)
    model.save(tmp_path / "m.zip")
    assert TD3Prior.load(tmp_path / "m.zip").prior_coef == 1.25


@pytest.mark.parametrize("bad", [-0.1, float("nan"), "x"])
def test_bad_prior_coef_is_refused(bad, tmp_path):
    with pytest.raises(ValueError, match="prior_coef must be a finite number >= 0"):
        TD3Prior("MlpPolicy", gym.make("Pendulum-v1"), prior_coef=bad)
    if isinstance(bad, float) and bad == bad:
        path = tmp_path / "c.yml"
        path.write_text(yaml.safe_dump({"Pendulum-v1": {"n_timesteps": 10, "prior_coef": bad}}), encoding="utf-8")
        with pytest.raises(ConfigError, match="prior_coef must be a finite number >= 0"):
            load_config(path, "td3_prior", "Pendulum-v1")
