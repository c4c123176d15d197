"""Running the leaderboard: the episodes to compute (cached), in this process or a process pool, then ranking.

:func:`run_leaderboard` is the entry point; the episodes are :mod:`leaderboard.running.jobs` (the :class:`Backend` there
says how environments, controllers and episodes are made, so that tests can substitute fakes), the result a
:class:`leaderboard.stats.result.LeaderboardResult`.
"""

from __future__ import annotations

import functools
import logging
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from leaderboard.output.report import write_outputs
from leaderboard.running.cache import CorruptCacheError, read_cached
from leaderboard.running.jobs import (
    DEFAULT_BACKEND,
    Backend,
    Job,
    close_worker_env,
    compute_job,
    plan_jobs,
    store_result,
    worker_setup,
)
from leaderboard.running.lock import output_lock
from leaderboard.running.reuse import CACHE_KEY_FIELD, check_reuse_dir, reusable_results
from leaderboard.stats.generalization import generalization_check
from leaderboard.stats.metrics import aggregate, aggregate_runs
from leaderboard.stats.ranking import RankedRow, rank_rows
from leaderboard.stats.result import LeaderboardResult
from leaderboard.suite.entries import Entry, check_seed_disjointness
from leaderboard.suite.tasks import CHECK_SPLIT, DEFAULT_EPISODES, DEFAULT_SPLIT, TASKS, TRACKS, Task
from uvdms_gym.seeds import EVALUATION_SPLITS, split_seeds
from uvdms_gym.utils.provenance import timing_record

log = logging.getLogger("uvdms.leaderboard")

EXECUTORS: tuple[str, ...] = ("local", "ray")
"""Where episodes run: this machine's processes, or Ray tasks (:mod:`leaderboard.running.distributed`)."""


def _execute(
    todo: Sequence[Job],
    backend: Backend,
    trust: bool,
    jobs: int,
    executor: str,
    address: str | None,
    num_cpus: int | None,
    max_retries: int | None,
) -> Iterator[tuple[Job, dict[str, Any]]]:
    """Compute the episodes of ``todo`` and yield ``(job, result)`` as each finishes (the caller stores them)."""
    if not todo:  # everything cached: no worker, no Ray instance
        return
    if executor == "ray":
        from leaderboard.running.distributed import DEFAULT_MAX_RETRIES, run_on_ray

        retries = DEFAULT_MAX_RETRIES if max_retries is None else max_retries
        yield from run_on_ray(todo, backend, trust, address=address, num_cpus=num_cpus, max_retries=retries)
        return
    if jobs <= 1 or len(todo) <= 1:
        try:
            for job in todo:
                try:
                    result = compute_job(job, backend, trust)
                except Exception:
                    log.error("episode failed: %s on %s, seed %d", job.entry.name, job.task.name, job.seed)
                    raise
                yield job, result
        finally:
            close_worker_env()
        return
    import multiprocessing

    context = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=worker_setup)
    try:
        futures = {pool.submit(compute_job, job, backend, trust): job for job in todo}
        for future in as_completed(futures):
            job = futures[future]
            try:
                result = future.result()
            except Exception:
                log.error("episode failed: %s on %s, seed %d", job.entry.name, job.task.name, job.seed)
                raise
            yield job, result
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def row_for(entry: Entry, task: Task, episodes: Mapping[Entry, Sequence[dict[str, Any]]]) -> RankedRow:
    """The (unranked) row of ``entry`` on ``task`` from the episodes of each of its runs (:meth:`Entry.runs`).

    A single agent or baseline aggregates its episodes (:func:`leaderboard.stats.metrics.aggregate`); a multi-seed entry
    its (training seed x episode) matrix (:func:`leaderboard.stats.metrics.aggregate_runs`), and its row's episodes are
    those of every seed, each with its ``training_seed``.
    """
    if not entry.multi_seed:
        own = list(episodes[entry])
        return RankedRow(entry, task, aggregate(own), own)
    runs = [list(episodes[member]) for member in entry.members]
    flat = [{**ep, "training_seed": member.training_seed} for member, run in zip(entry.members, runs) for ep in run]
    return RankedRow(entry, task, aggregate_runs(runs), flat)


