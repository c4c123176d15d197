"""An agent with memory (``frame_stack``) and the navigation filter, from training to the leaderboard's controller.

A tiny DAgger run (two realism levels as ``env_variants``) is exported; the export records the keys; the
controller keeps the history the training wrapper kept: its actions on an episode equal the policy's own actions on
the :class:`FrameStack`-wrapped observations of that episode (and, through ``make_controller`` at a realism level,
on the ``NavigationFilterWrapper`` then ``FrameStack`` wrapped ones, as in training); ``reset(seed)`` clears it.
"""

from __future__ import annotations

import json
import warnings

import gymnasium as gym
import numpy as np
import pytest
import torch

from agents.common.history import FrameStack
from agents.export import AgentController, EnvMismatchWarning, check_agent, load_agent
from agents.training.train import run_dir_for
from leaderboard.suite.registry import make_controller
from uvdms_cli.main import main as uvdms
from uvdms_gym.realism.navigation import FilteredController, NavigationFilterWrapper

CIRCLE = "uvdms/CircleTrack-v1"
K = 3
M = 2  # the policy's own last actions (action_history)
STEPS = 25


@pytest.fixture(scope="module")
def memory_export(tmp_path_factory) -> tuple:
    """A DAgger run with frame_stack=3, the navigation filter and two realism levels, exported weights-only."""
    tmp = tmp_path_factory.mktemp("memory")
    argv = ["train", "--algo", "dagger", "--env", CIRCLE, "--env-kwargs", "case=random", "hydro_randomization=0.3"]
    argv += ["max_episode_steps=30", "--residual", "none", "--total-timesteps", "120", "--seed", "0"]
    argv += ["--hyperparams", "teacher=campc-privileged", f"frame_stack={K}", f"action_history={M}"]
    argv += ["navigation_filter=true"]
    argv += ["env_variants=[{realism: 2}, {realism: 3}]", "eval_freq=0", "checkpoint_freq=0", "batch_size=32"]
    argv += ["save_replay_buffer=false", "policy_kwargs={net_arch: [16]}", "--out", str(tmp / "runs"), "--no-progress"]
    assert uvdms(argv) == 0
    run_dir = run_dir_for(tmp / "runs", CIRCLE, "dagger", 0)
    export = tmp / "export"
    assert uvdms(["export-agent", str(run_dir), str(export), "--trust"]) == 0
    return run_dir, export


def _policy_action(agent: AgentController, stacked: np.ndarray) -> np.ndarray:
    """The policy's own deterministic action for a stacked observation (SB3's predict, not the fast actor)."""
    with torch.no_grad():
        action, _ = agent.policy.predict(agent.normalize(stacked), deterministic=True)
    return action


def test_the_export_records_the_memory_and_the_filter(memory_export):
    run_dir, export = memory_export
    doc = json.loads((export / "agent.json").read_text())
    assert (doc["frame_stack"], doc["navigation_filter"], doc["residual_base"]) == (K, True, None)
    assert doc["run_time"] == {
        "network_only": False,  # the navigation filter runs with the network
        "base": None,
        "safety_filter": False,
        "navigation_filter": True,
        "memory": {"observations": K, "actions": M},
        "obstacle_features": False,
        "tracking_features": False,
    }
    agent = load_agent(export)
    assert (agent.composition.frame_stack, agent.composition.action_history, agent.composition.navigation_filter) == (
        K,
        M,
        True,
    )
    size = gym.make(CIRCLE).observation_space.shape[0]
    assert agent.policy.observation_space.shape == (K * size + M * 18,)  # the memory, the policy's input
    assert agent.observation_space == gym.make(CIRCLE).observation_space  # one observation, what predict takes
    run_agent = load_agent(run_dir, trust=True)  # the run itself records the same composition
    assert run_agent.composition == agent.composition


def test_the_controller_acts_as_the_policy_on_frame_stacked_observations(memory_export):
    agent = load_agent(memory_export[1])
    env = gym.make(CIRCLE, case=2, max_episode_steps=STEPS)
    stacked_env = FrameStack(gym.make(CIRCLE, case=2, max_episode_steps=STEPS), K, M)
    firsts = []
    for _ in range(2):  # the same seed twice: reset(seed) restarts the history
        agent.reset(seed=7)
        obs, _ = env.reset(seed=7)
        stacked, _ = stacked_env.reset(seed=7)
        actions = []
        while True:
            action = agent.predict(obs)
            np.testing.assert_allclose(action, _policy_action(agent, stacked), rtol=1e-5, atol=1e-6)
            actions.append(action)
            obs, _, terminated, truncated, _ = env.step(action)
            stacked, *_ = stacked_env.step(action)
            if terminated or truncated:
                break
        assert len(actions) > K
        firsts.append(actions[0])
    np.testing.assert_array_equal(firsts[0], firsts[1])
    # without reset the history would still hold the last episode: the first action differs
    stale, _ = env.reset(seed=7)
    assert not np.allclose(agent.predict(stale), firsts[0])


def test_make_controller_feeds_the_filters_estimate_to_the_memory_as_in_training(memory_export):
    env = gym.make(CIRCLE, case=2, realism=2, max_episode_steps=STEPS)
    controller = make_controller(str(memory_export[1]), env)
    assert isinstance(controller, FilteredController) and isinstance(controller.controller, AgentController)
    agent = controller.controller
    measured = gym.make(CIRCLE, case=2, realism=2, max_episode_steps=STEPS)
    training_env = FrameStack(NavigationFilterWrapper(measured), K, M)
    controller.reset(seed=3)
    obs, info = env.reset(seed=3)
    stacked, _ = training_env.reset(seed=3)
    steps = 0
    while True:
        action = controller.predict(obs, info)
        np.testing.assert_allclose(action, _policy_action(agent, stacked), rtol=1e-5, atol=1e-6)
        obs, _, terminated, truncated, info = env.step(action)
        stacked, _, terminated_t, truncated_t, _ = training_env.step(action)
        assert (terminated, truncated) == (terminated_t, truncated_t)
        steps += 1
        if terminated or truncated:
            break
    assert steps > K


def test_a_stacked_agent_on_an_env_of_another_observation_size_is_refused_saying_so(memory_export):
    agent = load_agent(memory_export[1])
    env = gym.make("uvdms/CooperativeTransport-v1")
    size = env.observation_space.shape[0]
    message = rf"expects observations of shape \(80,\), the environment gives \({size},\) "
    message += rf"\(each of the {K} observations its memory holds\)"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EnvMismatchWarning)
        with pytest.raises(ValueError, match=message):
            check_agent(agent, env, "memory")
    check_agent(agent, gym.make(CIRCLE, realism=3))  # the stacked shape of its own env fits


def test_uvdms_evaluate_runs_the_agent_with_its_filter(memory_export, tmp_path):
    out = tmp_path / "eval.json"
    argv = ["evaluate", "--controller", str(memory_export[1]), "--env", CIRCLE, "--env-kwargs", "case=2", "realism=2"]
    assert uvdms([*argv, "--episodes", "1", "--max-episode-steps", "15", "--out", str(out), "--no-progress"]) == 0
    result = json.loads(out.read_text())
    assert result["meta"]["controller_settings"]["class"] == "FilteredController"
    assert 1 <= result["summary"]["steps"] <= 15
