"""Leaderboard plots: bar charts with CI whiskers per track and metric, minimum distance over time, learning curves."""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from leaderboard.stats.metrics import METRICS, learning_curve_stats
from leaderboard.suite.entries import Entry
from leaderboard.suite.tasks import TRACKS
from uvdms_gym.physics.params import D1, D2

if TYPE_CHECKING:
    from leaderboard.stats.result import LeaderboardResult

log = logging.getLogger("uvdms.leaderboard")

PLOT_METRICS: tuple[str, ...] = ("contact_free_success", "rmse_pos", "min_distance", "contacts", "return")
"""The metrics with a bar chart."""
LEARNING_CURVE_PANELS: tuple[tuple[str, str, str], ...] = (
    ("success_rate", "success", "Success rate"),
    ("rmse_pos_mean", "rmse_pos", "RMSE pos (mm)"),
)
"""Panels of a learning-curve plot: (point key of :mod:`agents.common.learning_curve`, metric of :data:`METRICS` whose
scale the panel uses, axis label)."""


def write_plots(result: LeaderboardResult, plot_dir: str | Path) -> list[Path]:
    """Bar charts with CI whiskers per track and metric, and minimum distance over time on the circle tasks.

    Returns:
        The written PNG paths.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)

    plot_dir = Path(plot_dir)
    plot_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for track in TRACKS:
        rows = [r for r in result.rows if r.entry.track == track]
        if rows:
            written += [_bar_chart(rows, result.tasks, track, metric, plot_dir) for metric in PLOT_METRICS]
    for task in result.tasks:
        curves = _distance_curves(result, task) if task.trajectory else []
        if curves:
            written.append(_distance_plot(task, curves, plot_dir))
    written += write_learning_curves(result.entries, plot_dir)
    return written


def _bar_chart(rows: list[Any], all_tasks: Sequence[Any], track: str, metric: str, plot_dir: Path) -> Path:
    """One track's bars of ``metric`` per task and entry (mean or IQM, with the 95 % interval as whiskers)."""
    import matplotlib.pyplot as plt

    names = list(dict.fromkeys(r.entry.name for r in rows))
    tasks = [t for t in all_tasks if any(r.task is t for r in rows)]
    fig, ax = plt.subplots(figsize=(max(6.0, 1.2 * len(tasks) * max(1, len(names)) * 0.35 + 3), 4.0))
    width = 0.8 / max(1, len(names))
    plotted: list[float] = []
    for k, name in enumerate(names):
        xs, ys, lo, hi = _bars(rows, tasks, name, metric, offset=-0.4 + width * (k + 0.5))
        if xs:
            label = next(r.entry.label for r in rows if r.entry.name == name)
            ax.bar(xs, ys, width, yerr=[lo, hi], capsize=3, label=label)
            plotted.extend(ys)
    ax.set_xticks(range(len(tasks)), [t.label for t in tasks], rotation=15, ha="right")
    ax.set_ylabel(METRICS[metric]["label"])
    positive = [v for v in plotted if v > 0]
    if METRICS[metric].get("scale") and positive and max(positive) > 30 * min(positive):
        ax.set_yscale("log")  # errors spanning orders of magnitude (sub-mm MPC vs. cm agents)
    estimate = "mean (IQM over seeds)" if any(r.entry.multi_seed for r in rows) else "mean"
    ax.set_title(f"{track} track: {METRICS[metric]['label']} ({estimate}, 95 % bootstrap CI)")
    if metric == "min_distance":
        ax.axhline(D1, color="black", linestyle="--", linewidth=1, label="d1")
        ax.axhline(D2, color="0.4", linestyle=":", linewidth=1.2, label="d2")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(axis="y", alpha=0.3)
    return _save(fig, plot_dir / f"{track}_{metric}.png")


def _bars(
    rows: list[Any], tasks: list[Any], name: str, metric: str, offset: float
) -> tuple[list[float], list[float], list[float], list[float]]:
    """The positions, heights and whisker lengths (below, above) of one entry's bars (tasks without a value: none)."""
    xs: list[float] = []
    ys: list[float] = []
    lo: list[float] = []
    hi: list[float] = []
    scale = METRICS[metric].get("scale", 1.0)
    for i, task in enumerate(tasks):
        row = next((r for r in rows if r.task is task and r.entry.name == name), None)
        if row is None or not math.isfinite(row.stats[metric].mean):
            continue
        stat = row.stats[metric]
        a, b = stat.interval()
        xs.append(i + offset)
        ys.append(stat.mean * scale)
        lo.append((stat.mean - a) * scale)
        hi.append((b - stat.mean) * scale)
    return xs, ys, lo, hi


