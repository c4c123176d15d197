"""``plan_jobs`` under the seed protocol: which (entry run, task, draw) episodes a leaderboard run computes.

A deterministic task has one draw, which every training seed of an entry runs; the draws of a randomised task are
spread over the training seeds (draw ``i`` to seed ``i % k``), so that ``n`` draws cost ``n`` episodes. Every seed is
of the planned split; the generalisation check's ``test2`` jobs are other seeds than the ranking's.
"""

from __future__ import annotations

from collections import Counter

import pytest

import leaderboard as lb
from leaderboard.running.cache import cache_key, cache_material, cache_path
from leaderboard.running.jobs import plan_jobs
from leaderboard.suite.tasks import CHECK_SPLIT, DEFAULT_EPISODES, DEFAULT_SPLIT, TASKS
from tests.support.leaderboard_fakes import CALLS, FAKE, TINY_TASKS
from tests.support.multiseed_fakes import _multi_seed
from uvdms_gym.seeds import TEST, split_of, split_seeds

DETERMINISTIC, RANDOMISED = TINY_TASKS


@pytest.fixture
def entries(tmp_path):
    """A baseline and a three-seed agent entry."""
    return lb.resolve_entries(["campc", str(_multi_seed(tmp_path / "agents", seeds=(0, 1, 2)))], trust=True)


def test_the_suite_defaults():
    assert (DEFAULT_EPISODES, DEFAULT_SPLIT, CHECK_SPLIT) == (100, "test", "test2")
    assert [t.name for t in TASKS if t.deterministic] == ["case1", "case2", "transport", "coop"]
    assert all(t.paper == (t.deterministic and t.grasp == "rigid") for t in TASKS)  # coop: no paper task
    for task in TASKS:
        assert task.draws("test", 5) == ([TEST.start] if task.deterministic else split_seeds("test", 5))
        assert task.draws("validation", 3) == split_seeds("validation", 1 if task.deterministic else 3)


def test_a_randomised_task_plans_each_draw_once_across_the_training_seeds(tmp_path, entries):
    baseline, multi = entries
    jobs = plan_jobs([multi], [RANDOMISED], "test", 10, tmp_path / "cache")
    draws = split_seeds("test", 10)
    assert sorted(job.seed for job in jobs) == draws  # every draw exactly once: 10 draws, 10 episodes
    for k, member in enumerate(multi.members):
        assert [job.seed for job in jobs if job.entry is member] == [s for i, s in enumerate(draws) if i % 3 == k]
    single = plan_jobs([baseline], [RANDOMISED], "test", 10, tmp_path / "cache")
    assert [job.seed for job in single] == draws and {job.entry for job in single} == {baseline}


def test_a_deterministic_task_is_run_by_every_training_seed_on_its_one_draw(tmp_path, entries):
    baseline, multi = entries
    jobs = plan_jobs(entries, [DETERMINISTIC], "test", 10, tmp_path / "cache")
    assert [(job.entry, job.seed) for job in jobs] == [(run, TEST.start) for run in (baseline, *multi.members)]


def test_jobs_are_grouped_keyed_and_store_the_first_trajectory_of_each_run(tmp_path, entries):
    jobs = plan_jobs(entries, TINY_TASKS, "test", 7, tmp_path / "cache")
    assert len(jobs) == len(entries[1].members) + 1 + 7 * 2  # case1 per run, circle-random's 7 draws per entry
    assert len({job.path for job in jobs}) == len(jobs) and len({job.key for job in jobs}) == len(jobs)
    for job in jobs:
        assert job.split == "test" and split_of(job.seed) == "test"
        material = cache_material(job.entry, job.task, job.seed, job.save_trajectory)
        assert job.material == material and job.key == cache_key(material)
        assert job.path == cache_path(tmp_path / "cache", job.entry, job.task, job.seed, job.key)
    trajectories = Counter((job.entry, job.task.name) for job in jobs if job.save_trajectory)
    runs = [entries[0], *entries[1].members]
    assert trajectories == Counter({(run, task.name): 1 for run in runs for task in TINY_TASKS})
    for run in runs:  # the first planned episode of each run on each task
        first = next(job for job in jobs if job.entry is run and job.task is RANDOMISED)
        assert first.save_trajectory
    order = [(job.entry, job.task.name) for job in jobs]
    assert order == sorted(order, key=lambda pair: order.index(pair))  # each (run, task)'s jobs together
    check = plan_jobs(entries, [RANDOMISED], "test2", 7, tmp_path / "cache", trajectories=False)
    assert len(check) == 7 * 2 and not any(job.save_trajectory for job in check)  # the check plots nothing


