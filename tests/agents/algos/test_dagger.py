"""DAgger on a residual (agents/algos/dagger.py) and the teacher's labels (uvdms_gym.residual.ResidualAction).

* ``teacher_residual`` is the residual output that makes the composed command the teacher's, clipped to the bound.
* ``ResidualAction`` with a teacher reports, at every step, the label of the state the action was taken in,
  computed from independently recorded base and teacher outputs; the teacher never acts.
* ``TeacherReplayBuffer`` keeps each observation with its own label; DAgger fitted on a toy problem recovers the
  teacher's map (checked against the map itself on fresh states); an env without labels is refused by name.
* ``uvdms train --algo dagger --residual mpc`` -> ``export-agent`` -> ``evaluate``: the export is mpc plus the
  network, with no teacher in it; misconfigurations are one-line errors before a run directory exists.
"""

from __future__ import annotations

import json
import re

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml
from gymnasium import spaces

from agents.algos.dagger import TEACHER_INFO_KEY, DAgger, TeacherReplayBuffer
from agents.common.wrappers import KEPT_ARRAYS, ScalarInfo
from agents.training.train import run_dir_for
from leaderboard.suite.registry import BaselineFactory, TeacherFactory
from uvdms_cli.main import main as uvdms
from uvdms_gym.physics.params import D1, D2
from uvdms_gym.residual import TEACHER_KEY, ResidualAction, compose_residual, teacher_residual

CIRCLE = "uvdms/CircleTrack-v1"
SCALE = 0.5
ACTION_DIM = 18


def test_the_label_key_is_spelled_alike_everywhere():
    assert TEACHER_INFO_KEY == TEACHER_KEY and TEACHER_KEY in KEPT_ARRAYS


def test_the_label_composes_to_the_teachers_command_within_the_bound():
    rng = np.random.default_rng(0)
    base = rng.uniform(-0.8, 0.8, (200, ACTION_DIM))
    teacher = np.clip(base + rng.normal(0.0, 0.4, base.shape), -1.0, 1.0)
    for b, t in zip(base, teacher, strict=True):
        label = teacher_residual(t, b, SCALE)
        assert label.dtype == np.float32 and np.all(np.abs(label) <= 1.0)
        sent, _ = compose_residual(b, label, SCALE)
        within = np.abs(t - b) <= SCALE
        np.testing.assert_allclose(sent[within], t[within], atol=1e-6)  # exactly the teacher's, up to float32
        np.testing.assert_allclose(sent[~within], np.clip(b + SCALE * np.sign(t - b), -1, 1)[~within], atol=1e-6)


class _Scripted:
    """A controller whose action is a fixed function of the observation; records what it saw and sent."""

    def __init__(self, weight: float) -> None:
        self.weight = weight
        self.sent: list[np.ndarray] = []
        self.seeds: list[int | None] = []

    def reset(self, seed: int | None = None) -> None:
        self.seeds.append(seed)

    def predict(self, obs: np.ndarray, info: dict) -> np.ndarray:
        action = np.tanh(self.weight * np.asarray(obs[:ACTION_DIM], dtype=np.float64)).astype(np.float32)
        self.sent.append(action)
        return action


def test_the_wrapper_labels_each_step_with_the_teachers_correction_at_the_state_acted_in():
    base, teacher = _Scripted(0.5), _Scripted(3.0)
    wrapped = ResidualAction(
        gym.make(CIRCLE, case=2, max_episode_steps=25), lambda env: base, SCALE, teacher_factory=lambda env: teacher
    )
    wrapped.reset(seed=3)
    assert base.seeds == teacher.seeds == [3]
    rng = np.random.default_rng(1)
    for k in range(25):
        action = rng.uniform(-1.0, 1.0, ACTION_DIM).astype(np.float32)
        _, _, terminated, truncated, info = wrapped.step(action)
        # the label of step k belongs to the state the action was taken in: the k-th base and teacher outputs
        np.testing.assert_array_equal(info[TEACHER_KEY], teacher_residual(teacher.sent[k], base.sent[k], SCALE))
        # the teacher never acts: the command sent is the base's plus the agent's residual
        np.testing.assert_array_equal(info["residual_action"], compose_residual(base.sent[k], action, SCALE)[0])
        assert len(teacher.sent) == len(base.sent) == k + 2
        if terminated or truncated:
            break
    assert k == 24
    scalar = ScalarInfo(wrapped)
    scalar.reset(seed=3)
    _, _, _, _, info = scalar.step(np.zeros(ACTION_DIM, np.float32))
    assert TEACHER_KEY in info and "eta" not in info  # the label survives the training envs' info filter


