"""Training runs: run directories, resume, seeds, the command line, vector envs, action layers (agents.training)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import torch
import yaml

from agents.algos import ALGOS
from agents.config import ConfigError, parse_entry
from agents.training.train import (
    EnvironmentNotFoundError,
    RunDirError,
    eval_env_seed,
    latest_checkpoint,
    main,
    run_dir_for,
    train,
    train_env_seed,
    zip_num_timesteps,
)
from tests.support.agent_runs import COST_ALGOS, RUNS, TEST_ENVS, TINY, write_config
from uvdms_gym.seeds import PROTOCOL


@pytest.mark.parametrize(("algo", "env_id"), RUNS)
def test_training_writes_complete_run_dir(runs, algo, env_id):
    run_dir = runs[algo, env_id]
    assert run_dir == run_dir_for(run_dir.parents[1], env_id, algo, 7)
    assert "/" not in run_dir.parent.name
    for name in (
        "config.yml",
        "command.txt",
        "meta.json",
        "final_model.zip",
        "best_model.zip",
        "best_model.json",
        "logs/seg0/progress.csv",
        "logs/seg0/evaluations.npz",
        "monitor/seg0_train_0.monitor.csv",
        "monitor/seg0_train_1.monitor.csv",
        "monitor/seg0_eval_0.monitor.csv",
    ):
        assert (run_dir / name).is_file(), name
    assert list((run_dir / "logs" / "seg0").glob("events.out.tfevents.*"))
    assert list((run_dir / "checkpoints").glob("rl_model_*_steps.zip"))
    normalized = TINY[algo].get("normalize", False) is not False
    assert (run_dir / "vecnormalize.pkl").is_file() == normalized
    assert (run_dir / "best_vecnormalize.pkl").is_file() == normalized
    assert (run_dir / "lagrangian.csv").is_file() == (algo in COST_ALGOS)

    resolved = yaml.safe_load((run_dir / "config.yml").read_text())
    assert resolved["algo"] == algo and resolved["env_id"] == env_id and resolved["seed"] == 7
    assert resolved["config"]["env_kwargs"] == dict(TEST_ENVS)[env_id]
    assert parse_entry(resolved["config"], algo).n_envs == 2

    meta = json.loads((run_dir / "meta.json").read_text())
    for package in ("python", "numpy", "torch", "stable_baselines3", "sb3_contrib", "gymnasium"):
        assert meta["versions"][package]
    assert re.fullmatch(r"[0-9a-f]{40}", meta["git"]["revision"])
    assert isinstance(meta["git"]["dirty"], bool)
    assert (meta["seed"], meta["seed_protocol"], meta["seed_split"]) == (7, PROTOCOL, "training")
    (segment,) = meta["segments"]
    assert segment["status"] == "completed"
    assert segment["end_num_timesteps"] >= 300
    assert segment["train_env_seeds"] == [train_env_seed(7, 0, 0), train_env_seed(7, 0, 1)] == [7, 8]
    assert segment["eval_env_seeds"] == [eval_env_seed(7, 0)]
    assert not set(segment["train_env_seeds"]) & set(segment["eval_env_seeds"])
    assert zip_num_timesteps(run_dir / "final_model.zip") == segment["end_num_timesteps"]
    command = (run_dir / "command.txt").read_text().splitlines()
    assert len(command) == 1 and f"--algo {algo}" in command[0]


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_resume_continues_step_count(tmp_path, config_dir, algo):
    env_id, env_kwargs = TEST_ENVS[0]
    config = write_config(tmp_path, algo, save_replay_buffer=True) if algo == "sac" else (config_dir / f"{algo}.yml")
    run_dir = train(
        algo, env_id, env_kwargs, config, seed=1, out_dir=tmp_path / "runs", progress=False, total_timesteps=200
    )
    before = zip_num_timesteps(run_dir / "final_model.zip")
    assert latest_checkpoint(run_dir).model == run_dir / "final_model.zip"
    with pytest.raises(RunDirError, match="--resume"):
        train(algo, env_id, env_kwargs, config, seed=1, out_dir=tmp_path / "runs", progress=False)

    assert train(resume_dir=run_dir, total_timesteps=200, progress=False) == run_dir
    model = ALGOS[algo].load(run_dir / "final_model.zip")
    assert model.num_timesteps > before
    assert model.num_timesteps >= before + 200
    for segment in ("seg0", "seg1"):
        assert (run_dir / "logs" / segment / "progress.csv").is_file()
        assert (run_dir / "monitor" / f"{segment}_train_0.monitor.csv").is_file()
    progress = (run_dir / "logs" / "seg1" / "progress.csv").read_text().splitlines()
    header = progress[0].split(",")
    steps = [
        int(float(row.split(",")[header.index("time/total_timesteps")]))
        for row in progress[1:]
        if row.split(",")[header.index("time/total_timesteps")]
    ]
    assert steps and min(steps) > before  # the step axis continues
    meta = json.loads((run_dir / "meta.json").read_text())
    assert [s["status"] for s in meta["segments"]] == ["completed", "completed"]
    first, second = meta["segments"]
    assert second["start_num_timesteps"] == first["end_num_timesteps"] == before
    assert second["resumed_from"] == "final_model.zip"
    assert not set(first["train_env_seeds"]) & set(second["train_env_seeds"])
    assert len((run_dir / "command.txt").read_text().splitlines()) == 2
    if algo == "sac":
        assert (run_dir / "replay_buffer.pkl").is_file()
    # A finished run needs --total-timesteps to continue.
    with pytest.raises(ConfigError, match="--total-timesteps"):
        train(resume_dir=run_dir, progress=False, total_timesteps=None)
    with pytest.raises(ConfigError, match="differs"):
        train(algo="td3", resume_dir=run_dir, total_timesteps=10, progress=False)


def test_same_seed_gives_identical_weights(tmp_path, config_dir):
    env_id, env_kwargs = TEST_ENVS[0]
    weights = []
    for out in ("a", "b"):
        run_dir = train(
            "sac",
            env_id,
            env_kwargs,
            config_dir / "sac.yml",
            seed=5,
            out_dir=tmp_path / out,
            progress=False,
            total_timesteps=150,
        )
        model = ALGOS["sac"].load(run_dir / "final_model.zip")
        weights.append(torch.cat([p.flatten() for p in model.policy.parameters()]))
    torch.testing.assert_close(weights[0], weights[1], rtol=0, atol=0)


def test_cli(tmp_path, config_dir, capsys):
    env_id = TEST_ENVS[0][0]
    argv = [
        "--algo",
        "td3",
        "--env",
        env_id,
        "--config",
        str(config_dir / "td3.yml"),
        "--seed",
        "2",
        "--total-timesteps",
        "120",
        "--n-envs",
        "1",
        "--out",
        str(tmp_path),
        "--no-progress",
        "--env-kwargs",
        "max_episode_steps=50",
        "--hyperparams",
        "learning_rate=1.0e-3",
        "eval_freq=0",
        "checkpoint_freq=0",
    ]
    assert main(argv) == 0
    run_dir = run_dir_for(tmp_path, env_id, "td3", 2)
    assert capsys.readouterr().out.strip() == str(run_dir)
    resolved = yaml.safe_load((run_dir / "config.yml").read_text())["config"]
    assert resolved["env_kwargs"] == {"max_episode_steps": 50}
    assert resolved["n_envs"] == 1 and resolved["learning_rate"] == 1.0e-3
    assert not (run_dir / "best_model.zip").exists() and not (run_dir / "checkpoints").exists()
    assert "--env-kwargs max_episode_steps=50" in (run_dir / "command.txt").read_text()

    assert main(argv) == 2  # exists
    assert "--resume" in capsys.readouterr().err
    assert main(["--algo", "sac", "--env", "uvdms/NoSuchEnv-v0", "--out", str(tmp_path), "--no-progress"]) == 2
    assert "not registered" in capsys.readouterr().err
    assert main(["--algo", "sac", "--env", env_id, "--out", str(tmp_path), "--hyperparams", "gama=0.9"]) == 2
    assert "'gama'" in capsys.readouterr().err


def test_missing_env_package_is_reported(tmp_path, config_dir):
    with pytest.raises(EnvironmentNotFoundError, match=r"no_such_gym_pkg.*ModuleNotFoundError"):
        train(
            "sac",
            "NoSuch-v0",
            None,
            config_dir / "sac.yml",
            out_dir=tmp_path,
            progress=False,
            gym_packages=["no_such_gym_pkg"],
        )


def test_subproc_vec_env(tmp_path, config_dir):
    env_id, env_kwargs = TEST_ENVS[0]
    run_dir = train(
        "sac",
        env_id,
        env_kwargs,
        config_dir / "sac.yml",
        out_dir=tmp_path,
        progress=False,
        total_timesteps=100,
        vec_env="subproc",
        hyperparams={"eval_freq": 0, "checkpoint_freq": 0},
    )
    meta = json.loads((run_dir / "meta.json").read_text())
    assert meta["segments"][0]["vec_env"] == "subproc"
    assert meta["segments"][0]["status"] == "completed"
    assert (run_dir / "monitor" / "seg0_train_1.monitor.csv").is_file()


def test_max_episode_steps_and_alive_bonus(tmp_path, config_dir):
    """Both fields reach the training/evaluation envs; Monitor logs hold the shaped return."""
    env_id = "Pendulum-v1"
    run_dir = train(
        "ppo",
        env_id,
        None,
        config_dir / "ppo.yml",
        out_dir=tmp_path,
        progress=False,
        total_timesteps=128,
        hyperparams={"max_episode_steps": 16, "alive_bonus": 20.0, "checkpoint_freq": 0, "eval_freq": 64},
    )
    resolved = yaml.safe_load((run_dir / "config.yml").read_text())["config"]
    assert resolved["max_episode_steps"] == 16 and resolved["alive_bonus"] == 20.0
    assert parse_entry(resolved, "ppo").alive_bonus == 20.0
    from scripts.ship_agent import read_monitor_episodes

    episodes = read_monitor_episodes(run_dir)
    assert len(episodes["l"]) >= 4 and set(episodes["l"]) == {16}
    # Pendulum rewards are in [-16.3, 0]: with +20 per step every shaped return is positive.
    assert np.all(episodes["r"] > 0) and np.all(episodes["r"] - 20.0 * episodes["l"] <= 0)
    assert read_monitor_episodes(run_dir, "eval")["l"].tolist()[0] == 16
    with pytest.raises(ConfigError, match="'max_episode_steps'"):
        parse_entry({"n_timesteps": 10, "max_episode_steps": 0}, "ppo")
    with pytest.raises(ConfigError, match="'alive_bonus'"):
        parse_entry({"n_timesteps": 10, "alive_bonus": "lots"}, "ppo")


def _action_layer(model) -> torch.nn.Linear:
    layer = model.policy.action_net if hasattr(model.policy, "action_net") else model.policy.actor.mu
    if isinstance(layer, torch.nn.Sequential):
        layer = [m for m in layer if isinstance(m, torch.nn.Linear)][-1]
    return layer


@pytest.mark.parametrize("algo", ["sac", "td3", "tqc"])
def test_action_init_scale_scales_the_last_action_layer(tmp_path, config_dir, algo):
    """Same seed, no gradient step yet: the scaled run's action layer is exactly scale x the unscaled one."""
    layers = []
    for scale in (None, 0.01):
        run_dir = train(
            algo,
            "Pendulum-v1",
            {"max_episode_steps": 50},
            config_dir / f"{algo}.yml",
            seed=4,
            out_dir=tmp_path / str(scale),
            progress=False,
            total_timesteps=64,
            hyperparams={"eval_freq": 0, "checkpoint_freq": 0, "learning_starts": 10_000, "action_init_scale": scale},
        )
        layers.append(_action_layer(ALGOS[algo].load(run_dir / "final_model.zip")))
    torch.testing.assert_close(layers[1].weight, 0.01 * layers[0].weight)
    torch.testing.assert_close(layers[1].bias, 0.01 * layers[0].bias)
    with pytest.raises(ConfigError, match="'action_init_scale'"):
        parse_entry({"n_timesteps": 10, "action_init_scale": 0.0}, algo)


def test_scale_action_layer_on_ppo_and_td3_target():
    from agents.training.train import scale_action_layer

    ppo = ALGOS["ppo"]("MlpPolicy", "Pendulum-v1", seed=0)
    before = _action_layer(ppo).weight.clone()
    scale_action_layer(ppo, 0.5)
    torch.testing.assert_close(_action_layer(ppo).weight, 0.5 * before)
    td3 = ALGOS["td3"]("MlpPolicy", "Pendulum-v1", seed=0)
    scale_action_layer(td3, 0.1)
    for p, q in zip(td3.policy.actor.parameters(), td3.policy.actor_target.parameters()):
        torch.testing.assert_close(p, q)