def run_leaderboard(
    entries: Sequence[Entry],
    *,
    out_dir: str | Path = "leaderboard_out",
    cache_dir: str | Path | None = None,
    tasks: Sequence[Task] = TASKS,
    episodes: int = DEFAULT_EPISODES,
    force: bool = False,
    trust: bool = False,
    jobs: int = 1,
    progress: bool = True,
    plots: bool = True,
    backend: Backend | None = None,
    command: str | None = None,
    executor: str = "local",
    address: str | None = None,
    num_cpus: int | None = None,
    max_retries: int | None = None,
    reuse_from: str | Path | None = None,
    split: str = DEFAULT_SPLIT,
    generalization: bool = True,
) -> LeaderboardResult:
    """Evaluate ``entries`` on ``tasks`` (cached), rank them per track and task, and write the outputs.

    Args:
        entries: From :func:`resolve_entries`.
        out_dir: Output folder (``leaderboard.md``, ``leaderboard.csv``, ``entries/*.json``, ``plots/*.png``).
        cache_dir: Per-episode cache (default ``<out_dir>/cache``; a ``.gitignore`` inside keeps it out of git).
        tasks: The task suite.
        episodes: Draws of each randomised task (:meth:`Task.draws`; a deterministic task has one), spread over
            the training seeds of a multi-seed entry (:func:`leaderboard.running.jobs.plan_jobs`).
        force: Recompute every episode (overwriting the cache).
        trust: Passed to ``make_controller`` (unpickling agents outside ``trained_agents/``).
        jobs: Worker processes (1: in this process).
        progress: Show a tqdm progress bar (stderr).
        plots: Write the PNG plots.
        backend: How environments, controllers and episodes are made (default :data:`DEFAULT_BACKEND`; tests
            substitute a fake one).
        command: The command line, recorded in ``leaderboard.md``.
        executor: ``local`` (this process, or a pool of ``jobs`` processes) or ``ray`` (one Ray task per
            episode, :mod:`leaderboard.running.distributed`; ``jobs`` is then unused).
        address: Ray cluster to join (``ray`` executor; ``None`` starts a local instance).
        num_cpus: CPUs of the local Ray instance (``ray`` executor without ``address``; default: every core).
        max_retries: Re-runs of an episode whose Ray worker dies (default
            :data:`leaderboard.running.distributed.DEFAULT_MAX_RETRIES`).
        reuse_from: A previous leaderboard output folder whose recorded episodes are reused for the episodes not
            in the cache (:mod:`leaderboard.running.reuse`); they are stored in the cache and count as ``reused``.
        split: The seed split the ranking uses (:mod:`uvdms_gym.seeds`): ``test`` (the published leaderboard) or
            ``validation`` (development).
        generalization: With ``split="test"``, also run the randomised tasks on the second test set and compare
            (:mod:`leaderboard.stats.generalization`).

    Returns:
        The ranked rows and run statistics.

    Raises:
        ValueError: No entries, ``episodes < 1``, an unknown split, evaluation seeds that clash with training
            seeds, an unknown executor, Ray options without the ``ray`` executor, or ``reuse_from`` with ``force``.
        FileNotFoundError: ``reuse_from`` is not a leaderboard output folder.
        OutputFolderInUseError: Another run is writing ``out_dir`` (:mod:`leaderboard.running.lock`).
        ConnectionError: The Ray cluster at ``address`` cannot be reached.
    """
    backend = backend if backend is not None else DEFAULT_BACKEND
    _check_options(entries, episodes, executor, address, num_cpus, max_retries, jobs, force, reuse_from, split)
    out = Path(out_dir)
    with output_lock(out):  # one run per output folder: a second one refuses
        cache = _prepare_cache(Path(cache_dir) if cache_dir is not None else out / "cache")
        all_jobs, seeds, check_seeds = _plan(entries, tasks, split, episodes, generalization, cache)
        results, corrupt, todo, n_reused = _to_compute(all_jobs, entries, force, reuse_from)
        n_cached = len(all_jobs) - len(todo) - n_reused
        log.info(
            "leaderboard (%s split): %d entries, %d tasks, %d draws per randomised task%s: %d cached, %d reused, "
            "%d to compute",
            *(split, len(entries), len(tasks), episodes),
            f" (and {len(check_seeds)} of {CHECK_SPLIT})" if check_seeds else "",
            *(n_cached, n_reused, len(todo)),
        )
        with timing_record() as run_record:  # the run's machine and load (each episode has its own record)
            execute = functools.partial(
                _execute,
                backend=backend,
                trust=trust,
                jobs=jobs,
                executor=executor,
                address=address,
                num_cpus=num_cpus,
                max_retries=max_retries,
            )
            _compute(todo, len(all_jobs), n_cached + n_reused, execute, results, progress)
        result = LeaderboardResult(
            rows=_ranked_rows(all_jobs, results, entries, tasks, split),
            entries=list(entries),
            tasks=tuple(tasks),
            seeds=seeds,
            split=split,
            check_seeds=check_seeds,
            computed=len(todo),
            cached=n_cached,
            reused=n_reused,
            corrupt=corrupt,
            out_dir=out,
            timing=run_record,
        )
        write_outputs(result, command=command, plots=plots)
        return result


