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

_STATS = {
    **dict.fromkeys(
        [
            "BOOTSTRAP_SEED",
            "CONFIDENCE",
            "IQM_PROPORTION",
            "N_RESAMPLES",
            "Stat",
            "bootstrap_ci",
            "intervals_overlap",
            "iqm",
        ],
        "leaderboard.stats.intervals",
    ),
    **dict.fromkeys(
        [
            "METRICS",
            "OVERLOAD_MARK",
            "RATE_METRICS",
            "TABLE_METRICS",
            "TIMING_METRICS",
            "aggregate",
            "aggregate_runs",
            "episode_indicators",
            "learning_curve_stats",
            "run_matrix",
            "timing_summary",
        ],
        "leaderboard.stats.metrics",
    ),
    **dict.fromkeys(["RankedRow", "TIE_TOLERANCE", "rank_rows"], "leaderboard.stats.ranking"),
}

MOVED_NAMES: dict[str, dict[str, str]] = {
    "leaderboard.stats": _STATS,
    "leaderboard": {
        **_STATS,
        **dict.fromkeys(
            ["CIRCLE_ID", "HYDRO_RANDOMIZATION", "TRACKS", "TRANSPORT_ID"],
            "leaderboard.suite.tasks",
        ),
        **dict.fromkeys(
            [
                "BASELINES",
                "DEFAULT_ENTRIES",
                "MIN_TRAINING_SEEDS",
                "RECOMMENDED_TRAINING_SEEDS",
                "SEED_FOLDER_PREFIX",
                "agent_entry",
                "check_seed_disjointness",
                "find_agent_folders",
                "is_multi_seed_folder",
                "is_weights_only",
                "multi_seed_entry",
                "slugify",
            ],
            "leaderboard.suite.entries",
        ),
        **dict.fromkeys(["agent_checksum", "agent_env", "training_seeds"], "leaderboard.suite.agent_files"),
        **dict.fromkeys(
            [
                "CACHE_FORMAT",
                "CorruptCacheError",
                "REQUIRED_KEYS",
                "cache_key",
                "cache_material",
                "cache_path",
                "compact_result",
                "read_cached",
            ],
            "leaderboard.running.cache",
        ),
        **dict.fromkeys(
            ["Backend", "DEFAULT_BACKEND", "Job", "compute_job", "make_env", "plan_jobs"], "leaderboard.running.jobs"
        ),
        "row_for": "leaderboard.running.runner",
        **dict.fromkeys(["timing_text", "write_outputs"], "leaderboard.output.report"),
        **dict.fromkeys(["PLOT_METRICS", "write_learning_curves", "write_plots"], "leaderboard.output.plots"),
        "PAGE_NAME": "leaderboard.output.webpage",
        "PageError": "leaderboard.output.page_data",
        "PACKAGE_VERSION": "uvdms_gym (as __version__; the cache keys no longer hold it)",
    },
}
"""The names ``leaderboard`` and the former module ``leaderboard.stats`` exported before 0.4.0 that live elsewhere
now -> their module (``from leaderboard import bootstrap_ci`` fails in one line naming
``leaderboard.stats.intervals``)."""
