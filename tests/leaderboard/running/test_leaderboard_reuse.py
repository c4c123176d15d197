"""``uvdms leaderboard --reuse DIR``: episodes recorded in an earlier output are reused, and only when they match.

An earlier run's output (its ``entries/*.json``) is the independent record: a second run with an empty cache and
``reuse_from`` must give the same tables while running only the episodes that store a trajectory, and nothing may
be reused for an entry whose model, name or package version differs.
"""

from __future__ import annotations

import json
import logging
import zipfile
from pathlib import Path

import pytest

import leaderboard as lb
import leaderboard.running.cache
import leaderboard.running.reuse
from leaderboard.running.jobs import plan_jobs
from leaderboard.running.reuse import reusable_results
from leaderboard.suite.tasks import evaluation_seeds
from tests.support.leaderboard_fakes import CALLS, FAKE, TINY_TASKS
from tests.support.multiseed_fakes import _multi_seed

EPISODES = 3


def _run(out: Path, entries, **kwargs):
    CALLS.clear()
    return lb.run_leaderboard(
        entries, out_dir=out, tasks=TINY_TASKS, episodes=EPISODES, progress=False, plots=False, backend=FAKE, **kwargs
    )


@pytest.fixture
def entries(tmp_path):
    """The four baselines and a three-seed agent entry."""
    return lb.resolve_entries(["baselines", str(_multi_seed(tmp_path / "agents", seeds=(0, 1, 2)))], trust=True)


def _n_runs(entries) -> int:
    return sum(len(e.runs()) for e in entries)


def _trajectory_jobs(entries) -> int:
    """Episodes that store a trajectory: the first evaluation seed of each task with a distance plot, per run."""
    return _n_runs(entries) * sum(t.trajectory for t in TINY_TASKS)


def _untimed(episode: dict) -> dict:
    return {k: v for k, v in episode.items() if k != "timing"}


def test_reuse_gives_the_same_tables_and_runs_only_the_trajectory_episodes(tmp_path, entries):
    first = _run(tmp_path / "first", entries)
    n = _n_runs(entries) * len(TINY_TASKS) * EPISODES
    assert first.computed == n
    second = _run(tmp_path / "second", entries, reuse_from=tmp_path / "first")
    assert second.computed == len(CALLS) == _trajectory_jobs(entries) > 0
    assert second.reused == n - _trajectory_jobs(entries) and second.cached == 0
    assert lb.markdown_tables(second) == lb.markdown_tables(first)
    for doc in (tmp_path / "first" / "entries").glob("*.json"):  # the documents agree episode by episode
        again = json.loads((tmp_path / "second" / "entries" / doc.name).read_text())["tasks"]
        for name, row in json.loads(doc.read_text())["tasks"].items():
            assert again[name]["stats"] == row["stats"]
            # (the recomputed trajectory episodes carry this run's load record)
            assert [_untimed(ep) for ep in again[name]["episodes"]] == [_untimed(ep) for ep in row["episodes"]]
    # the reused episodes went into the cache: a third run computes nothing
    third = _run(tmp_path / "second", entries)
    assert third.computed == 0 and third.cached == n and CALLS == []


def test_documents_record_each_episode_cache_key(tmp_path, entries):
    _run(tmp_path / "out", entries)
    doc = json.loads((tmp_path / "out" / "entries" / "sac_multi.json").read_text())
    episode = doc["tasks"]["case2"]["episodes"][4]  # training seed 1, second evaluation seed
    member = next(e for e in entries if e.name == "sac_multi").members[1]
    task = TINY_TASKS[1]
    material = leaderboard.running.cache.cache_material(member, task, episode["seed"], False)
    assert episode["training_seed"] == 1 and episode["cache_key"] == leaderboard.running.cache.cache_key(material)


def test_an_entry_with_another_model_is_not_reused(tmp_path, entries):
    _run(tmp_path / "first", entries)
    seed_1 = tmp_path / "agents" / "sac_multi" / "seed_1" / "final_model.zip"
    with zipfile.ZipFile(seed_1, "w") as archive:  # seed 1 retrained: another checksum
        archive.writestr("data", json.dumps({"seed": 1, "retrained": True}))
    changed = lb.resolve_entries(["baselines", str(seed_1.parents[1])], trust=True)
    second = _run(tmp_path / "second", changed, reuse_from=tmp_path / "first")
    again = [seed for name, seed in CALLS if name == str(seed_1.parent)]
    assert len(again) == len(TINY_TASKS) * EPISODES  # every episode of the retrained seed ran again
    assert second.computed == _trajectory_jobs(changed) + len(again) - sum(t.trajectory for t in TINY_TASKS)


