"""Leaderboard outputs: markdown tables and document, CSV, one JSON per entry (plots: :mod:`.plots`)."""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import uvdms_gym
from leaderboard.output.plots import write_plots
from leaderboard.output.webpage import write_index_html
from leaderboard.stats.metrics import (  # (the table constants live in stats: the page, output.webpage, reads them too)
    GRASP_METRICS,
    METRICS,
    OVERLOAD_MARK,
    RATE_METRICS,
    TABLE_METRICS,
    TIMING_METRICS,
    timing_summary,
)
from leaderboard.stats.ranking import PRIVILEGED_RANK, RankedRow
from leaderboard.suite.entries import Entry
from leaderboard.suite.entry_info import entry_details
from leaderboard.suite.tasks import CHECK_SPLIT, COOP_OBSTACLE_DRAWS, REALISM_DRAWS, TRACKS, env_version
from uvdms_gym.seeds import PROTOCOL, protocol_record
from uvdms_gym.utils.io import write_json_atomic

if TYPE_CHECKING:
    from leaderboard.stats.result import LeaderboardResult


PRIVILEGED_MARK = "(privileged)"
PRIVILEGED_TEXT = (
    "reads the true state (`env.unwrapped.true_state()`) on the realism track: a reference row that shows what "
    "sensing alone costs, not a competitor (its actuation, delay and thrusters are real)."
)


def markdown_tables(
    result: LeaderboardResult, metrics: Sequence[str] = TABLE_METRICS, grasp_metrics: Sequence[str] = GRASP_METRICS
) -> str:
    """One markdown table per track (ranked within each task), with the columns ``metrics``.

    A track with a friction-grasp task (``Task.grasp``) also has the columns ``grasp_metrics`` (``—`` on the rows
    of the other tasks); the tables of a track without one are as they were before those columns existed.
    """
    lines: list[str] = []
    for track in TRACKS:
        rows = [r for r in result.rows if r.entry.track == track]
        if not rows:
            continue
        track_metrics = metrics
        if any(row.task.grasp == "friction" for row in rows):
            track_metrics = [*metrics, *(m for m in grasp_metrics if m not in metrics)]
        lines.append(f"### {track.capitalize()} track")
        lines.append("")
        header = ["Task", "Rank", "Entry", *[METRICS[m]["label"] for m in track_metrics], "n"]
        lines.append("| " + " | ".join(header) + " |")
        lines.append("|" + "|".join(["---"] * 3 + ["--:"] * (len(track_metrics) + 1)) + "|")
        marked = False
        for row in rows:
            label = row.entry.label + (f" {PRIVILEGED_MARK}" if row.entry.privileged else "")
            cells = [row.task.label, row.rank_label, label]
            for m in track_metrics:
                cell = row.stats[m].format(METRICS[m]["fmt"], METRICS[m].get("scale", 1.0))
                if m in TIMING_METRICS and row.timing["overloaded"]:
                    cell += f" {OVERLOAD_MARK}"
                    marked = True
                cells.append(cell)
            cells.append(episodes_label(row))
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
        if any(row.entry.privileged for row in rows):
            lines.append(f"{PRIVILEGED_MARK} {PRIVILEGED_TEXT}")
            lines.append("")
        if marked:
            lines.append(
                f"{OVERLOAD_MARK} timed with a 1-minute load average above the machine's core count in some of the "
                "row's episodes (other processes shared the CPU): the timing reads long."
            )
            lines.append("")
        versions = sorted({env_version(row.entry.task_spec(row.task)["env_id"]) for row in rows})
        if "return" in metrics and len(versions) > 1:
            lines.append(
                f"Returns are in the reward of the environment version each entry runs ({', '.join(versions)}: an "
                "agent runs the version it was trained on, baselines v0); v0 rewards are <= 0, v1 rewards >= 0 but "
                "for the contact penalty. The ranking does not use them."
            )
            lines.append("")
    return "\n".join(lines)


def episodes_label(row: RankedRow) -> str:
    """The ``n`` cell: the episode count, or ``seeds × 1`` for a multi-seed row on a deterministic task."""
    if not row.entry.multi_seed or not row.task.deterministic:
        return str(len(row.episodes))
    seeds = len(row.entry.members)
    return f"{seeds} × {len(row.episodes) / seeds:g}"


