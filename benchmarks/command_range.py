"""How large the commands that track a task are: a controller's normalised actions after the transient (JSON).

    python benchmarks/command_range.py [--controller campc] [--task circle-random] [--episodes 3] [--scale 0.3]

Runs ``--episodes`` episodes of the task on the first validation draws
(``uvdms_gym.seeds.split_seeds("validation", n)``: a development tool never uses
the leaderboard's test seeds) with the controller and, over the steps after the task's transient (the samples its
RMSE counts: ``t >= env.unwrapped.tracking_transient``, :mod:`uvdms_gym.evaluation`), prints per action axis the
99th percentile and the maximum of ``|action|``, and the fraction of steps on which any axis exceeds ``--scale``.
An end-to-end learner trained with ``action_scale`` s commands at most ``s`` of ``zeta_max`` on every axis; where
the tracking controller needs more, the learner cannot track as it does, however long it trains
(``docs/LEARNED_CONTROLLERS.md``, pure RL).
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
from uvdms_gym.seeds import split_seeds


def episode_actions(env: gym.Env, controller: Any, seed: int) -> np.ndarray:
    """``|action|`` of every step after the transient of one episode, shape (steps, 18)."""
    obs, info = env.reset(seed=seed)
    controller.reset(seed)
    transient = env.unwrapped.tracking_transient
    actions = []
    while True:
        action = np.asarray(controller.predict(obs, info), dtype=float)
        if info["t"] >= transient - 1e-9:
            actions.append(np.abs(action))
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            return np.array(actions)


def command_range(controller_name: str, task_name: str, episodes: int, scale: float) -> dict[str, Any]:
    """Per-axis 99th percentile and maximum of ``|action|`` after the transient, and the steps beyond ``scale``."""
    task = select_tasks([task_name])[0]
    env = gym.make(task.env_id, **task.spec("velocity")["env_kwargs"])
    try:
        controller = make_controller(controller_name, env)
        per_episode = [episode_actions(env, controller, seed) for seed in split_seeds("validation", episodes)]
    finally:
        env.close()
    actions = np.concatenate(per_episode)
    return {
        "controller": controller_name,
        "task": task_name,
        "episodes": episodes,
        "steps": len(actions),
        "p99_abs_action": np.round(np.percentile(actions, 99, axis=0), 3).tolist(),
        "max_abs_action": np.round(actions.max(axis=0), 3).tolist(),
        "scale": scale,
        "fraction_of_steps_beyond_scale": float((actions.max(axis=1) > scale).mean()),
    }


def main() -> None:
    """Print the figures as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0])
    parser.add_argument("--controller", default="campc")
    parser.add_argument("--task", default="circle-random")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--scale", type=float, default=0.3)
    args = parser.parse_args()
    print(json.dumps(command_range(args.controller, args.task, args.episodes, args.scale), indent=2))


if __name__ == "__main__":
    main()
