"""The leaderboard's statistics.

Intervals (``intervals``: bootstrap means, interquartile means, the hierarchical bootstrap of multi-seed rows), the
metrics and their aggregation per row (``metrics``), the generalisation check (``generalization``), the ranking with
ties (``ranking``) and what a run computed (``result``). The rules: ``docs/leaderboard.md``.
"""

from leaderboard.legacy import MOVED_NAMES as _MOVED_NAMES
from uvdms_gym.utils.legacy import moved_names as _moved_names

__getattr__ = _moved_names(__name__, _MOVED_NAMES[__name__])  # former names: one line naming their module
