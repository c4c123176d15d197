"""TD3-prior fine-tuning from a prior policy (agents/algos/td3_prior.py, agents/algos/prior.py).

* The actor loss with a prior's actions is the normalised Q term plus ``prior_coef`` times the mean squared
  deviation from the prior (checked against NumPy).
* ``prior_policy``: the actor and its target start as the exported actor, to the bit; the frozen prior stays so
  while the actor trains; a large ``prior_coef`` keeps the trained actor nearer the prior than a zero one does.
* Bad priors are refused by name (not an export, another network shape, observation normalisation), and so is
  ``action_init_scale`` with a prior.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3 import TD3

from agents.algos import prior as prior_module
from agents.algos.td3_prior import TD3Prior, actor_loss
from agents.config import ConfigError, load_config
from agents.export import weights as weights_module
from agents.export.controller import AgentController, ObsNormalizer
from agents.export.weights import export_controller

KW = {"learning_starts": 20, "policy_delay": 1, "batch_size": 16, "policy_kwargs": {"net_arch": [16]}, "seed": 4}


def _export(tmp_path, net_arch=(16,), normalizer=None, name="prior"):
    model = TD3("MlpPolicy", gym.make("Pendulum-v1"), seed=1, policy_kwargs={"net_arch": list(net_arch)})
    with torch.no_grad():
        for p in model.actor.parameters():
            p.add_(0.3)  # a prior unlike a fresh initialisation
    agent = AgentController(model.policy, algo="td3", env_id="Pendulum-v1", normalizer=normalizer)
    return export_controller(agent, tmp_path / name), model


def test_the_export_file_names_agree():
    assert (prior_module.AGENT_JSON, prior_module.WEIGHTS_FILE) == (
        weights_module.AGENT_JSON,
        weights_module.WEIGHTS_FILE,
    )


def test_actor_loss_with_a_prior_is_the_normalised_q_plus_the_deviation_term():
    rng = np.random.default_rng(0)
    q, a, p = rng.normal(3.0, 2.0, (32, 1)), rng.uniform(-1, 1, (32, 4)), rng.uniform(-1, 1, (32, 4))
    expected = -q.mean() / np.abs(q).mean() + 0.7 * ((a - p) ** 2).mean()
    got = actor_loss(torch.tensor(q), torch.tensor(a), 0.7, torch.tensor(p))
    assert float(got) == pytest.approx(expected, rel=1e-12)


def _state(module: torch.nn.Module) -> dict[str, np.ndarray]:
    return {k: v.detach().cpu().numpy().copy() for k, v in module.state_dict().items()}


def test_fine_tuning_starts_at_the_prior_and_holds_near_it(tmp_path):
    folder, source = _export(tmp_path)
    exported = _state(source.actor)
    model = TD3Prior("MlpPolicy", gym.make("Pendulum-v1"), prior_policy=str(folder), prior_coef=0.4, **KW)
    for module in (model.actor, model.actor_target, model.prior_actor):
        for key, value in _state(module).items():
            np.testing.assert_array_equal(value, exported[key])
    model.learn(300)
    for key, value in _state(model.prior_actor).items():
        np.testing.assert_array_equal(value, exported[key])  # the prior is frozen
    assert any(np.any(v != exported[k]) for k, v in _state(model.actor).items())  # the actor trained
    model.save(tmp_path / "tuned.zip")  # a saved model keeps its trained actor, and rebuilds the prior from the file
    loaded = TD3Prior.load(tmp_path / "tuned.zip", env=gym.make("Pendulum-v1"))
    for key, value in _state(loaded.actor).items():
        np.testing.assert_array_equal(value, _state(model.actor)[key])
    for key, value in _state(loaded.prior_actor).items():
        np.testing.assert_array_equal(value, exported[key])
    obs = torch.as_tensor(np.random.default_rng(2).uniform(-1, 1, (256, 3)).astype(np.float32))
    deviation = {}
    for coef in (0.0, 50.0):
        tuned = TD3Prior("MlpPolicy", gym.make("Pendulum-v1"), prior_policy=str(folder), prior_coef=coef, **KW)
        tuned.learn(400)
        with torch.no_grad():
            deviation[coef] = float(((tuned.actor(obs) - tuned.prior_actor(obs)) ** 2).mean())
    assert deviation[50.0] < 0.5 * deviation[0.0], deviation


def test_bad_priors_are_refused_by_name(tmp_path):
    with pytest.raises(ValueError, match="is not a weights-only agent export"):
        TD3Prior("MlpPolicy", gym.make("Pendulum-v1"), prior_policy=str(tmp_path), **KW)
    wide, _ = _export(tmp_path, net_arch=(32,), name="wide")
    with pytest.raises(ValueError, match=r"its actor does not fit this policy \(net_arch \[16\]"):
        TD3Prior("MlpPolicy", gym.make("Pendulum-v1"), prior_policy=str(wide), **KW)
    normalizer = ObsNormalizer(np.zeros(3), np.ones(3), 10.0, 1e-8)
    normalised, _ = _export(tmp_path, normalizer=normalizer, name="normalised")
    with pytest.raises(ValueError, match="trained with observation normalisation"):
        TD3Prior("MlpPolicy", gym.make("Pendulum-v1"), prior_policy=str(normalised), **KW)


def test_a_prior_with_action_init_scale_is_a_config_error(tmp_path):
    folder, _ = _export(tmp_path)
    config = tmp_path / "td3_prior.yml"
    config.write_text("default:\n  n_timesteps: 100\n  action_init_scale: 0.01\n")
    with pytest.raises(ConfigError, match="would shrink the actor that prior_policy starts from"):
        load_config(config, "td3_prior", "Pendulum-v1", overrides={"prior_policy": str(folder)})
    assert load_config(
        config, "td3_prior", "Pendulum-v1", overrides={"prior_policy": str(folder), "action_init_scale": None}
    )
