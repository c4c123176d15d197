"""Copy the top rows of the committed leaderboard's tables into the README (a subset of their columns).

    python scripts/readme_leaderboard_tables.py [--leaderboard docs/leaderboard/leaderboard.md] [--readme README.md]

The README's "#### Velocity track" and "#### Torque track" sections each hold one markdown table with the columns
below and the first :data:`TOP_ROWS` rows of every task; this replaces those tables by the same columns and rows
of the tables under "### Velocity track" and "### Torque track" of ``leaderboard.md`` (written by
``uvdms leaderboard --out docs/leaderboard``), so that the README never shows figures the committed run did not
produce. Run it after regenerating the leaderboard.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

COLUMNS = ("Task", "Rank", "Entry", "Contact-free success", "RMSE pos (mm)", "Min distance (m)", "Ctrl ms", "n")
TRACKS = ("Velocity track", "Torque track")
TOP_ROWS: dict[str, int] = {"Velocity track": 3, "Torque track": 1}
"""Rows shown per task (the leaderboard's ranking order) in each track's README table."""


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def _table_after(text: str, heading: str) -> tuple[int, int]:
    """The character span of the first markdown table after the line ``heading``."""
    match = re.search(rf"^{re.escape(heading)}\n", text, flags=re.MULTILINE)
    if match is None:
        raise ValueError(f"no line {heading!r}")
    start = text.index("\n|", match.end() - 1) + 1
    end = start
    for line in text[start:].splitlines(keepends=True):
        if not line.startswith("|"):
            break
        end += len(line)
    return start, end


def readme_table(leaderboard_md: str, track: str) -> str:
    """The README form of one track's table: :data:`COLUMNS` and each task's first :data:`TOP_ROWS` rows."""
    start, end = _table_after(leaderboard_md, f"### {track}")
    lines = leaderboard_md[start:end].splitlines()
    header = _cells(lines[0])
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise ValueError(f"the {track} table of the leaderboard has no column(s) {missing}")
    index = [header.index(c) for c in COLUMNS]
    align = ["---" if c in ("Task", "Rank", "Entry") else "--:" for c in COLUMNS]
    out = ["| " + " | ".join(COLUMNS) + " |", "|" + "|".join(align) + "|"]
    shown: dict[str, int] = {}
    for line in lines[2:]:
        cells = _cells(line)
        task = cells[header.index("Task")]
        shown[task] = shown.get(task, 0) + 1
        if shown[task] <= TOP_ROWS[track]:
            out.append("| " + " | ".join(cells[i] for i in index) + " |")
    return "\n".join(out) + "\n"


def update_readme(readme: str, leaderboard_md: str) -> str:
    """``readme`` with the table under each ``#### <track>`` heading replaced by :func:`readme_table`."""
    for track in TRACKS:
        start, end = _table_after(readme, f"#### {track}")
        readme = readme[:start] + readme_table(leaderboard_md, track) + readme[end:]
    return readme


def main() -> None:
    """Rewrite the README's leaderboard tables in place."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--leaderboard", type=Path, default=Path("docs/leaderboard/leaderboard.md"))
    parser.add_argument("--readme", type=Path, default=Path("README.md"))
    args = parser.parse_args()
    text = args.readme.read_text(encoding="utf-8")
    new = update_readme(text, args.leaderboard.read_text(encoding="utf-8"))
    if new != text:
        args.readme.write_text(new, encoding="utf-8")


if __name__ == "__main__":
    main()
