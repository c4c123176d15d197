"""Leaderboard statistics and ranking: bootstrap intervals, ties, rates, the tables of the tracks."""

from __future__ import annotations

import math

import numpy as np
import pytest

import leaderboard as lb
import leaderboard.running.cache
import leaderboard.running.runner
from leaderboard.stats.intervals import Stat, bootstrap_ci, intervals_overlap
from leaderboard.stats.metrics import aggregate
from leaderboard.stats.ranking import RankedRow, rank_rows
from leaderboard.suite.entries import BASELINES
from tests.support.leaderboard_fakes import BASELINE_ENTRIES, TINY_TASKS, _run


# ------------------------------------------------------------------------------------------------------
# Statistics and ranking
# ------------------------------------------------------------------------------------------------------
def test_bootstrap_ci_contains_the_mean_and_is_reproducible():
    x = np.random.default_rng(0).normal(3.0, 1.0, 20)
    stat = bootstrap_ci(x)
    assert stat.n == 20 and stat.mean == pytest.approx(x.mean())
    assert stat.low < stat.mean < stat.high
    assert stat.high - stat.low < 2.0  # about 4 standard errors of 1/sqrt(20)
    assert bootstrap_ci(x) == stat
    rate = bootstrap_ci([1, 1, 0, 1, 0, 1, 1, 1])
    assert 0.0 <= rate.low <= rate.mean <= rate.high <= 1.0
    assert "±" in rate.format(".2f")


def test_bootstrap_ci_degenerate_samples():
    empty = bootstrap_ci([])
    assert empty.n == 0 and math.isnan(empty.mean) and empty.format() == "—"
    one = bootstrap_ci([0.3])
    assert one.mean == 0.3 and math.isnan(one.low) and one.interval() == (0.3, 0.3)
    assert one.format(".2f") == "0.30 (n=1)"
    same = bootstrap_ci([0.7, 0.7, 0.7])
    assert (same.low, same.mean, same.high) == (0.7, 0.7, 0.7) and same.format(".2f") == "0.70 ± 0.00"
    nan_dropped = bootstrap_ci([1.0, math.nan, 3.0])
    assert nan_dropped.n == 2 and nan_dropped.mean == 2.0
    assert nan_dropped.low <= 2.0 <= nan_dropped.high


def _row(name, cfs, rmse, n=5):
    entry = lb.Entry(name=name, kind="baseline", spec=name, track="velocity")
    stats = {
        "contact_free_success": Stat(cfs[0], cfs[1], cfs[2], n),
        "rmse_pos": Stat(rmse[0], rmse[1], rmse[2], n) if rmse else Stat(math.nan, math.nan, math.nan, 0),
    }
    return RankedRow(entry, TINY_TASKS[0], stats, [])


def test_ranking_contact_free_success_first_then_rmse():
    rows = [
        _row("accurate-but-colliding", (0.2, 0.0, 0.4), (0.01, 0.009, 0.011)),
        _row("safe", (1.0, 1.0, 1.0), (0.05, 0.04, 0.06)),
        _row("safe-and-accurate", (1.0, 1.0, 1.0), (0.02, 0.015, 0.025)),
    ]
    ranked = rank_rows(rows)
    assert [r.entry.name for r in ranked] == ["safe-and-accurate", "safe", "accurate-but-colliding"]
    assert [r.rank_label for r in ranked] == ["1", "2", "3"]


def test_a_privileged_reference_row_is_listed_after_the_ranked_rows_unranked():
    privileged = _row("campc-privileged", (1.0, 1.0, 1.0), (0.001, 0.0009, 0.0011))
    privileged.entry = lb.Entry(
        name="campc-privileged", kind="baseline", spec="campc-privileged", track="velocity", privileged=True
    )
    rows = [_row("safe", (1.0, 1.0, 1.0), (0.05, 0.04, 0.06)), privileged, _row("colliding", (0.2, 0.0, 0.4), None)]
    ranked = rank_rows(rows)
    assert [(r.entry.name, r.rank_label) for r in ranked] == [
        ("safe", "1"),
        ("colliding", "2"),
        ("campc-privileged", "ref"),
    ]


