"""Copy the top rows of the committed leaderboard's tables into the README (a subset of their columns).

    python scripts/readme_leaderboard_tables.py [--leaderboard docs/leaderboard/leaderboard.md] [--readme README.md]

The README's "#### Velocity track" and "#### Torque track" sections each hold one markdown table with the columns
below and the first :data:`TOP_ROWS` rows of every oracle task; this replaces those tables by the same columns and
rows of the tables under "### Velocity track" and "### Torque track" of ``leaderboard.md`` (written by
``uvdms leaderboard --out docs/leaderboard``), so that the README never shows figures the committed run did not
produce. The realism track's tasks (labels with ", realism ") go to the README's "#### Realism track" table instead:
per task, the first ranked row and the rows of :data:`REALISM_ROWS`, from the velocity track. The cooperative
tasks (labels starting with "Cooperative") go to the README's "#### Cooperative transport" table: per task, the first
:data:`COOP_TOP_ROWS` rows of the velocity track and the rows of :data:`COOP_ROWS`, with :data:`COOP_COLUMNS` (the slip
and the drop rate added). Run it
after regenerating the leaderboard.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable
from pathlib import Path

COLUMNS = ("Task", "Rank", "Entry", "Contact-free success", "RMSE pos (mm)", "Min distance (m)", "Ctrl ms", "n")
TRACKS = ("Velocity track", "Torque track")
TOP_ROWS: dict[str, int] = {"Velocity track": 3, "Torque track": 1}
"""Rows shown per task (the leaderboard's ranking order) in each track's README table."""
REALISM_MARK = ", realism "
"""What a realism-track task's label contains (``leaderboard.suite.tasks``: ``"<label>, realism <level>"``)."""
REALISM_HEADING = "Realism track"
REALISM_ROWS: tuple[str, ...] = ("campc", "campc-raw", "campc-privileged (privileged)")
"""Entries (as the Entry column shows them) the README's realism table keeps besides each task's first row."""


COOP_MARK = "Cooperative"
"""How a cooperative task's label starts (``leaderboard.suite.tasks.COOP_TASKS``)."""
COOP_HEADING = "Cooperative transport"
COOP_COLUMNS = (*COLUMNS[:-1], "Max slip (mm)", "Drop rate", "n")
"""The columns of the README's cooperative table."""
COOP_TOP_ROWS = 3
"""Rows shown per cooperative task (the velocity track's ranking order)."""
COOP_ROWS: tuple[str, ...] = ("campc",)
"""Entries the README's cooperative table keeps besides each task's first rows: ``campc``, the ablation (a constant
grip)."""


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


def _track_rows(leaderboard_md: str, track: str) -> tuple[list[str], list[list[str]]]:
    """The header and the rows of one track's table in ``leaderboard.md``."""
    start, end = _table_after(leaderboard_md, f"### {track}")
    lines = leaderboard_md[start:end].splitlines()
    return _cells(lines[0]), [_cells(line) for line in lines[2:]]


def _selected_rows(
    leaderboard_md: str,
    track: str,
    columns: tuple[str, ...],
    in_table: Callable[[str], bool],
    top: int,
    always: tuple[str, ...] = (),
) -> str:
    """A README table: ``columns`` of one track's rows whose task passes ``in_table``.

    Per task, the first ``top`` rows (the leaderboard's ranking order) and every row of an entry in ``always``.

    Raises:
        ValueError: The track's table lacks one of ``columns``.
    """
    header, rows = _track_rows(leaderboard_md, track)
    missing = [c for c in columns if c not in header]
    if missing:
        raise ValueError(f"the {track} table of the leaderboard has no column(s) {missing}")
    index = [header.index(c) for c in columns]
    task_col, entry_col = header.index("Task"), header.index("Entry")
    align = ["---" if c in ("Task", "Rank", "Entry") else "--:" for c in columns]
    out = ["| " + " | ".join(columns) + " |", "|" + "|".join(align) + "|"]
    shown: dict[str, int] = {}
    for cells in rows:
        task = cells[task_col]
        if not in_table(task):
            continue
        shown[task] = shown.get(task, 0) + 1
        if shown[task] <= top or cells[entry_col] in always:
            out.append("| " + " | ".join(cells[i] for i in index) + " |")
    return "\n".join(out) + "\n"


def realism_table(leaderboard_md: str) -> str:
    """The README's realism table: per realism task, its first ranked row and the rows of :data:`REALISM_ROWS`."""
    return _selected_rows(leaderboard_md, TRACKS[0], COLUMNS, lambda task: REALISM_MARK in task, 1, REALISM_ROWS)


def coop_table(leaderboard_md: str) -> str:
    """The README's cooperative table: per cooperative task, its first :data:`COOP_TOP_ROWS` velocity-track rows.

    Raises:
        ValueError: The velocity track's table lacks one of :data:`COOP_COLUMNS`.
    """
    return _selected_rows(
        leaderboard_md, TRACKS[0], COOP_COLUMNS, lambda task: task.startswith(COOP_MARK), COOP_TOP_ROWS, COOP_ROWS
    )


def readme_table(leaderboard_md: str, track: str) -> str:
    """The README form of one track's table: :data:`COLUMNS` and each oracle task's first :data:`TOP_ROWS` rows.

    The realism and cooperative tasks have tables of their own (:func:`realism_table`, :func:`coop_table`).
    """
    return _selected_rows(
        leaderboard_md,
        track,
        COLUMNS,
        lambda task: REALISM_MARK not in task and not task.startswith(COOP_MARK),
        TOP_ROWS[track],
    )


def update_readme(readme: str, leaderboard_md: str) -> str:
    """``readme`` with the table under each ``#### <track>`` heading replaced by :func:`readme_table`.

    The realism and cooperative tables are replaced by :func:`realism_table` and :func:`coop_table` when the
    leaderboard has such tasks.

    Raises:
        ValueError: A heading without a table, or a leaderboard table without the columns the README shows.
    """
    for track in TRACKS:
        start, end = _table_after(readme, f"#### {track}")
        readme = readme[:start] + readme_table(leaderboard_md, track) + readme[end:]
    if REALISM_MARK in leaderboard_md:
        start, end = _table_after(readme, f"#### {REALISM_HEADING}")
        readme = readme[:start] + realism_table(leaderboard_md) + readme[end:]
    if f"| {COOP_MARK}" in leaderboard_md:  # (a heading with a table under it: add one to the README first)
        start, end = _table_after(readme, f"#### {COOP_HEADING}")
        readme = readme[:start] + coop_table(leaderboard_md) + readme[end:]
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
