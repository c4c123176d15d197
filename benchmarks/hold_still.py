"""How much closer to the goal than holding still an entry ends, per task and per episode (JSON).

    python benchmarks/hold_still.py [--entry docs/leaderboard/entries/ppo-lagrangian-transport-v1.json]
                                    [--tasks transport transport-random]

Holding still (the zero velocity command every step, the baseline ``hold``) is the floor a transport controller
must beat: the object stays where it starts, and the episode ends when the reference has left it 2 m behind. For
each task the script runs holding still on every evaluation seed the entry's leaderboard document recorded (the
same environment keywords, so the same goals and hydrodynamics), and compares the final object position error
(``final_pos_error`` of :func:`uvdms_gym.evaluation.run_episode`) episode by episode with the entry's, every
training seed's episode against the hold of the same evaluation seed. It prints, per task, the two means and how
many of the entry's episodes end closer (``docs/LEARNED_CONTROLLERS.md``, pure RL).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import uvdms_gym  # noqa: F401  (registers the ids)
from baselines.controllers import HoldStill
from leaderboard.suite.tasks import select_tasks
from uvdms_gym.evaluation import run_episode

DEFAULT_ENTRY = Path("docs/leaderboard/entries/ppo-lagrangian-transport-v1.json")


def compare(entry_doc: dict[str, Any], task_name: str) -> dict[str, Any]:
    """Holding still against the entry's recorded episodes on one task."""
    task = select_tasks([task_name])[0]
    episodes = entry_doc["tasks"][task_name]["episodes"]
    env = gym.make(entry_doc["env_id"], **task.spec("velocity")["env_kwargs"])
    try:
        seeds = sorted({e["seed"] for e in episodes})
        hold = {s: run_episode(env, HoldStill(env), s)["final_pos_error"] for s in seeds}
    finally:
        env.close()
    closer = [e["final_pos_error"] < hold[e["seed"]] for e in episodes]
    return {
        "task": task_name,
        "episodes": len(episodes),
        "hold_final_pos_error_mean_m": float(np.mean(list(hold.values()))),
        "entry_final_pos_error_mean_m": float(np.mean([e["final_pos_error"] for e in episodes])),
        "entry_episodes_closer": int(sum(closer)),
    }


def main() -> None:
    """Print the comparison as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0])
    parser.add_argument("--entry", type=Path, default=DEFAULT_ENTRY, help="an entries/<entry>.json of a leaderboard")
    parser.add_argument("--tasks", nargs="+", default=["transport", "transport-random"])
    args = parser.parse_args()
    doc = json.loads(args.entry.read_text(encoding="utf-8"))
    result = {"entry": doc["name"], "tasks": [compare(doc, name) for name in args.tasks]}
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
