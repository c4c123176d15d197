"""``uvdms leaderboard``: rank the baselines and trained agents (thin wrapper over :mod:`leaderboard`)."""

from __future__ import annotations

import argparse
import logging
import shlex
import sys

log = logging.getLogger("uvdms.leaderboard")

DESCRIPTION = """\
Evaluate the named baselines (mpc, campc: velocity track; campc-di, campc-nndi: torque track), every agent
folder in --agents-dir and any agent given by path on the task suite (paper Case 1, Case 2, transport, and held-
out randomised variants with hydro_randomization=0.3), on the test seeds of the seed protocol (uvdms_gym.seeds:
training, validation and test seeds in disjoint ranges; --split validation for development): 100 draws of each
randomised task, spread over the training seeds of a multi-seed entry, one episode per training seed on the
deterministic paper tasks; the randomised tasks also on the second test set (test2), each entry's difference
between the two reported and flagged when its 95% interval excludes 0. Rank each track per task by contact-free
success rate, then position RMSE (ties when the 95% bootstrap intervals overlap), print the tables and write
leaderboard.md, leaderboard.csv, entries/*.json, plots/*.png and index.html (the same tables as one self-
contained web page: sortable, filterable, a detail view per entry) to --out; --page-only DIR only rewrites
DIR/index.html from the files already in DIR. Every episode is cached under --cache-dir and reused on re-runs.
Episodes run in this process, in --jobs local processes, or with --backend ray as Ray tasks on a local instance
or the cluster at --address (the driver keeps the cache; agents travel to the workers as weights-only exports)."""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``leaderboard`` subcommand to ``uvdms``."""
    p = subparsers.add_parser(
        "leaderboard",
        help="rank baselines and agents on collisions and tracking error, with bootstrap CIs",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="the paper tasks only (deterministic: one episode per entry and training seed)",
    )
    p.add_argument("--out", default="leaderboard_out", help="output folder (default leaderboard_out/)")
    p.add_argument("--cache-dir", default=None, help="per-episode cache (default <out>/cache)")
    p.add_argument(
        "--entries",
        nargs="+",
        metavar="NAME|PATH",
        default=None,
        help="entries to rank: baseline names (mpc campc campc-di campc-nndi; campc-inner, the obstacle ablation; "
        "hold, the zero command), agent folders or SB3 zips, "
        "'baselines' (all four) and 'agents' (every folder in --agents-dir); a '+filter' suffix (mpc+filter, "
        "agents+filter, PATH+filter) adds the same entries with the safety filter; default: baselines agents",
    )
    p.add_argument(
        "--agents-dir",
        default=None,
        help="shipped-agents folder (default: ./trained_agents, else the repository's trained_agents/)",
    )
    p.add_argument("--tasks", nargs="+", default=None, metavar="TASK", help="subset of the task suite (by name)")
    _add_draw_arguments(p)
    p.add_argument("--force", action="store_true", help="recompute every episode instead of using the cache")
    p.add_argument(
        "--reuse",
        default=None,
        metavar="DIR",
        help="a previous leaderboard output (e.g. docs/leaderboard) whose recorded episodes are reused for "
        "the same entry, task and seeds instead of recomputing them (the first episode of the paper circle "
        "tasks, whose distance trajectory is plotted, is always run)",
    )
    p.add_argument(
        "--trust",
        action="store_true",
        help="allow loading full SB3 zips (pickles) from outside the repository's trained_agents/ folder",
    )
    _add_execution_arguments(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument(
        "--page-only",
        default=None,
        metavar="DIR",
        help="evaluate nothing: (re)write DIR/index.html from DIR's leaderboard.csv, entries/*.json and plots/ "
        "(entry documents that do not record their composition and training take them from the agent folders "
        "in --agents-dir whose files have the recorded checksums)",
    )
    p.set_defaults(func=_cmd_leaderboard)


def _add_draw_arguments(p: argparse.ArgumentParser) -> None:
    """The options that choose the draws: how many, of which split, with or without the check; the step limit."""
    p.add_argument(
        "--episodes",
        type=int,
        default=None,
        help="draws of each randomised task (default 100; quick: 2); the deterministic paper tasks have one",
    )
    p.add_argument(
        "--split",
        choices=("test", "validation"),
        default="test",
        help="seed split to rank on: test (the published leaderboard) or validation (development; no test seed)",
    )
    p.add_argument(
        "--no-generalization-check",
        action="store_true",
        help="skip the randomised tasks' second test set (test2) and the check against it",
    )
    p.add_argument(
        "--max-episode-steps",
        type=int,
        default=None,
        metavar="N",
        help="cut every episode after N steps (smoke tests: the metrics then describe the first N steps only)",
    )


def _add_execution_arguments(p: argparse.ArgumentParser) -> None:
    """The options that say where the episodes run: local processes or Ray."""
    p.add_argument("--jobs", type=int, default=1, help="worker processes of the local backend (default 1)")
    p.add_argument(
        "--backend",
        choices=("local", "ray"),
        default="local",
        help="local: this process or --jobs processes; ray: one Ray task per episode (the ray extra)",
    )
    p.add_argument(
        "--address", default=None, help="Ray cluster to join (auto, ray://host:10001, host:port); default: local"
    )
    p.add_argument("--num-cpus", type=int, default=None, help="CPUs of the local Ray instance (default: all cores)")
    p.add_argument(
        "--max-retries", type=int, default=None, help="re-runs of an episode whose Ray worker dies (default 3)"
    )


def _cmd_page_only(args: argparse.Namespace) -> int:
    """``--page-only DIR``: write ``DIR/index.html`` from the folder's files (no evaluation)."""
    from leaderboard.output.webpage import write_index_html
    from leaderboard.suite.entries import default_agents_dir

    agents_dir = args.agents_dir if args.agents_dir is not None else default_agents_dir()
    path = write_index_html(args.page_only, agents_dir=agents_dir)
    log.info("wrote %s (%.1f MB)", path, path.stat().st_size / 1e6)
    return 0


