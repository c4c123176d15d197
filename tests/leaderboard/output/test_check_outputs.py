"""The generalisation check and the seed protocol in the outputs: CSV, leaderboard.md, entry documents, index.html.

A tiny run with the fake backend of ``tests.support.multiseed_fakes``: an agent that succeeds on every test draw and
on no test2 draw (``overfit``: flagged), a three-seed agent that succeeds everywhere (not flagged) and a baseline.
"""

from __future__ import annotations

import csv
import json
from html.parser import HTMLParser
from pathlib import Path

import pytest

import leaderboard as lb
from leaderboard.output.webpage import PAGE_NAME
from leaderboard.running.jobs import Backend
from tests.support.multiseed_fakes import FAKE, TINY_TASKS, _agent_folder, _fake_episode, _multi_seed
from uvdms_gym.seeds import PROTOCOL, split_of, split_seeds

EPISODES = 20
CHECK_COLUMNS = [
    f"check_{part}_{bound}" for part in ("test", "test2", "difference") for bound in ("mean", "low", "high")
]


def _episode(env, controller, seed, save_trajectory):
    result = _fake_episode(env, controller, seed, save_trajectory)
    name = Path(controller.spec).name
    if name == "overfit":  # right on the ranking's draws, wrong on every other
        result.update(contacts=0, success=split_of(seed) == "test")
    elif name.startswith("seed_"):
        result.update(contacts=0, success=True)
    return result


BACKEND = Backend(make_env=FAKE.make_env, make_controller=FAKE.make_controller, run_episode=_episode)


def _board(root: Path, **kwargs) -> tuple[lb.LeaderboardResult, Path]:
    agents = root / "agents"
    if not agents.exists():
        _multi_seed(agents)
        _agent_folder(agents / "overfit", 5)
    entries = lb.resolve_entries(["agents", "mpc"], agents_dir=agents, trust=True)
    out = root / "out"
    result = lb.run_leaderboard(
        entries,
        out_dir=out,
        tasks=TINY_TASKS,
        episodes=EPISODES,
        progress=False,
        plots=False,
        backend=BACKEND,
        **kwargs,
    )
    return result, out


@pytest.fixture(scope="module")
def board(tmp_path_factory) -> tuple[lb.LeaderboardResult, Path]:
    return _board(tmp_path_factory.mktemp("check"))


def _csv(out: Path) -> dict[tuple[str, str], dict[str, str]]:
    with (out / "leaderboard.csv").open(encoding="utf-8", newline="") as f:
        return {(row["entry"], row["task"]): row for row in csv.DictReader(f)}


def test_the_rows_of_the_randomised_task_carry_the_check(board):
    result, _out = board
    rows = {(r.entry.name, r.task.name): r for r in result.rows}
    assert {name for name, task in rows if rows[name, task].check is not None} == {"overfit", "sac_multi", "mpc"}
    assert all(rows[name, "case1"].check is None for name in ("overfit", "sac_multi", "mpc"))
    overfit, multi = rows["overfit", "circle-random"].check, rows["sac_multi", "circle-random"].check
    assert (overfit.test.mean, overfit.test2.mean, overfit.difference.mean) == (1.0, 0.0, -1.0) and overfit.flagged
    assert (multi.test.mean, multi.test2.mean, multi.difference.mean) == (1.0, 1.0, 0.0) and not multi.flagged


def test_csv_has_the_split_and_the_check_columns(board):
    result, out = board
    header = (out / "leaderboard.csv").read_text(encoding="utf-8").splitlines()[0].split(",")
    assert header[-12:] == ["aggregation", "split", *CHECK_COLUMNS, "check_flagged"]
    rows = _csv(out)
    assert {row["split"] for row in rows.values()} == {"test"}
    for (entry, task), row in rows.items():
        if task == "case1":
            assert all(row[c] == "" for c in [*CHECK_COLUMNS, "check_flagged"]), (entry, task)
    overfit, multi = rows["overfit", "circle-random"], rows["sac_multi", "circle-random"]
    assert [overfit[c] for c in CHECK_COLUMNS] == ["1", "1", "1", "0", "0", "0", "-1", "-1", "-1"]
    assert overfit["check_flagged"] == "1"
    assert [multi[c] for c in CHECK_COLUMNS] == ["1", "1", "1", "1", "1", "1", "0", "0", "0"]
    assert multi["check_flagged"] == "0"
    mpc = next(r for r in result.rows if r.entry.name == "mpc" and r.task.name == "circle-random").check
    stats = (mpc.test, mpc.test2, mpc.difference)
    expected = [f"{v:.6g}" for s in stats for v in (s.mean, s.low, s.high)]
    assert [rows["mpc", "circle-random"][c] for c in CHECK_COLUMNS] == expected
    assert rows["mpc", "circle-random"]["check_flagged"] == str(int(mpc.flagged))


def test_markdown_states_the_protocol_and_has_the_check_table_flagged_rows_first(board):
    _result, out = board
    markdown = (out / "leaderboard.md").read_text(encoding="utf-8")
    test, test2 = split_seeds("test", EPISODES), split_seeds("test2", EPISODES)
    assert f"Seed protocol `{PROTOCOL}`" in markdown and "the `test` split" in markdown
    assert f"{EPISODES} draw(s) of each randomised task (seeds {test[0]}–{test[-1]}" in markdown
    assert f"second test set `test2`: seeds {test2[0]}–{test2[-1]}." in markdown
    section = markdown.split("## Generalisation check")[1]
    lines = [line for line in section.splitlines() if line.startswith("| Random circles |")]
    assert len(lines) == 3  # the randomised task's rows only
    assert lines[0] == "| Random circles | overfit | 1.00 | 0.00 | -1.00 [-1.00, -1.00] | **flagged** |"
    assert "| Random circles | sac_multi (3 seeds) | 1.00 | 1.00 | +0.00 [+0.00, +0.00] |  |" in lines
    flagged = [line.endswith(" **flagged** |") for line in lines]
    assert flagged == sorted(flagged, reverse=True)  # flagged rows first


