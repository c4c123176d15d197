"""Draw the realism ladder from the committed leaderboard, and the navigation filter's error over one episode per level.

    python -m scripts.realism_ladder [--entries docs/leaderboard/entries] [--out docs/figures]

Writes:

* ``realism_ladder.png``: contact-free success and position RMSE against the realism level (0: the oracle task,
  1-3: the realism track's ``<task>-r<level>``) for each controller of the committed leaderboard that ran the track,
  one column per task, with the 95 % intervals of the success rate;
* ``realism_filter_error.png``: the navigation filter's position and heading error over one episode per level
  (``campc`` on a validation draw of random circles, ``hydro_randomization=0.3``), judged on ``true_state()``;

and prints the ladder as a markdown table (``docs/realism.md`` quotes it).
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path
from typing import Any

import numpy as np

from leaderboard.output.comparison import success_cell
from leaderboard.suite.tasks import REALISM_BASES, REALISM_LEVELS
from uvdms_gym.seeds import split_seeds

LOG = logging.getLogger("realism_ladder")
FILTER_EPISODE_STEPS = 300
"""Steps of the filter-error episode per level (12 s: the approach and most of a circle)."""
FILTER_SPLIT = "validation"
"""The split of the filter-error episode's draw (a development figure, not a ranked result)."""


def ladder(entries_dir: Path) -> dict[str, dict[str, list[dict[str, Any] | None]]]:
    """``{task: {entry: [stats at level 0, 1, 2, 3]}}`` for entries that ran the realism track.

    Each stats item holds ``contact_free_success`` (mean, low, high) and ``rmse_pos`` (mean); level 0 of
    ``campc-raw`` and ``campc-privileged`` is ``campc``'s (at ``realism=0`` they are ``campc``).
    """
    docs = {p.stem: json.loads(p.read_text(encoding="utf-8")) for p in sorted(entries_dir.glob("*.json"))}
    out: dict[str, dict[str, list[dict[str, Any] | None]]] = {}
    for base in REALISM_BASES:
        rows: dict[str, list[dict[str, Any] | None]] = {}
        for doc in docs.values():
            tasks = doc.get("tasks", {})
            if not any(f"{base}-r{level}" in tasks for level in REALISM_LEVELS):
                continue
            zero_source = docs.get("campc", {}) if doc.get("name") in ("campc-raw", "campc-privileged") else doc
            levels = [zero_source.get("tasks", {}).get(base)]
            levels += [tasks.get(f"{base}-r{level}") for level in REALISM_LEVELS]
            rows[doc["name"]] = [None if t is None else _cell(t) for t in levels]
        out[base] = rows
    return out


def _cell(task_doc: dict[str, Any]) -> dict[str, Any]:
    stats = task_doc["stats"]
    return {"success": stats["contact_free_success"], "rmse": stats["rmse_pos"]["mean"]}


def markdown(table: dict[str, dict[str, list[dict[str, Any] | None]]]) -> str:
    """The ladder as markdown: contact-free success [95 % interval] and RMSE (mm) per level."""
    lines = []
    for base, rows in table.items():
        lines += [f"**{base}**", "", "| entry | level 0 | level 1 | level 2 | level 3 |", "|---|---|---|---|---|"]
        for name, cells in rows.items():
            lines.append("| " + " | ".join([f"`{name}`", *(_fmt(c) for c in cells)]) + " |")
        lines.append("")
    return "\n".join(lines)


def _fmt(cell: dict[str, Any] | None) -> str:
    if cell is None:
        return ""
    s = cell["success"]
    return success_cell(s["mean"], s["low"], s["high"], cell["rmse"])


PLOTTED_BASELINES: tuple[str, ...] = ("campc", "campc-raw", "campc-privileged", "campc-nndi", "mpc")
"""The baselines the figure draws (the table has every entry); besides them, each task's best learned entry."""


def plotted(rows: dict[str, list[dict[str, Any] | None]]) -> dict[str, list[dict[str, Any] | None]]:
    """The rows the figure draws: :data:`PLOTTED_BASELINES` and the learned entry best at level 1 (then level 0)."""
    learned = {name: cells for name, cells in rows.items() if name not in PLOTTED_BASELINES and name != "hold"}

    def score(cells: list[dict[str, Any] | None]) -> tuple[float, float]:
        return tuple(c["success"]["mean"] if c is not None else -1.0 for c in (cells[1], cells[0]))  # type: ignore[return-value]

    best = max(learned, key=lambda name: score(learned[name]), default=None)
    keep = [name for name in rows if name in PLOTTED_BASELINES or name == best]
    return {name: rows[name] for name in keep}


