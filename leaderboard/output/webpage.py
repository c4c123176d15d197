"""``index.html``: the leaderboard as one self-contained web page, made from the files of an output folder.

:func:`write_index_html` reads (:mod:`leaderboard.output.page_data`) what
:func:`leaderboard.output.report.write_outputs` wrote (``leaderboard.csv``, the rows and figures;
``entries/<entry>.json``, each entry's composition, seeds and training; ``leaderboard.md``, the command line and the
list of plots; ``plots/*.png``) and writes ``index.html`` beside them, so the page says exactly what ``leaderboard.csv``
says and can be made again for an existing folder (``uvdms leaderboard --page-only DIR``) without evaluating anything.
The page loads nothing: style sheet and script are inline (:mod:`~leaderboard.output.page_assets`), the plots are
``data:`` URIs (palette PNGs), and a Content-Security-Policy forbids every other source. It shows one ranked table per
track and task (each cell ``mean [low, high]``, the 95 % interval of the CSV; sortable by any column; filterable by
task, track, kind and safety filter) and a detail view per entry (composition, seeds, training budget and wall time
where recorded, learning curve).

Every text from the folder is HTML-escaped (:func:`html.escape`); the embedded plot data is JSON with ``<``, ``>``
and ``&`` escaped, so no value can close its ``<script>`` element.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from leaderboard.output.page_assets import CSS, JS
from leaderboard.output.page_data import PageData, plot_data_uri, read_page_data
from leaderboard.output.page_data import PageError as PageError  # re-exported: raised by write_index_html
from leaderboard.stats.metrics import GRASP_METRICS, METRICS, OVERLOAD_MARK, TABLE_METRICS, TIMING_METRICS
from leaderboard.suite.entries import FILTER_SUFFIX, slugify
from leaderboard.suite.entry_info import KINDS, entry_kind
from leaderboard.suite.tasks import TASKS, TRACKS

PAGE_NAME = "index.html"
"""The page's file name in the output folder (beside ``leaderboard.md``)."""
EXTRA_COLUMNS: tuple[tuple[str, str], ...] = (
    ("timing_episodes_overloaded", "Overloaded episodes"),
    ("timing_episodes_unknown_load", "Episodes without load record"),
    ("timing_load_1min_max", "Max 1-min load"),
    ("timing_machine", "Machine"),
    ("aggregation", "Aggregation"),
)
"""Columns of ``leaderboard.csv`` besides the metrics, shown with "all columns" (CSV name, header)."""
CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'"
"""The page's Content-Security-Policy: nothing but its own inline style, script and ``data:`` images."""


# ------------------------------------------------------------------------------------------------------
# Formatting
# ------------------------------------------------------------------------------------------------------
def esc(value: Any) -> str:
    """``value`` as text, escaped for HTML content and quoted attributes."""
    return html.escape("" if value is None else str(value), quote=True)


def _number(text: str | None) -> float | None:
    """A CSV cell as a finite number (``None``: empty or not a finite number)."""
    try:
        value = float(text) if text not in (None, "") else None
    except ValueError:
        return None
    return value if value is not None and math.isfinite(value) else None


def metric_cell_text(row: Mapping[str, str], metric: str) -> str:
    """A metric's cell: ``mean [low, high]`` in the tables' units and format (``—``: no value)."""
    spec = METRICS.get(metric, {"fmt": ".3g"})
    scale = spec.get("scale", 1.0)
    mean, low, high = (_number(row.get(f"{metric}_{part}")) for part in ("mean", "ci_low", "ci_high"))
    if mean is None:
        return "—"
    text = format(mean * scale, spec["fmt"])
    if low is not None and high is not None:
        text += f" [{format(low * scale, spec['fmt'])}, {format(high * scale, spec['fmt'])}]"
    return text