def test_entry_documents_record_the_protocol_and_the_check_with_its_episodes(board):
    _result, out = board
    overfit = json.loads((out / "entries" / "overfit.json").read_text())
    case1, randomised = overfit["tasks"]["case1"], overfit["tasks"]["circle-random"]
    assert case1["seed_protocol"] == randomised["seed_protocol"] == {"protocol": PROTOCOL, "split": "test"}
    assert "check" not in case1
    check = randomised["check"]
    assert check["seed_protocol"] == {"protocol": PROTOCOL, "split": "test2"}
    assert check["metric"] == "contact_free_success" and check["flagged"] is True
    assert (check["test"]["mean"], check["test2"]["mean"], check["difference"]["mean"]) == (1.0, 0.0, -1.0)
    assert [ep["seed"] for ep in check["episodes"]] == split_seeds("test2", EPISODES)
    assert not any(ep["success"] for ep in check["episodes"]) and all("cache_key" in ep for ep in check["episodes"])
    assert [ep["seed"] for ep in randomised["episodes"]] == split_seeds("test", EPISODES)
    multi = json.loads((out / "entries" / "sac_multi.json").read_text())["tasks"]["circle-random"]["check"]
    assert multi["flagged"] is False
    assert sorted((ep["training_seed"], ep["seed"]) for ep in multi["episodes"]) == sorted(
        (i % 3, seed) for i, seed in enumerate(split_seeds("test2", EPISODES))
    )


class _CheckRows(HTMLParser):
    """The rows of the page's generalisation section: attributes and cell texts."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[tuple[dict, list[str]]] = []
        self._inside = self._cell = False

    def handle_starttag(self, tag, attrs):
        attributes = dict(attrs)
        if tag == "section":
            self._inside = attributes.get("id") == "generalization"
        elif self._inside and tag == "tr" and "data-flagged" in attributes:
            self.rows.append((attributes, []))
        elif self._inside and tag == "td" and self.rows:
            self.rows[-1][1].append("")
            self._cell = True

    def handle_endtag(self, tag):
        if tag == "td":
            self._cell = False
        elif tag == "section":
            self._inside = False

    def handle_data(self, data):
        if self._cell:
            self.rows[-1][1][-1] += data


def _page_check_rows(out: Path) -> list[tuple[dict, list[str]]]:
    parser = _CheckRows()
    parser.feed((out / PAGE_NAME).read_text(encoding="utf-8"))
    return parser.rows


def test_the_page_lists_the_flagged_entry_first_with_both_figures(board):
    _result, out = board
    page = (out / PAGE_NAME).read_text(encoding="utf-8")
    assert page.count('<section id="generalization">') == 1
    rows = _page_check_rows(out)
    csv_rows = _csv(out)
    assert {(a["data-entry"], a["data-task"]) for a, _cells in rows} == {
        key for key, row in csv_rows.items() if row["check_flagged"] in ("0", "1")
    }
    attributes, cells = rows[0]
    assert (attributes["data-entry"], attributes["data-flagged"]) == ("overfit", "1")
    assert cells[1:] == ["overfit", "1.00", "0.00", "-1.00 [-1.00, -1.00]", "flagged"]
    flags = [a["data-flagged"] for a, _cells in rows]
    assert flags == sorted(flags, reverse=True)  # flagged rows first
    multi = next(cells for a, cells in rows if a["data-entry"] == "sac_multi")
    assert multi[1:] == ["sac_multi (3 seeds)", "1.00", "1.00", "+0.00 [+0.00, +0.00]", ""]
    for attributes, cells in rows:
        row = csv_rows[attributes["data-entry"], attributes["data-task"]]
        assert attributes["data-flagged"] == row["check_flagged"]
        assert cells[2:4] == [f"{float(row['check_test_mean']):.2f}", f"{float(row['check_test2_mean']):.2f}"]


def test_without_the_check_or_on_validation_there_is_no_check_anywhere(tmp_path):
    for kwargs, split in (({"generalization": False}, "test"), ({"split": "validation"}, "validation")):
        result, out = _board(tmp_path, **kwargs)
        assert result.split == split and result.check_seeds == [] and all(r.check is None for r in result.rows)
        markdown = (out / "leaderboard.md").read_text(encoding="utf-8")
        assert "## Generalisation check" not in markdown and "test2" not in markdown
        assert f"the `{split}` split" in markdown
        rows = _csv(out)
        assert {row["split"] for row in rows.values()} == {split}
        assert all(row[c] == "" for row in rows.values() for c in [*CHECK_COLUMNS, "check_flagged"])
        assert 'id="generalization"' not in (out / PAGE_NAME).read_text(encoding="utf-8")
        document = json.loads((out / "entries" / "overfit.json").read_text())
        for task in document["tasks"].values():
            assert "check" not in task and task["seed_protocol"] == {"protocol": PROTOCOL, "split": split}
