"""Torch threads of a training run: how many CPUs a run holds, and the update's thread count.

The rule (documented in ``docs/CLUSTER_TRAINING.md`` and docs/performance.md):

- A run *holds* :func:`run_cpus` CPUs: 1 with ``--vec-env dummy`` (the trainer steps every env itself),
  ``n_envs`` with ``subproc``, ``hybrid`` or ``rollout`` (one process per env is busy while the envs step). Sweeps and
  ``uvdms tune`` declare this number to Ray.
- While the envs step and the policy picks actions, the trainer uses **one** torch thread: the other CPUs the
  run holds are stepping envs, so a second thread would oversubscribe them.
- During an on-policy algorithm's gradient update (PPO's ``train()`` after each rollout) every env is idle,
  so the trainer uses :func:`update_threads` threads: all the CPUs the run holds (at most the CPUs this
  process may use). With 1 env that is 1 thread, so a ``dummy`` run never uses more than its one CPU.
  :class:`UpdateThreads` switches between the two counts at the rollout boundaries.
- Off-policy algorithms (SAC, TD3, TQC) keep one thread throughout: their gradient steps interleave with every
  vector step, so the count would switch on every step (not measured); SAC with 2 envs already runs 1.8-1.9x the
  env steps of 1 env (with ``gradient_steps: 1`` per vector step it also halves the updates per env step).
"""

from __future__ import annotations

import os

import torch
from stable_baselines3.common.callbacks import BaseCallback

ROLLOUT_THREADS = 1
"""Torch threads while the envs step (see the module)."""


def available_cpus() -> int:
    """CPUs this process may run on (its affinity where the platform tells it, else the machine's count)."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except (AttributeError, OSError):
        return max(os.cpu_count() or 1, 1)


def run_cpus(n_envs: int, vec_env: str) -> int:
    """CPUs a run keeps busy: 1 with ``dummy`` envs (stepped by the trainer), ``n_envs`` otherwise."""
    return 1 if vec_env == "dummy" else max(int(n_envs), 1)


def update_threads(n_envs: int, vec_env: str, on_policy: bool) -> int:
    """Torch threads of the gradient update (see the module): the run's CPUs for on-policy algorithms, else 1.

    Args:
        n_envs: Training envs.
        vec_env: ``dummy``, ``subproc``, ``hybrid`` or ``rollout``.
        on_policy: Whether the algorithm updates after whole rollouts (PPO, A2C).

    Returns:
        A thread count >= 1, at most :func:`available_cpus`.
    """
    if not on_policy:
        return ROLLOUT_THREADS
    return max(min(run_cpus(n_envs, vec_env), available_cpus()), ROLLOUT_THREADS)


class UpdateThreads(BaseCallback):
    """Sets ``torch.set_num_threads(update)`` for each gradient update and 1 thread for each rollout.

    SB3's on-policy ``learn`` calls ``on_rollout_end`` right before ``train()`` and ``on_rollout_start`` before
    the next rollout, so the update runs with ``update`` threads while every env is idle. At the end of
    training the rollout count is restored.

    Args:
        update: Threads of the update (>= 1), usually :func:`update_threads`.
    """

    def __init__(self, update: int) -> None:
        super().__init__()
        if not (isinstance(update, int) and update >= 1):
            raise ValueError(f"UpdateThreads: update must be an integer >= 1, got {update!r}")
        self.update = update

    def _on_rollout_start(self) -> None:
        torch.set_num_threads(ROLLOUT_THREADS)

    def _on_rollout_end(self) -> None:
        torch.set_num_threads(self.update)

    def _on_step(self) -> bool:
        return True

    def _on_training_end(self) -> None:
        torch.set_num_threads(ROLLOUT_THREADS)
