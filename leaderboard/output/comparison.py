"""Learned entries against a reference baseline on a leaderboard output folder, task by task, with a verdict.

Reads what ``uvdms leaderboard --out DIR`` wrote (``docs/leaderboard`` is the committed run): the published figures
of every row from ``leaderboard.csv`` (:func:`leaderboard.output.page_data.read_page_data`) and the per-episode
results of the compared rows from ``entries/<entry>.json``. Per task (:func:`compare_tasks`): the rows of
:data:`BASELINE_ROWS`, the best learned entry (:func:`best_learned`) and any entries asked for by name, each
learned one with its difference from :data:`REFERENCE` in :data:`METRIC`, paired over the task's draws
(:func:`leaderboard.stats.paired.paired_difference`), and its verdict (:func:`leaderboard.stats.paired.verdict`).
:func:`comparison_markdown` writes the tables; ``scripts/realism_comparison.py`` prints them for the realism track
(:func:`realism_task_names`).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from leaderboard.output.page_data import read_page_data
from leaderboard.stats.intervals import Stat
from leaderboard.stats.paired import paired_difference, runs_by_training_seed, verdict
from leaderboard.stats.ranking import PRIVILEGED_RANK
from leaderboard.suite.entries import slugify
from leaderboard.suite.tasks import REALISM_BASES, TASKS

REFERENCE = "campc"
"""The row every learned entry is compared with: CAMPC with the navigation filter and delay compensation."""
BASELINE_ROWS: dict[str, str] = {
    "campc": "`campc` (filter)",
    "campc-privileged": "`campc-privileged` (privileged ref.)",
    "campc-raw": "`campc-raw`",
}
"""The baseline rows shown on every task, with their column headers."""
LEARNED_KIND = "agent"
"""The ``kind`` (``leaderboard.csv``) of a learned entry."""
METRIC = "contact_free_success"
"""The compared metric: the ranking's first criterion."""
_LEVEL_SUFFIX = re.compile(r"-r\d+$")
"""A realism task's name is its base task's with ``-r<level>`` (``leaderboard.suite.tasks``)."""


@dataclass(frozen=True)
class RowFigures:
    """One row's published figures (``leaderboard.csv``).

    Attributes:
        entry: The entry's name.
        kind: ``baseline`` or ``agent``.
        privileged: A privileged reference row (rank ``ref``): never a competitor.
        success: Contact-free success with its 95 % interval (``n``: the row's episodes).
        rmse: Position RMSE (m; a multi-seed row's IQM), NaN without one.
    """

    entry: str
    kind: str
    privileged: bool
    success: Stat
    rmse: float

    @classmethod
    def from_csv(cls, row: Mapping[str, str]) -> RowFigures:
        """The figures of a ``leaderboard.csv`` row (column -> text)."""
        mean, low, high = (_number(row.get(f"{METRIC}_{part}", "")) for part in ("mean", "ci_low", "ci_high"))
        episodes = _number(row.get("episodes", ""))
        return cls(
            entry=row["entry"],
            kind=row["kind"],
            privileged=row["rank"] == PRIVILEGED_RANK,
            success=Stat(mean, low, high, int(episodes) if math.isfinite(episodes) else 0),
            rmse=_number(row.get("rmse_pos_mean", "")),
        )


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan


@dataclass(frozen=True)
class LearnedComparison:
    """A learned entry on one task against :data:`REFERENCE`.

    Attributes:
        row: The entry's figures.
        difference: ``entry - reference`` in :data:`METRIC`, paired over the draws, with its 95 % interval.
        best: Whether it is the task's best learned entry (:func:`best_learned`).
    """

    row: RowFigures
    difference: Stat
    best: bool

    @property
    def verdict(self) -> str:
        """``ahead``, ``behind``, ``not separated`` or ``no interval`` (:func:`leaderboard.stats.paired.verdict`)."""
        return verdict(self.difference)


@dataclass(frozen=True)
class TaskComparison:
    """One task: the rows of :data:`BASELINE_ROWS` (``None`` where missing) and the compared learned entries."""

    task: str
    baselines: dict[str, RowFigures | None]
    learned: list[LearnedComparison] = field(default_factory=list)


def best_learned(rows: Iterable[RowFigures]) -> RowFigures | None:
    """The learned row (kind ``agent``, not privileged) of highest contact-free success; ties: lower RMSE, then name.

    A missing success counts as the lowest, a missing RMSE as the highest. ``None`` without a learned row.
    """

    def key(row: RowFigures) -> tuple[float, float, str]:
        success = row.success.mean if math.isfinite(row.success.mean) else -math.inf
        rmse = row.rmse if math.isfinite(row.rmse) else math.inf
        return -success, rmse, row.entry

    learned = [row for row in rows if row.kind == LEARNED_KIND and not row.privileged]
    return min(learned, key=key, default=None)


def realism_task_names() -> list[str]:
    """The realism track's tasks (``leaderboard.suite.tasks``), grouped by base task, levels ascending."""
    realism = [task for task in TASKS if task.realism > 0]
    order = {base: i for i, base in enumerate(REALISM_BASES)}
    realism.sort(key=lambda task: (order.get(_LEVEL_SUFFIX.sub("", task.name), len(order)), task.realism))
    return [task.name for task in realism]


