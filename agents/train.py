"""Train a Stable-Baselines3 agent on a Gymnasium environment from a YAML configuration.

Library entry point: :func:`train`; command line: ``python -m agents.train`` (:func:`main`).

Run directory ``<out>/<env id, '/' and ':' replaced by '_'>/<algo>_<seed>/``::

    config.yml                  resolved configuration (algo, env id, seed, gym packages, flat entry)
    command.txt                 one equivalent command line per training segment (fresh run, resumes)
    meta.json                   package versions, git revision + dirty flag, seeds, per-segment records
    final_model.zip             model at the end of the latest segment (also written on Ctrl-C)
    vecnormalize.pkl            VecNormalize statistics of final_model.zip (only with ``normalize``)
    replay_buffer.pkl           replay buffer of final_model.zip (only with ``save_replay_buffer``)
    best_model.zip              best model on the evaluation env (only if an evaluation ran)
    best_vecnormalize.pkl       VecNormalize statistics of best_model.zip (only with ``normalize``)
    best_model.json             num_timesteps and mean reward of best_model.zip
    checkpoints/                rl_model_<N>_steps.zip, rl_model_vecnormalize_<N>_steps.pkl,
                                rl_model_replay_buffer_<N>_steps.pkl (latest one only)
    logs/seg<k>/                progress.csv, TensorBoard events, evaluations.npz of segment k
    monitor/seg<k>_train_<i>.monitor.csv, monitor/seg<k>_eval_<i>.monitor.csv   episode logs

Seed scheme (``seed`` = ``--seed``; segment k = 0 for a fresh run, k = 1, 2, ... for each ``--resume``):

* training env ``i`` of segment ``k`` is reset with seed ``seed + 1000 * k + i`` (``i < n_envs <= 1000``);
  the model's Python/NumPy/PyTorch generators and the action space are seeded with ``seed + 1000 * k``;
* evaluation env ``i`` is reset with seed ``seed + 1_000_000 + i`` before *every* evaluation, so all
  evaluations of a run use the same episodes (common random numbers for choosing the best model) and
  never the training seeds (requires fewer than 1000 segments).

A fresh run that fails or is interrupted before it saved any model removes its directory again (nothing
there could be resumed), so the same command can be rerun; errors creating the environments (a bad
``--env-kwargs`` value) are reported as :class:`agents.config.ConfigError`. Off-policy replay buffers are
allocated for at most the steps of the run (:func:`replay_buffer_size`; training is identical, the saved
``replay_buffer.pkl`` small) and grown when a resume adds steps. PPO collects whole rollouts of
``n_steps x n_envs`` steps, so it warns when that rounds ``--total-timesteps`` up (``planned_timesteps`` in the
segment record).

``--resume DIR`` reloads the newest of ``final_model.zip`` and ``checkpoints/rl_model_<N>_steps.zip``
(with its VecNormalize statistics and, if saved, its replay buffer), keeps counting ``num_timesteps``
(``reset_num_timesteps=False``) and writes into the same directory. ``--total-timesteps`` then means
*additional* steps (default: the steps missing to the configured ``n_timesteps``). Resuming unpickles
the files of DIR (SB3 zips and VecNormalize pickles): only resume runs you trust.
"""

from __future__ import annotations

import dataclasses
import datetime
import difflib
import importlib
import inspect
import json
import logging
import math
import os
import re
import shlex
import shutil
import sys
import time
import warnings
import zipfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
import yaml
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, CheckpointCallback, EvalCallback
from stable_baselines3.common.logger import configure
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecNormalize

from agents.algos import ALGOS, is_off_policy
from agents.args import DEFAULT_GYM_PACKAGES, VEC_ENV_TYPES, build_parser
from agents.config import ConfigError, TrainConfig, default_config_path, is_unit_scale, load_config, parse_entry
from uvdms_gym.provenance import git_info, package_versions

log = logging.getLogger(__name__)

SEGMENT_SEED_STRIDE = 1000
EVAL_SEED_OFFSET = 1_000_000
CHECKPOINT_PREFIX = "rl_model"


class EnvironmentNotFoundError(LookupError):
    """The environment id is not registered (possibly because a gym package failed to import)."""


class RunDirError(ValueError):
    """The run directory exists (fresh run) or is not a valid run to resume."""


# ------------------------------------------------------------------------------------------------------
# Environments
# ------------------------------------------------------------------------------------------------------
def import_gym_packages(packages: Sequence[str]) -> dict[str, str]:
    """Import the packages that register Gymnasium environments.

    Args:
        packages: Module names (e.g. ``["uvdms_gym"]``).

    Returns:
        Import errors as ``{package: "ExceptionType: message"}`` (empty if all imported).
    """
    errors = {}
    for name in packages:
        try:
            importlib.import_module(name)
        except Exception as exc:  # any error while importing an env package is reported, not fatal
            errors[name] = f"{type(exc).__name__}: {exc}"
    return errors