def _distance_curves(result: LeaderboardResult, task: Any) -> list[tuple[Entry, dict[str, Any]]]:
    """Each row's first recorded trajectory (time and minimum distance) on ``task``."""
    curves = []
    for row in result.rows:
        if row.task is not task:
            continue
        traj = next((ep.get("trajectory") for ep in row.episodes if ep.get("trajectory")), None)
        if traj:
            curves.append((row.entry, traj))
    return curves


def _distance_plot(task: Any, curves: list[tuple[Entry, dict[str, Any]]], plot_dir: Path) -> Path:
    """The minimum of the 18 distances over time of every entry on one task, with ``d1`` and ``d2``."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.0, 4.5))
    for entry, traj in curves:
        style = "-" if entry.track == "velocity" else "--"
        ax.plot(traj["t"], traj["min_distance"], style, linewidth=1.2, label=f"{entry.name} ({entry.track})")
    ax.axhline(D1, color="black", linestyle="--", linewidth=1, label="d1 = 0.05 m")
    ax.axhline(D2, color="0.4", linestyle=":", linewidth=1.2, label="d2 = 0.12 m")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("minimum of the 18 distances (m)")
    ax.set_title(f"{task.label}: minimum distance over time (first evaluation seed)")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    return _save(fig, plot_dir / f"min_distance_{task.name}.png")


def _save(fig: Any, path: Path) -> Path:
    """Lay out, write at 110 dpi and close a figure."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def entry_learning_curves(entry: Entry) -> list[list[dict[str, Any]]]:
    """The learning-curve points of each of an agent entry's runs that has a readable curve (baselines: none).

    An unreadable curve file is skipped with a warning.
    """
    from agents.common.learning_curve import LearningCurveError, find_learning_curve, read_learning_curve

    if entry.kind != "agent":
        return []
    curves = []
    for run in entry.runs():
        path = find_learning_curve(run.spec)
        if path is None:
            continue
        try:
            points = read_learning_curve(path)["points"]
        except LearningCurveError as exc:
            log.warning("%s: learning curve skipped: %s", run.name, exc)
            continue
        if points:
            curves.append(points)
    return curves


def write_learning_curves(entries: Sequence[Entry], plot_dir: str | Path) -> list[Path]:
    """``learning_curves_<entry>.png`` for every agent entry with learning curves.

    Success rate and position RMSE of the evaluation callback's episodes against environment steps: each
    training seed's curve (thin) and, at the step counts every seed has, their mean with a 95 % bootstrap
    interval over seeds (:func:`leaderboard.stats.metrics.learning_curve_stats`). An entry and its ``+filter`` twin
    share one plot (the same training).

    Returns:
        The written PNG paths.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    plot_dir = Path(plot_dir)
    written: list[Path] = []
    seen: set[tuple[str, ...]] = set()
    for entry in entries:
        key = tuple(run.spec for run in entry.runs())
        if key in seen:
            continue
        seen.add(key)
        curves = entry_learning_curves(entry)
        if not curves:
            continue
        if len(curves) < len(entry.runs()):
            log.warning("%s: %d of %d training seeds have a learning curve", entry.name, len(curves), len(entry.runs()))
        plot_dir.mkdir(parents=True, exist_ok=True)
        fig, axes = plt.subplots(len(LEARNING_CURVE_PANELS), 1, figsize=(7.0, 6.0), sharex=True)
        for ax, (key_, metric, ylabel) in zip(axes, LEARNING_CURVE_PANELS, strict=True):
            scale = METRICS[metric].get("scale", 1.0)
            for k, curve in enumerate(curves):
                xs = [p["num_timesteps"] for p in curve if p.get(key_) is not None]
                ys = [p[key_] * scale for p in curve if p.get(key_) is not None]
                ax.plot(xs, ys, color="0.6", linewidth=0.8, alpha=0.6, label="each seed" if k == 0 else None)
            steps, stats = learning_curve_stats(curves, key_)
            kept = [(x, st) for x, st in zip(steps, stats, strict=True) if math.isfinite(st.mean)]
            if kept:
                xs = [x for x, _ in kept]
                ax.plot(xs, [st.mean * scale for _, st in kept], "o-", color="tab:blue", ms=3, label="mean over seeds")
                if len(curves) > 1:
                    ax.fill_between(
                        xs,
                        [st.interval()[0] * scale for _, st in kept],
                        [st.interval()[1] * scale for _, st in kept],
                        color="tab:blue",
                        alpha=0.2,
                        label="95 % bootstrap CI over seeds",
                    )
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
        axes[-1].set_xlabel("environment steps")
        fig.suptitle(
            f"{entry.name}: evaluation callback's episodes during training ({len(curves)} seed(s))", fontsize=10
        )
        fig.tight_layout()
        path = plot_dir / f"learning_curves_{entry.slug}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written