def test_a_teacher_margin_moves_both_collision_thresholds_of_the_teacher_only():
    env = gym.make(CIRCLE, case=1)
    shifted = BaselineFactory("campc", collision_margin=0.01)(env).mpc.config
    registered = BaselineFactory("campc")(env).mpc.config
    assert (registered.d1, registered.d2) == (D1, D2)
    assert (shifted.d1, shifted.d2) == pytest.approx((D1 + 0.01, D2 + 0.01), abs=1e-15)
    with pytest.raises(ValueError, match="'mpc' has none"):
        BaselineFactory("mpc", collision_margin=0.01)


def test_a_teacher_outer_margin_moves_the_outer_obstacle_thresholds_only_where_there_are_obstacles():
    obstacles = gym.make("uvdms/TransportObstacles-v1", obstacles="random")
    registered = TeacherFactory("campc")(obstacles).mpc.config
    shifted = TeacherFactory("campc", collision_margin=0.02, outer_margin=0.05)(obstacles).mpc.config
    assert (shifted.outer_d1, shifted.outer_d2) == pytest.approx(
        (registered.outer_d1 + 0.05, registered.outer_d2 + 0.05), abs=1e-15
    )
    assert (shifted.d1, shifted.d2) == pytest.approx((D1 + 0.02, D2 + 0.02), abs=1e-15)
    assert shifted.outer_rows == registered.outer_rows > 0
    circle = TeacherFactory("campc", outer_margin=0.05)(gym.make(CIRCLE, case=1)).mpc.config
    assert (circle.d1, circle.d2, circle.outer_rows) == (D1, D2, 0)  # no obstacles: the registered CAMPC
    with pytest.raises(ValueError, match="'mpc' has none"):
        TeacherFactory("mpc", outer_margin=0.05)


@pytest.mark.parametrize("fraction", [0.0, 0.25, 1.0])
def test_the_hard_example_loss_adds_the_mean_of_the_hardest_samples(fraction):
    model = DAgger("MlpPolicy", _ToyTeacherEnv(), seed=0, hard_fraction=fraction, policy_kwargs={"net_arch": [8]})
    rng = np.random.default_rng(2)
    actions, labels = rng.normal(size=(40, 2)), rng.normal(size=(40, 2))
    per_sample = np.mean((actions - labels) ** 2, axis=1)
    n_hard = int(fraction * 40)
    expected = per_sample.mean() + (np.sort(per_sample)[::-1][:n_hard].mean() if n_hard else 0.0)
    loss = model.imitation_loss(torch.as_tensor(actions), torch.as_tensor(labels))
    assert float(loss) == pytest.approx(expected, rel=1e-12)


