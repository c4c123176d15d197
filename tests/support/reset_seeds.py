"""Every seed passed to an environment's ``reset()`` during a test, in this process and in vector-env workers.

:func:`record_reset_seeds` replaces ``gymnasium.Env.reset`` (which every environment's ``reset`` reaches through
``super().reset(seed=seed)``, as Gymnasium asks, under every wrapper) by one that appends each seed that is not
``None`` to a file, and wraps the env factories of every training segment (``TrainingSegment.env_factories``) in a
picklable :class:`RecordingFactory`, which installs the same recorder in whatever process builds the env (a
``SubprocVecEnv`` or ``HybridVecEnv`` worker). The seeds of all processes end up in the one file.

Also the tiny PPO run the seed tests of training, sweeps and searches record (:data:`TINY_PPO`) and their check
(:func:`assert_protocol_seeds`).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import yaml

from uvdms_gym.seeds import TEST_SPLITS, split_of

ENV = "uvdms/CircleTrack-v0"
ENV_KWARGS = {"case": 1, "max_episode_steps": 20}
TINY_PPO = {
    "n_timesteps": 128,
    "n_envs": 2,
    "n_steps": 32,
    "batch_size": 32,
    "n_epochs": 1,
    "policy_kwargs": {"net_arch": {"pi": [8], "vf": [8]}},
    "eval_freq": 32,
    "n_eval_episodes": 1,
    "checkpoint_freq": 0,
}
"""64 steps per env, an evaluation every 16 calls (32 steps), one 20-step evaluation episode each."""

_RECORDER_ATTR = "_records_seeds_to"


def recording_reset(original: Callable[..., Any], path: str) -> Callable[..., Any]:
    """``gymnasium.Env.reset`` that appends every seed (one line each) to ``path`` and then calls ``original``."""

    def reset(self: gym.Env, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        if seed is not None:
            with open(path, "a", encoding="utf-8") as f:  # one short O_APPEND write per seed: safe across processes
                f.write(f"{int(seed)}\n")
        return original(self, seed=seed, options=options)

    setattr(reset, _RECORDER_ATTR, path)
    return reset


def install(path: str) -> None:
    """Record this process's resets into ``path`` (for good: a worker process ends with its vector env)."""
    if getattr(gym.Env.reset, _RECORDER_ATTR, None) != path:
        gym.Env.reset = recording_reset(gym.Env.reset, path)


@dataclasses.dataclass(frozen=True)
class RecordingFactory:
    """An env factory that installs the recorder in the process that calls it (picklable, as its ``factory``)."""

    factory: Callable[[], gym.Env]
    path: str

    def __call__(self) -> gym.Env:
        install(self.path)
        return self.factory()


class ResetSeeds:
    """The file the seeds go to, and what it holds."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def seeds(self) -> list[int]:
        """Every recorded seed, in order (per process)."""
        if not self.path.is_file():
            return []
        return [int(line) for line in self.path.read_text(encoding="utf-8").split()]

    def clear(self) -> None:
        """Forget the seeds recorded so far."""
        if self.path.is_file():
            os.remove(self.path)


def record_reset_seeds(monkeypatch: Any, path: Path) -> ResetSeeds:
    """Record the seeds of every ``reset()`` from now until the test ends (``monkeypatch`` undoes it here)."""
    from agents.training.segment import TrainingSegment

    monkeypatch.setattr(gym.Env, "reset", recording_reset(gym.Env.reset, str(path)))
    env_factories = TrainingSegment.env_factories

    def recorded(self: TrainingSegment) -> tuple[list[Any], list[Any]]:
        train, evaluation = env_factories(self)
        return [RecordingFactory(f, str(path)) for f in train], [RecordingFactory(f, str(path)) for f in evaluation]

    monkeypatch.setattr(TrainingSegment, "env_factories", recorded)
    return ResetSeeds(path)


def write_tiny_config(folder: Path) -> Path:
    """:data:`TINY_PPO` as the ``default`` entry of ``folder/tiny_ppo.yml``."""
    path = folder / "tiny_ppo.yml"
    path.write_text(yaml.safe_dump({"default": TINY_PPO}), encoding="utf-8")
    return path


def assert_protocol_seeds(seeds: list[int]) -> None:
    """Some seeds, none a test seed (``uvdms_gym.seeds.split_of``), every one a training or validation seed."""
    assert seeds
    assert not [s for s in seeds if split_of(s) in TEST_SPLITS]
    assert {split_of(s) for s in seeds} <= {"training", "validation"}, sorted(set(seeds))
