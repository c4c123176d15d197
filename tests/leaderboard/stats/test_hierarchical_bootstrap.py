"""The hierarchical bootstrap of a (training seed x task draw) matrix, and the bootstrap of a difference.

Checked against independent computations: a per-resample loop over the random draws the docstring of
:func:`leaderboard.stats.intervals.hierarchical_bootstrap_estimates` documents (``scipy.stats.trim_mean`` for the
IQM), the plain bootstrap over draws where the hierarchy collapses to it (one run per draw: the randomised tasks'
draws spread over training seeds; identical runs: no seed variance), the seeds alone where there is one draw (a
deterministic task), the binomial standard error of a rate, and the coverage of the interval over simulated data.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats as sps

from leaderboard.stats.intervals import (
    BOOTSTRAP_SEED,
    N_RESAMPLES,
    bootstrap_difference,
    hierarchical_bootstrap_ci,
    hierarchical_bootstrap_estimates,
)
from leaderboard.stats.metrics import METRICS, aggregate_runs, run_matrix
from uvdms_gym.seeds import assign_draws, split_seeds

FEW = 999
"""Bootstrap resamples in the cross-checks that loop over resamples in Python."""


def _loop_estimates(x: np.ndarray, statistic, seed: int, n_resamples: int) -> np.ndarray:
    """The documented draws, one resample and one drawn column at a time.

    ``rng = default_rng(seed)``; ``rng.integers(0, c, size=(n_resamples, c))`` picks the columns (draws),
    ``rng.random((n_resamples, c, k_max))`` the runs within each: position ``m < k`` of a drawn column with ``k``
    finite cells takes its cell ``int(u * k)``.
    """
    columns = [x[np.isfinite(x[:, j]), j] for j in range(x.shape[1])]
    columns = [c for c in columns if c.size]
    c, k_max = len(columns), max(col.size for col in columns)
    rng = np.random.default_rng(seed)
    drawn = rng.integers(0, c, size=(n_resamples, c))
    u = rng.random((n_resamples, c, k_max))
    estimates = np.empty(n_resamples)
    for b in range(n_resamples):
        values = []
        for position in range(c):
            column = columns[drawn[b, position]]
            for m in range(column.size):
                values.append(column[int(u[b, position, m] * column.size)])
        estimates[b] = statistic(np.array(values))
    return estimates


def _interval(estimates: np.ndarray, point: float) -> tuple[float, float]:
    low, high = np.percentile(estimates, [2.5, 97.5])
    return min(float(low), point), max(float(high), point)


def _statistic(estimator: str):
    return (lambda v: sps.trim_mean(v, 0.25)) if estimator == "iqm" else np.mean


def _spread(values: np.ndarray, runs: int) -> np.ndarray:
    """A randomised task's matrix: draw ``i`` evaluated by training seed ``i % runs`` only (NaN elsewhere)."""
    x = np.full((runs, values.size), math.nan)
    for run in range(runs):
        columns = assign_draws(list(range(values.size)), runs, run)
        x[run, columns] = values[columns]
    return x


# ------------------------------------------------------------------------------------------------------
# Against the documented draws
# ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("estimator", ["iqm", "mean"])
def test_estimates_and_interval_match_a_loop_over_the_documented_draws(estimator):
    x = np.random.default_rng(1).normal(0.05, 0.02, size=(3, 8))
    x[1, 2] = math.nan  # an episode without a value: its column resamples the other two runs
    x[:, 5] = math.nan  # a draw without any value: left out
    statistic = _statistic(estimator)
    point, estimates, n = hierarchical_bootstrap_estimates(x, estimator=estimator, n_resamples=FEW, seed=123)
    expected = _loop_estimates(x, statistic, 123, FEW)
    assert n == 20 and point == pytest.approx(statistic(x[np.isfinite(x)]), rel=1e-14)
    np.testing.assert_allclose(estimates, expected, rtol=1e-12)
    stat = hierarchical_bootstrap_ci(x, estimator=estimator, n_resamples=FEW, seed=123)
    assert stat.n == 20 and stat.estimator == estimator and stat.mean == point
    assert (stat.low, stat.high) == pytest.approx(_interval(expected, point), rel=1e-12)
    assert stat.low <= stat.mean <= stat.high


def test_a_spread_matrix_with_runs_of_unequal_size_matches_the_loop():
    """The randomised tasks' layout: one run per draw, 3 seeds, some episodes without an RMSE."""
    values = np.random.default_rng(4).gamma(2.0, 0.01, size=17)
    x = _spread(values, 3)
    x[2, 2] = math.nan
    _, estimates, n = hierarchical_bootstrap_estimates(x, n_resamples=FEW, seed=7)
    assert n == 16
    np.testing.assert_allclose(estimates, _loop_estimates(x, _statistic("iqm"), 7, FEW), rtol=1e-12)


