"""Training throughput: ``uvdms bench train [--json] [--quick]``.

Environment steps per second of the training loop (``model.learn``: environment steps, policy inference and
gradient updates; no evaluation or checkpoint callbacks) for PPO and SAC, each with 1 training env
(``DummyVecEnv``) and 2 (``SubprocVecEnv``: one worker process per env), on ``uvdms/CircleTrack-v0``
(``case=1``) with the configurations of ``train_configs/<algo>.yml``. SAC's ``learning_starts`` is lowered
to 100 steps so that its blocks include the gradient steps of steady-state training.

The models of 1 and 2 envs are built first, then timed in alternating blocks (PPO: one rollout of
``n_steps x n_envs`` steps and its update; SAC: a fixed number of environment steps), so a change in machine
load affects both alike; the figures are medians over blocks and ``speedup_2_vs_1`` is the ratio of the
medians. The load average before and after is part of the result: timings taken beside other jobs are
only indicative.

Threads: the trainer runs ``torch.set_num_threads(1)`` (as :func:`agents.train.train` does), and each env
worker sets it too (:class:`agents.train.EnvFactory`). With 2 envs on 2 cores the two workers step the
physics while the trainer waits for them, then the trainer runs inference or an update while the workers
wait: at most two busy processes at a time, so one torch thread per process does not oversubscribe the cores.
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np

BENCH_ENV = "uvdms/CircleTrack-v0"
BENCH_ENV_KWARGS: dict[str, Any] = {"case": 1}
SAC_LEARNING_STARTS = 100


def _build(algo: str, n_envs: int, total_steps: int, seed: int = 0) -> Any:
    """A model of ``train_configs/<algo>.yml`` on ``n_envs`` training envs (subprocesses when > 1).

    ``total_steps`` caps the replay buffer (:func:`agents.train.replay_buffer_size`).
    """
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.algos import ALGOS, is_off_policy
    from agents.config import default_config_path, load_config
    from agents.train import EnvFactory, _configured_buffer_size, _make_vec_env, replay_buffer_size

    overrides: dict[str, Any] = {"n_envs": n_envs, "env_kwargs": {"action_mode": "velocity", **BENCH_ENV_KWARGS}}
    if is_off_policy(algo):
        overrides["learning_starts"] = SAC_LEARNING_STARTS
    cfg = load_config(default_config_path(algo), algo, BENCH_ENV, overrides=overrides)
    factories = [
        EnvFactory(BENCH_ENV, cfg.env_kwargs, alive_bonus=cfg.alive_bonus, action_scale=cfg.action_scale)
        for _ in range(n_envs)
    ]
    venv = _make_vec_env(factories, "subproc" if n_envs > 1 else "dummy")
    normalize_kwargs = cfg.normalize_kwargs()
    if normalize_kwargs is not None:
        venv = VecNormalize(venv, **normalize_kwargs)
    kwargs = cfg.sb3_hyperparams()
    if is_off_policy(algo):
        kwargs["buffer_size"] = replay_buffer_size(_configured_buffer_size(cfg), n_envs, total_steps)
    return ALGOS[algo](cfg.policy, venv, policy_kwargs=cfg.sb3_policy_kwargs(), seed=seed, verbose=0, **kwargs)


def _block(model: Any, steps: int) -> tuple[int, float]:
    """Run ``model.learn`` for ``steps`` more steps; return the steps actually run and the wall time."""
    before = model.num_timesteps
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps, reset_num_timesteps=False, progress_bar=False)
    return model.num_timesteps - before, time.perf_counter() - t0


def bench_train(quick: bool = False, *, blocks: int | None = None, sac_block_steps: int | None = None) -> dict:
    """Training steps per second of PPO and SAC with 1 and 2 envs (see the module docstring).

    Args:
        quick: Fewer and shorter blocks.
        blocks: Timed blocks per model (default 3, quick 1).
        sac_block_steps: Environment steps per SAC block (default 1000, quick 200).

    Returns:
        ``{"ppo": {"1": {...}, "2": {...}, "speedup_2_vs_1": r}, "sac": {...}, "load_avg_before": [...], ...}``;
        each entry has ``vec_env``, ``block_steps``, ``steps_per_s`` (median over blocks) and ``blocks_steps_per_s``.
    """
    import torch

    torch.set_num_threads(1)
    blocks = blocks if blocks is not None else (1 if quick else 3)
    sac_steps = sac_block_steps if sac_block_steps is not None else (200 if quick else 1000)
    result: dict[str, Any] = {
        "env_id": BENCH_ENV,
        "env_kwargs": BENCH_ENV_KWARGS,
        "cpu_count": os.cpu_count(),
        "torch_num_threads": torch.get_num_threads(),
        "load_avg_before": list(os.getloadavg()),
    }
    for algo in ("ppo", "sac"):
        models = {n: _build(algo, n, (blocks + 1) * sac_steps + SAC_LEARNING_STARTS + n) for n in (1, 2)}
        try:
            sizes = {
                n: (int(m.n_steps) * n if algo == "ppo" else sac_steps) for n, m in models.items()
            }  # PPO: one rollout and its update per block
            for n, model in models.items():  # warm-up: fills SAC's learning_starts, first PPO update
                _block(model, max(sizes[n], SAC_LEARNING_STARTS + n) if algo == "sac" else sizes[n])
            rates: dict[int, list[float]] = {1: [], 2: []}
            for _ in range(blocks):
                for n, model in models.items():
                    steps, seconds = _block(model, sizes[n])
                    rates[n].append(steps / seconds)
        finally:
            for model in models.values():
                model.get_env().close()
        entry: dict[str, Any] = {}
        for n in (1, 2):
            entry[str(n)] = {
                "vec_env": "subproc" if n > 1 else "dummy",
                "block_steps": sizes[n],
                "steps_per_s": float(np.median(rates[n])),
                "blocks_steps_per_s": rates[n],
            }
        entry["speedup_2_vs_1"] = entry["2"]["steps_per_s"] / entry["1"]["steps_per_s"]
        result[algo] = entry
    result["load_avg_after"] = list(os.getloadavg())
    return result
