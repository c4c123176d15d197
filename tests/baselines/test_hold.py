"""The ``hold`` baseline: the zero velocity command, a named leaderboard entry outside the ``baselines`` token."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import uvdms_gym  # noqa: F401  (registers the ids)
from baselines.controllers import HoldStill, make_baseline
from leaderboard.suite.entries import resolve_entries
from leaderboard.suite.registry import RESIDUAL_BASES
from uvdms_gym.evaluation import run_episode


def test_hold_keeps_the_hands_where_they_start_and_the_error_is_the_reference_distance():
    env = gym.make("uvdms/CircleTrack-v1", case=1, max_episode_steps=40)
    try:
        controller = make_baseline("hold", env)
        assert isinstance(controller, HoldStill)
        _, info = env.reset(seed=3)
        y0 = info["y"].copy()
        for _ in range(40):
            action = controller.predict(None, info)
            assert action.dtype == np.float32 and not action.any()
            _, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        # zero velocity commands: the hands stay put to within the low-level controllers' settling
        assert np.max(np.abs(info["y"] - y0)) < 2e-3
        # so the tracking error is the mean distance of the hands' start positions to their current references
        e = (info["y_ref"] - y0).reshape(2, 3)
        assert info["tracking_error"] == pytest.approx(0.5 * np.linalg.norm(e, axis=1).sum(), abs=2e-3)
    finally:
        env.close()


def test_hold_on_transport_ends_by_the_error_rule_about_where_the_object_started():
    env = gym.make("uvdms/Transport-v1", goal="paper")
    try:
        result = run_episode(env, make_baseline("hold", env), seed=0)
    finally:
        env.close()
    assert result["contacts"] == 0 and not result["success"] and result["terminated"]
    assert result["final_pos_error"] > 2.0  # ended because the reference left the object 2 m behind
    assert result["steps"] < env.spec.max_episode_steps


def test_hold_is_velocity_only():
    env = gym.make("uvdms/CircleTrack-v1", action_mode="torque")
    try:
        with pytest.raises(ValueError, match="hold"):
            make_baseline("hold", env)
    finally:
        env.close()


def test_hold_is_named_explicitly_and_is_no_residual_base():
    names = [e.name for e in resolve_entries(["baselines"], agents_dir="/nonexistent")]
    assert "hold" not in names and {"mpc", "campc", "campc-di", "campc-nndi"} == set(names)
    (entry,) = resolve_entries(["hold"], agents_dir="/nonexistent")
    assert (entry.kind, entry.track, entry.env_id) == ("baseline", "velocity", None)
    assert "hold" not in RESIDUAL_BASES
