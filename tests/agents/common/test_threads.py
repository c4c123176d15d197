"""Torch threads of training (agents/common/threads.py): the rule, the switch at rollout boundaries, the training."""

from __future__ import annotations

from typing import ClassVar

import gymnasium as gym
import pytest
import torch
from stable_baselines3 import PPO

from agents.common.envs import EnvFactory, make_vec_env
from agents.common.threads import ROLLOUT_THREADS, UpdateThreads, available_cpus, run_cpus, update_threads

ENV_ID = "uvdms/CircleTrack-v0"


def _factories(n: int) -> list[EnvFactory]:
    return [EnvFactory(ENV_ID, {"case": "random"}, max_episode_steps=40) for _ in range(n)]


def test_update_thread_rule():
    cpus = available_cpus()
    assert cpus >= 1
    assert update_threads(1, "dummy", on_policy=True) == 1
    assert update_threads(2, "dummy", on_policy=True) == 1  # a dummy run holds one CPU whatever its n_envs
    assert update_threads(2, "hybrid", on_policy=True) == min(2, cpus)
    assert update_threads(64, "subproc", on_policy=True) == min(64, cpus)
    assert update_threads(2, "subproc", on_policy=False) == 1  # off-policy updates interleave with env steps
    assert update_threads(2, "hybrid", on_policy=True) <= run_cpus(2, "hybrid")
    with pytest.raises(ValueError, match="integer >= 1"):
        UpdateThreads(0)


class _ThreadProbe(gym.Wrapper):
    """Records torch's thread count at every env step (the env runs in the trainer's process)."""

    seen: ClassVar[list[int]] = []

    def step(self, action):
        _ThreadProbe.seen.append(torch.get_num_threads())
        return super().step(action)


def test_update_runs_with_more_threads_and_rollouts_with_one():
    torch.set_num_threads(ROLLOUT_THREADS)
    _ThreadProbe.seen = []
    venv = make_vec_env([lambda: _ThreadProbe(EnvFactory(ENV_ID, {"case": 1}, max_episode_steps=40)())], "dummy")
    during_update: list[int] = []
    try:
        model = PPO("MlpPolicy", venv, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu")
        train = model.train

        def recording_train() -> None:
            during_update.append(torch.get_num_threads())
            train()

        model.train = recording_train  # type: ignore[method-assign]
        model.learn(total_timesteps=96, callback=UpdateThreads(2))
    finally:
        venv.close()
    assert during_update == [2, 2, 2]
    assert _ThreadProbe.seen and set(_ThreadProbe.seen) == {ROLLOUT_THREADS}
    assert torch.get_num_threads() == ROLLOUT_THREADS  # restored at the end of training


PARAMETER_ATOL = 3e-5
"""Parameters after training with 2 update threads agree with 1 thread to this (absolute, float32 parameters).

torch does not promise bit identity across thread counts: with 2 threads a matrix product may sum in another
order (it does on an Intel Xeon with MKL, not on AMD EPYC), and rounding differences grow through the updates
and the rollouts that follow. Other CPU kernels give the same kind of difference: the test's training with
``MKL_CBWR=COMPATIBLE`` or ``ATEN_CPU_CAPABILITY=default`` moved parameters by up to 3.9e-6 and 2.0e-6 (AMD EPYC),
while training moves them by up to 1.2e-3; so 3e-5 holds on any x86-64 CPU and a change of what is trained (other
minibatches, another seed, a lost update) exceeds it.
"""


def _train_ppo(threads: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The shipped PPO sizes (batch 256, 256-wide layers): parameters before and after 512 steps."""
    torch.set_num_threads(ROLLOUT_THREADS)
    venv = make_vec_env(_factories(2), "hybrid")
    try:
        model = PPO(
            "MlpPolicy",
            venv,
            n_steps=128,
            batch_size=256,
            n_epochs=2,
            seed=5,
            device="cpu",
            policy_kwargs={"net_arch": {"pi": [256, 256], "vf": [256, 256]}},
        )
        before = torch.nn.utils.parameters_to_vector(model.policy.parameters()).detach().clone()
        model.learn(total_timesteps=512, callback=UpdateThreads(threads) if threads > 1 else None)
        return before, torch.nn.utils.parameters_to_vector(model.policy.parameters()).detach().clone()
    finally:
        venv.close()


@pytest.mark.portability
def test_two_update_threads_train_the_parameters_of_one_thread_to_rounding():
    """2 update threads train what 1 thread trains, equal to ``PARAMETER_ATOL`` (not bit for bit: see there)."""
    before, one = _train_ppo(1)
    _, two = _train_ppo(2)
    assert (one - before).abs().max() > 10 * PARAMETER_ATOL  # training moves them: the comparison can fail
    torch.testing.assert_close(two, one, rtol=0.0, atol=PARAMETER_ATOL)