def _kind_text(document: Mapping[str, Any]) -> str:
    """The kind column: ``baseline``, ``learned``, ``residual on <base>`` or ``agent``, with ``+ safety filter``."""
    kind = entry_kind(document) if document else "agent"
    composition = document.get("composition") if isinstance(document.get("composition"), dict) else {}
    text = f"residual on {composition.get('residual_base')}" if kind == "residual" else kind
    return text + (" + safety filter" if composition.get("evaluated_with_filter") else "")


def _safety_filter(row: Mapping[str, str], document: Mapping[str, Any]) -> bool:
    """Whether the row's entry was evaluated with the safety filter (its composition, else its ``+filter`` name)."""
    composition = document.get("composition") if isinstance(document.get("composition"), dict) else None
    if composition is not None and "evaluated_with_filter" in composition:
        return bool(composition["evaluated_with_filter"])
    return FILTER_SUFFIX in row["entry"]


def _task_order(rows: Iterable[Mapping[str, str]]) -> list[str]:
    """The tasks of the rows in the suite's order (unknown tasks after, in order of appearance)."""
    present = list(dict.fromkeys(row["task"] for row in rows))
    known = [t.name for t in TASKS if t.name in present]
    return known + [t for t in present if t not in known]


def _task_label(name: str) -> str:
    return next((t.label for t in TASKS if t.name == name), name)


def _shown(task: str, rows: Iterable[Mapping[str, str]]) -> frozenset[str]:
    """The metrics ``task``'s table shows by default (the others only with "all columns").

    :data:`TABLE_METRICS` everywhere; also :data:`GRASP_METRICS` in the tables of the friction-grasp tasks: those of
    the suite (``Task.grasp``) and any whose rows (``rows``, the task's) have a value of one of them.
    """
    friction = any(t.grasp == "friction" for t in TASKS if t.name == task) or any(
        row.get(f"{m}_mean") for row in rows for m in GRASP_METRICS
    )
    return frozenset(TABLE_METRICS) | (frozenset(GRASP_METRICS) if friction else frozenset())


def _metrics(columns: Sequence[str]) -> list[str]:
    """The metrics of the CSV (those with a ``<metric>_mean`` column), in :data:`METRICS` order."""
    known = [m for m in METRICS if f"{m}_mean" in columns]
    others = [c.removesuffix("_mean") for c in columns if c.endswith("_mean") and c.removesuffix("_mean") not in known]
    return known + others


def _duration(seconds: Any) -> str:
    if not isinstance(seconds, int | float):
        return "not recorded"
    if seconds >= 3600:
        return f"{seconds:,.0f} s ({seconds / 3600:.1f} h)"
    return f"{seconds:,.0f} s ({seconds / 60:.1f} min)"


def _steps(value: Any) -> str:
    return f"{value:,}" if isinstance(value, int) and not isinstance(value, bool) else "not recorded"


# ------------------------------------------------------------------------------------------------------
# The tables
# ------------------------------------------------------------------------------------------------------
def _header(metrics: Sequence[str], shown: frozenset[str]) -> str:
    """The header row of a ranking table (``data-type``: how the column sorts; ``shown``: :func:`_shown`)."""
    cells = ['<th data-type="number">Rank</th>', '<th data-type="text">Entry</th>', '<th data-type="text">Kind</th>']
    for metric in metrics:
        label = METRICS.get(metric, {}).get("label", metric)
        extra = "" if metric in shown else ' class="extra"'
        cells.append(f'<th data-type="number" data-metric="{esc(metric)}"{extra}>{esc(label)}</th>')
    cells.append('<th data-type="number">n</th>')
    cells += [f'<th data-type="text" class="extra" data-column="{esc(c)}">{esc(h)}</th>' for c, h in EXTRA_COLUMNS]
    return "<tr>" + "".join(cells) + "</tr>"


