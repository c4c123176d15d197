"""The realism comparison (``leaderboard.output.comparison``, ``scripts/realism_comparison.py``).

On a constructed output folder (the best learned entry, its tie-break, privileged rows never chosen, the verdicts)
and on the committed leaderboard (a row for every realism task; the best entry and the difference recomputed from
``leaderboard.csv`` with the csv module).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

from leaderboard.output.comparison import (
    RowFigures,
    best_learned,
    compare_tasks,
    comparison_markdown,
    realism_task_names,
    success_cell,
)
from leaderboard.stats.intervals import Stat
from scripts.realism_comparison import main
from uvdms_gym.seeds import assign_draws, split_seeds

REPO = Path(__file__).resolve().parents[3]
COMMITTED = REPO / "docs" / "leaderboard"
REALISM_TASKS = [
    f"{base}-r{level}" for base in ("circle-random", "transport-random", "transport-obstacles") for level in (1, 2, 3)
]
VERDICTS = {"ahead", "behind", "not separated", "no interval"}
DRAWS = split_seeds("test", 30)
COLUMNS = ["track", "task", "rank", "tied", "entry", "kind", "episodes"]
COLUMNS += ["contact_free_success_mean", "contact_free_success_ci_low", "contact_free_success_ci_high", "rmse_pos_mean"]


def _figures(entry, success, rmse, kind="agent", privileged=False):
    return RowFigures(entry, kind, privileged, Stat(success, success, success, 30), rmse)


def test_best_learned_takes_the_highest_success_then_the_lower_rmse_then_the_name():
    rows = [
        _figures("campc", 1.0, 0.001, kind="baseline"),
        _figures("oracle-net", 1.0, 0.0001, privileged=True),
        _figures("b-net", 0.8, 0.02),
        _figures("a-net", 0.8, 0.02),
        _figures("c-net", 0.8, 0.01),
        _figures("d-net", 0.5, 0.001),
        _figures("e-net", math.nan, 0.0),
    ]
    assert best_learned(rows).entry == "c-net"
    assert best_learned(rows[:4]).entry == "a-net"  # same success and RMSE: the name
    assert best_learned([_figures("x", 0.8, math.nan), _figures("y", 0.8, 0.5)]).entry == "y"
    assert best_learned(rows[:2]) is None  # a baseline and a privileged row are never the best learned entry
    assert best_learned([rows[-1]]).entry == "e-net"


def test_a_csv_row_of_rank_ref_is_privileged():
    row = dict.fromkeys(COLUMNS, "") | {"entry": "campc-privileged", "kind": "baseline", "rank": "ref"}
    row |= {"episodes": "30", "contact_free_success_mean": "0.5", "rmse_pos_mean": "0.01"}
    figures = RowFigures.from_csv(row)
    assert figures.privileged and figures.success.n == 30 and math.isnan(figures.success.low)
    assert not RowFigures.from_csv(row | {"rank": "3"}).privileged


def _episodes(outcomes, runs):
    outcome = dict(zip(DRAWS, outcomes))
    if runs == 1:
        return [{"seed": s, "success": bool(outcome[s]), "contacts": 0} for s in DRAWS]
    return [
        {"seed": s, "success": bool(outcome[s]), "contacts": 0, "training_seed": k}
        for k in range(runs)
        for s in assign_draws(DRAWS, runs, k)
    ]


def _write_folder(out: Path, rows: dict[str, dict[str, tuple]]) -> Path:
    """``rows[task][entry] = (kind, rank, outcomes, rmse, runs)``: ``leaderboard.csv`` and ``entries/*.json``."""
    (out / "entries").mkdir(parents=True)
    documents: dict[str, dict] = {}
    with (out / "leaderboard.csv").open("w", encoding="utf-8", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(COLUMNS)
        for task, entries in rows.items():
            for entry, (kind, rank, outcomes, rmse, runs) in entries.items():
                rate = sum(outcomes) / len(outcomes)
                writer.writerow(["velocity", task, rank, 0, entry, kind, 30, rate, rate, rate, rmse])
                document = documents.setdefault(entry, {"name": entry, "kind": kind, "tasks": {}})
                document["tasks"][task] = {"episodes": _episodes(outcomes, runs)}
    for entry, document in documents.items():
        (out / "entries" / f"{entry.replace('+', '_')}.json").write_text(json.dumps(document), encoding="utf-8")
    return out


@pytest.fixture
def folder(tmp_path):
    wins, losses, half = [1] * 30, [0] * 30, [i % 2 for i in range(30)]
    return _write_folder(
        tmp_path / "board",
        {
            "circle-random-r1": {
                "campc": ("baseline", "2", losses, 0.05, 1),
                "campc-privileged": ("baseline", "ref", wins, 0.002, 1),
                "campc-raw": ("baseline", "3", losses, 0.5, 1),
                "net-a": ("agent", "1", wins, 0.02, 3),
                "net-b+filter": ("agent", "1", wins, 0.03, 3),
                "oracle-net": ("agent", "ref", wins, 0.001, 3),
            },
            "circle-random-r2": {
                "campc": ("baseline", "1", half, 0.05, 1),
                "campc-privileged": ("baseline", "ref", wins, 0.002, 1),
                "net-a": ("agent", "1", half, 0.02, 3),
                "net-b+filter": ("agent", "3", losses, 0.03, 3),
            },
        },
    )


def test_compare_tasks_on_a_constructed_folder(folder):
    first, second = compare_tasks(folder, ["circle-random-r1", "circle-random-r2"])
    assert [c.row.entry for c in first.learned] == ["net-a"]  # success tie with net-b: lower RMSE; not oracle-net
    assert first.learned[0].verdict == "ahead" and first.learned[0].difference.mean == 1.0
    assert first.baselines["campc-raw"].success.mean == 0.0
    assert second.baselines["campc-raw"] is None
    assert second.learned[0].verdict == "not separated" and second.learned[0].difference.mean == 0.0

    named = compare_tasks(folder, ["circle-random-r1", "circle-random-r2"], ["net-b+filter"])
    assert [(c.row.entry, c.best) for c in named[1].learned] == [("net-a", True), ("net-b+filter", False)]
    assert named[1].learned[1].verdict == "behind"
    text = comparison_markdown(named)
    assert text == comparison_markdown(
        compare_tasks(folder, ["circle-random-r1", "circle-random-r2"], ["net-b+filter"])
    )
    assert "| `circle-random-r2` | 0.50 [0.50, 0.50], 50.0 mm | 1.00 [1.00, 1.00], 2.0 mm | — | " in text
    assert "`net-b+filter` (named) | 0.00 [0.00, 0.00], 30.0 mm | -0.50 [-0.67, -0.33] | behind |" in text


def test_unknown_tasks_and_entries_are_refused(folder):
    with pytest.raises(ValueError, match="no-such-task"):
        compare_tasks(folder, ["circle-random-r1", "no-such-task"])
    with pytest.raises(ValueError, match="net-z"):
        compare_tasks(folder, ["circle-random-r1"], ["net-z"])


def test_success_cell():
    assert success_cell(0.5, 0.25, 0.75, 0.0123) == "0.50 [0.25, 0.75], 12.3 mm"
    assert success_cell(0.5, None, math.nan, None) == "0.50"
    assert success_cell(math.nan, 0.1, 0.2, 0.1) == "—"


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def test_the_script_on_the_committed_leaderboard(capsys):
    assert realism_task_names() == REALISM_TASKS
    main(["--leaderboard", str(COMMITTED)])
    lines = capsys.readouterr().out.splitlines()
    header = _cells(next(line for line in lines if line.startswith("| Task |")))
    table = {_cells(line)[0].strip("`"): dict(zip(header, _cells(line))) for line in lines if line.startswith("| `")}
    assert sorted(table) == sorted(REALISM_TASKS)

    with (COMMITTED / "leaderboard.csv").open(encoding="utf-8", newline="") as file:
        csv_rows = list(csv.DictReader(file))
    for task, row in table.items():
        rows = {r["entry"]: r for r in csv_rows if r["task"] == task}
        learned = [r for r in rows.values() if r["kind"] == "agent" and r["rank"] != "ref"]
        best = max(learned, key=lambda r: (float(r["contact_free_success_mean"]), -float(r["rmse_pos_mean"])))
        assert row["Learned entry"] == f"`{best['entry']}`"
        point = float(row["Learned − `campc`"].split(" [")[0])
        expected = float(best["contact_free_success_mean"]) - float(rows["campc"]["contact_free_success_mean"])
        assert point == pytest.approx(expected, abs=0.006)  # (two decimals)
        low, high = (float(x) for x in row["Learned − `campc`"].split(" [")[1].rstrip("]").split(", "))
        assert row["Verdict"] == ("ahead" if low > 0 else "behind" if high < 0 else "not separated")
        assert row["`campc` (filter)"].startswith(f"{float(rows['campc']['contact_free_success_mean']):.2f} [")


def test_the_script_shows_a_named_entry_and_refuses_an_unknown_one(capsys):
    main(["--leaderboard", str(COMMITTED), "--tasks", "circle-random-r1", "--entry", "sac-circle-v1"])
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| `circle-random-r1`")]
    assert len(rows) == 2 and "`sac-circle-v1` (named)" in rows[1]
    assert _cells(rows[1])[-1] in VERDICTS
    with pytest.raises(SystemExit):
        main(["--leaderboard", str(COMMITTED), "--tasks", "circle-random-r1", "--entry", "no-such-entry"])
