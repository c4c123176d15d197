"""Resuming a training run (``--resume DIR``): what a resume may state, the run's configuration, the steps to train.

Moved out of :mod:`agents.training.train` (which re-exports :class:`ResumeRequest` and :func:`resume_run`); see
its module docstring for what a resume reloads and where it writes.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml
from stable_baselines3.common.callbacks import BaseCallback

from agents.common.envs import ActionComponents, check_env_id, check_training_seed
from agents.common.names import DEFAULT_GYM_PACKAGES, NO_BASE, VEC_ENV_TYPES
from agents.config import ConfigError, TrainConfig, parse_entry
from agents.training.composition import check_vec_env, composition_factories
from agents.training.rundir import CHECKPOINT_PREFIX, Checkpoint, RunDirError, latest_checkpoint
from agents.training.segment import TrainingSegment
from agents.training.spec import command_prefix


@dataclasses.dataclass(frozen=True)
class ResumeRequest:
    """What a ``--resume`` may state about the run (each must agree with its ``config.yml``) and how it runs.

    Attributes:
        algo: ``--algo`` (``None``: the run's).
        env_id: ``--env`` (``None``: the run's).
        total_timesteps: Additional steps (``None``: the steps missing to the configured ``n_timesteps``).
        n_envs: ``--n-envs`` (cannot change).
        vec_env: Vectorised env type of this segment (``None``: the type of the run's last segment in ``meta.json``).
        given: The composition options given (``None`` values: not given).
    """

    algo: str | None
    env_id: str | None
    total_timesteps: int | None
    n_envs: int | None
    vec_env: str | None
    given: Mapping[str, Any]


def resume_run(
    run_dir: Path,
    request: ResumeRequest,
    progress: bool,
    verbose: int,
    callbacks: Sequence[BaseCallback] = (),
    after_eval: Sequence[BaseCallback] = (),
    components: ActionComponents | None = None,
) -> Path:
    """Continue the run in ``run_dir`` from its newest checkpoint (``--resume``; module docstring).

    Raises:
        ConfigError: The request disagrees with the run, or there are no steps left to train.
        RunDirError: ``run_dir`` is not a resumable run directory.
        SeedProtocolError: The run's seed or one of its derived seeds is not a training seed (``uvdms_gym.seeds``).
    """
    resolved, cfg = _resumed_config(run_dir, request)
    env_id, seed = resolved["env_id"], int(resolved["seed"])
    check_training_seed(seed, cfg.n_envs, cfg.n_eval_envs, f"--resume {run_dir}: the run's seed")
    vec_env = request.vec_env or _last_vec_env(run_dir)
    check_vec_env(cfg, vec_env)
    factories = composition_factories(cfg, components)
    gym_packages = tuple(resolved.get("gym_packages", DEFAULT_GYM_PACKAGES))
    check_env_id(env_id, gym_packages)

    checkpoint = latest_checkpoint(run_dir)
    if checkpoint is None:
        raise RunDirError(f"{run_dir}: no final_model.zip or checkpoints/{CHECKPOINT_PREFIX}_<N>_steps.zip")
    if cfg.normalize is not False and checkpoint.vecnormalize is None:
        raise RunDirError(f"{run_dir}: normalize is on but no VecNormalize statistics for {checkpoint.model}")
    total_timesteps = _resume_steps(run_dir, cfg, checkpoint, request.total_timesteps)
    command = [
        *command_prefix(cfg),
        "--resume",
        str(run_dir),
        "--total-timesteps",
        str(total_timesteps),
        "--vec-env",
        vec_env,
    ]
    segment = TrainingSegment(
        run_dir,
        cfg,
        env_id,
        seed,
        gym_packages,
        total_timesteps,
        command,
        checkpoint,
        vec_env,
        verbose,
        factories,
    )
    segment.run(progress, callbacks, after_eval)
    return run_dir


def _resumed_config(run_dir: Path, request: ResumeRequest) -> tuple[dict[str, Any], TrainConfig]:
    """The run's recorded ``config.yml`` and its configuration; what the request states must agree with it."""
    config_file = run_dir / "config.yml"
    if not config_file.is_file() or not (run_dir / "meta.json").is_file():
        raise RunDirError(f"{run_dir} is not a run directory (config.yml / meta.json missing)")
    resolved = yaml.safe_load(config_file.read_text(encoding="utf-8"))
    for name, value in (("algo", request.algo), ("env_id", request.env_id)):
        if value is not None and value != resolved[name]:
            raise ConfigError(f"--resume {run_dir}: {name} {value!r} differs from the run's {resolved[name]!r}")
    algo, env_id = resolved["algo"], resolved["env_id"]
    cfg = parse_entry(resolved["config"], algo, source=str(config_file), entry_name=env_id)
    if request.n_envs is not None and request.n_envs != cfg.n_envs:
        raise ConfigError(f"--resume: n_envs cannot change ({cfg.n_envs} in {config_file}, got {request.n_envs})")
    for name, value in request.given.items():
        if name == "residual_base" and value == NO_BASE:
            value = None if cfg.residual_base is None else value  # --residual none agrees with a run without a base
        if value is not None and value != getattr(cfg, name):
            raise ConfigError(
                f"--resume: {name} cannot change ({getattr(cfg, name)!r} in {config_file}, got {value!r}); "
                "the run keeps its composition"
            )
    return resolved, cfg


def _last_vec_env(run_dir: Path) -> str:
    """The vectorised env type of the run's last segment (``dummy`` for a run with no segment recorded)."""
    try:
        segments = json.loads((run_dir / "meta.json").read_text(encoding="utf-8"))["segments"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise RunDirError(f"{run_dir}/meta.json is unreadable or has no segments list: {exc}") from exc
    if not segments:
        return "dummy"
    vec_env = segments[-1].get("vec_env", "dummy")
    if vec_env not in VEC_ENV_TYPES:
        raise RunDirError(f"{run_dir}/meta.json: last segment's vec_env {vec_env!r} is not one of {VEC_ENV_TYPES}")
    return vec_env


def _resume_steps(run_dir: Path, cfg: TrainConfig, checkpoint: Checkpoint, requested: int | None) -> int:
    """The steps a resume trains: those requested, or those missing to the configured ``n_timesteps``."""
    total_timesteps = requested
    if total_timesteps is None:
        total_timesteps = cfg.n_timesteps - checkpoint.num_timesteps
        if total_timesteps <= 0:
            raise ConfigError(
                f"{run_dir} already has {checkpoint.num_timesteps} of {cfg.n_timesteps} steps; "
                "pass --total-timesteps N to train N more steps"
            )
    if total_timesteps <= 0:
        raise ConfigError(f"total_timesteps must be positive, got {total_timesteps}")
    return total_timesteps


# ------------------------------------------------------------------------------------------------------
# Command line
# ------------------------------------------------------------------------------------------------------
