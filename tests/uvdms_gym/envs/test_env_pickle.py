"""Environments pickle and deep-copy the Gymnasium way, and reset after close (uvdms_gym/envs/base.py).

A copy is a new environment built from the same constructor arguments (``gymnasium.utils.EzPickle``), with its own
PyBullet client: stepping or closing it leaves the original alone. During an episode the copy replays it (the
generator after the reset's seeding and the actions since), so it is in the original's state and steps at once, as
the Gymnasium wrappers around it (which pickle their own flags) claim; a copy of a closed or never-reset environment
says in one line that it must be reset. The simulator itself (``UVDMSSim``) refuses to be pickled or copied, since a
copy would share its client.
"""

from __future__ import annotations

import contextlib
import copy
import gc
import pickle
import warnings
from collections.abc import Iterator

import cloudpickle
import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from stable_baselines3.common.env_checker import check_env

import uvdms_gym

COPIES = {
    "pickle": lambda env: pickle.loads(pickle.dumps(env)),
    "cloudpickle": lambda env: cloudpickle.loads(cloudpickle.dumps(env)),
    "deepcopy": copy.deepcopy,
}
KWARGS = {  # non-default keywords, so that a copy that dropped them would show
    "uvdms/CircleTrack-v0": {"case": 2},
    "uvdms/CircleTrack-v1": {"case": "random", "hydro_randomization": 0.2, "current": "random"},
    "uvdms/Transport-v0": {"goal": "random", "current": [0.1, -0.05, 0.0]},
    "uvdms/Transport-v1": {"goal": "paper", "contact_weight": 5.0},
    "uvdms/TransportObstacles-v1": {"current": "random", "n_observed_obstacles": 2},
    "uvdms/CooperativeTransport-v1": {"goal": "random", "grasp": {"mu": 0.4}},
    "uvdms/CooperativeTransportObstacles-v1": {"current": "random", "grasp": {"crush_force": 120.0}},
}
STEPS = 4
SEED = 11


def _actions(env: gym.Env, n: int = STEPS) -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    return [rng.uniform(-0.5, 0.5, env.action_space.shape).astype(np.float32) for _ in range(n)]


def _trajectory(env: gym.Env, actions: list[np.ndarray]) -> list[np.ndarray]:
    out = [env.reset(seed=SEED)[0]]
    out += [env.step(a)[0] for a in actions]
    return out


@pytest.mark.parametrize("env_id", uvdms_gym.ENV_IDS)
@pytest.mark.parametrize("how", sorted(COPIES))
def test_a_copy_is_an_independent_environment(env_id, how):
    original = gym.make(env_id, **KWARGS[env_id])
    fresh = gym.make(env_id, **KWARGS[env_id])
    try:
        actions = _actions(original)
        expected = _trajectory(fresh, actions)
        first = original.reset(seed=SEED)[0]
        duplicate = COPIES[how](original)
        assert duplicate.unwrapped is not original.unwrapped
        assert duplicate.unwrapped._sim is not original.unwrapped._sim
        # same constructor arguments: the same first observation for the same seed
        np.testing.assert_array_equal(duplicate.reset(seed=SEED)[0], first)
        for a in _actions(duplicate, 2 * STEPS)[::-1]:  # the copy moves first, differently
            duplicate.step(a)
        observed = [first] + [original.step(a)[0] for a in actions]
        for got, want in zip(observed, expected):
            np.testing.assert_array_equal(got, want)  # the original's trajectory is the undisturbed one
        duplicate.close()
        original.step(actions[0])  # closing the copy leaves the original's client alone
    finally:
        original.close()
        fresh.close()


@contextlib.contextmanager
def _closing(env: gym.Env) -> Iterator[gym.Env]:
    try:
        yield env
    finally:
        env.close()


@pytest.mark.parametrize("env_id", uvdms_gym.ENV_IDS)
@pytest.mark.parametrize("how", sorted(COPIES))
def test_a_copy_made_during_an_episode_steps_on_from_the_originals_state(env_id, how):
    """The newcomer's defect: a copy came back with its wrappers marked as reset and failed deep inside ``step``."""
    limit = STEPS + 2  # the TimeLimit truncates both on the second step after the copy: its step count is copied
    with _closing(gym.make(env_id, max_episode_steps=limit, **KWARGS[env_id])) as original:
        actions = _actions(original, limit)
        original.reset()  # no seed: the copy must carry the generator, not a seed
        for a in actions[:STEPS]:
            original.step(a)
        with _closing(COPIES[how](original)) as duplicate:
            assert duplicate.unwrapped.t == original.unwrapped.t
            truncated, terminated = [], []
            for a in actions[STEPS:]:
                got, want = duplicate.step(a), original.step(a)
                np.testing.assert_array_equal(got[0], want[0])
                assert got[1:4] == want[1:4]  # reward, terminated, truncated
                truncated.append(got[3])
                terminated.append(got[2])
                if got[2]:  # a friction-grasp episode may end by a drop (its unseeded task varies): both did
                    break
            assert truncated == [False, True] or terminated[-1]


