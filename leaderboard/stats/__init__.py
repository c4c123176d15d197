"""The leaderboard's statistics.

Intervals (``intervals``: bootstrap means, interquartile means, the stratified bootstrap of multi-seed rows), the
metrics and their aggregation per row (``metrics``), the ranking with ties (``ranking``) and what a run computed
(``result``). The rules: ``docs/leaderboard.md``.
"""
