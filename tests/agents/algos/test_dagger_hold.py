"""DAgger's hold weight (``hold_weight``): the samples whose reference is at rest count more in the imitation loss.

* :func:`reference_at_rest` flags every observation a transport gives once its reference holds (``t >= move_time``,
  the environment's own clock), and none while the reference moves (up to 0.1 s before it stops, where the preview
  rows differ by less than the tolerance).
* The loss with weights is their weighted mean of the per-sample squared errors (numpy), without weights SB3's mean
  squared error, and the hard-example term adds to either.
* ``sample_labelled`` flags the stored (unnormalised) observations it draws; a bad weight is refused by name.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3.common.vec_env import DummyVecEnv

from agents.algos.dagger import PREVIEW_ROWS, PREVIEW_SIZE, DAgger, TeacherReplayBuffer, reference_at_rest
from uvdms_gym.envs.base import PREVIEW_TIMES

MOVE_TIME = 1.0
"""Seconds of the short transports below; then the reference holds."""


def _model(**kwargs) -> DAgger:
    env = DummyVecEnv([lambda: gym.make("uvdms/Transport-v1", max_episode_steps=10)])
    return DAgger("MlpPolicy", env, seed=0, policy_kwargs={"net_arch": [8]}, **kwargs)


def test_the_rest_flags_are_the_transports_hold():
    assert (PREVIEW_ROWS, PREVIEW_SIZE) == (len(PREVIEW_TIMES), 6 * len(PREVIEW_TIMES))
    env = gym.make("uvdms/Transport-v1", action_mode="velocity", move_time=MOVE_TIME, max_episode_steps=60)
    obs, _ = env.reset(seed=4)
    observations, times = [obs], [env.unwrapped.t]
    for _ in range(59):
        obs, *_ = env.step(np.zeros(18, dtype=np.float32))
        observations.append(obs)
        times.append(env.unwrapped.t)
    env.close()
    flags, times = reference_at_rest(np.array(observations)), np.array(times)
    assert flags[times >= MOVE_TIME].all() and (times >= MOVE_TIME).sum() >= 30
    assert not flags[times < MOVE_TIME - 0.1].any()


def test_the_weighted_loss_is_the_weighted_mean_of_the_squared_errors():
    rng = np.random.default_rng(0)
    actions, labels = rng.uniform(-1, 1, (64, 18)), rng.uniform(-1, 1, (64, 18))
    weights = 1.0 + 3.0 * (rng.uniform(size=64) < 0.2)
    per_sample = ((actions - labels) ** 2).mean(axis=1)
    as_torch = [torch.as_tensor(x) for x in (actions, labels, weights)]
    model = _model(hold_weight=3.0)
    assert float(model.imitation_loss(*as_torch)) == pytest.approx(np.sum(weights * per_sample) / np.sum(weights))
    assert float(model.imitation_loss(*as_torch[:2])) == pytest.approx(per_sample.mean())
    hard = _model(hold_weight=3.0, hard_fraction=0.25)
    top = np.sort(per_sample)[-16:].mean()
    assert float(hard.imitation_loss(*as_torch)) == pytest.approx(np.sum(weights * per_sample) / np.sum(weights) + top)


def test_sampled_batches_flag_their_stored_observations():
    model = _model(hold_weight=3.0)
    buffer = model.replay_buffer
    assert isinstance(buffer, TeacherReplayBuffer)
    rng = np.random.default_rng(1)
    dim = model.observation_space.shape[0]
    for k in range(40):
        obs = rng.normal(size=(1, dim)).astype(np.float32)
        if k % 3 == 0:  # every preview row the same: a reference at rest
            obs[0, 6:PREVIEW_SIZE] = np.tile(obs[0, :6], 2)
        info = {"teacher_residual": np.zeros(18, dtype=np.float32)}
        buffer.add(obs, obs, np.zeros((1, 18)), np.zeros(1), np.zeros(1), [info])
    np.random.seed(7)  # noqa: NPY002 - the buffer draws from NumPy's global generator, as SB3's do
    assert buffer.sample_labelled(5)[2] is None  # flags only when asked
    obs, _, flags = buffer.sample_labelled(200, rest_flags=True)
    stored = buffer.observations[:40, 0]
    drawn = [int(np.flatnonzero((stored == row).all(axis=1))[0]) for row in obs.numpy()]
    assert flags.dtype == bool and 0 < flags.sum() < 200
    assert np.array_equal(flags, np.array(drawn) % 3 == 0)


@pytest.mark.parametrize("value", [-1.0, float("nan"), True])
def test_a_bad_hold_weight_is_refused_by_name(value):
    with pytest.raises(ValueError, match="hold_weight must be a finite number >= 0"):
        _model(hold_weight=value)


def test_an_observation_without_a_preview_is_refused_by_name():
    with pytest.raises(ValueError, match="hold_weight needs the observations of a UVDMS environment"):
        reference_at_rest(np.zeros((4, 3)))
