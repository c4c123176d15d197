"""A training segment's env factories under ``env_variants``, ``navigation_filter`` and ``frame_stack``.

Training env ``i`` gets variant ``i % len(env_variants)`` (its ``realism`` level read back from the built env),
the evaluation envs the first variant with ``eval_env_kwargs``; the navigation filter wraps the env where it has
a realism level and not at ``realism=0``; the frame stack is the outermost wrapper but for the ``Monitor``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.monitor import Monitor

from agents.common.envs import EnvFactory
from agents.common.history import FrameStack
from agents.common.names import DEFAULT_GYM_PACKAGES
from agents.config import ConfigError, parse_entry
from agents.training.segment import TrainingSegment
from uvdms_gym.realism.navigation import NavigationFilterWrapper

CIRCLE = "uvdms/CircleTrack-v1"


def _segment(tmp_path, **extra) -> TrainingSegment:
    entry = {"n_timesteps": 10, "env_kwargs": {"case": 2}, "max_episode_steps": 5, **extra}
    cfg = parse_entry(entry, "sac", source="test.yml", entry_name=CIRCLE)
    segment = TrainingSegment(tmp_path, cfg, CIRCLE, 0, DEFAULT_GYM_PACKAGES, 10, [], None, "dummy", 0)
    segment.record = {"index": 0}
    return segment


def _layers(env: gym.Env) -> list[type]:
    layers = []
    while isinstance(env, gym.Wrapper):
        layers.append(type(env))
        env = env.env
    return layers


def test_each_training_env_gets_its_variants_realism_and_the_filter_only_where_there_is_one(tmp_path):
    variants = [{"realism": 2}, {"realism": 0}, {"realism": 3}]
    segment = _segment(
        tmp_path, n_envs=4, n_eval_envs=2, env_variants=variants, navigation_filter=True, frame_stack=2,
        eval_env_kwargs={"case": 1},
    )  # fmt: skip
    train, evaluation = segment.env_factories()
    expected_levels = [2, 0, 3, 2]
    assert [f.env_kwargs["realism"] for f in train] == expected_levels
    assert [f.env_kwargs for f in evaluation] == [{"case": 1, "realism": 2}] * 2
    for factory, level in zip([*train, *evaluation], [*expected_levels, 2, 2], strict=True):
        env = factory()
        try:
            realism = env.unwrapped.realism
            assert (realism.level if realism is not None else 0) == level
            layers = _layers(env)
            assert layers[0] is Monitor and layers[1] is FrameStack
            assert (NavigationFilterWrapper in layers) == (level > 0)
            obs, _ = env.reset(seed=1)
            size = env.unwrapped.observation_space.shape[0]
            assert obs.shape == (2 * size,) and env.observation_space.shape == (2 * size,)
            np.testing.assert_array_equal(obs[:size], obs[size:])  # the first observation, twice
        finally:
            env.close()


def test_without_the_keys_every_env_is_alike_and_unwrapped_by_them(tmp_path):
    segment = _segment(tmp_path, n_envs=2, env_kwargs={"case": 2, "realism": 2})
    train, evaluation = segment.env_factories()
    assert [f.env_kwargs for f in [*train, *evaluation]] == [{"case": 2, "realism": 2}] * 3
    env = train[0]()
    try:
        assert env.unwrapped.realism is not None
        layers = _layers(env)
        assert FrameStack not in layers and NavigationFilterWrapper not in layers
        assert env.observation_space.shape == env.unwrapped.observation_space.shape
    finally:
        env.close()


def test_a_variant_the_env_rejects_is_a_config_error_naming_the_variants(tmp_path):
    segment = _segment(tmp_path, n_envs=2, env_variants=[{"realism": 2}, {"realism": 9}])
    with pytest.raises(ConfigError, match=r"and env_variants \[\{'realism': 2\}, \{'realism': 9\}\]") as info:
        segment.make_envs()
    assert "ValueError: realism must be 0, 1, 2 or 3" in str(info.value)


def test_the_navigation_filter_needs_a_uvdms_env():
    factory = EnvFactory("Pendulum-v1", {}, DEFAULT_GYM_PACKAGES, None, 10, navigation_filter=True)
    with pytest.raises(ValueError, match=r"navigation_filter needs a UVDMS environment .*, not Pendulum-v1"):
        factory()
    assert FrameStack in _layers(EnvFactory("Pendulum-v1", {}, DEFAULT_GYM_PACKAGES, None, 10, frame_stack=2)())
