"""Subcommand ``uvdms reproduce`` (registered by :mod:`uvdms_cli.main`)."""

from __future__ import annotations

import argparse


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``reproduce`` to the ``uvdms`` command."""
    rp = subparsers.add_parser(
        "reproduce",
        help="run the paper's experiments: figures, summary.md and acceptance checks",
        description="Case 1/2 circle tracking (MPC vs CAMPC), transport with campc-nndi and the NN ablation; "
        "writes PNG figures, summary.md and results.json into --out (see baselines.paper.reproduce).",
    )
    rp.add_argument("--out", required=True, help="output folder")
    rp.add_argument("--check", action="store_true", help="exit non-zero if an acceptance criterion fails")
    rp.add_argument("--quick", action="store_true", help="ablation on Case 1 only, smaller figures")
    rp.set_defaults(func=_cmd_reproduce)


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from baselines.paper.reproduce import reproduce

    return reproduce(args.out, check=args.check, quick=args.quick)
