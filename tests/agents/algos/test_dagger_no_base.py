"""DAgger with no base: a distilled controller that outputs the whole command (``--residual none``).

* ``TeacherLabel`` reports, at every step, the teacher's command clipped to the action box at the state the
  action was taken in, computed from independently recorded teacher outputs; the teacher never acts (the
  trajectory equals the bare environment's under the same actions).
* ``TeacherFactory`` builds a baseline of either action mode, or a trained agent composed as it was trained.
* ``uvdms train --algo dagger --residual none`` -> ``export-agent`` -> ``evaluate``: the export is the network
  alone (no base, no filter, no teacher); its misconfigurations are among the one-line errors of
  tests/agents/algos/test_dagger.py.
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
import yaml

from agents.training.train import run_dir_for
from leaderboard.suite.registry import TeacherFactory
from uvdms_cli.main import main as uvdms
from uvdms_gym.residual import TEACHER_KEY, ResidualController, TeacherLabel, teacher_action

CIRCLE = "uvdms/CircleTrack-v1"
ACTION_DIM = 18


class _Scripted:
    """A teacher whose command is a fixed function of the observation, beyond the box at times; records it."""

    action_mode = "velocity"

    def __init__(self) -> None:
        self.sent: list[np.ndarray] = []
        self.seeds: list[int | None] = []

    def reset(self, seed: int | None = None) -> None:
        self.seeds.append(seed)

    def predict(self, obs: np.ndarray, info: dict) -> np.ndarray:
        action = (4.0 * np.asarray(obs[:ACTION_DIM], dtype=np.float64)).astype(np.float32)  # |a| > 1 often
        self.sent.append(action)
        return action


def test_the_label_is_the_teachers_command_clipped_to_the_box():
    raw = np.random.default_rng(0).normal(0.0, 2.0, (100, ACTION_DIM))
    for a in raw:
        label = teacher_action(a)
        assert label.dtype == np.float32
        np.testing.assert_array_equal(label, np.clip(a, -1.0, 1.0).astype(np.float32))


def test_the_wrapper_labels_each_step_with_the_teachers_command_and_never_lets_it_act():
    teacher = _Scripted()
    wrapped = TeacherLabel(gym.make(CIRCLE, case=2, max_episode_steps=20), lambda env: teacher)
    bare = gym.make(CIRCLE, case=2, max_episode_steps=20)
    obs, _ = wrapped.reset(seed=4)
    obs_bare, _ = bare.reset(seed=4)
    assert teacher.seeds == [4]
    np.testing.assert_array_equal(obs, obs_bare)
    rng = np.random.default_rng(1)
    clipped_somewhere = False
    for k in range(20):
        action = rng.uniform(-0.2, 0.2, ACTION_DIM).astype(np.float32)
        obs, reward, terminated, truncated, info = wrapped.step(action)
        obs_bare, reward_bare, *_ = bare.step(action)
        # the label of step k belongs to the state the action was taken in: the teacher's k-th command, clipped
        np.testing.assert_array_equal(info[TEACHER_KEY], np.clip(teacher.sent[k], -1.0, 1.0))
        clipped_somewhere |= bool(np.any(np.abs(teacher.sent[k]) > 1.0))
        np.testing.assert_array_equal(obs, obs_bare)  # the teacher never acts
        assert reward == reward_bare
        if terminated or truncated:
            break
    assert k == 19 and clipped_somewhere


def test_the_wrapper_refuses_a_teacher_in_the_other_action_mode():
    class _Torque(_Scripted):
        action_mode = "torque"

    with pytest.raises(
        ValueError, match=r"'teacher _Torque' needs action_mode='torque' but the environment has action_mode='velocity'"
    ):
        TeacherLabel(gym.make(CIRCLE, case=2), lambda env: _Torque())


def test_a_teacher_is_a_baseline_of_either_mode_or_a_trained_agent():
    assert TeacherFactory("campc").action_mode == "velocity"
    assert TeacherFactory("campc-nndi").action_mode == "torque"
    torque_env = gym.make(CIRCLE, case=2, action_mode="torque")
    assert TeacherFactory("campc-nndi", collision_margin=0.02)(torque_env).mpc.config.d1 == pytest.approx(0.07)
    shipped = TeacherFactory("residual-mpc-sac-transport-v1/seed_0")
    assert shipped.action_mode == "velocity"
    assert isinstance(shipped(gym.make("uvdms/Transport-v1")), ResidualController)
    with pytest.raises(ValueError, match="unknown teacher 'nope'"):
        TeacherFactory("nope")
    with pytest.raises(ValueError, match="'mpc' has none"):
        TeacherFactory("mpc", collision_margin=0.01)


def test_uvdms_train_dagger_with_no_base_export_and_evaluate(tmp_path, capsys):
    argv = ["train", "--algo", "dagger", "--env", CIRCLE, "--env-kwargs", "case=2", "max_episode_steps=30"]
    argv += ["--residual", "none", "--total-timesteps", "120", "--seed", "0", "--hyperparams", "batch_size=32"]
    argv += ["eval_freq=100", "n_eval_episodes=1", "checkpoint_freq=0", "save_replay_buffer=false"]
    argv += ["policy_kwargs={net_arch: [16]}", "--out", str(tmp_path / "runs"), "--no-progress"]
    assert uvdms(argv) == 0, capsys.readouterr().err
    run_dir = run_dir_for(tmp_path / "runs", CIRCLE, "dagger", 0)
    config = yaml.safe_load((run_dir / "config.yml").read_text())["config"]
    assert config["teacher"] == "campc" and config.get("residual_base") is None
    segment = json.loads((run_dir / "meta.json").read_text())["segments"][0]
    assert segment["action_composition"]["teacher_factory"] == repr(TeacherFactory("campc"))
    assert segment["action_composition"]["base_factory"] is None
    assert segment["command"].startswith("uvdms train ")  # a teacher needs the composition layer
    export = tmp_path / "export"
    assert uvdms(["export-agent", str(run_dir), str(export), "--trust"]) == 0
    doc = json.loads((export / "agent.json").read_text())
    assert (doc["algo"], doc["residual_base"], doc["safety_filter"]) == ("dagger", None, False)
    assert doc["run_time"] == {
        "network_only": True,
        "base": None,
        "safety_filter": False,
        "navigation_filter": False,
        "memory": {"observations": 1, "actions": 0},
        "obstacle_features": False,
        "tracking_features": False,
    }
    assert (doc["navigation_filter"], doc["frame_stack"]) == (False, 1)
    out = tmp_path / "eval.json"
    argv = ["evaluate", "--controller", str(export), "--env", CIRCLE, "--env-kwargs", "case=2", "max_episode_steps=20"]
    assert uvdms([*argv, "--episodes", "1", "--out", str(out), "--no-progress"]) == 0, capsys.readouterr().err
    result = json.loads(out.read_text())
    assert result["meta"]["controller_settings"]["class"] == "AgentController"  # the network alone
    assert 1 <= result["summary"]["steps"] <= 20


def test_resume_accepts_residual_none_for_a_run_without_a_base(tmp_path, capsys):
    argv = ["train", "--algo", "dagger", "--env", CIRCLE, "--env-kwargs", "case=2", "max_episode_steps=20"]
    argv += ["--residual", "none", "--total-timesteps", "40", "--seed", "1", "--hyperparams", "batch_size=16"]
    argv += ["eval_freq=0", "checkpoint_freq=0", "policy_kwargs={net_arch: [8]}", "--out", str(tmp_path / "runs")]
    assert uvdms([*argv, "--no-progress"]) == 0, capsys.readouterr().err
    run_dir = run_dir_for(tmp_path / "runs", CIRCLE, "dagger", 1)
    resume = ["train", "--resume", str(run_dir), "--total-timesteps", "20", "--no-progress"]
    assert uvdms([*resume, "--residual", "none"]) == 0, capsys.readouterr().err
    assert uvdms([*resume, "--residual", "mpc"]) == 2
    assert "residual_base cannot change (None" in capsys.readouterr().err


def test_without_the_composition_layer_a_teacher_is_refused_by_name(tmp_path):
    from agents.config import ConfigError
    from agents.training.train import train

    with pytest.raises(ConfigError, match=r"needs the teacher 'campc', whose controllers live in the baselines"):
        train("dagger", CIRCLE, out_dir=tmp_path / "runs", progress=False)
    assert not (tmp_path / "runs").exists()
