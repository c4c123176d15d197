"""The leaderboard's metrics and their aggregation: per row (episodes, or training seeds x episodes) and over curves.

:func:`aggregate` gives a single agent's or a baseline's row (a mean with its bootstrap interval per metric),
:func:`aggregate_runs` a multi-seed entry's row (rates as fractions, every other metric as the interquartile mean,
with hierarchical bootstrap intervals: task draws, then training seeds), :func:`learning_curve_stats` the mean of
learning curves over training seeds and :func:`timing_summary` where and under what load the controller timings ran.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from leaderboard.stats.intervals import BOOTSTRAP_SEED, Stat, bootstrap_ci, hierarchical_bootstrap_ci

RATE_METRICS: tuple[str, ...] = ("contact_free_success", "success", "contact_free", "dropped", "crushed")
"""The 0/1 indicators: a multi-seed row reports their rate (the mean), not an IQM (see :func:`aggregate_runs`)."""

METRICS: dict[str, dict[str, Any]] = {
    "contact_free_success": {"label": "Contact-free success", "fmt": ".2f", "better": "high"},
    "success": {"label": "Success", "fmt": ".2f", "better": "high"},
    "contact_free": {"label": "Contact-free", "fmt": ".2f", "better": "high"},
    "rmse_pos": {"label": "RMSE pos (mm)", "fmt": ".1f", "scale": 1e3, "better": "low"},
    "rmse_ori": {"label": "RMSE ori (deg)", "fmt": ".2f", "scale": 180 / math.pi, "better": "low"},
    "final_pos_error": {"label": "Final pos err (mm)", "fmt": ".1f", "scale": 1e3, "better": "low"},
    "final_ori_error": {"label": "Final ori err (deg)", "fmt": ".2f", "scale": 180 / math.pi, "better": "low"},
    "min_distance": {"label": "Min distance (m)", "fmt": ".3f", "better": "high"},
    "contacts": {"label": "Contacts", "fmt": ".1f", "better": "low"},
    "zone_steps": {"label": "Zone steps", "fmt": ".1f", "better": "low"},
    "cost": {"label": "Cost", "fmt": ".1f", "better": "low"},
    "return": {"label": "Return", "fmt": ".1f", "better": "high"},
    "steps": {"label": "Steps", "fmt": ".0f", "better": "high"},
    "controller_ms_median": {"label": "Ctrl ms", "fmt": ".2f", "better": "low"},
    "qp_slack_max": {"label": "QP slack max", "fmt": ".3g", "better": "low"},
    "slip_max": {"label": "Max slip (mm)", "fmt": ".1f", "scale": 1e3, "better": "low"},
    "dropped": {"label": "Drop rate", "fmt": ".2f", "better": "low"},
    "crushed": {"label": "Crush rate", "fmt": ".2f", "better": "low"},
    "internal_force_max": {"label": "Max internal force (N)", "fmt": ".1f", "better": "low"},
}
"""Aggregated metrics (per-episode keys of ``run_episode`` plus the derived 0/1 indicators). Values are SI
(m, rad) everywhere but in the tables and plots, which multiply by ``scale`` (mm, degrees). The friction grasp's
(:data:`GRASP_METRICS` and the two after them) come last, so every other metric keeps its bootstrap seed
(``BOOTSTRAP_SEED + index``); they have no value (``—``, empty CSV cells) on the rigid-grasp tasks, whose episodes
record ``None`` or (computed before the keys existed) nothing."""
GRASP_METRICS: tuple[str, ...] = ("slip_max", "dropped")
"""The columns the tables add for the friction-grasp tasks (``Task.grasp == "friction"``): in ``leaderboard.md``
for a track with such a task (``—`` on the other tasks' rows), on the page in those tasks' tables."""
TABLE_METRICS: tuple[str, ...] = (
    "contact_free_success",
    "success",
    "contact_free",
    "rmse_pos",
    "rmse_ori",
    "min_distance",
    "return",
    "controller_ms_median",
)
"""The metrics of the tables of ``leaderboard.md`` (and the columns the page shows by default)."""
TIMING_METRICS: tuple[str, ...] = ("controller_ms_median",)
"""Metrics that are wall-clock timings (marked when taken under overload)."""
OVERLOAD_MARK = "†"
"""Marks a controller timing taken with a 1-minute load average above the core count (tables)."""


def timing_summary(episodes: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Summary of the per-episode timing records (:func:`uvdms_gym.utils.provenance.timing_record`).

    Returns:
        ``{"overloaded": episodes whose 1-minute load exceeded the core count, "unknown": episodes without a
        load record, "load_1min_max": highest load seen (``None`` if none), "machines": sorted distinct
        ``"<cpu model> (<n> cores)"``}``.
    """
    overloaded = unknown = 0
    loads: list[float] = []
    machines: set[str] = set()
    for ep in episodes:
        record = ep.get("timing")
        flag = record.get("overloaded") if isinstance(record, Mapping) else None
        if flag is None:
            unknown += 1
        overloaded += int(flag is True)
        if isinstance(record, Mapping):
            loads += [x for x in (record.get("load_1min_start"), record.get("load_1min_end")) if x is not None]
            machine = record.get("machine") or {}
            machines.add(f"{machine.get('cpu_model', 'unknown')} ({machine.get('cpu_count', '?')} cores)")
    return {
        "overloaded": overloaded,
        "unknown": unknown,
        "load_1min_max": max(loads) if loads else None,
        "machines": sorted(machines),
    }


def episode_indicators(result: Mapping[str, Any]) -> dict[str, float]:
    """The derived 0/1 indicators of one episode: ``contact_free`` and ``contact_free_success``."""
    contact_free = float((result.get("contacts") or 0) == 0)
    return {"contact_free": contact_free, "contact_free_success": float(bool(result.get("success")) and contact_free)}


def _episode_value(result: Mapping[str, Any], metric: str) -> float | None:
    """One episode's value of ``metric`` (the derived indicators included); ``None`` where it has none."""
    if metric in ("contact_free", "contact_free_success"):
        return episode_indicators(result)[metric]
    raw = result.get(metric)
    if raw is None or isinstance(raw, str):
        return None
    return float(raw)


def aggregate(results: Sequence[Mapping[str, Any]]) -> dict[str, Stat]:
    """Mean and bootstrap CI of every metric in :data:`METRICS` over the episodes ``results``."""
    out = {}
    for index, metric in enumerate(METRICS):
        values = [v for v in (_episode_value(result, metric) for result in results) if v is not None]
        out[metric] = bootstrap_ci(values, seed=BOOTSTRAP_SEED + index)
    return out


def run_matrix(runs: Sequence[Sequence[Mapping[str, Any]]], metric: str) -> np.ndarray:
    """The ``(runs, draws)`` matrix of ``metric``: one row per run, one column per evaluation seed (task draw).

    Columns are the sorted evaluation seeds (``result["seed"]``) of all runs; a run without an episode of a seed, or
    an episode without a value of the metric, leaves NaN.

    Raises:
        ValueError: A run with two episodes of the same seed.
    """
    seeds = sorted({int(result["seed"]) for run in runs for result in run})
    column = {seed: j for j, seed in enumerate(seeds)}
    x = np.full((len(runs), len(seeds)), math.nan)
    for i, run in enumerate(runs):
        seen: set[int] = set()
        for result in run:
            seed = int(result["seed"])
            if seed in seen:
                raise ValueError(f"run {i} has two episodes of evaluation seed {seed}")
            seen.add(seed)
            value = _episode_value(result, metric)
            if value is not None:
                x[i, column[seed]] = value
    return x


def aggregate_runs(runs: Sequence[Sequence[Mapping[str, Any]]]) -> dict[str, Stat]:
    """The statistics of a multi-seed row: every metric of :data:`METRICS` over its runs' episodes.

    Rates (:data:`RATE_METRICS`) are the fraction over all runs x episodes (the mean: an IQM of 0/1 values is
    ``clip(2 p - 1/2, 0, 1)`` of the rate ``p``, not a rate); every other metric is the IQM of the matrix
    (:func:`iqm`). Both with :func:`hierarchical_bootstrap_ci` (seed ``BOOTSTRAP_SEED + metric index``, as
    :func:`aggregate`).

    Args:
        runs: One list of per-episode results per training seed: the same draws in each (a deterministic task), or
            each its share of the draws (a randomised task, :func:`uvdms_gym.seeds.assign_draws`).

    Raises:
        ValueError: No runs.
    """
    if not runs:
        raise ValueError("aggregate_runs needs at least one run")
    out = {}
    for index, metric in enumerate(METRICS):
        estimator = "mean" if metric in RATE_METRICS else "iqm"
        out[metric] = hierarchical_bootstrap_ci(
            run_matrix(runs, metric), estimator=estimator, seed=BOOTSTRAP_SEED + index
        )
    return out


def learning_curve_stats(curves: Sequence[Sequence[Mapping[str, Any]]], key: str) -> tuple[list[int], list[Stat]]:
    """Mean over training seeds, with :func:`bootstrap_ci`, of a learning-curve value at each step count.

    Args:
        curves: One list of points (:mod:`agents.common.learning_curve`) per training seed.
        key: The point's value (``success_rate``, ``rmse_pos_mean``, ...).

    Returns:
        ``(steps, stats)`` over the step counts present in every curve, ascending (a seed without a value at a
        step, e.g. no RMSE, is left out of that step's statistic). A single curve gives its values without an
        interval.
    """
    if not curves:
        return [], []
    by_seed = [{int(p["num_timesteps"]): p.get(key) for p in curve} for curve in curves]
    steps = sorted(set.intersection(*(set(values) for values in by_seed)))
    stats_ = []
    for step in steps:
        values = [float(v[step]) for v in by_seed if v[step] is not None]
        stats_.append(bootstrap_ci(values))
    return steps, stats_