def _metric_cell(row: Mapping[str, str], metric: str, shown: frozenset[str]) -> str:
    """One metric's ``<td>``: sorts by the CSV's mean, shows ``mean [low, high]``, exact bounds in its title."""
    mean, low, high = (row.get(f"{metric}_{p}", "") for p in ("mean", "ci_low", "ci_high"))
    text = metric_cell_text(row, metric)
    if metric in TIMING_METRICS and (_number(row.get("timing_episodes_overloaded")) or 0) > 0:
        text += f" {OVERLOAD_MARK}"
    classes = "num" + ("" if metric in shown else " extra") + (" empty" if not mean else "")
    title = f"{metric}: mean {mean or '-'}, 95 % CI [{low or '-'}, {high or '-'}] (leaderboard.csv)"
    attributes = f'class="{classes}" data-metric="{esc(metric)}" data-value="{esc(mean)}" title="{esc(title)}"'
    return f"<td {attributes}>{esc(text)}</td>"


def _deterministic(task: str) -> bool:
    return any(t.deterministic for t in TASKS if t.name == task)


def _episodes_text(row: Mapping[str, str]) -> str:
    """The ``n`` cell: episodes, or ``seeds × 1`` for a multi-seed row on a deterministic task."""
    seeds, episodes = _number(row.get("training_seeds")), _number(row.get("episodes"))
    if seeds and episodes is not None and _deterministic(row["task"]):
        return f"{seeds:g} × {episodes / seeds:g}"
    return row.get("episodes", "")


def _entry_label(row: Mapping[str, str]) -> str:
    seeds = row.get("training_seeds", "")
    return f"{row['entry']} ({seeds} seeds)" if seeds else row["entry"]


def _table_row(
    row: Mapping[str, str], document: Mapping[str, Any], metrics: Sequence[str], shown: frozenset[str]
) -> str:
    """One ``<tr>`` of a ranking table, with the attributes the filters read."""
    kind = entry_kind(document) if document else "agent"
    safety = "yes" if _safety_filter(row, document) else "no"
    rank = row["rank"] + ("=" if row.get("tied") == "1" else "")
    kind_text = _kind_text(document)
    cells = [
        f'<td class="num" data-value="{esc(row["rank"])}">{esc(rank)}</td>',
        f'<td class="entry" data-value="{esc(row["entry"])}"><button type="button" class="entry-link" '
        f'data-slug="{esc(slugify(row["entry"]))}">{esc(_entry_label(row))}</button></td>',
        f'<td class="kind" data-value="{esc(kind_text)}">{esc(kind_text)}</td>',
        *[_metric_cell(row, m, shown) for m in metrics],
        f'<td class="num" data-value="{esc(row["episodes"])}">{esc(_episodes_text(row))}</td>',
        *[f'<td class="extra" data-value="{esc(row.get(c))}">{esc(row.get(c))}</td>' for c, _h in EXTRA_COLUMNS],
    ]
    attributes = (
        f'data-entry="{esc(row["entry"])}" data-track="{esc(row["track"])}" data-task="{esc(row["task"])}" '
        f'data-kind="{esc(kind)}" data-safety-filter="{safety}"'
    )
    return f"<tr {attributes}>" + "".join(cells) + "</tr>"


def _board(track: str, task: str, rows: Sequence[Mapping[str, str]], data: PageData, metrics: Sequence[str]) -> str:
    """The section of one track and task: heading and ranking table (rows in the CSV's order, i.e. by rank)."""
    shown = _shown(task, rows)
    body = "\n".join(_table_row(row, data.documents.get(row["entry"], {}), metrics, shown) for row in rows)
    return (
        f'<section class="board" data-track="{esc(track)}" data-task="{esc(task)}">\n'
        f"<h2>{esc(track.capitalize())} track · {esc(_task_label(task))} <small>({esc(task)})</small></h2>\n"
        f'<div class="table-wrap"><table class="ranking">\n<thead>{_header(metrics, shown)}</thead>\n'
        f"<tbody>\n{body}\n</tbody></table></div>\n</section>"
    )


