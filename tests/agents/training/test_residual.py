"""Residual agents and the training-time safety filter (uvdms_gym/residual/ and its wiring).

* The training wrapper sends ``clip(a_base + s a, -1, 1)`` with ``a_base`` an independently computed MPC action,
  and the policy observes ``[obs; a_base]``.
* On the same episode the training wrappers (residual, then filter) and the evaluation composition
  (``SafetyFilter(ResidualController(...))``) send the same actions, bit for bit.
* ``uvdms train --residual mpc --residual-scale 0.2`` -> ``uvdms export-agent`` -> ``uvdms evaluate`` composes the
  base from the export's record alone; with the policy's output layer zeroed the evaluation is plain ``mpc``,
  action for action. ``--resume`` keeps the composition.
* The factories build in hybrid vector-env workers; bad bases, scales and ``python -m agents.training.train`` are
  refused with clear errors.
"""

from __future__ import annotations

import json
import pickle
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml

from agents.common.envs import EnvFactory, make_vec_env
from agents.config import ConfigError, parse_entry
from agents.export.weights import export_controller, load_weights_only
from agents.training.train import main as agents_train_main
from agents.training.train import run_dir_for
from baselines.controllers import make_baseline
from baselines.safety.filter import SafetyFilter
from leaderboard.running.evaluate import evaluate
from leaderboard.suite.entries import resolve_entries
from leaderboard.suite.registry import (
    BaselineFactory,
    SafetyFilterFactory,
    make_controller,
    with_safety_filter,
)
from uvdms_cli.main import main as uvdms
from uvdms_gym.evaluation import run_episode
from uvdms_gym.residual import (
    ActionComposition,
    FilteredAction,
    ResidualAction,
    ResidualController,
    residual_observation,
)

CIRCLE = "uvdms/CircleTrack-v0"
SCALE = 0.2
OBS_DIM = 80
ACTION_DIM = 18
SEED = 7


