"""``uvdms evaluate``: a baseline, an agent or a multi-seed entry over seeded episodes.

The episodes' seeds follow the seed protocol (:mod:`uvdms_gym.seeds`): draws ``0, ..., N - 1`` of ``--split``
(``validation`` unless told), or ``--seed S, S + 1, ...`` given explicitly. The evaluation itself:
:mod:`leaderboard.running.evaluate`.
"""

from __future__ import annotations

import argparse
import json
import sys

from uvdms_gym.seeds import EVALUATION_SPLITS, VALIDATION, split_seeds

DEFAULT_SPLIT = "validation"
"""The draws ``uvdms evaluate`` uses without ``--split`` or ``--seed``: public draws, for development."""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``evaluate`` to the ``uvdms`` command."""
    ev = subparsers.add_parser(
        "evaluate",
        help="evaluate a baseline or a trained agent over seeded episodes (JSON metrics)",
        description="Run a controller (baseline name or agent path) on an environment for N seeded episodes and "
        "write per-episode metrics and their means as JSON (see uvdms_gym.evaluation). The episodes are draws "
        "0..N-1 of a seed split (--split, validation by default; uvdms_gym.seeds) or the seeds --seed S, S+1, ...; "
        "the JSON records the split (meta.seed_protocol). A folder of training seeds (seed_<k>/ sub-folders, as "
        "the leaderboard ranks them) spreads the draws over its seeds (draw i evaluated once, by the (i % n)-th "
        "seed folder, as the leaderboard does on its randomised tasks; --every-seed: every seed runs every draw) "
        "and aggregates the episodes (rates as fractions, IQM otherwise, hierarchical bootstrap intervals: draws, "
        "then training seeds; summary keys "
        "aggregate, per_seed).",
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
    ev.add_argument("--episodes", type=int, default=5, help="number of episodes (draws) N")
    seeds = ev.add_mutually_exclusive_group()
    seeds.add_argument(
        "--split",
        choices=EVALUATION_SPLITS,
        default=None,
        help=f"the episodes are draws 0..N-1 of this split (uvdms_gym.seeds; default {DEFAULT_SPLIT}: public "
        f"draws from {VALIDATION.start}, for development; test and test2 are the leaderboard's ranking draws)",
    )
    seeds.add_argument(
        "--seed",
        type=int,
        default=None,
        metavar="S",
        help="instead of --split (not with it): the episodes' seeds are S, S+1, ..., S+N-1, recorded with the "
        "split holding them (none if they lie in no split or several); seeds below 1e9 are training seeds, "
        "which agents were trained on",
    )
    ev.add_argument(
        "--every-seed",
        action="store_true",
        help="for a folder of training seeds: every seed evaluates every draw (N episodes per seed, aggregated "
        "over seeds x episodes as the leaderboard does) instead of spreading the draws over the seeds",
    )
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
        seeds=episode_seeds(args.episodes, args.split, args.seed),
        every_seed=args.every_seed,
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


def episode_seeds(episodes: int, split: str | None = None, seed: int | None = None) -> list[int]:
    """The seeds of ``uvdms evaluate``'s episodes (its ``--episodes``, ``--split`` and ``--seed``).

    ``seed, ..., seed + episodes - 1`` if ``seed`` is given, else draws ``0, ..., episodes - 1`` of ``split``
    (:data:`DEFAULT_SPLIT` if ``None``): :func:`uvdms_gym.seeds.split_seeds`.

    Raises:
        ValueError: ``episodes < 1``; both ``split`` and ``seed``; more draws than the split holds.
    """
    if episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {episodes}")
    if seed is not None and split is not None:
        raise ValueError("give --split or --seed, not both")
    if seed is not None:
        return [seed + i for i in range(episodes)]
    return split_seeds(split or DEFAULT_SPLIT, episodes)
