"""A paired comparison of two rows on the same task draws: the difference of a metric, its interval, its verdict.

Two rows of one task of the leaderboard are evaluated on the same draws (the evaluation seeds of the seed protocol),
so their difference is taken draw by draw: :func:`paired_difference` subtracts the reference's value on each draw
from the compared row's on the same draw and gives the mean of these differences with the leaderboard's
hierarchical bootstrap interval (:func:`leaderboard.stats.intervals.hierarchical_bootstrap_ci`; draws resampled with
their pairs, then training seeds within each draw). :func:`verdict` reads the interval: the compared row is
ahead of the reference when it excludes 0 above, behind when it excludes 0 below, not separated when it contains 0.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from leaderboard.stats.intervals import BOOTSTRAP_SEED, CONFIDENCE, N_RESAMPLES, Stat, hierarchical_bootstrap_ci
from leaderboard.stats.metrics import run_matrix

AHEAD, BEHIND, NOT_SEPARATED, NO_INTERVAL = "ahead", "behind", "not separated", "no interval"
"""The verdicts of :func:`verdict`."""


def runs_by_training_seed(episodes: Sequence[Mapping[str, Any]]) -> list[list[Mapping[str, Any]]]:
    """A row's episodes (as ``entries/<entry>.json`` records them) as one run per training seed.

    A multi-seed entry's episodes carry their ``training_seed``: one run per seed, ascending. Episodes without one
    (a single agent, a baseline) are one run.
    """
    runs: dict[int, list[Mapping[str, Any]]] = {}
    for episode in episodes:
        seed = episode.get("training_seed")
        runs.setdefault(-1 if seed is None else int(seed), []).append(episode)
    return [runs[seed] for seed in sorted(runs)]


def paired_difference(
    reference: Sequence[Sequence[Mapping[str, Any]]],
    compared: Sequence[Sequence[Mapping[str, Any]]],
    metric: str = "contact_free_success",
    *,
    confidence: float = CONFIDENCE,
    n_resamples: int = N_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Stat:
    """``compared - reference`` in ``metric``, paired draw by draw, with its hierarchical bootstrap interval.

    Both rows are given as runs (one list of episodes per training seed, :func:`runs_by_training_seed`); a draw is
    an evaluation seed (``episode["seed"]``). On each draw, every run of ``compared`` that evaluated it gives one
    difference: its value minus the reference's on that draw (the mean of the reference's runs there, when it has
    several). Draws that only one row evaluated, and episodes without a value of ``metric``, are left out.

    How the training seeds enter: the differences form a (training seed x draw) matrix, summarised as the mean of
    its cells, so for a rate the point estimate is the compared row's rate minus the reference's on the common
    draws (the leaderboard's rates are such means, :data:`leaderboard.stats.metrics.RATE_METRICS`). The interval is
    :func:`leaderboard.stats.intervals.hierarchical_bootstrap_ci` of that matrix: the draws are resampled with
    their pairs, then the training seeds within each draw. On a randomised task the leaderboard spreads the draws
    over the training seeds (one seed per draw), so each draw keeps its one difference and the spread between the
    seeds enters the interval as part of the draws' variance; where every seed evaluated every draw, the seeds are
    resampled within each draw. The reference's own seeds (if it has several) are averaged per draw, not
    resampled: it is the fixed side of the comparison.

    Returns:
        The :class:`leaderboard.stats.intervals.Stat` (``n``: the differences). No common draw: NaN everything; all
        differences equal (identical rows: all 0): the zero-width interval at that value. Reproducible from
        ``seed``.

    Raises:
        ValueError: A run with two episodes of the same draw.
    """
    matrix = run_matrix([*compared, *reference], metric)
    own, other = matrix[: len(compared)], matrix[len(compared) :]
    finite = np.isfinite(other)
    counts = finite.sum(axis=0)
    per_draw = np.where(finite, other, 0.0).sum(axis=0) / np.maximum(counts, 1)
    per_draw[counts == 0] = math.nan
    return hierarchical_bootstrap_ci(
        own - per_draw[np.newaxis, :], estimator="mean", confidence=confidence, n_resamples=n_resamples, seed=seed
    )


def verdict(difference: Stat) -> str:
    """Where the interval of ``difference`` lies with respect to 0.

    Returns:
        :data:`AHEAD` / :data:`BEHIND` when it excludes 0 above / below, :data:`NOT_SEPARATED` when it contains 0
        (bounds included), :data:`NO_INTERVAL` without a finite interval.
    """
    low, high = difference.low, difference.high
    if not (math.isfinite(low) and math.isfinite(high)):
        return NO_INTERVAL
    if low > 0.0:
        return AHEAD
    if high < 0.0:
        return BEHIND
    return NOT_SEPARATED
