"""``uvdms evaluate`` of a multi-seed entry folder, and of shipped names from any directory (running/evaluate.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from leaderboard.running.cache import compact_result
from leaderboard.running.evaluate import evaluate
from leaderboard.stats.metrics import aggregate_runs
from uvdms_cli.main import main

REPO = Path(__file__).resolve().parents[3]
ENTRY = REPO / "trained_agents" / "sac-circle-v1"  # plain SAC, three seeds: cheap to run
KWARGS = ["case=2", "max_episode_steps=4"]


def _behaviour(doc: dict) -> dict:
    """``doc`` without the controller's timings (they depend on the machine's load, not on the behaviour)."""
    return {k: v for k, v in doc.items() if not k.startswith(("controller_ms", "timing"))}


def _run(tmp_path: Path, controller: str, name: str) -> dict:
    out = tmp_path / f"{name}.json"
    argv = ["evaluate", "--controller", controller, "--env", "uvdms/CircleTrack-v1", "--env-kwargs", *KWARGS]
    assert main([*argv, "--episodes", "2", "--seed", "7", "--out", str(out), "--no-progress"]) == 0
    return json.loads(out.read_text())


def test_a_folder_of_seeds_is_evaluated_per_seed_and_aggregated_like_the_leaderboard(tmp_path, capsys):
    result = _run(tmp_path, str(ENTRY), "entry")
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
