"""Learning curves: the evaluation callback's benchmark metrics in ``learning_curve.json``, through resume and export.

Tiny SAC runs on short transport episodes whose gradient updates never start (``learning_starts`` above the
budget), so the policy of every evaluation is the final model's and the recorded metrics can be checked against
:func:`uvdms_gym.evaluation.run_episode`. The last test ships three such runs as one multi-seed entry and runs it
through a tiny leaderboard with the real environment and loading.
"""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import leaderboard as lb
from agents.common.envs import EnvFactory, eval_env_seed
from agents.common.learning_curve import (
    INFO_KEY,
    LEARNING_CURVE_FILE,
    EpisodeMetrics,
    LearningCurve,
    LearningCurveError,
    episode_summary,
    read_learning_curve,
)
from agents.export import export_agent, load_agent
from agents.training.train import train
from leaderboard.running.jobs import DEFAULT_BACKEND
from leaderboard.stats.metrics import aggregate_runs
from leaderboard.suite.agent_files import agent_checksum
from uvdms_gym.evaluation import run_episode
from uvdms_gym.seeds import TEST

TRANSPORT = "uvdms/Transport-v0"
CIRCLE = "uvdms/CircleTrack-v0"
EPISODE_STEPS = 30
EVAL_FREQ = 32
BUDGET = 64
EVAL_EPISODES = 2
TINY_SAC = {
    "n_timesteps": BUDGET,
    "n_envs": 1,
    "eval_freq": EVAL_FREQ,
    "n_eval_episodes": EVAL_EPISODES,
    "checkpoint_freq": EVAL_FREQ,
    "max_episode_steps": EPISODE_STEPS,
    "buffer_size": 1000,
    "batch_size": 32,
    "learning_starts": 100_000,  # no gradient step: every evaluation runs the initial (= final) policy
    "policy_kwargs": {"net_arch": [16]},
}


