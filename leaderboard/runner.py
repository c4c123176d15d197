"""Running the leaderboard: the episodes to compute (cached), in this process or a process pool, then ranking.

:func:`run_leaderboard` is the entry point; the :class:`Backend` says how environments, controllers
(:func:`leaderboard.registry.make_controller`) and episodes (:func:`uvdms_gym.evaluation.run_episode`) are made,
so that tests can substitute fakes.
"""

from __future__ import annotations

import json
import logging
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from leaderboard.cache import CorruptCacheError, cache_key, cache_material, cache_path, compact_result, read_cached
from leaderboard.entries import Entry, check_seed_disjointness
from leaderboard.report import write_outputs
from leaderboard.reuse import CACHE_KEY_FIELD, check_reuse_dir, reusable_results
from leaderboard.stats import RankedRow, aggregate, aggregate_runs, rank_rows
from leaderboard.tasks import DEFAULT_EPISODES, TASKS, TRACKS, Task, evaluation_seeds
from uvdms_gym.utils.io import write_json_atomic
from uvdms_gym.utils.provenance import timing_record

log = logging.getLogger("uvdms.leaderboard")

EXECUTORS: tuple[str, ...] = ("local", "ray")
"""Where episodes run: this machine's processes, or Ray tasks (:mod:`leaderboard.distributed`)."""


@dataclass(frozen=True)
class Backend:
    """How episodes are run (module-level callables, so that worker processes can receive them).

    Attributes:
        make_env: ``(task spec) -> env``.
        make_controller: ``(spec, env, trust) -> controller``.
        run_episode: ``(env, controller, seed, save_trajectory) -> dict`` (per-episode metrics).
    """

    make_env: Callable[[Mapping[str, Any]], Any]
    make_controller: Callable[[str, Any, bool], Any]
    run_episode: Callable[[Any, Any, int, bool], dict[str, Any]]


def make_env(spec: Mapping[str, Any]) -> Any:
    """``gymnasium.make`` of a task spec (:meth:`Task.spec`)."""
    import gymnasium as gym

    kwargs = dict(spec["env_kwargs"])
    if spec.get("max_episode_steps") is not None:
        kwargs["max_episode_steps"] = spec["max_episode_steps"]
    return gym.make(spec["env_id"], **kwargs)


def _real_make_controller(spec: str, env: Any, trust: bool) -> Any:
    from leaderboard.registry import make_controller

    return make_controller(spec, env, trust=trust)


def _real_run_episode(env: Any, controller: Any, seed: int, save_trajectory: bool) -> dict[str, Any]:
    from uvdms_gym.evaluation import run_episode

    return run_episode(env, controller, seed, save_trajectory=save_trajectory)


DEFAULT_BACKEND = Backend(make_env=make_env, make_controller=_real_make_controller, run_episode=_real_run_episode)


@dataclass(frozen=True)
class Job:
    """One episode to compute."""

    entry: Entry
    task: Task
    seed: int
    save_trajectory: bool
    key: str
    material: dict[str, Any]
    path: Path


_WORKER: dict[str, Any] = {}
"""Per-process reuse of the environment (and of stateless agent controllers) across consecutive jobs."""


def worker_setup() -> None:
    """Prepare a worker process for episodes, once: one torch thread, and the last simulator closed at exit."""
    if _WORKER.get("setup"):
        return
    import atexit

    atexit.register(_close_worker_env)  # disconnect the worker's last simulator before interpreter teardown
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # pragma: no cover - torch is a dependency
        pass
    _WORKER["setup"] = True


def _close_worker_env() -> None:
    env = _WORKER.pop("env", None)
    _WORKER.pop("controller", None)
    _WORKER.pop("key", None)
    if env is not None:
        env.close()


