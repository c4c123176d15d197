"""A policy's memory (``agents.common.history``) against Gymnasium's own frame stack.

The independent computation is ``gymnasium.wrappers.FrameStackObservation(env, k, padding_type="reset")``
flattened: oldest first, the episode's first observation repeated at the start. Compared over a real UVDMS
episode, reset in the middle, for the wrapper (:class:`FrameStack`) and the history the evaluation controller
keeps (:class:`ObservationHistory`).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.wrappers import FrameStackObservation

from agents.common.history import FrameStack, ObservationHistory, stacked_space, unstacked_space
from uvdms_gym.residual import MAX_FRAME_STACK

CIRCLE = "uvdms/CircleTrack-v1"


def _circle() -> gym.Env:
    return gym.make(CIRCLE, case=2, max_episode_steps=12)


def _actions(env: gym.Env, n: int) -> list[np.ndarray]:
    rng = np.random.default_rng(3)
    low, high = env.action_space.low, env.action_space.high
    return [rng.uniform(0.3 * low, 0.3 * high).astype(np.float32) for _ in range(n)]


@pytest.mark.parametrize("k", [1, 3])
def test_the_wrapper_and_the_history_equal_gymnasiums_frame_stack_flattened(k):
    ours, theirs, bare = FrameStack(_circle(), k), FrameStackObservation(_circle(), k, padding_type="reset"), _circle()
    history = ObservationHistory(k)
    actions = _actions(bare, 30)
    steps = 0
    for episode, (seed, n_steps) in enumerate([(5, 7), (6, 30)]):  # the first episode is cut short: reset mid-way
        obs, _ = ours.reset(seed=seed)
        ref, _ = theirs.reset(seed=seed)
        raw, _ = bare.reset(seed=seed)
        history.reset()
        np.testing.assert_array_equal(obs, np.asarray(ref).reshape(-1))
        np.testing.assert_array_equal(obs, np.tile(raw, k))  # the first observation k times
        np.testing.assert_array_equal(history.push(raw), obs)
        for action in actions[:n_steps]:
            obs, reward, terminated, truncated, _ = ours.step(action)
            ref, ref_reward, ref_terminated, ref_truncated, _ = theirs.step(action)
            raw, *_ = bare.step(action)
            np.testing.assert_array_equal(obs, np.asarray(ref).reshape(-1))
            np.testing.assert_array_equal(obs[-raw.size :], raw)  # the newest last
            np.testing.assert_array_equal(history.push(raw), obs)
            assert (reward, terminated, truncated) == (ref_reward, ref_terminated, ref_truncated)
            assert obs.shape == ours.observation_space.shape and obs.dtype == ours.observation_space.dtype
            steps += 1
            if terminated or truncated:
                break
        assert episode == 1 or not (terminated or truncated)
    assert steps > 7 + k  # the second episode ran past the padding


def test_a_pushed_history_is_a_new_array_each_time():
    history = ObservationHistory(2)
    first = history.push(np.array([1.0, 2.0]))
    second = history.push(np.array([3.0, 4.0]))
    np.testing.assert_array_equal(first, [1.0, 2.0, 1.0, 2.0])
    np.testing.assert_array_equal(second, [1.0, 2.0, 3.0, 4.0])
    first[:] = 0.0
    np.testing.assert_array_equal(history.push(np.array([5.0, 6.0])), [3.0, 4.0, 5.0, 6.0])


def test_the_stacked_space_tiles_the_bounds_oldest_first():
    env = _circle()
    space = FrameStack(env, 4).observation_space
    reference = FrameStackObservation(_circle(), 4, padding_type="reset").observation_space
    assert isinstance(space, spaces.Box)
    assert space.shape == (4 * env.observation_space.shape[0],) == (int(np.prod(reference.shape)),)
    assert space.dtype == env.observation_space.dtype
    np.testing.assert_array_equal(space.low, np.asarray(reference.low).reshape(-1))
    np.testing.assert_array_equal(space.high, np.asarray(reference.high).reshape(-1))
    box = spaces.Box(np.array([-1.0, -2.0], np.float32), np.array([1.0, 3.0], np.float32))
    stacked = stacked_space(box, 3)
    np.testing.assert_array_equal(stacked.low, [-1.0, -2.0] * 3)
    np.testing.assert_array_equal(stacked.high, [1.0, 3.0] * 3)


@pytest.mark.parametrize("k", [0, -1, True, 2.0, "3", MAX_FRAME_STACK + 1])
def test_a_bad_k_is_refused_naming_frame_stack(k):
    with pytest.raises(ValueError, match=r"frame_stack must be an integer in \[1, 64\]"):
        ObservationHistory(k)
    with pytest.raises(ValueError, match="frame_stack must be an integer"):
        FrameStack(_circle(), k)


def test_only_1d_observations_are_stacked():
    history = ObservationHistory(2)
    with pytest.raises(ValueError, match=r"1-D observations, got shape \(2, 3\)"):
        history.push(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="frame_stack stacks 1-D Box observations"):
        stacked_space(spaces.Box(-1.0, 1.0, (2, 3)), 2)
    with pytest.raises(ValueError, match="frame_stack stacks 1-D Box observations"):
        stacked_space(spaces.Discrete(3), 2)


def test_the_action_history_is_the_last_actions_taken_oldest_first_zeros_before_the_first():
    m, k = 3, 2
    env = FrameStack(gym.make(CIRCLE, case=2, max_episode_steps=8), k, actions=m)
    size, n_act = gym.make(CIRCLE).observation_space.shape[0], env.action_space.shape[0]
    assert env.observation_space.shape == (k * size + m * n_act,)
    rng = np.random.default_rng(0)
    for _ in range(2):  # a second episode starts again from zeros
        obs, _ = env.reset(seed=1)
        np.testing.assert_array_equal(obs[k * size :], np.zeros(m * n_act, dtype=np.float32))
        taken: list[np.ndarray] = [np.zeros(n_act, dtype=np.float32)] * m
        for _ in range(5):
            action = rng.uniform(-1, 1, n_act).astype(np.float32)
            obs, *_ = env.step(action)
            taken.append(action)
            np.testing.assert_array_equal(obs[k * size :], np.concatenate(taken[-m:]))
            assert env.observation_space.contains(obs)


def test_a_bad_action_history_is_refused_naming_it():
    with pytest.raises(ValueError, match="action_history must be an integer"):
        FrameStack(gym.make(CIRCLE), 2, actions=-1)


def test_unstacked_space_inverts_stacked_space():
    env = gym.make(CIRCLE)
    for k, m in [(1, 2), (4, 0), (4, 4)]:
        stacked = stacked_space(env.observation_space, k, m, env.action_space)
        assert unstacked_space(stacked, k, m, env.action_space.shape[0]) == env.observation_space
    with pytest.raises(ValueError, match="is not 3 observations"):
        unstacked_space(env.observation_space, 3, 0, 18)
