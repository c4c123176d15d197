"""Multi-seed entries: IQM and stratified bootstrap CIs, the seed-folder layout, one row per entry, learning curves.

The statistics are checked against independent computations (``scipy.stats.trim_mean``, a sort-and-slice IQM, a
per-resample loop with the same random draws, and rliable's ``StratifiedBootstrap.update_indices`` transcribed:
``rliable`` itself does not import with the pinned pandas 3, see ``CHANGELOG.md``). The committed leaderboard
(``docs/leaderboard``) is recomputed from its own episodes to show that single-seed rows are unchanged.
"""

from __future__ import annotations

import csv
import json
import logging
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats as sps

import leaderboard as lb
from leaderboard.output.plots import write_learning_curves
from leaderboard.stats.intervals import Stat, bootstrap_ci, iqm, stratified_bootstrap_ci
from leaderboard.stats.metrics import aggregate, aggregate_runs, learning_curve_stats, run_matrix
from leaderboard.stats.ranking import RankedRow, rank_rows
from leaderboard.stats.result import LeaderboardResult
from leaderboard.suite.entries import agent_entry, check_seed_disjointness, find_agent_folders
from leaderboard.suite.tasks import SEED_BASE, TRACKS, evaluation_seeds
from tests.support.multiseed_fakes import (
    CALLS,
    CIRCLE,
    FAKE,
    TINY_TASKS,
    _agent_folder,
    _multi_seed,
    _write_curve,
)

REPO = Path(__file__).resolve().parents[3]
TRANSPORT = "uvdms/Transport-v0"
FEW = 999
"""Bootstrap resamples in the cross-checks that loop over resamples in Python."""


# ------------------------------------------------------------------------------------------------------
# IQM
# ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("shape", [(3, 10), (4, 7), (5, 1), (2, 2), (3, 20)])
def test_iqm_is_the_pooled_25_percent_trimmed_mean(shape):
    x = np.random.default_rng(sum(shape)).lognormal(size=shape)
    assert iqm(x) == pytest.approx(sps.trim_mean(x, 0.25, axis=None), rel=1e-14)
    pooled = np.sort(x.ravel())
    cut = int(0.25 * pooled.size)  # scipy's rule: int(proportion * n) values off each end
    assert iqm(x) == pytest.approx(pooled[cut : pooled.size - cut].mean(), rel=1e-14)


def test_iqm_ignores_outliers_and_missing_values():
    x = np.array([[1.0, 2.0, 3.0, 4.0], [5.0, 6.0, 7.0, 8.0]])
    assert iqm(x) == 4.5  # the middle four of eight
    spoiled = x.copy()
    spoiled[0, 0], spoiled[1, 3] = -1e9, 1e9  # a diverged episode at each end
    assert iqm(spoiled) == 4.5 and spoiled.mean() != 4.5
    with_nan = np.array([[1.0, math.nan], [2.0, 3.0]])
    assert iqm(with_nan) == sps.trim_mean([1.0, 2.0, 3.0], 0.25)
    assert math.isnan(iqm([]))


# ------------------------------------------------------------------------------------------------------
# Stratified bootstrap
# ------------------------------------------------------------------------------------------------------
def _loop_resampling(x: np.ndarray, statistic, seed: int, n_resamples: int) -> tuple[float, float]:
    """The documented draws, one resample at a time: an explicit resampled matrix per resample."""
    rng = np.random.default_rng(seed)
    columns = [x[np.isfinite(x[:, j]), j] for j in range(x.shape[1])]
    columns = [c for c in columns if c.size]
    draws = [rng.integers(0, c.size, size=(n_resamples, c.size)) for c in columns]
    estimates = []
    for b in range(n_resamples):
        resampled = [c[d[b]] for c, d in zip(columns, draws, strict=True)]
        estimates.append(statistic(np.concatenate(resampled)))
    low, high = np.percentile(estimates, [2.5, 97.5])
    return float(low), float(high)