def check_env_id(env_id: str, packages: Sequence[str]) -> None:
    """Import ``packages`` and check that ``env_id`` is registered.

    Args:
        env_id: Gymnasium environment id (``module:Id`` ids are left to ``gymnasium.make``).
        packages: Packages to import first.

    Raises:
        EnvironmentNotFoundError: If the id is not registered; the message lists failed imports and
            close matches.
    """
    errors = import_gym_packages(packages)
    if ":" in env_id or env_id in gym.registry:
        return
    msg = f"environment id {env_id!r} is not registered."
    if errors:
        failed = "; ".join(f"{name} -> {err}" for name, err in errors.items())
        msg += f" These gym packages failed to import: {failed}."
    imported = [p for p in packages if p not in errors]
    if imported:
        msg += f" Imported gym packages: {', '.join(imported)}."
    else:
        msg += " No gym package was imported (use --gym-packages to name the package that registers it)."
    close = difflib.get_close_matches(env_id, list(gym.registry), n=3)
    if close:
        msg += f" Close matches: {', '.join(close)}."
    raise EnvironmentNotFoundError(msg)


@dataclasses.dataclass(frozen=True)
class EnvFactory:
    """Picklable environment constructor (works with ``SubprocVecEnv``).

    Attributes:
        env_id: Gymnasium id.
        env_kwargs: Keyword arguments of ``gymnasium.make``.
        gym_packages: Packages imported first (in the worker process) to register the id.
        monitor_file: ``Monitor`` log file (``None``: no file).
        max_episode_steps: ``gymnasium.make``'s episode length limit (``None``: the registered one).
        alive_bonus: Constant added to every reward inside the ``Monitor`` (0: no wrapper).
        action_scale: The policy's action is multiplied by this before the env sees it (1: no wrapper).
    """

    env_id: str
    env_kwargs: Mapping[str, Any]
    gym_packages: tuple[str, ...] = DEFAULT_GYM_PACKAGES
    monitor_file: str | None = None
    max_episode_steps: int | None = None
    alive_bonus: float = 0.0
    action_scale: float = 1.0

    def __call__(self) -> gym.Env:
        """Create the environment wrapped in a ``Monitor`` (action scaling and alive bonus inside it).

        Also sets ``torch.set_num_threads(1)`` in the calling process: in a ``SubprocVecEnv`` worker (which
        imports torch with this module but never uses it) as in the trainer (see :func:`train`).
        """
        torch.set_num_threads(1)
        check_env_id(self.env_id, self.gym_packages)
        make_kwargs = dict(self.env_kwargs)
        if self.max_episode_steps is not None:
            make_kwargs["max_episode_steps"] = self.max_episode_steps
        env = gym.make(self.env_id, **make_kwargs)
        if self.action_scale != 1.0:
            env = ScaledAction(env, self.action_scale)
        if self.alive_bonus:
            env = AliveBonus(env, self.alive_bonus)
        return Monitor(env, filename=self.monitor_file)


class AliveBonus(gym.RewardWrapper):
    """Adds a constant to every reward (training-side shaping; see ``TrainConfig.alive_bonus``).

    Args:
        env: The environment.
        bonus: Constant added to each step's reward.
    """

    def __init__(self, env: gym.Env, bonus: float) -> None:
        super().__init__(env)
        self.bonus = float(bonus)

    def reward(self, reward: float) -> float:
        """Shaped reward."""
        return float(reward) + self.bonus


class ScaledAction(gym.ActionWrapper):
    """Sends ``scale * action`` to the environment (see ``TrainConfig.action_scale``).

    The action space stays the wrapped env's ``Box(-1, 1)``; the scaled action lies in ``[-scale, scale]``.

    Args:
        env: The environment (a ``Box`` action space symmetric about 0).
        scale: Factor in (0, 1].
    """

    def __init__(self, env: gym.Env, scale: float) -> None:
        super().__init__(env)
        if not is_unit_scale(scale):
            raise ValueError(f"action scale must be in (0, 1], got {scale}")
        self.scale = float(scale)

    def action(self, action: np.ndarray) -> np.ndarray:
        """Scaled action."""
        return self.scale * np.asarray(action)


def train_env_seed(seed: int, segment: int, rank: int) -> int:
    """Seed of training env ``rank`` in training segment ``segment`` (see the module docstring)."""
    return seed + SEGMENT_SEED_STRIDE * segment + rank


def eval_env_seed(seed: int, rank: int) -> int:
    """Seed of evaluation env ``rank`` (the same for every evaluation and segment)."""
    return seed + EVAL_SEED_OFFSET + rank


def run_dir_for(out_dir: str | Path, env_id: str, algo: str, seed: int) -> Path:
    """Run directory ``<out_dir>/<env id with '/' and ':' replaced by '_'>/<algo>_<seed>``."""
    return Path(out_dir) / re.sub(r"[/:\\]", "_", env_id) / f"{algo}_{seed}"


