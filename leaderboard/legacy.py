"""The module paths ``leaderboard`` had before 0.4.0 grouped it: importing one fails in one line naming its home.

``import leaderboard.registry`` raises ``ModuleNotFoundError: leaderboard.registry was moved in 0.4.0: import from
leaderboard.suite.registry (evaluate: leaderboard.running.evaluate)`` (:mod:`uvdms_gym.utils.legacy`);
``import leaderboard`` installs the finder.
"""

from __future__ import annotations

REGROUPED: dict[str, str] = {
    "leaderboard.tasks": "leaderboard.suite.tasks",
    "leaderboard.entries": "leaderboard.suite.entries",
    "leaderboard.agent_files": "leaderboard.suite.agent_files",
    "leaderboard.entry_info": "leaderboard.suite.entry_info",
    "leaderboard.registry": "leaderboard.suite.registry (evaluate: leaderboard.running.evaluate)",
    "leaderboard.evaluate": "leaderboard.running.evaluate",
    "leaderboard.cache": "leaderboard.running.cache",
    "leaderboard.jobs": "leaderboard.running.jobs",
    "leaderboard.runner": "leaderboard.running.runner",
    "leaderboard.reuse": "leaderboard.running.reuse",
    "leaderboard.distributed": "leaderboard.running.distributed",
    "leaderboard.result": "leaderboard.stats.result",
    "leaderboard.report": "leaderboard.output.report",
    "leaderboard.plots": "leaderboard.output.plots",
    "leaderboard.webpage": "leaderboard.output.webpage",
    "leaderboard.page_data": "leaderboard.output.page_data",
    "leaderboard.page_assets": "leaderboard.output.page_assets",
}
"""Old module path of ``leaderboard`` -> where its names live now (``leaderboard.stats`` is a package now:
``leaderboard.stats.intervals``, ``leaderboard.stats.metrics``, ``leaderboard.stats.ranking``)."""