@pytest.mark.parametrize("estimator", ["iqm", "mean"])
def test_interval_matches_an_independent_resampling_with_the_same_seed(estimator):
    x = np.random.default_rng(1).normal(0.05, 0.02, size=(3, 8))
    x[1, 2] = math.nan  # an episode without a value: its column resamples the other two runs
    stat = stratified_bootstrap_ci(x, estimator=estimator, n_resamples=FEW, seed=123)
    statistic = (lambda v: sps.trim_mean(v, 0.25)) if estimator == "iqm" else np.mean
    low, high = _loop_resampling(x, statistic, 123, FEW)
    assert stat.n == 23 and stat.estimator == estimator
    assert stat.mean == pytest.approx(statistic(x[np.isfinite(x)]), rel=1e-14)
    assert (stat.low, stat.high) == pytest.approx((low, high), rel=1e-12)
    assert stat.low <= stat.mean <= stat.high
    assert stratified_bootstrap_ci(x, estimator=estimator, n_resamples=FEW, seed=123) == stat
    assert stratified_bootstrap_ci(x, estimator=estimator, n_resamples=FEW, seed=124) != stat


def test_interval_agrees_with_rliables_stratified_bootstrap_scheme():
    """rliable's ``update_indices`` (a run index drawn for every cell, the column kept) with its own draws."""
    rng = np.random.default_rng(2)
    x = np.linspace(0.01, 0.1, 10) + rng.gamma(2.0, 0.005, size=(4, 10))  # episodes differ: the strata matter
    n_resamples = 20_000
    rng = np.random.default_rng(99)
    num_runs, num_tasks = x.shape
    estimates = np.empty(n_resamples)
    task_index = np.ogrid[0:num_tasks]  # rliable: self._strata_indices (the column of each cell)
    for b in range(n_resamples):
        indices = rng.choice(num_runs, x.shape, replace=True)  # rliable: np.random.choice(num_runs, args_shape)
        estimates[b] = sps.trim_mean(x[indices, task_index], 0.25, axis=None)  # rliable: metrics.aggregate_iqm
    low, high = np.percentile(estimates, [2.5, 97.5])  # rliable's default method='percentile'
    ours = stratified_bootstrap_ci(x, n_resamples=n_resamples)
    width = high - low
    assert ours.mean == sps.trim_mean(x, 0.25, axis=None)
    assert abs(ours.low - low) < 0.05 * width and abs(ours.high - high) < 0.05 * width  # Monte Carlo error only


def test_interval_reflects_the_spread_between_training_seeds():
    # a deterministic task: each run repeats one episode, the runs differ
    runs = np.array([[0.010] * 6, [0.020] * 6, [0.035] * 6])
    stat = stratified_bootstrap_ci(runs)
    assert stat.low < stat.mean < stat.high and stat.low >= 0.010 and stat.high <= 0.035
    for row in runs:  # every run on its own has a zero-width interval over its episodes
        assert bootstrap_ci(row).half_width == 0.0
    same = stratified_bootstrap_ci(np.full((3, 4), 0.02))
    assert (same.low, same.mean, same.high) == (0.02, 0.02, 0.02)
    one = stratified_bootstrap_ci([[0.5, math.nan], [math.nan, math.nan]])
    assert one.n == 1 and one.mean == 0.5 and math.isnan(one.low)
    assert stratified_bootstrap_ci(np.full((2, 2), math.nan)).n == 0
    with pytest.raises(ValueError, match="matrix"):
        stratified_bootstrap_ci([1.0, 2.0])
    with pytest.raises(ValueError, match="estimator"):
        stratified_bootstrap_ci(runs, estimator="median")


def test_interval_covers_the_point_on_skewed_small_samples():
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = rng.exponential(size=(int(rng.integers(2, 5)), int(rng.integers(1, 6))))
        stat = stratified_bootstrap_ci(x, n_resamples=FEW)
        assert stat.low <= stat.mean <= stat.high


def _episode(seed: int, *, rmse: float | None, success: bool, contacts: int = 0) -> dict:
    return {"seed": seed, "rmse_pos": rmse, "success": success, "contacts": contacts, "return": -rmse if rmse else 0.0}