def _make_vec_env(factories: list[Callable[[], gym.Env]], vec_env: str) -> VecEnv:
    if vec_env == "subproc":
        return SubprocVecEnv(factories)
    return DummyVecEnv(factories)


# ------------------------------------------------------------------------------------------------------
# Callbacks
# ------------------------------------------------------------------------------------------------------
class _CheckpointCallback(CheckpointCallback):
    """CheckpointCallback that keeps only the newest replay-buffer checkpoint."""

    def _on_step(self) -> bool:
        result = super()._on_step()
        if self.save_replay_buffer and self.n_calls % self.save_freq == 0:
            newest = Path(self._checkpoint_path("replay_buffer_", extension="pkl"))
            for old in Path(self.save_path).glob(f"{self.name_prefix}_replay_buffer_*_steps.pkl"):
                if old != newest:
                    old.unlink()
        return result


class _SeededEvalCallback(EvalCallback):
    """EvalCallback that reseeds the evaluation envs before every evaluation (same episodes each time)."""

    def __init__(self, *args: Any, eval_seed: int, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.eval_seed = eval_seed

    def _on_step(self) -> bool:
        if self.eval_freq > 0 and self.n_calls % self.eval_freq == 0:
            self.eval_env.seed(self.eval_seed)
        return super()._on_step()


class _SaveBestExtras(BaseCallback):
    """Called by EvalCallback on a new best model: saves its VecNormalize stats and ``best_model.json``."""

    def __init__(self, run_dir: Path, segment: int) -> None:
        super().__init__()
        self.run_dir = run_dir
        self.segment = segment

    def _on_step(self) -> bool:
        vec_normalize = self.model.get_vec_normalize_env()
        if vec_normalize is not None:
            vec_normalize.save(str(self.run_dir / "best_vecnormalize.pkl"))
        best = float(self.parent.best_mean_reward) if self.parent is not None else None
        _write_json(
            self.run_dir / "best_model.json",
            {"num_timesteps": int(self.num_timesteps), "mean_reward": best, "segment": self.segment},
        )
        return True


# ------------------------------------------------------------------------------------------------------
# Training
# ------------------------------------------------------------------------------------------------------
def train(
    algo: str | None = None,
    env_id: str | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    config_path: str | Path | None = None,
    seed: int = 0,
    total_timesteps: int | None = None,
    n_envs: int | None = None,
    out_dir: str | Path = "runs",
    resume_dir: str | Path | None = None,
    progress: bool = True,
    *,
    hyperparams: Mapping[str, Any] | None = None,
    vec_env: str = "dummy",
    gym_packages: Sequence[str] = DEFAULT_GYM_PACKAGES,
    verbose: int = 0,
) -> Path:
    """Train (or resume training of) an agent and return its run directory.

    Args:
        algo: Algorithm name (``ppo``, ``sac``, ``td3``, ``tqc``); optional when resuming.
        env_id: Gymnasium environment id; optional when resuming.
        env_kwargs: Extra ``gymnasium.make`` keyword arguments (override the config's ``env_kwargs``).
        config_path: YAML config; default ``train_configs/<algo>.yml``.
        seed: Base seed (see the module docstring for the seed scheme).
        total_timesteps: Fresh run: total steps (overrides ``n_timesteps``). Resume: additional steps
            (default: the steps missing to ``n_timesteps``).
        n_envs: Number of training environments (overrides the config).
        out_dir: Root of the run directories.
        resume_dir: Run directory to resume; the other configuration arguments must then be left at
            their defaults or agree with the run's ``config.yml``.
        progress: Show a progress bar (tqdm + rich).
        hyperparams: Extra config keys (algorithm hyperparameters or TrainConfig fields) overriding the
            file, validated like the file. Not allowed when resuming.
        vec_env: ``dummy`` (default, fastest for 1-2 cheap envs) or ``subproc``.
        gym_packages: Packages to import so that the env id is registered.
        verbose: SB3 verbosity (1: print the training table to stdout).

    Returns:
        The run directory.

    Raises:
        ConfigError: Invalid configuration or arguments.
        EnvironmentNotFoundError: The env id is not registered.
        RunDirError: The run directory exists (fresh run) or is not resumable.
    """
    if vec_env not in VEC_ENV_TYPES:
        raise ConfigError(f"vec_env must be one of {VEC_ENV_TYPES}, got {vec_env!r}")
    torch.set_num_threads(1)
    if resume_dir is not None:
        if hyperparams or env_kwargs or config_path is not None:
            raise ConfigError(
                "--resume takes its configuration from the run's config.yml; do not pass "
                "--config, --env-kwargs or --hyperparams"
            )
        return _resume(Path(resume_dir), algo, env_id, total_timesteps, n_envs, progress, vec_env, verbose)

    if algo is None or env_id is None:
        raise ConfigError("algo and env id are required unless resuming")
    if algo not in ALGOS:
        raise ConfigError(f"unknown algorithm {algo!r}; choose one of {sorted(ALGOS)}")
    gym_packages = tuple(gym_packages)
    check_env_id(env_id, gym_packages)
    config_path = Path(config_path) if config_path is not None else default_config_path(algo)
    cfg = load_config(config_path, algo, env_id, overrides=hyperparams)
    entry = cfg.to_entry()
    if env_kwargs:
        entry["env_kwargs"] = {**entry["env_kwargs"], **dict(env_kwargs)}
    if n_envs is not None:
        entry["n_envs"] = n_envs
    if total_timesteps is not None:
        entry["n_timesteps"] = total_timesteps
    cfg = parse_entry(entry, algo, source=f"{config_path} + command line", entry_name=env_id)

    run_dir = run_dir_for(out_dir, env_id, algo, seed)
    if run_dir.exists() and any(run_dir.iterdir()):
        if latest_checkpoint(run_dir) is None:
            raise RunDirError(
                f"run directory {run_dir} exists but holds no model (a run still starting, or one killed before "
                "its first checkpoint: see its meta.json); delete it or use another --seed/--out"
            )
        raise RunDirError(f"run directory {run_dir} exists; use --resume {run_dir} or another --seed/--out")
    run_dir.mkdir(parents=True, exist_ok=True)
    resolved = {
        "algo": algo,
        "env_id": env_id,
        "seed": seed,
        "gym_packages": list(gym_packages),
        "config_source": str(config_path),
        "config": cfg.to_entry(),
    }
    (run_dir / "config.yml").write_text(yaml.safe_dump(resolved, sort_keys=False), encoding="utf-8")
    meta = {
        "algo": algo,
        "env_id": env_id,
        "seed": seed,
        "seed_scheme": {
            "train_env": f"seed + {SEGMENT_SEED_STRIDE} * segment + rank",
            "model": f"seed + {SEGMENT_SEED_STRIDE} * segment",
            "eval_env": f"seed + {EVAL_SEED_OFFSET} + rank (reset before every evaluation)",
        },
        "versions": package_versions(),
        "git": git_info(),
        "segments": [],
    }
    _write_json(run_dir / "meta.json", meta)
    command = [
        "python",
        "-m",
        "agents.train",
        "--algo",
        algo,
        "--env",
        env_id,
        "--config",
        str(config_path),
        "--seed",
        str(seed),
        "--total-timesteps",
        str(cfg.n_timesteps),
        "--n-envs",
        str(cfg.n_envs),
        "--out",
        str(out_dir),
        "--vec-env",
        vec_env,
        "--gym-packages",
        *gym_packages,
    ]
    if env_kwargs:
        command += ["--env-kwargs", *(f"{k}={json.dumps(v)}" for k, v in env_kwargs.items())]
    if hyperparams:
        command += ["--hyperparams", *(f"{k}={json.dumps(v)}" for k, v in hyperparams.items())]
    try:
        _run_segment(
            run_dir, cfg, env_id, seed, gym_packages, cfg.n_timesteps, command, None, progress, vec_env, verbose
        )
    except BaseException as exc:
        # a user error (bad config or kwargs: a ValueError) is reported by the caller in one line; say nothing more
        _remove_if_no_model(run_dir, quiet=isinstance(exc, ValueError))
        raise
    return run_dir


def _remove_if_no_model(run_dir: Path, quiet: bool = False) -> None:
    """Delete a fresh run's directory that holds no model, so that rerunning the same command works.

    A fresh run that fails (or is interrupted) before its first checkpoint or final model leaves only its
    config, meta record and partial logs, which would otherwise block the seed ("exists but holds no model").
    ``quiet`` logs the removal at debug level instead of as a warning.
    """
    if latest_checkpoint(run_dir) is not None:
        return
    shutil.rmtree(run_dir, ignore_errors=True)
    (log.debug if quiet else log.warning)(
        "removed %s: the run failed before saving a model; the same command can be rerun", run_dir
    )


def _resume(
    run_dir: Path,
    algo: str | None,
    env_id: str | None,
    total_timesteps: int | None,
    n_envs: int | None,
    progress: bool,
    vec_env: str,
    verbose: int,
) -> Path:
    config_file = run_dir / "config.yml"
    if not config_file.is_file() or not (run_dir / "meta.json").is_file():
        raise RunDirError(f"{run_dir} is not a run directory (config.yml / meta.json missing)")
    resolved = yaml.safe_load(config_file.read_text(encoding="utf-8"))
    for name, given in (("algo", algo), ("env_id", env_id)):
        if given is not None and given != resolved[name]:
            raise ConfigError(f"--resume {run_dir}: {name} {given!r} differs from the run's {resolved[name]!r}")
    algo, env_id, seed = resolved["algo"], resolved["env_id"], int(resolved["seed"])
    cfg = parse_entry(resolved["config"], algo, source=str(config_file), entry_name=env_id)
    if n_envs is not None and n_envs != cfg.n_envs:
        raise ConfigError(f"--resume: n_envs cannot change ({cfg.n_envs} in {config_file}, got {n_envs})")
    gym_packages = tuple(resolved.get("gym_packages", DEFAULT_GYM_PACKAGES))
    check_env_id(env_id, gym_packages)

    checkpoint = latest_checkpoint(run_dir)
    if checkpoint is None:
        raise RunDirError(f"{run_dir}: no final_model.zip or checkpoints/{CHECKPOINT_PREFIX}_<N>_steps.zip")
    if cfg.normalize is not False and checkpoint.vecnormalize is None:
        raise RunDirError(f"{run_dir}: normalize is on but no VecNormalize statistics for {checkpoint.model}")
    if total_timesteps is None:
        total_timesteps = cfg.n_timesteps - checkpoint.num_timesteps
        if total_timesteps <= 0:
            raise ConfigError(
                f"{run_dir} already has {checkpoint.num_timesteps} of {cfg.n_timesteps} steps; "
                "pass --total-timesteps N to train N more steps"
            )
    if total_timesteps <= 0:
        raise ConfigError(f"total_timesteps must be positive, got {total_timesteps}")
    command = [
        "python",
        "-m",
        "agents.train",
        "--resume",
        str(run_dir),
        "--total-timesteps",
        str(total_timesteps),
        "--vec-env",
        vec_env,
    ]
    _run_segment(
        run_dir, cfg, env_id, seed, gym_packages, total_timesteps, command, checkpoint, progress, vec_env, verbose
    )
    return run_dir


def _run_segment(
    run_dir: Path,
    cfg: TrainConfig,
    env_id: str,
    seed: int,
    gym_packages: tuple[str, ...],
    timesteps: int,
    command: list[str],
    checkpoint: Checkpoint | None,
    progress: bool,
    vec_env: str,
    verbose: int,
) -> None:
    meta = json.loads((run_dir / "meta.json").read_text(encoding="utf-8"))
    segment = len(meta["segments"])
    if segment >= EVAL_SEED_OFFSET // SEGMENT_SEED_STRIDE:
        raise RunDirError(f"{run_dir}: too many segments for the seed scheme")
    with (run_dir / "command.txt").open("a", encoding="utf-8") as f:
        f.write(shlex.join(command) + "\n")
    model_seed = train_env_seed(seed, segment, 0)
    (run_dir / "monitor").mkdir(exist_ok=True)
    train_factories = [
        EnvFactory(
            env_id,
            cfg.env_kwargs,
            gym_packages,
            str(run_dir / "monitor" / f"seg{segment}_train_{i}"),
            cfg.max_episode_steps,
            cfg.alive_bonus,
            cfg.action_scale,
        )
        for i in range(cfg.n_envs)
    ]
    eval_kwargs = {**cfg.env_kwargs, **cfg.eval_env_kwargs}
    eval_factories = [
        EnvFactory(
            env_id,
            eval_kwargs,
            gym_packages,
            str(run_dir / "monitor" / f"seg{segment}_eval_{i}"),
            cfg.max_episode_steps,
            cfg.alive_bonus,
            cfg.action_scale,
        )
        for i in range(cfg.n_eval_envs)
    ]
    record: dict[str, Any] = {
        "index": segment,
        "command": shlex.join(command),
        "resumed_from": str(checkpoint.model.relative_to(run_dir)) if checkpoint else None,
        "start_num_timesteps": checkpoint.num_timesteps if checkpoint else 0,
        "requested_timesteps": timesteps,
        "model_seed": model_seed,
        "train_env_seeds": [train_env_seed(seed, segment, i) for i in range(cfg.n_envs)],
        "eval_env_seeds": [eval_env_seed(seed, i) for i in range(cfg.n_eval_envs)],
        "vec_env": vec_env,
        "torch_num_threads": torch.get_num_threads(),
        "versions": package_versions(),
        "git": git_info(),
        "started_utc": _utc_now(),
        "status": "running",
    }
    meta["segments"].append(record)
    _write_json(run_dir / "meta.json", meta)

    venv: VecEnv | None = None
    eval_venv: VecEnv | None = None
    model: BaseAlgorithm | None = None
    start = time.perf_counter()
    start_timesteps = checkpoint.num_timesteps if checkpoint else 0
    try:
        try:
            venv = _make_vec_env(train_factories, vec_env)
            eval_venv = DummyVecEnv(eval_factories)
        except Exception as exc:  # a bad --env-kwargs value surfaces here: report it as a config error
            raise ConfigError(
                f"cannot create {env_id} with env_kwargs {dict(cfg.env_kwargs)} (eval: {eval_kwargs}): "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        normalize_kwargs = cfg.normalize_kwargs()
        if checkpoint is None:
            if normalize_kwargs is not None:
                venv = VecNormalize(venv, **normalize_kwargs)
            kwargs = cfg.sb3_hyperparams()
            if is_off_policy(cfg.algo):
                kwargs["buffer_size"] = replay_buffer_size(_configured_buffer_size(cfg), cfg.n_envs, timesteps)
            if cfg.noise_type is not None:
                kwargs["action_noise"] = cfg.action_noise(venv.action_space)
            model = ALGOS[cfg.algo](
                cfg.policy,
                venv,
                policy_kwargs=cfg.sb3_policy_kwargs(),
                seed=model_seed,
                verbose=verbose,
                **kwargs,
            )
            if cfg.action_init_scale is not None:
                scale_action_layer(model, cfg.action_init_scale)
        else:
            if checkpoint.vecnormalize is not None:
                venv = VecNormalize.load(str(checkpoint.vecnormalize), venv)
                venv.training = True
            model = ALGOS[cfg.algo].load(str(checkpoint.model), env=venv, print_system_info=False)
            model.verbose = verbose
            model.set_random_seed(model_seed)
            if is_off_policy(cfg.algo):
                if checkpoint.replay_buffer is not None:
                    model.load_replay_buffer(str(checkpoint.replay_buffer))
                else:
                    warnings.warn(
                        f"{checkpoint.model.name} has no saved replay buffer (save_replay_buffer: false): "
                        "training continues from an empty buffer",
                        stacklevel=2,
                    )
                record["replay_buffer_loaded"] = checkpoint.replay_buffer is not None
                grow_replay_buffer(
                    model,
                    replay_buffer_size(_configured_buffer_size(cfg), cfg.n_envs, start_timesteps + timesteps),
                )
        if is_off_policy(cfg.algo):
            record["replay_buffer_size"] = int(model.replay_buffer.buffer_size * model.replay_buffer.n_envs)
        record["planned_timesteps"] = _planned_timesteps(model, cfg, timesteps)
        if normalize_kwargs is not None:
            eval_venv = VecNormalize(
                eval_venv,
                training=False,
                norm_reward=False,
                **{k: v for k, v in normalize_kwargs.items() if k != "norm_reward"},
            )
        formats = ["csv", "tensorboard"] + (["stdout"] if verbose else [])
        log_dir = run_dir / "logs" / f"seg{segment}"
        model.set_logger(configure(str(log_dir), formats))

        callbacks: list[BaseCallback] = []
        if cfg.checkpoint_freq > 0:
            callbacks.append(
                _CheckpointCallback(
                    save_freq=max(cfg.checkpoint_freq // cfg.n_envs, 1),
                    save_path=str(run_dir / "checkpoints"),
                    name_prefix=CHECKPOINT_PREFIX,
                    save_replay_buffer=cfg.save_replay_buffer,
                    save_vecnormalize=True,
                )
            )
        if cfg.eval_freq > 0:
            eval_callback = _SeededEvalCallback(
                eval_venv,
                eval_seed=eval_env_seed(seed, 0),
                callback_on_new_best=_SaveBestExtras(run_dir, segment),
                n_eval_episodes=cfg.n_eval_episodes,
                eval_freq=max(cfg.eval_freq // cfg.n_envs, 1),
                log_path=str(log_dir),
                best_model_save_path=str(run_dir),
                deterministic=True,
                verbose=verbose,
            )
            best_file = run_dir / "best_model.json"
            if best_file.is_file():
                best = json.loads(best_file.read_text(encoding="utf-8")).get("mean_reward")
                if best is not None:
                    eval_callback.best_mean_reward = float(best)
            callbacks.append(eval_callback)

        model.learn(
            total_timesteps=timesteps,
            callback=CallbackList(callbacks),
            reset_num_timesteps=checkpoint is None,
            progress_bar=progress,
        )
        _save_final(run_dir, model, cfg)
        record["status"] = "completed"
    except KeyboardInterrupt:
        if model is not None:
            _save_final(run_dir, model, cfg)
        record["status"] = "interrupted"
        raise
    except BaseException as exc:
        record["status"] = "failed"
        record["error"] = f"{type(exc).__name__}: {exc}"
        raise
    finally:
        record["end_num_timesteps"] = int(model.num_timesteps) if model is not None else None
        record["finished_utc"] = _utc_now()
        record["wall_time_s"] = round(time.perf_counter() - start, 3)
        _write_json(run_dir / "meta.json", meta)
        for env in (venv, eval_venv):
            if env is not None:
                env.close()
        if model is not None and getattr(model, "_logger", None) is not None:
            model.logger.close()  # progress.csv and TensorBoard files


def _configured_buffer_size(cfg: TrainConfig) -> int:
    """``buffer_size`` of the configuration, or the algorithm's default."""
    if "buffer_size" in cfg.hyperparams:
        return int(cfg.hyperparams["buffer_size"])
    return int(inspect.signature(ALGOS[cfg.algo].__init__).parameters["buffer_size"].default)


def replay_buffer_size(configured: int, n_envs: int, total_timesteps: int) -> int:
    """Replay-buffer capacity (transitions) for a run that ends at ``total_timesteps``.

    SB3 preallocates the whole buffer (and ``save_replay_buffer`` pickles all of it), so a 300-step run with
    ``buffer_size: 300000`` would hold and write ~200 MB. The capacity is capped at the transitions the run
    can store, ``n_envs * (ceil(total_timesteps / n_envs) + 1)``: the buffer never fills, so sampling and
    training are exactly those of the configured size. A resumed run grows it (:func:`grow_replay_buffer`).

    Args:
        configured: ``buffer_size`` of the configuration.
        n_envs: Number of training environments.
        total_timesteps: ``num_timesteps`` at the end of the segment.

    Returns:
        ``min(configured, cap)``.
    """
    return min(int(configured), n_envs * (math.ceil(total_timesteps / n_envs) + 1))


def grow_replay_buffer(model: BaseAlgorithm, size: int) -> bool:
    """Enlarge an off-policy model's replay buffer to ``size`` transitions, keeping its content.

    A buffer that has wrapped around (``full``) or is already large enough is left alone (a full buffer was
    allocated at the configured size, see :func:`replay_buffer_size`).

    Args:
        model: An off-policy SB3 model.
        size: The capacity wanted, in transitions over all envs.

    Returns:
        Whether the buffer was enlarged.
    """
    buffer = model.replay_buffer
    old = buffer.buffer_size
    new = max(size // buffer.n_envs, 1)
    if buffer.full or new <= old:
        return False
    for name, value in list(vars(buffer).items()):
        if isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == old:
            setattr(buffer, name, _grown(value, new, buffer.pos))
        elif isinstance(value, dict) and all(isinstance(v, np.ndarray) for v in value.values()):
            setattr(buffer, name, {k: _grown(v, new, buffer.pos) if v.shape[0] == old else v for k, v in value.items()})
    buffer.buffer_size = new
    model.buffer_size = new * buffer.n_envs
    return True


def _grown(array: np.ndarray, length: int, filled: int) -> np.ndarray:
    out = np.zeros((length, *array.shape[1:]), dtype=array.dtype)
    out[:filled] = array[:filled]
    return out


def _planned_timesteps(model: BaseAlgorithm, cfg: TrainConfig, timesteps: int) -> int:
    """Steps the segment will run: on-policy algorithms collect whole rollouts of ``n_steps x n_envs``.

    Warns when that exceeds the requested steps (PPO with ``--total-timesteps 300`` and ``n_steps: 1024`` on
    2 envs runs 2048 steps).
    """
    if is_off_policy(cfg.algo):
        return timesteps
    rollout = int(model.n_steps) * cfg.n_envs
    planned = math.ceil(timesteps / rollout) * rollout
    if planned != timesteps:
        warnings.warn(
            f"{cfg.algo.upper()} trains in whole rollouts of n_steps x n_envs = {model.n_steps} x {cfg.n_envs} = "
            f"{rollout} steps: the {timesteps} requested steps run as {planned} (pass --hyperparams n_steps=N "
            "for shorter rollouts)",
            stacklevel=3,
        )
    return planned


def scale_action_layer(model: BaseAlgorithm, scale: float) -> torch.nn.Linear:
    """Multiply the last action layer of a fresh model's policy by ``scale`` (``TrainConfig.action_init_scale``).

    Args:
        model: A freshly built SB3 model (PPO: ``policy.action_net``; SAC/TQC: ``actor.mu``; TD3: the last
            ``Linear`` of ``actor.mu``, copied to ``actor_target``).
        scale: The factor.

    Returns:
        The scaled layer.

    Raises:
        ConfigError: If the policy has no recognised action layer.
    """
    policy = model.policy
    actor = getattr(policy, "actor", None)
    if hasattr(policy, "action_net"):
        layer = policy.action_net
    elif actor is not None and isinstance(getattr(actor, "mu", None), torch.nn.Linear):
        layer = actor.mu
    elif actor is not None and isinstance(getattr(actor, "mu", None), torch.nn.Sequential):
        layer = [m for m in actor.mu if isinstance(m, torch.nn.Linear)][-1]
    else:
        raise ConfigError(f"action_init_scale: no action layer found in {type(policy).__name__}")
    with torch.no_grad():
        layer.weight.mul_(scale)
        if layer.bias is not None:
            layer.bias.mul_(scale)
    if getattr(policy, "actor_target", None) is not None:
        policy.actor_target.load_state_dict(actor.state_dict())
    return layer


def _save_final(run_dir: Path, model: BaseAlgorithm, cfg: TrainConfig) -> None:
    model.save(str(run_dir / "final_model.zip"))
    vec_normalize = model.get_vec_normalize_env()
    if vec_normalize is not None:
        vec_normalize.save(str(run_dir / "vecnormalize.pkl"))
    if cfg.save_replay_buffer and is_off_policy(cfg.algo):
        model.save_replay_buffer(str(run_dir / "replay_buffer.pkl"))


# ------------------------------------------------------------------------------------------------------
# Run directory helpers
# ------------------------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Checkpoint:
    """A saved model of a run with its companion files.

    Attributes:
        model: The SB3 zip.
        num_timesteps: Its step count (read from the zip's JSON data, nothing unpickled).
        vecnormalize: Its VecNormalize statistics, if any.
        replay_buffer: Its replay buffer, if saved.
    """

    model: Path
    num_timesteps: int
    vecnormalize: Path | None
    replay_buffer: Path | None


def zip_num_timesteps(path: str | Path) -> int:
    """``num_timesteps`` stored in an SB3 zip (read from its JSON ``data`` member, no unpickling)."""
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data").decode("utf-8"))
    return int(data["num_timesteps"])


def latest_checkpoint(run_dir: str | Path) -> Checkpoint | None:
    """The newest model of a run: ``final_model.zip`` or the checkpoint with the most steps.

    Ties go to ``final_model.zip``.
    """
    run_dir = Path(run_dir)
    candidates: list[Checkpoint] = []
    final = run_dir / "final_model.zip"
    if final.is_file():
        candidates.append(
            Checkpoint(
                final,
                zip_num_timesteps(final),
                _existing(run_dir / "vecnormalize.pkl"),
                _existing(run_dir / "replay_buffer.pkl"),
            )
        )
    pattern = re.compile(rf"^{CHECKPOINT_PREFIX}_(\d+)_steps\.zip$")
    for path in sorted((run_dir / "checkpoints").glob(f"{CHECKPOINT_PREFIX}_*_steps.zip")):
        match = pattern.match(path.name)
        if match:
            n = int(match.group(1))
            candidates.append(
                Checkpoint(
                    path,
                    n,
                    _existing(path.with_name(f"{CHECKPOINT_PREFIX}_vecnormalize_{n}_steps.pkl")),
                    _existing(path.with_name(f"{CHECKPOINT_PREFIX}_replay_buffer_{n}_steps.pkl")),
                )
            )
    if not candidates:
        return None
    # max() keeps the first of equal keys: final_model.zip comes first.
    return max(candidates, key=lambda c: c.num_timesteps)


def _existing(path: Path) -> Path | None:
    return path if path.is_file() else None


def _utc_now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def _write_json(path: Path, data: Any) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2, allow_nan=True) + "\n", encoding="utf-8")
    os.replace(tmp, path)


# ------------------------------------------------------------------------------------------------------
# Command line
# ------------------------------------------------------------------------------------------------------
def parse_key_values(items: Sequence[str] | None, option: str = "--env-kwargs") -> dict[str, Any]:
    """Parse ``key=value`` strings; values are YAML literals (``yaml.safe_load``).

    Args:
        items: Strings such as ``["case=1", "goal=paper", "hydro_randomization=0.3"]``.
        option: Option name for error messages.

    Returns:
        The mapping (``{"case": 1, "goal": "paper", "hydro_randomization": 0.3}``).

    Raises:
        ConfigError: On a malformed item.
    """
    out: dict[str, Any] = {}
    for item in items or []:
        key, sep, text = item.partition("=")
        if not sep or not key.isidentifier():
            raise ConfigError(f"{option}: expected key=value with an identifier key, got {item!r}")
        try:
            out[key] = yaml.safe_load(text) if text else ""
        except yaml.YAMLError as exc:
            raise ConfigError(f"{option}: cannot parse the value of {key!r} as YAML: {exc}") from exc
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit code (0 ok, 2 bad arguments/config, 130 interrupted)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.resume is None and (args.algo is None or args.env_id is None):
        parser.error("--algo and --env are required unless --resume DIR is given")
    try:
        run_dir = train(
            algo=args.algo,
            env_id=args.env_id,
            env_kwargs=parse_key_values(args.env_kwargs, "--env-kwargs"),
            config_path=args.config,
            seed=args.seed,
            total_timesteps=args.total_timesteps,
            n_envs=args.n_envs,
            out_dir=args.out,
            resume_dir=args.resume,
            progress=not args.no_progress,
            hyperparams=parse_key_values(args.hyperparams, "--hyperparams"),
            vec_env=args.vec_env,
            gym_packages=args.gym_packages,
            verbose=args.verbose,
        )
    except (ConfigError, EnvironmentNotFoundError, RunDirError) as exc:
        print("uvdms: error: " + " ".join(str(exc).split()), file=sys.stderr)  # one line, as the uvdms command
        return 2
    except KeyboardInterrupt:
        run_dir = args.resume or run_dir_for(args.out, args.env_id, args.algo, args.seed)
        if latest_checkpoint(run_dir) is not None:
            print(f"interrupted: final_model.zip saved; continue with --resume {run_dir}", file=sys.stderr)
        else:
            print("interrupted before a model was saved: nothing to resume", file=sys.stderr)
        return 130
    print(run_dir)
    return 0


if __name__ == "__main__":
    sys.exit(main())