def compute_job(job: Job, backend: Backend, trust: bool) -> dict[str, Any]:
    """Run one episode and return its compact result (the driver stores it with :func:`store_result`)."""
    group = (job.entry.name, job.entry.checksum, json.dumps(job.entry.task_spec(job.task), sort_keys=True))
    if _WORKER.get("key") != group:
        _close_worker_env()
        _WORKER["env"] = backend.make_env(job.entry.task_spec(job.task))
        _WORKER["key"] = group
    env = _WORKER["env"]
    # baselines are stateful (adaptive networks, warm starts): a fresh one per episode; so is a residual agent's base
    reusable = job.entry.kind == "agent" and job.entry.residual_base is None
    controller = _WORKER.get("controller") if reusable else None
    if controller is None:
        controller = backend.make_controller(job.entry.spec, env, trust)
        if job.entry.safety_filter:
            from leaderboard.registry import with_safety_filter

            controller = with_safety_filter(controller, env)
        if reusable:
            _WORKER["controller"] = controller
    with timing_record() as timing:
        raw = backend.run_episode(env, controller, job.seed, job.save_trajectory)
    result = compact_result(raw)
    result["seed"] = int(job.seed)
    result["timing"] = timing
    return result


def store_result(job: Job, result: dict[str, Any]) -> dict[str, Any]:
    """Write ``result`` to the job's cache file atomically (only the driver writes the cache) and return it."""
    write_json_atomic(job.path, {"key": job.key, "material": job.material, "result": result}, indent=None)
    return result


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
        from leaderboard.distributed import DEFAULT_MAX_RETRIES, run_on_ray

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
            _close_worker_env()
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


@dataclass
class LeaderboardResult:
    """What :func:`run_leaderboard` computed."""

    rows: list[RankedRow]
    entries: list[Entry]
    tasks: tuple[Task, ...]
    seeds: list[int]
    computed: int
    cached: int
    corrupt: list[Path]
    out_dir: Path
    markdown: str = ""
    timing: dict[str, Any] = field(default_factory=dict)
    reused: int = 0


def plan_jobs(
    entries: Sequence[Entry], tasks: Sequence[Task], seeds: Sequence[int], cache_dir: str | Path
) -> list[Job]:
    """Every (entry, task, seed) episode of the run, grouped by entry and task.

    A multi-seed entry contributes the episodes of each of its members (:meth:`Entry.runs`): the job's entry is
    the member, so each (entry, training seed, task, evaluation seed) episode is cached on its own.
    """
    jobs = []
    for entry in entries:
        for task in tasks:
            if not entry.runs_on(task):
                continue
            for run in entry.runs():
                for i, seed in enumerate(seeds):
                    save = task.trajectory and i == 0
                    material = cache_material(run, task, seed, save)
                    key = cache_key(material)
                    path = cache_path(cache_dir, run, task, seed, key)
                    jobs.append(Job(run, task, seed, save, key, material, path))
    return jobs


