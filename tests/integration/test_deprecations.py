"""The deprecated aliases of release 0.2 (CHANGELOG.md): they still resolve, warn, and are the new objects."""

from __future__ import annotations

import importlib

import gymnasium as gym
import pytest

import uvdms_gym  # noqa: F401  (registers the environments)
from uvdms_gym import evaluation
from uvdms_gym.utils import io

MOVED_FROM_BASELINES_EVALUATE = {
    "run_episode": evaluation,
    "summarize": evaluation,
    "tracking_rmse": evaluation,
    "is_transport": evaluation,
    "controller_settings": evaluation,
    "EPISODE_KEYS": evaluation,
    "TRAJECTORY_KEYS": evaluation,
    "CIRCLE_SUCCESS_RMSE": evaluation,
    "write_json_atomic": io,
}


@pytest.mark.parametrize("name", sorted(MOVED_FROM_BASELINES_EVALUATE))
def test_baselines_evaluate_names_warn_and_are_the_new_objects(name):
    import baselines.evaluate as old

    with pytest.warns(DeprecationWarning, match=f"baselines.evaluate.{name} is deprecated"):
        value = getattr(old, name)
    assert value is getattr(MOVED_FROM_BASELINES_EVALUATE[name], name)


def test_from_import_of_a_moved_name_warns():
    with pytest.warns(DeprecationWarning, match="uvdms_gym.evaluation"):
        from baselines.evaluate import run_episode
    assert run_episode is evaluation.run_episode
    with pytest.raises(ImportError):
        from baselines.evaluate import no_such_name  # noqa: F401


def test_deprecated_evaluate_runs_a_baseline_and_refuses_agents(tmp_path):
    from baselines.evaluate import evaluate

    with pytest.warns(DeprecationWarning, match=r"leaderboard\.registry\.evaluate"):
        result = evaluate("campc", "uvdms/CircleTrack-v0", {"max_episode_steps": 3}, episodes=1, progress=False)
    assert result["meta"]["controller"] == "campc" and result["meta"]["env_kwargs"]["action_mode"] == "velocity"
    assert result["episodes"][0]["steps"] == 3
    with pytest.warns(DeprecationWarning), pytest.raises(ValueError, match=r"leaderboard\.registry\.evaluate"):
        evaluate(str(tmp_path), "uvdms/CircleTrack-v0", episodes=1, progress=False)


def test_controller_protocol_is_reexported_by_baselines():
    from baselines.controllers import Controller, make_controller

    assert Controller is evaluation.Controller
    env = gym.make("uvdms/CircleTrack-v0")
    try:
        with pytest.raises(ValueError, match=r"leaderboard\.registry\.make_controller"):
            make_controller("some/agent/path", env)
    finally:
        env.close()


def test_the_removed_cli_alias_is_gone():
    """``uvdms_gym.cli`` (deprecated in 0.2) was removed with the package's regrouping; the command is ``uvdms``."""
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("uvdms_gym.cli")