@pytest.mark.parametrize("env_id", uvdms_gym.ENV_IDS)
@pytest.mark.parametrize("how", sorted(COPIES))
def test_a_copy_of_a_never_reset_environment_asks_for_reset_in_one_line(env_id, how):
    """Through ``gym.make``'s wrappers ``OrderEnforcing`` answers first; the environment itself answers alike."""
    with _closing(gym.make(env_id, **KWARGS[env_id])) as env:
        action = env.action_space.sample()
        with _closing(COPIES[how](env)) as wrapped, _closing(COPIES[how](env.unwrapped)) as bare:
            for duplicate, message in ((wrapped, r"env\.reset\(\)"), (bare, r"call reset\(\) before step\(\)")):
                with pytest.raises(ResetNeeded, match=message) as err:
                    duplicate.step(action)
                assert "\n" not in str(err.value)
                duplicate.reset(seed=SEED)
                duplicate.step(action)


@pytest.mark.parametrize("env_id", uvdms_gym.ENV_IDS)
@pytest.mark.parametrize("how", sorted(COPIES))
def test_a_copy_without_an_episode_asks_for_reset_in_one_line(env_id, how):
    with _closing(gym.make(env_id, **KWARGS[env_id])) as env:
        env.reset(seed=SEED)
        env.step(env.action_space.sample())
        env.close()  # the wrappers still say "reset", the copy is a fresh environment
        with _closing(COPIES[how](env)) as duplicate:
            with pytest.raises(ResetNeeded, match=r"call reset\(\) before step\(\)") as err:
                duplicate.step(env.action_space.sample())
            assert "\n" not in str(err.value)
            duplicate.reset(seed=SEED)
            duplicate.step(env.action_space.sample())


@pytest.mark.parametrize("env_id", uvdms_gym.ENV_IDS)
def test_reset_after_close_connects_a_new_client(env_id):
    env = gym.make(env_id, **KWARGS[env_id])
    actions = _actions(env)
    before = _trajectory(env, actions)
    old_sim = env.unwrapped._sim
    env.close()
    env.close()  # idempotent
    try:
        after = _trajectory(env, actions)  # the same constructor arguments: the same physics, bit for bit
        assert env.unwrapped._sim is not old_sim and old_sim.closed
        for got, want in zip(after, before):
            np.testing.assert_array_equal(got, want)
    finally:
        env.close()


def test_the_simulator_refuses_to_be_copied():
    """A copy of a ``UVDMSSim`` would share its PyBullet client (collecting the copy disconnected the original)."""
    env = gym.make("uvdms/CircleTrack-v1")
    try:
        env.reset(seed=SEED)
        sim = env.unwrapped._sim
        for how, make_copy in {**COPIES, "copy": copy.copy}.items():
            with pytest.raises(TypeError, match="cannot be pickled or copied"):
                make_copy(sim)
            assert not sim.closed, how
        gc.collect()
        env.step(env.action_space.sample())  # the original's client is still connected
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ["uvdms/CircleTrack-v0", "uvdms/Transport-v1"])
def test_stable_baselines3_check_env_with_the_render_check(env_id):
    env = gym.make(env_id, render_mode="rgb_array", render_width=32, render_height=24).unwrapped
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # SB3 reports problems as warnings
            check_env(env, warn=True, skip_render_check=False)  # calls close() then reset()
    finally:
        env.close()


def test_async_vector_env():
    envs = gym.make_vec("uvdms/CircleTrack-v1", num_envs=2, vectorization_mode="async", case="random")
    try:
        obs, _ = envs.reset(seed=[1, 2])
        assert obs.shape == (2, *envs.single_observation_space.shape) and not np.array_equal(obs[0], obs[1])
        for _ in range(2):
            obs, reward, *_ = envs.step(envs.action_space.sample())
        assert np.all(np.isfinite(reward))
    finally:
        envs.close()