class _Episodes:
    """The per-episode results of ``entries/<entry>.json``, each document read once."""

    def __init__(self, out_dir: Path) -> None:
        self.out_dir = out_dir
        self.documents: dict[str, dict[str, Any]] = {}

    def runs(self, entry: str, task: str) -> list[list[Mapping[str, Any]]]:
        """The entry's episodes on ``task``, one run per training seed (none if the document lacks them)."""
        if entry not in self.documents:
            path = self.out_dir / "entries" / f"{slugify(entry)}.json"
            self.documents[entry] = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}
        episodes = self.documents[entry].get("tasks", {}).get(task, {}).get("episodes", [])
        return runs_by_training_seed(episodes)


def compare_tasks(
    out_dir: str | Path, tasks: Sequence[str] | None = None, entries: Sequence[str] = ()
) -> list[TaskComparison]:
    """Per task of ``tasks`` (default :func:`realism_task_names`): the baselines, the best learned entry, ``entries``.

    Each learned entry's difference from :data:`REFERENCE` is
    :func:`leaderboard.stats.paired.paired_difference` of their episodes (the bootstrap's default seed: the
    same output on every call). A named entry the task lacks is left out of that task.

    Raises:
        ValueError: A task or a named entry without any row in ``leaderboard.csv``.
        leaderboard.output.page_data.PageError: ``out_dir`` is not a readable leaderboard output folder.
    """
    out = Path(out_dir)
    data = read_page_data(out)
    names = list(tasks) if tasks is not None else realism_task_names()
    by_task: dict[str, dict[str, RowFigures]] = {name: {} for name in names}
    for row in data.rows:
        if row["task"] in by_task:
            by_task[row["task"]][row["entry"]] = RowFigures.from_csv(row)
    _check_present(by_task, entries)
    episodes = _Episodes(out)
    comparisons = []
    for task, rows in by_task.items():
        best = best_learned(rows.values())
        shown = [name for name in [best.entry if best else None, *entries] if name in rows]
        learned = [
            LearnedComparison(
                row=rows[name],
                difference=paired_difference(episodes.runs(REFERENCE, task), episodes.runs(name, task), METRIC),
                best=rows[name] is best,
            )
            for name in dict.fromkeys(shown)
        ]
        comparisons.append(TaskComparison(task, {name: rows.get(name) for name in BASELINE_ROWS}, learned))
    return comparisons


def _check_present(by_task: Mapping[str, Mapping[str, RowFigures]], entries: Sequence[str]) -> None:
    """Raise ``ValueError`` for a task without rows or a named entry on none of the tasks."""
    empty = [task for task, rows in by_task.items() if not rows]
    if empty:
        raise ValueError(f"no row of task(s) {', '.join(empty)} in leaderboard.csv")
    absent = [e for e in entries if not any(e in rows for rows in by_task.values())]
    if absent:
        raise ValueError(f"no row of entry(ies) {', '.join(absent)} on these tasks in leaderboard.csv")


def success_cell(mean: float | None, low: float | None, high: float | None, rmse: float | None) -> str:
    """``mean [low, high], RMSE mm`` (contact-free success, position RMSE in m): without undefined parts.

    ``None`` and NaN are undefined: no interval, no RMSE; ``—`` without a mean.
    """
    if not _defined(mean):
        return "—"
    interval = f" [{low:.2f}, {high:.2f}]" if _defined(low) and _defined(high) else ""
    return f"{mean:.2f}{interval}, {rmse * 1000:.1f} mm" if _defined(rmse) else f"{mean:.2f}{interval}"


def _defined(value: float | None) -> bool:
    return value is not None and math.isfinite(value)


def _figures(row: RowFigures | None) -> str:
    if row is None:
        return "—"
    return success_cell(row.success.mean, row.success.low, row.success.high, row.rmse)


def _difference(stat: Stat) -> str:
    if not math.isfinite(stat.mean):
        return "—"
    if not (math.isfinite(stat.low) and math.isfinite(stat.high)):
        return f"{stat.mean:+.2f}"
    return f"{stat.mean:+.2f} [{stat.low:+.2f}, {stat.high:+.2f}]"


def comparison_markdown(comparisons: Sequence[TaskComparison]) -> str:
    """One markdown table per base task (a realism task's name without ``-r<level>``), one row per task and entry.

    Columns: the task, the rows of :data:`BASELINE_ROWS`, the learned entry (``best`` or ``named``), its figures,
    its difference from :data:`REFERENCE` and the verdict. Cells: contact-free success [95 % interval], position
    RMSE; the difference is in contact-free success. A task without a learned row has one row with ``—``.
    """
    groups: dict[str, list[TaskComparison]] = {}
    for comparison in comparisons:
        groups.setdefault(_LEVEL_SUFFIX.sub("", comparison.task), []).append(comparison)
    header = ["Task", *BASELINE_ROWS.values(), "Learned entry", "Learned", f"Learned − `{REFERENCE}`", "Verdict"]
    lines: list[str] = []
    for base, group in groups.items():
        lines += [f"**{base}**", "", "| " + " | ".join(header) + " |", "|---" * len(header) + "|"]
        for comparison in group:
            baselines = [_figures(comparison.baselines[name]) for name in BASELINE_ROWS]
            for learned in comparison.learned or [None]:
                lines.append("| " + " | ".join([f"`{comparison.task}`", *baselines, *_learned_cells(learned)]) + " |")
        lines.append("")
    return "\n".join(lines)


def _learned_cells(learned: LearnedComparison | None) -> list[str]:
    if learned is None:
        return ["— (no learned entry)", "—", "—", "—"]
    label = f"`{learned.row.entry}`" + ("" if learned.best else " (named)")
    return [label, _figures(learned.row), _difference(learned.difference), learned.verdict]
