"""``index.html``: the leaderboard page holds every row of ``leaderboard.csv``, loads nothing, escapes every text.

A small output folder is made with the fake backend of ``tests.support.multiseed_fakes`` (no physics, a few seconds
with its plots): the four baselines, a three-seed residual agent with learning curves (and its ``+filter`` twin) and a
single agent whose folder name is HTML (``sac<b>&"q"``). The page is parsed with :mod:`html.parser` and checked
against the CSV, cell by cell, with the intervals formatted independently of :mod:`leaderboard.output.webpage`. The
page's behaviour in a browser: ``test_webpage_browser.py``.
"""

from __future__ import annotations

import csv
import html
import json
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import pytest

import leaderboard as lb
import leaderboard.suite.registry
from leaderboard.output.webpage import PAGE_NAME, metric_cell_text, write_index_html
from leaderboard.stats.metrics import METRICS
from leaderboard.suite.entries import slugify
from tests.support.multiseed_fakes import CALLS, FAKE, TINY_TASKS, _agent_folder, _multi_seed, _write_curve
from uvdms_cli.main import main as uvdms_main

GRASP_ONLY_COLUMNS = ("slip_max", "dropped", "crushed", "internal_force_max")
"""The friction grasp's metrics (the last of ``METRICS``), which CSVs written before them lack."""

REPO = Path(__file__).resolve().parents[3]
COMMITTED = REPO / "docs" / "leaderboard"
HTML_NAME = 'sac<b>&"q"'
"""A single agent's folder name: markup and quotes, which the page must show as text."""
RESIDUAL = "residual-campc-sac_multi"


@pytest.fixture(scope="module")
def board(tmp_path_factory) -> Path:
    """An output folder written by ``run_leaderboard`` (the fake backend), with plots and learning curves."""
    root = tmp_path_factory.mktemp("webpage")
    agents = root / "agents"
    composition = {"residual_base": "campc", "residual_scale": 0.2}
    multi = _multi_seed(agents, seeds=(0, 1, 2), composition=composition)
    for k in (0, 1, 2):
        _write_curve(multi / f"seed_{k}", k, [0.3 - 0.05 * k, 0.2, 0.1])
    single = _agent_folder(agents / HTML_NAME, 5)
    entries = lb.resolve_entries(["baselines", str(multi), f"{multi}+filter", str(single)], trust=True)
    CALLS.clear()
    with pytest.MonkeyPatch.context() as patch:  # the fake environment cannot host the real safety filter
        patch.setattr(leaderboard.suite.registry, "with_safety_filter", lambda controller, env: controller)
        lb.run_leaderboard(entries, out_dir=root / "out", tasks=TINY_TASKS, episodes=3, progress=False, backend=FAKE)
    return root / "out"


class _Rows(HTMLParser):
    """The ranking rows of a page (``<tr data-track>``): their attributes and cells (attributes and text).

    ``selector`` picks other rows by an attribute (``data-flagged``: the generalisation check's).
    """

    selector = "data-track"

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[dict] = []
        self._row: dict | None = None
        self._cell: dict | None = None

    def handle_starttag(self, tag, attrs):
        attributes = dict(attrs)
        if tag == "tr" and self.selector in attributes:
            self._row = {"attrs": attributes, "cells": []}
            self.rows.append(self._row)
        elif tag == "td" and self._row is not None:
            self._cell = {**attributes, "text": ""}
            self._row["cells"].append(self._cell)

    def handle_endtag(self, tag):
        if tag == "td":
            self._cell = None
        elif tag == "tr":
            self._row = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell["text"] += data


def page_rows(page: str) -> dict[tuple[str, str, str], dict]:
    """The page's ranking rows by (track, task, entry)."""
    parser = _Rows()
    parser.feed(page)
    rows = {(r["attrs"]["data-track"], r["attrs"]["data-task"], r["attrs"]["data-entry"]): r for r in parser.rows}
    assert len(rows) == len(parser.rows), "a (track, task, entry) appears twice"
    return rows


def n_cell(page_row: dict) -> str:
    """The ``n`` cell of a ranking row: the one after the metric cells."""
    last_metric = max(i for i, cell in enumerate(page_row["cells"]) if "data-metric" in cell)
    return page_row["cells"][last_metric + 1]["text"]


