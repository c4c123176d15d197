"""``uvdms leaderboard --reuse DIR``: episodes recorded in an earlier output are reused, and only when they match.

An earlier run's output (its ``entries/*.json``) is the independent record: a second run with an empty cache and
``reuse_from`` must give the same tables while running only the episodes that store a trajectory, and nothing may
be reused for an entry whose model, name or package version differs. Keys of the formats before the seed protocol
(3, and 2 with the package version) match too; an older leaderboard's episodes are validation draws now, so a run on
the test split finds none of them.
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
from tests.support.leaderboard_fakes import CALLS, FAKE, TINY_TASKS, planned_episodes
from tests.support.multiseed_fakes import _multi_seed
from uvdms_gym.seeds import TEST, TEST2, VALIDATION, split_of, split_seeds

EPISODES = 6
"""Draws of the randomised task: each of the three training seeds gets two of each test set, the first of which
stores a trajectory."""


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
    """Episodes that store a trajectory: the first draw of each run on each task with a distance plot.

    Both tiny tasks have one: the deterministic ``case1`` (its one draw, every run) and the randomised
    ``circle-random`` on the ranking's draws (the generalisation check's store none).
    """
    assert all(t.trajectory for t in TINY_TASKS) and EPISODES >= max(len(e.runs()) for e in entries)
    return _n_runs(entries) * 2


def _untimed(episode: dict) -> dict:
    return {k: v for k, v in episode.items() if k != "timing"}


def _same_documents(first: Path, second: Path) -> None:
    """The documents of two outputs agree: statistics, checks and episodes (but the episodes' load records)."""
    for doc in (first / "entries").glob("*.json"):
        again = json.loads((second / "entries" / doc.name).read_text())["tasks"]
        for name, row in json.loads(doc.read_text())["tasks"].items():
            assert again[name]["stats"] == row["stats"]
            # (the recomputed trajectory episodes carry this run's load record)
            assert [_untimed(ep) for ep in again[name]["episodes"]] == [_untimed(ep) for ep in row["episodes"]]
            assert ("check" in again[name]) == ("check" in row)
            if "check" in row:  # the generalisation check: the same figures from the same test2 episodes
                summary = {k: v for k, v in row["check"].items() if k != "episodes"}
                assert {k: v for k, v in again[name]["check"].items() if k != "episodes"} == summary
                episodes = [_untimed(ep) for ep in row["check"]["episodes"]]
                assert [_untimed(ep) for ep in again[name]["check"]["episodes"]] == episodes


def test_reuse_gives_the_same_tables_and_runs_only_the_trajectory_episodes(tmp_path, entries):
    first = _run(tmp_path / "first", entries)
    n = planned_episodes(entries, episodes=EPISODES)
    assert first.computed == n == (4 + 3) * 1 + 5 * 2 * EPISODES  # case1 per run; circle-random per entry, twice
    second = _run(tmp_path / "second", entries, reuse_from=tmp_path / "first")
    assert second.computed == len(CALLS) == _trajectory_jobs(entries) > 0
    assert second.reused == n - _trajectory_jobs(entries) and second.cached == 0
    # the generalisation check's episodes too (the documents record them under each task's check)
    assert [seed for _name, seed in CALLS if split_of(seed) == "test2"] == []
    assert lb.markdown_tables(second) == lb.markdown_tables(first)
    _same_documents(tmp_path / "first", tmp_path / "second")
    # the reused episodes went into the cache: a third run computes nothing
    third = _run(tmp_path / "second", entries)
    assert third.computed == 0 and third.cached == n and CALLS == []


def test_documents_record_each_episode_cache_key(tmp_path, entries):
    _run(tmp_path / "out", entries)
    doc = json.loads((tmp_path / "out" / "entries" / "sac_multi.json").read_text())
    member = next(e for e in entries if e.name == "sac_multi").members[1]
    task = TINY_TASKS[1]  # randomised: training seed 1 evaluates draws 1 and 4 of each test set
    row = doc["tasks"][task.name]
    checked = [(row["episodes"], TEST.start, (True, False)), (row["check"]["episodes"], TEST2.start, (False, False))]
    for episodes, start, trajectories in checked:
        mine = [ep for ep in episodes if ep["training_seed"] == 1]
        assert [ep["seed"] for ep in mine] == [start + 1, start + 4]
        for episode, trajectory in zip(mine, trajectories):  # its first test draw stores a trajectory
            material = leaderboard.running.cache.cache_material(member, task, episode["seed"], trajectory)
            assert episode["cache_key"] == leaderboard.running.cache.cache_key(material)
    episode = doc["tasks"]["case1"]["episodes"][1]  # deterministic: every training seed runs the one draw
    material = leaderboard.running.cache.cache_material(member, TINY_TASKS[0], TEST.start, True)
    assert episode["training_seed"] == 1 and episode["cache_key"] == leaderboard.running.cache.cache_key(material)


def test_an_entry_with_another_model_is_not_reused(tmp_path, entries):
    _run(tmp_path / "first", entries)
    seed_1 = tmp_path / "agents" / "sac_multi" / "seed_1" / "final_model.zip"
    with zipfile.ZipFile(seed_1, "w") as archive:  # seed 1 retrained: another checksum
        archive.writestr("data", json.dumps({"seed": 1, "retrained": True}))
    changed = lb.resolve_entries(["baselines", str(seed_1.parents[1])], trust=True)
    second = _run(tmp_path / "second", changed, reuse_from=tmp_path / "first")
    again = sorted(seed for name, seed in CALLS if name == str(seed_1.parent))
    # every episode of the retrained seed ran again: case1, its draws 1 and 4 of test and of test2
    assert again == [TEST.start, TEST.start + 1, TEST.start + 4, TEST2.start + 1, TEST2.start + 4]
    assert second.computed == _trajectory_jobs(changed) + 3  # (its test draw 4 and test2 draws store no trajectory)


def test_keys_of_the_format_before_the_seed_protocol_are_matched(tmp_path, entries):
    """Documents whose keys are format 3's (no seed protocol hashed), written out here independently."""
    first = _run(tmp_path / "first", entries, split="validation")
    assert first.check_seeds == [] and {split_of(s) for s in first.seeds} == {"validation"}
    runs = {run.name: run for entry in entries for run in entry.runs()}
    tasks = {t.name: t for t in TINY_TASKS}
    for path in (tmp_path / "first" / "entries").glob("*.json"):
        doc = json.loads(path.read_text())
        for name, row in doc["tasks"].items():
            assert "check" not in row and row["seed_protocol"]["split"] == "validation"
            for ep in row["episodes"]:
                run = runs[doc["name"] if "training_seed" not in ep else f"{doc['name']}/seed_{ep['training_seed']}"]
                material = {
                    "format": 3,
                    "entry": run.identity(),
                    "task": run.task_spec(tasks[name]),
                    "seed": ep["seed"],
                    "trajectory": False,  # (those with one are not reused: their trajectory is not in the document)
                }
                if run.kind == "baseline":
                    material["qp_solver"] = leaderboard.running.cache.PROXSUITE_BUILD
                ep["cache_key"] = leaderboard.running.cache.cache_key(material)
        path.write_text(json.dumps(doc))
    second = _run(tmp_path / "second", entries, split="validation", reuse_from=tmp_path / "first")
    assert second.computed == len(CALLS) == _trajectory_jobs(entries)
    assert lb.markdown_tables(second) == lb.markdown_tables(first)
    # the same documents on the test split: other draws, nothing to reuse
    third = _run(tmp_path / "third", entries, reuse_from=tmp_path / "first", generalization=False)
    assert third.reused == 0 and third.computed == planned_episodes(entries, episodes=EPISODES, check=False)


def _strip_keys(out: Path) -> None:
    """Make ``out``'s documents look like those of a leaderboard from before episodes carried their keys."""
    for path in (out / "entries").glob("*.json"):
        doc = json.loads(path.read_text())
        for row in doc["tasks"].values():
            for ep in row["episodes"]:
                del ep["cache_key"]
        path.write_text(json.dumps(doc))


def test_keyless_documents_are_matched_on_name_checksum_version_and_seeds_with_a_warning(tmp_path, entries, caplog):
    # a leaderboard from before the keys ranked on what are validation draws now (and had no generalisation check)
    first = _run(tmp_path / "first", entries, split="validation")
    _strip_keys(tmp_path / "first")
    with caplog.at_level(logging.WARNING, logger="leaderboard.running.reuse"):
        second = _run(tmp_path / "second", entries, split="validation", reuse_from=tmp_path / "first")
    assert second.computed == _trajectory_jobs(entries)
    assert lb.markdown_tables(second) == lb.markdown_tables(first)
    assert "records no cache keys" in caplog.text and "sac_multi.json" in caplog.text


def test_keyless_documents_of_another_package_version_or_checksum_are_not_used(tmp_path, entries, release):
    _run(tmp_path / "first", entries, split="validation")
    _strip_keys(tmp_path / "first")
    path = tmp_path / "first" / "entries" / "sac_multi.json"
    doc = json.loads(path.read_text())
    doc["seeds"][0]["checksum"] = "0" * 64
    path.write_text(json.dumps(doc))
    second = _run(tmp_path / "second", entries, split="validation", reuse_from=tmp_path / "first")
    # sac_multi's seed 0 only: its circle-random draw 3 (its draw 0 and case1 store a trajectory)
    assert sorted(seed for name, seed in CALLS if name.endswith("seed_0")) == [
        VALIDATION.start,
        VALIDATION.start,
        VALIDATION.start + 3,
    ]
    assert second.computed == _trajectory_jobs(entries) + 1
    release("9.9.9")  # keyless documents record neither environment spec nor solver build: kept per version
    third = _run(tmp_path / "third", entries, split="validation", reuse_from=tmp_path / "first")
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
    """Its documents (written by 0.1.0, whose keys hashed the version) are found in full by a release of 0.4.0.

    A leaderboard from before the seed protocol ranked on the evaluation seeds ``2_000_000_000 + i``, validation
    draws now: a run on the validation split finds every episode it plans (but those that plot a trajectory), a run
    on the test split none. (Once the committed leaderboard is one of the protocol, the same holds of its split.)
    """
    documents = [json.loads(p.read_text()) for p in sorted((COMMITTED / "entries").glob("*.json"))]
    rows = [row for doc in documents for row in doc["tasks"].values()]
    split = next((row["seed_protocol"]["split"] for row in rows if "seed_protocol" in row), "validation")
    other = "test" if split == "validation" else "validation"
    tokens = ["baselines", "agents", "campc-inner", "hold"]
    tokens += ["realism"] if any(doc["name"] == "campc-privileged" for doc in documents) else []
    tokens += ["coop"] if any(doc["name"] == "campc-coop" for doc in documents) else []
    shipped = COMMITTED.parents[1] / "trained_agents"
    tokens += [f"{shipped / doc['spec']}+filter" for doc in documents if doc["name"].endswith("+filter")]
    release("0.4.0")
    entries = lb.resolve_entries(tokens)
    assert sorted(e.name for e in entries) == sorted(doc["name"] for doc in documents)
    recorded = {ep["seed"] for row in rows for ep in row["episodes"]}
    episodes = len(recorded)  # the draws of a randomised task (the deterministic tasks have the first)
    assert sorted(recorded) == split_seeds(split, episodes)
    tasks = [t for t in lb.TASKS if any(t.name in doc["tasks"] for doc in documents)]  # the tasks it has run
    jobs = plan_jobs(entries, tasks, split, episodes, tmp_path / "cache")
    found = reusable_results(jobs, entries, COMMITTED)
    missing = [(job.entry.name, job.task.name, job.seed) for job in jobs if job.path not in found]
    assert len(missing) == sum(job.save_trajectory for job in jobs), missing[:5]  # only those that plot a trajectory
    assert len(found) == len(jobs) - sum(job.save_trajectory for job in jobs) > 900
    assert reusable_results(plan_jobs(entries, tasks, other, episodes, tmp_path / "cache"), entries, COMMITTED) == {}