def _boards(data: PageData) -> str:
    """Every track's tables, one per task in the suite's order."""
    metrics = _metrics(data.columns)
    tracks = [t for t in TRACKS if any(r["track"] == t for r in data.rows)]
    tracks += [t for t in dict.fromkeys(r["track"] for r in data.rows) if t not in tracks]
    sections = []
    for track in tracks:
        for task in _task_order(data.rows):
            rows = [r for r in data.rows if r["track"] == track and r["task"] == task]
            if rows:
                sections.append(_board(track, task, rows, data, metrics))
    return "\n".join(sections)


# ------------------------------------------------------------------------------------------------------
# Controls, details, plots, the page
# ------------------------------------------------------------------------------------------------------
def _select(element_id: str, label: str, options: Sequence[tuple[str, str]]) -> str:
    items = '<option value="">all</option>' + "".join(f'<option value="{esc(v)}">{esc(t)}</option>' for v, t in options)
    return f'<label>{esc(label)}<select id="{esc(element_id)}">{items}</select></label>'


def _controls(data: PageData) -> str:
    """The filter bar: task, track, kind, safety filter, all columns, and the count of rows shown."""
    kinds = {entry_kind(d) if d else "agent" for d in data.documents.values()}
    tracks = list(dict.fromkeys(r["track"] for r in data.rows))
    return (
        '<nav id="controls">'
        + _select("filter-task", "Task", [(t, _task_label(t)) for t in _task_order(data.rows)])
        + _select("filter-track", "Track", [(t, t) for t in tracks])
        + _select("filter-kind", "Kind", [(k, k) for k in KINDS if k in kinds])
        + _select("filter-safety", "Safety filter", [("yes", "with"), ("no", "without")])
        + '<label><input type="checkbox" id="show-extra"> all columns of leaderboard.csv</label>'
        + '<span id="shown-count"></span></nav>'
    )


def _composition_items(document: Mapping[str, Any]) -> list[tuple[str, str]]:
    """``(term, text)`` of an entry's composition: base, residual, safety filter."""
    composition = document.get("composition") if isinstance(document.get("composition"), dict) else None
    if composition is None:
        return [("Composition", "not recorded")]
    with_filter = (
        "evaluated with the safety filter" if composition.get("evaluated_with_filter") else "evaluated without"
    )
    if "controller" in composition:
        return [("Base", f"the baseline controller {composition['controller']}"), ("Safety filter", with_filter)]
    base = composition.get("residual_base")
    base_text = (
        f"{base}: the policy's output, scaled by {composition.get('residual_scale')}, is added to its command (the "
        f"policy observes {composition.get('residual_observation')}, acts in the "
        f"{composition.get('residual_space')} space)"
        if base
        else "none: the policy's output is the command"
    )
    trained = "trained with it" if composition.get("trained_with_filter") else "trained without it"
    return [("Base", base_text), ("Safety filter", f"{with_filter}; {trained}"), *_observation_terms(composition)]


def _observation_terms(composition: Mapping[str, Any]) -> list[tuple[str, str]]:
    """``(term, text)`` of what a policy observes beyond the environment's observation: the filter, memory, features."""
    terms = []
    if composition.get("navigation_filter"):
        terms.append(("Navigation filter", "the policy observes the filter's estimate where the measured state was"))
    k, m = composition.get("frame_stack") or 1, composition.get("action_history") or 0
    if k > 1 or m:
        terms.append(("Memory", f"its last {k} observations and its own last {m} actions"))
    if composition.get("obstacle_features"):
        terms.append(
            ("Obstacle features", "each observed obstacle's nearest robot part, computed from the observation")
        )
    if composition.get("tracking_features"):
        terms.append(("Tracking features", "its tracking error now, magnified to the scale of success"))
    return terms


