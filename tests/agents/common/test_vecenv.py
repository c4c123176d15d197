"""``HybridVecEnv`` (agents/common/vecenv.py): the same transitions and the same training as ``DummyVecEnv``."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv

from agents.common.envs import EnvFactory, make_vec_env
from agents.common.vecenv import HybridVecEnv

ENV_ID = "uvdms/CircleTrack-v0"


def _factories(n: int, max_episode_steps: int = 30) -> list[EnvFactory]:
    # case=random: every env draws its circle from its own seed, so a seed mix-up changes the observations
    return [EnvFactory(ENV_ID, {"case": "random"}, max_episode_steps=max_episode_steps) for _ in range(n)]


def _rollout(venv, steps: int, seed: int) -> list:
    rng = np.random.default_rng(seed)
    venv.seed(seed)
    out = [venv.reset()]
    for _ in range(steps):
        actions = rng.uniform(-1.0, 1.0, size=(venv.num_envs, *venv.action_space.shape)).astype(np.float32)
        obs, rew, done, infos = venv.step(actions)
        out.append(
            (obs, rew, done, [(i.get("TimeLimit.truncated"), i.get("terminal_observation"), i["t"]) for i in infos])
        )
    return out


def _assert_same(a, b) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        if isinstance(x, tuple | list):
            _assert_same(x, y)
        elif isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and x.shape == y.shape
            np.testing.assert_array_equal(x, y)
        else:
            assert x == y


@pytest.mark.portability
def test_hybrid_steps_exactly_like_dummy():
    """3 envs over 75 steps with two automatic resets each (30-step episodes): bit-identical obs, rewards,
    dones, truncation flags and terminal observations; per-env seeds seed + i as in DummyVecEnv."""
    dummy = make_vec_env(_factories(3), "dummy")
    hybrid = make_vec_env(_factories(3), "hybrid")
    assert isinstance(dummy, DummyVecEnv) and isinstance(hybrid, HybridVecEnv)
    try:
        ref = _rollout(dummy, 75, seed=11)
        got = _rollout(hybrid, 75, seed=11)
        _assert_same(ref, got)
        assert sum(bool(d.any()) for _, _, d, _ in ref[1:]) >= 2  # the episodes did end and reset
        other = _rollout(hybrid, 5, seed=12)  # another seed gives other circles: the seeds reach every env
        assert not np.array_equal(other[0], ref[0])
        # attribute access and methods are routed to the right env, in env order
        assert hybrid.get_attr("spec")[0].id == ENV_ID
        assert hybrid.env_is_wrapped(Monitor) == [True, True, True]
        assert hybrid.env_method("get_episode_rewards", indices=[2, 0]) == dummy.env_method(
            "get_episode_rewards", indices=[2, 0]
        )
        assert len(hybrid.env_method("get_episode_rewards", indices=[2])[0]) == 2  # env 2's two finished episodes
        hybrid.set_attr("marker", 7, indices=[0, 2])
        assert hybrid.get_attr("marker", indices=[0, 2]) == [7, 7]
    finally:
        dummy.close()
        hybrid.close()
    hybrid.close()  # idempotent


@pytest.mark.portability
def test_ppo_trains_identically_on_hybrid_and_dummy():
    """Two PPO updates on 2 envs: the same parameters bit for bit whichever vector env steps them."""
    params = []
    for vec_env in ("dummy", "hybrid"):
        torch.set_num_threads(1)
        venv = make_vec_env(_factories(2, max_episode_steps=40), vec_env)
        try:
            model = PPO("MlpPolicy", venv, n_steps=32, batch_size=32, n_epochs=2, seed=3, device="cpu")
            model.learn(total_timesteps=128)
            params.append(torch.nn.utils.parameters_to_vector(model.policy.parameters()).detach().clone())
        finally:
            venv.close()
    assert torch.equal(params[0], params[1])


def test_bad_vec_env_arguments():
    with pytest.raises(ValueError, match="at least 2 envs"):
        HybridVecEnv(_factories(1))
    with pytest.raises(ValueError, match="spin_s"):
        HybridVecEnv(_factories(2), spin_s=-1.0)
    with pytest.raises(ValueError, match="unknown vec_env 'threads'"):
        make_vec_env(_factories(2), "threads")
    single = make_vec_env(_factories(1), "hybrid")  # one env: nothing to overlap, plain DummyVecEnv
    assert isinstance(single, DummyVecEnv)
    single.close()


def test_scalar_info_keeps_every_scalar_and_drops_only_the_arrays():
    full, scalar = EnvFactory(ENV_ID, {"case": 1})(), EnvFactory(ENV_ID, {"case": 1}, scalar_info=True)()
    try:
        rng = np.random.default_rng(0)
        (_, info_full), (_, info_scalar) = full.reset(seed=4), scalar.reset(seed=4)
        for _ in range(5):
            action = rng.uniform(-1.0, 1.0, 18).astype(np.float32)
            (obs_f, rew_f, *_, info_full), (obs_s, rew_s, *_, info_scalar) = full.step(action), scalar.step(action)
            np.testing.assert_array_equal(obs_f, obs_s)
            assert rew_f == rew_s
            arrays = {k for k, v in info_full.items() if isinstance(v, np.ndarray)}
            assert {"eta", "q", "distances", "tau"} <= arrays
            assert info_scalar == {k: v for k, v in info_full.items() if k not in arrays}
            assert "cost" in info_scalar and "is_success" in info_scalar
    finally:
        full.close()
        scalar.close()