def test_the_resampling_is_reproducible_from_its_seed():
    x = np.random.default_rng(5).normal(size=(3, 12))
    stat = hierarchical_bootstrap_ci(x, n_resamples=FEW, seed=11)
    assert hierarchical_bootstrap_ci(x, n_resamples=FEW, seed=11) == stat
    assert hierarchical_bootstrap_ci(x, n_resamples=FEW, seed=12) != stat
    _, first, _ = hierarchical_bootstrap_estimates(x, n_resamples=FEW, seed=11)
    _, again, _ = hierarchical_bootstrap_estimates(x, n_resamples=FEW, seed=11)
    assert np.array_equal(first, again)
    assert hierarchical_bootstrap_ci(x) == hierarchical_bootstrap_ci(x, n_resamples=N_RESAMPLES, seed=BOOTSTRAP_SEED)


# ------------------------------------------------------------------------------------------------------
# Where the hierarchy collapses: one run per draw, one draw, no seed variance
# ------------------------------------------------------------------------------------------------------
def test_one_run_per_draw_is_the_plain_bootstrap_over_draws():
    """A randomised task's draws spread over 3 training seeds: each column has one value to keep."""
    values = np.random.default_rng(6).normal(0.3, 0.1, size=30)
    x = _spread(values, 3)
    point, estimates, n = hierarchical_bootstrap_estimates(x, estimator="mean", n_resamples=FEW, seed=3)
    drawn = np.random.default_rng(3).integers(0, values.size, size=(FEW, values.size))
    np.testing.assert_allclose(estimates, values[drawn].mean(axis=1), rtol=1e-12)
    assert n == 30 and point == pytest.approx(values.mean(), rel=1e-14)


def test_a_hundred_fair_coin_draws_give_an_interval_of_about_0_1():
    """100 Bernoulli(0.5) draws (a rate over a randomised task's draws): 1.96 * sqrt(0.25 / 100) = 0.098."""
    values = np.array([1.0, 0.0] * 50)
    np.random.default_rng(8).shuffle(values)
    for x in (values[np.newaxis, :], _spread(values, 3)):  # one training seed, or three with the draws spread
        stat = hierarchical_bootstrap_ci(x, estimator="mean")
        assert stat.mean == 0.5 and stat.n == 100
        assert 0.085 <= stat.mean - stat.low <= 0.11 and 0.085 <= stat.high - stat.mean <= 0.11
        assert stat.half_width == pytest.approx(1.96 * math.sqrt(0.25 / 100), abs=0.012)


def test_one_draw_resamples_the_training_seeds_only():
    """A deterministic task: each training seed runs the one draw; the interval is the seeds' spread."""
    seeds = np.array([0.010, 0.020, 0.035])
    x = seeds[:, np.newaxis]
    point, estimates, n = hierarchical_bootstrap_estimates(x, estimator="mean", n_resamples=FEW, seed=5)
    assert n == 3 and point == pytest.approx(seeds.mean())
    possible = {round(float(np.mean(seeds[list(c)])), 12) for c in np.ndindex(3, 3, 3)}  # every resample of 3 seeds
    assert {round(float(e), 12) for e in estimates} <= possible
    assert len({round(float(e), 12) for e in estimates}) > 5  # and many of them
    stat = hierarchical_bootstrap_ci(x, estimator="mean")
    assert seeds.min() <= stat.low < stat.mean < stat.high <= seeds.max()
    repeated = np.repeat(x, 6, axis=1)  # the same draw six times (0.4.0's deterministic columns): the same seeds
    assert hierarchical_bootstrap_ci(repeated, estimator="mean").low >= seeds.min()


def test_identical_runs_give_the_plain_bootstrap_over_draws():
    """Fully crossed with zero seed variance: resampling seeds within a draw changes nothing."""
    draws = np.random.default_rng(9).normal(0.5, 0.2, size=25)
    x = np.tile(draws, (3, 1))
    for estimator in ("mean", "iqm"):
        _, estimates, n = hierarchical_bootstrap_estimates(x, estimator=estimator, n_resamples=FEW, seed=21)
        drawn = np.random.default_rng(21).integers(0, draws.size, size=(FEW, draws.size))
        plain = [_statistic(estimator)(np.repeat(draws[row], 3)) for row in drawn]
        np.testing.assert_allclose(estimates, plain, rtol=1e-12)
        assert n == 75
    stat = hierarchical_bootstrap_ci(x, estimator="mean")
    drawn = np.random.default_rng(BOOTSTRAP_SEED).integers(0, draws.size, size=(N_RESAMPLES, draws.size))
    plain = _interval(draws[drawn].mean(axis=1), float(draws.mean()))  # the percentile bootstrap over draws
    assert (stat.low, stat.mean, stat.high) == pytest.approx((plain[0], draws.mean(), plain[1]), rel=1e-12)
    single = hierarchical_bootstrap_ci(draws[np.newaxis, :], estimator="mean")  # one training seed: the same
    assert (single.low, single.mean, single.high) == pytest.approx((stat.low, stat.mean, stat.high), rel=1e-12)
    assert (single.n, stat.n) == (25, 75)


