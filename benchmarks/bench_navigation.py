"""Cost of one navigation-filter update (one control step): median µs, its ratio to one environment step, the machine.

    python benchmarks/bench_navigation.py [--level 1 2 3] [--steps 500] [--repeats 5]

One random-circle episode (``scripts/filter_consistency.py``: ``uvdms/CircleTrack-v1``, ``case="random"``,
``hydro_randomization=0.3``, smooth random velocity commands) is run at the level; its ``env.step`` calls are timed
and what the filter gets each step (``info["t"]``, ``info["measurements"]``, ``info["tau_cmd"]``) is recorded. Then
:meth:`NavigationFilter.update` is timed over the recorded steps, ``--repeats`` times from a fresh reset (the first
:data:`WARM_UP` updates of each pass, which may compile or load numba's kernels, are left out). The machine is
often shared: the report has the CPU model, the core count and the load average, and the ratio of the update's
median to the environment step's median measured in the same run, which the load affects alike.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository's scripts package

from scripts.filter_consistency import FIRST_SEED, make_env, random_commands
from uvdms_gym.realism.navigation import NavigationFilter
from uvdms_gym.utils.provenance import cpu_model

WARM_UP = 20
"""Updates left out of the statistics in each pass (numba compilation or cache loading)."""


def bench(level: int, n_steps: int, repeats: int) -> dict[str, object]:
    """Time ``env.step`` and ``NavigationFilter.update`` on one episode at ``level`` (module docstring)."""
    env = make_env(level)
    base = env.unwrapped
    _, info0 = env.reset(seed=FIRST_SEED)
    commands = random_commands(FIRST_SEED, n_steps, base.control_dt).astype(np.float32)
    stream, step_s = [], []
    for k in range(n_steps):
        t0 = time.perf_counter()
        _, _, _, _, info = env.step(commands[k])
        step_s.append(time.perf_counter() - t0)
        stream.append((info["t"], info["measurements"], info["tau_cmd"]))
    env.close()
    nav = NavigationFilter(base.realism, base.params, control_dt=base.control_dt, physics_dt=base.physics_dt)
    update_s = []
    for _ in range(repeats):
        nav.reset(info0["t"], info0["measurements"])
        times = []
        for t, meas, tau in stream:
            t0 = time.perf_counter()
            nav.update(t, meas, tau)
            times.append(time.perf_counter() - t0)
        update_s.extend(times[WARM_UP:])
    us = np.array(update_s) * 1e6
    step_us = np.array(step_s[WARM_UP:]) * 1e6
    return {
        "level": level,
        "updates": int(us.size),
        "update_median_us": round(float(np.median(us)), 1),
        "update_mean_us": round(float(us.mean()), 1),
        "update_p95_us": round(float(np.percentile(us, 95)), 1),
        "env_step_median_us": round(float(np.median(step_us)), 1),
        "update_to_env_step": round(float(np.median(us) / np.median(step_us)), 4),
        "cpu": cpu_model(),
        "cpus": os.cpu_count(),
        "load_1min": round(os.getloadavg()[0], 2),
    }


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--level", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    print(json.dumps([bench(level, args.steps, args.repeats) for level in args.level], indent=2))