def _network_text(training: Sequence[Mapping[str, Any]]) -> str:
    """The policy network(s) of the training records (one text per distinct network)."""
    texts = []
    for record in training:
        if record.get("algo") or record.get("net_arch"):
            arch = json.dumps(record.get("net_arch")) if record.get("net_arch") is not None else "not recorded"
            texts.append(
                f"{record.get('policy') or 'policy'} trained with {record.get('algo') or 'an unrecorded algorithm'}, "
                f"layers {arch}, activation {record.get('activation_fn') or 'not recorded'}"
            )
    return "; ".join(dict.fromkeys(texts)) or "not recorded"


def _dl(items: Sequence[tuple[str, str]]) -> str:
    return "<dl>" + "".join(f"<dt>{esc(t)}</dt><dd>{esc(d)}</dd>" for t, d in items) + "</dl>"


def _training_table(document: Mapping[str, Any]) -> str:
    """Seeds and training records: one row per run (its seed folder and checksum from the document)."""
    details = document.get("details") or {}
    records = {r.get("training_seed"): r for r in details.get("training", [])}
    seeds = document.get("seeds") if isinstance(document.get("seeds"), list) else None
    runs = seeds or [{"training_seed": None, "folder": document.get("spec"), "checksum": document.get("checksum")}]
    header = ["Training seed", "Folder", "Checksum", "Budget (steps)", "Trained steps", "Model steps", "Wall time"]
    lines = []
    for run in runs:
        record = records.get(run.get("training_seed"), {})
        cells = [
            "single run" if run.get("training_seed") is None else run.get("training_seed"),
            run.get("folder"),
            (str(run.get("checksum") or "")[:12] + "…") if run.get("checksum") else "-",
            _steps(record.get("budget_timesteps")),
            _steps(record.get("trained_timesteps")),
            _steps(record.get("model_timesteps")),
            _duration(record.get("wall_time_s")),
        ]
        lines.append("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in cells) + "</tr>")
    head = "".join(f"<th>{esc(h)}</th>" for h in header)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(lines)}</tbody></table>"


def _results_table(document: Mapping[str, Any], rows: Sequence[Mapping[str, str]]) -> str:
    """The entry's rank and headline figures on each task (from ``leaderboard.csv``)."""
    head = "".join(f"<th>{esc(h)}</th>" for h in ("Track", "Task", "Rank", "Contact-free success", "RMSE pos (mm)"))
    lines = [
        "<tr>"
        + "".join(
            f"<td>{esc(c)}</td>"
            for c in (
                r["track"],
                _task_label(r["task"]),
                r["rank"] + ("=" if r.get("tied") == "1" else ""),
                metric_cell_text(r, "contact_free_success"),
                metric_cell_text(r, "rmse_pos"),
            )
        )
        + "</tr>"
        for r in rows
    ]
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(lines)}</tbody></table>"


def learning_curve_plot(name: str, data: PageData) -> str | None:
    """The learning-curve plot of an entry: its own, or that of an entry of the same agent (its ``+filter`` twin)."""
    own = f"plots/learning_curves_{slugify(name)}.png"
    if own in data.plots:
        return own
    document = data.documents.get(name) or {}
    if document.get("kind") != "agent":
        return None
    for other, doc in data.documents.items():
        same = doc.get("kind") == "agent" and (doc.get("spec"), doc.get("checksum")) == (
            document.get("spec"),
            document.get("checksum"),
        )
        plot = f"plots/learning_curves_{slugify(other)}.png"
        if same and plot in data.plots:
            return plot
    return None


def _identity_items(name: str, document: Mapping[str, Any], rows: Sequence[Mapping[str, str]]) -> list[tuple[str, str]]:
    """Kind, track, environment, folder and model files of an entry."""
    items = [("Kind", _kind_text(document)), ("Track", rows[0]["track"] if rows else "")]
    if document.get("kind") == "agent":
        files = "weights-only export" if document.get("weights_only") else "Stable-Baselines3 model archive"
        items += [
            ("Trained on", str(document.get("env_id"))),
            ("Folder", str(document.get("spec"))),
            ("Model files", f"{files}, checksum {document.get('checksum')}"),
        ]
    return items


