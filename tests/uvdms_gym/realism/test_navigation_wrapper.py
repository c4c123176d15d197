"""NavigationFilterWrapper on the real environment: the estimate replaces the state, check_env, copies."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import uvdms_gym  # noqa: F401  (registers the ids)
from uvdms_gym.realism.navigation import NavigationFilter, NavigationFilterWrapper
from uvdms_gym.seeds import split_seeds

SEED = split_seeds("validation", 4)[3]  # a validation draw
"""A validation seed."""
STEPS = 6
"""Steps of each episode (a fix and a DVL sample arrive within them at level 1)."""


def _make(level: int = 1) -> NavigationFilterWrapper:
    env = gym.make("uvdms/CircleTrack-v1", case="random", hydro_randomization=0.3, realism=level)
    return NavigationFilterWrapper(env)


def _actions(n: int) -> np.ndarray:
    return np.random.default_rng(0).uniform(-0.3, 0.3, (n, 18)).astype(np.float32)


def _check_estimate(env: NavigationFilterWrapper, obs: np.ndarray, info: dict, nav: NavigationFilter) -> None:
    """The observation and info state keys are those of the independent filter's estimate."""
    eta, nu, q, qdot = nav.state()
    for key, value in zip(("eta", "nu", "q", "qdot"), (eta, nu, q, qdot), strict=True):
        np.testing.assert_array_equal(info[key], value, err_msg=key)
    expected, keys = env.unwrapped.observe_estimate(eta, nu, q, qdot)
    np.testing.assert_array_equal(obs, expected)
    np.testing.assert_array_equal(info["y"], keys["y"])
    truth = env.unwrapped.true_state()
    assert not np.array_equal(info["eta"], truth["eta"])  # the estimate, not the truth


def test_wrapper_observes_the_filter_estimate():
    env = _make()
    base = env.unwrapped
    obs, info = env.reset(seed=SEED)
    # an independent filter fed from what the environment reports
    nav = NavigationFilter(base.realism, base.params, control_dt=base.control_dt, physics_dt=base.physics_dt)
    nav.reset(info["t"], info["measurements"])
    _check_estimate(env, obs, info, nav)
    for action in _actions(STEPS):
        obs, _, terminated, truncated, info = env.step(action)
        nav.update(info["t"], info["measurements"], info["tau_cmd"])
        _check_estimate(env, obs, info, nav)
        assert not (terminated or truncated)
    assert env.observation_space.contains(obs)
    env.close()


def test_wrapper_needs_a_realism_level():
    env = gym.make("uvdms/CircleTrack-v1")
    with pytest.raises(ValueError, match="realism"):
        NavigationFilterWrapper(env)
    env.close()


def test_check_env_passes_on_the_wrapped_env():
    env = _make()
    check_env(env, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("how", ["pickle", "deepcopy"])
def test_copies_continue_as_the_original(how):
    env = _make()
    env.reset(seed=SEED)
    actions = _actions(2 * STEPS)
    for action in actions[:STEPS]:
        env.step(action)
    twin = pickle.loads(pickle.dumps(env)) if how == "pickle" else copy.deepcopy(env)
    np.testing.assert_array_equal(twin.filter.P, env.filter.P)
    for action in actions[STEPS:]:
        obs_a, reward_a, *_, info_a = env.step(action)
        obs_b, reward_b, *_, info_b = twin.step(action)
        np.testing.assert_array_equal(obs_a, obs_b)
        np.testing.assert_array_equal(info_a["eta"], info_b["eta"])
        assert reward_a == reward_b
    env.close()
    twin.close()


class _Keep:
    """A controller that keeps what it is handed and holds still."""

    def __init__(self) -> None:
        self.seen: list[tuple[np.ndarray, dict]] = []

    def reset(self, seed=None) -> None:
        self.seen.clear()

    def predict(self, obs, info):
        self.seen.append((obs, info))
        return np.zeros(18, dtype=np.float32)


def test_filtered_controller_hands_the_estimate_and_passes_through_at_level_zero():
    from uvdms_gym.realism.navigation import FilteredController

    env = gym.make("uvdms/TransportObstacles-v1", current="random", realism=2)
    base = env.unwrapped
    inner = _Keep()
    controller = FilteredController(inner, env)
    obs, info = env.reset(seed=SEED)
    controller.reset(SEED)
    nav = NavigationFilter(base.realism, base.params, control_dt=base.control_dt, physics_dt=base.physics_dt)
    for k in range(STEPS):
        action = controller.predict(obs, info)
        if k == 0:
            nav.reset(info["t"], info["measurements"])
        else:
            nav.update(info["t"], info["measurements"], info["tau_cmd"])
        seen_obs, seen_info = inner.seen[-1]
        expected, _ = base.observe_estimate(*nav.state(), info["obstacles"])  # the sonar's rows, not the truth
        np.testing.assert_array_equal(seen_obs, expected)
        np.testing.assert_array_equal(seen_info["eta"], nav.state()[0])
        np.testing.assert_array_equal(seen_info["obstacles"], info["obstacles"])
        obs, _, _, _, info = env.step(action)
    env.close()
    oracle = gym.make("uvdms/CircleTrack-v1")
    inner = _Keep()
    controller = FilteredController(inner, oracle)
    obs, info = oracle.reset(seed=SEED)
    controller.predict(obs, info)
    assert inner.seen[-1][0] is obs and inner.seen[-1][1] is info
    oracle.close()
