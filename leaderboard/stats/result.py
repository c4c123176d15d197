"""What a run computed (:func:`leaderboard.running.runner.run_leaderboard`), read by the report and the plots."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from leaderboard.stats.ranking import RankedRow
from leaderboard.suite.entries import Entry
from leaderboard.suite.tasks import Task


@dataclass
class LeaderboardResult:
    """What :func:`run_leaderboard` computed."""

    rows: list[RankedRow]
    entries: list[Entry]
    tasks: tuple[Task, ...]
    seeds: list[int]
    """The draws of a randomised task on ``split`` (a deterministic task evaluates the first)."""
    computed: int
    cached: int
    corrupt: list[Path]
    out_dir: Path
    markdown: str = ""
    timing: dict[str, Any] = field(default_factory=dict)
    reused: int = 0
    split: str = "test"
    """The seed split the ranking used (:mod:`uvdms_gym.seeds`)."""
    check_seeds: list[int] = field(default_factory=list)
    """The draws of the generalisation check's second test set (empty without the check)."""
