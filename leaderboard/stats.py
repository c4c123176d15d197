"""Leaderboard statistics: means with bootstrap CIs, multi-seed IQMs with stratified bootstrap CIs, and the ranking.

Rules in :mod:`leaderboard`. A row of a single agent or a baseline aggregates its episodes (:func:`aggregate`,
:func:`bootstrap_ci`); a row of a multi-seed entry aggregates its (training seed x evaluation episode) matrix
(:func:`aggregate_runs`, :func:`stratified_bootstrap_ci`, the method of Agarwal et al., NeurIPS 2021, as in their
``rliable`` library); :func:`learning_curve_stats` summarises learning curves over training seeds.
"""

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
IQM_PROPORTION = 0.25
"""Fraction cut from each end of the sorted values for the interquartile mean (a 25 % trimmed mean)."""
RATE_METRICS: tuple[str, ...] = ("contact_free_success", "success", "contact_free")
"""The 0/1 indicators: a multi-seed row reports their rate (the mean), not an IQM (see :func:`aggregate_runs`)."""
ESTIMATORS: tuple[str, ...] = ("mean", "iqm")
"""Point estimates a :class:`Stat` can hold."""

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
TIE_TOLERANCE: dict[str, float] = {"contact_free_success": 0.0, "rmse_pos": 1e-4}
"""Two intervals of a ranking metric closer than this count as overlapping (RMSE: 0.1 mm, the tables'
printed resolution; without it two deterministic controllers with zero-width intervals that print the same
value would be ranked apart)."""


@dataclass(frozen=True)
class Stat:
    """A point estimate with its bootstrap confidence interval (``low``/``high`` NaN when undefined).

    Attributes:
        mean: The point estimate: the mean, or the interquartile mean where ``estimator`` is ``"iqm"``.
        low: Lower bound of the interval.
        high: Upper bound of the interval.
        n: Number of values.
        estimator: ``"mean"`` or ``"iqm"`` (:data:`ESTIMATORS`).
    """

    mean: float
    low: float
    high: float
    n: int
    estimator: str = "mean"

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
        """Plain dict (NaN as ``None``; ``estimator`` only when it is not the mean, so mean rows keep their form)."""
        out = {k: _finite_or_none(getattr(self, k)) for k in ("mean", "low", "high")} | {"n": self.n}
        if self.estimator != "mean":
            out["estimator"] = self.estimator
        return out

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


def iqm(values: Sequence[float] | np.ndarray) -> float:
    """Interquartile mean of the finite ``values`` (pooled over every axis): ``scipy.stats.trim_mean(x, 0.25)``.

    NaN without a finite value.
    """
    from scipy import stats

    x = np.asarray(values, dtype=float).ravel()
    x = x[np.isfinite(x)]
    return float(stats.trim_mean(x, IQM_PROPORTION)) if x.size else math.nan


def _point(x: np.ndarray, estimator: str) -> np.ndarray:
    """The point estimate of each row of ``x`` (2-D, finite)."""
    from scipy import stats

    if estimator == "iqm":
        return np.asarray(stats.trim_mean(x, IQM_PROPORTION, axis=1), dtype=float)
    return x.mean(axis=1)


def stratified_bootstrap_ci(
    matrix: Sequence[Sequence[float]] | np.ndarray,
    *,
    estimator: str = "iqm",
    confidence: float = CONFIDENCE,
    n_resamples: int = N_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Stat:
    """Point estimate and stratified bootstrap CI of a (training seed x evaluation episode) score matrix.

    The scheme of ``rliable.library.StratifiedBootstrap`` (Agarwal et al., NeurIPS 2021) with the evaluation
    episodes as the strata (rliable's tasks): every resample draws, for each evaluation episode (column)
    independently, as many runs as the column has, with replacement, from that column's runs, and evaluates the
    estimator on the pooled resampled values; the interval is the percentile interval of the ``n_resamples``
    estimates (``numpy.percentile``, linear interpolation), widened to contain the point estimate if it falls
    outside. Why this scheme: :mod:`leaderboard`, Statistics.

    Non-finite cells are missing values (an episode without an RMSE): a column resamples its finite cells only, a
    column without one is left out. Random draws, reproducible from ``seed``: ``rng =
    numpy.random.default_rng(seed)``, then for each remaining column in order, with ``k`` finite cells, one
    ``rng.integers(0, k, size=(n_resamples, k))``.

    Args:
        matrix: ``(runs, episodes)``; rows are training seeds, columns evaluation episodes (the same evaluation
            seed in every row).
        estimator: ``"iqm"`` (:func:`iqm` of the pooled values) or ``"mean"``.
        confidence: Coverage of the interval.
        n_resamples: Bootstrap resamples.
        seed: Seed of the resampling.

    Returns:
        The :class:`Stat` (``n``: finite cells). No finite cell: NaN everything; one: no interval; all equal: the
        zero-width interval at that value.

    Raises:
        ValueError: ``matrix`` is not 2-D, or an unknown ``estimator``.
    """
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
    x = np.asarray(matrix, dtype=float)
    if x.ndim != 2:
        raise ValueError(f"a stratified bootstrap needs a (runs, episodes) matrix, got shape {x.shape}")
    finite = np.isfinite(x)
    pooled = x[finite]
    n = int(pooled.size)
    if n == 0:
        return Stat(math.nan, math.nan, math.nan, 0, estimator)
    point = float(_point(pooled[np.newaxis, :], estimator)[0])
    if n < 2:
        return Stat(point, math.nan, math.nan, n, estimator)
    if np.all(pooled == pooled[0]):
        value = float(pooled[0])
        return Stat(value, value, value, n, estimator)
    rng = np.random.default_rng(seed)
    resampled = np.empty((n_resamples, n))
    start = 0
    for j in range(x.shape[1]):
        column = x[finite[:, j], j]
        k = column.size
        if k == 0:
            continue
        resampled[:, start : start + k] = column[rng.integers(0, k, size=(n_resamples, k))]
        start += k
    estimates = _point(resampled, estimator)
    tail = 100.0 * (1.0 - confidence) / 2.0
    low, high = (float(v) for v in np.percentile(estimates, [tail, 100.0 - tail]))
    return Stat(point, min(low, point), max(high, point), n, estimator)


def run_matrix(runs: Sequence[Sequence[Mapping[str, Any]]], metric: str) -> np.ndarray:
    """The ``(runs, episodes)`` matrix of ``metric``: one row per run, one column per evaluation seed.

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
    (:func:`iqm`). Both with :func:`stratified_bootstrap_ci` (seed ``BOOTSTRAP_SEED + metric index``, as
    :func:`aggregate`).

    Args:
        runs: One list of per-episode results per training seed (the same evaluation seeds in each).

    Raises:
        ValueError: No runs.
    """
    if not runs:
        raise ValueError("aggregate_runs needs at least one run")
    out = {}
    for index, metric in enumerate(METRICS):
        estimator = "mean" if metric in RATE_METRICS else "iqm"
        out[metric] = stratified_bootstrap_ci(
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
