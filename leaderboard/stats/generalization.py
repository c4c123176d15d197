"""The generalisation check: an entry's figure on the test draws against the same entry on a second set of draws.

The randomised tasks are scored on the ``test`` split (the ranking) and on the disjoint ``test2`` split
(:mod:`uvdms_gym.seeds`). An entry whose 95 % interval of the difference ``test2 - test`` of its contact-free
success rate excludes 0 is flagged: its published figure does not hold on other draws of the same distribution
(``docs/leaderboard.md``, Generalisation check).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from leaderboard.stats.intervals import BOOTSTRAP_SEED, Stat, bootstrap_difference, hierarchical_bootstrap_ci
from leaderboard.stats.metrics import run_matrix

CHECK_METRIC = "contact_free_success"
"""The metric the check compares: the ranking's first criterion."""


@dataclass(frozen=True)
class GeneralizationCheck:
    """One entry's ``metric`` on the two test sets of a task, and their difference.

    Attributes:
        metric: The compared metric (:data:`CHECK_METRIC`).
        test: The figure on the ``test`` draws (the ranking's).
        test2: The figure on the ``test2`` draws.
        difference: ``test2 - test`` with its 95 % bootstrap interval (each set resampled on its own).
    """

    metric: str
    test: Stat
    test2: Stat
    difference: Stat

    @property
    def flagged(self) -> bool:
        """Whether the interval of the difference excludes 0 (no interval: not flagged)."""
        low, high = self.difference.low, self.difference.high
        return math.isfinite(low) and math.isfinite(high) and (low > 0.0 or high < 0.0)

    def to_json(self) -> dict[str, Any]:
        """Plain dict for the entry documents."""
        return {
            "metric": self.metric,
            "test": self.test.to_json(),
            "test2": self.test2.to_json(),
            "difference": self.difference.to_json(),
            "flagged": self.flagged,
        }


def generalization_check(
    test_runs: Sequence[Sequence[Mapping[str, Any]]],
    test2_runs: Sequence[Sequence[Mapping[str, Any]]],
    metric: str = CHECK_METRIC,
) -> GeneralizationCheck:
    """The check of one entry on one task from its runs' episodes on each test set (one list per training seed).

    Both figures are means over the draws with their hierarchical bootstrap intervals
    (:func:`leaderboard.stats.intervals.hierarchical_bootstrap_ci`); the difference is
    :func:`leaderboard.stats.intervals.bootstrap_difference`.
    """
    first, second = run_matrix(test_runs, metric), run_matrix(test2_runs, metric)
    return GeneralizationCheck(
        metric=metric,
        test=hierarchical_bootstrap_ci(first, estimator="mean", seed=BOOTSTRAP_SEED),
        test2=hierarchical_bootstrap_ci(second, estimator="mean", seed=BOOTSTRAP_SEED + 1),
        difference=bootstrap_difference(first, second, estimator="mean", seed=BOOTSTRAP_SEED + 2),
    )
