"""Multi-seed entries: the IQM, the seed-folder layout, one row per entry, learning curves.

The IQM is checked against independent computations (``scipy.stats.trim_mean``, a sort-and-slice IQM); the
hierarchical bootstrap of a multi-seed row: ``tests/leaderboard/stats/test_hierarchical_bootstrap.py``. Under the
seed protocol a multi-seed entry runs the one draw of a deterministic task with every training seed and spreads the
draws of a randomised task over them (draw ``i`` to seed ``i % k``). The committed leaderboard (``docs/leaderboard``)
is recomputed from its own episodes with the aggregation of the code that wrote it.
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
from leaderboard.output.report import check_table
from leaderboard.stats.generalization import GeneralizationCheck, generalization_check
from leaderboard.stats.intervals import BOOTSTRAP_SEED, N_RESAMPLES, Stat, iqm
from leaderboard.stats.metrics import (
    METRICS,
    RATE_METRICS,
    aggregate,
    aggregate_runs,
    learning_curve_stats,
    run_matrix,
)
from leaderboard.stats.ranking import RankedRow, rank_rows
from leaderboard.stats.result import LeaderboardResult
from leaderboard.suite.entries import agent_entry, check_seed_disjointness, find_agent_folders
from leaderboard.suite.tasks import TRACKS
from tests.support.multiseed_fakes import (
    CALLS,
    CIRCLE,
    FAKE,
    TINY_TASKS,
    _agent_folder,
    _multi_seed,
    _write_curve,
)
from uvdms_gym.seeds import PROTOCOL, TEST, TEST2, assign_draws, split_of, split_seeds

REPO = Path(__file__).resolve().parents[3]
TRANSPORT = "uvdms/Transport-v0"


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
# Aggregation of a multi-seed row
# ------------------------------------------------------------------------------------------------------
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
    folder = _multi_seed(tmp_path, seeds=(0, TEST.start + 1))
    entry = agent_entry(folder, trust=True)
    with pytest.raises(ValueError, match=rf"sac_multi/seed_{TEST.start + 1}.*disjoint"):
        check_seed_disjointness(split_seeds("test", 3), [entry])
    check_seed_disjointness(split_seeds("validation", 3), [entry])  # the validation draws do not clash


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
    deterministic, randomised = TINY_TASKS
    assert deterministic.deterministic and not randomised.deterministic
    CALLS.clear()
    out = tmp_path / "out"
    result = lb.run_leaderboard(
        entries, out_dir=out, tasks=TINY_TASKS, episodes=4, progress=False, plots=True, backend=FAKE
    )
    # case1: its one draw by each of the 3 + 1 runs; circle-random: 4 draws per entry, on test and on test2
    test, test2 = split_seeds("test", 4), split_seeds("test2", 4)
    expected = [(f"seed_{k}", TEST.start) for k in range(3)] + [("sac_single", TEST.start)]
    expected += [(f"seed_{i % 3}", seed) for draws in (test, test2) for i, seed in enumerate(draws)]
    expected += [("sac_single", seed) for seed in test + test2]
    assert sorted((Path(spec).name, seed) for spec, seed in CALLS) == sorted(expected)
    assert result.computed == len(CALLS) == 4 + 2 * 4 + 2 * 4
    rows = {(r.entry.name, r.task.name): r for r in result.rows}
    assert set(rows) == {(e, t.name) for e in ("sac_multi", "sac_single") for t in TINY_TASKS}

    multi = rows["sac_multi", "case1"]  # every training seed on the one draw: the seeds' spread
    assert [(ep["training_seed"], ep["seed"]) for ep in multi.episodes] == [(k, TEST.start) for k in (0, 1, 2)]
    by_seed = [[ep for ep in multi.episodes if ep["training_seed"] == k] for k in (0, 1, 2)]
    assert multi.stats == aggregate_runs(by_seed)
    assert multi.stats["rmse_pos"].estimator == "iqm"
    assert multi.stats["rmse_pos"].mean == pytest.approx(iqm([ep["rmse_pos"] for ep in multi.episodes]))
    assert multi.stats["rmse_pos"].low < multi.stats["rmse_pos"].mean < multi.stats["rmse_pos"].high
    assert multi.check is None and multi.check_episodes == []
    spread = rows["sac_multi", "circle-random"]  # the draws spread over the training seeds: draw i to seed i % 3
    assert [(ep["training_seed"], ep["seed"]) for ep in spread.episodes] == sorted(
        [(i % 3, seed) for i, seed in enumerate(test)]
    )
    by_seed = [[ep for ep in spread.episodes if ep["training_seed"] == k] for k in (0, 1, 2)]
    assert spread.stats == aggregate_runs(by_seed)
    assert spread.stats["success"].mean == np.mean([ep["success"] for ep in spread.episodes])
    assert spread.stats["success"].n == 4
    assert spread.check is not None and spread.check.metric == "contact_free_success"
    assert sorted((ep["training_seed"], ep["seed"]) for ep in spread.check_episodes) == sorted(
        (i % 3, seed) for i, seed in enumerate(test2)
    )
    plain = rows["sac_single", "circle-random"]
    assert plain.stats == aggregate(plain.episodes) and "training_seed" not in plain.episodes[0]
    assert [ep["seed"] for ep in plain.episodes] == test and [ep["seed"] for ep in plain.check_episodes] == test2

    tables = lb.markdown_tables(result)
    assert "| sac_multi (3 seeds) |" in tables and "| sac_single |" in tables
    multi_lines = [line for line in tables.splitlines() if "| sac_multi (3 seeds) |" in line]
    assert [line.rsplit("|", 2)[1].strip() for line in multi_lines] == ["3 × 1", "4"]  # case1, then circle-random
    markdown = (out / "leaderboard.md").read_text()
    assert "interquartile mean" in markdown and "hierarchical bootstrap" in markdown
    with (out / "leaderboard.csv").open() as f:
        csv_rows = {(r["entry"], r["task"]): r for r in csv.DictReader(f)}
    assert csv_rows["sac_multi", "case1"]["training_seeds"] == "3"
    assert csv_rows["sac_multi", "case1"]["aggregation"] == "seeds-iqm-hierarchical"
    assert (
        csv_rows["sac_multi", "case1"]["episodes"] == "3" and csv_rows["sac_multi", "circle-random"]["episodes"] == "4"
    )
    assert csv_rows["sac_single", "case1"]["training_seeds"] == ""
    assert csv_rows["sac_single", "case1"]["aggregation"] == "episodes-mean-bca"
    assert float(csv_rows["sac_multi", "case1"]["rmse_pos_mean"]) == pytest.approx(multi.stats["rmse_pos"].mean, 1e-5)
    doc = json.loads((out / "entries" / "sac_multi.json").read_text())
    assert [s["folder"] for s in doc["seeds"]] == ["seed_0", "seed_1", "seed_2"] and "aggregation" in doc
    assert "hierarchical" in doc["aggregation"]["interval"]
    assert doc["tasks"]["case1"]["stats"]["rmse_pos"]["estimator"] == "iqm"
    assert doc["tasks"]["case1"]["seed_protocol"] == {"protocol": PROTOCOL, "split": "test"}
    check = doc["tasks"]["circle-random"]["check"]
    assert check["seed_protocol"] == {"protocol": PROTOCOL, "split": "test2"}
    assert sorted((ep["training_seed"], ep["seed"]) for ep in check["episodes"]) == sorted(
        (i % 3, seed) for i, seed in enumerate(test2)
    )
    assert "seeds" not in json.loads((out / "entries" / "sac_single.json").read_text())
    cached = {p.parent.parent.name for p in (out / "cache").rglob("*.json")}
    assert cached == {"sac_multi_seed_0", "sac_multi_seed_1", "sac_multi_seed_2", "sac_single"}
    plots = {p.name for p in (out / "plots").glob("*.png")}
    assert "learning_curves_sac_multi.png" in plots and "learning_curves_sac_single.png" not in plots
    assert "plots/learning_curves_sac_multi.png" in markdown

    CALLS.clear()
    again = lb.run_leaderboard(
        entries, out_dir=out, tasks=TINY_TASKS, episodes=4, progress=False, plots=False, backend=FAKE
    )
    assert CALLS == [] and again.cached == result.computed
    assert lb.markdown_tables(again) == tables
    (next((out / "cache").glob("sac_multi_seed_1/circle-random/*.json"))).unlink()
    again = lb.run_leaderboard(
        entries, out_dir=out, tasks=TINY_TASKS, episodes=4, progress=False, plots=False, backend=FAKE
    )
    assert again.computed == 1 and CALLS[0][0].endswith("seed_1")


def test_fewer_draws_than_training_seeds_leave_a_seed_without_episodes_on_a_randomised_task(tmp_path):
    entries = lb.resolve_entries([str(_multi_seed(tmp_path / "agents"))], trust=True)
    CALLS.clear()
    result = lb.run_leaderboard(
        entries, out_dir=tmp_path / "out", tasks=TINY_TASKS[1:], episodes=2, progress=False, plots=False, backend=FAKE
    )
    (row,) = result.rows
    assert sorted((ep["training_seed"], ep["seed"]) for ep in row.episodes) == [(0, TEST.start), (1, TEST.start + 1)]
    assert row.stats["success"].n == 2
    assert sorted(ep["seed"] for ep in row.check_episodes) == [TEST2.start, TEST2.start + 1]


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
# The committed leaderboard recomputed from its own episodes (with the aggregation of the code that wrote it)
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


def _sorted_iqm(x: np.ndarray, axis: int | None = None) -> np.ndarray:
    """The 25 % trimmed mean (``int(0.25 n)`` off each end) by sorting: ``scipy.stats.trim_mean`` to rounding."""
    x = np.sort(x, axis=-1) if axis is not None else np.sort(np.ravel(x))
    cut = int(0.25 * x.shape[-1])
    return x[..., cut : x.shape[-1] - cut].mean(axis=-1)


def _stratified_bootstrap_0_4(matrix: np.ndarray, estimator: str, seed: int) -> Stat:
    """The interval of a multi-seed row before the seed protocol (0.4.0's ``stratified_bootstrap_ci``, transcribed).

    rliable's scheme with the evaluation episodes as strata: for each column in order, with ``k`` finite cells, one
    ``rng.integers(0, k, size=(N_RESAMPLES, k))`` of ``rng = default_rng(seed)``; the estimator of the pooled
    resample; the percentile interval widened to the point. Kept here to check a leaderboard it wrote.
    """
    x = np.asarray(matrix, dtype=float)
    finite = np.isfinite(x)
    pooled = x[finite]
    statistic = _sorted_iqm if estimator == "iqm" else np.mean
    if pooled.size == 0:
        return Stat(math.nan, math.nan, math.nan, 0, estimator)
    point = float(statistic(pooled))
    if pooled.size < 2:
        return Stat(point, math.nan, math.nan, 1, estimator)
    if np.all(pooled == pooled[0]):
        return Stat(float(pooled[0]), float(pooled[0]), float(pooled[0]), int(pooled.size), estimator)
    rng = np.random.default_rng(seed)
    columns = [x[finite[:, j], j] for j in range(x.shape[1]) if finite[:, j].any()]
    resampled = np.concatenate([c[rng.integers(0, c.size, size=(N_RESAMPLES, c.size))] for c in columns], axis=1)
    low, high = np.percentile(statistic(resampled, axis=1), [2.5, 97.5])
    return Stat(point, min(float(low), point), max(float(high), point), int(pooled.size), estimator)


def _aggregate_runs_0_4(runs) -> dict[str, Stat]:
    """0.4.0's ``aggregate_runs``: rates as means, the rest as IQMs, each with its stratified bootstrap interval."""
    return {
        metric: _stratified_bootstrap_0_4(
            run_matrix(runs, metric), "mean" if metric in RATE_METRICS else "iqm", BOOTSTRAP_SEED + index
        )
        for index, metric in enumerate(METRICS)
    }


def _n_cells_before_the_protocol(tables: str, rows: list[RankedRow]) -> str:
    """``tables`` with the ``n`` cell 0.4.0 wrote for a multi-seed row on a randomised task (``k × episodes``)."""
    lines = tables.splitlines()
    for row in rows:
        if row.entry.multi_seed and not row.task.deterministic:
            k, n = len(row.entry.members), len(row.episodes)
            prefix = f"| {row.task.label} | {row.rank_label} | {row.entry.label} |"
            (i,) = [i for i, line in enumerate(lines) if line.startswith(prefix)]
            assert lines[i].endswith(f" {n} |")
            lines[i] = lines[i][: -len(f" {n} |")] + f" {k} × {n / k:g} |"
    return "\n".join(lines) + ("\n" if tables.endswith("\n") else "")


def _committed_check(check: dict) -> GeneralizationCheck:
    parts = {part: _committed_stats({part: check[part]})[part] for part in ("test", "test2", "difference")}
    return GeneralizationCheck(metric=check["metric"], **parts)


@pytest.mark.portability
def test_committed_leaderboard_is_reproduced_from_its_episodes():
    root = REPO / "docs" / "leaderboard"
    assert len(list((root / "entries").glob("*.json"))) > 20
    assert_reproduced_from_its_episodes(root, lb.TASKS)


def test_a_leaderboard_of_the_seed_protocol_is_reproduced_from_its_episodes(tmp_path):
    """The same check of a tiny leaderboard written now (fake episodes): the branch a regenerated board takes."""
    folder = _multi_seed(tmp_path / "agents")
    _agent_folder(tmp_path / "agents" / "sac_single", 5)
    entries = lb.resolve_entries(["agents", "mpc"], agents_dir=tmp_path / "agents", trust=True)
    out = tmp_path / "out"
    lb.run_leaderboard(entries, out_dir=out, tasks=TINY_TASKS, episodes=7, progress=False, plots=False, backend=FAKE)
    assert folder.name == "sac_multi" and "## Generalisation check" in (out / "leaderboard.md").read_text()
    assert_reproduced_from_its_episodes(out, TINY_TASKS)


def _assert_stats_reproduced(stats: dict, committed: dict, where: tuple) -> None:
    """Recomputed statistics equal the committed ones to rounding (the bootstrap's sums may round differently on
    another CPU: 1e-15 seen); a cell written before the friction grasp's metrics lacks them, and its episodes have
    no value of them."""
    newer = {m for m in stats if m not in committed}
    assert all(stats[m].n == 0 for m in newer), (*where, newer)
    assert _close({m: s.to_json() for m, s in stats.items() if m not in newer}, committed), where


def assert_reproduced_from_its_episodes(root: Path, task_list) -> None:
    """Every cell's statistics from its episodes, then the tables from the committed statistics.

    A leaderboard of the seed protocol (its cells record their ``seed_protocol``): the draws of each task on its
    split, the aggregation of this code, the generalisation check from the ``test2`` episodes. One from before it
    (the evaluation seeds ``2_000_000_000 + i`` of every task, by every training seed): its multi-seed rows with
    the stratified bootstrap that wrote them, single-seed rows unchanged.
    """
    tasks = {t.name: t for t in task_list}
    markdown = (root / "leaderboard.md").read_text(encoding="utf-8")
    rows = []
    protocols = set()
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
            privileged="privileged" in doc,  # a reference row: unranked
        )
        for name, cell in doc["tasks"].items():
            task = tasks[name]
            protocol = cell.get("seed_protocol")
            protocols.add(None if protocol is None else protocol["protocol"])
            runs = [[e for e in cell["episodes"] if e["training_seed"] == k] for k in seeds]
            if protocol is not None:  # each run's draws as the protocol assigns them
                split = protocol["split"]
                draws = sorted({e["seed"] for e in cell["episodes"]})
                assert draws == split_seeds(split, len(draws)), (doc["name"], name)
                assert len(draws) == 1 or not task.deterministic, (doc["name"], name)
                for i, run in enumerate(runs):
                    mine = draws if task.deterministic else assign_draws(draws, len(runs), i)
                    assert sorted(e["seed"] for e in run) == mine, (doc["name"], name)
                stats = aggregate_runs(runs) if seeds else aggregate(cell["episodes"])
            else:  # 0.4.0: every training seed on the same evaluation seeds
                assert all(len(run) == len(runs[0]) > 0 for run in runs), (doc["name"], name)
                stats = _aggregate_runs_0_4(runs) if seeds else aggregate(cell["episodes"])
            _assert_stats_reproduced(stats, cell["stats"], (doc["name"], name))
            # the tables from the committed statistics: the same bits on any CPU (a last-bit difference of the
            # recomputed ones could move a rounded digit or an interval's overlap)
            row = RankedRow(entry, task, _committed_stats(cell["stats"]), cell["episodes"])
            if "check" in cell:
                check = cell["check"]
                test2 = [[e for e in check["episodes"] if e["training_seed"] == k] for k in seeds] or [
                    check["episodes"]
                ]
                again = generalization_check(runs or [cell["episodes"]], test2).to_json()
                assert _close(again, {k: v for k, v in check.items() if k not in ("episodes", "seed_protocol")})
                assert {split_of(e["seed"]) for e in check["episodes"]} == {"test2"}
                row.check = _committed_check(check)
            rows.append(row)
    assert len(rows) >= 4 and len(protocols) == 1, protocols  # one protocol for the whole leaderboard
    ranked = []
    for track in TRACKS:
        for task in task_list:
            ranked += rank_rows([r for r in rows if r.entry.track == track and r.task is task])
    result = LeaderboardResult(ranked, [], tuple(task_list), [], 0, 0, [], root)
    tables = lb.markdown_tables(result)
    if protocols == {None}:
        tables = _n_cells_before_the_protocol(tables, ranked)
    else:
        assert check_table(result) in markdown
    assert tables in markdown
