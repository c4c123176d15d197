"""Train a Stable-Baselines3 agent on a Gymnasium environment from a YAML configuration.

Library entry point: :func:`train`; command line: ``python -m agents.train`` (:func:`main`). The parts live in
:mod:`agents.envs` (env construction, seeds), :mod:`agents.callbacks`, :mod:`agents.models` (replay buffer,
action-layer scaling) and :mod:`agents.rundir` (run directories, checkpoints); their public names are
re-exported here. The same ``train_configs/<algo>.yml`` also train with ``python -m rl_zoo3.train``
(:mod:`agents.zoo`).

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
    learning_curve.json         the benchmark's metrics of every evaluation (success rate, contact-free rates,
                                position RMSE) against num_timesteps, kept through --resume (uvdms envs only;
                                :mod:`agents.learning_curve`)
    lagrangian.csv              ppo_lagrangian only: the multiplier after every rollout, all segments
                                (agents.ppo_lagrangian.HISTORY_FIELDS)
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

Residual agents and the safety filter (``residual_base``, ``residual_scale``, ``safety_filter`` in the config, or
``--residual BASE --residual-scale S`` / ``--safety-filter``; :mod:`uvdms_gym.residual`) compose the policy with
controllers of ``baselines``, which this package never imports: :func:`train` needs them injected as
``components`` (:class:`agents.envs.ActionComponents`; ``uvdms train`` passes the registry's). Without them (this
module's ``python -m agents.train``) such a configuration is refused with an error naming ``uvdms train``. The
composition is recorded in ``config.yml`` (the flat entry) and in every segment of ``meta.json``, kept by
``--resume``, and exported with the agent.

``--resume DIR`` reloads the newest of ``final_model.zip`` and ``checkpoints/rl_model_<N>_steps.zip``
(with its VecNormalize statistics and, if saved, its replay buffer), keeps counting ``num_timesteps``
(``reset_num_timesteps=False``) and writes into the same directory. ``--total-timesteps`` then means
*additional* steps (default: the steps missing to the configured ``n_timesteps``). Resuming unpickles
the files of DIR (SB3 zips and VecNormalize pickles): only resume runs you trust.
"""

from __future__ import annotations

import json
import shlex
import sys
import time
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import torch
import yaml
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.logger import configure
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecNormalize

from agents.algos import ALGOS, is_off_policy
from agents.args import DEFAULT_GYM_PACKAGES, VEC_ENV_TYPES, build_parser
from agents.callbacks import DelayActorUpdates, LatestBufferCheckpointCallback, SaveBestExtras, SeededEvalCallback
from agents.config import ConfigError, TrainConfig, default_config_path, load_config, parse_entry
from agents.dagger import teacher_margin, teacher_name
from agents.envs import (
    EVAL_SEED_OFFSET,
    SEGMENT_SEED_STRIDE,
    ActionComponents,
    EnvFactory,
    EnvironmentNotFoundError,
    check_env_id,
    eval_env_seed,
    import_gym_packages,
    make_vec_env,
    train_env_seed,
)
from agents.learning_curve import LEARNING_CURVE_FILE, LearningCurve
from agents.models import (
    configured_buffer_size,
    grow_replay_buffer,
    planned_timesteps,
    replay_buffer_size,
    scale_action_layer,
)
from agents.ppo_lagrangian import HISTORY_FILE, LagrangianHistory, PPOLagrangian
from agents.rollouts import check_rollout_vec_env
from agents.rundir import (
    CHECKPOINT_PREFIX,
    Checkpoint,
    RunDirError,
    _write_json,
    create_run_dir,
    latest_checkpoint,
    remove_if_no_model,
    run_dir_for,
    save_final,
    utc_now,
    zip_num_timesteps,
)
from agents.threads import UpdateThreads, update_threads
from agents.wrappers import AliveBonus, ScaledAction
from uvdms_gym.kwargs import parse_kv as _parse_key_values
from uvdms_gym.provenance import git_info, package_versions
from uvdms_gym.residual import ControllerFactory, FilterFactory