def test_aggregate_runs_rates_are_pooled_rates_and_the_rest_iqms():
    runs = [
        [_episode(1, rmse=0.01, success=True), _episode(2, rmse=0.02, success=False)],
        [_episode(1, rmse=0.03, success=True, contacts=2), _episode(2, rmse=None, success=True)],
        [_episode(2, rmse=0.05, success=True), _episode(1, rmse=0.04, success=True)],  # order does not matter
    ]
    stats = aggregate_runs(runs)
    assert stats["success"].mean == pytest.approx(5 / 6) and stats["success"].estimator == "mean"
    assert stats["contact_free"].mean == pytest.approx(5 / 6)
    assert stats["contact_free_success"].mean == pytest.approx(4 / 6)
    assert stats["rmse_pos"].estimator == "iqm" and stats["rmse_pos"].n == 5
    assert stats["rmse_pos"].mean == pytest.approx(sps.trim_mean([0.01, 0.02, 0.03, 0.04, 0.05], 0.25))
    assert stats["rmse_ori"].n == 0
    matrix = run_matrix(runs, "rmse_pos")
    assert matrix[2].tolist() == [0.04, 0.05] and math.isnan(matrix[1, 1])
    assert stats["rmse_pos"].to_json()["estimator"] == "iqm" and "estimator" not in stats["success"].to_json()
    with pytest.raises(ValueError, match="two episodes"):
        run_matrix([[_episode(1, rmse=0.1, success=True)] * 2], "rmse_pos")


def test_learning_curve_stats_over_seeds():
    curves = [
        [{"num_timesteps": 100, "success_rate": 0.0}, {"num_timesteps": 200, "success_rate": 0.5}],
        [{"num_timesteps": 100, "success_rate": 0.2}, {"num_timesteps": 200, "success_rate": 0.7}],
        [{"num_timesteps": 200, "success_rate": 0.9}, {"num_timesteps": 100, "success_rate": 0.1}],
        [{"num_timesteps": 100, "success_rate": None}, {"num_timesteps": 200, "success_rate": 0.6},
         {"num_timesteps": 300, "success_rate": 1.0}],
    ]  # fmt: skip
    steps, stats = learning_curve_stats(curves, "success_rate")
    assert steps == [100, 200]  # 300 is not in every curve
    assert stats[0].mean == pytest.approx(0.1) and stats[0].n == 3  # the missing value is left out
    assert stats[1].mean == pytest.approx(np.mean([0.5, 0.7, 0.9, 0.6]))
    assert all(s.low <= s.mean <= s.high for s in stats)
    single = learning_curve_stats(curves[:1], "success_rate")[1]
    assert [s.mean for s in single] == [0.0, 0.5] and math.isnan(single[1].low)


# ------------------------------------------------------------------------------------------------------
# Layout of a multi-seed entry
# ------------------------------------------------------------------------------------------------------
def test_multi_seed_folder_is_one_entry_with_a_member_per_seed(tmp_path):
    folder = _multi_seed(tmp_path, seeds=(0, 1, 10))
    single = _agent_folder(tmp_path / "sac_single", 5)
    assert find_agent_folders(tmp_path) == [folder, single]
    entry = agent_entry(folder, trust=True)
    assert entry.multi_seed and entry.name == "sac_multi" and entry.label == "sac_multi (3 seeds)"
    assert [m.name for m in entry.members] == ["sac_multi/seed_0", "sac_multi/seed_1", "sac_multi/seed_10"]
    assert [m.training_seed for m in entry.members] == [0, 1, 10]
    assert entry.env_id == CIRCLE and entry.track == "velocity" and not entry.weights_only
    assert entry.training_seeds == {0, 1, 2, 10, 11}
    assert len({m.checksum for m in entry.members}) == 3 and entry.checksum not in {m.checksum for m in entry.members}
    assert entry.runs() == entry.members
    filtered = entry.filtered()
    assert filtered.name == "sac_multi+filter" and all(m.safety_filter for m in filtered.members)
    assert filtered.members[0].name == "sac_multi+filter/seed_0"
    plain = agent_entry(single, trust=True)
    assert not plain.multi_seed and plain.runs() == (plain,) and plain.label == "sac_single"