COOP_TEXT = (
    "The cooperative tasks (`coop`, `coop-random`, `coop-obstacles`) hold the object by friction "
    '(`grasp="friction"`, `uvdms_gym/envs/cooperative.py`): a disagreement between the hands squeezes or '
    "stretches it and, beyond the friction limit, slips it; a drop or a crush ends the episode as a failure. Their "
    "rows add *Max slip (mm)*, the largest movement of either hand's contact over the object in an episode, and "
    "*Drop rate*, the fraction of episodes that dropped it (`—` on the other tasks). `coop-obstacles` runs "
    f"{COOP_OBSTACLE_DRAWS} draws; the randomised cooperative tasks run no generalisation check."
)
"""The explanation that ``leaderboard.md`` carries when a run has a friction-grasp task."""

MULTI_SEED_TEXT = (
    "Rows of multi-seed entries (`name (k seeds)`) aggregate k training seeds: on a randomised task the draws are "
    "spread over the seeds (draw i to the seed i mod k, so `n` draws are `n` episodes), on a deterministic paper "
    "task every seed runs its one draw (`n` = k × 1). Rates are fractions of the row's episodes, every other "
    "metric is the interquartile mean (IQM, the mean of the middle 50 % of the values), each ± the half-width of "
    "a 95 % hierarchical bootstrap interval (percentile): a resample draws the task draws with replacement, then "
    "the training seeds within each drawn draw, so the interval covers what another set of draws shows, and on "
    "the paper tasks how the entry would score if trained again with other seeds."
)
"""The explanation that ``leaderboard.md`` carries when a row aggregates training seeds."""

CHECK_TEXT = (
    "The randomised tasks were run on a second test set too (`test2`: as many other draws of the same "
    "distributions). Each cell is the contact-free success rate on each set with the difference `test2 - test` "
    "and its 95 % bootstrap interval (each set resampled on its own, draws then training seeds); **flagged** "
    "where that interval excludes 0: the entry's figure does not hold on other draws. At 95 % a correct figure "
    "is flagged in about 1 of 20 cells by chance."
)
"""The explanation above the generalisation table of ``leaderboard.md``."""


def check_table(result: LeaderboardResult) -> str:
    """The generalisation check as a markdown table (empty without checks): flagged rows first."""
    rows = [r for r in result.rows if r.check is not None]
    if not rows:
        return ""
    lines = [
        "## Generalisation check",
        "",
        CHECK_TEXT,
        "",
        "| Task | Entry | test | test2 | test2 - test [95 % CI] | Flag |",
        "|---|---|--:|--:|--:|---|",
    ]
    for row in sorted(rows, key=lambda r: (not r.check.flagged, r.task.name, r.entry.name)):
        check = row.check
        diff = check.difference
        interval = f"[{diff.low:+.2f}, {diff.high:+.2f}]" if math.isfinite(diff.half_width) else ""
        lines.append(
            f"| {row.task.label} | {row.entry.label} | {check.test.mean:.2f} | {check.test2.mean:.2f} | "
            f"{diff.mean:+.2f} {interval} | {'**flagged**' if check.flagged else ''} |"
        )
    return "\n".join([*lines, ""])


def timing_text(result: LeaderboardResult) -> str:
    """One sentence: the machine(s) and the load under which the run's timings were taken."""
    summary = timing_summary([ep for row in result.rows for ep in row.episodes])
    run = result.timing or {}
    machines = ", ".join(summary["machines"]) or "unknown"
    n = sum(len(row.episodes) for row in result.rows)
    text = (
        f"Timings (`Ctrl ms`, `controller_ms_median`) were taken on {machines}; 1-minute load average "
        f"{run.get('load_1min_start')} at the start and {run.get('load_1min_end')} at the end of this run "
        f"(episodes from the cache or reused from an earlier output, `--reuse`, keep the record of the run that "
        f"computed them; {result.computed} were computed in this run), highest seen in an episode "
        f"{summary['load_1min_max']}; {summary['overloaded']} of {n} episodes ran with a load above the core count"
    )
    if summary["unknown"]:
        text += f", {summary['unknown']} without a load record"
    return text + f" (marked {OVERLOAD_MARK})."


