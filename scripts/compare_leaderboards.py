"""Compare the quality columns of two leaderboard CSVs, row by row (a refactoring's "behaviour unchanged" check).

Usage: ``python -m scripts.compare_leaderboards BEFORE/leaderboard.csv AFTER/leaderboard.csv [--rename OLD=NEW ...]``.

Rows are matched by (track, task, entry); ``--rename`` maps entry names of BEFORE to those of AFTER (a shipped agent
folder renamed). Every column is compared exactly except the machine-dependent ones: the controller's time
(``controller_ms_median_*``) and the timing record (``timing_*``). Prints one line per differing cell and a summary;
exits 1 if anything differs or a row is missing on either side.
"""

from __future__ import annotations

import argparse
import csv
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

KEY = ("track", "task", "entry")
"""The columns that identify a row."""
MACHINE_DEPENDENT = ("controller_ms_median_", "timing_")
"""Prefixes of the columns that depend on the machine and its load, not on the behaviour."""


def read_rows(path: Path, rename: Mapping[str, str] | None = None) -> dict[tuple[str, ...], dict[str, str]]:
    """The rows of a leaderboard CSV by (track, task, entry), entry names renamed."""
    rename = rename or {}
    with path.open(newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    out = {}
    for row in rows:
        row["entry"] = rename.get(row["entry"], row["entry"])
        out[tuple(row[k] for k in KEY)] = row
    return out


def quality_columns(columns: Sequence[str]) -> list[str]:
    """The columns compared: all but the key and the machine-dependent ones."""
    return [c for c in columns if c not in KEY and not c.startswith(MACHINE_DEPENDENT)]


def compare(before: Mapping, after: Mapping) -> list[str]:
    """One line per missing row or differing quality cell."""
    problems = [f"only in BEFORE: {k}" for k in sorted(set(before) - set(after))]
    problems += [f"only in AFTER: {k}" for k in sorted(set(after) - set(before))]
    for key in sorted(set(before) & set(after)):
        a, b = before[key], after[key]
        for column in quality_columns(list(a)):
            if a.get(column) != b.get(column):
                problems.append(f"{key} {column}: {a.get(column)!r} -> {b.get(column)!r}")
    return problems


def main(argv: Sequence[str] | None = None) -> int:
    """Command line; exit status 0 when every quality column of every row is the same."""
    description = __doc__.split("\n\n")[0]
    parser = argparse.ArgumentParser(prog="python -m scripts.compare_leaderboards", description=description)
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--rename", nargs="*", default=[], metavar="OLD=NEW", help="entry names renamed since BEFORE")
    args = parser.parse_args(argv)
    rename = dict(item.split("=", 1) for item in args.rename)
    before, after = read_rows(args.before, rename), read_rows(args.after)
    problems = compare(before, after)
    for line in problems:
        print(line)
    columns = quality_columns(list(next(iter(before.values()), {})))
    print(f"{len(before)} rows x {len(columns)} quality columns compared: {len(problems)} difference(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
