"""``uvdms sweep`` and ``uvdms tune``: thin command lines over the sweep and the tune functions.

They call :func:`agents.distributed.sweep.sweep` and :func:`agents.distributed.tune.tune`.

:mod:`uvdms_cli.main` calls :func:`register` with its subparsers. Building the parsers imports nothing heavy
(no torch, SB3 or Ray); the commands import the library lazily. Errors in the arguments are raised as
``ValueError`` (one line ``uvdms: error: ...``, exit status 2, from :func:`uvdms_cli.main.main`); a sweep with a
failed run prints its table and exits with status 1.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from agents.training.args import ALGO_NAMES, DEFAULT_GYM_PACKAGES, VEC_ENV_TYPES

if TYPE_CHECKING:
    from agents.common.envs import ActionComponents

_SWEEP_HELP = "train one run per seed (and grid point), locally or as Ray tasks, and summarise them"
_TUNE_HELP = "search hyperparameters with Ray Tune and Optuna's TPE sampler; write the best config"
_SWEEP_EPILOG = (
    "Example: uvdms sweep --algo ppo --env uvdms/CircleTrack-v0 --env-kwargs case=1 --seeds 0 1 2 "
    "--grid learning_rate=1.0e-3,3.0e-4 --backend ray --out sweeps/ppo_case1. Run directories, summary and CPU "
    "accounting: see agents/distributed/sweep.py and docs/CLUSTER_TRAINING.md."
)
_TUNE_EPILOG = (
    "Example: uvdms tune --algo ppo --env uvdms/CircleTrack-v0 --env-kwargs case=1 --n-trials 50 "
    "--total-timesteps 100000 --out tune/ppo_case1; then uvdms train --algo ppo --env uvdms/CircleTrack-v0 "
    "--config tune/ppo_case1/ppo.yml. See agents/distributed/tune.py and docs/CLUSTER_TRAINING.md."
)


def _common(parser: argparse.ArgumentParser) -> None:
    """The training arguments both commands share with ``uvdms train``."""
    parser.add_argument("--algo", required=True, metavar="ALGO", help=f"algorithm: {', '.join(ALGO_NAMES)}")
    parser.add_argument("--env", dest="env_id", required=True, metavar="ID", help="Gymnasium env id")
    parser.add_argument(
        "--env-kwargs", nargs="*", default=[], metavar="K=V", help="gymnasium.make keyword arguments (YAML literals)"
    )
    parser.add_argument("--config", type=Path, help="YAML config (default: train_configs/<algo>.yml)")
    parser.add_argument("--total-timesteps", type=int, help="steps per run (default: the config's n_timesteps)")
    parser.add_argument("--n-envs", type=int, help="training envs per run (default: from the config)")
    parser.add_argument("--vec-env", choices=VEC_ENV_TYPES, default="dummy", help="vectorised env type")
    parser.add_argument(
        "--gym-packages",
        nargs="*",
        default=list(DEFAULT_GYM_PACKAGES),
        metavar="PKG",
        help="packages imported to register env ids (default: uvdms_gym)",
    )
    parser.add_argument("--address", help="Ray cluster address (auto, ray://host:10001, host:port); default: local")
    parser.add_argument("--num-cpus", type=int, help="CPUs of the local Ray instance (default: all cores)")


def register(
    subparsers: argparse._SubParsersAction, *, components: Callable[[], ActionComponents] | None = None
) -> None:
    """Add ``sweep`` and ``tune`` to the ``uvdms`` subcommands.

    Args:
        subparsers: The ``add_subparsers()`` object of the ``uvdms`` parser.
        components: Returns the base and filter factories that residual and filtered sweeps and searches need
            (called only when one runs; ``uvdms_cli`` passes the composition layer's).
    """
    sweep = subparsers.add_parser("sweep", help=_SWEEP_HELP, description=_SWEEP_HELP, epilog=_SWEEP_EPILOG)
    _common(sweep)
    sweep.add_argument(
        "--seeds",
        nargs="*",
        default=[],
        metavar="S",
        help="base seeds, one run each (distinct training seeds, uvdms_gym.seeds)",
    )
    sweep.add_argument(
        "--hyperparams", nargs="*", default=[], metavar="K=V", help="config overrides of every run (YAML literals)"
    )
    sweep.add_argument(
        "--grid",
        nargs="*",
        default=[],
        metavar="K=V1,V2",
        help="grid axes: every combination runs with every seed (learning_rate=1.0e-3,3.0e-4 batch_size=64,256)",
    )
    sweep.add_argument("--backend", choices=("local", "ray"), default="local", help="where runs train (local)")
    sweep.add_argument("--max-retries", type=int, default=3, help="retries of a run whose Ray worker dies (3)")
    sweep.add_argument("--out", type=Path, default=Path("sweeps"), help="run directories and summary (sweeps)")
    sweep.set_defaults(func=_cmd_sweep, _components=components)

    tune = subparsers.add_parser("tune", help=_TUNE_HELP, description=_TUNE_HELP, epilog=_TUNE_EPILOG)
    _common(tune)
    tune.add_argument("--n-trials", type=int, required=True, help="number of sampled configurations")
    tune.add_argument(
        "--hyperparams", nargs="*", default=[], metavar="K=V", help="fixed config keys (left out of the search)"
    )
    tune.add_argument("--search-space", type=Path, help="default: train_configs/search_spaces/<algo>.yml")
    tune.add_argument(
        "--seed", type=int, default=0, help="training seed of every trial (uvdms_gym.seeds) and sampler seed (0)"
    )
    tune.add_argument("--n-startup-trials", type=int, default=10, help="random trials before TPE (10)")
    tune.add_argument("--grace-period", type=int, help="steps before a trial can be pruned (default: eval_freq)")
    tune.add_argument("--reduction-factor", type=float, default=3.0, help="ASHA keeps the best 1/F per rung (3)")
    tune.add_argument("--max-concurrent", type=int, help="trials at a time (default: as the CPUs allow)")
    tune.add_argument("--backend", choices=("ray",), default="ray", help="Ray Tune (the only backend)")
    tune.add_argument("--out", type=Path, default=Path("tune"), help="best config and trial records (tune)")
    tune.set_defaults(func=_cmd_tune, _components=components)


def _seeds(items: list[str]) -> list[int]:
    seeds = []
    for item in items:
        try:
            seeds.append(int(item))
        except ValueError:
            raise ValueError(f"--seeds: {item!r} is not an integer") from None
    return seeds


def _check_env(env_id: str, packages: list[str]) -> None:
    """An unknown env id as a ``ValueError`` (one line), as ``uvdms train`` reports it."""
    from agents.common.envs import EnvironmentNotFoundError, check_env_id

    try:
        check_env_id(env_id, packages)
    except EnvironmentNotFoundError as exc:
        raise ValueError(str(exc)) from None


def _cmd_sweep(args: argparse.Namespace) -> int:
    from agents.distributed.report import format_table
    from agents.distributed.sweep import parse_grid, sweep
    from uvdms_gym.utils.kwargs import parse_kv

    env_kwargs = parse_kv(args.env_kwargs, "--env-kwargs")
    hyperparams = parse_kv(args.hyperparams, "--hyperparams")
    grid = parse_grid(args.grid)
    seeds = _seeds(args.seeds)
    _check_env(args.env_id, args.gym_packages)
    result = sweep(
        args.algo,
        args.env_id,
        seeds,
        env_kwargs=env_kwargs,
        config_path=args.config,
        hyperparams=hyperparams,
        grid=grid,
        total_timesteps=args.total_timesteps,
        n_envs=args.n_envs,
        vec_env=args.vec_env,
        gym_packages=args.gym_packages,
        backend=args.backend,
        address=args.address,
        num_cpus=args.num_cpus,
        max_retries=args.max_retries,
        out_dir=args.out,
        components=args._components() if args._components is not None else None,
    )
    sys.stdout.write(format_table(result.rows) + "\n")
    sys.stdout.write(f"summary: {args.out / 'sweep.csv'}, {args.out / 'sweep.json'}\n")
    for row in result.failed:
        sys.stderr.write(f"uvdms sweep: run {row['run']} failed: {row.get('error')}\n")
    return 1 if result.failed else 0


def _cmd_tune(args: argparse.Namespace) -> int:
    import json

    from agents.distributed.tune import METRIC, NoTrialCompletedError, tune
    from uvdms_gym.utils.kwargs import parse_kv

    env_kwargs = parse_kv(args.env_kwargs, "--env-kwargs")
    hyperparams = parse_kv(args.hyperparams, "--hyperparams")
    _check_env(args.env_id, args.gym_packages)
    try:
        result = _run_tune(args, tune, env_kwargs, hyperparams)
    except NoTrialCompletedError as exc:
        sys.stderr.write(f"uvdms tune: {exc}\n")
        return 1
    counts = {s: sum(t["status"] == s for t in result.trials) for s in ("completed", "pruned", "error")}
    sys.stdout.write(
        f"{len(result.trials)} trials ({', '.join(f'{n} {s}' for s, n in counts.items())}); best {METRIC} "
        f"{result.best[METRIC]:.4g}: {json.dumps(result.best['params'], sort_keys=True)}\n"
    )
    sys.stdout.write(f"best config: {result.best_config}\ntrials: {args.out / 'tune.csv'}\n")
    return 0


def _run_tune(args: argparse.Namespace, tune: Any, env_kwargs: dict, hyperparams: dict) -> Any:
    return tune(
        args.algo,
        args.env_id,
        args.n_trials,
        env_kwargs=env_kwargs,
        config_path=args.config,
        search_space_path=args.search_space,
        hyperparams=hyperparams,
        total_timesteps=args.total_timesteps,
        n_envs=args.n_envs,
        vec_env=args.vec_env,
        gym_packages=args.gym_packages,
        seed=args.seed,
        n_startup_trials=args.n_startup_trials,
        grace_period=args.grace_period,
        reduction_factor=args.reduction_factor,
        max_concurrent=args.max_concurrent,
        address=args.address,
        num_cpus=args.num_cpus,
        out_dir=args.out,
        components=args._components() if args._components is not None else None,
    )