def seeds_text(result: LeaderboardResult) -> str:
    """One sentence: the seed protocol, the split, the draws of the randomised tasks and the check's draws."""
    seeds = result.seeds
    if any(not task.deterministic for task in result.tasks):
        draws = (
            f"{len(seeds)} draw(s) of each randomised task (seeds {_span(seeds)}; the deterministic paper tasks "
            "run the first)"
        )
    else:
        draws = f"one draw of each deterministic paper task (seed {seeds[0]})"
    text = (
        f"Seed protocol `{PROTOCOL}` (`uvdms_gym/seeds.py`): the `{result.split}` split, {draws}, disjoint from every "
        "training seed" + (" and every validation seed" if result.split != "validation" else "")
    )
    if result.check_seeds:
        text += f"; the generalisation check's second test set `test2`: seeds {_span(result.check_seeds)}"
    return text + "."


def _span(seeds: Sequence[int]) -> str:
    return f"{seeds[0]}" if len(seeds) == 1 else f"{seeds[0]}–{seeds[-1]}"


def _markdown_document(result: LeaderboardResult, command: str | None, plot_files: Sequence[str]) -> str:
    task_lines = [
        f"- **{t.label}** (`{t.name}`): `{t.env_id}` with `{json.dumps(dict(t.env_kwargs))}`" for t in result.tasks
    ]
    parts = [
        "# uvdms-gym leaderboard",
        "",
        f"Generated by `{command or 'uvdms leaderboard'}` (uvdms-gym {uvdms_gym.__version__}). " + seeds_text(result),
        "",
        "Tasks:",
        "",
        *task_lines,
        "",
        "Each cell is the mean over episodes ± the half-width of its 95 % bootstrap confidence interval "
        "(`max(mean - low, high - mean)`; exact bounds in `leaderboard.csv`). Rates are fractions of episodes: "
        "*contact-free* = no physical contact, *contact-free success* = task success without contact. "
        "Ranking within each track and task: contact-free success rate (higher first), then position RMSE "
        "(lower first); an entry whose contact-free-success and RMSE intervals both overlap those of the "
        "first entry of the current group (RMSE intervals less than 0.1 mm apart count as overlapping) is tied "
        "with it (`2=`). Success: the episode ran to its time limit without contact and, on the circle tasks, "
        "with RMSE <= 30 mm; on transport, with the object at the goal at the end (`uvdms_gym/evaluation.py`). "
        "The paper's tasks have a fixed start and no randomisation: every seed gives the same episode, so they run "
        "one episode per entry and training seed (no interval for a single agent or baseline); the randomised "
        "tasks carry the spread. Agents run only on "
        "the tasks of the environment they were trained on. The realism track (tasks `*-r1`, `-r2`, `-r3`) runs the "
        "randomised tasks with sensing and actuation realism (`docs/realism.md`): every controller acts on "
        "measurements, late and noisy, through the thrusters and the action delay, and is judged on the truth; "
        f"it runs {REALISM_DRAWS} draws per task and no generalisation check.",
        "",
        *([COOP_TEXT, ""] if any(task.grasp == "friction" for task in result.tasks) else []),
        timing_text(result),
        "",
    ]
    if any(entry.multi_seed for entry in result.entries):
        parts += [MULTI_SEED_TEXT, ""]
    parts += [markdown_tables(result)]
    if any(row.check is not None for row in result.rows):
        parts += [check_table(result)]
    if plot_files:
        parts += ["## Plots", ""]
        parts += [f"![{Path(p).stem}]({p})" for p in plot_files]
        parts.append("")
    return "\n".join(parts)


def _csv_text(result: LeaderboardResult) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    header = ["track", "task", "rank", "tied", "entry", "kind", "episodes"]
    for metric in METRICS:
        header += [f"{metric}_mean", f"{metric}_ci_low", f"{metric}_ci_high"]
    header += ["timing_episodes_overloaded", "timing_episodes_unknown_load", "timing_load_1min_max", "timing_machine"]
    header += ["training_seeds", "aggregation", "split"]
    header += [f"check_{part}_{bound}" for part in ("test", "test2", "difference") for bound in ("mean", "low", "high")]
    header.append("check_flagged")
    writer.writerow(header)
    for row in result.rows:
        cells: list[Any] = [
            row.entry.track,
            row.task.name,
            PRIVILEGED_RANK if row.entry.privileged else row.rank,
            int(row.tied),
            row.entry.name,
            row.entry.kind,
            len(row.episodes),
        ]
        for metric in METRICS:
            stat = row.stats[metric]
            cells += [_number(v) for v in (stat.mean, stat.low, stat.high)]
        timing = row.timing
        load_max = timing["load_1min_max"]
        cells += [timing["overloaded"], timing["unknown"], "" if load_max is None else load_max]
        cells.append("; ".join(timing["machines"]))
        cells += [len(row.entry.members) if row.entry.multi_seed else "", _aggregation(row.entry), result.split]
        cells += _check_cells(row)
        writer.writerow(cells)
    return buffer.getvalue()