@pytest.mark.parametrize("split", ["validation", "test", "test2"])
def test_every_planned_seed_is_of_the_split(tmp_path, entries, split):
    jobs = plan_jobs(entries, TINY_TASKS, split, 20, tmp_path / "cache")
    assert {split_of(job.seed) for job in jobs} == {split} and {job.split for job in jobs} == {split}
    assert {job.material["seed_protocol"]["split"] for job in jobs} == {split}


def test_the_check_jobs_are_disjoint_from_the_test_jobs(tmp_path, entries):
    test = plan_jobs(entries, TINY_TASKS, "test", 20, tmp_path / "cache")
    test2 = plan_jobs(entries, [RANDOMISED], "test2", 20, tmp_path / "cache")
    assert {job.seed for job in test}.isdisjoint(job.seed for job in test2)
    assert {job.path for job in test}.isdisjoint(job.path for job in test2)
    assert {job.key for job in test}.isdisjoint(job.key for job in test2)


def _run(tmp_path, entries, **kwargs):
    """A run of the tiny suite (6 draws of its randomised task) and the seeds of the episodes it computed."""
    CALLS.clear()
    result = lb.run_leaderboard(
        entries,
        out_dir=tmp_path / "out",
        tasks=TINY_TASKS,
        episodes=6,
        progress=False,
        plots=False,
        backend=FAKE,
        **kwargs,
    )
    return result, [seed for _name, seed in CALLS]


def test_a_run_on_the_test_split_adds_the_check_on_test2_for_the_randomised_tasks_only(tmp_path, entries):
    result, seeds = _run(tmp_path, entries)
    assert Counter(split_of(s) for s in seeds) == {"test": 4 + 2 * 6, "test2": 2 * 6}
    assert result.seeds == split_seeds("test", 6) and result.check_seeds == split_seeds("test2", 6)
    rows = {(r.entry.name, r.task.name): r for r in result.rows}
    assert all(rows[name, "case1"].check is None for name in ("campc", "sac_multi"))
    assert all(rows[name, "circle-random"].check is not None for name in ("campc", "sac_multi"))


def test_the_validation_split_plans_no_test_seed_and_no_check(tmp_path, entries):
    jobs = plan_jobs(entries, TASKS, "validation", DEFAULT_EPISODES, tmp_path / "cache")
    assert not any(split_of(job.seed) in ("test", "test2") for job in jobs)
    result, seeds = _run(tmp_path, entries, split="validation")
    assert seeds and {split_of(s) for s in seeds} == {"validation"}
    assert result.split == "validation" and result.check_seeds == [] and all(r.check is None for r in result.rows)
    assert result.seeds == split_seeds("validation", 6)


def test_without_the_check_a_test_run_plans_no_test2_job(tmp_path, entries):
    result, seeds = _run(tmp_path, entries, generalization=False)
    assert {split_of(s) for s in seeds} == {"test"} and len(seeds) == 4 + 2 * 6
    assert result.check_seeds == [] and all(r.check is None for r in result.rows)


@pytest.mark.parametrize("split", ["test2", "training", "nope"])
def test_the_ranking_split_is_test_or_validation(tmp_path, entries, split):
    with pytest.raises(ValueError, match="ranks on the test or validation split"):
        _run(tmp_path, entries, split=split)
