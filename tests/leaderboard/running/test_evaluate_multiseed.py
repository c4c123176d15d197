"""``uvdms evaluate`` of a multi-seed entry folder, and of shipped names from any directory (running/evaluate.py).

A folder of training seeds spreads the draws over its seeds (draw ``i`` evaluated once, by the ``i % n``-th seed
folder) unless ``--every-seed``, where every seed evaluates every draw.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from leaderboard.running.cache import compact_result
from leaderboard.running.evaluate import draw_shares, evaluate
from leaderboard.stats.intervals import iqm
from leaderboard.stats.metrics import aggregate_runs
from uvdms_cli.main import main
from uvdms_gym.seeds import PROTOCOL, VALIDATION

REPO = Path(__file__).resolve().parents[3]
ENTRY = REPO / "trained_agents" / "sac-circle-v1"  # plain SAC, three seeds: cheap to run
KWARGS = ["case=2", "max_episode_steps=4"]


def _behaviour(doc: dict) -> dict:
    """``doc`` without the controller's timings (they depend on the machine's load, not on the behaviour)."""
    return {k: v for k, v in doc.items() if not k.startswith(("controller_ms", "timing"))}


def _run(
    tmp_path: Path, controller: str, name: str, flags: tuple[str, ...] = ("--episodes", "2", "--seed", "7")
) -> dict:
    out = tmp_path / f"{name}.json"
    argv = ["evaluate", "--controller", controller, "--env", "uvdms/CircleTrack-v1", "--env-kwargs", *KWARGS]
    assert main([*argv, *flags, "--out", str(out), "--no-progress"]) == 0
    return json.loads(out.read_text())


def test_every_seed_evaluates_every_draw_and_aggregates_seeds_x_episodes(tmp_path, capsys):
    result = _run(tmp_path, str(ENTRY), "entry", ("--episodes", "2", "--seed", "7", "--every-seed"))
    summary = result["summary"]
    seeds = sorted(p.name for p in ENTRY.iterdir() if p.name.startswith("seed_"))
    assert list(summary["seeds"]) == seeds and summary["seeds"] == {s: int(s.split("_")[1]) for s in seeds}
    assert len(result["episodes"]) == 2 * len(seeds)
    assert json.loads(capsys.readouterr().out) == summary  # the printed summary is the written one
    # each seed as the single-agent command evaluates it, independently
    runs = []
    for name in seeds:
        alone = evaluate(
            str(ENTRY / name), "uvdms/CircleTrack-v1", {"case": 2, "max_episode_steps": 4}, 2, 7, progress=False
        )
        assert _behaviour(summary["per_seed"][name]) == _behaviour(alone["summary"])
        runs.append([compact_result(ep) for ep in alone["episodes"]])
    expected = {metric: stat.to_json() for metric, stat in aggregate_runs(runs).items()}
    assert _behaviour(summary["aggregate"]) == _behaviour(json.loads(json.dumps(expected)))
    assert summary["aggregate"]["rmse_pos"]["estimator"] == "iqm"
    assert [ep["seed_folder"] for ep in result["episodes"]] == [s for s in seeds for _ in range(2)]
    assert [ep["seed"] for ep in result["episodes"]] == [7, 8] * len(seeds)
    meta = result["meta"]
    assert meta["seeds"] == [7, 8] and meta["episodes"] == 2
    assert meta["seed_protocol"] == {"protocol": PROTOCOL, "split": "training"}  # --seed 7: a training seed
    assert meta["draw_assignment"]["rule"] == "every_seed"
    assert meta["draw_assignment"]["by_seed_folder"] == {s: [7, 8] for s in seeds}


def test_a_folder_of_seeds_spreads_the_validation_draws_over_its_seeds(tmp_path, capsys):
    result = _run(tmp_path, str(ENTRY), "spread", ("--episodes", "4"))
    seeds = sorted(p.name for p in ENTRY.iterdir() if p.name.startswith("seed_"))
    draws = [VALIDATION.start + i for i in range(4)]
    # each draw evaluated once, draw i by the (i % n)-th seed folder
    by_draw = {ep["seed"]: ep["seed_folder"] for ep in result["episodes"]}
    assert len(result["episodes"]) == 4 and sorted(by_draw) == draws
    assert by_draw == {draw: seeds[i % len(seeds)] for i, draw in enumerate(draws)}
    meta, summary = result["meta"], result["summary"]
    assert meta["seeds"] == draws and meta["episodes"] == 4
    assert meta["seed_protocol"] == {"protocol": PROTOCOL, "split": "validation"}
    assert meta["draw_assignment"]["rule"] == "spread"
    assert meta["draw_assignment"]["by_seed_folder"] == {s: draws[i :: len(seeds)] for i, s in enumerate(seeds)}
    assert json.loads(capsys.readouterr().out) == summary
    # each seed's share, as the single-agent command evaluates it; the row pools the episodes
    runs = []
    for name, share in meta["draw_assignment"]["by_seed_folder"].items():
        kwargs = {"case": 2, "max_episode_steps": 4}
        alone = evaluate(str(ENTRY / name), "uvdms/CircleTrack-v1", kwargs, len(share), seeds=share, progress=False)
        assert _behaviour(summary["per_seed"][name]) == _behaviour(alone["summary"])
        assert alone["meta"]["seeds"] == share
        runs.append([compact_result(ep) for ep in alone["episodes"]])
    expected = {metric: stat.to_json() for metric, stat in aggregate_runs(runs).items()}
    assert _behaviour(summary["aggregate"]) == _behaviour(json.loads(json.dumps(expected)))
    assert summary["aggregate"]["return"]["n"] == 4 and "hierarchical bootstrap" in summary["aggregation"]


def _episodes(values: dict[int, float]) -> list[dict]:
    return [{"seed": seed, "return": value, "contacts": 0, "success": value > 0} for seed, value in values.items()]


def test_spread_draws_pool_into_one_sample_whatever_seed_evaluated_them():
    values = {100 + i: float(v) for i, v in enumerate([3, -1, 4, 1, -5, 9, 2, 6])}
    one_way = aggregate_runs([_episodes(dict(list(values.items())[k::3])) for k in range(3)])
    other_way = aggregate_runs([_episodes(dict(list(values.items())[:5])), _episodes(dict(list(values.items())[5:]))])
    assert {k: v.to_json() for k, v in one_way.items()} == {k: v.to_json() for k, v in other_way.items()}
    stat = one_way["return"]
    assert stat.mean == pytest.approx(iqm(np.array(list(values.values())))) and stat.n == 8
    assert stat.low < stat.mean < stat.high  # a real interval: the draws are resampled
    assert one_way["success"].mean == pytest.approx(6 / 8) and one_way["success"].estimator == "mean"


def test_draw_shares():
    draws = [10, 11, 12, 13, 14]
    assert draw_shares(["a", "b"], draws) == {"a": [10, 12, 14], "b": [11, 13]}
    assert draw_shares(["a", "b"], draws, every_seed=True) == {"a": draws, "b": draws}
    with pytest.raises(ValueError, match=r"2 episode\(s\) cannot be spread over 3 training seeds.*--every-seed"):
        draw_shares(["a", "b", "c"], draws[:2])


def test_too_few_draws_for_the_seeds_and_every_seed_for_one_controller_are_one_line_errors(tmp_path, capsys):
    argv = ["evaluate", "--env", "uvdms/CircleTrack-v1", "--env-kwargs", *KWARGS, "--no-progress"]
    assert main([*argv, "--controller", str(ENTRY), "--episodes", "2"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "cannot be spread over 3 training seeds" in lines[0] and "--every-seed" in lines[0]
    assert main([*argv, "--controller", "hold", "--episodes", "1", "--every-seed"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "--every-seed applies to a folder of training seeds" in lines[0]


def test_one_seed_folder_still_evaluates_one_agent(tmp_path):
    result = _run(tmp_path, str(ENTRY / "seed_1"), "one")
    assert "per_seed" not in result["summary"] and len(result["episodes"]) == 2


@pytest.mark.parametrize("name", ["trained_agents/sac-circle-v1/seed_0", "trained_agents/circle_case1_sac"])
def test_shipped_names_resolve_from_any_directory(tmp_path, monkeypatch, name):
    monkeypatch.chdir(tmp_path)  # no trained_agents/ here
    out = tmp_path / "r.json"
    env = "uvdms/CircleTrack-v1" if "v1" in name else "uvdms/CircleTrack-v0"
    argv = ["evaluate", "--controller", name, "--env", env, "--env-kwargs", "max_episode_steps=3", "--episodes", "1"]
    assert main([*argv, "--out", str(out), "--no-progress"]) == 0
    assert len(json.loads(out.read_text())["episodes"]) == 1