def _check_cells(row: RankedRow) -> list[Any]:
    """The CSV cells of a row's generalisation check (empty without one)."""
    if row.check is None:
        return [""] * 10
    stats = (row.check.test, row.check.test2, row.check.difference)
    return [_number(v) for stat in stats for v in (stat.mean, stat.low, stat.high)] + [int(row.check.flagged)]


def _number(value: float) -> str:
    return "" if not math.isfinite(value) else f"{value:.6g}"


def _aggregation(entry: Entry) -> str:
    """How a row's statistics were formed (CSV ``aggregation``): over episodes, or over draws then seeds."""
    return "seeds-iqm-hierarchical" if entry.multi_seed else "episodes-mean-bca"


def _task_document(row: RankedRow, split: str) -> dict[str, Any]:
    """One task of an entry document: its rank, statistics and episodes, and its generalisation check."""
    document = {
        "rank": PRIVILEGED_RANK if row.entry.privileged else row.rank,
        "tied": row.tied,
        "seed_protocol": protocol_record(split),
        "timing": row.timing,
        "stats": {m: s.to_json() for m, s in row.stats.items()},
        "episodes": _without_trajectories(row.episodes),
    }
    if row.check is not None:
        document["check"] = {**row.check.to_json(), "seed_protocol": protocol_record(CHECK_SPLIT)}
        document["check"]["episodes"] = _without_trajectories(row.check_episodes)
    return document


def _without_trajectories(episodes: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{k: v for k, v in ep.items() if k != "trajectory"} for ep in episodes]


def _entry_document(entry: Entry, rows: Sequence[RankedRow], split: str) -> dict[str, Any]:
    document = {
        "name": entry.name,
        "kind": entry.kind,
        "spec": entry.spec if entry.kind == "baseline" else Path(entry.spec).name,
        "track": entry.track,
        "env_id": entry.env_id,
        "checksum": entry.checksum,
        "weights_only": entry.weights_only,
        "package_version": uvdms_gym.__version__,
        **({"privileged": PRIVILEGED_TEXT} if entry.privileged else {}),
        **entry_details(entry),
        "tasks": {row.task.name: _task_document(row, split) for row in rows},
    }
    if entry.multi_seed:  # (absent otherwise: the documents of single agents and baselines keep their form)
        document["aggregation"] = {
            "rates": f"mean over the row's episodes ({', '.join(RATE_METRICS)})",
            "other_metrics": "interquartile mean (25 % trimmed mean) over the row's episodes",
            "interval": "95 % hierarchical bootstrap: task draws resampled, then training seeds within each draw",
        }
        document["seeds"] = [
            {"training_seed": m.training_seed, "folder": Path(m.spec).name, "checksum": m.checksum}
            for m in entry.members
        ]
    return document


def write_outputs(result: LeaderboardResult, *, command: str | None = None, plots: bool = True) -> None:
    """Write ``leaderboard.md``, ``leaderboard.csv``, ``entries/<entry>.json``, (optionally) the plots, ``index.html``.

    ``index.html`` (:func:`leaderboard.output.webpage.write_index_html`) is made from the other files, written first.
    """
    out = result.out_dir
    out.mkdir(parents=True, exist_ok=True)
    plot_files = write_plots(result, out / "plots") if plots else []
    rel = [str(Path(p).relative_to(out)) for p in plot_files]
    result.markdown = _markdown_document(result, command, rel)
    (out / "leaderboard.md").write_text(result.markdown, encoding="utf-8")
    (out / "leaderboard.csv").write_text(_csv_text(result), encoding="utf-8")
    entries_dir = out / "entries"
    entries_dir.mkdir(exist_ok=True)
    for entry in result.entries:
        rows = [r for r in result.rows if r.entry is entry]
        write_json_atomic(entries_dir / f"{entry.slug}.json", _entry_document(entry, rows, result.split), indent=None)
    write_index_html(out)
