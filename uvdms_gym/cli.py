"""The ``uvdms`` command: thin wrappers over library functions (each subcommand imports lazily).

Errors [D]: library code raises specific exceptions with messages naming the problem (``ValueError`` and its
subclasses for bad arguments, ``OSError`` subclasses for files, :class:`~uvdms_gym.display.DisplayUnavailableError`
for a missing display, ...). :func:`main` is the one place that turns the user-facing ones
(:func:`user_error_types`) into a single line ``uvdms: error: <message>`` on stderr and exit status 2
(argparse's convention for usage errors); anything else is a bug and keeps its traceback. ``--debug`` (or the
environment variable ``UVDMS_DEBUG=1``) re-raises every error with its traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import inspect
import json
import logging
import os
import sys
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import yaml

log = logging.getLogger("uvdms")

DEBUG_ENV = "UVDMS_DEBUG"
"""Environment variable that, set to a non-empty value other than ``0``, works like ``--debug``."""
GYM_MAKE_KWARGS: tuple[str, ...] = ("max_episode_steps", "disable_env_checker")
"""Keyword arguments ``gymnasium.make`` takes itself (not passed to the environment)."""


def parse_kv(items: Sequence[str] | None, option: str = "--env-kwargs") -> dict:
    """Parse ``k=v`` strings; values are YAML literals (``case=1``, ``radius=0.15``, ``goal=random``).

    Args:
        items: The strings.
        option: The option they came from (for error messages).

    Raises:
        ValueError: An item without ``=`` or an identifier key, or a value that is not valid YAML.
    """
    out: dict = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        if not sep or not key.isidentifier():
            raise ValueError(f"{option}: expected key=value with an identifier key, got {item!r}")
        try:
            out[key] = yaml.safe_load(value) if value else ""
        except yaml.YAMLError as exc:
            problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
            raise ValueError(f"{option}: the value of {key!r} ({value!r}) is not a YAML literal: {problem}") from None
    return out


def env_spec(env_id: str) -> Any:
    """The Gymnasium spec of ``env_id`` (``module:Id`` imports the module first).

    Raises:
        ValueError: The id is not registered (the message lists the ``uvdms/`` ids).
    """
    import importlib

    import gymnasium as gym

    import uvdms_gym

    module, sep, name = env_id.rpartition(":")
    if sep:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise ValueError(f"environment id {env_id!r}: cannot import {module!r} ({exc})") from None
    try:
        return gym.spec(name)
    except gym.error.Error as exc:
        raise ValueError(
            f"unknown environment id {name!r} ({exc}); the uvdms environments are {', '.join(uvdms_gym.ENV_IDS)}"
        ) from None


def check_make_kwargs(env_id: str, kwargs: Mapping[str, Any]) -> None:
    """Check that ``gymnasium.make(env_id, **kwargs)`` accepts every key (values are the environment's to check).

    The accepted keys are :data:`GYM_MAKE_KWARGS` and the keyword parameters of the entry point's
    ``__init__`` along its class hierarchy (a ``**kwargs`` passes on to the base class); an entry point that
    takes arbitrary ``**kwargs`` accepts everything.

    Raises:
        ValueError: Unknown id, or keys the environment does not take (the message lists the accepted ones).
    """
    from gymnasium.envs.registration import load_env_creator

    spec = env_spec(env_id)
    creator = spec.entry_point if callable(spec.entry_point) else load_env_creator(spec.entry_point)
    accepted = set(GYM_MAKE_KWARGS)
    functions = (
        [k.__init__ for k in creator.__mro__ if "__init__" in vars(k)] if isinstance(creator, type) else [creator]
    )
    open_ended = True
    for fn in functions:
        params = inspect.signature(fn).parameters.values()
        accepted |= {p.name for p in params if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD) and p.name != "self"}
        if not any(p.kind is p.VAR_KEYWORD for p in params):
            open_ended = False
            break
    unknown = sorted(set(kwargs) - accepted)
    if unknown and not open_ended:
        raise ValueError(
            f"{env_id} takes no keyword argument {', '.join(map(repr, unknown))}; "
            f"it takes {', '.join(sorted(accepted))}"
        )


def _emit_json(obj: dict) -> None:
    sys.stdout.write(json.dumps(obj, indent=2, sort_keys=True) + "\n")


def _cmd_demo(args: argparse.Namespace) -> int:
    from uvdms_gym.demo import run_demo

    run_demo(seconds=args.seconds, gui=args.gui, png=args.png, trace_every=args.trace_every)
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from uvdms_gym import bench
    from uvdms_gym.provenance import timing_record

    if args.what == "train":
        from agents.bench import bench_train as fn
    else:
        fn = {"sim": bench.bench_sim, "env": bench.bench_env, "mpc": bench.bench_mpc}[args.what]
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
    """The installed distribution's version (``uvdms_gym.__version__`` when running from a source tree)."""
    import importlib.metadata

    try:
        return importlib.metadata.version("uvdms-gym")
    except importlib.metadata.PackageNotFoundError:
        import uvdms_gym

        return f"{uvdms_gym.__version__} (not installed)"


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``uvdms`` (subcommands register themselves here)."""
    parser = argparse.ArgumentParser(prog="uvdms", description=__doc__.split("\n\n")[0])
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
    bench.add_argument("what", choices=["sim", "env", "mpc", "train"])
    bench.add_argument("--json", action="store_true", help="print JSON")
    bench.add_argument("--quick", action="store_true", help="fewer repetitions")
    bench.set_defaults(func=_cmd_bench)

    _register_optional(sub)
    return parser


def _register_optional(sub: argparse._SubParsersAction) -> None:
    """Subcommands implemented in other packages (baselines, agents, leaderboard)."""
    import importlib

    for module_name in ("baselines.cli", "agents.cli", "uvdms_gym.leaderboard_cli"):
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name != module_name:
                raise
            continue
        module.register(sub)


def user_error_types() -> tuple[type[BaseException], ...]:
    """The exceptions :func:`main` reports as one line: bad arguments, files, formats, a missing display.

    ``ValueError`` covers the project's argument errors and their subclasses (``UntrustedFileError``,
    ``ExportFormatError``, ``ConfigError``, ...); ``OSError`` missing, existing or unreadable files;
    ``zipfile.BadZipFile`` a corrupt model archive; ``gymnasium.error.Error`` Gymnasium's registry errors;
    ``yaml.YAMLError`` a malformed configuration file.
    """
    import zipfile

    from gymnasium import error as gym_error

    from uvdms_gym.display import DisplayUnavailableError

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
    return " ".join(msg.split()) or type(exc).__name__


@contextlib.contextmanager
def _quiet_stderr_fd() -> Iterator[None]:
    """Silence the C-level stderr for the duration of the block (PyBullet's import prints its build time)."""
    try:
        sys.stderr.flush()
        fd = sys.stderr.fileno()
        saved = os.dup(fd)
    except (AttributeError, OSError, ValueError):
        yield
        return
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), fd)
            try:
                yield
            finally:
                os.dup2(saved, fd)
    finally:
        os.close(saved)


def _import_pybullet_quietly() -> None:
    """Import PyBullet once with its ``pybullet build time: ...`` line suppressed (3 ms; it is needed anyway)."""
    if "pybullet" in sys.modules:
        return
    with _quiet_stderr_fd(), contextlib.suppress(ImportError):
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
