"""Multi-seed agent folders (never loaded) and a fake backend whose quality depends on the training seed."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

import leaderboard as lb
from leaderboard.running.jobs import Backend

CIRCLE = "uvdms/CircleTrack-v0"
TINY_TASKS = (
    lb.Task(
        "case1", "Case 1", CIRCLE, {"case": 1}, paper=True, trajectory=True, max_episode_steps=3, deterministic=True
    ),
    lb.Task("circle-random", "Random circles", CIRCLE, {"case": "random"}, paper=False, max_episode_steps=3),
)
"""A deterministic task (every training seed runs its one draw, with a trajectory) and a randomised one (the draws
spread over the training seeds, and a generalisation check on ``test2``)."""


def _agent_folder(
    folder: Path, seed: int, env_id: str = CIRCLE, env_kwargs=None, recorded_seed=None, composition=None
) -> Path:
    """A run-like agent folder (a valid zip that is never loaded, config.yml and meta.json with seeds)."""
    folder.mkdir(parents=True)
    with zipfile.ZipFile(folder / "final_model.zip", "w") as archive:
        archive.writestr("data", json.dumps({"seed": seed}))  # different bytes per seed
    recorded = seed if recorded_seed is None else recorded_seed
    entry = {"env_kwargs": env_kwargs or {}, **(composition or {})}
    config = {"algo": "sac", "env_id": env_id, "seed": recorded, "config": entry}
    (folder / "config.yml").write_text(json.dumps(config))
    meta = {"seed": recorded, "segments": [{"model_seed": recorded, "train_env_seeds": [recorded, recorded + 1]}]}
    (folder / "meta.json").write_text(json.dumps(meta))
    return folder


def _multi_seed(root: Path, name: str = "sac_multi", seeds=(0, 1, 2), **kwargs) -> Path:
    folder = root / name
    for k in seeds:
        _agent_folder(folder / f"seed_{k}", k, **kwargs)
    (folder / "README.md").write_text("notes are ignored")
    return folder


class _Env:
    def __init__(self, spec):
        self.spec_ = dict(spec)

    def close(self):
        pass


class _Controller:
    def __init__(self, spec):
        self.spec = spec

    def reset(self, seed=None):
        pass


CALLS: list[tuple[str, int]] = []


def _fake_env(spec):
    return _Env(spec)


def _fake_controller(spec, env, trust):
    return _Controller(spec)


def _fake_episode(env, controller, seed, save_trajectory):
    """Per-seed quality: the seed folder's number sets the RMSE level, the evaluation seed the noise."""
    CALLS.append((controller.spec, seed))
    name = Path(controller.spec).name
    level = 1 + int(name.removeprefix("seed_")) if name.startswith("seed_") else 1
    rng = np.random.default_rng([seed, level])
    result = {
        "seed": seed,
        "return": float(rng.normal(-50, 5)),
        "cost": 0.0,
        "contacts": int(rng.uniform() < 0.2),
        "zone_steps": 0,
        "min_distance": float(rng.uniform(0.1, 0.2)),
        "rmse_pos": 0.01 * level + float(rng.uniform(0, 0.002)),
        "rmse_ori": None,
        "final_pos_error": 0.01,
        "final_ori_error": None,
        "success": bool(rng.uniform() < 0.7),
        "controller_ms_median": 0.3,
        "qp_slack_max": None,
        "steps": 3,
        "terminated": False,
        "truncated": True,
        "physics_error": None,
    }
    if save_trajectory:
        result["trajectory"] = {"t": [0.0, 0.04], "distances": [[0.2] * 18, [0.19] * 18]}
    return result


FAKE = Backend(make_env=_fake_env, make_controller=_fake_controller, run_episode=_fake_episode)


def _write_curve(folder: Path, seed: int, levels: list[float]) -> None:
    from agents.common.learning_curve import LearningCurve, curve_point

    curve = LearningCurve(folder / "learning_curve.json", CIRCLE, seed)
    for i, level in enumerate(levels):
        episodes = [
            {"rmse_pos": level, "success": i > 0, "contact_free": True, "contact_free_success": i > 0},
            {"rmse_pos": None, "success": False, "contact_free": False, "contact_free_success": False},
        ]
        curve.add(curve_point(1000 * (i + 1), 0, episodes, -10.0))
