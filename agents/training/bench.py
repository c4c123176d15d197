"""Training throughput: ``uvdms bench train [--json] [--quick]``.

Environment steps per second of the training loop (``model.learn``: environment steps, policy inference and
gradient updates; no evaluation or checkpoint callbacks) for PPO and SAC, each with 1 training env
(``DummyVecEnv``), 2 envs in worker processes (``SubprocVecEnv``, key ``"2"``), 2 envs stepped in the
trainer's process (``DummyVecEnv``, key ``"2_dummy"``, the ``--vec-env`` default) and 2 envs of which one
steps in the trainer's process while the other steps in a worker (:class:`agents.common.vecenv.HybridVecEnv`, key
``"2_hybrid"``, ``--vec-env hybrid``) and, for PPO, 2 envs each collecting its part of every rollout with its own
policy copy (:mod:`agents.common.rollouts`, key ``"2_rollout"``, ``--vec-env rollout``), on ``uvdms/CircleTrack-v0``
(``case=1``) with the configurations of ``train_configs/<algo>.yml``. SAC's ``learning_starts`` is lowered
to 100 steps so that its blocks include the gradient steps of steady-state training.

The models (five for PPO, four for SAC) are built first, then timed in alternating blocks (PPO: one rollout of
``n_steps x n_envs`` steps and its update; SAC: a fixed number of environment steps), so a change in machine
load affects all alike; the figures are medians over blocks and ``speedup_2_vs_1`` is the ratio of the
medians (``speedup_2_dummy_vs_1``, ``speedup_2_hybrid_vs_1`` and ``speedup_2_rollout_vs_1`` likewise).
``speedup_2_vs_1_paired`` (and ``_dummy``/``_hybrid``/``_rollout``) is the median over rounds of the ratio of the
two models' blocks of the same round (seconds apart), which cancels the machine's slower drifts (a shared VM's
speed can change 2x within minutes).
The load average before and after is part of the result: timings taken beside other jobs are only indicative.

Threads (:mod:`agents.common.threads`, as :func:`agents.training.train.train` sets them): one torch thread in the
trainer while
the envs step and the policy acts, and each env worker sets one too (:class:`agents.common.envs.EnvFactory`). PPO's
gradient update after each rollout runs with as many threads as the run holds CPUs (1 with ``dummy`` envs,
``n_envs`` with ``subproc`` or ``hybrid``: every env is idle then); SAC keeps one thread (its updates interleave
with single env steps). With ``SubprocVecEnv`` the two workers step the physics while the trainer waits for
them; with ``HybridVecEnv`` the trainer and its one worker step at the same time. Either way at most two busy
threads at a time, so the 2 cores are not oversubscribed. Each entry records its ``torch_update_threads``.
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np

BENCH_ENV = "uvdms/CircleTrack-v0"
BENCH_ENV_KWARGS: dict[str, Any] = {"case": 1}
SAC_LEARNING_STARTS = 100
DEFAULT_BLOCKS: dict[str, int] = {"ppo": 5, "sac": 3}
"""Timed blocks per model (PPO's blocks are short, and its 2-env ratio is the noisier figure on a shared VM)."""


CONFIGURATIONS: tuple[tuple[str, int, str], ...] = (
    ("1", 1, "dummy"),
    ("2", 2, "subproc"),
    ("2_dummy", 2, "dummy"),
    ("2_hybrid", 2, "hybrid"),
    ("2_rollout", 2, "rollout"),
)
"""(result key, n_envs, vec_env) of the timed models (``rollout``: PPO only, :mod:`agents.common.rollouts`)."""


def _build(algo: str, n_envs: int, vec_env: str, total_steps: int, seed: int = 0) -> Any:
    """A model of ``train_configs/<algo>.yml`` on ``n_envs`` training envs of type ``vec_env``.

    ``total_steps`` caps the replay buffer (:func:`agents.training.models.replay_buffer_size`).
    """
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.algos import ALGOS, is_off_policy
    from agents.common.envs import EnvFactory, make_vec_env
    from agents.config import default_config_path, load_config
    from agents.training.models import configured_buffer_size, replay_buffer_size

    overrides: dict[str, Any] = {"n_envs": n_envs, "env_kwargs": {"action_mode": "velocity", **BENCH_ENV_KWARGS}}
    if is_off_policy(algo):
        overrides["learning_starts"] = SAC_LEARNING_STARTS
    cfg = load_config(default_config_path(algo), algo, BENCH_ENV, overrides=overrides)
    factories = [
        EnvFactory(
            BENCH_ENV, cfg.env_kwargs, alive_bonus=cfg.alive_bonus, action_scale=cfg.action_scale, scalar_info=True
        )
        for _ in range(n_envs)
    ]
    venv = make_vec_env(factories, vec_env)
    normalize_kwargs = cfg.normalize_kwargs()
    if normalize_kwargs is not None:
        venv = VecNormalize(venv, **normalize_kwargs)
    kwargs = cfg.sb3_hyperparams()
    if is_off_policy(algo):
        kwargs["buffer_size"] = replay_buffer_size(configured_buffer_size(cfg), n_envs, total_steps)
    model = ALGOS[algo](cfg.policy, venv, policy_kwargs=cfg.sb3_policy_kwargs(), seed=seed, verbose=0, **kwargs)
    # a logger that writes nothing: without one, SB3 makes an empty SB3-<date> folder in the temp directory per learn
    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


def _block(model: Any, steps: int, update_threads: int = 1) -> tuple[int, float]:
    """Run ``model.learn`` for ``steps`` more steps; return the steps actually run and the wall time.

    ``update_threads`` > 1 runs each on-policy update with that many torch threads, as
    :func:`agents.training.train.train`
    does (:class:`agents.common.threads.UpdateThreads`).
    """
    from agents.common.threads import UpdateThreads

    before = model.num_timesteps
    callback = UpdateThreads(update_threads) if update_threads > 1 else None
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps, reset_num_timesteps=False, progress_bar=False, callback=callback)
    return model.num_timesteps - before, time.perf_counter() - t0


