"""Print, per realism task and level, CAMPC with the filter, the privileged CAMPC, CAMPC raw and the best learned entry.

    python -m scripts.realism_comparison [--leaderboard docs/leaderboard] [--tasks TASK ...] [--entry NAME ...]

Reads a leaderboard output folder (default: the committed one) and prints one markdown table per base task of the
realism track (:func:`leaderboard.output.comparison.comparison_markdown`): per task and level, ``campc`` (the
navigation filter and delay compensation), ``campc-privileged`` (the privileged reference row), ``campc-raw`` and
the best learned entry (highest contact-free success, ties broken by lower position RMSE,
:func:`leaderboard.output.comparison.best_learned`), each with its contact-free success, 95 % interval and RMSE;
then the difference "learned - campc" in contact-free success with its 95 % interval and the verdict: ``ahead`` /
``behind`` when the interval excludes 0 above / below, ``not separated`` when it contains 0.

The difference is paired over the task's test draws (both rows ran the same evaluation seeds):
:func:`leaderboard.stats.paired.paired_difference`. A multi-seed learned entry (aggregation
``seeds-iqm-hierarchical`` in ``leaderboard.csv``) ran each draw with one of its training seeds (the leaderboard
spreads the draws over the seeds); each draw's difference is that seed's episode minus ``campc``'s on the draw, the
draws are resampled with their pairs (and the seeds within a draw where several ran it), so the seeds' spread is in
the interval through the draws. The bootstrap is seeded: the output is the same on every run. ``--entry NAME``
adds the named learned entry's row (beside the best one) on the tasks it ran.
"""

from __future__ import annotations

import argparse

from leaderboard.output.comparison import compare_tasks, comparison_markdown


def main(argv: list[str] | None = None) -> None:
    """Command line: print the comparison tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--leaderboard", default="docs/leaderboard", help="a leaderboard output folder")
    parser.add_argument("--tasks", nargs="+", default=None, help="tasks to compare (default: the realism track's)")
    parser.add_argument("--entry", action="append", default=[], help="also show this entry (repeatable)")
    args = parser.parse_args(argv)
    try:
        comparisons = compare_tasks(args.leaderboard, args.tasks, args.entry)
    except ValueError as exc:
        parser.error(str(exc))
    print(comparison_markdown(comparisons))  # the command's output


if __name__ == "__main__":
    main()
