"""Leaderboard statistics: means with bootstrap CIs and the ranking with ties (rules in :mod:`leaderboard`)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from leaderboard.entries import Entry
from leaderboard.tasks import Task

CONFIDENCE = 0.95
N_RESAMPLES = 9999
BOOTSTRAP_SEED = 20240926

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
}
"""Aggregated metrics (per-episode keys of ``run_episode`` plus the derived 0/1 indicators). Values are SI
(m, rad) everywhere but in the tables and plots, which multiply by ``scale`` (mm, degrees)."""
TIE_TOLERANCE: dict[str, float] = {"contact_free_success": 0.0, "rmse_pos": 1e-4}
"""Two intervals of a ranking metric closer than this count as overlapping (RMSE: 0.1 mm, the tables'
printed resolution; without it two deterministic controllers with zero-width intervals that print the same
value would be ranked apart)."""


@dataclass(frozen=True)
class Stat:
    """A mean with its bootstrap confidence interval (``low``/``high`` NaN when undefined)."""

    mean: float
    low: float
    high: float
    n: int

    @property
    def half_width(self) -> float:
        """``max(mean - low, high - mean)`` (NaN without an interval)."""
        return max(self.mean - self.low, self.high - self.mean)

    def interval(self) -> tuple[float, float]:
        """The interval used for tie decisions: the CI, or the point ``[mean, mean]`` without one."""
        if math.isfinite(self.low) and math.isfinite(self.high):
            return self.low, self.high
        return self.mean, self.mean

    def to_json(self) -> dict[str, Any]:
        """Plain dict (NaN as ``None``)."""
        return {k: _finite_or_none(getattr(self, k)) for k in ("mean", "low", "high")} | {"n": self.n}

    def format(self, fmt: str = ".3f", scale: float = 1.0) -> str:
        """``mean ± half-width`` times ``scale`` (``—`` without data, ``mean (n=1)`` without an interval)."""
        if self.n == 0 or not math.isfinite(self.mean):
            return "—"
        if not math.isfinite(self.half_width):
            return f"{self.mean * scale:{fmt}} (n={self.n})"
        return f"{self.mean * scale:{fmt}} ± {self.half_width * scale:{fmt}}"


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def bootstrap_ci(
    values: Sequence[float] | np.ndarray,
    *,
    confidence: float = CONFIDENCE,
    n_resamples: int = N_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Stat:
    """Mean and bootstrap CI of the mean of ``values`` (non-finite values are dropped).

    Degenerate samples: no value gives NaN everything; one value gives the mean with no interval (NaN
    bounds); all-equal values give the zero-width interval at that value. Otherwise ``scipy.stats.bootstrap``
    (BCa; the percentile method if BCa returns a non-finite bound), seeded, and the bounds are widened to
    contain the mean if numerical noise would leave it outside.
    """
    from scipy import stats

    x = np.asarray(values, dtype=float).ravel()
    x = x[np.isfinite(x)]
    n = int(x.size)
    if n == 0:
        return Stat(math.nan, math.nan, math.nan, 0)
    mean = float(x.mean())
    if n < 2:
        return Stat(mean, math.nan, math.nan, n)
    if np.all(x == x[0]):
        value = float(x[0])  # exactly the common value (the float mean may differ in the last bit)
        return Stat(value, value, value, n)
    low = high = math.nan
    for method in ("BCa", "percentile"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = stats.bootstrap(
                (x,),
                np.mean,
                confidence_level=confidence,
                n_resamples=n_resamples,
                method=method,
                rng=np.random.default_rng(seed),
            )
        low, high = float(res.confidence_interval.low), float(res.confidence_interval.high)
        if math.isfinite(low) and math.isfinite(high):
            break
    return Stat(mean, min(low, mean), max(high, mean), n)


def intervals_overlap(a: Stat, b: Stat, tolerance: float = 0.0) -> bool:
    """Closed-interval overlap of two statistics' CIs, up to a gap of ``tolerance``.

    See :meth:`Stat.interval` for a statistic without an interval; two statistics without data overlap.
    """
    if a.n == 0 or b.n == 0 or not (math.isfinite(a.mean) and math.isfinite(b.mean)):
        return (a.n == 0 or not math.isfinite(a.mean)) and (b.n == 0 or not math.isfinite(b.mean))
    (a_lo, a_hi), (b_lo, b_hi) = a.interval(), b.interval()
    return a_lo <= b_hi + tolerance and b_lo <= a_hi + tolerance


@dataclass
class RankedRow:
    """A (track, task, entry) cell of the leaderboard."""

    entry: Entry
    task: Task
    stats: dict[str, Stat]
    episodes: list[dict[str, Any]]
    rank: int = 0
    tied: bool = False

    @property
    def rank_label(self) -> str:
        """``3`` or ``3=`` for a tie."""
        return f"{self.rank}=" if self.tied else str(self.rank)

    @property
    def timing(self) -> dict[str, Any]:
        """Where and under what load this row's controller timings ran (:func:`timing_summary` of its episodes)."""
        return timing_summary(self.episodes)


def timing_summary(episodes: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Summary of the per-episode timing records (:func:`uvdms_gym.provenance.timing_record`).

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


def _sort_key(row: RankedRow) -> tuple[float, float, str]:
    cfs = row.stats["contact_free_success"].mean
    rmse = row.stats["rmse_pos"].mean
    return (
        -(cfs if math.isfinite(cfs) else -1.0),
        rmse if math.isfinite(rmse) else math.inf,
        row.entry.name,
    )


def rank_rows(rows: Sequence[RankedRow]) -> list[RankedRow]:
    """Rank one (track, task) group in place and return it sorted (rule in the module docstring)."""
    ordered = sorted(rows, key=_sort_key)
    leader: RankedRow | None = None
    group: list[RankedRow] = []
    for position, row in enumerate(ordered, start=1):
        if leader is not None and all(
            intervals_overlap(leader.stats[m], row.stats[m], TIE_TOLERANCE[m]) for m in _RANK_METRICS
        ):
            row.rank = leader.rank
            group.append(row)
        else:
            leader, group = row, [row]
            row.rank = position
        if len(group) > 1:
            for member in group:
                member.tied = True
    return ordered


_RANK_METRICS = ("contact_free_success", "rmse_pos")


def episode_indicators(result: Mapping[str, Any]) -> dict[str, float]:
    """The derived 0/1 indicators of one episode: ``contact_free`` and ``contact_free_success``."""
    contact_free = float((result.get("contacts") or 0) == 0)
    return {"contact_free": contact_free, "contact_free_success": float(bool(result.get("success")) and contact_free)}


def aggregate(results: Sequence[Mapping[str, Any]]) -> dict[str, Stat]:
    """Mean and bootstrap CI of every metric in :data:`METRICS` over the episodes ``results``."""
    out = {}
    for index, metric in enumerate(METRICS):
        values = []
        for result in results:
            value = episode_indicators(result)[metric] if metric in ("contact_free", "contact_free_success") else None
            if value is None:
                raw = result.get(metric)
                if raw is None or isinstance(raw, str):
                    continue
                value = float(raw)
            values.append(value)
        out[metric] = bootstrap_ci(values, seed=BOOTSTRAP_SEED + index)
    return out
