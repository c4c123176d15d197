"""``uvdms leaderboard --backend ray``: same results as the local backend, a two-node cluster, a killed worker.

Episodes are cut to a few steps (``--max-episode-steps``): the properties under test (which episodes run,
where results go, that a result does not depend on the process that computed it) do not need whole episodes.
Every Ray test starts its own Ray, shuts it down, and checks that no process it started outlives it (the
``ray_processes`` fixture of ``tests/support/ray_cluster.py``).
"""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

import pytest

import leaderboard as lb
from leaderboard.running.cache import read_cached
from leaderboard.running.distributed import agent_files, materialise
from leaderboard.running.jobs import plan_jobs
from tests.support.ray_cluster import in_background, kill_when
from uvdms_cli.main import main

pytestmark = pytest.mark.slow  # Ray instances and clusters

REPO = Path(__file__).resolve().parents[3]
SHIPPED_SAC = REPO / "trained_agents" / "sac-circle-case1-v0"
TIMING_PREFIXES = ("timing_", "controller_ms_")
"""``leaderboard.csv`` columns that measure time (everything else is a quality column)."""


def quality_columns(path: Path) -> list[dict[str, str]]:
    """The rows of a ``leaderboard.csv`` without its timing columns."""
    with path.open(encoding="utf-8", newline="") as f:
        return [{k: v for k, v in row.items() if not k.startswith(TIMING_PREFIXES)} for row in csv.DictReader(f)]


def check_cache(cache: Path, jobs: list) -> None:
    """The cache holds exactly one complete file per job, and nothing else (no partial or temporary file)."""
    files = sorted(p for p in cache.rglob("*") if p.is_file() and p.name != ".gitignore")
    assert files == sorted(job.path for job in jobs)
    for job in jobs:
        assert read_cached(job.path, job.key)["seed"] == job.seed


def leaderboard_argv(out: Path, *extra: str) -> list[str]:
    return ["leaderboard", "--out", str(out), "--no-plots", "--no-progress", *extra]


@pytest.mark.portability
def test_ray_backend_writes_the_quick_leaderboard_of_the_local_backend(tmp_path, ray_processes, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the default agents folder is the repository's trained_agents/
    quick = ["--quick", "--max-episode-steps", "8"]
    assert main(leaderboard_argv(tmp_path / "local", *quick)) == 0
    assert main(leaderboard_argv(tmp_path / "ray", *quick, "--backend", "ray", "--num-cpus", "2")) == 0
    local, distributed = (
        quality_columns(tmp_path / "local" / "leaderboard.csv"),
        quality_columns(tmp_path / "ray" / "leaderboard.csv"),
    )
    # every baseline and every shipped agent on the three paper tasks, and the same bits in every quality column
    assert {row["entry"] for row in local} >= {"mpc", "campc", "campc-di", "campc-nndi", "sac-circle-case1-v0"}
    assert {row["task"] for row in local} == {"case1", "case2", "transport"}
    assert distributed == local
    assert len(ray_processes.seen) > 2  # Ray's own processes and its workers were started and watched


def test_two_node_cluster(tmp_path, ray_processes):
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    try:
        cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        out = tmp_path / "out"
        argv = ["--entries", "mpc", str(SHIPPED_SAC), "--tasks", "case1", "--episodes", "2"]
        argv += ["--max-episode-steps", "6", "--backend", "ray", "--address", cluster.address]
        assert main(leaderboard_argv(out, *argv)) == 0
        rows = quality_columns(out / "leaderboard.csv")
        assert sorted((row["entry"], row["episodes"]) for row in rows) == [("mpc", "1"), ("sac-circle-case1-v0", "1")]
        entries = lb.resolve_entries(["mpc", str(SHIPPED_SAC)])
        tasks = [replace(t, max_episode_steps=6) for t in lb.TASKS if t.name == "case1"]
        # case1 is deterministic: its one test draw per entry, whatever --episodes
        check_cache(out / "cache", plan_jobs(entries, tasks, "test", 2, out / "cache"))
    finally:
        cluster.shutdown()


def test_a_killed_worker_is_retried_and_every_episode_is_cached_once(tmp_path, ray_processes):
    entries = lb.resolve_entries(["mpc", "campc"])
    tasks = [t for t in lb.TASKS if t.name == "circle-random"]  # randomised: 3 draws per entry
    tasks = [replace(t, max_episode_steps=60) for t in tasks]
    cache = tmp_path / "ray" / "cache"
    jobs = plan_jobs(entries, tasks, "test", 3, cache)
    thread, outcome = in_background(
        lambda: lb.run_leaderboard(
            entries,
            out_dir=tmp_path / "ray",
            tasks=tasks,
            episodes=3,
            executor="ray",
            num_cpus=2,
            progress=False,
            plots=False,
            generalization=False,  # (the test draws only: the jobs planned above)
        )
    )
    killed = kill_when("ray::episode ", thread, settle=0.5)  # into the episode: its steps are running
    thread.join(timeout=400)
    assert "error" not in outcome, outcome.get("error")
    assert killed is not None, "no episode was seen running: nothing was killed"
    result = outcome["result"]
    assert result.computed == len(jobs) == 6 and result.cached == 0
    check_cache(cache, jobs)
    assert all(len(row.episodes) == 3 for row in result.rows)
    # the retried episode is the one a first attempt gives: the local backend's results, bit for bit
    lb.run_leaderboard(
        entries, out_dir=tmp_path / "local", tasks=tasks, episodes=3, progress=False, plots=False, generalization=False
    )
    assert quality_columns(tmp_path / "ray" / "leaderboard.csv") == quality_columns(
        tmp_path / "local" / "leaderboard.csv"
    )


def test_agent_reaches_workers_as_a_weights_only_export(tmp_path):
    (entry,) = lb.resolve_entries([str(SHIPPED_SAC)])
    assert not entry.weights_only  # a shipped SB3 zip: the driver loads it and exports it
    files = agent_files(entry, trust=False)
    assert set(files) >= {"agent.json", "policy.pt"}
    assert not any(name.endswith((".zip", ".pkl")) for name in files)
    folder = materialise("checksum", files)
    assert materialise("checksum", files) == folder  # once per process
    assert sorted(p.name for p in folder.iterdir()) == sorted(files)
    with pytest.raises(ValueError, match="not plain file names"):
        materialise("other", {"../evil": b""})
    (baseline,) = lb.resolve_entries(["mpc"])
    with pytest.raises(ValueError, match="reaches the workers by name"):
        agent_files(baseline, trust=False)


def test_ray_options_need_the_ray_backend(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(leaderboard_argv(out, "--entries", "mpc", "--address", "auto")) == 2
    assert "options of the ray backend" in capsys.readouterr().err
    assert main(leaderboard_argv(out, "--entries", "mpc", "--backend", "ray", "--address", "127.0.0.1:1")) == 2
    assert "cannot connect to the Ray cluster at '127.0.0.1:1'" in capsys.readouterr().err
