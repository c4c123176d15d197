"""PPO-Lagrangian (agents/algos/ppo_lagrangian.py): the formulas, a problem where the budget binds, state, configs, CLI.

The small problem (:class:`CostlyPush`): one action ``a`` in [-1, 1] per step for ``HORIZON`` steps, reward ``a``,
cost ``a**2``. Unconstrained, the best policy pushes ``a = 1`` and pays ``HORIZON`` per episode; under the budget
``BUDGET`` the constrained optimum is ``E[a**2] = BUDGET / HORIZON``. The env keeps its own log of every finished
episode's cost, against which the trainer's multiplier updates are recomputed.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.buffers import RolloutBuffer
from stable_baselines3.common.callbacks import CallbackList
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecNormalize

from agents.algos.ppo_lagrangian import (
    HISTORY_FILE,
    CostActorCriticPolicy,
    LagrangianHistory,
    PPOLagrangian,
    dual_ascent,
    gae,
    lagrangian_advantages,
    read_history,
)
from agents.common.rollouts import RolloutVecEnv
from agents.config import ConfigError, load_config, validate_config_file
from agents.export import export_agent, load_agent, load_weights_only
from agents.training.train import latest_checkpoint, run_dir_for, train
from uvdms_cli.main import main as uvdms

REPO = Path(__file__).resolve().parents[3]
UVDMS = Path(sys.executable).with_name("uvdms")

HORIZON = 10
BUDGET = 2.5
LOOSE_BUDGET = 100.0  # above the most an episode can cost (HORIZON)
ROLLOUTS = 96
STEPS = ROLLOUTS * 2 * 64  # 2 envs x n_steps 64: whole rollouts
TAIL = 20  # rollouts averaged at the end of a run
TOY_ID = "lagtest/CostlyPush-v0"
SMALL = {
    "n_steps": 64,
    "batch_size": 64,
    "n_epochs": 4,
    "learning_rate": 1.0e-3,
    "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}, "log_std_init": -1.0},
}


class CostlyPush(gym.Env):
    """Reward ``a``, cost ``a**2``, ``HORIZON`` steps; observation ``t / HORIZON``; logs its episodes' costs.

    Args:
        truncate: End episodes by truncation (time limit) instead of termination.
    """

    observation_space = spaces.Box(0.0, 1.0, (1,), np.float32)
    action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, truncate: bool = False) -> None:
        self.truncate = truncate
        self.t = 0
        self.steps = 0
        self.episode_cost = 0.0
        self.log: list[tuple[int, float]] = []  # (steps of this env when the episode ended, its cost)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.t, self.episode_cost = 0, 0.0
        return np.zeros(1, np.float32), {}

    def step(self, action):
        a = float(np.clip(action[0], -1.0, 1.0))
        self.t += 1
        self.steps += 1
        cost = a * a
        self.episode_cost += cost
        end = self.t >= HORIZON
        if end:
            self.log.append((self.steps, self.episode_cost))
        obs = np.array([self.t / HORIZON], np.float32)
        return obs, a, end and not self.truncate, end and self.truncate, {"cost": cost}


gym.register(TOY_ID, entry_point=CostlyPush)


@pytest.fixture(autouse=True)
def one_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def _venv(n_envs: int = 2, **kwargs) -> DummyVecEnv:
    return DummyVecEnv([lambda: Monitor(CostlyPush(**kwargs)) for _ in range(n_envs)])


def _episode_logs(venv: VecEnv) -> list[list[tuple[int, float]]]:
    return venv.get_attr("log")  # (also from worker processes)


def _train_toy(tmp_path: Path, algo: type, name: str, steps: int = STEPS, parallel: bool = False, **kwargs):
    """A run on CostlyPush with reward normalisation on (the cost must still be the raw one).

    ``parallel``: the envs collect their parts of every rollout themselves (``--vec-env rollout``, env 1 in a
    worker process), else ``DummyVecEnv``.
    """
    envs = RolloutVecEnv([lambda: Monitor(CostlyPush()) for _ in range(2)]) if parallel else _venv()
    venv = VecNormalize(envs, norm_obs=False, norm_reward=True)
    model = algo("MlpPolicy", venv, seed=0, **{**SMALL, **kwargs})
    history = tmp_path / f"{name}.csv"
    model.learn(steps, callback=[LagrangianHistory(history)] if algo is PPOLagrangian else [])
    logs = _episode_logs(venv.venv)
    venv.close()
    return model, logs, (read_history(history) if algo is PPOLagrangian else None)


@pytest.fixture(scope="module")
def toy_runs(tmp_path_factory):
    """Unconstrained PPO, PPO-Lagrangian with a binding budget and with a loose one (same seed and settings)."""
    folder = tmp_path_factory.mktemp("toy")
    return {
        "ppo": _train_toy(folder, PPO, "ppo", normalize_advantage=True),
        "binding": _train_toy(folder, PPOLagrangian, "binding", cost_limit=BUDGET, lagrangian_lr=0.1),
        "loose": _train_toy(folder, PPOLagrangian, "loose", cost_limit=LOOSE_BUDGET, lagrangian_lr=0.1),
        "binding_parallel": _train_toy(
            folder, PPOLagrangian, "binding_parallel", parallel=True, cost_limit=BUDGET, lagrangian_lr=0.1
        ),
    }


def _tail_cost(logs: list[list[tuple[int, float]]], steps_per_env: int) -> float:
    """Mean episode cost of the episodes that ended in the last TAIL rollouts."""
    start = steps_per_env - TAIL * SMALL["n_steps"]
    return float(np.mean([cost for log in logs for steps, cost in log if steps > start]))


# ------------------------------------------------------------------------------------------------------
# The formulas
# ------------------------------------------------------------------------------------------------------
def test_dual_ascent_and_lagrangian_advantages():
    assert dual_ascent(0.5, 7.0, 5.0, 0.1) == pytest.approx(0.7)
    assert dual_ascent(0.5, 1.0, 5.0, 0.1) == pytest.approx(0.1)
    assert dual_ascent(0.1, 0.0, 5.0, 0.1) == 0.0  # projected onto lambda >= 0
    rng = np.random.default_rng(0)
    a_r, a_c = rng.normal(3.0, 2.0, (8, 2)), rng.normal(1.0, 0.5, (8, 2))
    expected = ((a_r - a_r.mean()) / a_r.std() - 2.0 * (a_c - a_c.mean())) / 3.0
    np.testing.assert_allclose(lagrangian_advantages(a_r, a_c, 2.0), expected, rtol=1e-5, atol=1e-6)


def test_gae_is_sb3s_rollout_buffer_formula():
    rng = np.random.default_rng(1)
    n_steps, n_envs = 12, 3
    rewards = rng.normal(size=(n_steps, n_envs)).astype(np.float32)
    values = rng.normal(size=(n_steps, n_envs)).astype(np.float32)
    starts = (rng.random((n_steps, n_envs)) < 0.2).astype(np.float32)
    last_values = rng.normal(size=n_envs).astype(np.float32)
    dones = np.array([True, False, False])
    buffer = RolloutBuffer(n_steps, CostlyPush.observation_space, CostlyPush.action_space, "cpu", 0.9, 0.97, n_envs)
    buffer.rewards[:], buffer.values[:], buffer.episode_starts[:] = rewards, values, starts
    buffer.compute_returns_and_advantage(torch.as_tensor(last_values), dones)
    advantages, returns = gae(rewards, values, starts, last_values, dones, 0.97, 0.9)
    np.testing.assert_allclose(advantages, buffer.advantages, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(returns, buffer.returns, rtol=1e-6, atol=1e-6)


def test_cost_returns_bootstrap_truncated_episodes_with_the_cost_critic():
    """One rollout's cost returns recomputed with SB3's buffer from the env's costs and the cost critic."""
    venv = _venv(truncate=True)
    model = PPOLagrangian("MlpPolicy", venv, seed=2, **{**SMALL, "n_steps": 25, "batch_size": 25})
    model._setup_learn(50, CallbackList([]))
    callback = CallbackList([])
    callback.init_callback(model)
    assert model.collect_rollouts(model.env, callback, model.rollout_buffer, model.n_steps)

    buffer = model.rollout_buffer
    obs = buffer.observations  # (n_steps, n_envs, 1): t / HORIZON
    with torch.no_grad():
        values = model.policy.predict_costs(torch.as_tensor(obs.reshape(-1, 1))).numpy().reshape(obs.shape[:2])
        terminal_value = float(model.policy.predict_costs(torch.ones(1, 1))[0, 0])  # the observation at t = HORIZON
        last_values = model.policy.predict_costs(torch.as_tensor(model._last_obs))
    costs = np.zeros(obs.shape[:2], np.float32)
    for step in range(obs.shape[0]):
        for i in range(obs.shape[1]):
            t = round(float(obs[step, i, 0]) * HORIZON)
            action = np.clip(buffer.actions[step, i, 0], -1.0, 1.0)
            costs[step, i] = action * action
            if t == HORIZON - 1:  # this step reached the time limit
                costs[step, i] += model.gamma * terminal_value
    n_steps, n_envs = obs.shape[:2]
    reference = RolloutBuffer(
        n_steps, venv.observation_space, venv.action_space, "cpu", model.gae_lambda, model.gamma, n_envs
    )
    reference.rewards[:], reference.values[:], reference.episode_starts[:] = costs, values, buffer.episode_starts
    reference.compute_returns_and_advantage(last_values, np.asarray(model._last_episode_starts))
    np.testing.assert_allclose(model._cost_returns, reference.returns, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(model._cost_advantages, reference.advantages, rtol=1e-5, atol=1e-5)
    assert buffer.episode_starts[HORIZON:].sum() > 0  # episodes did end inside the rollout


def test_at_lambda_zero_the_policy_updates_are_ppos():
    """Same seed, lambda held at 0, SB3's per-minibatch normalisation on: the weights follow PPO's to rounding."""

    def run(algo, **kwargs):
        model = algo("MlpPolicy", _venv(), seed=5, normalize_advantage=True, **SMALL, **kwargs)
        return model.learn(5 * 2 * SMALL["n_steps"])

    ppo = run(PPO).policy.state_dict()
    lagrangian = run(PPOLagrangian, cost_limit=LOOSE_BUDGET)
    assert lagrangian.lagrangian_multiplier == 0.0
    state = lagrangian.policy.state_dict()
    cost_critic = ["cost_net.0.bias", "cost_net.0.weight", "cost_net.2.bias", "cost_net.2.weight"]
    assert sorted(set(state) - set(ppo)) == cost_critic
    for key, value in ppo.items():
        torch.testing.assert_close(state[key], value, rtol=0, atol=1e-6)


# ------------------------------------------------------------------------------------------------------
# The small problem where the constraint binds
# ------------------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_unconstrained_ppo_exceeds_the_budget(toy_runs):
    _, logs, _ = toy_runs["ppo"]
    assert _tail_cost(logs, STEPS // 2) > 3 * BUDGET


@pytest.mark.slow
@pytest.mark.parametrize("run", ["binding", "binding_parallel"])
def test_binding_budget_ends_near_the_budget_with_a_positive_multiplier(toy_runs, run):
    model, logs, history = toy_runs[run]
    tail = [row["episode_cost"] for row in history[-TAIL:]]
    assert 0.6 * BUDGET < np.mean(tail) < 1.3 * BUDGET  # near the budget (PPO: 4x)
    assert model.lagrangian_multiplier > 0 and history[-1]["lambda"] == model.lagrangian_multiplier
    assert _tail_cost(logs, STEPS // 2) < _tail_cost(toy_runs["ppo"][1], STEPS // 2) / 3


@pytest.mark.slow
def test_loose_budget_keeps_lambda_at_zero_and_learns_like_ppo(toy_runs):
    model, logs, history = toy_runs["loose"]
    assert model.lagrangian_multiplier == 0.0 and all(row["lambda"] == 0.0 for row in history)
    ppo_cost = _tail_cost(toy_runs["ppo"][1], STEPS // 2)
    assert _tail_cost(logs, STEPS // 2) == pytest.approx(ppo_cost, rel=0.1)


@pytest.mark.slow
@pytest.mark.parametrize("run", ["binding", "binding_parallel"])
def test_multiplier_updates_match_an_independent_computation(toy_runs, run):
    """lambda recomputed from the env's own episode log (rollout k holds the episodes ending in its steps).

    ``binding_parallel``: with parallel rollouts the costs of env 1 come from its worker's part of each rollout.
    """
    _, logs, history = toy_runs[run]
    n_steps = SMALL["n_steps"]
    assert [row["update"] for row in history] == list(range(1, ROLLOUTS + 1))
    multiplier = 0.0
    for k, row in enumerate(history):
        costs = [cost for log in logs for steps, cost in log if k * n_steps < steps <= (k + 1) * n_steps]
        assert row["n_episodes"] == len(costs) and row["num_timesteps"] == (k + 1) * 2 * n_steps
        assert row["cost_limit"] == BUDGET
        if costs:
            assert row["episode_cost"] == pytest.approx(np.mean(costs), rel=1e-9)
            multiplier = max(0.0, multiplier + 0.1 * (np.mean(costs) - BUDGET))
        else:
            assert row["episode_cost"] is None
        assert row["lambda"] == pytest.approx(multiplier, rel=1e-9, abs=1e-12)


def test_costs_reach_the_trainer_from_worker_processes():
    """The same run with the envs in SubprocVecEnv workers: the infos' costs and so the multipliers are the same."""

    def run(venv):
        model = PPOLagrangian("MlpPolicy", venv, seed=4, cost_limit=1.0, lagrangian_lr=0.2, **SMALL)
        model.learn(4 * 2 * SMALL["n_steps"])
        venv.close()
        return model

    dummy, subproc = run(_venv()), run(SubprocVecEnv([CostlyPush, CostlyPush]))
    assert subproc.n_dual_updates == dummy.n_dual_updates == 4
    assert subproc.last_dual_update == dummy.last_dual_update
    assert dummy.lagrangian_multiplier > 0


def test_an_env_without_cost_is_a_clear_error():
    model = PPOLagrangian("MlpPolicy", "Pendulum-v1", n_steps=16, batch_size=16, seed=0)
    with pytest.raises(ValueError, match=re.escape("info['cost']")):
        model.learn(32)


# ------------------------------------------------------------------------------------------------------
# State: checkpoints and --resume
# ------------------------------------------------------------------------------------------------------
def _toy_config(tmp_path: Path, **extra) -> Path:
    entry = {
        "n_timesteps": 640,
        "n_envs": 2,
        "normalize": True,
        "eval_freq": 0,
        "checkpoint_freq": 256,
        "cost_limit": 0.5,
        "lagrangian_lr": 0.5,
        "lagrangian_init": 0.2,
        **SMALL,
        "n_epochs": 2,
        **extra,
    }
    path = tmp_path / "ppo_lagrangian.yml"
    path.write_text(yaml.safe_dump({"default": entry}), encoding="utf-8")
    return path


def _zip_multiplier(path: Path) -> float:
    with zipfile.ZipFile(path) as archive:
        return float(json.loads(archive.read("data"))["lagrangian_multiplier"])


def test_lambda_survives_checkpoints_and_resume(tmp_path):
    run_dir = train("ppo_lagrangian", TOY_ID, None, _toy_config(tmp_path), seed=1, out_dir=tmp_path, progress=False)
    history = read_history(run_dir / HISTORY_FILE)
    assert [row["segment"] for row in history] == [0] * 5 and history[0]["num_timesteps"] == 128
    assert [row["update"] for row in history] == [1, 2, 3, 4, 5]
    saved = _zip_multiplier(run_dir / "final_model.zip")
    assert saved == history[-1]["lambda"] > 0.2
    # a checkpoint holds the multiplier in effect when it was written (after the updates of earlier rollouts)
    checkpoint = run_dir / "checkpoints" / "rl_model_512_steps.zip"
    assert _zip_multiplier(checkpoint) == next(r["lambda"] for r in history if r["num_timesteps"] == 384)
    assert PPOLagrangian.load(checkpoint).lagrangian_multiplier == _zip_multiplier(checkpoint)
    progress = (run_dir / "logs" / "seg0" / "progress.csv").read_text().splitlines()
    assert {"lagrangian/lambda", "lagrangian/episode_cost", "lagrangian/cost_limit", "train/cost_value_loss"} <= set(
        progress[0].split(",")
    )
    assert list((run_dir / "logs" / "seg0").glob("events.out.tfevents.*"))

    assert train(resume_dir=run_dir, total_timesteps=256, progress=False) == run_dir
    resumed = read_history(run_dir / HISTORY_FILE)
    assert resumed[:5] == history
    first, second = resumed[5:]
    assert (first["segment"], first["update"], first["num_timesteps"]) == (1, 6, 768)
    assert first["lambda"] == pytest.approx(dual_ascent(saved, first["episode_cost"], 0.5, 0.5), rel=1e-12)
    assert second["lambda"] == pytest.approx(dual_ascent(first["lambda"], second["episode_cost"], 0.5, 0.5))
    assert _zip_multiplier(run_dir / "final_model.zip") == second["lambda"]
    assert latest_checkpoint(run_dir).num_timesteps == 896


@pytest.mark.slow
def test_resume_keeps_the_vec_env_of_the_last_segment_unless_told(tmp_path):
    # a registered id: the rollout worker is a fresh process, which knows only the ids of gym_packages
    run_dir = train(
        "ppo_lagrangian", "uvdms/CircleTrack-v1", None, _toy_config(tmp_path), seed=1, out_dir=tmp_path, progress=False,
        vec_env="rollout", total_timesteps=256,
    )  # fmt: skip
    # through `uvdms train --resume` as scripts/train_v1_entries.sh does (that CLI used to pass --vec-env dummy)
    assert uvdms(["train", "--resume", str(run_dir), "--total-timesteps", "128", "--no-progress"]) == 0
    train(resume_dir=run_dir, total_timesteps=128, progress=False, vec_env="dummy")
    train(resume_dir=run_dir, total_timesteps=128, progress=False)
    segments = json.loads((run_dir / "meta.json").read_text())["segments"]
    assert [s["vec_env"] for s in segments] == ["rollout", "rollout", "dummy", "dummy"]
    commands = (run_dir / "command.txt").read_text().splitlines()
    assert [c.split("--vec-env ")[1].split()[0] for c in commands] == ["rollout", "rollout", "dummy", "dummy"]


# ------------------------------------------------------------------------------------------------------
# Configuration
# ------------------------------------------------------------------------------------------------------
def test_shipped_config_validates_with_the_lagrangian_keys():
    configs = validate_config_file(REPO / "train_configs" / "ppo_lagrangian.yml")
    for env_id in ("uvdms/CircleTrack-v1", "uvdms/Transport-v1", "uvdms/CircleTrack-v0", "uvdms/Transport-v0"):
        params = configs[env_id].sb3_hyperparams()
        assert {"cost_limit", "lagrangian_lr", "lagrangian_init"} <= set(params)
        assert params["normalize_advantage"] is False


@pytest.mark.parametrize(
    ("entry", "algo", "message"),
    [
        ({"cost_limt": 5.0}, "ppo_lagrangian", r"unknown key 'cost_limt'.*did you mean 'cost_limit'"),
        ({"cost_limit": -1.0}, "ppo_lagrangian", r"key 'cost_limit' must be >= 0, got -1.0"),
        ({"lagrangian_lr": 0.0}, "ppo_lagrangian", r"key 'lagrangian_lr' must be > 0, got 0.0"),
        ({"lagrangian_init": -0.5}, "ppo_lagrangian", r"key 'lagrangian_init' must be >= 0"),
        ({"lagrangian_init": "high"}, "ppo_lagrangian", r"'lagrangian_init'"),
        ({"cost_limit": float("inf")}, "ppo_lagrangian", r"key 'cost_limit' must be a finite number"),
        ({"cost_limit": 5.0}, "ppo", r"unknown key 'cost_limit' \(neither a TrainConfig field nor a PPO argument"),
        ({"policy": "CnnPolicy"}, "ppo_lagrangian", r"unknown policy 'CnnPolicy' for PPOLagrangian"),
        ({"policy_kwargs": {"net_arch": {"pi": [8], "qf": [8]}}}, "ppo_lagrangian", r"unknown sub-keys \['qf'\]"),
    ],
)
def test_bad_lagrangian_keys_are_clear_errors(tmp_path, entry, algo, message):
    path = tmp_path / f"{algo}.yml"
    path.write_text(yaml.safe_dump({"default": {"n_timesteps": 10, **entry}}), encoding="utf-8")
    with pytest.raises(ConfigError, match=message) as info:
        load_config(path, algo, TOY_ID)
    assert str(path) in str(info.value)


def test_the_class_checks_its_arguments():
    with pytest.raises(ValueError, match="key 'cost_limit' must be >= 0"):
        PPOLagrangian("MlpPolicy", _venv(), cost_limit=-1.0)
    with pytest.raises(TypeError, match="CostActorCriticPolicy"):
        PPOLagrangian(PPO.policy_aliases["MlpPolicy"], _venv())
    assert PPOLagrangian.policy_aliases == {"MlpPolicy": CostActorCriticPolicy}


# ------------------------------------------------------------------------------------------------------
# End to end: the uvdms command on a uvdms env, through a worker process
# ------------------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_uvdms_train_ppo_lagrangian_on_circle_track(tmp_path):
    argv = [
        str(UVDMS),
        "train",
        "--algo",
        "ppo_lagrangian",
        "--env",
        "uvdms/CircleTrack-v1",
        "--env-kwargs",
        "case=1",
        "max_episode_steps=40",
        "--hyperparams",
        "n_steps=64",
        "batch_size=64",
        "n_epochs=2",
        "eval_freq=0",
        "checkpoint_freq=128",
        "lagrangian_init=0.3",
        "--total-timesteps",
        "256",
        "--vec-env",
        "hybrid",
        "--no-progress",
        "--out",
        "runs",
    ]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH")) if p)}
    done = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    run_dir = run_dir_for(tmp_path / "runs", "uvdms/CircleTrack-v1", "ppo_lagrangian", 0)
    history = read_history(run_dir / HISTORY_FILE)
    assert [(row["update"], row["num_timesteps"], row["n_episodes"]) for row in history] == [(1, 128, 2), (2, 256, 4)]
    assert all(row["cost_limit"] == 5.0 for row in history)  # train_configs/ppo_lagrangian.yml
    multiplier = 0.3
    for row in history:
        multiplier = dual_ascent(multiplier, row["episode_cost"], 5.0, 0.01)
        assert row["lambda"] == pytest.approx(multiplier, rel=1e-12)
    assert _zip_multiplier(run_dir / "final_model.zip") == history[-1]["lambda"]

    # the trained agent loads, evaluates and exports like a PPO agent (its export holds the cost critic too)
    agent = load_agent(run_dir, trust=True)
    exported = load_weights_only(export_agent(run_dir, tmp_path / "export", trust=True))
    assert agent.algo == exported.algo == "ppo_lagrangian"
    obs, _ = gym.make("uvdms/CircleTrack-v1", case=1).reset(seed=0)
    np.testing.assert_array_equal(agent.predict(obs, {}), exported.predict(obs, {}))
