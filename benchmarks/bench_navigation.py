"""Cost of one navigation-filter update (one control step), median and mean µs, with the machine and its load (JSON).

    python benchmarks/bench_navigation.py [--level 3] [--steps 500]

The measurements come from one recorded random-circle episode (``scripts/filter_consistency.py``), sampled by a
:class:`~uvdms_gym.realism.sensors.SensorBank`; only :meth:`NavigationFilter.update` is timed (the first 20 updates,
which compile or load numba's kernels, are left out). Run it on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from scripts.filter_consistency import SENSORS, _sensor_values, simulate
from uvdms_gym.physics.params import UVDMSParams
from uvdms_gym.realism.config import LEVELS
from uvdms_gym.realism.navigation import NavigationFilter
from uvdms_gym.realism.sensors import SensorBank
from uvdms_gym.utils.provenance import cpu_model

WARM_UP = 20
"""Updates left out of the statistics (numba compilation or cache loading)."""


def bench(level: int, n_steps: int) -> dict[str, object]:
    truth = simulate(0, n_steps)
    cfg, n_sub, dt = LEVELS[level], truth.n_substeps, truth.physics_dt
    bank = SensorBank(cfg, physics_dt=dt, control_substeps=n_sub, names=SENSORS)
    nav = NavigationFilter(cfg, UVDMSParams(), control_dt=truth.control_dt, physics_dt=dt)
    bank.reset(0, 0, _sensor_values(truth, 0))
    nav.reset(0.0, bank.initial())
    times = []
    for k in range(n_steps):
        for s in range(k * n_sub + 1, (k + 1) * n_sub + 1):
            values = _sensor_values(truth, s)
            bank.sample(s, {n: values[n] for n in bank.due(s)})
        meas = bank.release((k + 1) * n_sub)
        t0 = time.perf_counter()
        nav.update((k + 1) * n_sub * dt, meas, truth.tau[k])
        times.append(time.perf_counter() - t0)
    us = np.array(times[WARM_UP:]) * 1e6
    return {
        "level": level,
        "updates": int(us.size),
        "median_us": round(float(np.median(us)), 1),
        "mean_us": round(float(us.mean()), 1),
        "p95_us": round(float(np.percentile(us, 95)), 1),
        "cpu": cpu_model(),
        "cpus": os.cpu_count(),
        "load_1min": round(os.getloadavg()[0], 2),
    }


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--level", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--steps", type=int, default=500)
    args = ap.parse_args()
    print(json.dumps([bench(level, args.steps) for level in args.level], indent=2))
