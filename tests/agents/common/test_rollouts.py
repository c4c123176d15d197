"""Parallel PPO rollouts (agents/common/rollouts.py, ``--vec-env rollout``).

* One rollout on 2 envs (env 1 in a worker) inside ``VecNormalize``: replaying each env from its seed with the
  buffer's clipped actions gives the buffer's observations (normalised with the rollout's starting statistics),
  episode starts and rewards (normalised by an independent replay of the return statistics, plus the discounted
  value of each truncated episode's terminal observation); the buffer's values and log-probabilities are the
  policy's; the observation statistics afterwards are those of sequential updates with the replayed observations.
* A run is reproducible from its seed; with any other vector env the class is SB3's PPO, bit for bit.
* A callback that stops training stops the rollout and leaves the env usable; worker errors come back with
  their traceback; algorithms other than PPO are refused by name.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3 import PPO as SB3PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from agents.common.envs import EnvFactory, make_vec_env
from agents.common.rollouts import COLLECT_METHOD, ObsNormalization, RolloutPPO, RolloutVecEnv
from agents.common.threads import run_cpus
from agents.config import ConfigError
from agents.training.train import train

ENV = "Pendulum-v1"
EPISODE = 30  # shorter than a rollout: every part holds truncations and resets
N_STEPS = 64
GAMMA = 0.9
SEED = 3
PPO_KWARGS = {"n_steps": N_STEPS, "batch_size": 64, "n_epochs": 2, "gamma": GAMMA, "policy_kwargs": {"net_arch": [16]}}


def _factory() -> EnvFactory:
    return EnvFactory(ENV, {}, (), max_episode_steps=EPISODE)


def _venv(kind: str, n: int = 2, normalize: bool = True):
    venv = make_vec_env([_factory() for _ in range(n)], kind)
    venv.seed(SEED)
    return VecNormalize(venv, gamma=GAMMA) if normalize else venv


class _Stop(BaseCallback):
    def __init__(self, after: int) -> None:
        super().__init__()
        self.after = after
        self.calls = 0

    def _on_step(self) -> bool:
        self.calls += 1
        return self.calls < self.after


def _normalize(obs: np.ndarray, mean: np.ndarray, var: np.ndarray) -> np.ndarray:
    return np.clip((obs - mean) / np.sqrt(var + 1e-8), -10.0, 10.0).astype(np.float32)


@pytest.mark.portability
def test_a_parallel_rollout_is_the_replay_of_its_envs_and_of_vecnormalize():
    env = _venv("rollout")
    try:
        assert isinstance(env.venv, RolloutVecEnv)
        model = RolloutPPO("MlpPolicy", env, seed=SEED, **PPO_KWARGS)
        _, callback = model._setup_learn(N_STEPS * 2, None)  # resets the envs (one VecNormalize update)
        mean0, var0, count0 = env.obs_rms.mean.copy(), env.obs_rms.var.copy(), env.obs_rms.count
        assert model.collect_rollouts(env, callback, model.rollout_buffer, N_STEPS)
        buf = model.rollout_buffer
        assert model.num_timesteps == 2 * N_STEPS

        low, high = env.action_space.low, env.action_space.high
        replayed_obs = np.empty((N_STEPS, 2, 3), np.float32)  # the env's dtype, as VecNormalize receives them
        raw_rewards = np.empty((N_STEPS, 2))
        terminals: dict[tuple[int, int], np.ndarray] = {}
        for i in range(2):
            raw_env = gym.make(ENV, max_episode_steps=EPISODE)
            obs, _ = raw_env.reset(seed=SEED + i)
            start = True
            for t in range(N_STEPS):
                np.testing.assert_array_equal(buf.observations[t, i], _normalize(obs, mean0, var0))
                assert buf.episode_starts[t, i] == float(start)
                obs, raw_rewards[t, i], terminated, truncated, _ = raw_env.step(np.clip(buf.actions[t, i], low, high))
                start = terminated or truncated
                if start:
                    assert truncated and not terminated  # (Pendulum only truncates)
                    terminals[t, i] = obs
                    obs, _ = raw_env.reset()
                replayed_obs[t, i] = obs
            raw_env.close()
        assert sorted(terminals) == [(t, i) for t in range(EPISODE - 1, N_STEPS, EPISODE) for i in range(2)]
        assert len(model.ep_info_buffer) == len(terminals)  # both envs' Monitor episodes

        # rewards: an independent replay of VecNormalize's return statistics (gamma-discounted running return),
        # plus gamma V(terminal observation) on a truncation
        ret_rms, returns = RunningMeanStd(shape=()), np.zeros(2)
        for t in range(N_STEPS):
            returns = returns * GAMMA + raw_rewards[t]
            ret_rms.update(returns)
            expected = np.clip(raw_rewards[t] / np.sqrt(ret_rms.var + 1e-8), -10, 10).astype(np.float32)
            for i in range(2):
                if (t, i) in terminals:
                    with th.no_grad():
                        value = model.policy.predict_values(
                            th.as_tensor(_normalize(terminals[t, i], mean0, var0)[None])
                        )
                    expected[i] += GAMMA * float(value[0, 0])
                    returns[i] = 0.0
                assert buf.rewards[t, i] == pytest.approx(expected[i], rel=1e-5, abs=1e-6)

        # values and log-probabilities are the (unchanged) policy's on the stored observations and actions
        obs_t = th.as_tensor(buf.observations.reshape(-1, 3))
        with th.no_grad():
            values, log_probs, _ = model.policy.evaluate_actions(obs_t, th.as_tensor(buf.actions.reshape(-1, 1)))
        np.testing.assert_allclose(buf.values.reshape(-1), values.numpy().reshape(-1), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(buf.log_probs.reshape(-1), log_probs.numpy(), rtol=1e-5, atol=1e-5)

        # the observation statistics: the starting ones updated with each step's two raw observations in turn
        rms = RunningMeanStd(shape=(3,))
        rms.mean, rms.var, rms.count = mean0, var0, count0
        for t in range(N_STEPS):
            rms.update(replayed_obs[t])
        np.testing.assert_allclose(env.obs_rms.mean, rms.mean, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(env.obs_rms.var, rms.var, rtol=1e-10, atol=1e-12)
        np.testing.assert_array_equal(model._last_obs, _normalize(replayed_obs[-1], env.obs_rms.mean, env.obs_rms.var))
    finally:
        env.close()


def _trained(kind: str, algo_cls: type = RolloutPPO, seed: int = SEED) -> list[np.ndarray]:
    env = _venv(kind)
    try:
        model = algo_cls("MlpPolicy", env, seed=seed, **PPO_KWARGS)
        model.learn(2 * 2 * N_STEPS)
        return [p.detach().numpy().copy() for p in model.policy.parameters()]
    finally:
        env.close()


@pytest.mark.portability
def test_a_parallel_run_is_reproducible_from_its_seed():
    first, again, other = _trained("rollout"), _trained("rollout"), _trained("rollout", seed=SEED + 1)
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a, b)
    assert any(np.any(a != c) for a, c in zip(first, other, strict=True))


def test_on_other_vector_envs_it_is_sb3_ppo_bit_for_bit():
    for a, b in zip(_trained("dummy"), _trained("dummy", SB3PPO), strict=True):
        np.testing.assert_array_equal(a, b)
    assert isinstance(make_vec_env([_factory()], "rollout"), DummyVecEnv)  # one env: nothing to parallelise
    assert run_cpus(2, "rollout") == 2


def test_a_stopping_callback_ends_the_rollout_and_the_envs_stay_usable():
    env = _venv("rollout")
    try:
        model = RolloutPPO("MlpPolicy", env, seed=SEED, **PPO_KWARGS)
        stop = _Stop(after=5)
        model.learn(4 * N_STEPS, callback=stop)
        assert stop.calls == 5 and model.num_timesteps == 10
        model.learn(2 * N_STEPS, reset_num_timesteps=False)  # the worker's part was received: the pipe is in step
        assert model.num_timesteps == 10 + 2 * N_STEPS
    finally:
        env.close()


def test_a_failing_worker_reports_its_traceback():
    venv = make_vec_env([_factory(), _factory()], "rollout")
    try:
        venv.reset()
        payload = {"policy": None, "state": {}, "seed": 0, "n_steps": 4, "normalization": ObsNormalization()}
        venv.remote.remotes[0].send(("env_method", (COLLECT_METHOD, (payload,), {})))
        with pytest.raises(RuntimeError, match=r"(?s)rollout worker of env 1 failed.*no policy received"):
            venv.finish_parts()
    finally:
        venv.close()


@pytest.mark.parametrize(
    ("algo", "hyperparams", "message"),
    [
        ("sac", {}, "for ppo, ppo_lagrangian only, not sac"),
        ("ppo", {"use_sde": True}, "does not support gSDE"),
    ],
)
def test_rollout_vec_env_is_refused_for_other_algorithms_before_a_run_exists(tmp_path, algo, hyperparams, message):
    with pytest.raises(ConfigError, match=message):
        train(algo, ENV, vec_env="rollout", hyperparams=hyperparams, out_dir=tmp_path, gym_packages=(), progress=False)
    assert not any(tmp_path.iterdir())
