"""The leaderboard's episodes as jobs: what one episode is, how a worker computes it, and the plan of a run.

A :class:`Job` is one (entry, task, evaluation seed) episode with its cache key and file; :func:`plan_jobs` lists a
run's; :func:`compute_job` runs one in this process or a worker (the :class:`Backend` says how environments,
controllers (:func:`leaderboard.suite.registry.make_controller`) and episodes (:func:`uvdms_gym.evaluation.run_episode`)
are made, so that tests can substitute fakes); :func:`store_result` is the driver's write of its result. The local
pool (:mod:`leaderboard.running.runner`) and the Ray backend (:mod:`leaderboard.running.distributed`) both run these.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from leaderboard.running.cache import cache_key, cache_material, cache_path, compact_result
from leaderboard.suite.entries import Entry
from leaderboard.suite.tasks import Task
from uvdms_gym.seeds import assign_draws
from uvdms_gym.utils.io import write_json_atomic
from uvdms_gym.utils.provenance import timing_record


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
    from leaderboard.suite.registry import make_controller

    return make_controller(spec, env, trust=trust)


def _real_run_episode(env: Any, controller: Any, seed: int, save_trajectory: bool) -> dict[str, Any]:
    from uvdms_gym.evaluation import run_episode

    return run_episode(env, controller, seed, save_trajectory=save_trajectory)


DEFAULT_BACKEND = Backend(make_env=make_env, make_controller=_real_make_controller, run_episode=_real_run_episode)


@dataclass(frozen=True)
class Job:
    """One episode to compute: ``entry`` on draw ``seed`` of ``task`` in the seed split ``split``."""

    entry: Entry
    task: Task
    seed: int
    save_trajectory: bool
    key: str
    material: dict[str, Any]
    path: Path
    split: str


_WORKER: dict[str, Any] = {}
"""Per-process reuse of the environment (and of stateless agent controllers) across consecutive jobs."""


def worker_setup() -> None:
    """Prepare a worker process for episodes, once: one torch thread, and the last simulator closed at exit."""
    if _WORKER.get("setup"):
        return
    import atexit

    atexit.register(close_worker_env)  # disconnect the worker's last simulator before interpreter teardown
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # pragma: no cover - torch is a dependency
        pass
    _WORKER["setup"] = True


def close_worker_env() -> None:
    """Close the worker's environment and forget its controller (before another entry's episodes, and at exit)."""
    env = _WORKER.pop("env", None)
    _WORKER.pop("controller", None)
    _WORKER.pop("key", None)
    if env is not None:
        env.close()


def compute_job(job: Job, backend: Backend, trust: bool) -> dict[str, Any]:
    """Run one episode and return its compact result (the driver stores it with :func:`store_result`)."""
    group = (job.entry.name, job.entry.checksum, json.dumps(job.entry.task_spec(job.task), sort_keys=True))
    if _WORKER.get("key") != group:
        close_worker_env()
        _WORKER["env"] = backend.make_env(job.entry.task_spec(job.task))
        _WORKER["key"] = group
    env = _WORKER["env"]
    # baselines are stateful (adaptive networks, warm starts): a fresh one per episode; so is a residual agent's base
    reusable = job.entry.kind == "agent" and job.entry.residual_base is None
    controller = _WORKER.get("controller") if reusable else None
    if controller is None:
        controller = backend.make_controller(job.entry.spec, env, trust)
        if job.entry.safety_filter:
            from leaderboard.suite.registry import with_safety_filter

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


def plan_jobs(
    entries: Sequence[Entry],
    tasks: Sequence[Task],
    split: str,
    episodes: int,
    cache_dir: str | Path,
    *,
    trajectories: bool = True,
) -> list[Job]:
    """Every (entry, task, draw) episode of a run on the seed split ``split``, grouped by entry and task.

    A task's draws are :meth:`Task.draws` (``episodes`` of a randomised task, one of a deterministic one). A
    multi-seed entry contributes the episodes of each of its members (:meth:`Entry.runs`), each cached on its own:
    every member evaluates a deterministic task's draw, and the draws of a randomised task are spread over the
    members (:func:`uvdms_gym.seeds.assign_draws`: draw ``i`` to member ``i % members``), so that ``episodes``
    draws cost ``episodes`` episodes whatever the number of training seeds (a member beyond the ``episodes``-th gets
    none). With ``trajectories``, the first episode of each run of a ``trajectory`` task stores its distance
    trajectory (the distance plot; the generalisation check's jobs store none).
    """
    jobs = []
    for entry in entries:
        for task in tasks:
            if not entry.runs_on(task):
                continue
            draws = task.draws(split, episodes)
            runs = entry.runs()
            for index, run in enumerate(runs):
                seeds = draws if task.deterministic else assign_draws(draws, len(runs), index)
                for i, seed in enumerate(seeds):
                    save = trajectories and task.trajectory and i == 0
                    material = cache_material(run, task, seed, save)
                    key = cache_key(material)
                    path = cache_path(cache_dir, run, task, seed, key)
                    jobs.append(Job(run, task, seed, save, key, material, path, split))
    return jobs
