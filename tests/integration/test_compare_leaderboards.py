"""scripts/compare_leaderboards.py: the "behaviour unchanged" check of a refactoring, on the committed leaderboard."""

from __future__ import annotations

import csv
from pathlib import Path

from scripts.compare_leaderboards import main, quality_columns

REPO = Path(__file__).resolve().parents[2]
COMMITTED = REPO / "docs" / "leaderboard" / "leaderboard.csv"


def _rewrite(src: Path, dst: Path, change) -> None:
    with src.open(newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        change(row)
    with dst.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def test_same_file_and_machine_columns_compare_equal(tmp_path, capsys):
    slower = tmp_path / "slower.csv"
    _rewrite(COMMITTED, slower, lambda r: r.update(controller_ms_median_mean="99", timing_load_1min_max="7"))
    assert main([str(COMMITTED), str(slower)]) == 0
    assert "0 difference(s)" in capsys.readouterr().out


def test_a_changed_quality_cell_and_a_renamed_entry(tmp_path, capsys):
    with COMMITTED.open(newline="", encoding="utf-8") as f:
        first = next(csv.DictReader(f))
    columns = quality_columns(list(first))
    assert "rmse_pos_mean" in columns and "controller_ms_median_mean" not in columns and "entry" not in columns

    def change(row):
        if row["entry"] == first["entry"] and row["task"] == first["task"] and row["track"] == first["track"]:
            row["rmse_pos_mean"] = "0.123"

    changed = tmp_path / "changed.csv"
    _rewrite(COMMITTED, changed, change)
    assert main([str(COMMITTED), str(changed)]) == 1
    out = capsys.readouterr().out
    assert "rmse_pos_mean" in out and "1 difference(s)" in out

    renamed = tmp_path / "renamed.csv"
    _rewrite(COMMITTED, renamed, lambda r: r.update(entry="MPC" if r["entry"] == "mpc" else r["entry"]))
    assert main([str(COMMITTED), str(renamed)]) == 1
    assert main([str(COMMITTED), str(renamed), "--rename", "mpc=MPC"]) == 0
