"""``uvdms evaluate``: a baseline, an agent or a multi-seed entry over seeded episodes.

The evaluation itself: :mod:`leaderboard.running.evaluate`.
"""

from __future__ import annotations

import argparse
import json
import sys


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``evaluate`` to the ``uvdms`` command."""
    ev = subparsers.add_parser(
        "evaluate",
        help="evaluate a baseline or a trained agent over seeded episodes (JSON metrics)",
        description="Run a controller (baseline name or agent path) on an environment for N seeded episodes and "
        "write per-episode metrics and their means as JSON (see uvdms_gym.evaluation). A folder of training seeds "
        "(seed_<k>/ sub-folders, as the leaderboard ranks them) is evaluated seed by seed and aggregated as the "
        "leaderboard does (IQM over seeds x episodes, stratified bootstrap; summary keys aggregate, per_seed).",
    )
    ev.add_argument(
        "--controller",
        required=True,
        help="mpc | campc | campc-di | campc-nndi | campc-inner | hold, a path to an agent (weights-only export, "
        "run dir or SB3 zip) or to a folder of seed_<k> agents; trained_agents/NAME also resolves from any directory",
    )
    ev.add_argument("--env", required=True, help="environment id, e.g. uvdms/CircleTrack-v0")
    ev.add_argument(
        "--env-kwargs",
        nargs="*",
        default=[],
        metavar="K=V",
        help="gymnasium.make keyword arguments as YAML literals (case=1 radius=0.15 hydro_randomization=0.3)",
    )
    ev.add_argument("--episodes", type=int, default=5, help="number of episodes (seeds S, S+1, ...)")
    ev.add_argument("--seed", type=int, default=0, help="seed of the first episode")
    ev.add_argument(
        "--max-episode-steps",
        type=int,
        default=None,
        metavar="N",
        help="cut every episode after N steps, as uvdms leaderboard does (smoke tests: the metrics then describe "
        "the first N steps only; the same as --env-kwargs max_episode_steps=N)",
    )
    ev.add_argument("--out", default=None, help="JSON file to write (atomically)")
    ev.add_argument("--save-trajectory", action="store_true", help="include each episode's time series")
    ev.add_argument("--trust", action="store_true", help="allow unpickling the agent's SB3/VecNormalize files")
    ev.add_argument(
        "--safety-filter",
        action="store_true",
        help="project every velocity command onto the collision rows (baselines.safety.filter.SafetyFilter)",
    )
    ev.add_argument("--no-progress", action="store_true", help="no progress bar")
    ev.set_defaults(func=_cmd_evaluate)


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from leaderboard.running.evaluate import evaluate_entry
    from uvdms_gym.utils.kwargs import check_make_kwargs, parse_kv

    env_kwargs = parse_kv(args.env_kwargs, "--env-kwargs")
    if args.max_episode_steps is not None:
        if args.max_episode_steps < 1:
            raise ValueError(f"--max-episode-steps must be >= 1, got {args.max_episode_steps}")
        given = env_kwargs.get("max_episode_steps", args.max_episode_steps)
        if given != args.max_episode_steps:
            raise ValueError(
                f"--max-episode-steps {args.max_episode_steps} and --env-kwargs max_episode_steps={given} disagree; "
                "give one of them"
            )
        env_kwargs["max_episode_steps"] = args.max_episode_steps
    check_make_kwargs(args.env, env_kwargs, "--env-kwargs")  # errors are reported by uvdms_cli.main.main as one line
    result = evaluate_entry(
        args.controller,
        args.env,
        env_kwargs,
        episodes=args.episodes,
        seed=args.seed,
        out=args.out,
        save_trajectory=args.save_trajectory,
        progress=not args.no_progress,
        trust=args.trust,
        safety_filter=args.safety_filter,
    )
    sys.stdout.write(json.dumps(result["summary"], indent=2, sort_keys=True) + "\n")
    if args.out:
        sys.stderr.write(f"wrote {args.out}\n")
    return 0
