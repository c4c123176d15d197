"""The generalisation check: an entry's contact-free success rate on the test draws against the test2 draws.

Flagged exactly when the 95 % interval of the difference ``test2 - test`` excludes 0; its figures are the
hierarchical bootstrap of each set and :func:`bootstrap_difference`, recomputed here from the episodes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from leaderboard.stats.generalization import CHECK_METRIC, GeneralizationCheck, generalization_check
from leaderboard.stats.intervals import BOOTSTRAP_SEED, Stat, bootstrap_difference, hierarchical_bootstrap_ci
from leaderboard.stats.metrics import run_matrix
from uvdms_gym.seeds import assign_draws, split_seeds


def _episodes(split: str, outcomes, runs: int = 1) -> list[list[dict]]:
    """One list of episodes per training seed: draw ``i`` of ``split`` (to seed ``i % runs``) with its outcome."""
    draws = split_seeds(split, len(outcomes))
    outcome = dict(zip(draws, outcomes))
    return [
        [
            {"seed": s, "contacts": 0, "success": bool(outcome[s]), "rmse_pos": 0.01}
            for s in assign_draws(draws, runs, k)
        ]
        for k in range(runs)
    ]


def _rate(n: int, rate: float, seed: int) -> np.ndarray:
    """``n`` 0/1 outcomes with exactly ``round(rate * n)`` ones, shuffled."""
    ones = round(rate * n)
    values = np.array([1] * ones + [0] * (n - ones))
    np.random.default_rng(seed).shuffle(values)
    return values


@pytest.mark.parametrize("runs", [1, 3])
def test_a_rate_of_0_9_on_test_and_0_3_on_test2_is_flagged(runs):
    check = generalization_check(
        _episodes("test", _rate(100, 0.9, 1), runs), _episodes("test2", _rate(100, 0.3, 2), runs)
    )
    assert check.metric == CHECK_METRIC == "contact_free_success"
    assert check.test.mean == pytest.approx(0.9) and check.test2.mean == pytest.approx(0.3)
    assert check.difference.mean == pytest.approx(-0.6) and check.difference.n == 100
    assert check.difference.high < 0 and check.flagged
    assert check.test.low < 0.9 < check.test.high and check.test2.low < 0.3 < check.test2.high


@pytest.mark.parametrize("runs", [1, 3])
def test_the_same_outcomes_on_both_sets_are_not_flagged(runs):
    outcomes = _rate(100, 0.6, 3)
    check = generalization_check(_episodes("test", outcomes, runs), _episodes("test2", outcomes, runs))
    assert check.test.mean == check.test2.mean == pytest.approx(0.6) and check.difference.mean == 0.0
    assert check.difference.low < 0 < check.difference.high and not check.flagged
    assert 0.1 < check.difference.half_width < 0.2  # about 1.96 * sqrt(2 * 0.24 / 100) = 0.136


def test_a_small_difference_is_not_flagged_and_the_flag_follows_the_interval():
    check = generalization_check(_episodes("test", _rate(100, 0.8, 4)), _episodes("test2", _rate(100, 0.75, 5)))
    assert check.difference.mean == pytest.approx(-0.05) and not check.flagged
    stat = Stat
    for low, high, flagged in ((0.01, 0.2, True), (-0.2, -0.01, True), (-0.1, 0.1, False), (0.0, 0.2, False)):
        assert GeneralizationCheck("m", stat(1, 1, 1, 2), stat(1, 1, 1, 2), stat(0.1, low, high, 2)).flagged is flagged
    no_interval = GeneralizationCheck("m", stat(1, 1, 1, 2), stat(0, 0, 0, 1), stat(-1, math.nan, math.nan, 1))
    assert not no_interval.flagged  # too few episodes to say


def test_the_figures_are_the_bootstraps_of_the_two_matrices():
    first, second = _episodes("test", _rate(40, 0.7, 6), 3), _episodes("test2", _rate(40, 0.5, 7), 3)
    check = generalization_check(first, second)
    a, b = run_matrix(first, CHECK_METRIC), run_matrix(second, CHECK_METRIC)
    assert a.shape == b.shape == (3, 40) and np.isfinite(a).sum() == 40  # each draw by one training seed
    assert check.test == hierarchical_bootstrap_ci(a, estimator="mean", seed=BOOTSTRAP_SEED)
    assert check.test2 == hierarchical_bootstrap_ci(b, estimator="mean", seed=BOOTSTRAP_SEED + 1)
    assert check.difference == bootstrap_difference(a, b, estimator="mean", seed=BOOTSTRAP_SEED + 2)
    # independently: one value per draw, so each side is the plain bootstrap over its draws
    va, vb = a.T[np.isfinite(a.T)], b.T[np.isfinite(b.T)]  # the one value of each column, in the draws' order
    ia = np.random.default_rng(BOOTSTRAP_SEED + 2).integers(0, 40, size=(9999, 40))
    ib = np.random.default_rng(BOOTSTRAP_SEED + 3).integers(0, 40, size=(9999, 40))
    differences = vb[ib].mean(axis=1) - va[ia].mean(axis=1)
    low, high = np.percentile(differences, [2.5, 97.5])
    point = vb.mean() - va.mean()
    assert (check.difference.low, check.difference.high) == pytest.approx(
        (min(low, point), max(high, point)), rel=1e-12, abs=1e-15
    )


def test_contacts_count_as_failures():
    first = [[{"seed": s, "contacts": 1, "success": True} for s in split_seeds("test", 20)]]
    second = [[{"seed": s, "contacts": 0, "success": True} for s in split_seeds("test2", 20)]]
    check = generalization_check(first, second)
    assert (check.test.mean, check.test2.mean, check.difference.mean) == (0.0, 1.0, 1.0) and check.flagged


def test_to_json():
    check = generalization_check(_episodes("test", _rate(30, 0.9, 8)), _episodes("test2", _rate(30, 0.2, 9)))
    document = check.to_json()
    assert document == {
        "metric": "contact_free_success",
        "test": check.test.to_json(),
        "test2": check.test2.to_json(),
        "difference": check.difference.to_json(),
        "flagged": True,
    }