def _detail(name: str, data: PageData) -> str:
    """The ``<template>`` of one entry's detail view."""
    document = data.documents.get(name) or {}
    rows = [r for r in data.rows if r["entry"] == name]
    details = document.get("details") or {}
    parts = [f'<div class="detail"><h2>{esc(name)}</h2>', _dl(_identity_items(name, document, rows))]
    if not document:
        parts.append(f"<p>No entries/{esc(slugify(name))}.json in this folder.</p>")
    composition = _composition_items(document)
    if document.get("kind") == "agent":
        training = details.get("training", [])
        composition.append(("Network", _network_text(training)))
        teachers = sorted({str(r["teacher"]) for r in training if r.get("teacher")})
        composition += [("Teacher", "; ".join(teachers))] if teachers else []
    parts += ["<h3>Composition</h3>", _dl(composition)]
    if document.get("kind") == "agent":
        parts += ["<h3>Seeds and training</h3>", _training_table(document)]
        source = document.get("details_source") or "training not recorded in the entry document"
        parts.append(f'<p class="note">Composition and training: {esc(source)}.</p>')
    parts += ["<h3>Results</h3>", _results_table(document, rows), "<h3>Learning curve</h3>"]
    plot = learning_curve_plot(name, data)
    if plot is None:
        parts.append("<p>No learning curve recorded for this entry.</p>")
    else:
        parts.append(f'<img data-plot="{esc(plot)}" alt="{esc("learning curve of " + name)}">')
    parts.append("</div>")
    return f'<template id="detail-{esc(slugify(name))}">' + "".join(parts) + "</template>"


CHECK_INTRO = (
    "The randomised tasks were also run on a second test set (test2: as many other draws of the same "
    "distributions). Contact-free success rate on each set, the difference test2 - test with its 95 % bootstrap "
    "interval, and a flag where that interval excludes 0 (the entry's figure does not hold on other draws; at 95 % "
    "about 1 cell in 20 is flagged by chance). Flagged rows first."
)


def _check_row(row: Mapping[str, str]) -> str:
    """One ``<tr>`` of the generalisation table (the CSV's ``check_*`` columns)."""
    test, test2, diff, low, high = (
        _number(row.get(f"check_{c}"))
        for c in ("test_mean", "test2_mean", "difference_mean", "difference_low", "difference_high")
    )
    interval = f" [{low:+.2f}, {high:+.2f}]" if low is not None and high is not None else ""
    flagged = row.get("check_flagged") == "1"
    cells = [
        esc(_task_label(row["task"])),
        esc(_entry_label(row)),
        "" if test is None else f"{test:.2f}",
        "" if test2 is None else f"{test2:.2f}",
        ("" if diff is None else f"{diff:+.2f}") + interval,
        "flagged" if flagged else "",
    ]
    attributes = f'data-entry="{esc(row["entry"])}" data-task="{esc(row["task"])}" data-flagged="{int(flagged)}"'
    return f"<tr {attributes}>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>"


def _check_section(data: PageData) -> str:
    """The generalisation check of every row that has one (none: no section)."""
    rows = [r for r in data.rows if r.get("check_flagged") in ("0", "1")]
    if not rows:
        return ""
    rows.sort(key=lambda r: (r.get("check_flagged") != "1", r["task"], r["entry"]))
    header = "".join(f"<th>{h}</th>" for h in ("Task", "Entry", "test", "test2", "test2 - test [95 % CI]", "Flag"))
    body = "\n".join(_check_row(r) for r in rows)
    return (
        f'<section id="generalization"><h2>Generalisation check</h2><p>{esc(CHECK_INTRO)}</p>'
        f'<div class="table-wrap"><table class="check"><thead><tr>{header}</tr></thead>'
        f"<tbody>\n{body}\n</tbody></table></div></section>"
    )


