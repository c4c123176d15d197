"""The paired difference of two rows over the same draws (``leaderboard.stats.paired``) and its verdict.

The figures are recomputed here with numpy from the per-draw outcomes: the point as the difference of the two
rates, the interval as a percentile bootstrap of the per-draw differences drawn as the hierarchical bootstrap draws
its columns (one training seed per draw: the draw resampling alone).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from leaderboard.stats.intervals import BOOTSTRAP_SEED, N_RESAMPLES, Stat, bootstrap_difference
from leaderboard.stats.metrics import run_matrix
from leaderboard.stats.paired import (
    AHEAD,
    BEHIND,
    NO_INTERVAL,
    NOT_SEPARATED,
    paired_difference,
    runs_by_training_seed,
    verdict,
)
from uvdms_gym.seeds import assign_draws, split_seeds

DRAWS = split_seeds("test", 30)


def _row(outcomes, runs: int = 1, contacts=None) -> list[list[dict]]:
    """One list of episodes per training seed: draw ``i`` (to seed ``i % runs``, as the leaderboard spreads them)."""
    outcome = dict(zip(DRAWS, outcomes))
    touched = dict(zip(DRAWS, contacts if contacts is not None else [0] * len(outcomes)))
    return [
        [
            {"seed": s, "success": bool(outcome[s]), "contacts": touched[s], "training_seed": k}
            for s in assign_draws(list(outcome), runs, k)
        ]
        for k in range(runs)
    ]


def test_all_successes_against_all_failures_are_ahead_and_the_reverse_behind():
    wins, losses = _row([1] * 30, runs=3), _row([0] * 30)
    ahead = paired_difference(losses, wins)
    assert (ahead.mean, ahead.low, ahead.high, ahead.n) == (1.0, 1.0, 1.0, 30)
    assert verdict(ahead) == AHEAD
    behind = paired_difference(wins, losses)
    assert (behind.mean, behind.low, behind.high) == (-1.0, -1.0, -1.0)
    assert verdict(behind) == BEHIND


def test_identical_rows_are_not_separated():
    outcomes = [i % 3 == 0 for i in range(30)]
    same = paired_difference(_row(outcomes), _row(outcomes, runs=3))
    assert (same.mean, same.low, same.high) == (0.0, 0.0, 0.0)
    assert verdict(same) == NOT_SEPARATED


def test_the_interval_is_the_bootstrap_of_the_per_draw_differences():
    rng = np.random.default_rng(7)
    reference = rng.random(30) < 0.5
    compared = reference.copy()
    compared[rng.choice(30, size=8, replace=False)] = True  # better on some draws, same on the rest
    diff = paired_difference(_row(reference), _row(compared, runs=3), seed=BOOTSTRAP_SEED)

    per_draw = (compared.astype(float) - reference.astype(float))[np.argsort(DRAWS)]  # columns: ascending seeds
    assert diff.mean == pytest.approx(compared.mean() - reference.mean())
    columns = np.random.default_rng(BOOTSTRAP_SEED).integers(0, 30, size=(N_RESAMPLES, 30))
    low, high = np.percentile(per_draw[columns].mean(axis=1), [2.5, 97.5])
    assert (diff.low, diff.high) == pytest.approx((min(low, diff.mean), max(high, diff.mean)))
    assert diff.n == 30


def test_pairing_narrows_the_interval_of_correlated_rows():
    rng = np.random.default_rng(3)
    reference = rng.random(30) < 0.5
    compared = reference.copy()
    compared[np.flatnonzero(~reference)[:4]] = True  # the same draws succeed, four more
    paired = paired_difference(_row(reference), _row(compared, runs=3))
    unpaired = bootstrap_difference(
        run_matrix(_row(reference), "contact_free_success"), run_matrix(_row(compared, runs=3), "contact_free_success")
    )
    assert paired.mean == pytest.approx(unpaired.mean) == pytest.approx(4 / 30)
    assert paired.high - paired.low < unpaired.high - unpaired.low
    assert verdict(paired) == AHEAD  # every per-draw difference is >= 0 and some are 1
    assert verdict(unpaired) == NOT_SEPARATED


def test_contacts_make_a_success_a_failure_and_only_common_draws_count():
    reference = _row([1] * 30)
    compared = _row([1] * 30, contacts=[1] * 10 + [0] * 20, runs=3)
    diff = paired_difference(reference, compared)
    assert diff.mean == pytest.approx(-10 / 30)
    assert verdict(diff) == BEHIND
    partial = [[ep for ep in run if ep["seed"] in DRAWS[:12]] for run in compared]
    assert paired_difference(reference, partial).n == 12
    assert paired_difference([], compared).n == 0
    assert verdict(paired_difference([], compared)) == NO_INTERVAL


def test_several_seeds_on_one_draw_are_resampled_within_it():
    reference = [[{"seed": s, "success": True, "contacts": 0} for s in DRAWS]]
    compared = [[{"seed": s, "success": k == 0, "contacts": 0, "training_seed": k} for s in DRAWS] for k in range(2)]
    diff = paired_difference(reference, compared)
    assert diff.mean == pytest.approx(-0.5) and diff.n == 60
    assert diff.low < -0.5 < diff.high  # the seeds' spread within each draw is in the interval


def test_runs_by_training_seed():
    episodes = [{"seed": 1, "training_seed": 2}, {"seed": 2, "training_seed": 0}, {"seed": 3, "training_seed": 2}]
    assert runs_by_training_seed(episodes) == [[episodes[1]], [episodes[0], episodes[2]]]
    single = [{"seed": 1}, {"seed": 2}]
    assert runs_by_training_seed(single) == [single]
    with pytest.raises(ValueError, match="two episodes"):
        paired_difference([single + single], [single])


@pytest.mark.parametrize(
    ("low", "high", "expected"),
    [
        (0.01, 0.5, AHEAD),
        (-0.5, -0.01, BEHIND),
        (-0.1, 0.0, NOT_SEPARATED),
        (0.0, 0.2, NOT_SEPARATED),
        (-0.2, 0.2, NOT_SEPARATED),
        (math.nan, math.nan, NO_INTERVAL),
    ],
)
def test_verdict_reads_the_interval(low, high, expected):
    assert verdict(Stat(0.0, low, high, 30)) == expected