def csv_rows(folder: Path) -> list[dict[str, str]]:
    with (folder / "leaderboard.csv").open(encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def assert_page_holds_the_csv(folder: Path) -> None:
    """Every CSV row is one page row with the same rank and, per metric, the CSV's mean and interval."""
    rows, shown = csv_rows(folder), page_rows((folder / PAGE_NAME).read_text(encoding="utf-8"))
    assert len(shown) == len(rows) > 0
    for row in rows:
        page_row = shown[row["track"], row["task"], row["entry"]]
        assert page_row["cells"][0]["data-value"] == row["rank"]
        assert page_row["cells"][0]["text"] == row["rank"] + ("=" if row["tied"] == "1" else "")
        cells = {c["data-metric"]: c for c in page_row["cells"] if "data-metric" in c}
        # (a CSV written before the friction grasp's metrics, the committed one, has none of their columns)
        for metric in (m for m in METRICS if f"{m}_mean" in row or m not in GRASP_ONLY_COLUMNS):
            assert cells[metric]["data-value"] == row[f"{metric}_mean"]
            assert cells[metric]["text"].startswith(metric_cell_text(row, metric))
        mean, low, high = (row[f"rmse_pos_{p}"] for p in ("mean", "ci_low", "ci_high"))
        if mean and low and high:  # the interval, formatted here independently: mm with one decimal
            expected = f"{float(mean) * 1e3:.1f} [{float(low) * 1e3:.1f}, {float(high) * 1e3:.1f}]"
            assert cells["rmse_pos"]["text"] == expected


def _template(page: str, slug: str) -> str:
    match = re.search(rf'<template id="detail-{re.escape(slug)}">(.*?)</template>', page, re.S)
    assert match, f"no detail view of {slug}"
    return match.group(1)


# ------------------------------------------------------------------------------------------------------
# Content, offline, escaping
# ------------------------------------------------------------------------------------------------------
def test_the_page_holds_every_csv_row_with_its_figures_and_intervals(board):
    assert_page_holds_the_csv(board)
    rows = csv_rows(board)
    baselines = {"mpc", "campc", "campc-di", "campc-nndi"}
    assert {r["entry"] for r in rows} == baselines | {RESIDUAL, RESIDUAL + "+filter", HTML_NAME}
    page = (board / PAGE_NAME).read_text(encoding="utf-8")
    multi = next(r for r in rows if r["entry"] == RESIDUAL)
    assert "[" in metric_cell_text(multi, "rmse_pos")  # a multi-seed row has an interval
    assert f"{RESIDUAL} (3 seeds)" in page  # label as in leaderboard.md
    # n as in leaderboard.md: every seed's episode of the deterministic case1, the 3 draws of circle-random
    shown = page_rows(page)
    assert [n_cell(shown["velocity", task, RESIDUAL]) for task in ("case1", "circle-random")] == ["3 × 1", "3"]
    assert (
        n_cell(shown["velocity", "case1", "campc"]) == "1"
        and n_cell(shown["velocity", "circle-random", "campc"]) == "3"
    )
    markdown = (board / "leaderboard.md").read_text(encoding="utf-8").split("## Generalisation check")[0]
    lines = [line for line in markdown.splitlines() if line.startswith("| ") and f"| {RESIDUAL} (3 seeds) |" in line]
    assert [line.rsplit("|", 2)[1].strip() for line in lines] == ["3 × 1", "3"]


def test_the_page_loads_nothing(board):
    page = (board / PAGE_NAME).read_text(encoding="utf-8")
    plots = json.loads(re.search(r'<script type="application/json" id="plot-data">(.*?)</script>', page, re.S)[1])
    assert plots and all(uri.startswith("data:image/png;base64,") for uri in plots.values())
    assert f"plots/learning_curves_{RESIDUAL}.png" in plots and "plots/velocity_rmse_pos.png" in plots
    text = re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]+", "", page)
    for reference in ("http://", "https://", "//cdn", "url(", "@import", "<link", "<iframe"):
        assert reference not in text.lower(), reference
    assert not re.search(r"\b(src|href)\s*=", text, re.I)  # images get their data: URIs from the inline script
    csp = re.search(r'<meta http-equiv="Content-Security-Policy" content="([^"]*)">', page)[1]
    assert html.unescape(csp).startswith("default-src 'none'; img-src data:;")  # the browser may load nothing else
    assert len(re.findall(r"<script\b", page)) == 2  # the plot data and the inline script, no src


def test_every_text_from_the_folder_is_escaped(board):
    page = (board / PAGE_NAME).read_text(encoding="utf-8")
    assert HTML_NAME not in page and "<b>" not in page
    assert html.escape(HTML_NAME) in page  # shown as text, in the table and its detail view
    assert (board / "entries" / f"{slugify(HTML_NAME)}.json").is_file()
    row = next(r for (_t, _k, e), r in page_rows(page).items() if e == HTML_NAME)
    assert row["cells"][1]["text"] == HTML_NAME  # the parser unescapes what the browser will show