def test_a_residual_entry_trained_with_the_filter_is_named_as_a_single_agent_would_be(tmp_path):
    composition = {"residual_base": "campc", "residual_scale": 0.2, "safety_filter": True}
    folder = _multi_seed(tmp_path, seeds=(0, 1, 2), composition=composition)
    (entry,) = lb.resolve_entries([str(folder)], trust=True)
    assert entry.name == "residual-campc-sac_multi+filter" and entry.safety_filter and entry.residual_base == "campc"
    assert entry.members[1].name == "residual-campc-sac_multi+filter/seed_1"
    assert all(m.safety_filter and m.residual_base == "campc" for m in entry.members)
    assert lb.resolve_entries([str(folder), str(folder) + "+filter"], trust=True) == [entry]  # the same entry


def test_two_seeds_are_accepted_with_a_warning(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="uvdms.leaderboard"):
        entry = agent_entry(_multi_seed(tmp_path, seeds=(3, 4)), trust=True)
    assert len(entry.members) == 2 and "at least 3" in caplog.text


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda root: _multi_seed(root, seeds=(0,)), "at least 2 seed folders"),
        (lambda root: (_multi_seed(root) / "seed_3").mkdir(), "not an agent folder"),
        (lambda root: (_multi_seed(root) / "seed_x").mkdir(), r"seed_<training seed>"),
        (lambda root: _agent_folder(_multi_seed(root) / "seed_01", 1), "both training seed 1"),
        (lambda root: _agent_folder(_multi_seed(root) / "seed_4", 4, env_id=TRANSPORT), "different environments"),
        (
            lambda root: _agent_folder(_multi_seed(root) / "seed_4", 4, env_kwargs={"action_mode": "torque"}),
            "different environments",
        ),
        (lambda root: _agent_folder(_multi_seed(root) / "seed_4", 4, recorded_seed=7), "trained with seed 7"),
        (
            lambda root: _agent_folder(_multi_seed(root) / "seed_4", 4, composition={"safety_filter": True}),
            "different environments.*safety filter",
        ),
        (lambda root: _agent_folder(_multi_seed(root) / "seed_0" / "seed_5", 5), "not another folder of seeds"),
        (lambda root: (_agent_folder(root / "sac_multi", 9), _multi_seed(root)), "holds both an agent"),
    ],
)
def test_bad_multi_seed_folders_are_refused_with_a_clear_error(tmp_path, build, message):
    build(tmp_path)
    with pytest.raises(ValueError, match=message):
        lb.resolve_entries([str(tmp_path / "sac_multi")], trust=True)


def test_identical_seed_folders_are_refused(tmp_path):
    import shutil

    folder = tmp_path / "sac_multi"
    _agent_folder(folder / "seed_0", 0)
    first = _agent_folder(folder / "seed_1", 1)
    (first / "meta.json").unlink()  # no recorded seed: the copy below is indistinguishable from seed_1
    (first / "config.yml").write_text(json.dumps({"algo": "sac", "env_id": CIRCLE, "config": {}}))
    shutil.copytree(first, folder / "seed_2")
    with pytest.raises(ValueError, match="sac_multi/seed_1 and sac_multi/seed_2 hold identical model files"):
        agent_entry(folder, trust=True)


def test_a_clashing_training_seed_names_its_seed_folder(tmp_path):
    folder = _multi_seed(tmp_path, seeds=(0, SEED_BASE + 1))
    entry = agent_entry(folder, trust=True)
    with pytest.raises(ValueError, match=rf"sac_multi/seed_{SEED_BASE + 1}.*disjoint"):
        check_seed_disjointness(evaluation_seeds(3), [entry])


