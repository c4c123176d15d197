"""Leaderboard throughput: ``uvdms bench leaderboard [--json] [--quick]``.

Episodes per second of the quick leaderboard (``uvdms leaderboard --quick``: every baseline and shipped agent
on the three paper tasks, 2 episodes each) computed from an empty cache with

* ``local_1``: ``--backend local --jobs 1`` (this process),
* ``local_2``: ``--backend local --jobs 2`` (a pool of 2 spawned processes),
* ``ray_2``: ``--backend ray --num-cpus 2`` (a local Ray instance of 2 CPUs, one task per episode),

each measured from the call to the written report, so process and Ray start-up are included as a user meets
them. ``speedup_*_vs_local_1`` are ratios of episodes/s. Ray's cost is reported twice: ``ray_startup_s``, an
empty ``ray.init`` + ``ray.shutdown`` of the same instance measured on its own, and
``ray_overhead_per_episode_ms``, ``(wall(ray_2) - wall(local_2)) / episodes``: what a Ray task costs beyond
a process-pool job of the same parallelism (start-up included). ``--quick`` cuts every episode to
:data:`QUICK_EPISODE_STEPS` steps, which makes the fixed costs weigh more than in real runs.

The three runs go one after another in one invocation, so a change of machine load affects the ratios less
than the absolute figures; the load average before and after is part of the result.
"""

from __future__ import annotations

import os
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

QUICK_EPISODE_STEPS = 50
"""Steps per episode with ``--quick``."""
RUNS: tuple[tuple[str, str, int], ...] = (("local_1", "local", 1), ("local_2", "local", 2), ("ray_2", "ray", 2))
"""(result key, backend, jobs or Ray CPUs) of the timed runs."""


def bench_leaderboard(quick: bool = False) -> dict[str, Any]:
    """Time the quick leaderboard on each backend of :data:`RUNS` (see the module docstring).

    Args:
        quick: Cut every episode to :data:`QUICK_EPISODE_STEPS` steps.

    Returns:
        ``{"episodes": n, "local_1": {"wall_s", "episodes_per_s"}, "local_2": {...}, "ray_2": {...},
        "speedup_local_2_vs_local_1", "speedup_ray_2_vs_local_1", "ray_startup_s",
        "ray_overhead_per_episode_ms", "load_avg_before", "load_avg_after", ...}``.
    """
    import torch

    import leaderboard as lb
    from uvdms_gym.utils.cluster import ray_session

    torch.set_num_threads(1)
    tasks = lb.select_tasks(None, quick=True)
    if quick:
        tasks = tuple(replace(task, max_episode_steps=QUICK_EPISODE_STEPS) for task in tasks)
    entries = lb.resolve_entries(None)
    result: dict[str, Any] = {
        "entries": [entry.name for entry in entries],
        "tasks": [task.name for task in tasks],
        "episodes_per_task": lb.QUICK_EPISODES,
        "max_episode_steps": QUICK_EPISODE_STEPS if quick else None,
        "cpu_count": os.cpu_count(),
        "load_avg_before": list(os.getloadavg()),
    }
    start = time.perf_counter()
    with ray_session(num_cpus=2):
        pass
    result["ray_startup_s"] = time.perf_counter() - start
    for key, backend, workers in RUNS:
        with tempfile.TemporaryDirectory(prefix="uvdms-bench-leaderboard-") as tmp:
            ray_options = {"num_cpus": workers} if backend == "ray" else {"jobs": workers}
            start = time.perf_counter()
            run = lb.run_leaderboard(
                entries,
                out_dir=Path(tmp),
                tasks=tasks,
                episodes=lb.QUICK_EPISODES,
                executor=backend,
                progress=False,
                plots=False,
                **ray_options,
            )
            wall = time.perf_counter() - start
        result["episodes"] = run.computed
        result[key] = {"backend": backend, "workers": workers, "wall_s": wall, "episodes_per_s": run.computed / wall}
    base = result["local_1"]["episodes_per_s"]
    result["speedup_local_2_vs_local_1"] = result["local_2"]["episodes_per_s"] / base
    result["speedup_ray_2_vs_local_1"] = result["ray_2"]["episodes_per_s"] / base
    result["ray_overhead_per_episode_ms"] = (
        1000.0 * (result["ray_2"]["wall_s"] - result["local_2"]["wall_s"]) / result["episodes"]
    )
    result["load_avg_after"] = list(os.getloadavg())
    return result