def test_seed_variance_widens_the_interval():
    draws = np.random.default_rng(10).normal(0.5, 0.05, size=20)
    same = np.tile(draws, (3, 1))
    offsets = np.array([[-0.2], [0.0], [0.2]])
    assert hierarchical_bootstrap_ci(same + offsets, estimator="mean").half_width > 1.5 * (
        hierarchical_bootstrap_ci(same, estimator="mean").half_width
    )


# ------------------------------------------------------------------------------------------------------
# Coverage, degenerate matrices
# ------------------------------------------------------------------------------------------------------
def test_the_interval_covers_the_rate_about_95_percent_of_the_time():
    rng = np.random.default_rng(12)
    rate, trials = 0.7, 300
    covered = 0
    for t in range(trials):
        values = (rng.random(100) < rate).astype(float)
        stat = hierarchical_bootstrap_ci(_spread(values, 3), estimator="mean", n_resamples=FEW, seed=t)
        covered += stat.low <= rate <= stat.high
    assert 0.90 <= covered / trials <= 0.985  # 95 % nominal; the percentile interval runs a little short at n=100


def test_degenerate_matrices():
    same = hierarchical_bootstrap_ci(np.full((3, 4), 0.02))
    assert (same.low, same.mean, same.high) == (0.02, 0.02, 0.02)
    one = hierarchical_bootstrap_ci([[0.5, math.nan], [math.nan, math.nan]])
    assert one.n == 1 and one.mean == 0.5 and math.isnan(one.low) and math.isnan(one.high)
    assert hierarchical_bootstrap_estimates([[0.5, math.nan]])[1].size == 0
    empty = hierarchical_bootstrap_ci(np.full((2, 2), math.nan))
    assert empty.n == 0 and math.isnan(empty.mean)
    with pytest.raises(ValueError, match="matrix"):
        hierarchical_bootstrap_ci([1.0, 2.0])
    with pytest.raises(ValueError, match="estimator"):
        hierarchical_bootstrap_ci([[1.0, 2.0]], estimator="median")
    rng = np.random.default_rng(3)
    for _ in range(20):  # skewed small samples: the interval always holds the point
        x = rng.exponential(size=(int(rng.integers(2, 5)), int(rng.integers(1, 6))))
        stat = hierarchical_bootstrap_ci(x, n_resamples=FEW)
        assert stat.low <= stat.mean <= stat.high


def test_aggregate_runs_of_a_spread_task_is_the_hierarchical_bootstrap_of_its_matrix():
    draws = split_seeds("test", 9)
    rng = np.random.default_rng(13)
    runs = [
        [{"seed": s, "rmse_pos": float(rng.uniform(0.01, 0.02)), "success": True, "contacts": 0} for s in mine]
        for mine in (assign_draws(draws, 3, run) for run in range(3))
    ]
    stats = aggregate_runs(runs)
    matrix = run_matrix(runs, "rmse_pos")
    assert matrix.shape == (3, 9) and np.isfinite(matrix).sum() == 9
    assert stats["rmse_pos"] == hierarchical_bootstrap_ci(
        matrix, estimator="iqm", seed=BOOTSTRAP_SEED + list(METRICS).index("rmse_pos")
    )
    assert stats["success"].mean == 1.0 and stats["success"].n == 9


# ------------------------------------------------------------------------------------------------------
# The difference of two independent matrices
# ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("estimator", ["mean", "iqm"])
def test_bootstrap_difference_matches_an_independent_computation(estimator):
    rng = np.random.default_rng(14)
    first = _spread(rng.normal(0.6, 0.2, size=12), 3)
    second = _spread(rng.normal(0.4, 0.2, size=12), 3)
    second[0, 0] = math.nan
    statistic = _statistic(estimator)
    diff = bootstrap_difference(first, second, estimator=estimator, n_resamples=FEW, seed=40)
    differences = _loop_estimates(second, statistic, 41, FEW) - _loop_estimates(first, statistic, 40, FEW)
    point = statistic(second[np.isfinite(second)]) - statistic(first[np.isfinite(first)])
    assert diff.mean == pytest.approx(point, rel=1e-12) and diff.n == 11 and diff.estimator == estimator
    assert (diff.low, diff.high) == pytest.approx(_interval(differences, point), rel=1e-9, abs=1e-12)
    assert bootstrap_difference(first, second, estimator=estimator, n_resamples=FEW, seed=40) == diff


def test_bootstrap_difference_without_two_values_on_a_side_has_no_interval():
    diff = bootstrap_difference([[0.5]], [[0.2, 0.4]])
    assert diff.mean == pytest.approx(-0.2) and diff.n == 1 and math.isnan(diff.low) and math.isnan(diff.high)
    equal = bootstrap_difference(np.full((1, 10), 0.3), np.full((1, 10), 0.3))
    assert (equal.low, equal.mean, equal.high) == (0.0, 0.0, 0.0)