class ReplayController:
    """Seeded random actions (the same sequence for the same seed), for comparing two ways of running an episode."""

    def __init__(self, scale: float = 0.5) -> None:
        self.scale = scale
        self.rng = np.random.default_rng(0)

    def reset(self, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def predict(self, obs, info):
        return self.rng.uniform(-self.scale, self.scale, 18)


@pytest.mark.parametrize(
    ("env_id", "kwargs", "steps"),
    [(TRANSPORT, {"goal": "paper"}, 40), (CIRCLE, {"case": 1}, 140), (CIRCLE, {"case": 2}, 20)],
)
def test_episode_metrics_wrapper_reports_what_run_episode_reports(env_id, kwargs, steps):
    env = gym.make(env_id, max_episode_steps=steps, **kwargs)
    expected = run_episode(env, ReplayController(), 11)
    env.close()
    wrapped = EpisodeMetrics(gym.make(env_id, max_episode_steps=steps, **kwargs))
    controller = ReplayController()
    obs, info = wrapped.reset(seed=11)
    controller.reset(11)
    while True:
        obs, _, terminated, truncated, info = wrapped.step(controller.predict(obs, info))
        if terminated or truncated:
            break
        assert INFO_KEY not in info
    wrapped.close()
    metrics = info[INFO_KEY]
    assert metrics == episode_summary(expected)
    assert metrics["rmse_pos"] == expected["rmse_pos"] and metrics["steps"] == expected["steps"] == steps
    if env_id == CIRCLE and steps < 125:  # shorter than the 5 s transient: no RMSE
        assert metrics["rmse_pos"] is None


def test_only_uvdms_evaluation_envs_get_the_wrapper():
    def wrappers(env):
        names = []
        while isinstance(env, gym.Wrapper):
            names.append(type(env).__name__)
            env = env.env
        return names

    assert "EpisodeMetrics" in wrappers(EnvFactory(TRANSPORT, {"goal": "paper"}, episode_metrics=True)())
    assert "EpisodeMetrics" not in wrappers(EnvFactory(TRANSPORT, {"goal": "paper"})())
    assert "EpisodeMetrics" not in wrappers(EnvFactory("Pendulum-v1", {}, episode_metrics=True)())
    with pytest.raises(ValueError, match="not a uvdms environment"):
        EpisodeMetrics(gym.make("Pendulum-v1"))


def _config(folder: Path) -> Path:
    path = folder / "sac.yml"
    path.write_text(yaml.safe_dump({"default": TINY_SAC}), encoding="utf-8")
    return path


def _train(tmp_path: Path, seed: int) -> Path:
    return train(
        "sac", TRANSPORT, {"goal": "paper"}, _config(tmp_path), seed=seed, out_dir=tmp_path / "runs", progress=False
    )


@pytest.mark.filterwarnings("ignore:final_model.zip has no saved replay buffer")
def test_training_records_the_benchmark_metrics_and_resume_continues_the_curve(tmp_path):
    run_dir = _train(tmp_path, seed=3)
    doc = read_learning_curve(run_dir / LEARNING_CURVE_FILE)
    assert doc["env_id"] == TRANSPORT and doc["seed"] == 3
    points = doc["points"]
    assert [p["num_timesteps"] for p in points] == [EVAL_FREQ, BUDGET] and {p["segment"] for p in points} == {0}
    for point in points:
        assert point["episodes"] == EVAL_EPISODES and len(point["episode"]["rmse_pos"]) == EVAL_EPISODES
        assert point["rmse_pos_mean"] == pytest.approx(np.mean(point["episode"]["rmse_pos"]))
        assert point["success_rate"] == np.mean(point["episode"]["success"])
        assert 0.0 <= point["contact_free_success_rate"] <= point["contact_free_rate"] <= 1.0

    # the recorded episode is the one uvdms evaluate would report for the evaluated policy (= the final model)
    agent = load_agent(run_dir, trust=True)
    env = gym.make(TRANSPORT, goal="paper", max_episode_steps=EPISODE_STEPS)
    episode = run_episode(env, agent, eval_env_seed(3, 0))
    env.close()
    assert points[-1]["episode"]["rmse_pos"][0] == pytest.approx(episode["rmse_pos"], rel=1e-9)
    assert points[-1]["episode"]["success"][0] == episode["success"]
    assert points[-1]["episode"]["contact_free"][0] == (episode["contacts"] == 0)

    # a point past the checkpoint a resume starts from (an abandoned continuation) is dropped, the rest kept
    curve = LearningCurve.resume(run_dir / LEARNING_CURVE_FILE, TRANSPORT, 3, BUDGET)
    curve.add({**points[-1], "num_timesteps": 10**6, "segment": 5})
    assert train(resume_dir=run_dir, total_timesteps=BUDGET, progress=False) == run_dir
    resumed = read_learning_curve(run_dir / LEARNING_CURVE_FILE)["points"]
    assert [p["num_timesteps"] for p in resumed] == [EVAL_FREQ, BUDGET, BUDGET + EVAL_FREQ, 2 * BUDGET]
    assert resumed[:2] == points and [p["segment"] for p in resumed[2:]] == [1, 1]

    # exports and shipped folders carry it
    from scripts.ship_agent import package_run

    export = export_agent(run_dir, tmp_path / "export", trust=True)
    shipped = package_run(run_dir, tmp_path / "shipped", which="final")
    for folder in (export, shipped):
        assert json.loads((folder / LEARNING_CURVE_FILE).read_text()) == json.loads(
            (run_dir / LEARNING_CURVE_FILE).read_text()
        )
    assert agent_checksum(export) == agent_checksum(export_agent(run_dir, tmp_path / "e2", trust=True))
    # and the run's meta.json (seeds, versions, git, every segment's budget and wall time), outside the checksum
    meta = json.loads((run_dir / "meta.json").read_text())
    assert json.loads((export / "meta.json").read_text()) == meta
    assert [s["end_num_timesteps"] for s in meta["segments"]] == [BUDGET, 2 * BUDGET]
    assert all(s["wall_time_s"] > 0 for s in meta["segments"])
    checksum = agent_checksum(export)
    (export / "meta.json").unlink()
    assert agent_checksum(export) == checksum
    re_export = export_agent(export, tmp_path / "e3")  # an export of an export without the record has none
    assert not (re_export / "meta.json").exists()


def test_a_broken_curve_file_is_a_clear_error(tmp_path):
    path = tmp_path / LEARNING_CURVE_FILE
    for text, message in [
        ("{", "cannot read"),
        ('{"format": "other"}', "not a uvdms-learning-curve"),
        ('{"format": "uvdms-learning-curve", "format_version": 9, "points": []}', "format_version"),
        ('{"format": "uvdms-learning-curve", "format_version": 1, "points": [{"num_timesteps": "x"}]}', "integer"),
    ]:
        path.write_text(text)
        with pytest.raises(LearningCurveError, match=message):
            read_learning_curve(path)
        with pytest.raises(LearningCurveError):
            LearningCurve.resume(path, TRANSPORT, 0, 100)


def test_three_trained_seeds_rank_as_one_entry_with_learning_curves(tmp_path):
    entry_dir = tmp_path / "agents" / "sac_transport"
    for seed in (0, 1, 2):
        export_agent(_train(tmp_path, seed), entry_dir / f"seed_{seed}", trust=True)
    entries = lb.resolve_entries(["agents"], agents_dir=tmp_path / "agents", trust=False)  # weights-only: no trust
    assert len(entries) == 1 and entries[0].multi_seed and entries[0].weights_only
    task = lb.Task(
        "transport", "Transport", TRANSPORT, {"goal": "paper"}, paper=True, max_episode_steps=3, deterministic=True
    )
    result = lb.run_leaderboard(
        entries,
        out_dir=tmp_path / "out",
        tasks=(task,),
        episodes=2,
        progress=False,
        plots=True,
        backend=DEFAULT_BACKEND,
    )
    (row,) = result.rows
    assert row.entry.name == "sac_transport" and len(row.episodes) == 3 and result.computed == 3
    by_seed = [[ep for ep in row.episodes if ep["training_seed"] == k] for k in (0, 1, 2)]
    assert row.stats == aggregate_runs(by_seed)
    assert all([ep["seed"] for ep in run] == [TEST.start] for run in by_seed)  # a paper task: each seed's one draw
    assert len({run[0]["rmse_pos"] for run in by_seed}) == 3  # the seeds differ
    rmse = row.stats["rmse_pos"]
    assert rmse.estimator == "iqm" and rmse.low < rmse.mean < rmse.high
    plot = tmp_path / "out" / "plots" / "learning_curves_sac_transport.png"
    assert plot.is_file() and plot.stat().st_size > 0