# ------------------------------------------------------------------------------------------------------
# A tiny leaderboard (fake episodes, the real runner, cache and outputs)
# ------------------------------------------------------------------------------------------------------
def test_multi_seed_entry_is_one_row_aggregated_over_its_seeds(tmp_path):
    folder = _multi_seed(tmp_path / "agents")
    for k, member in enumerate(sorted(folder.glob("seed_*"))):
        _write_curve(member, k, [0.3 - 0.05 * k, 0.2, 0.1 + 0.01 * k])
    _agent_folder(tmp_path / "agents" / "sac_single", 5)
    entries = lb.resolve_entries(["agents"], agents_dir=tmp_path / "agents", trust=True)
    assert [e.name for e in entries] == ["sac_multi", "sac_single"]
    CALLS.clear()
    out = tmp_path / "out"
    result = lb.run_leaderboard(
        entries, out_dir=out, tasks=TINY_TASKS, episodes=4, progress=False, plots=True, backend=FAKE
    )
    assert len(CALLS) == (3 + 1) * len(TINY_TASKS) * 4 and result.computed == len(CALLS)
    rows = {(r.entry.name, r.task.name): r for r in result.rows}
    assert set(rows) == {(e, t.name) for e in ("sac_multi", "sac_single") for t in TINY_TASKS}
    multi = rows["sac_multi", "case1"]
    assert len(multi.episodes) == 12 and {ep["training_seed"] for ep in multi.episodes} == {0, 1, 2}
    by_seed = [[ep for ep in multi.episodes if ep["training_seed"] == k] for k in (0, 1, 2)]
    assert multi.stats == aggregate_runs(by_seed)
    assert multi.stats["rmse_pos"].estimator == "iqm"
    assert multi.stats["rmse_pos"].mean == pytest.approx(iqm([ep["rmse_pos"] for ep in multi.episodes]))
    assert multi.stats["success"].mean == np.mean([ep["success"] for ep in multi.episodes])
    assert multi.stats["rmse_pos"].low < multi.stats["rmse_pos"].mean < multi.stats["rmse_pos"].high
    plain = rows["sac_single", "case1"]
    assert plain.stats == aggregate(plain.episodes) and "training_seed" not in plain.episodes[0]

    tables = lb.markdown_tables(result)
    assert "| sac_multi (3 seeds) |" in tables and "| 3 × 4 |" in tables and "| sac_single |" in tables
    assert "interquartile mean" in (out / "leaderboard.md").read_text()
    with (out / "leaderboard.csv").open() as f:
        csv_rows = {(r["entry"], r["task"]): r for r in csv.DictReader(f)}
    assert csv_rows["sac_multi", "case1"]["training_seeds"] == "3"
    assert csv_rows["sac_multi", "case1"]["aggregation"] == "seeds-iqm-stratified"
    assert csv_rows["sac_single", "case1"]["training_seeds"] == ""
    assert float(csv_rows["sac_multi", "case1"]["rmse_pos_mean"]) == pytest.approx(multi.stats["rmse_pos"].mean, 1e-5)
    doc = json.loads((out / "entries" / "sac_multi.json").read_text())
    assert [s["folder"] for s in doc["seeds"]] == ["seed_0", "seed_1", "seed_2"] and "aggregation" in doc
    assert doc["tasks"]["case1"]["stats"]["rmse_pos"]["estimator"] == "iqm"
    assert "seeds" not in json.loads((out / "entries" / "sac_single.json").read_text())
    cached = {p.parent.parent.name for p in (out / "cache").rglob("*.json")}
    assert cached == {"sac_multi_seed_0", "sac_multi_seed_1", "sac_multi_seed_2", "sac_single"}
    plots = {p.name for p in (out / "plots").glob("*.png")}
    assert "learning_curves_sac_multi.png" in plots and "learning_curves_sac_single.png" not in plots
    assert "plots/learning_curves_sac_multi.png" in (out / "leaderboard.md").read_text()

    CALLS.clear()
    again = lb.run_leaderboard(
        entries, out_dir=out, tasks=TINY_TASKS, episodes=4, progress=False, plots=False, backend=FAKE
    )
    assert CALLS == [] and again.cached == result.computed
    assert lb.markdown_tables(again) == tables
    (next((out / "cache").glob("sac_multi_seed_1/case2/*.json"))).unlink()
    again = lb.run_leaderboard(
        entries, out_dir=out, tasks=TINY_TASKS, episodes=4, progress=False, plots=False, backend=FAKE
    )
    assert again.computed == 1 and CALLS[0][0].endswith("seed_1")


