"""The ranking: rows sorted within each (track, task) and tied where their intervals overlap.

The rule (``docs/leaderboard.md``, Ranking): contact-free success rate first, then position RMSE; an entry is tied
with the leader of its group when both intervals overlap (up to :data:`TIE_TOLERANCE`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from leaderboard.stats.generalization import GeneralizationCheck
from leaderboard.stats.intervals import Stat, intervals_overlap
from leaderboard.stats.metrics import timing_summary
from leaderboard.suite.entries import Entry
from leaderboard.suite.tasks import Task

TIE_TOLERANCE: dict[str, float] = {"contact_free_success": 0.0, "rmse_pos": 1e-4}
"""Two intervals of a ranking metric closer than this count as overlapping (RMSE: 0.1 mm, the tables'
printed resolution; without it two deterministic controllers with zero-width intervals that print the same
value would be ranked apart)."""


@dataclass
class RankedRow:
    """A (track, task, entry) cell of the leaderboard.

    ``episodes`` are those of the ranking's split; a randomised task of a run on the ``test`` split also has the
    generalisation ``check`` and the episodes of the second test set it was computed from (``check_episodes``).
    """

    entry: Entry
    task: Task
    stats: dict[str, Stat]
    episodes: list[dict[str, Any]]
    rank: int = 0
    tied: bool = False
    check: GeneralizationCheck | None = None
    check_episodes: list[dict[str, Any]] = field(default_factory=list)

    @property
    def rank_label(self) -> str:
        """``3`` or ``3=`` for a tie; ``ref`` for a privileged reference row (not ranked)."""
        if self.entry.privileged:
            return PRIVILEGED_RANK
        return f"{self.rank}=" if self.tied else str(self.rank)

    @property
    def timing(self) -> dict[str, Any]:
        """Where and under what load this row's controller timings ran (:func:`timing_summary` of its episodes)."""
        return timing_summary(self.episodes)


def _sort_key(row: RankedRow) -> tuple[float, float, str]:
    cfs = row.stats["contact_free_success"].mean
    rmse = row.stats["rmse_pos"].mean
    return (
        -(cfs if math.isfinite(cfs) else -1.0),
        rmse if math.isfinite(rmse) else math.inf,
        row.entry.name,
    )


PRIVILEGED_RANK = "ref"
"""The rank label of a privileged reference row (it reads the true state: shown after the ranked rows, not ranked)."""


def rank_rows(rows: Sequence[RankedRow]) -> list[RankedRow]:
    """Rank one (track, task) group in place and return it sorted (rule in the module docstring).

    Privileged reference rows (``Entry.privileged``) are not ranked: rank 0, listed after the ranked rows.
    """
    references = sorted((r for r in rows if r.entry.privileged), key=_sort_key)
    for row in references:
        row.rank, row.tied = 0, False
    return _rank_competitors([r for r in rows if not r.entry.privileged]) + references


def _rank_competitors(rows: Sequence[RankedRow]) -> list[RankedRow]:
    ordered = sorted(rows, key=_sort_key)
    leader: RankedRow | None = None
    group: list[RankedRow] = []
    for position, row in enumerate(ordered, start=1):
        if leader is not None and all(
            intervals_overlap(leader.stats[m], row.stats[m], TIE_TOLERANCE[m]) for m in _RANK_METRICS
        ):
            row.rank = leader.rank
            group.append(row)
        else:
            leader, group = row, [row]
            row.rank = position
        if len(group) > 1:
            for member in group:
                member.tied = True
    return ordered


_RANK_METRICS = ("contact_free_success", "rmse_pos")
