"""Point estimates with confidence intervals: the bootstrap mean, the interquartile mean and its hierarchical bootstrap.

A row of a single agent or a baseline gets :func:`bootstrap_ci` (BCa) of each metric; a row of a multi-seed entry
:func:`hierarchical_bootstrap_ci` of its (training seed x task draw) matrix: the draws resampled first, then the
training seeds within each draw; :func:`bootstrap_difference` compares two sets of draws (the generalisation check).
The rules: ``docs/leaderboard.md``, Statistics.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

CONFIDENCE = 0.95
N_RESAMPLES = 9999
BOOTSTRAP_SEED = 20240926
IQM_PROPORTION = 0.25
"""Fraction cut from each end of the sorted values for the interquartile mean (a 25 % trimmed mean)."""
ESTIMATORS: tuple[str, ...] = ("mean", "iqm")
"""Point estimates a :class:`Stat` can hold."""


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


def _nan_point(x: np.ndarray, estimator: str) -> np.ndarray:
    """The point estimate of each row of ``x`` (2-D; NaN cells are missing).

    The mean, or the IQM as ``scipy.stats.trim_mean(row, 0.25)`` of the row's finite cells (``int(0.25 n)`` cut from
    each end).
    """
    if estimator == "mean":
        return np.nanmean(x, axis=1)
    ordered = np.sort(x, axis=1)  # NaN last
    finite = np.isfinite(ordered)
    n = finite.sum(axis=1)
    cut = (n * IQM_PROPORTION).astype(int)
    sums = np.concatenate([np.zeros((x.shape[0], 1)), np.cumsum(np.where(finite, ordered, 0.0), axis=1)], axis=1)
    rows = np.arange(x.shape[0])
    return (sums[rows, n - cut] - sums[rows, cut]) / (n - 2 * cut)


def hierarchical_bootstrap_estimates(
    matrix: Sequence[Sequence[float]] | np.ndarray,
    *,
    estimator: str = "iqm",
    n_resamples: int = N_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> tuple[float, np.ndarray, int]:
    """The point estimate of a (training seed x task draw) matrix and its hierarchical bootstrap resamples.

    A resample draws the task draws (columns) first, as many as there are, with replacement; then, for each drawn
    column, as many of its runs (training seeds) as it has, with replacement, among them; and evaluates the
    estimator on the pooled values. The draws' variance (which circle, which hydrodynamics) is so in the
    interval, and the training seeds' within each draw: the interval covers what another set of draws shows
    (``docs/leaderboard.md``, Statistics). A column evaluated by one training seed (the randomised tasks spread
    their draws over the seeds) keeps that seed's value; a matrix with one column (a deterministic task) resamples
    the training seeds only.

    Non-finite cells are missing (an episode without an RMSE, a draw another seed evaluates): a column resamples
    its finite cells, a column without one is left out. Reproducible from ``seed``: ``rng =
    numpy.random.default_rng(seed)``, then ``rng.integers(0, c, size=(n_resamples, c))`` for the ``c`` columns and
    ``rng.random((n_resamples, c, k_max))`` for the runs within them.

    Returns:
        ``(point, estimates, n)``: the estimator of every finite cell, the ``n_resamples`` resampled estimates
        (empty with fewer than 2 finite cells) and the number of finite cells.

    Raises:
        ValueError: ``matrix`` is not 2-D, or an unknown ``estimator``.
    """
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
    x = np.asarray(matrix, dtype=float)
    if x.ndim != 2:
        raise ValueError(f"a hierarchical bootstrap needs a (runs, draws) matrix, got shape {x.shape}")
    finite = np.isfinite(x)
    pooled = x[finite]
    n = int(pooled.size)
    if n == 0:
        return math.nan, np.empty(0), 0
    point = float(_point(pooled[np.newaxis, :], estimator)[0])
    if n < 2:
        return point, np.empty(0), n
    columns = [x[finite[:, j], j] for j in range(x.shape[1]) if finite[:, j].any()]
    counts = np.array([c.size for c in columns])
    values = np.full((len(columns), int(counts.max())), math.nan)
    for j, column in enumerate(columns):
        values[j, : column.size] = column
    rng = np.random.default_rng(seed)
    drawn = rng.integers(0, len(columns), size=(n_resamples, len(columns)))
    k = counts[drawn]
    runs = (rng.random((n_resamples, len(columns), values.shape[1])) * k[..., np.newaxis]).astype(int)
    resampled = values[drawn[..., np.newaxis], runs]
    resampled[np.arange(values.shape[1]) >= k[..., np.newaxis]] = math.nan
    return point, _nan_point(resampled.reshape(n_resamples, -1), estimator), n


def _percentile_interval(estimates: np.ndarray, confidence: float) -> tuple[float, float]:
    tail = 100.0 * (1.0 - confidence) / 2.0
    low, high = (float(v) for v in np.percentile(estimates, [tail, 100.0 - tail]))
    return low, high


def hierarchical_bootstrap_ci(
    matrix: Sequence[Sequence[float]] | np.ndarray,
    *,
    estimator: str = "iqm",
    confidence: float = CONFIDENCE,
    n_resamples: int = N_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Stat:
    """Point estimate and hierarchical bootstrap CI (draws, then training seeds) of a (run x draw) score matrix.

    The resampling is :func:`hierarchical_bootstrap_estimates`; the interval is the percentile interval of the
    ``n_resamples`` estimates (``numpy.percentile``, linear interpolation), widened to contain the point estimate
    if it falls outside.

    Args:
        matrix: ``(runs, draws)``; rows are training seeds, columns task draws (evaluation seeds); NaN where a
            seed did not evaluate a draw.
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
    point, estimates, n = hierarchical_bootstrap_estimates(
        matrix, estimator=estimator, n_resamples=n_resamples, seed=seed
    )
    if n < 2:
        return Stat(point, math.nan, math.nan, n, estimator)
    pooled = np.asarray(matrix, dtype=float)
    pooled = pooled[np.isfinite(pooled)]
    if np.all(pooled == pooled[0]):
        value = float(pooled[0])
        return Stat(value, value, value, n, estimator)
    low, high = _percentile_interval(estimates, confidence)
    return Stat(point, min(low, point), max(high, point), n, estimator)


def bootstrap_difference(
    first: Sequence[Sequence[float]] | np.ndarray,
    second: Sequence[Sequence[float]] | np.ndarray,
    *,
    estimator: str = "mean",
    confidence: float = CONFIDENCE,
    n_resamples: int = N_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Stat:
    """``estimate(second) - estimate(first)`` of two independent (run x draw) matrices, with its bootstrap CI.

    Each matrix is resampled on its own (:func:`hierarchical_bootstrap_estimates`, seeds ``seed`` and ``seed + 1``);
    the interval is the percentile interval of the ``n_resamples`` differences of the resampled estimates, widened
    to contain the point difference. ``n`` is the smaller number of finite cells. Either side with fewer than 2
    finite cells: no interval.
    """
    point_a, est_a, n_a = hierarchical_bootstrap_estimates(
        first, estimator=estimator, n_resamples=n_resamples, seed=seed
    )
    point_b, est_b, n_b = hierarchical_bootstrap_estimates(
        second, estimator=estimator, n_resamples=n_resamples, seed=seed + 1
    )
    point, n = point_b - point_a, min(n_a, n_b)
    if est_a.size == 0 or est_b.size == 0:
        return Stat(point, math.nan, math.nan, n, estimator)
    low, high = _percentile_interval(est_b - est_a, confidence)
    return Stat(point, min(low, point), max(high, point), n, estimator)
