"""Cost of the thrusters per physics substep: ``allocate`` + ``step`` of :class:`uvdms_gym.realism.actuation.Thrusters`.

    python benchmarks/bench_actuation.py [--calls 20000] [--repeats 7]

Times ``--repeats`` blocks of ``--calls`` calls of each of ``allocate(w)``, ``step(f)``, both in sequence (what the
environment runs every substep), and ``limit_joint_speed`` on 12 joints, with the default layout, a 0.1 s rotor
time constant and a 0.1 dead zone, on wrenches drawn once (a third of them beyond the capacity, so that the
saturation branch runs). Prints the median per call over the blocks in µs, with the machine: the ``lscpu`` model
name, ``nproc`` and the load average before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import time
from collections.abc import Callable

import numpy as np

from uvdms_gym.realism.actuation import DEFAULT_LAYOUT, Thrusters, limit_joint_speed

PHYSICS_DT = 0.01
"""The environments' physics substep, s."""
WRENCH_SCALE = (300.0, 300.0, 300.0, 100.0, 100.0, 100.0)
"""Standard deviations of the drawn wrenches, N and N m (some beyond the capacity)."""
N_WRENCHES = 1024
"""Distinct wrenches cycled through."""
N_JOINTS = 12
"""Joints of the two arms."""


def cpu_model() -> str:
    """``Model name`` of ``lscpu`` (empty if lscpu is missing)."""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=False).stdout
    except OSError:
        return ""
    for line in out.splitlines():
        if line.startswith("Model name:"):
            return line.split(":", 1)[1].strip()
    return ""


def per_call_us(fn: Callable[[int], object], calls: int, repeats: int) -> float:
    """Median over ``repeats`` blocks of the time of one call of ``fn(i)`` in a block of ``calls``, µs."""
    blocks = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for i in range(calls):
            fn(i)
        blocks.append((time.perf_counter() - t0) / calls * 1e6)
    return float(np.median(blocks))


def main() -> None:
    """Print the medians and the machine as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0])
    parser.add_argument("--calls", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    load_before = os.getloadavg()
    thr = Thrusters(DEFAULT_LAYOUT, rotor_time_constant=0.1, dead_zone=0.1, physics_dt=PHYSICS_DT)
    rng = np.random.default_rng(0)
    wrenches = list(rng.normal(size=(N_WRENCHES, 6)) * WRENCH_SCALE)
    cmds = [thr.allocate(w)[0] for w in wrenches]
    tau = list(rng.normal(size=(N_WRENCHES, N_JOINTS)) * 20.0)
    qdot = list(rng.normal(size=(N_WRENCHES, N_JOINTS)))
    mask = N_WRENCHES - 1
    allocate, step = thr.allocate, thr.step

    def both(i: int) -> None:
        step(allocate(wrenches[i & mask])[0])

    result = {
        "allocate_us": per_call_us(lambda i: allocate(wrenches[i & mask]), args.calls, args.repeats),
        "step_us": per_call_us(lambda i: step(cmds[i & mask]), args.calls, args.repeats),
        "allocate_plus_step_us": per_call_us(both, args.calls, args.repeats),
        "limit_joint_speed_us": per_call_us(
            lambda i: limit_joint_speed(tau[i & mask], qdot[i & mask], 1.0), args.calls, args.repeats
        ),
        "saturated_fraction": float(np.mean([thr.allocate(w)[1] < 1.0 for w in wrenches])),
        "cpu": cpu_model(),
        "nproc": os.cpu_count(),
        "loadavg_before": [round(v, 2) for v in load_before],
        "loadavg_after": [round(v, 2) for v in os.getloadavg()],
        "calls": args.calls,
        "repeats": args.repeats,
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
