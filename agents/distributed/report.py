"""The summary of a sweep (:mod:`agents.distributed.sweep`).

Evaluation results of a run, ``sweep.json``/``sweep.csv``, the table.

A row per run holds :data:`SUMMARY_COLUMNS`: the run directory relative to ``--out``, seed, grid point (index
and values), status, steps, the evaluation results of :func:`evaluation_summary`, wall time, retries, the Ray node
that finished it, and the error of a failed run.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from uvdms_gym.utils.io import to_jsonable, write_json_atomic

SUMMARY_COLUMNS: tuple[str, ...] = (
    "run",
    "seed",
    "grid",
    "grid_point",
    "status",
    "num_timesteps",
    "final_eval_return",
    "best_eval_return",
    "final_eval_episode_length",
    "n_evaluations",
    "wall_time_s",
    "retries",
    "node",
    "error",
)
"""Columns of ``sweep.csv`` (and keys of each run in ``sweep.json``)."""


def evaluation_summary(run_dir: str | Path) -> dict[str, Any]:
    """Evaluation results of a run from its ``logs/seg<k>/evaluations.npz`` (all segments, in order).

    Returns:
        ``final_eval_return`` (mean return of the last evaluation), ``best_eval_return`` (best mean return of any
        evaluation), ``final_eval_episode_length`` (mean episode length of the last evaluation),
        ``n_evaluations``; ``None`` values when the run never evaluated. Returns are those of the evaluation
        callback, i.e. with the configuration's ``alive_bonus`` included.
    """
    files = sorted(Path(run_dir).glob("logs/seg*/evaluations.npz"), key=lambda p: int(p.parent.name[3:]))
    returns: list[float] = []
    lengths: list[float] = []
    for path in files:
        with np.load(path) as data:
            returns += [float(np.mean(r)) for r in data["results"]]
            lengths += [float(np.mean(n)) for n in data["ep_lengths"]]
    return {
        "final_eval_return": returns[-1] if returns else None,
        "best_eval_return": max(returns) if returns else None,
        "final_eval_episode_length": lengths[-1] if lengths else None,
        "n_evaluations": len(returns),
    }


def write_summary(out_dir: Path, header: Mapping[str, Any], rows: Sequence[Mapping[str, Any]]) -> None:
    """Write ``sweep.json`` (the sweep's arguments and every row) and ``sweep.csv`` (:data:`SUMMARY_COLUMNS`)."""
    write_json_atomic(out_dir / "sweep.json", to_jsonable({"sweep": dict(header), "runs": list(rows)}))
    with (out_dir / "sweep.csv").open("w", encoding="utf-8", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=SUMMARY_COLUMNS)
        writer.writeheader()
        for row in rows:
            values = {k: row.get(k) for k in SUMMARY_COLUMNS}
            values["grid_point"] = json.dumps(row.get("grid_point") or {}, sort_keys=True)
            writer.writerow({k: "" if v is None else v for k, v in values.items()})


def format_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """The summary as an aligned text table (one line per run)."""

    def fmt(value: Any, digits: int = 2) -> str:
        if value is None:
            return "-"
        return f"{value:.{digits}f}" if isinstance(value, float) else str(value)

    header = ["run", "seed", "grid", "status", "steps", "final_return", "best_return", "ep_len", "wall_s", "retries"]
    lines = [header] + [
        [
            str(r["run"]),
            str(r["seed"]),
            fmt(r.get("grid")),
            str(r["status"]),
            fmt(r.get("num_timesteps")),
            fmt(r.get("final_eval_return")),
            fmt(r.get("best_eval_return")),
            fmt(r.get("final_eval_episode_length"), 1),
            fmt(r.get("wall_time_s"), 1),
            str(r.get("retries", 0)),
        ]
        for r in rows
    ]
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(line, widths)).rstrip() for line in lines)