def bench_train(quick: bool = False, *, blocks: int | None = None, sac_block_steps: int | None = None) -> dict:
    """Training steps per second of PPO and SAC with 1 and 2 envs (see the module docstring).

    Args:
        quick: Fewer and shorter blocks.
        blocks: Timed blocks per model (default :data:`DEFAULT_BLOCKS` per algorithm, quick 1).
        sac_block_steps: Environment steps per SAC block (default 1000, quick 200).

    Returns:
        ``{"ppo": {"1": {...}, "2": {...}, "2_dummy": {...}, "2_hybrid": {...}, "speedup_2_vs_1": r, ...},
        "sac": {...},
        "load_avg_before": [...], ...}``; each entry has ``n_envs``, ``vec_env``, ``block_steps``, ``steps_per_s``
        (median over blocks) and ``blocks_steps_per_s``.
    """
    import torch

    from agents.algos import is_off_policy
    from agents.common.rollouts import ROLLOUT_ALGOS
    from agents.common.threads import update_threads

    torch.set_num_threads(1)
    sac_steps = sac_block_steps if sac_block_steps is not None else (200 if quick else 1000)
    result: dict[str, Any] = {
        "env_id": BENCH_ENV,
        "env_kwargs": BENCH_ENV_KWARGS,
        "cpu_count": os.cpu_count(),
        "torch_num_threads": torch.get_num_threads(),
        "load_avg_before": list(os.getloadavg()),
    }
    for algo in ("ppo", "sac"):
        n_blocks = blocks if blocks is not None else (1 if quick else DEFAULT_BLOCKS[algo])
        total = (n_blocks + 1) * sac_steps + SAC_LEARNING_STARTS + 2
        configurations = [c for c in CONFIGURATIONS if c[2] != "rollout" or algo in ROLLOUT_ALGOS]
        models = {key: _build(algo, n, vec_env, total) for key, n, vec_env in configurations}
        n_envs = {key: n for key, n, _ in configurations}
        threads = {key: update_threads(n, vec_env, not is_off_policy(algo)) for key, n, vec_env in configurations}
        try:
            # PPO: one rollout of n_steps x n_envs and its update per block; SAC: sac_steps environment steps
            sizes = {key: int(m.n_steps) * n_envs[key] if algo == "ppo" else sac_steps for key, m in models.items()}
            for key, model in models.items():  # warm-up: past SAC's learning_starts, PPO's first update
                _block(model, sizes[key] if algo == "ppo" else max(sac_steps, SAC_LEARNING_STARTS + 2), threads[key])
            rates: dict[str, list[float]] = {key: [] for key in models}
            for _ in range(n_blocks):
                for key, model in models.items():
                    steps, seconds = _block(model, sizes[key], threads[key])
                    rates[key].append(steps / seconds)
        finally:
            for model in models.values():
                model.get_env().close()
        entry: dict[str, Any] = {}
        for key, n, vec_env in configurations:
            entry[key] = {
                "n_envs": n,
                "vec_env": vec_env,
                "block_steps": sizes[key],
                "torch_update_threads": threads[key],
                "steps_per_s": float(np.median(rates[key])),
                "blocks_steps_per_s": rates[key],
            }
        for key in models:
            if key == "1":
                continue
            suffix = key[1:]  # "2" -> "", "2_hybrid" -> "_hybrid"
            entry[f"speedup_2{suffix}_vs_1"] = entry[key]["steps_per_s"] / entry["1"]["steps_per_s"]
            paired = [two / one for two, one in zip(rates[key], rates["1"], strict=True)]
            entry[f"speedup_2{suffix}_vs_1_paired"] = float(np.median(paired))
        result[algo] = entry
    result["load_avg_after"] = list(os.getloadavg())
    return result
