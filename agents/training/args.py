"""The argument parser of ``python -m agents.training.train`` / ``uvdms train``, importable without torch or SB3.

``uvdms`` builds its subcommand parsers at start-up, so this module must stay light (no torch, no SB3).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from agents.common.names import (
    ALGO_NAMES,
    DEFAULT_GYM_PACKAGES,
    RESIDUAL_OBSERVATION_NAMES,
    RESIDUAL_SPACE_NAMES,
    VEC_ENV_TYPES,
)
from uvdms_gym.utils.cli import OneLineArgumentParser

__all__ = [
    "ALGO_NAMES",
    "DEFAULT_GYM_PACKAGES",
    "RESIDUAL_OBSERVATION_NAMES",
    "RESIDUAL_SPACE_NAMES",
    "VEC_ENV_TYPES",
    "build_parser",
]


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of ``python -m agents.training.train``."""
    parser = OneLineArgumentParser(
        command="uvdms",
        prog="python -m agents.training.train",
        description="Train a Stable-Baselines3 agent from train_configs/<algo>.yml.",
        epilog="Run directory layout and seed scheme: see the docstring of agents/training/train.py.",
    )
    parser.add_argument("--algo", choices=ALGO_NAMES, help="algorithm (required unless --resume)")
    parser.add_argument("--env", dest="env_id", help="Gymnasium env id (required unless --resume)")
    parser.add_argument(
        "--env-kwargs",
        nargs="*",
        metavar="K=V",
        default=[],
        help="gymnasium.make keyword arguments, values parsed as YAML (case=1 goal=paper)",
    )
    parser.add_argument("--config", type=Path, help="YAML config (default: train_configs/<algo>.yml)")
    parser.add_argument(
        "--hyperparams",
        nargs="*",
        metavar="K=V",
        default=[],
        help="override config keys, values parsed as YAML (learning_rate=1.0e-4)",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help="base seed, a training seed in [0, 1e9) with all its derived seeds (uvdms_gym.seeds; default 0)",
    )
    parser.add_argument(
        "--total-timesteps", type=int, help="fresh run: total steps (default: n_timesteps); resume: additional steps"
    )
    parser.add_argument("--n-envs", type=int, help="number of training envs (default: from the config)")
    parser.add_argument("--out", type=Path, default=Path("runs"), help="root of run directories (runs)")
    parser.add_argument("--resume", type=Path, metavar="DIR", help="continue training the run in DIR")
    parser.add_argument(
        "--vec-env",
        choices=VEC_ENV_TYPES,
        default=None,
        help="vectorised env type (default: dummy; a resume: the type of the run's last segment): dummy (all envs in "
        "the trainer's process), subproc (each in a worker), "
        "hybrid (env 0 in the trainer's process, the others in workers, all stepping at once; same results as "
        "dummy), rollout (PPO, PPO-Lagrangian: as hybrid, each env collects its part of every rollout with its own "
        "policy copy: PPO's fastest with n_envs free cores; reproducible, not identical to dummy)",
    )
    parser.add_argument(
        "--gym-packages",
        nargs="*",
        default=list(DEFAULT_GYM_PACKAGES),
        metavar="PKG",
        help="packages imported to register env ids (default: uvdms_gym)",
    )
    _add_composition_arguments(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--verbose", type=int, default=0, help="SB3 verbosity (1 prints training tables)")
    return parser


def _add_composition_arguments(parser: argparse.ArgumentParser) -> None:
    """The options that compose the trained policy with a base and a filter (``--residual*``, ``--safety-filter``)."""
    parser.add_argument(
        "--residual",
        metavar="BASE",
        help="train a residual agent on this velocity-mode baseline (mpc, campc): the env gets "
        "clip(a_base + S * a, -1, 1), the policy observes [obs; a_base] (uvdms train only); 'none': no base "
        "(the policy outputs the whole command, e.g. a distilled controller with --algo dagger)",
    )
    parser.add_argument(
        "--residual-scale", type=float, metavar="S", help="bound S of the residual, in (0, 1] (with --residual)"
    )
    parser.add_argument(
        "--residual-observation",
        choices=RESIDUAL_OBSERVATION_NAMES,
        help="what the residual policy observes besides the env's observation (with --residual): base (default: "
        "the base's action) or clearance (also the 36 clearance features of uvdms_gym.residual.ClearanceFeatures)",
    )
    parser.add_argument(
        "--residual-space",
        choices=RESIDUAL_SPACE_NAMES,
        help="where the residual acts (with --residual): full (default: the whole command) or nullspace (the "
        "policy's output projected onto the null space of both end-effector positions first, "
        "uvdms_gym.residual.NullspaceProjection)",
    )
    parser.add_argument(
        "--safety-filter",
        action="store_true",
        help="filter the training envs' velocity command (after the residual) with "
        "baselines.safety.filter.SafetyFilter; evaluation composes the same (uvdms train only)",
    )