def row_for(entry: Entry, task: Task, episodes: Mapping[Entry, Sequence[dict[str, Any]]]) -> RankedRow:
    """The (unranked) row of ``entry`` on ``task`` from the episodes of each of its runs (:meth:`Entry.runs`).

    A single agent or baseline aggregates its episodes (:func:`leaderboard.stats.aggregate`); a multi-seed entry
    its (training seed x episode) matrix (:func:`leaderboard.stats.aggregate_runs`), and its row's episodes are
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
) -> LeaderboardResult:
    """Evaluate ``entries`` on ``tasks`` (cached), rank them per track and task, and write the outputs.

    Args:
        entries: From :func:`resolve_entries`.
        out_dir: Output folder (``leaderboard.md``, ``leaderboard.csv``, ``entries/*.json``, ``plots/*.png``).
        cache_dir: Per-episode cache (default ``<out_dir>/cache``; a ``.gitignore`` inside keeps it out of git).
        tasks: The task suite.
        episodes: Episodes per (entry, task).
        force: Recompute every episode (overwriting the cache).
        trust: Passed to ``make_controller`` (unpickling agents outside ``trained_agents/``).
        jobs: Worker processes (1: in this process).
        progress: Show a tqdm progress bar (stderr).
        plots: Write the PNG plots.
        backend: How environments, controllers and episodes are made (default :data:`DEFAULT_BACKEND`; tests
            substitute a fake one).
        command: The command line, recorded in ``leaderboard.md``.
        executor: ``local`` (this process, or a pool of ``jobs`` processes) or ``ray`` (one Ray task per
            episode, :mod:`leaderboard.distributed`; ``jobs`` is then unused).
        address: Ray cluster to join (``ray`` executor; ``None`` starts a local instance).
        num_cpus: CPUs of the local Ray instance (``ray`` executor without ``address``; default: every core).
        max_retries: Re-runs of an episode whose Ray worker dies (default
            :data:`leaderboard.distributed.DEFAULT_MAX_RETRIES`).
        reuse_from: A previous leaderboard output folder whose recorded episodes are reused for the episodes not
            in the cache (:mod:`leaderboard.reuse`); they are stored in the cache and count as ``reused``.

    Returns:
        The ranked rows and run statistics.

    Raises:
        ValueError: No entries, ``episodes < 1``, evaluation seeds that clash with training seeds, an unknown
            executor, Ray options without the ``ray`` executor, or ``reuse_from`` with ``force``.
        FileNotFoundError: ``reuse_from`` is not a leaderboard output folder.
        ConnectionError: The Ray cluster at ``address`` cannot be reached.
    """
    from tqdm.auto import tqdm

    backend = backend if backend is not None else DEFAULT_BACKEND
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
    out = Path(out_dir)
    cache = Path(cache_dir) if cache_dir is not None else out / "cache"
    seeds = evaluation_seeds(episodes)
    check_seed_disjointness(seeds, entries)
    cache.mkdir(parents=True, exist_ok=True)
    if not (cache / ".gitignore").exists():
        (cache / ".gitignore").write_text("*\n", encoding="utf-8")

    all_jobs = plan_jobs(entries, tasks, seeds, cache)
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
    n_reused = 0
    if reuse_from is not None and todo:
        reused = reusable_results(todo, entries, reuse_from)
        for job in todo:
            if job.path in reused:
                results[job.path] = store_result(job, reused[job.path])
        todo = [job for job in todo if job.path not in reused]
        n_reused = len(reused)
    n_cached = len(all_jobs) - len(todo) - n_reused
    # the model-based baselines' episodes first: they are the long ones (an MPC QP per step), and workers that
    # finish the short agent episodes last leave less idle time at the end (the results do not depend on order)
    todo.sort(key=lambda job: job.entry.kind != "baseline")
    log.info(
        "leaderboard: %d entries, %d tasks, %d episodes each: %d cached, %d reused, %d to compute",
        len(entries),
        len(tasks),
        episodes,
        n_cached,
        n_reused,
        len(todo),
    )
    with timing_record() as run_record:  # the run's machine and load (each episode has its own record)
        bar = tqdm(
            total=len(all_jobs),
            initial=n_cached + n_reused,
            desc="leaderboard",
            unit="ep",
            disable=not progress,
            mininterval=0.1 if sys.stderr.isatty() else 30.0,  # a log file gets a line every 30 s, not every episode
        )
        try:
            finished = _execute(todo, backend, trust, jobs, executor, address, num_cpus, max_retries)
            for job, result in finished:
                results[job.path] = store_result(job, result)
                bar.set_postfix_str(f"{job.entry.name} / {job.task.name}", refresh=False)
                bar.update()
        finally:
            bar.close()

    by_run: dict[tuple[Entry, str], list[dict[str, Any]]] = {}
    for job in all_jobs:  # each episode with its cache key, so that a later run can reuse it from the documents
        by_run.setdefault((job.entry, job.task.name), []).append({**results[job.path], CACHE_KEY_FIELD: job.key})
    rows = []
    for entry in entries:
        for task in tasks:
            if not entry.runs_on(task):
                continue
            rows.append(row_for(entry, task, {run: by_run[run, task.name] for run in entry.runs()}))
    ranked: list[RankedRow] = []
    for track in TRACKS:
        for task in tasks:
            group = [r for r in rows if r.entry.track == track and r.task is task]
            if group:
                ranked.extend(rank_rows(group))
    result = LeaderboardResult(
        rows=ranked,
        entries=list(entries),
        tasks=tuple(tasks),
        seeds=seeds,
        computed=len(todo),
        cached=n_cached,
        reused=n_reused,
        corrupt=corrupt,
        out_dir=out,
        timing=run_record,
    )
    write_outputs(result, command=command, plots=plots)
    return result
