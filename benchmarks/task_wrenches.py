"""The body wrenches a controller asks of the vehicle's thrusters on the paper's tasks (JSON): the sizing data of
:data:`uvdms_gym.realism.actuation.DEFAULT_LAYOUT`.

    python benchmarks/task_wrenches.py [--controller campc] [--episodes 3] [--out wrenches.npz] [--run NAME]

Runs the controller on each named run (:data:`RUNS`: ``CircleTrack-v1`` cases 1 and 2 and random circles with
``hydro_randomization=0.3``; ``Transport-v1`` with the paper's goal and with random goals, hydrodynamic
randomisation and a random current) on the first validation draws and records, at every physics substep, the
vehicle wrench ``tau[:6]`` (body frame, about the body origin) the velocity loop asks (before the simulator's
500 N / 150 N m saturation) and the one applied (after it; ``info["tau"][:6]`` is the last substep's). Prints
per run the componentwise extremes, the largest allocation scale :data:`~uvdms_gym.realism.actuation.DEFAULT_LAYOUT`
needs (the largest ``|u|`` of ``B^+ w`` over the applied wrenches, 1 = full thrust) and the episodes' outcomes;
with ``--out`` also saves every applied and requested wrench (``npz``). With ``--thrusters`` the vehicle wrench
passes through the default thrusters' allocation and saturation (no rotor lag, no dead zone) before it is applied:
the same tasks with the thrusters' producible set in place of the 500 N / 150 N m box alone.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import gymnasium as gym
import numpy as np

import uvdms_gym  # noqa: F401  (registers the ids)
from leaderboard.suite.registry import make_controller
from uvdms_gym.evaluation import run_episode
from uvdms_gym.physics.stepping import Stepping
from uvdms_gym.realism.actuation import DEFAULT_LAYOUT, Thrusters
from uvdms_gym.seeds import split_seeds

RUNS: dict[str, tuple[str, dict[str, Any]]] = {
    "circle-case1": ("uvdms/CircleTrack-v1", {"case": 1}),
    "circle-case2": ("uvdms/CircleTrack-v1", {"case": 2}),
    "circle-random": ("uvdms/CircleTrack-v1", {"case": "random", "hydro_randomization": 0.3}),
    "transport-paper": ("uvdms/Transport-v1", {}),
    "transport-random": (
        "uvdms/Transport-v1",
        {"goal": "random", "hydro_randomization": 0.3, "current": "random"},
    ),
}
"""Run name -> (environment id, ``gymnasium.make`` keywords)."""
WRENCH_DIM = 6
"""Components of the vehicle wrench ``[X, Y, Z, K, M, N]``."""

_requested: list[np.ndarray] = []
_applied: list[np.ndarray] = []
_original_feedback = Stepping._feedback
_thrusters: list[Thrusters] = []


def _recording_feedback(self: Stepping, feedback: Any, nu: tuple[float, ...]) -> tuple[list[float], list[float]]:
    """:meth:`Stepping._feedback` that also records the law's raw output (before saturation)."""

    def law(z: np.ndarray) -> np.ndarray:
        t = np.array(feedback(z), dtype=float)
        _requested.append(t[:WRENCH_DIM].copy())
        if _thrusters:
            thrust, _ = _thrusters[0].allocate(
                np.clip(t[:WRENCH_DIM], -self._tau_max[:WRENCH_DIM], self._tau_max[:WRENCH_DIM])
            )
            t[:WRENCH_DIM] = _thrusters[0].step(thrust)
        return t

    tau_v, tau_q = _original_feedback(self, law, nu)
    _applied.append(np.array(tau_v))
    return tau_v, tau_q


def measure(controller_name: str, run: str, episodes: int, thrusters: bool = False) -> dict[str, Any]:
    """Run ``episodes`` episodes of ``run``; the applied and requested wrenches of every substep."""
    env_id, kwargs = RUNS[run]
    env = gym.make(env_id, **kwargs)
    _requested.clear()
    _applied.clear()
    _thrusters.clear()
    if thrusters:
        _thrusters.append(Thrusters(DEFAULT_LAYOUT, physics_dt=env.unwrapped.physics_dt))
    Stepping._feedback = _recording_feedback  # type: ignore[method-assign]
    summaries = []
    try:
        controller = make_controller(controller_name, env)
        for seed in split_seeds("validation", episodes):
            ep = run_episode(env, controller, seed)
            summaries.append({k: ep[k] for k in ("seed", "success", "steps", "rmse_pos", "physics_error")})
    finally:
        Stepping._feedback = _original_feedback  # type: ignore[method-assign]
        env.close()
    applied, requested = np.array(_applied), np.array(_requested)
    f = applied @ np.linalg.pinv(Thrusters(DEFAULT_LAYOUT, physics_dt=env.unwrapped.physics_dt).matrix).T
    use = np.maximum(f / DEFAULT_LAYOUT.max_forward, -f / DEFAULT_LAYOUT.max_reverse).max(axis=1)
    return {
        "run": run,
        "env_id": env_id,
        "env_kwargs": kwargs,
        "thrusters": thrusters,
        "episodes": summaries,
        "max_allocation_scale": round(float(use.max()), 3),
        "substeps": len(applied),
        "applied_min": applied.min(axis=0).round(2).tolist(),
        "applied_max": applied.max(axis=0).round(2).tolist(),
        "requested_min": requested.min(axis=0).round(2).tolist(),
        "requested_max": requested.max(axis=0).round(2).tolist(),
        "_applied": applied,
        "_requested": requested,
    }


def main() -> None:
    """Print the figures as JSON; optionally save the wrenches."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0])
    parser.add_argument("--controller", default="campc")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--run", action="append", choices=sorted(RUNS), help="default: every run")
    parser.add_argument("--out", help="npz file of every applied and requested wrench")
    parser.add_argument("--thrusters", action="store_true", help="apply the wrench through DEFAULT_LAYOUT")
    args = parser.parse_args()
    arrays: dict[str, np.ndarray] = {}
    for run in args.run or list(RUNS):
        result = measure(args.controller, run, args.episodes, args.thrusters)
        arrays[f"{run}_applied"] = result.pop("_applied")
        arrays[f"{run}_requested"] = result.pop("_requested")
        print(json.dumps(result), flush=True)
    if args.out:
        np.savez_compressed(args.out, **arrays)


if __name__ == "__main__":
    main()
