"""Shared pieces of the agents tests: the environments, tiny configurations and the training runs."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import yaml

from agents.algos import ALGOS
from agents.training.train import (
    train,
)

REPO = Path(__file__).resolve().parents[2]

# (env id, gymnasium.make kwargs).
TEST_ENVS: list[tuple[str, dict]] = [
    ("Pendulum-v1", {"max_episode_steps": 100}),
    ("MountainCarContinuous-v0", {"max_episode_steps": 100}),
    ("uvdms/CircleTrack-v0", {"case": 1, "max_episode_steps": 60}),
    ("uvdms/Transport-v0", {"goal": "paper", "max_episode_steps": 60}),
]
ALGO_NAMES = sorted(ALGOS)
UVDMS_IDS = ("uvdms/CircleTrack-v0", "uvdms/Transport-v0")
COST_ALGOS = ("ppo_lagrangian",)  # need info["cost"]: trained on the uvdms ids only
TEACHER_ALGOS = ("dagger",)  # need a residual base and a teacher (uvdms train): tests/agents/algos/test_dagger.py
RUNS = [
    (a, e)
    for a in ALGO_NAMES
    for e, _ in TEST_ENVS
    if a not in TEACHER_ALGOS and (a not in COST_ALGOS or e in UVDMS_IDS)
]
"""The (algo, env id) pairs of the shared training runs."""

_COMMON = {"n_timesteps": 300, "n_envs": 2, "eval_freq": 200, "n_eval_episodes": 1, "checkpoint_freq": 200}
TINY = {
    "dagger": {
        **_COMMON,
        "buffer_size": 1000,
        "batch_size": 32,
        "noise_type": "normal",
        "noise_std": 0.1,
        "teacher": "campc",
        "policy_kwargs": {"net_arch": [16]},
    },
    "ppo": {
        **_COMMON,
        "normalize": True,
        "n_steps": 64,
        "batch_size": 64,
        "n_epochs": 2,
        "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}, "log_std_init": -1.0},
    },
    "ppo_lagrangian": {
        **_COMMON,
        "normalize": True,
        "n_steps": 64,
        "batch_size": 64,
        "n_epochs": 2,
        "cost_limit": 1.0,
        "lagrangian_init": 0.5,
        "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}, "log_std_init": -1.0},
    },
    "sac": {
        **_COMMON,
        "normalize": {"norm_obs": True, "norm_reward": False},
        "buffer_size": 1000,
        "batch_size": 32,
        "learning_starts": 50,
        "policy_kwargs": {"net_arch": [16]},
    },
    "td3": {
        **_COMMON,
        "buffer_size": 1000,
        "batch_size": 32,
        "learning_starts": 50,
        "noise_type": "normal",
        "noise_std": 0.2,
        "policy_kwargs": {"net_arch": [16]},
    },
    "td3_prior": {
        **_COMMON,
        "buffer_size": 1000,
        "batch_size": 32,
        "learning_starts": 50,
        "noise_type": "normal",
        "noise_std": 0.2,
        "prior_coef": 0.4,
        "actor_warmup_steps": 100,
        "policy_kwargs": {"net_arch": [16]},
    },
    "tqc": {
        **_COMMON,
        "normalize": True,
        "buffer_size": 1000,
        "batch_size": 32,
        "learning_starts": 50,
        "policy_kwargs": {"net_arch": [16], "n_quantiles": 5},
    },
}


def write_config(folder: Path, algo: str, **extra) -> Path:
    path = folder / f"{algo}.yml"
    path.write_text(yaml.safe_dump({"default": {**TINY[algo], **extra}}), encoding="utf-8")
    return path


def sample_observations(env_id: str, env_kwargs: dict, n: int = 12) -> list[np.ndarray]:
    env = gym.make(env_id, **env_kwargs)
    obs_list = []
    obs, _ = env.reset(seed=123)
    env.action_space.seed(123)
    for _ in range(n):
        obs_list.append(obs)
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            obs, _ = env.reset()
    env.close()
    return obs_list


class Runs:
    """One short training run per (algo, env) pair of :data:`RUNS`, trained when a test first asks for it."""

    def __init__(self, out: Path, config_dir: Path) -> None:
        self.out, self.config_dir = out, config_dir
        self._done: dict[tuple[str, str], Path] = {}

    def __getitem__(self, key: tuple[str, str]) -> Path:
        if key not in self._done:
            algo, env_id = key
            self._done[key] = train(
                algo,
                env_id,
                dict(TEST_ENVS)[env_id],
                self.config_dir / f"{algo}.yml",
                seed=7,
                total_timesteps=None,
                n_envs=None,
                out_dir=self.out,
                resume_dir=None,
                progress=False,
                gym_packages=["uvdms_gym"],
            )
        return self._done[key]
