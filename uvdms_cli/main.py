"""The ``uvdms`` command: thin wrappers over library functions (each subcommand imports lazily).

Errors [D]: library code raises specific exceptions with messages naming the problem (``ValueError`` and its
subclasses for bad arguments, ``OSError`` subclasses for files,
:class:`~uvdms_gym.utils.display.DisplayUnavailableError`
for a missing display, ...). :func:`main` is the one place that turns the user-facing ones
(:func:`user_error_types`) into a single line ``uvdms: error: <message>`` on stderr and exit status 2
(argparse's convention for usage errors); anything else is a bug and keeps its traceback. ``--debug`` (or the
environment variable ``UVDMS_DEBUG=1``) re-raises every error with its traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import os
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

import yaml

from uvdms_gym.utils.cli import OneLineArgumentParser

if TYPE_CHECKING:
    from agents.common.envs import ActionComponents

log = logging.getLogger("uvdms")


DEBUG_ENV = "UVDMS_DEBUG"
"""Environment variable that, set to a non-empty value other than ``0``, works like ``--debug``."""


def _emit_json(obj: dict) -> None:
    sys.stdout.write(json.dumps(obj, indent=2, sort_keys=True) + "\n")


def _cmd_demo(args: argparse.Namespace) -> int:
    from uvdms_cli.demo import run_demo

    run_demo(seconds=args.seconds, gui=args.gui, png=args.png, trace_every=args.trace_every)
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from uvdms_gym.utils.provenance import timing_record

    if args.what == "train":
        from agents.training.bench import bench_train as fn
    elif args.what == "leaderboard":
        from leaderboard.bench import bench_leaderboard as fn
    elif args.what == "mpc":
        from baselines.bench import benchmark_all as fn
    else:
        from uvdms_cli import bench

        fn = {"sim": bench.bench_sim, "env": bench.bench_env}[args.what]
    with timing_record() as timing:
        result = fn(quick=args.quick)
    result = {**result, "timing": timing}
    if args.json:
        _emit_json(result)
    else:
        for key, value in result.items():
            sys.stdout.write(f"{key}: {value}\n")
    return 0


def _package_version() -> str:
    """The version of the code that runs (``uvdms_gym.__version__``), as runs record it.

    An editable install keeps the metadata of the version it was installed at; the running code's version is the
    one a bug report needs. ``(not installed)`` marks a source tree run without an install.
    """
    import importlib.metadata

    from uvdms_gym.utils.provenance import package_versions

    version = package_versions({"uvdms_gym": "uvdms-gym"})["uvdms_gym"]
    try:
        importlib.metadata.version("uvdms-gym")
    except importlib.metadata.PackageNotFoundError:
        return f"{version} (not installed)"
    return version


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``uvdms`` (subcommands register themselves here)."""
    parser = OneLineArgumentParser(prog="uvdms", description=__doc__.split("\n\n")[0])
    parser.add_argument("--version", action="version", version=f"%(prog)s {_package_version()}")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    parser.add_argument(
        "--debug",
        action="store_true",
        help=f"show the full traceback of an error instead of one line (also: {DEBUG_ENV}=1)",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="drop the vehicle with arms holding a pose and print a state trace")
    demo.add_argument("--seconds", type=float, default=5.0, help="simulated time (s, > 0)")
    demo.add_argument("--gui", action="store_true", help="open the PyBullet GUI window (needs a display)")
    demo.add_argument("--png", default=None, help="save a rendered frame at the end to this PNG path")
    demo.add_argument("--trace-every", type=float, default=0.5, help="trace period (s, > 0)")
    demo.set_defaults(func=_cmd_demo)

    bench = sub.add_parser("bench", help="benchmarks that print medians and ratios")
    bench.add_argument("what", choices=["sim", "env", "mpc", "train", "leaderboard"])
    bench.add_argument("--json", action="store_true", help="print JSON")
    bench.add_argument("--quick", action="store_true", help="fewer repetitions")
    bench.set_defaults(func=_cmd_bench)

    _register_commands(sub)
    return parser


def _register_commands(sub: argparse._SubParsersAction) -> None:
    """Subcommands implemented beside the packages they drive (each module's ``register(subparsers)``)."""
    from agents import cli as agents_cli
    from agents.distributed import cli as sweep_cli
    from baselines import cli as baselines_cli
    from leaderboard import cli as leaderboard_cli
    from uvdms_cli import evaluate

    evaluate.register(sub)
    baselines_cli.register(sub)
    agents_cli.register(sub, components=_action_components)  # uvdms train composes residuals and the filter
    sweep_cli.register(sub, components=_action_components)  # so do residual and filtered sweeps
    leaderboard_cli.register(sub)


def _action_components() -> ActionComponents:
    """What ``uvdms train`` injects: the residual bases and the safety filter (built when training starts)."""
    from leaderboard.suite.registry import action_components

    return action_components()


def user_error_types() -> tuple[type[BaseException], ...]:
    """The exceptions :func:`main` reports as one line: bad arguments, files, formats, a missing display.

    ``ValueError`` covers the project's argument errors and their subclasses (``UntrustedFileError``,
    ``ExportFormatError``, ``ConfigError``, ...); ``OSError`` missing, existing or unreadable files;
    ``zipfile.BadZipFile`` a corrupt model archive; ``gymnasium.error.Error`` Gymnasium's registry errors;
    ``yaml.YAMLError`` a malformed configuration file.
    """
    import zipfile

    from gymnasium import error as gym_error

    from uvdms_gym.utils.display import DisplayUnavailableError

    return (ValueError, OSError, zipfile.BadZipFile, gym_error.Error, yaml.YAMLError, DisplayUnavailableError)


def error_message(exc: BaseException) -> str:
    """One line naming the problem of a user-facing error (whitespace, e.g. YAML's multi-line, collapsed)."""
    import zipfile

    if isinstance(exc, OSError) and exc.strerror:
        msg = f"{exc.strerror}: {exc.filename}" if exc.filename is not None else exc.strerror
    else:
        msg = str(exc)
    if isinstance(exc, FileNotFoundError) and not exc.strerror and len(msg.split()) <= 1:  # FileNotFoundError(path)
        msg = f"not found: {msg}"
    if isinstance(exc, zipfile.BadZipFile):
        msg = f"a model file is not a valid zip archive (corrupt or truncated): {msg}"
    if type(exc).__name__ == "UntrustedFileError":  # the library speaks Python (trust=True), the CLI has a flag
        msg = msg.replace("pass trust=True", "pass --trust")
        msg = msg.replace("(export_agent / load_weights_only)", "(uvdms export-agent PATH OUT --trust, once)")
    return " ".join(msg.split()) or type(exc).__name__


def _import_pybullet_quietly() -> None:
    """Import PyBullet once with its ``pybullet build time: ...`` line suppressed (3 ms; it is needed anyway)."""
    if "pybullet" in sys.modules:
        return
    from uvdms_gym.utils.io import quiet_c_stream

    with quiet_c_stream(sys.stderr), contextlib.suppress(ImportError):
        import pybullet  # noqa: F401


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``uvdms`` console script; returns the exit status (2: a user-facing error)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    debug = args.debug or os.environ.get(DEBUG_ENV, "") not in ("", "0")
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO, format="%(levelname)s %(name)s: %(message)s"
    )
    _import_pybullet_quietly()
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        if debug:
            raise
        sys.stderr.write("uvdms: interrupted\n")
        return 130
    except user_error_types() as exc:
        if debug:
            raise
        sys.stderr.write(f"uvdms: error: {error_message(exc)}\n")
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