def test_ties_when_both_intervals_overlap_competition_ranking():
    rows = [
        _row("a", (1.0, 1.0, 1.0), (0.020, 0.015, 0.030)),
        _row("b", (1.0, 1.0, 1.0), (0.025, 0.018, 0.035)),  # RMSE overlaps a's: tie
        _row("c", (0.9, 0.7, 1.0), (0.028, 0.026, 0.032)),  # both intervals overlap a's: tie
        _row("d", (0.8, 0.6, 1.0), (0.100, 0.090, 0.110)),  # RMSE does not overlap a's: new group
        _row("e", (0.8, 0.6, 1.0), (0.105, 0.095, 0.115)),  # tied with d
        _row("f", (0.0, 0.0, 0.0), (0.010, 0.009, 0.011)),  # never succeeds without contact
        _row("g", (0.0, 0.0, 0.0), None),  # no RMSE: after f
    ]
    ranked = rank_rows(rows)
    assert [(r.entry.name, r.rank_label) for r in ranked] == [
        ("a", "1="),
        ("b", "1="),
        ("c", "1="),
        ("d", "4="),
        ("e", "4="),
        ("f", "6"),
        ("g", "7"),
    ]


def test_ties_are_judged_against_the_group_leader_not_chained():
    rows = [
        _row("a", (1.0, 1.0, 1.0), (0.020, 0.018, 0.022)),
        _row("b", (1.0, 1.0, 1.0), (0.023, 0.021, 0.025)),  # overlaps a
        _row("c", (1.0, 1.0, 1.0), (0.026, 0.024, 0.028)),  # overlaps b, not a: new group
    ]
    assert [r.rank_label for r in rank_rows(rows)] == ["1=", "1=", "3"]


def test_rmse_values_equal_at_printed_resolution_tie():
    rows = [
        _row("x", (1.0, 1.0, 1.0), (0.01000, 0.01000, 0.01000)),
        _row("y", (1.0, 1.0, 1.0), (0.01005, 0.01005, 0.01005)),  # 0.05 mm worse: below TIE_TOLERANCE
        _row("z", (1.0, 1.0, 1.0), (0.01030, 0.01030, 0.01030)),  # 0.3 mm worse
    ]
    assert [r.rank_label for r in rank_rows(rows)] == ["1=", "1=", "3"]


def test_intervals_overlap_rules():
    s = Stat
    assert intervals_overlap(s(1, 0, 2, 3), s(2.5, 2, 3, 3))  # touching closed intervals
    assert not intervals_overlap(s(1, 0, 1.9, 3), s(2.5, 2, 3, 3))
    assert intervals_overlap(s(1, math.nan, math.nan, 1), s(1, math.nan, math.nan, 1))
    assert not intervals_overlap(s(1, math.nan, math.nan, 1), s(2, math.nan, math.nan, 1))
    empty = s(math.nan, math.nan, math.nan, 0)
    assert intervals_overlap(empty, empty) and not intervals_overlap(empty, s(1, 1, 1, 2))


def test_rates_come_from_contacts_and_success():
    episodes = [
        {"contacts": 0, "success": True, "rmse_pos": 0.1},
        {"contacts": 2, "success": True, "rmse_pos": 0.2},
        {"contacts": 0, "success": False, "rmse_pos": None},
        {"contacts": 0, "success": True, "rmse_pos": 0.3},
    ]
    stats = aggregate(episodes)
    assert stats["contact_free"].mean == 0.75
    assert stats["contact_free_success"].mean == 0.5
    assert stats["success"].mean == 0.75
    assert stats["rmse_pos"].n == 3 and stats["rmse_pos"].mean == pytest.approx(0.2)
    assert stats["rmse_ori"].n == 0


def test_tracks_and_tables(tmp_path):
    result = _run(tmp_path, episodes=2)
    tables = lb.markdown_tables(result)
    assert "### Velocity track" in tables and "### Torque track" in tables
    velocity = tables.split("### Torque track")[0]
    assert "campc" in velocity and "campc-nndi" not in velocity and "±" in velocity
    csv_lines = (tmp_path / "out" / "leaderboard.csv").read_text().splitlines()
    assert len(csv_lines) == 1 + len(BASELINE_ENTRIES) * len(TINY_TASKS)
    assert all(r.entry.track == BASELINES[r.entry.name] for r in result.rows)
