"""A network alone with the obstacle features (``obstacle_features=true``), from training to the leaderboard.

A tiny DAgger run on the obstacle task is exported, with the obstacle features alone and with the tracking features
after them (``tracking_features=true``); the run and the export record the keys, ``run_time`` says the network runs
alone with the features; the leaderboard's controller computes the features from each observation as the training
wrappers did (its actions equal the policy's on the wrappers' observations, step by step; the evasion term finds its
columns through both wrappers); an environment without obstacle slots is refused, naming the features.
"""

from __future__ import annotations

import json
import warnings

import gymnasium as gym
import numpy as np
import pytest
import torch

from agents.export import AgentController, EnvMismatchWarning, check_agent, load_agent
from agents.training.train import run_dir_for
from leaderboard.suite.registry import make_controller
from uvdms_cli.main import main as uvdms
from uvdms_gym.residual import (
    FeatureController,
    ObstacleFeatureObservation,
    ObstacleFeatures,
    TrackingFeatureObservation,
    TrackingFeatures,
)

ENV = "uvdms/TransportObstacles-v1"
STEPS = 40
N_FEATURES = 99
TRACKING = 6


@pytest.fixture(scope="module", params=[False, True], ids=["obstacle", "obstacle+tracking"])
def feature_export(request, tmp_path_factory) -> tuple:
    """A DAgger run with obstacle_features=true (CAMPC teaching), exported weights-only; with tracking_features."""
    tmp = tmp_path_factory.mktemp("features")
    argv = ["train", "--algo", "dagger", "--env", ENV, "--env-kwargs", "obstacles=random", "current=random"]
    argv += ["max_episode_steps=30", "--residual", "none", "--total-timesteps", "80", "--seed", "0"]
    argv += ["--hyperparams", "teacher=campc", "obstacle_features=true", "evasion_weight=1.0", "eval_freq=0"]
    argv += ["checkpoint_freq=0"]
    argv += ["batch_size=32", "save_replay_buffer=false", "policy_kwargs={net_arch: [16]}"]
    argv += [f"tracking_features={str(request.param).lower()}", "--out", str(tmp / "runs"), "--no-progress"]
    assert uvdms(argv) == 0
    run_dir = run_dir_for(tmp / "runs", ENV, "dagger", 0)
    export = tmp / "export"
    assert uvdms(["export-agent", str(run_dir), str(export), "--trust"]) == 0
    return run_dir, export, request.param


def test_the_run_and_the_export_record_the_features(feature_export):
    run_dir, export, tracking = feature_export
    doc = json.loads((export / "agent.json").read_text())
    assert (doc["obstacle_features"], doc["tracking_features"], doc["residual_base"]) == (True, tracking, None)
    assert doc["run_time"]["network_only"] is True and doc["run_time"]["obstacle_features"] is True
    assert doc["run_time"]["tracking_features"] is tracking
    agent = load_agent(export)
    size = gym.make(ENV).observation_space.shape[0]
    assert agent.policy.observation_space.shape == (size + N_FEATURES + TRACKING * tracking,)
    assert load_agent(run_dir, trust=True).composition == agent.composition


def test_the_leaderboard_controller_computes_the_features_as_in_training(feature_export):
    env = gym.make(ENV, max_episode_steps=STEPS)
    controller = make_controller(str(feature_export[1]), env)
    assert isinstance(controller, FeatureController) and isinstance(controller.features, ObstacleFeatures)
    training_env = ObstacleFeatureObservation(gym.make(ENV, max_episode_steps=STEPS))
    agent = controller.policy
    if feature_export[2]:  # the tracking features inside, as the training wrappers nest them
        assert isinstance(agent, FeatureController) and isinstance(agent.features, TrackingFeatures)
        agent = agent.policy
        training_env = TrackingFeatureObservation(training_env)
    assert isinstance(agent, AgentController)
    controller.reset(seed=4)
    obs, info = env.reset(seed=4)
    featured, _ = training_env.reset(seed=4)
    steps = 0
    while True:
        action = controller.predict(obs, info)
        with torch.no_grad():
            policy_action, _ = agent.policy.predict(featured, deterministic=True)
        np.testing.assert_allclose(action, policy_action, rtol=1e-5, atol=1e-6)
        obs, _, terminated, truncated, info = env.step(action)
        featured, _, terminated_t, truncated_t, _ = training_env.step(action)
        assert (terminated, truncated) == (terminated_t, truncated_t)
        steps += 1
        if terminated or truncated:
            break
    assert steps > 10
    size = env.observation_space.shape[0]
    assert np.any(featured[size : size + N_FEATURES] != 0.0)
    assert not feature_export[2] or np.any(featured[-TRACKING:] != 0.0)


def test_an_environment_without_obstacle_slots_is_refused_naming_the_features(feature_export):
    agent = load_agent(feature_export[1])
    check_agent(agent, gym.make(ENV))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EnvMismatchWarning)  # (another env id: warned, not refused)
        with pytest.raises(ValueError, match="obstacle_features=True needs an environment whose observation has"):
            check_agent(agent, gym.make("uvdms/Transport-v1"), "features")
    assert ObstacleFeatures.for_env(gym.make(ENV)).size == N_FEATURES