class Recorder(gym.Wrapper):
    """Records every action the raw environment receives and the observation/info it returns."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.actions: list[np.ndarray] = []
        self.outputs: list[tuple[np.ndarray, dict]] = []

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self.actions, self.outputs = [], [(obs, info)]
        return obs, info

    def step(self, action):
        self.actions.append(np.array(action, copy=True))
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.outputs.append((obs, info))
        return obs, reward, terminated, truncated, info


class LinearPolicy:
    """A deterministic stand-in for a trained residual policy: ``tanh(W [obs; a_base])``, reading ``a_base``."""

    def __init__(self, seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        self.w = rng.normal(0.0, 0.3, (ACTION_DIM, OBS_DIM + ACTION_DIM)).astype(np.float32)
        self.w[:, OBS_DIM:] += 3.0 * np.eye(ACTION_DIM, dtype=np.float32)  # strongly follows the base's action
        self.seen: list[np.ndarray] = []

    def reset(self, seed: int | None = None) -> None:
        self.seen = []

    def predict(self, obs: np.ndarray, info: dict | None = None) -> np.ndarray:
        assert obs.shape == (OBS_DIM + ACTION_DIM,) and obs.dtype == np.float32
        self.seen.append(obs.copy())
        return np.tanh(self.w @ obs).astype(np.float32)


def _circle(steps: int, case: int = 1) -> gym.Env:
    return gym.make(CIRCLE, case=case, max_episode_steps=steps)


# ------------------------------------------------------------------------------------------------------
# The composition itself
# ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("scale", [SCALE, 1.0])
def test_wrapper_sends_the_clipped_sum_of_an_independent_base_and_the_scaled_action(scale):
    steps = 30
    recorder = Recorder(_circle(steps))
    wrapped = ResidualAction(recorder, BaselineFactory("mpc"), scale)
    reference = make_baseline("mpc", recorder)  # the same baseline, built and driven independently
    assert wrapped.observation_space.shape == (OBS_DIM + ACTION_DIM,)
    rng = np.random.default_rng(0)
    obs, _ = wrapped.reset(seed=SEED)
    reference.reset(SEED)
    clipped_steps = 0
    for k in range(steps):
        raw_obs, raw_info = recorder.outputs[k]
        base = reference.predict(raw_obs, raw_info)
        np.testing.assert_array_equal(obs, np.concatenate([raw_obs, base]))  # the policy sees [obs; a_base]
        action = rng.choice([-1.0, 1.0], ACTION_DIM).astype(np.float32)  # large enough to saturate at scale 1
        obs, _, terminated, truncated, info = wrapped.step(action)
        raw = base.astype(np.float64) + scale * action.astype(np.float64)
        expected = np.clip(raw, -1.0, 1.0)
        np.testing.assert_array_equal(recorder.actions[k], expected.astype(np.float32))
        assert info["residual_clipped"] == bool(np.any(expected != raw))
        np.testing.assert_array_equal(info["residual_base_action"], base)
        clipped_steps += info["residual_clipped"]
        if terminated or truncated:
            break
    assert k > 10, "the episode ended too early to say anything"
    if scale == 1.0:
        assert clipped_steps > 0  # the clip is exercised (at 0.2 too: the MPC's command sits on its box at times)


def test_residual_penalty_adds_its_term_to_the_environment_reward_and_changes_nothing_else():
    """reward = env reward - penalty * |a|^2 / 18, reported as reward_residual; the actions sent are unchanged."""
    steps, penalty = 12, 0.7
    plain_recorder, shaped_recorder = Recorder(_circle(steps)), Recorder(_circle(steps))
    plain = ResidualAction(plain_recorder, BaselineFactory("mpc"), SCALE)
    shaped = ResidualAction(shaped_recorder, BaselineFactory("mpc"), SCALE, penalty=penalty)
    plain.reset(seed=SEED)
    shaped.reset(seed=SEED)
    rng = np.random.default_rng(3)
    for _ in range(steps):
        action = rng.uniform(-1.0, 1.0, ACTION_DIM).astype(np.float32)
        _, r_plain, *_, info_plain = plain.step(action)
        _, r_shaped, *_, info = shaped.step(action)
        expected_term = -penalty * sum(float(x) ** 2 for x in action) / ACTION_DIM  # elementwise, independently
        assert "reward_residual" not in info_plain
        assert info["reward_residual"] == pytest.approx(expected_term, rel=1e-12)
        assert r_shaped == pytest.approx(r_plain + expected_term, rel=1e-12, abs=1e-12)
        np.testing.assert_array_equal(shaped_recorder.actions[-1], plain_recorder.actions[-1])
    for bad in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="residual_penalty must be a finite number >= 0"):
            ResidualAction(_circle(5), BaselineFactory("mpc"), SCALE, penalty=bad)


def test_training_wrappers_and_evaluation_controller_send_identical_actions():
    """Residual then filter: the wrappers of training and SafetyFilter(ResidualController) of evaluation."""
    steps = 110  # plain mpc reaches the frame in Case 1 after about 70 steps: the filter must act
    train_recorder = Recorder(_circle(steps))
    train_env = ResidualAction(FilteredAction(train_recorder, SafetyFilterFactory()), BaselineFactory("mpc"), SCALE)
    policy = LinearPolicy()
    obs, _ = train_env.reset(seed=SEED)
    filter_active = 0
    while True:
        obs, _, terminated, truncated, info = train_env.step(policy.predict(obs))
        filter_active += info["filter_active"]
        if terminated or truncated:
            break
    train_seen = policy.seen

    eval_recorder = Recorder(_circle(steps))
    controller = with_safety_filter(
        ResidualController(make_baseline("mpc", eval_recorder), policy, SCALE), eval_recorder
    )
    run_episode(eval_recorder, controller, SEED)
    assert len(eval_recorder.actions) == len(train_recorder.actions) > 60
    for k, (a_train, a_eval) in enumerate(zip(train_recorder.actions, eval_recorder.actions, strict=True)):
        np.testing.assert_array_equal(a_train, a_eval, err_msg=f"step {k}")
    for o_train, o_eval in zip(train_seen, policy.seen, strict=True):  # the policy saw the same [obs; a_base]
        np.testing.assert_array_equal(o_train, o_eval)
    assert filter_active > 0, "the filter never changed an action: the comparison did not cover it"


def test_factories_pickle_and_build_the_residual_in_hybrid_workers():
    factory = EnvFactory(
        CIRCLE,
        {"case": 2},
        max_episode_steps=5,
        scalar_info=True,
        base_factory=BaselineFactory("campc"),
        residual_scale=SCALE,
        filter_factory=SafetyFilterFactory(),
    )
    assert pickle.loads(pickle.dumps(factory)) == factory  # plain data, classes by reference
    venv = make_vec_env([factory, factory], "hybrid")  # env 1 lives in a worker process
    try:
        venv.seed(SEED)
        obs = venv.reset()
        assert obs.shape == (2, OBS_DIM + ACTION_DIM)
        local = factory()
        try:
            local_obs, _ = local.reset(seed=SEED + 1)
        finally:
            local.close()
        np.testing.assert_array_equal(obs[1], local_obs)  # the worker built the same base and filter
        assert np.any(obs[1][OBS_DIM:] != 0.0)  # (campc commands a motion at the start)
        obs, _, _, infos = venv.step(np.zeros((2, ACTION_DIM), dtype=np.float32))
        assert obs.shape == (2, OBS_DIM + ACTION_DIM) and "residual_clipped" in infos[1]
        assert "residual_base_action" not in infos[1]  # arrays stay in the worker (ScalarInfo)
    finally:
        venv.close()


# ------------------------------------------------------------------------------------------------------
# uvdms train -> export-agent -> evaluate
# ------------------------------------------------------------------------------------------------------
TINY_SAC = [
    "learning_starts=50",
    "batch_size=32",
    "eval_freq=100",
    "n_eval_episodes=1",
    "checkpoint_freq=0",
    "save_replay_buffer=false",
    "policy_kwargs={net_arch: [16]}",
]
TRAIN_STEPS = 200
EPISODE_STEPS = 20


@pytest.fixture(scope="module")
def residual_export(tmp_path_factory) -> tuple[Path, Path]:
    """A tiny ``uvdms train --residual mpc`` run and its weights-only export."""
    root = tmp_path_factory.mktemp("residual")
    argv = [
        "train",
        "--algo",
        "sac",
        "--env",
        CIRCLE,
        "--env-kwargs",
        "case=1",
        f"max_episode_steps={EPISODE_STEPS}",
        "--residual",
        "mpc",
        "--residual-scale",
        str(SCALE),
        "--total-timesteps",
        str(TRAIN_STEPS),
        "--hyperparams",
        *TINY_SAC,
        "--out",
        str(root / "runs"),
        "--no-progress",
    ]
    assert uvdms(argv) == 0
    run_dir = run_dir_for(root / "runs", CIRCLE, "sac", 0)
    assert uvdms(["export-agent", str(run_dir), str(root / "export"), "--trust"]) == 0
    return run_dir, root / "export"


def test_train_records_the_residual_and_evaluate_composes_it(residual_export, tmp_path, capsys):
    run_dir, export = residual_export
    config = yaml.safe_load((run_dir / "config.yml").read_text())["config"]
    assert (config["residual_base"], config["residual_scale"], config["safety_filter"]) == ("mpc", SCALE, False)
    segment = json.loads((run_dir / "meta.json").read_text())["segments"][0]
    assert segment["action_composition"]["residual_base"] == "mpc"
    assert segment["command"].startswith("uvdms train ") and "--residual mpc" in segment["command"]
    doc = json.loads((export / "agent.json").read_text())
    assert (doc["residual_base"], doc["residual_scale"], doc["safety_filter"]) == ("mpc", SCALE, False)
    assert doc["observation_space"]["shape"] == [OBS_DIM + ACTION_DIM]

    out = tmp_path / "eval.json"
    capsys.readouterr()
    argv = ["evaluate", "--controller", str(export), "--env", CIRCLE, "--env-kwargs", "case=1"]
    argv += [f"max_episode_steps={EPISODE_STEPS}", "--episodes", "1", "--out", str(out), "--no-progress"]
    assert uvdms(argv) == 0, capsys.readouterr().err
    result = json.loads(out.read_text())
    assert result["summary"]["steps"] == EPISODE_STEPS
    assert result["meta"]["controller_settings"]["class"] == "ResidualController"
    assert result["episodes"][0]["qp_slack_max"] is not None  # the base's QP record reaches the metrics

    entry = resolve_entries([str(export)])[0]
    assert entry.name == "residual-mpc-export" and entry.residual_base == "mpc" and not entry.safety_filter


def test_a_zero_residual_evaluates_as_plain_mpc_action_for_action(residual_export, tmp_path):
    _, export = residual_export
    agent = load_weights_only(export)
    with torch.no_grad():  # SAC's deterministic action is tanh(mu(latent)): zero mu, zero residual
        agent.policy.actor.mu.weight.zero_()
        agent.policy.actor.mu.bias.zero_()
    zero = export_controller(agent, tmp_path / "zero")
    kwargs = {"case": 1, "max_episode_steps": 40}
    residual = evaluate(str(zero), CIRCLE, kwargs, episodes=1, seed=SEED, save_trajectory=True, progress=False)
    plain = evaluate("mpc", CIRCLE, kwargs, episodes=1, seed=SEED, save_trajectory=True, progress=False)
    a_res = residual["episodes"][0]["trajectory"]["action"]
    a_mpc = plain["episodes"][0]["trajectory"]["action"]
    assert len(a_res) == len(a_mpc) == 41
    assert a_res == a_mpc
    assert residual["episodes"][0]["rmse_pos"] == plain["episodes"][0]["rmse_pos"]
    assert np.any(np.abs(np.array(a_mpc)) > 0.01)  # (the base does command a motion)


def test_resume_keeps_the_residual_and_refuses_to_change_it(residual_export, capsys):
    run_dir, _ = residual_export
    capsys.readouterr()
    changed = ["train", "--resume", str(run_dir), "--residual", "campc", "--total-timesteps", "20", "--no-progress"]
    assert uvdms(changed) == 2
    assert "residual_base cannot change" in capsys.readouterr().err
    with pytest.warns(UserWarning, match="no saved replay buffer"):  # (the tiny run saves none)
        assert uvdms(["train", "--resume", str(run_dir), "--total-timesteps", "20", "--no-progress"]) == 0
    meta = json.loads((run_dir / "meta.json").read_text())
    assert meta["segments"][-1]["status"] == "completed"
    assert meta["segments"][-1]["action_composition"]["residual_base"] == "mpc"
    assert meta["segments"][-1]["command"].startswith("uvdms train --resume")
    assert agents_train_main(["--resume", str(run_dir), "--total-timesteps", "20", "--no-progress"]) == 2
    assert "uvdms train" in capsys.readouterr().err  # python -m agents.training.train cannot build the base


def test_an_export_trained_with_the_filter_is_filtered_once(residual_export, tmp_path):
    _, export = residual_export
    agent = load_weights_only(export)
    agent.composition = ActionComposition("mpc", SCALE, safety_filter=True)
    filtered = export_controller(agent, tmp_path / "filtered")
    assert json.loads((filtered / "agent.json").read_text())["safety_filter"] is True
    env = _circle(5)
    try:
        controller = make_controller(str(filtered), env)
        assert isinstance(controller, SafetyFilter) and isinstance(controller.controller, ResidualController)
        assert with_safety_filter(controller, env) is controller  # +filter / --safety-filter add nothing more
    finally:
        env.close()
    entries = resolve_entries([str(filtered), f"{filtered}+filter"])
    assert [(e.name, e.safety_filter) for e in entries] == [("residual-mpc-filtered+filter", True)]


def test_uvdms_train_safety_filter_alone_is_recorded_and_evaluated_filtered(tmp_path):
    argv = ["train", "--algo", "sac", "--env", CIRCLE, "--env-kwargs", "case=1", f"max_episode_steps={EPISODE_STEPS}"]
    argv += ["--safety-filter", "--total-timesteps", "100", "--hyperparams", *TINY_SAC, "--n-envs", "1"]
    assert uvdms([*argv, "--out", str(tmp_path / "runs"), "--no-progress"]) == 0
    run_dir = run_dir_for(tmp_path / "runs", CIRCLE, "sac", 0)
    record = json.loads((run_dir / "meta.json").read_text())["segments"][0]["action_composition"]
    assert record["safety_filter"] is True and record["residual_base"] is None
    assert record["filter_factory"] == "SafetyFilterFactory()"
    assert uvdms(["export-agent", str(run_dir), str(tmp_path / "sac"), "--trust"]) == 0
    assert json.loads((tmp_path / "sac" / "agent.json").read_text())["safety_filter"] is True
    env = _circle(5)
    try:
        controller = make_controller(str(tmp_path / "sac"), env)
        assert isinstance(controller, SafetyFilter) and type(controller.controller).__name__ == "AgentController"
    finally:
        env.close()
    assert [e.name for e in resolve_entries([str(tmp_path / "sac")])] == ["sac+filter"]


# ------------------------------------------------------------------------------------------------------
# Bad inputs
# ------------------------------------------------------------------------------------------------------
_ENTRY = {"n_timesteps": 10, "env_kwargs": {"action_mode": "velocity"}}


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({"residual_base": "mpc"}, r"residual_scale must be a number in \(0, 1\]"),
        ({"residual_base": "mpc", "residual_scale": 0.0}, r"residual_scale must be a number in \(0, 1\]"),
        ({"residual_base": "mpc", "residual_scale": 1.5}, r"residual_scale must be a number in \(0, 1\]"),
        ({"residual_scale": 0.2}, "residual_scale 0.2 is given without a residual_base"),
        (
            {"residual_base": "mpc", "residual_scale": 0.2, "env_kwargs": {"action_mode": "torque"}},
            "'residual_base' composes velocity commands, but env_kwargs has action_mode='torque'",
        ),
        ({"safety_filter": True, "env_kwargs": {"action_mode": "torque"}}, "'safety_filter' composes velocity"),
        (
            {"residual_base": "mpc", "residual_scale": 0.2, "residual_penalty": -1.0},
            "key 'residual_penalty' must be a finite number >= 0",
        ),
    ],
)
def test_bad_residual_configs_are_config_errors(extra, message):
    with pytest.raises(ConfigError, match=message):
        parse_entry({**_ENTRY, **extra}, "sac", source="test.yml", entry_name=CIRCLE)


def test_bad_bases_are_refused_by_name():
    with pytest.raises(ValueError, match=r"unknown residual base 'foo'.* one of mpc, campc"):
        BaselineFactory("foo")
    with pytest.raises(ValueError, match=r"'campc-di' is a torque-mode baseline.* mpc, campc"):
        BaselineFactory("campc-di")
    with pytest.raises(ValueError, match=r"residual_scale must be a number in \(0, 1\]"):
        ResidualController(LinearPolicy(), LinearPolicy(), 0.0)
    assert residual_observation(np.zeros(OBS_DIM, np.float32), np.ones(ACTION_DIM)).dtype == np.float32


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--residual", "campc-di", "--residual-scale", "0.2"], "'campc-di' is a torque-mode baseline"),
        (["--residual", "nope", "--residual-scale", "0.2"], "unknown residual base 'nope'"),
        (["--residual", "mpc", "--residual-scale", "0"], r"residual_scale must be a number in \(0, 1\]"),
        (["--residual", "mpc"], r"residual_scale must be a number in \(0, 1\]"),
        (["--hyperparams", "residual_penalty=0.5"], "residual_penalty=0.5 shapes a residual agent's reward"),
    ],
)
def test_uvdms_train_refuses_bad_residuals_before_creating_a_run(flags, message, tmp_path, capsys):
    argv = ["train", "--algo", "sac", "--env", CIRCLE, "--out", str(tmp_path / "runs"), "--no-progress", *flags]
    assert uvdms(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("uvdms: error: ") and len(err.strip().splitlines()) == 1, err
    assert re.search(message, err), err
    assert not (tmp_path / "runs").exists()


def test_python_m_agents_train_refuses_a_residual_naming_uvdms_train(tmp_path, capsys):
    argv = ["--algo", "sac", "--env", CIRCLE, "--residual", "mpc", "--residual-scale", "0.2"]
    assert agents_train_main([*argv, "--out", str(tmp_path / "runs"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "a residual on 'mpc'" in err and "train it with `uvdms train`" in err
    assert not (tmp_path / "runs").exists()
    assert agents_train_main(["--algo", "sac", "--env", CIRCLE, "--safety-filter", "--out", str(tmp_path)]) == 2
    assert "the safety filter" in capsys.readouterr().err