class _ToyTeacherEnv(gym.Env):
    """2-D states drawn at random each step; the label is a fixed nonlinear map of the state the action saw."""

    observation_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
    action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)

    def __init__(self) -> None:
        self._obs = np.zeros(2, np.float32)

    @staticmethod
    def label(obs: np.ndarray) -> np.ndarray:
        return np.array([np.tanh(2.0 * obs[0] - obs[1]), 0.8 * np.sin(3.0 * obs[1])], dtype=np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self._obs = self.np_random.uniform(-1.0, 1.0, 2).astype(np.float32)
        return self._obs, {}

    def step(self, action):
        info = {TEACHER_INFO_KEY: self.label(self._obs)}
        self._obs = self.np_random.uniform(-1.0, 1.0, 2).astype(np.float32)
        return self._obs, 0.0, False, False, info


@pytest.mark.slow
def test_dagger_fits_the_teachers_map_on_a_toy_problem():
    kwargs = {"learning_rate": 3e-3, "batch_size": 64, "policy_kwargs": {"net_arch": [32, 32]}}
    model = DAgger("MlpPolicy", _ToyTeacherEnv(), seed=0, teacher="toy", **kwargs)
    model.learn(2000)
    states = np.random.default_rng(5).uniform(-1.0, 1.0, (500, 2)).astype(np.float32)
    labels = np.array([_ToyTeacherEnv.label(s) for s in states])
    predicted, _ = model.predict(states, deterministic=True)
    error = float(np.mean((predicted - labels) ** 2))
    assert error < 0.05 * float(np.mean(labels**2)), error  # the untrained actor is at ~1x
    buffer = model.replay_buffer
    n = buffer.pos
    stored = np.array([_ToyTeacherEnv.label(o) for o in buffer.observations[:n, 0]])
    np.testing.assert_allclose(buffer.labels[:n, 0], stored, atol=1e-6)  # each observation with its own label


def test_dagger_refuses_an_env_without_labels():
    model = DAgger("MlpPolicy", "Pendulum-v1", seed=0)
    with pytest.raises(ValueError, match=r"DAgger needs the teacher's label in info\['teacher_residual'\]"):
        model.learn(5)
    with pytest.raises(ValueError, match="TeacherReplayBuffer"):
        DAgger("MlpPolicy", "Pendulum-v1", replay_buffer_class=TeacherReplayBuffer.__mro__[1])


def test_uvdms_train_dagger_export_and_evaluate(tmp_path, capsys):
    steps = 150
    argv = ["train", "--algo", "dagger", "--env", CIRCLE, "--env-kwargs", "case=2", "max_episode_steps=30"]
    argv += ["--residual", "mpc", "--residual-scale", str(SCALE), "--total-timesteps", str(steps), "--seed", "0"]
    argv += ["--hyperparams", "batch_size=32", "eval_freq=100", "n_eval_episodes=1", "checkpoint_freq=0"]
    argv += ["save_replay_buffer=false", "policy_kwargs={net_arch: [16]}", "--out", str(tmp_path / "runs")]
    assert uvdms([*argv, "--no-progress"]) == 0, capsys.readouterr().err
    run_dir = run_dir_for(tmp_path / "runs", CIRCLE, "dagger", 0)
    config = yaml.safe_load((run_dir / "config.yml").read_text())["config"]
    assert config["teacher"] == "campc" and config["residual_base"] == "mpc"
    composition = json.loads((run_dir / "meta.json").read_text())["segments"][0]["action_composition"]
    assert composition["teacher_factory"] == repr(TeacherFactory("campc"))
    export = tmp_path / "export"
    assert uvdms(["export-agent", str(run_dir), str(export), "--trust"]) == 0
    doc = json.loads((export / "agent.json").read_text())
    assert (doc["algo"], doc["residual_base"], doc["residual_scale"]) == ("dagger", "mpc", SCALE)
    assert "campc" not in json.dumps({k: v for k, v in doc.items() if k != "policy_kwargs"})  # no teacher at run time
    out = tmp_path / "eval.json"
    argv = ["evaluate", "--controller", str(export), "--env", CIRCLE, "--env-kwargs", "case=2", "max_episode_steps=20"]
    assert uvdms([*argv, "--episodes", "1", "--out", str(out), "--no-progress"]) == 0, capsys.readouterr().err
    result = json.loads(out.read_text())
    assert result["meta"]["controller_settings"]["class"] == "ResidualController"
    assert result["summary"]["steps"] == 20
    weights = torch.load(export / "policy.pt", weights_only=True)
    assert any(k.startswith("actor.") for k in weights)  # the trained actor is what the export carries


RESIDUAL = ["--residual", "mpc", "--residual-scale", "0.5"]


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        ([*RESIDUAL, "--residual-space", "nullspace"], r"residual_space='nullspace'"),
        ([*RESIDUAL, "--hyperparams", "action_scale=0.3"], r"action_scale=0.3"),
        ([*RESIDUAL, "--hyperparams", "teacher=nope"], r"dagger's teacher or base: unknown teacher 'nope'"),
        ([*RESIDUAL, "--hyperparams", "teacher=3"], r"key 'teacher': expected str, got int"),
        ([*RESIDUAL, "--hyperparams", "teacher_margin=-0.01"], r"teacher_margin must be a finite number >= 0"),
        ([*RESIDUAL, "--hyperparams", "teacher=mpc", "teacher_margin=0.01"], r"'mpc' has none \(use campc\)"),
        ([*RESIDUAL, "--hyperparams", "teacher_outer_margin=-1"], r"teacher_outer_margin must be a finite number >= 0"),
        ([*RESIDUAL, "--hyperparams", "hard_fraction=1.5"], r"hard_fraction must be a number in \[0, 1\], got 1.5"),
        ([*RESIDUAL, "--hyperparams", "evasion_weight=-1"], r"evasion_weight must be a finite number >= 0, got -1"),
        ([*RESIDUAL, "--hyperparams", "hold_weight=-2"], r"hold_weight must be a finite number >= 0, got -2"),
        # with no base (a distilled controller, tests/agents/algos/test_dagger_no_base.py)
        (["--residual", "none", "--residual-scale", "0.5"], r"residual_scale 0.5 is given without a residual_base"),
        (
            ["--env-kwargs", "action_mode=torque"],
            r"teacher 'campc' commands action_mode='velocity', but the training env has action_mode='torque'",
        ),
        (
            [*RESIDUAL, "--hyperparams", "teacher=campc-nndi"],
            r"teacher 'campc-nndi' commands joint torques, but a residual corrects a velocity command",
        ),
        (["--safety-filter"], r"the safety filter but no residual base"),
        (["--hyperparams", "teacher=nope"], r"dagger's teacher or base: unknown teacher 'nope'"),
    ],
)
def test_bad_dagger_configurations_are_one_line_errors(flags, message, tmp_path, capsys):
    argv = ["train", "--algo", "dagger", "--env", CIRCLE, "--out", str(tmp_path / "runs"), "--no-progress", *flags]
    assert uvdms(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("uvdms: error: ") and len(err.strip().splitlines()) == 1, err
    assert re.search(message, err), err
    assert not (tmp_path / "runs").exists()
