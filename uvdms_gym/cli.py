"""The ``uvdms`` command: thin wrappers over library functions (each subcommand imports lazily)."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Sequence

import yaml

log = logging.getLogger("uvdms")


def parse_kv(items: Sequence[str] | None) -> dict:
    """Parse ``k=v`` strings; values are YAML literals (``case=1``, ``radius=0.15``, ``goal=random``).

    Raises:
        SystemExit: an item without ``=`` (argparse-style error message).
    """
    out: dict = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise SystemExit(f"uvdms: error: expected key=value, got {item!r}")
        out[key] = yaml.safe_load(value)
    return out


def _emit_json(obj: dict) -> None:
    sys.stdout.write(json.dumps(obj, indent=2, sort_keys=True) + "\n")


def _cmd_demo(args: argparse.Namespace) -> int:
    from uvdms_gym.demo import run_demo

    run_demo(seconds=args.seconds, gui=args.gui, png=args.png, trace_every=args.trace_every)
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from uvdms_gym import bench

    if args.what == "train":
        from agents.bench import bench_train as fn
    else:
        fn = {"sim": bench.bench_sim, "env": bench.bench_env, "mpc": bench.bench_mpc}[args.what]
    result = fn(quick=args.quick)
    if args.json:
        _emit_json(result)
    else:
        for key, value in result.items():
            sys.stdout.write(f"{key}: {value}\n")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``uvdms`` (subcommands register themselves here)."""
    parser = argparse.ArgumentParser(prog="uvdms", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="drop the vehicle with arms holding a pose and print a state trace")
    demo.add_argument("--seconds", type=float, default=5.0, help="simulated time (s)")
    demo.add_argument("--gui", action="store_true", help="open the PyBullet GUI window")
    demo.add_argument("--png", default=None, help="save a rendered frame at the end to this PNG path")
    demo.add_argument("--trace-every", type=float, default=0.5, help="trace period (s)")
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


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``uvdms`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO, format="%(levelname)s %(name)s: %(message)s"
    )
    return int(args.func(args) or 0)


if __name__ == "__main__":
    raise SystemExit(main())