def plot_ladder(table: dict[str, dict[str, list[dict[str, Any] | None]]], path: Path) -> Path:
    """Success and RMSE against the level, one column per task (the rows of :func:`plotted`)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    levels = np.arange(1 + len(REALISM_LEVELS))
    fig, axes = plt.subplots(2, len(table), figsize=(5 * len(table), 7), squeeze=False)
    for col, (base, rows) in enumerate(table.items()):
        top, bottom = axes[0, col], axes[1, col]
        for name, cells in plotted(rows).items():
            keep = [i for i, c in enumerate(cells) if c is not None]
            if not keep:
                continue
            mean = np.array([cells[i]["success"]["mean"] for i in keep])
            low = np.array(
                [
                    cells[i]["success"]["low"] if cells[i]["success"]["low"] is not None else m
                    for i, m in zip(keep, mean, strict=True)
                ]
            )
            high = np.array(
                [
                    cells[i]["success"]["high"] if cells[i]["success"]["high"] is not None else m
                    for i, m in zip(keep, mean, strict=True)
                ]
            )
            line = top.errorbar(levels[keep], mean, yerr=[mean - low, high - mean], marker="o", capsize=3, label=name)
            rmse = [cells[i]["rmse"] for i in keep]
            bottom.plot(levels[keep], np.array(rmse, dtype=float) * 1000, marker="o", color=line[0].get_color())
        top.set_title(base)
        top.set_ylim(-0.05, 1.05)
        top.set_ylabel("contact-free success")
        bottom.set_ylabel("position RMSE (mm)")
        bottom.set_yscale("log")
        for ax in (top, bottom):
            ax.set_xticks(levels)
            ax.set_xlabel("realism level")
            ax.grid(alpha=0.3)
        bottom.legend(*top.get_legend_handles_labels(), fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def filter_errors(steps: int = FILTER_EPISODE_STEPS) -> dict[int, dict[str, np.ndarray]]:
    """Per level: time, position error norm (m) and heading error (rad) of ``campc``'s filter over one episode."""
    import gymnasium as gym

    from baselines.controllers import make_baseline
    from uvdms_gym.physics.frames import wrap_angle

    seed = split_seeds(FILTER_SPLIT, 1)[0]
    out: dict[int, dict[str, np.ndarray]] = {}
    for level in REALISM_LEVELS:
        env = gym.make("uvdms/CircleTrack-v1", case="random", hydro_randomization=0.3, realism=level)
        controller = make_baseline("campc", env)
        obs, info = env.reset(seed=seed)
        controller.reset(seed)
        rows = []
        for _ in range(steps):
            action = controller.predict(obs, info)
            eta_hat = controller.nav.state()[0]
            truth = env.unwrapped.true_state()["eta"]
            rows.append((info["t"], np.linalg.norm(eta_hat[:3] - truth[:3]), abs(wrap_angle(eta_hat[5] - truth[5]))))
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        env.close()
        arr = np.array(rows)
        out[level] = {"t": arr[:, 0], "position": arr[:, 1], "heading": arr[:, 2]}
        LOG.info("level %d: filter position error median %.1f mm", level, 1000 * np.median(arr[:, 1]))
    return out


def plot_filter(errors: dict[int, dict[str, np.ndarray]], path: Path) -> Path:
    """The filter's position and heading error against time, one line per level."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, (pos, head) = plt.subplots(1, 2, figsize=(10, 3.5))
    for level, e in errors.items():
        pos.plot(e["t"], 1000 * e["position"], label=f"level {level}")
        head.plot(e["t"], np.degrees(e["heading"]), label=f"level {level}")
    pos.set_ylabel("position error (mm)")
    head.set_ylabel("heading error (deg)")
    for ax in (pos, head):
        ax.set_xlabel("t (s)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> None:
    """Command line: draw both figures and print the ladder table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--entries", default="docs/leaderboard/entries", help="committed entry documents")
    parser.add_argument("--out", default="docs/figures", help="folder of the figures")
    parser.add_argument("--no-filter", action="store_true", help="skip the filter-error episodes")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table = ladder(Path(args.entries))
    LOG.info("%s", plot_ladder(table, out / "realism_ladder.png"))
    if not args.no_filter:
        LOG.info("%s", plot_filter(filter_errors(), out / "realism_filter_error.png"))
    print(markdown(table))  # the command's output


if __name__ == "__main__":
    main()
