"""The README's leaderboard tables are the committed leaderboard's (``scripts/readme_leaderboard_tables.py``)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("readme_tables", REPO / "scripts" / "readme_leaderboard_tables.py")
tables = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tables)


def test_readme_tables_equal_the_committed_leaderboard():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    board = (REPO / "docs" / "leaderboard" / "leaderboard.md").read_text(encoding="utf-8")
    assert tables.update_readme(readme, board) == readme, "run scripts/readme_leaderboard_tables.py"


def test_a_changed_cell_is_rewritten_and_missing_columns_are_named():
    board = (REPO / "docs" / "leaderboard" / "leaderboard.md").read_text(encoding="utf-8")
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    row = next(line for line in readme.splitlines() if line.startswith("| Case 1 | 1 | campc |"))
    stale = readme.replace(row, row.replace("| 0.5 (n=1) |", "| 9.9 (n=1) |"), 1)
    assert stale != readme and tables.update_readme(stale, board) == readme
    with pytest.raises(ValueError, match=r"no column\(s\) \['Ctrl ms'\]"):
        tables.readme_table(board.replace("| Ctrl ms |", "| Ctrl |"), "Velocity track")


def test_the_readme_shows_each_tasks_first_rows_in_the_leaderboards_order():
    board = (REPO / "docs" / "leaderboard" / "leaderboard.md").read_text(encoding="utf-8")
    for track, top in tables.TOP_ROWS.items():
        start, end = tables._table_after(board, f"### {track}")
        rows = [tables._cells(line) for line in board[start:end].splitlines()[2:]]
        shown = [tables._cells(line) for line in tables.readme_table(board, track).splitlines()[2:]]
        expected: list[tuple[str, str]] = []
        oracle = (r[0] for r in rows if tables.REALISM_MARK not in r[0] and not r[0].startswith(tables.COOP_MARK))
        for task in dict.fromkeys(oracle):
            expected += [(r[0], r[2]) for r in rows if r[0] == task][:top]
        assert [(r[0], r[2]) for r in shown] == expected
        assert len(shown) < len(rows)  # a cut, not the whole table


def test_the_realism_table_shows_each_realism_tasks_first_row_and_the_reference_rows():
    board = (REPO / "docs" / "leaderboard" / "leaderboard.md").read_text(encoding="utf-8")
    start, end = tables._table_after(board, "### Velocity track")
    rows = [tables._cells(line) for line in board[start:end].splitlines()[2:]]
    realism = [r for r in rows if tables.REALISM_MARK in r[0]]
    if not realism:
        pytest.skip("the committed leaderboard has no realism track yet")
    shown = [(c[0], c[2]) for c in map(tables._cells, tables.realism_table(board).splitlines()[2:])]
    expected = []
    for task in dict.fromkeys(r[0] for r in realism):
        task_rows = [r for r in realism if r[0] == task]
        expected += [(r[0], r[2]) for i, r in enumerate(task_rows) if i == 0 or r[2] in tables.REALISM_ROWS]
    assert shown == expected
    assert {"campc", "campc-raw"} <= {entry for _, entry in shown}


def test_the_cooperative_table_shows_each_cooperative_tasks_first_rows_with_slip_and_drop_rate():
    header = "| Task | Rank | Entry | Contact-free success | RMSE pos (mm) | Min distance (m) | Ctrl ms | n |"
    coop_header = header.replace("| n |", "| Max slip (mm) | Drop rate | n |")
    board = "\n".join(
        [
            "### Velocity track",
            "",
            coop_header,
            "|---|---|---|--:|--:|--:|--:|--:|--:|--:|",
            "| Case 1 | 1 | campc | 1.00 (n=1) | 0.5 (n=1) | 0.070 (n=1) | 1.0 (n=1) | — | — | 1 |",
            *(
                f"| Cooperative transport | {k} | e{k} | 1.00 (n=1) | 0.5 (n=1) | 0.070 (n=1) | 1.0 (n=1) | "
                f"{k}.0 (n=1) | 0.00 (n=1) | 1 |"
                for k in range(1, 6)
            ),
            "| Cooperative transport | 6 | campc | 0.00 (n=1) | 0.5 (n=1) | 0.070 (n=1) | 1.0 (n=1) | 6.0 (n=1) "
            "| 1.00 (n=1) | 1 |",
            "",
            "### Torque track",
            "",
            header,
            "|---|---|---|--:|--:|--:|--:|--:|",
            "",
        ]
    )
    table = tables.coop_table(board)
    rows = [tables._cells(line) for line in table.splitlines()]
    assert tuple(rows[0]) == tables.COOP_COLUMNS
    assert [r[2] for r in rows[2:]] == [*["e1", "e2", "e3"][: tables.COOP_TOP_ROWS], "campc"]  # and the ablation
    assert rows[2][tables.COOP_COLUMNS.index("Max slip (mm)")] == "1.0 (n=1)"
    assert "Cooperative" not in tables.readme_table(board, "Velocity track")  # not among the oracle tasks' rows
    readme = "#### Velocity track\n\n| x |\n\n#### Torque track\n\n| x |\n\n#### Cooperative transport\n\n| x |\n"
    assert tables.update_readme(readme, board).endswith(table)
    with pytest.raises(ValueError, match="Drop rate"):
        tables.coop_table(board.replace("| Drop rate |", "| Drops |"))