def _check_options(
    entries: Sequence[Entry],
    episodes: int,
    executor: str,
    address: str | None,
    num_cpus: int | None,
    max_retries: int | None,
    jobs: int,
    force: bool,
    reuse_from: str | Path | None,
    split: str,
) -> None:
    """The argument checks of :func:`run_leaderboard` (its ``Raises``), before anything runs or is written."""
    if split not in EVALUATION_SPLITS or split == CHECK_SPLIT:
        raise ValueError(f"the leaderboard ranks on the test or validation split, not {split!r}")
    if not entries:
        raise ValueError("no entries to evaluate")
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if executor not in EXECUTORS:
        raise ValueError(f"executor must be one of {EXECUTORS}, got {executor!r}")
    if executor != "ray" and (address is not None or num_cpus is not None or max_retries is not None):
        raise ValueError("address, num_cpus and max_retries are options of the ray backend")
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    if force and reuse_from is not None:
        raise ValueError("force recomputes every episode: it cannot be combined with reuse_from")
    if reuse_from is not None:
        check_reuse_dir(reuse_from)


def _plan(
    entries: Sequence[Entry], tasks: Sequence[Task], split: str, episodes: int, generalization: bool, cache: Path
) -> tuple[list[Job], list[int], list[int]]:
    """``(jobs, the split's draws, the check's draws)`` of a run, the seeds checked against the training seeds.

    The jobs are the ranking's episodes on ``split`` and, with ``generalization`` on the test split, the randomised
    tasks' on the second test set.
    """
    seeds = split_seeds(split, episodes)
    checked = generalization and split == DEFAULT_SPLIT
    check_tasks = [t for t in tasks if not t.deterministic and t.check] if checked else []
    check_seeds = split_seeds(CHECK_SPLIT, episodes) if check_tasks else []
    check_seed_disjointness(seeds + check_seeds, entries)
    jobs = plan_jobs(entries, tasks, split, episodes, cache)
    jobs += plan_jobs(entries, check_tasks, CHECK_SPLIT, episodes, cache, trajectories=False)
    return jobs, seeds, check_seeds


def _prepare_cache(cache: Path) -> Path:
    """The cache folder, created, with a ``.gitignore`` that keeps it out of git."""
    cache.mkdir(parents=True, exist_ok=True)
    if not (cache / ".gitignore").exists():
        (cache / ".gitignore").write_text("*\n", encoding="utf-8")
    return cache


def _read_cache(all_jobs: Sequence[Job], force: bool) -> tuple[dict[Path, dict[str, Any]], list[Path], list[Job]]:
    """``(results by cache file, corrupt cache files, jobs to compute)``: every job is to compute with ``force``."""
    results: dict[Path, dict[str, Any]] = {}
    corrupt: list[Path] = []
    todo: list[Job] = []
    for job in all_jobs:
        if force:
            todo.append(job)
            continue
        try:
            results[job.path] = read_cached(job.path, job.key)
        except FileNotFoundError:
            todo.append(job)
        except (CorruptCacheError, OSError, UnicodeDecodeError) as exc:
            log.warning("corrupt cached result %s (%s): recomputing", job.path, exc)
            corrupt.append(job.path)
            todo.append(job)
    return results, corrupt, todo


