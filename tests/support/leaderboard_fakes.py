"""The leaderboard's tests' fake backend (no physics) and a tiny baseline leaderboard run on it.

The tiny suite has a task of each kind of the seed protocol (:mod:`uvdms_gym.seeds`): the deterministic ``case1``
(one draw, which every training seed runs) and the randomised ``circle-random`` (``episodes`` draws of the split,
spread over training seeds, and as many of the second test set for the generalisation check).
"""

from __future__ import annotations

import numpy as np

import leaderboard as lb
from leaderboard.running.jobs import Backend

CIRCLE = "uvdms/CircleTrack-v0"
RANDOM_KWARGS = {"case": "random", "hydro_randomization": 0.3}
TINY_TASKS = (
    lb.Task(
        "case1", "Case 1", CIRCLE, {"case": 1}, paper=True, trajectory=True, max_episode_steps=3, deterministic=True
    ),
    lb.Task(
        "circle-random", "Random circles", CIRCLE, RANDOM_KWARGS, paper=False, trajectory=True, max_episode_steps=3
    ),
)
DETERMINISTIC, RANDOMISED = TINY_TASKS


# ------------------------------------------------------------------------------------------------------
# A fake backend: no physics, deterministic per (controller, task, seed) metrics, and a call counter
# ------------------------------------------------------------------------------------------------------
class FakeEnv:
    def __init__(self, spec):
        self.spec_ = dict(spec)
        self.closed = False

    def close(self):
        self.closed = True


class FakeController:
    def __init__(self, name):
        self.name = name

    def reset(self, seed=None):
        pass


CALLS: list[tuple[str, int]] = []


def fake_make_env(spec):
    return FakeEnv(spec)


def fake_make_controller(spec, env, trust):
    return FakeController(spec)


def fake_run_episode(env, controller, seed, save_trajectory):
    CALLS.append((controller.name, seed))
    case = env.spec_["env_kwargs"].get("case", 0)
    rng = np.random.default_rng([seed, sum(map(ord, controller.name)), case if isinstance(case, int) else 9])
    contacts = int(rng.integers(0, 2)) if controller.name == "mpc" else 0
    result = {
        "seed": seed,
        "return": float(rng.normal(-50, 5)),
        "cost": float(contacts),
        "contacts": contacts,
        "zone_steps": contacts,
        "min_distance": float(rng.uniform(0.04, 0.1)),
        "min_distance_by_pair": rng.uniform(0.04, 0.3, 18).tolist(),
        "rmse_pos": float(rng.uniform(0.01, 0.02) * (1 + len(controller.name))),
        "rmse_ori": None,
        "final_pos_error": float(rng.uniform(0, 0.1)),
        "final_ori_error": None,
        "success": bool(rng.uniform() < 0.8),
        "controller_ms_median": 1.0,
        "qp_slack_max": 0.0,
        "steps": 3,
        "terminated": False,
        "truncated": True,
        "physics_error": None,
    }
    if save_trajectory:
        t = np.arange(4) * 0.04
        result["trajectory"] = {
            "t": t,
            "y": np.zeros((4, 6)),
            "y_ref": np.zeros((4, 6)),
            "distances": rng.uniform(0.04, 0.3, (4, 18)),
            "tau": np.zeros((4, 18)),
            "nn_output": None,
        }
    return result


FAKE = Backend(make_env=fake_make_env, make_controller=fake_make_controller, run_episode=fake_run_episode)
BASELINE_ENTRIES = lb.resolve_entries(["baselines"])


def planned_episodes(entries, tasks=TINY_TASKS, episodes=3, *, check=True) -> int:
    """Episodes of a run on the test split: per run of an entry, 1 on a deterministic task; ``episodes`` draws of a
    randomised task per entry (spread over its runs), and as many of ``test2`` with the generalisation ``check``."""
    total = 0
    for entry in entries:
        for task in tasks:
            if entry.runs_on(task):
                total += len(entry.runs()) if task.deterministic else episodes * (2 if check else 1)
    return total


def _run(tmp_path, *, entries=BASELINE_ENTRIES, episodes=3, plots=False, **kwargs):
    CALLS.clear()
    return lb.run_leaderboard(
        entries,
        out_dir=tmp_path / "out",
        tasks=TINY_TASKS,
        episodes=episodes,
        progress=False,
        plots=plots,
        backend=FAKE,
        **kwargs,
    )
