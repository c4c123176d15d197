"""``uvdms`` subcommands of the agents package: ``uvdms train`` and ``uvdms export-agent``.

:mod:`uvdms_cli.main` imports this module and calls :func:`register` with its subparsers.
``uvdms train`` takes exactly the arguments of ``python -m agents.training.train`` (the parser is shared); unlike it, it
gets the base and filter factories of residual agents and the safety filter from the composition layer
(``register(..., components=...)``: :mod:`uvdms_cli.main` passes the registry's, built on first use).
``uvdms export-agent RUN_DIR OUT`` writes the weights-only export of :func:`agents.export.export_agent`.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from agents.common.names import NO_BASE

if TYPE_CHECKING:
    from agents.common.envs import ActionComponents

_TRAIN_HELP = "train a Stable-Baselines3 agent from train_configs/<algo>.yml (same as python -m agents.training.train)"
_EXPORT_HELP = "export a trained agent to the weights-only format (no pickles; loads with load_weights_only)"


def register(
    subparsers: argparse._SubParsersAction, *, components: Callable[[], ActionComponents] | None = None
) -> None:
    """Add ``train`` and ``export-agent`` to the ``uvdms`` subcommands.

    Args:
        subparsers: The ``add_subparsers()`` object of the ``uvdms`` parser.
        components: Returns the base and filter factories that residual and filtered training need (called
            only when ``uvdms train`` runs; ``None``: such configurations are refused).
    """
    from agents.training.args import build_parser

    train_parser = build_parser()
    train = subparsers.add_parser(
        "train",
        help=_TRAIN_HELP,
        description=train_parser.description,
        epilog=train_parser.epilog,
        parents=[train_parser],
        add_help=False,
    )
    train.set_defaults(func=_cmd_train, _train_parser=train, _components=components)

    export = subparsers.add_parser("export-agent", help=_EXPORT_HELP, description=_EXPORT_HELP)
    export.add_argument(
        "run_dir", type=Path, metavar="RUN_DIR", help="run directory, shipped agent folder or SB3 zip to export"
    )
    export.add_argument("out", type=Path, metavar="OUT", help="output directory (agent.json, policy.pt, ...)")
    export.add_argument(
        "--which", choices=("best", "final"), default="final", help="model of a run directory (default final)"
    )
    export.add_argument(
        "--trust",
        action="store_true",
        help="allow unpickling the run's SB3 zip / VecNormalize files (implied inside trained_agents/)",
    )
    export.add_argument("--overwrite", action="store_true", help="replace the files of an existing export")
    export.set_defaults(func=_cmd_export)


_TRAIN_OPTIONS: tuple[tuple[str, str, Callable[[Any], list[str]] | None], ...] = (
    # (namespace attribute, option, its values; None: a flag), in the order of the rebuilt command line
    ("algo", "--algo", lambda v: [v]),
    ("env_id", "--env", lambda v: [v]),
    ("env_kwargs", "--env-kwargs", list),
    ("config", "--config", lambda v: [str(v)]),
    ("hyperparams", "--hyperparams", list),
    ("seed", "--seed", lambda v: [str(v)]),
    ("total_timesteps", "--total-timesteps", lambda v: [str(v)]),
    ("n_envs", "--n-envs", lambda v: [str(v)]),
    ("out", "--out", lambda v: [str(v)]),
    ("resume", "--resume", lambda v: [str(v)]),
    ("vec_env", "--vec-env", lambda v: [v]),
    ("gym_packages", "--gym-packages", list),
    ("residual", "--residual", lambda v: [v]),
    ("residual_scale", "--residual-scale", lambda v: [repr(v)]),
    ("residual_observation", "--residual-observation", lambda v: [v]),
    ("residual_space", "--residual-space", lambda v: [v]),
    ("safety_filter", "--safety-filter", None),
    ("no_progress", "--no-progress", None),
    ("verbose", "--verbose", lambda v: [str(v)]),
)
"""How ``uvdms train``'s namespace maps back to ``python -m agents.training.train``'s options (:func:`_train_argv`)."""
_ALWAYS = ("seed", "out", "gym_packages", "verbose")
"""Options written even at their defaults (the others only when given: ``None``, empty and ``False`` are not)."""


def _train_argv(args: argparse.Namespace) -> list[str]:
    """Rebuild the ``agents.training.train`` argument list from the parsed namespace (so ``main`` does the work)."""
    argv: list[str] = []
    for attribute, option, values in _TRAIN_OPTIONS:
        value = getattr(args, attribute)
        if values is None:
            argv += [option] if value else []
        elif attribute in _ALWAYS or (value is not None and value != []):
            argv += [option, *values(value)]
    return argv


def _cmd_train(args: argparse.Namespace) -> int:
    from uvdms_gym.utils.kwargs import check_make_kwargs, parse_kv

    if args.resume is None and (args.algo is None or args.env_id is None):
        args._train_parser.error("--algo and --env are required unless --resume DIR is given")
    if args.env_id is not None:  # before torch loads and a run directory exists: bad YAML, ids and keys
        env_kwargs = parse_kv(args.env_kwargs, "--env-kwargs")
        parse_kv(args.hyperparams, "--hyperparams")
        _import_quietly(args.gym_packages)  # import failures are reported by agents.training.train
        import gymnasium as gym

        if ":" not in args.env_id and args.env_id not in gym.registry:
            from agents.training.train import EnvironmentNotFoundError, check_env_id

            try:
                check_env_id(args.env_id, args.gym_packages)  # its message names failed imports, close matches
            except EnvironmentNotFoundError as exc:
                raise ValueError(str(exc)) from None
        check_make_kwargs(args.env_id, env_kwargs, "--env-kwargs")
    components = args._components() if args._components is not None else None
    if args.residual not in (None, NO_BASE) and components is not None:
        components.base_factory(args.residual)  # an unknown or torque-mode base: one line, before torch loads
    from agents.training.train import main

    return main(_train_argv(args), components=components)


def _import_quietly(packages: list[str]) -> None:
    """Import the packages that register environments, ignoring failures (``agents.training.train`` reports them)."""
    import contextlib
    import importlib

    for name in packages:
        with contextlib.suppress(Exception):
            importlib.import_module(name)


def _cmd_export(args: argparse.Namespace) -> int:
    import zipfile

    out_dir = Path(args.out)
    if out_dir.is_dir() and any(out_dir.iterdir()) and not args.overwrite:  # before loading torch and the model
        raise FileExistsError(f"{out_dir} exists and is not empty (pass --overwrite to replace its files)")
    from agents.export import UntrustedFileError, export_agent

    try:
        out = export_agent(args.run_dir, args.out, which=args.which, trust=args.trust, overwrite=args.overwrite)
    except zipfile.BadZipFile as exc:  # other errors are reported by uvdms_cli.main.main as one line
        raise ValueError(
            f"{args.run_dir}: a model file is not a valid zip archive, corrupt or truncated ({exc})"
        ) from None
    except UntrustedFileError as exc:  # this command is the way to a weights-only export: advise its flag only
        raise UntrustedFileError(
            f"{exc.path} contains pickled objects, which can run arbitrary code when loaded: pass --trust if you "
            "trust its origin, and this command writes a weights-only export that loads without trust"
        ) from None
    print(out)
    return 0