def _to_compute(
    all_jobs: Sequence[Job], entries: Sequence[Entry], force: bool, reuse_from: str | Path | None
) -> tuple[dict[Path, dict[str, Any]], list[Path], list[Job], int]:
    """``(results found, corrupt cache files, jobs to compute, episodes reused)``: the cache, then ``reuse_from``.

    The jobs to compute come baselines first: they are the long ones (an MPC QP per step), and workers that finish
    the short agent episodes last leave less idle time at the end (the results do not depend on order).
    """
    results, corrupt, todo = _read_cache(all_jobs, force)
    n_reused = 0
    if reuse_from is not None and todo:
        todo, n_reused = _reuse(todo, entries, reuse_from, results)
    todo.sort(key=lambda job: job.entry.kind != "baseline")
    return results, corrupt, todo, n_reused


def _reuse(
    todo: list[Job], entries: Sequence[Entry], reuse_from: str | Path, results: dict[Path, dict[str, Any]]
) -> tuple[list[Job], int]:
    """Store the episodes an earlier output recorded into the cache and ``results``; the jobs left, and how many."""
    reused = reusable_results(todo, entries, reuse_from)
    for job in todo:
        if job.path in reused:
            results[job.path] = store_result(job, reused[job.path])
    return [job for job in todo if job.path not in reused], len(reused)


def _compute(
    todo: Sequence[Job],
    total: int,
    done: int,
    execute: Callable[[Sequence[Job]], Iterator[tuple[Job, dict[str, Any]]]],
    results: dict[Path, dict[str, Any]],
    progress: bool,
) -> None:
    """Compute ``todo`` with ``execute`` and store each result as it finishes, behind a progress bar."""
    from tqdm.auto import tqdm

    bar = tqdm(
        total=total,
        initial=done,
        desc="leaderboard",
        unit="ep",
        disable=not progress,
        mininterval=0.1 if sys.stderr.isatty() else 30.0,  # a log file gets a line every 30 s, not every episode
    )
    try:
        for job, result in execute(todo):
            results[job.path] = store_result(job, result)
            bar.set_postfix_str(f"{job.entry.name} / {job.task.name}", refresh=False)
            bar.update()
    finally:
        bar.close()


def _ranked_rows(
    all_jobs: Sequence[Job],
    results: dict[Path, dict[str, Any]],
    entries: Sequence[Entry],
    tasks: Sequence[Task],
    split: str,
) -> list[RankedRow]:
    """The rows of every entry on every task it runs on, ranked per track and task, with their generalisation checks."""
    by_run: dict[tuple[str, Entry, str], list[dict[str, Any]]] = {}
    for job in all_jobs:  # each episode with its cache key, so that a later run can reuse it from the documents
        episode = {**results[job.path], CACHE_KEY_FIELD: job.key}
        by_run.setdefault((job.split, job.entry, job.task.name), []).append(episode)
    rows = []
    for entry in entries:
        for task in tasks:
            if not entry.runs_on(task):
                continue
            row = row_for(entry, task, {run: by_run.get((split, run, task.name), []) for run in entry.runs()})
            if (CHECK_SPLIT, entry.runs()[0], task.name) in by_run:
                _attach_check(row, entry, task, by_run, split)
            rows.append(row)
    ranked: list[RankedRow] = []
    for track in TRACKS:
        for task in tasks:
            group = [r for r in rows if r.entry.track == track and r.task is task]
            if group:
                ranked.extend(rank_rows(group))
    return ranked


def _attach_check(
    row: RankedRow, entry: Entry, task: Task, by_run: Mapping[tuple[str, Entry, str], list[dict[str, Any]]], split: str
) -> None:
    """Add the generalisation check (``split`` against the second test set) and its episodes to ``row``."""
    runs = entry.runs()
    first = [by_run.get((split, run, task.name), []) for run in runs]  # (a seed beyond the draws has none)
    second = [by_run.get((CHECK_SPLIT, run, task.name), []) for run in runs]
    row.check = generalization_check(first, second)
    row.check_episodes = [
        {**ep, "training_seed": run.training_seed} if entry.multi_seed else ep
        for run, episodes in zip(runs, second)
        for ep in episodes
    ]