def test_detail_views_show_composition_seeds_training_and_learning_curve(board):
    page = (board / PAGE_NAME).read_text(encoding="utf-8")
    residual = _template(page, RESIDUAL)
    assert "residual on campc" in residual and "scaled by 0.2" in residual
    assert all(f"seed_{k}" in residual for k in (0, 1, 2))
    assert "trained with sac" in residual and "recorded in entries/" in residual
    assert f'data-plot="plots/learning_curves_{RESIDUAL}.png"' in residual
    twin = _template(page, slugify(RESIDUAL + "+filter"))
    assert "evaluated with the safety filter" in twin
    assert f'data-plot="plots/learning_curves_{RESIDUAL}.png"' in twin  # one training, one plot, embedded once
    assert page.count(f'"plots/learning_curves_{RESIDUAL}.png":') == 1
    assert "the baseline controller campc" in _template(page, "campc")
    assert "No learning curve recorded" in _template(page, slugify(HTML_NAME))
    kinds = {r["attrs"]["data-entry"]: r["attrs"]["data-kind"] for r in page_rows(page).values()}
    assert kinds == {
        **{b: "baseline" for b in ("mpc", "campc", "campc-di", "campc-nndi")},
        RESIDUAL: "residual",
        RESIDUAL + "+filter": "residual",
        HTML_NAME: "learned",
    }


# ------------------------------------------------------------------------------------------------------
# Regenerating a folder's page: uvdms leaderboard --page-only DIR
# ------------------------------------------------------------------------------------------------------
def test_page_only_rewrites_the_same_page_from_the_folder(board, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(board, copy, ignore=shutil.ignore_patterns("cache"))
    (copy / PAGE_NAME).unlink()
    assert uvdms_main(["leaderboard", "--page-only", str(copy), "--agents-dir", str(tmp_path / "none")]) == 0
    assert (copy / PAGE_NAME).read_bytes() == (board / PAGE_NAME).read_bytes()


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        ("missing", "no such leaderboard output folder"),
        ("no-csv", "not a leaderboard output folder (no leaderboard.csv)"),
        ("truncated-csv", "does not have one value per column"),
        ("not-a-csv", "missing columns"),
        ("bad-json", "not a valid entry document"),
        ("bad-png", "not a readable PNG image"),
    ],
)
def test_page_only_reports_a_missing_or_corrupt_folder_in_one_line(board, tmp_path, capsys, damage, message):
    folder = tmp_path / "copy"
    if damage != "missing":
        shutil.copytree(board, folder, ignore=shutil.ignore_patterns("cache"))
    if damage == "no-csv":
        (folder / "leaderboard.csv").unlink()
    elif damage == "truncated-csv":
        text = (folder / "leaderboard.csv").read_text()
        (folder / "leaderboard.csv").write_text(text[: len(text) // 2])
    elif damage == "not-a-csv":
        (folder / "leaderboard.csv").write_text("<html>not a csv</html>\n")
    elif damage == "bad-json":
        (folder / "entries" / "campc.json").write_text("{truncated")
    elif damage == "bad-png":
        (folder / "plots" / "velocity_rmse_pos.png").write_bytes(b"not a png")
    capsys.readouterr()
    assert uvdms_main(["leaderboard", "--page-only", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("uvdms: error: ") and err.count("\n") == 1 and message in err


def test_documents_without_details_take_them_from_the_agent_folder_only_if_it_is_the_evaluated_one(board, tmp_path):
    copy = tmp_path / "old"
    shutil.copytree(board, copy, ignore=shutil.ignore_patterns("cache"))
    for path in (copy / "entries").glob("*.json"):  # as written before the documents recorded them
        doc = json.loads(path.read_text())
        path.write_text(json.dumps({k: v for k, v in doc.items() if k not in ("composition", "training")}))
    agents = board.parent / "agents"
    page = write_index_html(copy, agents_dir=agents).read_text(encoding="utf-8")
    residual = _template(page, RESIDUAL)
    assert "residual on campc" in residual and "read from agents/sac_multi" in residual
    assert_page_holds_the_csv(copy)

    changed = tmp_path / "agents"
    shutil.copytree(agents, changed)
    with (changed / "sac_multi" / "seed_1" / "final_model.zip").open("ab") as f:
        f.write(b"retrained")
    residual = _template(write_index_html(copy, agents_dir=changed).read_text(encoding="utf-8"), RESIDUAL)
    assert "Composition</dt><dd>not recorded" in residual and "residual on campc" not in residual


def test_the_committed_page_holds_the_committed_csv():
    assert_page_holds_the_csv(COMMITTED)
    assert (COMMITTED / PAGE_NAME).stat().st_size < 4_000_000


def test_the_composition_names_the_navigation_filter_and_the_memory_of_an_agent_that_has_them():
    from leaderboard.output.webpage import _composition_items

    plain = {"residual_base": None, "evaluated_with_filter": False, "trained_with_filter": False}
    memory = {**plain, "navigation_filter": True, "frame_stack": 4, "action_history": 2}
    terms = dict(_composition_items({"composition": memory}))
    assert terms["Memory"] == "its last 4 observations and its own last 2 actions"
    assert "estimate" in terms["Navigation filter"]
    assert {"Memory", "Navigation filter", "Obstacle features"}.isdisjoint(
        dict(_composition_items({"composition": plain}))
    )
    featured = dict(_composition_items({"composition": {**plain, "obstacle_features": True}}))
    assert "nearest robot part" in featured["Obstacle features"]
