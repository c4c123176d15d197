"""Train a Stable-Baselines3 agent on a Gymnasium environment from a YAML configuration.

Library entry point: :func:`train`; command line: ``python -m agents.training.train`` (:func:`main`). The parts live in
:mod:`agents.training.spec` (the run specification), :mod:`agents.training.segment` (one training segment),
:mod:`agents.common.envs` (env construction, seeds), :mod:`agents.training.callbacks`, :mod:`agents.training.models`
(replay buffer, action-layer scaling), :mod:`agents.training.rundir` (run directories, checkpoints) and
:mod:`agents.training.resume` (``--resume``); their public names are re-exported here. The same
``train_configs/<algo>.yml`` also train with ``python -m rl_zoo3.train`` (:mod:`agents.config.zoo`).

Run directory ``<out>/<env id, '/' and ':' replaced by '_'>/<algo>_<seed>/``::

    config.yml                  resolved configuration (algo, env id, seed, gym packages, flat entry)
    command.txt                 one equivalent command line per training segment (fresh run, resumes)
    meta.json                   package versions, git revision + dirty flag, seeds and seed protocol,
                                per-segment records
    final_model.zip             model at the end of the latest segment (also written on Ctrl-C)
    vecnormalize.pkl            VecNormalize statistics of final_model.zip (only with ``normalize``)
    replay_buffer.pkl           replay buffer of final_model.zip (only with ``save_replay_buffer``)
    best_model.zip              best model on the evaluation env (only if an evaluation ran)
    best_vecnormalize.pkl       VecNormalize statistics of best_model.zip (only with ``normalize``)
    best_model.json             num_timesteps and mean reward of best_model.zip
    learning_curve.json         the benchmark's metrics of every evaluation (success rate, contact-free rates,
                                position RMSE) against num_timesteps, kept through --resume (uvdms envs only;
                                :mod:`agents.common.learning_curve`)
    lagrangian.csv              ppo_lagrangian only: the multiplier after every rollout, all segments
                                (agents.algos.ppo_lagrangian.HISTORY_FIELDS)
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

Seed protocol (:mod:`uvdms_gym.seeds`, recorded in ``meta.json`` as ``seed_protocol`` and ``seed_split``): ``seed``
and all these derived seeds are ``training`` seeds (``[0, 1e9)``), never validation or test seeds. A seed whose
derived seeds would leave that range (up to 1000 segments and every evaluation env; so any seed above
``1e9 - 1_000_000 - n_eval_envs``), or a negative one, is refused in one line before anything runs
(:func:`agents.common.envs.check_training_seed`; ``uvdms_gym.seeds.SeedProtocolError``).

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
``components`` (:class:`agents.common.envs.ActionComponents`; ``uvdms train`` passes the registry's). Without them (this
module's ``python -m agents.training.train``) such a configuration is refused with an error naming ``uvdms train``. The
composition is recorded in ``config.yml`` (the flat entry) and in every segment of ``meta.json``, kept by
``--resume``, and exported with the agent.

``--resume DIR`` reloads the newest of ``final_model.zip`` and ``checkpoints/rl_model_<N>_steps.zip``
(with its VecNormalize statistics and, if saved, its replay buffer), keeps counting ``num_timesteps``
(``reset_num_timesteps=False``) and writes into the same directory. ``--total-timesteps`` then means
*additional* steps (default: the steps missing to the configured ``n_timesteps``). Resuming unpickles
the files of DIR (SB3 zips and VecNormalize pickles): only resume runs you trust.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import torch
from stable_baselines3.common.callbacks import BaseCallback

from agents.common.envs import (
    EVAL_SEED_OFFSET,
    SEGMENT_SEED_STRIDE,
    ActionComponents,
    EnvFactory,
    EnvironmentNotFoundError,
    check_env_id,
    check_training_seed,
    eval_env_seed,
    import_gym_packages,
    train_env_seed,
)
from agents.common.wrappers import AliveBonus, ScaledAction
from agents.config import ConfigError
from agents.training.args import DEFAULT_GYM_PACKAGES, VEC_ENV_TYPES, build_parser
from agents.training.composition import check_vec_env, composition_factories
from agents.training.models import (
    grow_replay_buffer,
    replay_buffer_size,
    scale_action_layer,
)
from agents.training.resume import ResumeRequest, resume_run
from agents.training.rundir import (
    CHECKPOINT_PREFIX,
    Checkpoint,
    RunDirError,
    create_run_dir,
    latest_checkpoint,
    remove_if_no_model,
    run_dir_for,
    zip_num_timesteps,
)
from agents.training.segment import TrainingSegment
from agents.training.spec import RunSpec, resolve_config
from uvdms_gym.seeds import SeedProtocolError
from uvdms_gym.utils.kwargs import check_make_kwargs
from uvdms_gym.utils.kwargs import parse_kv as _parse_key_values
from uvdms_gym.utils.provenance import git_info, package_versions

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
    "check_training_seed",
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
    vec_env: str | None = None,
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
        seed: Base seed, a training seed of :mod:`uvdms_gym.seeds` (see the module docstring for the seed scheme).
        total_timesteps: Fresh run: total steps (overrides ``n_timesteps``). Resume: additional steps
            (default: the steps missing to ``n_timesteps``).
        n_envs: Number of training environments (overrides the config).
        out_dir: Root of the run directories.
        resume_dir: Run directory to resume; the other configuration arguments must then be left at
            their defaults or agree with the run's ``config.yml``.
        progress: Show a progress bar (tqdm + rich).
        hyperparams: Extra config keys (algorithm hyperparameters or TrainConfig fields) overriding the
            file, validated like the file. Not allowed when resuming.
        vec_env: ``None`` (default: ``dummy``, or for a resume the last segment's type), ``dummy`` (every env in
            the trainer's process), ``subproc`` (every env in a worker process), ``hybrid`` (env 0 in the trainer's
            process, the others in workers, stepped at the same time; identical results to ``dummy``) or
            ``rollout`` (PPO and PPO-Lagrangian: as ``hybrid``, and each env collects its part of every rollout with
            its own copy of the policy, :mod:`agents.common.rollouts`; the fastest PPO setting with 2 envs on 2 free
            cores, reproducible from the seed but not identical to ``dummy``).
        gym_packages: Packages to import so that the env id is registered.
        verbose: SB3 verbosity (1: print the training table to stdout).
        callbacks: Extra SB3 callbacks, called on every step after the checkpoint and evaluation callbacks
            (so a checkpoint written on a step is on disk when they run; :mod:`agents.distributed.worker` ships it).
        after_eval: SB3 callbacks called after every evaluation; their ``parent`` is the evaluation callback
            (``parent.last_mean_reward``; :mod:`agents.distributed.tune` reports it to Ray Tune). Returning ``False``
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
        SeedProtocolError: The seed or one of its derived seeds is not a training seed (module docstring).
    """
    if vec_env is not None and vec_env not in VEC_ENV_TYPES:
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
        resume = ResumeRequest(algo, env_id, total_timesteps, n_envs, vec_env, given)
        return resume_run(Path(resume_dir), resume, progress, verbose, callbacks, after_eval, components)
    if algo is None or env_id is None:
        raise ConfigError("algo and env id are required unless resuming")
    spec = RunSpec(
        algo=algo,
        env_id=env_id,
        env_kwargs=env_kwargs or {},
        config_path=Path(config_path) if config_path is not None else None,
        seed=seed,
        total_timesteps=total_timesteps,
        n_envs=n_envs,
        hyperparams=hyperparams or {},
        vec_env=vec_env or "dummy",
        gym_packages=tuple(gym_packages),
        residual_base=residual_base,
        residual_scale=residual_scale,
        residual_observation=residual_observation,
        residual_space=residual_space,
        safety_filter=safety_filter,
    )
    return train_run(
        spec,
        out_dir=out_dir,
        progress=progress,
        verbose=verbose,
        callbacks=callbacks,
        after_eval=after_eval,
        components=components,
    )