def _plots_section(data: PageData) -> str:
    """Every plot of the folder but the learning curves (those are in the detail views)."""
    plots = [p for p in data.plots if not Path(p).name.startswith("learning_curves_")]
    if not plots:
        return ""
    figures = "".join(
        f'<figure><div class="plot-wrap"><img data-plot="{esc(p)}" alt="{esc(Path(p).stem)}"></div>'
        f"<figcaption>{esc(Path(p).stem)}</figcaption></figure>"
        for p in plots
    )
    return f'<section id="plots"><h2>Plots</h2>{figures}</section>'


def _plot_json(data: PageData) -> str:
    """The embedded plots, ``{relative path: data URI}``, as JSON safe inside ``<script>``."""
    plots = {p: plot_data_uri(data.out_dir / p) for p in data.plots}
    text = json.dumps(plots, separators=(",", ":"))
    return text.replace("&", "\\u0026").replace("<", "\\u003c").replace(">", "\\u003e")


INTRO = (
    "One table per track and task, ranked as in leaderboard.md (contact-free success rate, then position RMSE; "
    "2= marks a tie). Each cell is the mean over episodes with its 95 % bootstrap confidence interval, "
    "mean [low, high], from leaderboard.csv, on the test draws of the seed protocol (100 draws of each randomised "
    "task; the paper tasks are deterministic: one episode per entry and training seed). For multi-seed entries "
    "(name (k seeds)) the draws are spread over the seeds, the mean is the interquartile mean (rates: the "
    "fraction) and the interval a hierarchical bootstrap: draws, then training seeds within each. "
    "Click a column header to sort (again to reverse), an entry to see its "
    "composition, seeds, training and learning curve. "
    f"{OVERLOAD_MARK}: timed with a load above the machine's core count in some episodes."
)


def render_page(data: PageData) -> str:
    """The HTML text of the page (see the module docstring)."""
    summary = "<summary>How this was generated</summary>"
    generated = f'<details class="generated">{summary}<p>{esc(data.generated)}</p></details>'
    templates = "\n".join(_detail(name, data) for name in data.documents)
    return "\n".join(
        [
            "<!DOCTYPE html>",
            '<html lang="en"><head><meta charset="utf-8">',
            f'<meta http-equiv="Content-Security-Policy" content="{esc(CSP)}">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            "<title>uvdms-gym leaderboard</title>",
            f"<style>{CSS}</style></head><body>",
            f"<header><h1>uvdms-gym leaderboard</h1><p>{esc(INTRO)}</p>{generated if data.generated else ''}</header>",
            _controls(data),
            f"<main>{_boards(data)}</main>",
            _check_section(data),
            _plots_section(data),
            '<div id="detail-overlay" hidden><div id="detail-box" role="dialog" aria-modal="true">'
            '<button type="button" id="detail-close">Close</button><div id="detail-body"></div></div></div>',
            templates,
            f'<script type="application/json" id="plot-data">{_plot_json(data)}</script>',
            f"<script>{JS}</script>",
            "</body></html>",
        ]
    )


def write_index_html(out_dir: str | Path, *, agents_dir: str | Path | None = None) -> Path:
    """Write ``index.html`` into a leaderboard output folder, from the files already there.

    Args:
        out_dir: The folder (``leaderboard.csv``, ``entries/``, ``leaderboard.md``, ``plots/``).
        agents_dir: See :func:`read_page_data` (details of entry documents that do not record them).

    Returns:
        The page's path.

    Raises:
        PageError: The folder is missing or its files are corrupt (the message names the file).
    """
    data = read_page_data(out_dir, agents_dir=agents_dir)
    path = data.out_dir / PAGE_NAME
    tmp = path.with_name(f".{PAGE_NAME}.tmp")
    tmp.write_text(render_page(data), encoding="utf-8")
    tmp.replace(path)
    return path