def _cmd_leaderboard(args: argparse.Namespace) -> int:
    if args.page_only is not None:
        return _cmd_page_only(args)
    from dataclasses import replace

    import torch

    import leaderboard as lb

    torch.set_num_threads(1)  # tiny MLP policies: one thread is fastest and leaves the other core free
    tasks = lb.select_tasks(args.tasks, quick=args.quick)
    if args.max_episode_steps is not None:
        if args.max_episode_steps < 1:
            raise ValueError(f"--max-episode-steps must be >= 1, got {args.max_episode_steps}")
        tasks = tuple(replace(t, max_episode_steps=args.max_episode_steps) for t in tasks)
    episodes = args.episodes if args.episodes is not None else (lb.QUICK_EPISODES if args.quick else None)
    # bad entries, seeds or files raise; uvdms_cli.main.main reports them as one line (exit status 2)
    entries = lb.resolve_entries(args.entries, agents_dir=args.agents_dir, trust=args.trust)
    result = lb.run_leaderboard(
        entries,
        out_dir=args.out,
        cache_dir=args.cache_dir,
        tasks=tasks,
        episodes=episodes if episodes is not None else lb.DEFAULT_EPISODES,
        force=args.force,
        trust=args.trust,
        jobs=args.jobs,
        executor=args.backend,
        address=args.address,
        num_cpus=args.num_cpus,
        max_retries=args.max_retries,
        reuse_from=args.reuse,
        split=args.split,
        generalization=not args.no_generalization_check,
        progress=not args.no_progress,
        plots=not args.no_plots,
        command=_command_line(args),
    )
    sys.stdout.write(lb.markdown_tables(result) + "\n")
    log.info(
        "wrote %s (%d episodes computed, %d from cache, %d reused from %s%s)",
        result.out_dir / "leaderboard.md",
        result.computed,
        result.cached,
        result.reused,
        args.reuse,
        f", {len(result.corrupt)} corrupt cache files recomputed" if result.corrupt else "",
    )
    return 0


def _command_line(args: argparse.Namespace) -> str:
    """The command as recorded in ``leaderboard.md`` (output-shaping options only)."""
    parts = ["uvdms", "leaderboard"]
    if args.quick:
        parts.append("--quick")
    if args.entries:
        parts += ["--entries", *args.entries]
    if args.agents_dir is not None:
        parts += ["--agents-dir", args.agents_dir]
    if args.tasks:
        parts += ["--tasks", *args.tasks]
    if args.episodes is not None:
        parts += ["--episodes", str(args.episodes)]
    if args.split != "test":
        parts += ["--split", args.split]
    if args.no_generalization_check:
        parts.append("--no-generalization-check")
    if args.max_episode_steps is not None:
        parts += ["--max-episode-steps", str(args.max_episode_steps)]
    parts += ["--out", args.out]
    return shlex.join(parts)
