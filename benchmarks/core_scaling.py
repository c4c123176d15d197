"""How much throughput a second core adds on this machine: the ceiling of any 2-env training speed-up.

Runs the same CPU-bound workload in 1 process, then in 2 processes at once (one per core), and prints the
ratio of aggregate throughputs. Two workloads:

* ``env``: ``uvdms/CircleTrack-v0`` (case 1, velocity mode) stepped with a fixed small action, resetting at
  the end of each episode: the physics, hydrodynamics and distances of a training env step;
* ``python``: a pure-Python integer loop (no memory traffic): what the cores give when nothing is shared.

On a machine with two independent cores both ratios are near 2.0. If the env ratio is well below the Python
one, the two cores share something the env step needs (cache or memory bandwidth, or, on a VM, vCPUs that are
siblings of one physical core), and no 2-env training can reach 2x: its env steps slow down by the same
factor. ``uvdms bench train``'s PPO ``speedup_2_hybrid_vs_1`` is bounded by the env ratio.

Rounds alternate 1 and 2 processes so that drifts of a shared VM's speed affect both alike; the figure is the
median over rounds of the per-round ratio. Run it with nothing else running::

    python benchmarks/core_scaling.py [--rounds 5] [--seconds 4] [--json]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import statistics
import sys
import time
from typing import Any

from uvdms_gym.utils.provenance import load_average, machine_info

ENV_ID = "uvdms/CircleTrack-v0"
ENV_KWARGS: dict[str, Any] = {"case": 1}
ACTION_LEVEL = 0.05
"""Every entry of the fixed action (normalised velocity command): small enough to stay contact-free for long."""


def _env_work(seconds: float, start: Any, out: Any) -> None:
    import gymnasium as gym
    import numpy as np

    import uvdms_gym  # noqa: F401  (registers the ids)

    env = gym.make(ENV_ID, **ENV_KWARGS)
    action = np.full(env.action_space.shape, ACTION_LEVEL, dtype=np.float32)
    env.reset(seed=0)
    for _ in range(50):  # warm-up (imports, caches)
        env.step(action)
    start.wait()
    steps, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        _, _, terminated, truncated, _ = env.step(action)
        steps += 1
        if terminated or truncated:
            env.reset(seed=steps)
    out.put(steps / (time.perf_counter() - t0))
    env.close()


def _python_work(seconds: float, start: Any, out: Any) -> None:
    start.wait()
    count, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        x = 0
        for i in range(10_000):
            x += i * i
        count += 1
    out.put(count / (time.perf_counter() - t0))


WORKLOADS = {"env": _env_work, "python": _python_work}


def throughput(workload: str, processes: int, seconds: float) -> float:
    """Aggregate throughput (units per second) of ``processes`` concurrent copies of ``workload``."""
    ctx = mp.get_context("spawn")
    start = ctx.Barrier(processes + 1)
    out = ctx.Queue()
    procs = [ctx.Process(target=WORKLOADS[workload], args=(seconds, start, out)) for _ in range(processes)]
    for p in procs:
        p.start()
    start.wait()
    rates = [out.get(timeout=seconds + 120) for _ in procs]
    for p in procs:
        p.join()
    return float(sum(rates))


def measure(rounds: int, seconds: float) -> dict[str, Any]:
    """Per workload: the 1- and 2-process throughputs of every round and the median per-round ratio."""
    load_before = load_average()
    result: dict[str, Any] = {}
    for workload in WORKLOADS:
        one, two = [], []
        for _ in range(rounds):
            one.append(throughput(workload, 1, seconds))
            two.append(throughput(workload, 2, seconds))
        ratios = [b / a for a, b in zip(one, two, strict=True)]
        result[workload] = {
            "one_process_per_s": one,
            "two_processes_per_s": two,
            "ratio_median": statistics.median(ratios),
            "ratio_min": min(ratios),
            "ratio_max": max(ratios),
        }
    machine = machine_info()
    result["machine"] = {
        "cpu": machine["cpu_model"],
        "cores": machine["cpu_count"],
        "load_1min_before": load_before,
        "load_1min_after": load_average(),
    }
    return result


def main(argv: list[str] | None = None) -> int:
    """Print the 2-process / 1-process throughput ratios (``--json``: the whole record)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5, help="alternating 1/2-process rounds (default 5)")
    parser.add_argument("--seconds", type=float, default=4.0, help="seconds per timed run (default 4)")
    parser.add_argument("--json", action="store_true", help="print the whole record as JSON")
    args = parser.parse_args(argv)
    result = measure(args.rounds, args.seconds)
    if args.json:
        json.dump(result, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    m = result["machine"]
    sys.stdout.write(f"{m['cpu']}, {m['cores']} cores, load {m['load_1min_before']} -> {m['load_1min_after']}\n")
    for workload in WORKLOADS:
        r = result[workload]
        sys.stdout.write(
            f"{workload:7s} 1 process {statistics.median(r['one_process_per_s']):9.1f}/s   "
            f"2 processes {statistics.median(r['two_processes_per_s']):9.1f}/s   "
            f"ratio {r['ratio_median']:.2f} (min {r['ratio_min']:.2f}, max {r['ratio_max']:.2f})\n"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
