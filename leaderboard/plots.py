"""Leaderboard plots: bar charts with CI whiskers per track and metric, and minimum distance over time."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

from leaderboard.stats import METRICS
from leaderboard.tasks import TRACKS
from uvdms_gym.params import D1, D2

if TYPE_CHECKING:
    from leaderboard.runner import LeaderboardResult

PLOT_METRICS: tuple[str, ...] = ("contact_free_success", "rmse_pos", "min_distance", "contacts", "return")
"""The metrics with a bar chart."""


def write_plots(result: LeaderboardResult, plot_dir: str | Path) -> list[Path]:
    """Bar charts with CI whiskers per track and metric, and minimum distance over time on the circle tasks.

    Returns:
        The written PNG paths.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    plot_dir = Path(plot_dir)
    plot_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for track in TRACKS:
        rows = [r for r in result.rows if r.entry.track == track]
        if not rows:
            continue
        names = list(dict.fromkeys(r.entry.name for r in rows))
        tasks = [t for t in result.tasks if any(r.task is t for r in rows)]
        for metric in PLOT_METRICS:
            fig, ax = plt.subplots(figsize=(max(6.0, 1.2 * len(tasks) * max(1, len(names)) * 0.35 + 3), 4.0))
            width = 0.8 / max(1, len(names))
            plotted: list[float] = []
            for k, name in enumerate(names):
                xs, ys, lo, hi = [], [], [], []
                for i, task in enumerate(tasks):
                    row = next((r for r in rows if r.task is task and r.entry.name == name), None)
                    if row is None or not math.isfinite(row.stats[metric].mean):
                        continue
                    stat = row.stats[metric]
                    scale = METRICS[metric].get("scale", 1.0)
                    a, b = stat.interval()
                    xs.append(i - 0.4 + width * (k + 0.5))
                    ys.append(stat.mean * scale)
                    lo.append((stat.mean - a) * scale)
                    hi.append((b - stat.mean) * scale)
                if xs:
                    ax.bar(xs, ys, width, yerr=[lo, hi], capsize=3, label=name)
                    plotted.extend(ys)
            ax.set_xticks(range(len(tasks)), [t.label for t in tasks], rotation=15, ha="right")
            ax.set_ylabel(METRICS[metric]["label"])
            positive = [v for v in plotted if v > 0]
            if METRICS[metric].get("scale") and positive and max(positive) > 30 * min(positive):
                ax.set_yscale("log")  # errors spanning orders of magnitude (sub-mm MPC vs. cm agents)
            ax.set_title(f"{track} track: {METRICS[metric]['label']} (mean, 95 % bootstrap CI)")
            if metric == "min_distance":
                ax.axhline(D1, color="black", linestyle="--", linewidth=1, label="d1")
                ax.axhline(D2, color="0.4", linestyle=":", linewidth=1.2, label="d2")
            ax.legend(fontsize=7, ncol=2)
            ax.grid(axis="y", alpha=0.3)
            fig.tight_layout()
            path = plot_dir / f"{track}_{metric}.png"
            fig.savefig(path, dpi=110)
            plt.close(fig)
            written.append(path)
    for task in result.tasks:
        if not task.trajectory:
            continue
        curves = []
        for row in result.rows:
            if row.task is not task:
                continue
            traj = next((ep.get("trajectory") for ep in row.episodes if ep.get("trajectory")), None)
            if traj:
                curves.append((row.entry, traj))
        if not curves:
            continue
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
        fig.tight_layout()
        path = plot_dir / f"min_distance_{task.name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written