__all__ = [  # the names other modules and the tests import from here (the implementations live in the modules above)
    "CHECKPOINT_PREFIX",
    "EVAL_SEED_OFFSET",
    "SEGMENT_SEED_STRIDE",
    "ActionComponents",
    "AliveBonus",
    "Checkpoint",
    "EnvFactory",
    "EnvironmentNotFoundError",
    "RunDirError",
    "ScaledAction",
    "check_env_id",
    "composition_factories",
    "eval_env_seed",
    "git_info",
    "grow_replay_buffer",
    "import_gym_packages",
    "latest_checkpoint",
    "main",
    "package_versions",
    "parse_key_values",
    "replay_buffer_size",
    "resolve_config",
    "run_dir_for",
    "scale_action_layer",
    "train",
    "train_env_seed",
    "zip_num_timesteps",
]

_make_vec_env = make_vec_env  # former private names, kept for agents.bench and old callers
_configured_buffer_size = configured_buffer_size


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
    callbacks: Sequence[BaseCallback] = (),
    after_eval: Sequence[BaseCallback] = (),
    residual_base: str | None = None,
    residual_scale: float | None = None,
    safety_filter: bool | None = None,
    components: ActionComponents | None = None,
    residual_observation: str | None = None,
    residual_space: str | None = None,
) -> Path:
    """Train (or resume training of) an agent and return its run directory.

    Args:
        algo: Algorithm name (``ppo``, ``ppo_lagrangian``, ``sac``, ``td3``, ``tqc``); optional when resuming.
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
        vec_env: ``dummy`` (default: every env in the trainer's process), ``subproc`` (every env in a worker
            process), ``hybrid`` (env 0 in the trainer's process, the others in workers, stepped at the same
            time; identical results to ``dummy``) or ``rollout`` (PPO and PPO-Lagrangian: as ``hybrid``, and each
            env collects its part of every rollout with its own copy of the policy, :mod:`agents.rollouts`; the
            fastest PPO setting with 2 envs on 2 free cores, reproducible from the seed but not identical to ``dummy``).
        gym_packages: Packages to import so that the env id is registered.
        verbose: SB3 verbosity (1: print the training table to stdout).
        callbacks: Extra SB3 callbacks, called on every step after the checkpoint and evaluation callbacks
            (so a checkpoint written on a step is on disk when they run; :mod:`agents.sweep_worker` ships it).
        after_eval: SB3 callbacks called after every evaluation; their ``parent`` is the evaluation callback
            (``parent.last_mean_reward``; :mod:`agents.tune` reports it to Ray Tune). Returning ``False``
            stops training. Ignored when ``eval_freq`` is 0.
        residual_base: Train a residual on this base controller (overrides the config's ``residual_base``;
            ``--residual``). Resume: must equal the run's, if given.
        residual_scale: Bound of the residual in (0, 1] (``--residual-scale``; same rules).
        residual_observation: What the residual policy observes besides the env's observation
            (``--residual-observation``; same rules; :data:`uvdms_gym.residual.RESIDUAL_OBSERVATIONS`).
        residual_space: Where the residual acts (``--residual-space``; same rules;
            :data:`uvdms_gym.residual.RESIDUAL_SPACES`).
        safety_filter: Filter the training envs' velocity command (``--safety-filter``; ``None``: the config's).
        components: The base and filter factories of the composition layer; required when the configuration
            has a residual base or the safety filter.

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
        given = {
            "residual_base": residual_base,
            "residual_scale": residual_scale,
            "residual_observation": residual_observation,
            "residual_space": residual_space,
            "safety_filter": safety_filter,
        }
        return _resume(
            Path(resume_dir),
            algo,
            env_id,
            total_timesteps,
            n_envs,
            progress,
            vec_env,
            verbose,
            callbacks,
            after_eval,
            given,
            components,
        )

    if algo is None or env_id is None:
        raise ConfigError("algo and env id are required unless resuming")
    if algo not in ALGOS:
        raise ConfigError(f"unknown algorithm {algo!r}; choose one of {sorted(ALGOS)}")
    gym_packages = tuple(gym_packages)
    check_env_id(env_id, gym_packages)
    config_path = Path(config_path) if config_path is not None else default_config_path(algo)
    composition_args = {
        key: value
        for key, value in (
            ("residual_base", residual_base),
            ("residual_scale", residual_scale),
            ("residual_observation", residual_observation),
            ("residual_space", residual_space),
            ("safety_filter", safety_filter),
        )
        if value is not None
    }
    cfg = resolve_config(
        config_path, algo, env_id, hyperparams, env_kwargs, n_envs, total_timesteps, composition=composition_args
    )
    _check_vec_env(cfg, vec_env)
    factories = composition_factories(cfg, components)  # before the run directory exists

    run_dir = create_run_dir(
        run_dir_for(out_dir, env_id, algo, seed), algo, env_id, seed, gym_packages, config_path, cfg
    )
    command = [
        *_command_prefix(cfg),
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
    if residual_base is not None:
        command += ["--residual", residual_base]
    if residual_scale is not None:
        command += ["--residual-scale", repr(float(residual_scale))]
    if residual_observation is not None:
        command += ["--residual-observation", residual_observation]
    if residual_space is not None:
        command += ["--residual-space", residual_space]
    if safety_filter:
        command.append("--safety-filter")
    try:
        _run_segment(
            run_dir,
            cfg,
            env_id,
            seed,
            gym_packages,
            cfg.n_timesteps,
            command,
            None,
            progress,
            vec_env,
            verbose,
            callbacks,
            after_eval,
            factories,
        )
    except BaseException as exc:
        # a user error (bad config or kwargs: a ValueError) is reported by the caller in one line; say nothing more
        remove_if_no_model(run_dir, quiet=isinstance(exc, ValueError))
        raise
    return run_dir


def resolve_config(
    config_path: str | Path,
    algo: str,
    env_id: str,
    hyperparams: Mapping[str, Any] | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    n_envs: int | None = None,
    total_timesteps: int | None = None,
    *,
    composition: Mapping[str, Any] | None = None,
) -> TrainConfig:
    """The configuration a fresh run of :func:`train` uses: the file's entry with the command line's overrides.

    Args:
        config_path: The configuration file.
        algo: Algorithm name.
        env_id: Environment id (its entry, or ``default``).
        hyperparams: Config keys overriding the entry (``--hyperparams``).
        env_kwargs: Merged into the entry's ``env_kwargs`` (``--env-kwargs``).
        n_envs: Overrides ``n_envs`` (``--n-envs``).
        total_timesteps: Overrides ``n_timesteps`` (``--total-timesteps``).
        composition: Overrides of ``residual_base``, ``residual_scale``, ``residual_observation``,
            ``residual_space``, ``safety_filter`` (``--residual``, ``--residual-scale``, ``--residual-observation``,
            ``--residual-space``, ``--safety-filter``).

    Raises:
        ConfigError: An invalid file, key or value.
    """
    cfg = load_config(config_path, algo, env_id, overrides=hyperparams)
    entry = cfg.to_entry()
    if env_kwargs:
        entry["env_kwargs"] = {**entry["env_kwargs"], **dict(env_kwargs)}
    if n_envs is not None:
        entry["n_envs"] = n_envs
    if total_timesteps is not None:
        entry["n_timesteps"] = total_timesteps
    entry.update(composition or {})
    return parse_entry(entry, algo, source=f"{config_path} + command line", entry_name=env_id)


def _resume(
    run_dir: Path,
    algo: str | None,
    env_id: str | None,
    total_timesteps: int | None,
    n_envs: int | None,
    progress: bool,
    vec_env: str,
    verbose: int,
    callbacks: Sequence[BaseCallback] = (),
    after_eval: Sequence[BaseCallback] = (),
    given: Mapping[str, Any] | None = None,
    components: ActionComponents | None = None,
) -> Path:
    config_file = run_dir / "config.yml"
    if not config_file.is_file() or not (run_dir / "meta.json").is_file():
        raise RunDirError(f"{run_dir} is not a run directory (config.yml / meta.json missing)")
    resolved = yaml.safe_load(config_file.read_text(encoding="utf-8"))
    for name, value in (("algo", algo), ("env_id", env_id)):
        if value is not None and value != resolved[name]:
            raise ConfigError(f"--resume {run_dir}: {name} {value!r} differs from the run's {resolved[name]!r}")
    algo, env_id, seed = resolved["algo"], resolved["env_id"], int(resolved["seed"])
    cfg = parse_entry(resolved["config"], algo, source=str(config_file), entry_name=env_id)
    if n_envs is not None and n_envs != cfg.n_envs:
        raise ConfigError(f"--resume: n_envs cannot change ({cfg.n_envs} in {config_file}, got {n_envs})")
    for name, value in (given or {}).items():
        if value is not None and value != getattr(cfg, name):
            raise ConfigError(
                f"--resume: {name} cannot change ({getattr(cfg, name)!r} in {config_file}, got {value!r}); "
                "the run keeps its composition"
            )
    _check_vec_env(cfg, vec_env)
    factories = composition_factories(cfg, components)
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
        *_command_prefix(cfg),
        "--resume",
        str(run_dir),
        "--total-timesteps",
        str(total_timesteps),
        "--vec-env",
        vec_env,
    ]
    _run_segment(
        run_dir,
        cfg,
        env_id,
        seed,
        gym_packages,
        total_timesteps,
        command,
        checkpoint,
        progress,
        vec_env,
        verbose,
        callbacks,
        after_eval,
        factories,
    )
    return run_dir


def composition_factories(
    cfg: TrainConfig, components: ActionComponents | None
) -> tuple[ControllerFactory | None, FilterFactory | None, ControllerFactory | None]:
    """The base, filter and teacher factories of a configuration's residual base, safety filter and teacher.

    Args:
        cfg: The configuration.
        components: The composition layer's factories (``None``: none available).

    Returns:
        ``(base_factory, filter_factory, teacher_factory)``, each ``None`` when not configured; the teacher is that
        of an imitation learner (``dagger``'s ``teacher`` hyperparameter, :mod:`agents.dagger`), built like a base.

    Raises:
        ConfigError: A residual base or the filter without ``components`` (the message names ``uvdms train``), a
            base or teacher name the components reject, a ``residual_penalty`` without a residual base, or a
            ``dagger`` configuration without a residual base, with ``residual_space: nullspace`` or with
            ``action_scale`` other than 1 (its labels are residuals in the base's action units, on the full space).
    """
    composition = cfg.composition
    if cfg.residual_penalty and not composition.is_residual:
        raise ConfigError(
            f"residual_penalty={cfg.residual_penalty} shapes a residual agent's reward, but the configuration has no "
            "residual_base (--residual)"
        )
    imitation = cfg.algo == "dagger"
    if imitation:
        problems = []
        if not composition.is_residual:
            problems.append("no residual_base (--residual mpc)")
        if composition.residual_space != "full":
            problems.append(f"residual_space={composition.residual_space!r} (its labels live on the full space)")
        if cfg.action_scale != 1.0:
            problems.append(f"action_scale={cfg.action_scale} (its labels are in the residual's own units: use 1.0)")
        if problems:
            raise ConfigError(
                f"dagger imitates a teacher's correction of a residual base, but this configuration has "
                f"{'; '.join(problems)}"
            )
    if composition.is_plain:
        return None, None, None
    if components is None:
        parts = []
        if composition.is_residual:
            parts.append(f"a residual on {composition.residual_base!r}")
        if composition.safety_filter:
            parts.append("the safety filter")
        raise ConfigError(
            f"this configuration trains {' with '.join(parts)}, whose controllers live in the baselines package, "
            "which agents does not import: train it with `uvdms train` (python -m agents.train cannot), or pass "
            "components= to agents.train.train"
        )
    base_factory = teacher_factory = None
    if composition.is_residual:
        try:
            base_factory = components.base_factory(str(composition.residual_base))
            if imitation:
                margin = teacher_margin(cfg.hyperparams)
                teacher_factory = components.base_factory(teacher_name(cfg.hyperparams), collision_margin=margin)
        except ValueError as exc:
            raise ConfigError(f"{exc}" if not imitation else f"dagger's teacher or base: {exc}") from None
    return base_factory, components.filter_factory if composition.safety_filter else None, teacher_factory


def _check_vec_env(cfg: TrainConfig, vec_env: str) -> None:
    """``--vec-env rollout`` only for the algorithms that collect parallel rollouts (:mod:`agents.rollouts`)."""
    if vec_env == "rollout":
        try:
            check_rollout_vec_env(cfg.algo, bool(cfg.hyperparams.get("use_sde", False)))
        except ValueError as exc:
            raise ConfigError(str(exc)) from None


def _command_prefix(cfg: TrainConfig) -> list[str]:
    """What runs ``cfg``: ``uvdms train`` when it composes controllers, else ``python -m agents.train``."""
    return ["python", "-m", "agents.train"] if cfg.composition.is_plain else ["uvdms", "train"]


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
    extra_callbacks: Sequence[BaseCallback] = (),
    after_eval: Sequence[BaseCallback] = (),
    factories: tuple[ControllerFactory | None, FilterFactory | None, ControllerFactory | None] = (None, None, None),
) -> None:
    meta = json.loads((run_dir / "meta.json").read_text(encoding="utf-8"))
    segment = len(meta["segments"])
    if segment >= EVAL_SEED_OFFSET // SEGMENT_SEED_STRIDE:
        raise RunDirError(f"{run_dir}: too many segments for the seed scheme")
    with (run_dir / "command.txt").open("a", encoding="utf-8") as f:
        f.write(shlex.join(command) + "\n")
    model_seed = train_env_seed(seed, segment, 0)
    (run_dir / "monitor").mkdir(exist_ok=True)
    base_factory, filter_factory, teacher_factory = factories
    composed = {
        "base_factory": base_factory,
        "residual_scale": cfg.residual_scale if base_factory is not None else None,
        "residual_penalty": cfg.residual_penalty if base_factory is not None else 0.0,
        "residual_observation": cfg.residual_observation if base_factory is not None else "base",
        "residual_space": cfg.residual_space if base_factory is not None else "full",
        "filter_factory": filter_factory,
    }
    train_factories = [
        EnvFactory(
            env_id,
            cfg.env_kwargs,
            gym_packages,
            str(run_dir / "monitor" / f"seg{segment}_train_{i}"),
            cfg.max_episode_steps,
            cfg.alive_bonus,
            cfg.action_scale,
            scalar_info=True,
            **composed,
            teacher_factory=teacher_factory,  # training envs only: the evaluation callback needs no labels
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
            **composed,
            episode_metrics=True,
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
        "action_composition": {
            **cfg.composition.to_record(),
            "base_factory": repr(base_factory) if base_factory is not None else None,
            "filter_factory": repr(filter_factory) if filter_factory is not None else None,
            "teacher_factory": repr(teacher_factory) if teacher_factory is not None else None,
        },
        "torch_num_threads": torch.get_num_threads(),
        "torch_update_threads": update_threads(cfg.n_envs, vec_env, not is_off_policy(cfg.algo)),
        "versions": package_versions(),
        "git": git_info(),
        "started_utc": utc_now(),
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
            venv = make_vec_env(train_factories, vec_env)
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
                kwargs["buffer_size"] = replay_buffer_size(configured_buffer_size(cfg), cfg.n_envs, timesteps)
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
                    replay_buffer_size(configured_buffer_size(cfg), cfg.n_envs, start_timesteps + timesteps),
                )
        if is_off_policy(cfg.algo):
            record["replay_buffer_size"] = int(model.replay_buffer.buffer_size * model.replay_buffer.n_envs)
        record["planned_timesteps"] = planned_timesteps(model, cfg, timesteps)
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
                LatestBufferCheckpointCallback(
                    save_freq=max(cfg.checkpoint_freq // cfg.n_envs, 1),
                    save_path=str(run_dir / "checkpoints"),
                    name_prefix=CHECKPOINT_PREFIX,
                    save_replay_buffer=cfg.save_replay_buffer,
                    save_vecnormalize=True,
                )
            )
        if cfg.eval_freq > 0:
            eval_callback = SeededEvalCallback(
                eval_venv,
                eval_seed=eval_env_seed(seed, 0),
                learning_curve=LearningCurve.resume(run_dir / LEARNING_CURVE_FILE, env_id, seed, start_timesteps),
                segment=segment,
                callback_on_new_best=SaveBestExtras(run_dir, segment),
                callback_after_eval=CallbackList(list(after_eval)) if after_eval else None,
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
        if record["torch_update_threads"] > 1:  # the envs are idle during an on-policy update (agents.threads)
            callbacks.append(UpdateThreads(record["torch_update_threads"]))
        if isinstance(model, PPOLagrangian):
            callbacks.append(LagrangianHistory(run_dir / HISTORY_FILE, segment))
        if cfg.actor_warmup_steps > model.num_timesteps:
            callbacks.append(DelayActorUpdates(cfg.actor_warmup_steps))
        callbacks.extend(extra_callbacks)

        model.learn(
            total_timesteps=timesteps,
            callback=CallbackList(callbacks),
            reset_num_timesteps=checkpoint is None,
            progress_bar=progress,
        )
        save_final(run_dir, model, cfg.save_replay_buffer and is_off_policy(cfg.algo))
        record["status"] = "completed"
    except KeyboardInterrupt:
        if model is not None:
            save_final(run_dir, model, cfg.save_replay_buffer and is_off_policy(cfg.algo))
        record["status"] = "interrupted"
        raise
    except BaseException as exc:
        record["status"] = "failed"
        record["error"] = f"{type(exc).__name__}: {exc}"
        raise
    finally:
        record["end_num_timesteps"] = int(model.num_timesteps) if model is not None else None
        record["finished_utc"] = utc_now()
        record["wall_time_s"] = round(time.perf_counter() - start, 3)
        _write_json(run_dir / "meta.json", meta)
        for env in (venv, eval_venv):
            if env is not None:
                env.close()
        if model is not None and getattr(model, "_logger", None) is not None:
            model.logger.close()  # progress.csv and TensorBoard files


# ------------------------------------------------------------------------------------------------------
# Command line
# ------------------------------------------------------------------------------------------------------
def parse_key_values(items: Sequence[str] | None, option: str = "--env-kwargs") -> dict[str, Any]:
    """Parse ``key=value`` strings (:func:`uvdms_gym.kwargs.parse_kv`), raising :class:`ConfigError`.

    Args:
        items: Strings such as ``["case=1", "goal=paper", "hydro_randomization=0.3"]``.
        option: Option name for error messages.

    Returns:
        The mapping (``{"case": 1, "goal": "paper", "hydro_randomization": 0.3}``).

    Raises:
        ConfigError: On a malformed item or a value that is not a YAML literal.
    """
    try:
        return _parse_key_values(items, option)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None


def main(argv: Sequence[str] | None = None, *, components: ActionComponents | None = None) -> int:
    """Command-line entry point; returns the exit code (0 ok, 2 bad arguments/config, 130 interrupted).

    Args:
        argv: The arguments (default ``sys.argv[1:]``).
        components: The base and filter factories (``uvdms train`` passes the registry's; ``python -m
            agents.train`` has none, so it refuses residual and filtered configurations).
    """
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
            residual_base=args.residual,
            residual_scale=args.residual_scale,
            residual_observation=args.residual_observation,
            residual_space=args.residual_space,
            safety_filter=True if args.safety_filter else None,
            components=components,
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
