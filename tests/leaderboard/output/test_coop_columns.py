"""The cooperative tasks' columns (``Max slip (mm)``, ``Drop rate``): shown for the friction-grasp tasks only.

A fake run (no physics) of the tiny suite plus one friction-grasp task: the markdown table of a track with such a
task gains the two columns (``—`` on the rigid tasks' rows), the CSV has them (empty cells for the rigid tasks),
the page shows them in the cooperative task's table and hides them (``all columns``) in the others'; a run without
a friction-grasp task has the tables it had before the columns existed.
"""

from __future__ import annotations

import csv
import re

import pytest

import leaderboard as lb
from leaderboard.running.jobs import Backend
from leaderboard.stats.metrics import GRASP_METRICS, METRICS
from tests.support.leaderboard_fakes import BASELINE_ENTRIES, TINY_TASKS, fake_make_controller, fake_make_env
from tests.support.leaderboard_fakes import fake_run_episode as rigid_episode

COOP_TASK = lb.Task(
    "coop-tiny", "Cooperative tiny", "uvdms/CooperativeTransport-v1", {"goal": "paper"}, paper=False,
    max_episode_steps=3, deterministic=True, grasp="friction",
)  # fmt: skip


def coop_episode(env, controller, seed, save_trajectory):
    """The fake episode, with the friction grasp's keys on a cooperative environment (``None`` elsewhere)."""
    result = rigid_episode(env, controller, seed, save_trajectory)
    friction = "Cooperative" in env.spec_["env_id"]
    dropped = controller.name == "mpc"
    result.update(
        slip_max=(0.05 if dropped else 0.002) if friction else None,
        dropped=dropped if friction else None,
        crushed=False if friction else None,
        internal_force_max=12.0 if friction else None,
        internal_force_rms=5.0 if friction else None,
    )
    return result


BACKEND = Backend(make_env=fake_make_env, make_controller=fake_make_controller, run_episode=coop_episode)


def _run(tmp_path, tasks):
    return lb.run_leaderboard(
        BASELINE_ENTRIES, out_dir=tmp_path, tasks=tasks, episodes=2, progress=False, plots=False, backend=BACKEND
    )


def _table(markdown: str, track: str) -> list[list[str]]:
    block = markdown.split(f"### {track} track\n\n", 1)[1].split("\n\n", 1)[0]
    return [[c.strip() for c in line.strip("|").split("|")] for line in block.splitlines() if line.startswith("|")]


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    out = tmp_path_factory.mktemp("coop")
    _run(out, (*TINY_TASKS, COOP_TASK))
    return out


def test_markdown_adds_the_columns_for_a_track_with_a_cooperative_task(board):
    markdown = (board / "leaderboard.md").read_text(encoding="utf-8")
    labels = [METRICS[m]["label"] for m in GRASP_METRICS]
    assert labels == ["Max slip (mm)", "Drop rate"]
    assert "The cooperative tasks" in markdown
    for track in ("Velocity", "Torque"):
        header, _align, *rows = _table(markdown, track)
        index = [header.index(label) for label in labels]
        for cells in rows:
            values = [cells[i] for i in index]
            if cells[0] == COOP_TASK.label:
                assert values[0].startswith(("50.0", "2.0")) and values[1] in ("1.00 (n=1)", "0.00 (n=1)")
            else:
                assert values == ["—", "—"]


def test_the_csv_has_the_grasp_columns_empty_on_rigid_tasks(board):
    with (board / "leaderboard.csv").open(encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        filled = [row[f"{m}_mean"] != "" for m in (*GRASP_METRICS, "crushed", "internal_force_max")]
        assert all(filled) if row["task"] == COOP_TASK.name else not any(filled)
    mpc = next(r for r in rows if r["task"] == COOP_TASK.name and r["entry"] == "mpc")
    assert float(mpc["dropped_mean"]) == 1.0 and float(mpc["slip_max_mean"]) == pytest.approx(0.05)


def test_the_page_shows_the_columns_in_the_cooperative_tables_only(board):
    page = (board / "index.html").read_text(encoding="utf-8")
    sections = re.findall(r'<section class="board" data-track="\w+" data-task="([\w-]+)">(.*?)</section>', page, re.S)
    assert {task for task, _ in sections} == {"case1", "circle-random", COOP_TASK.name}
    for task, body in sections:
        for metric in GRASP_METRICS:
            (header,) = re.findall(rf'<th data-type="number" data-metric="{metric}"([^>]*)>', body)
            assert ('class="extra"' in header) == (task != COOP_TASK.name)


def test_without_a_cooperative_task_the_tables_have_no_grasp_column(tmp_path):
    result = _run(tmp_path, TINY_TASKS)
    assert "Max slip" not in result.markdown and "Drop rate" not in result.markdown
    assert "The cooperative tasks" not in result.markdown
