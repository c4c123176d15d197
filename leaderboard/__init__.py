"""Leaderboard: the baselines and trained agents ranked on collisions and tracking error, with bootstrap CIs.

:func:`run_leaderboard` evaluates entries (:func:`resolve_entries`) on the task suite (:data:`TASKS`) and writes
``leaderboard.md``, ``leaderboard.csv``, one JSON per entry, PNG plots and ``index.html``; ``uvdms leaderboard``
(``cli``) wraps it. The rules (tracks, multi-seed entries, seeds, statistics, ranking, cache, timings, safety):
``docs/leaderboard.md``; the subpackages (``suite``, ``running``, ``stats``, ``output``): ``docs/ARCHITECTURE.md``.
The module paths before the grouping (``leaderboard.registry``, ...) fail in one line naming their new home
(:mod:`leaderboard.legacy`).
"""

from __future__ import annotations

from leaderboard.legacy import MOVED_NAMES as _MOVED_NAMES
from leaderboard.legacy import REGROUPED as _REGROUPED
from leaderboard.output.report import markdown_tables
from leaderboard.output.webpage import write_index_html
from leaderboard.running.evaluate import evaluate
from leaderboard.running.runner import run_leaderboard
from leaderboard.stats.result import LeaderboardResult
from leaderboard.suite.entries import Entry, resolve_entries
from leaderboard.suite.tasks import DEFAULT_EPISODES, QUICK_EPISODES, TASKS, Task, select_tasks
from uvdms_gym.utils.legacy import install_moved_finder, moved_names, regrouped_message

install_moved_finder(_REGROUPED, regrouped_message)
__getattr__ = moved_names(__name__, _MOVED_NAMES[__name__])  # former names: one line naming their module

__all__ = [
    "DEFAULT_EPISODES",
    "QUICK_EPISODES",
    "TASKS",
    "Entry",
    "LeaderboardResult",
    "Task",
    "evaluate",
    "markdown_tables",
    "resolve_entries",
    "run_leaderboard",
    "select_tasks",
    "write_index_html",
]