def train_run(
    spec: RunSpec,
    *,
    out_dir: str | Path = "runs",
    progress: bool = True,
    verbose: int = 0,
    callbacks: Sequence[BaseCallback] = (),
    after_eval: Sequence[BaseCallback] = (),
    components: ActionComponents | None = None,
) -> Path:
    """Train a fresh run of ``spec`` and return its run directory (see :func:`train` for the arguments).

    Raises:
        ConfigError: Invalid configuration or arguments.
        EnvironmentNotFoundError: The env id is not registered.
        RunDirError: The run directory exists.
        SeedProtocolError: The seed or one of its derived seeds is not a training seed.
    """
    torch.set_num_threads(1)
    check_env_id(spec.env_id, spec.gym_packages)
    cfg = spec.resolve()
    check_training_seed(spec.seed, cfg.n_envs, cfg.n_eval_envs, "--seed")
    for kwargs in (cfg.env_kwargs, {**cfg.env_kwargs, **cfg.eval_env_kwargs}):
        try:
            check_make_kwargs(spec.env_id, kwargs)  # a key the env does not take, or radius=abc: one clear line
        except ValueError as exc:
            raise ConfigError(f"--env-kwargs / env_kwargs: {exc}") from None
    check_vec_env(cfg, spec.vec_env)
    factories = composition_factories(cfg, components)  # before the run directory exists
    run_dir = create_run_dir(
        run_dir_for(out_dir, spec.env_id, spec.algo, spec.seed),
        spec.algo,
        spec.env_id,
        spec.seed,
        spec.gym_packages,
        spec.config_file,
        cfg,
    )
    segment = TrainingSegment(
        run_dir,
        cfg,
        spec.env_id,
        spec.seed,
        spec.gym_packages,
        cfg.n_timesteps,
        spec.command(cfg, out_dir),
        None,
        spec.vec_env,
        verbose,
        factories,
    )
    try:
        segment.run(progress, callbacks, after_eval)
    except BaseException as exc:
        # a user error (bad config or kwargs: a ValueError) is reported by the caller in one line; say nothing more
        remove_if_no_model(run_dir, quiet=isinstance(exc, ValueError))
        raise
    return run_dir


def parse_key_values(items: Sequence[str] | None, option: str = "--env-kwargs") -> dict[str, Any]:
    """Parse ``key=value`` strings (:func:`uvdms_gym.utils.kwargs.parse_kv`), raising :class:`ConfigError`.

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
            agents.training.train`` has none, so it refuses residual and filtered configurations).
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
    except (ConfigError, EnvironmentNotFoundError, RunDirError, SeedProtocolError) as exc:
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
