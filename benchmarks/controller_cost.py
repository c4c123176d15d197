"""What a controller costs per step against CAMPC's, in one run: median ``predict`` time and the ratio (JSON).

    python benchmarks/controller_cost.py [--controllers campc trained_agents/distilled-dagger-campc-circle-v1/seed_0]
                                         [--task case1] [--rounds 5] [--max-steps 200]

Each round runs one episode of every controller on the same task and seed (the first validation draw,
``uvdms_gym.seeds.VALIDATION.start``), one controller after the other
(interleaved, so that a change of machine load affects all of them alike); an episode's figure is the median wall
time of ``controller.predict`` (``controller_ms_median`` of :func:`uvdms_gym.evaluation.run_episode`). The output
gives, per controller, the median over rounds, and its ratio to the first controller's. The acceptance figure of a
distilled controller (``docs/LEARNED_CONTROLLERS.md``) is that ratio with ``campc`` first; the leaderboard's
``Ctrl ms`` column is the same median, per entry and task. Run it on an idle machine: the record names the CPU
and the load average.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import gymnasium as gym
import numpy as np

import uvdms_gym  # noqa: F401  (registers the ids)
from leaderboard.suite.registry import make_controller
from leaderboard.suite.tasks import select_tasks
from uvdms_gym.evaluation import run_episode
from uvdms_gym.seeds import VALIDATION
from uvdms_gym.utils.provenance import load_average, machine_info

DEFAULT_CONTROLLERS = ("campc", "trained_agents/distilled-dagger-campc-circle-v1/seed_0")


def controller_cost(controllers: list[str], task_name: str, rounds: int, max_steps: int) -> dict[str, Any]:
    """Median ``predict`` time of each controller (ms) over ``rounds`` interleaved episodes, and ratios to the first."""
    task = select_tasks([task_name])[0]
    medians: dict[str, list[float]] = {name: [] for name in controllers}
    for _ in range(rounds):
        for name in controllers:
            env = gym.make(task.env_id, max_episode_steps=max_steps, **task.spec("velocity")["env_kwargs"])
            controller = make_controller(name, env)
            metrics = run_episode(env, controller, seed=VALIDATION.start)
            medians[name].append(float(metrics["controller_ms_median"]))
            env.close()
    first = float(np.median(medians[controllers[0]]))
    return {
        "task": task_name,
        "rounds": rounds,
        "max_steps": max_steps,
        "machine": machine_info(),
        "load_1min": load_average(),
        "controller_ms_median": {name: float(np.median(v)) for name, v in medians.items()},
        "ratio_to_first": {name: float(np.median(v)) / first for name, v in medians.items()},
    }


def main() -> None:
    """Command line: print the JSON record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--controllers", nargs="+", default=list(DEFAULT_CONTROLLERS))
    parser.add_argument("--task", default="case1")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--max-steps", type=int, default=200)
    args = parser.parse_args()
    print(json.dumps(controller_cost(args.controllers, args.task, args.rounds, args.max_steps), indent=2))


if __name__ == "__main__":
    main()