def test_learning_curve_plot_skips_a_broken_curve(tmp_path, caplog):
    folder = _multi_seed(tmp_path, seeds=(0, 1))
    _write_curve(folder / "seed_0", 0, [0.3, 0.2])
    (folder / "seed_1" / "learning_curve.json").write_text("{not json")
    entry = agent_entry(folder, trust=True)
    with caplog.at_level(logging.WARNING, logger="uvdms.leaderboard"):
        written = write_learning_curves([entry], tmp_path / "plots")
    assert [p.name for p in written] == ["learning_curves_sac_multi.png"] and written[0].stat().st_size > 0
    assert "learning curve skipped" in caplog.text and "1 of 2 training seeds" in caplog.text
    assert write_learning_curves([lb.resolve_entries(["campc"])[0]], tmp_path / "plots") == []


# ------------------------------------------------------------------------------------------------------
# Single-seed rows are unchanged: the committed leaderboard recomputed from its own episodes
# ------------------------------------------------------------------------------------------------------
def _close(a, b, rel=1e-12):
    """Equal structures, floats to a relative ``rel``."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k], rel) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_close(x, y, rel) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        return a == pytest.approx(b, rel=rel, abs=1e-300)
    return a == b


def _committed_stats(stats: dict) -> dict:
    """The ``Stat`` of each metric of a committed cell (``None`` read as NaN, as ``Stat.to_json`` writes it)."""
    nan = float("nan")
    return {
        metric: Stat(**{**s, **{k: nan if s[k] is None else s[k] for k in ("mean", "low", "high")}})
        for metric, s in stats.items()
    }


@pytest.mark.portability
def test_committed_leaderboard_is_reproduced_from_its_episodes():
    root = REPO / "docs" / "leaderboard"
    tasks = {t.name: t for t in lb.TASKS}
    rows = []
    for path in sorted((root / "entries").glob("*.json")):
        doc = json.loads(path.read_text(encoding="utf-8"))
        seeds = [s["training_seed"] for s in doc.get("seeds") or []]
        members = tuple(
            lb.Entry(
                name=f"{doc['name']}/seed_{k}",
                kind=doc["kind"],
                spec=doc["spec"],
                track=doc["track"],
                env_id=doc["env_id"],
                training_seed=k,
            )
            for k in seeds
        )
        entry = lb.Entry(
            name=doc["name"],
            kind=doc["kind"],
            spec=doc["spec"],
            track=doc["track"],
            env_id=doc["env_id"],
            members=members,
        )
        for name, cell in doc["tasks"].items():
            if seeds:  # a multi-seed entry: its own aggregation (IQM, stratified bootstrap) over seeds x episodes
                runs = [[e for e in cell["episodes"] if e["training_seed"] == k] for k in seeds]
                assert all(len(run) == len(runs[0]) > 0 for run in runs), (doc["name"], name)
                stats = aggregate_runs(runs)
            else:
                stats = aggregate(cell["episodes"])
            # equal to rounding: the bootstrap's sums may round differently on another CPU (1e-15 seen)
            assert _close({m: s.to_json() for m, s in stats.items()}, cell["stats"]), (doc["name"], name)
            # the tables from the committed statistics: the same bits on any CPU (a last-bit difference of the
            # recomputed ones could move a rounded digit or an interval's overlap)
            rows.append(RankedRow(entry, tasks[name], _committed_stats(cell["stats"]), cell["episodes"]))
    assert len(rows) > 20
    ranked = []
    for track in TRACKS:
        for task in lb.TASKS:
            ranked += rank_rows([r for r in rows if r.entry.track == track and r.task is task])
    result = LeaderboardResult(ranked, [], lb.TASKS, [], 0, 0, [], root)
    assert lb.markdown_tables(result) in (root / "leaderboard.md").read_text(encoding="utf-8")