def _strip_keys(out: Path) -> None:
    """Make ``out``'s documents look like those of a leaderboard from before episodes carried their keys."""
    for path in (out / "entries").glob("*.json"):
        doc = json.loads(path.read_text())
        for row in doc["tasks"].values():
            for ep in row["episodes"]:
                del ep["cache_key"]
        path.write_text(json.dumps(doc))


def test_keyless_documents_are_matched_on_name_checksum_version_and_seeds_with_a_warning(tmp_path, entries, caplog):
    first = _run(tmp_path / "first", entries)
    _strip_keys(tmp_path / "first")
    with caplog.at_level(logging.WARNING, logger="leaderboard.running.reuse"):
        second = _run(tmp_path / "second", entries, reuse_from=tmp_path / "first")
    assert second.computed == _trajectory_jobs(entries)
    assert lb.markdown_tables(second) == lb.markdown_tables(first)
    assert "records no cache keys" in caplog.text and "sac_multi.json" in caplog.text


def test_keyless_documents_of_another_package_version_or_checksum_are_not_used(tmp_path, entries, release):
    _run(tmp_path / "first", entries)
    _strip_keys(tmp_path / "first")
    path = tmp_path / "first" / "entries" / "sac_multi.json"
    doc = json.loads(path.read_text())
    doc["seeds"][0]["checksum"] = "0" * 64
    path.write_text(json.dumps(doc))
    second = _run(tmp_path / "second", entries, reuse_from=tmp_path / "first")
    runs_per_task = len(TINY_TASKS) * EPISODES - sum(t.trajectory for t in TINY_TASKS)
    assert second.computed == _trajectory_jobs(entries) + runs_per_task  # sac_multi's seed 0 only
    release("9.9.9")  # keyless documents record neither environment spec nor solver build: kept per version
    third = _run(tmp_path / "third", entries, reuse_from=tmp_path / "first")
    assert third.reused == 0


def test_bad_reuse_arguments_name_the_problem(tmp_path, entries):
    with pytest.raises(FileNotFoundError, match="not a leaderboard output folder"):
        _run(tmp_path / "out", entries, reuse_from=tmp_path / "nowhere")
    _run(tmp_path / "out", entries)  # every episode cached now: the folder is still checked
    with pytest.raises(FileNotFoundError, match="not a leaderboard output folder"):
        _run(tmp_path / "out", entries, reuse_from=tmp_path / "nowhere")
    with pytest.raises(ValueError, match="cannot be combined"):
        _run(tmp_path / "out", entries, reuse_from=tmp_path / "nowhere", force=True)
    _run(tmp_path / "first", entries)
    (tmp_path / "first" / "entries" / "mpc.json").write_text("{truncated")
    with pytest.raises(ValueError, match=r"mpc\.json is not valid JSON"):
        _run(tmp_path / "second", entries, reuse_from=tmp_path / "first")


COMMITTED = Path(__file__).resolve().parents[3] / "docs" / "leaderboard"


def test_the_committed_leaderboard_is_reused_after_a_version_bump(tmp_path, release):
    """Its documents (written by 0.1.0, whose keys hashed the version) are found in full by a release of 0.4.0."""
    documents = [json.loads(p.read_text()) for p in sorted((COMMITTED / "entries").glob("*.json"))]
    tokens = ["baselines", "agents", "campc-inner", "hold"]
    shipped = COMMITTED.parents[1] / "trained_agents"
    tokens += [f"{shipped / doc['spec']}+filter" for doc in documents if doc["name"].endswith("+filter")]
    release("0.4.0")
    entries = lb.resolve_entries(tokens)
    assert sorted(e.name for e in entries) == sorted(doc["name"] for doc in documents)
    jobs = plan_jobs(entries, lb.TASKS, evaluation_seeds(lb.DEFAULT_EPISODES), tmp_path / "cache")
    found = reusable_results(jobs, entries, COMMITTED)
    missing = [(job.entry.name, job.task.name, job.seed) for job in jobs if job.path not in found]
    assert len(missing) == sum(job.save_trajectory for job in jobs), missing[:5]  # only those that plot a trajectory
    assert len(found) == len(jobs) - sum(job.save_trajectory for job in jobs) > 4000
