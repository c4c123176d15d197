"""Record the v0 reference trajectories that ``tests/uvdms_gym/physics/test_same_physics.py`` compares against.

Run once on the code whose physics is the reference (it was run before the speed work of the step):

    python benchmarks/record_v0_reference.py tests/data/v0_reference_trajectories.npz

Each case is a registered v0 id with fixed kwargs, seed and a fixed action sequence drawn from a seeded
generator; the file stores, per step, the state (eta, nu, q, qdot), the observation, the reward and the 18
distances.
"""

from __future__ import annotations

import sys

import gymnasium as gym
import numpy as np

import uvdms_gym  # noqa: F401  (registers the ids)

N_STEPS = 200
_FREE_TORQUE = {"action_mode": "torque", "terminate_on_contact": False, "max_tracking_error": 100.0}
"""Torque mode run through contacts and large errors, so that 200 steps of free dynamics are compared."""
CASES: dict[str, tuple[str, dict, float]] = {
    # name: (id, gym.make kwargs, action amplitude)
    "circle_case1_velocity": ("uvdms/CircleTrack-v0", {"case": 1}, 0.5),
    "circle_random_hydro_velocity": ("uvdms/CircleTrack-v0", {"case": "random", "hydro_randomization": 0.3}, 0.5),
    "transport_paper_velocity": ("uvdms/Transport-v0", {"goal": "paper"}, 0.5),
    "circle_case2_torque": ("uvdms/CircleTrack-v0", {"case": 2, **_FREE_TORQUE}, 0.05),
    "transport_random_torque": ("uvdms/Transport-v0", {"goal": "random", **_FREE_TORQUE}, 0.05),
    "circle_case2_torque_contact": ("uvdms/CircleTrack-v0", {"case": 2, "action_mode": "torque"}, 0.5),
}


def actions(name: str, n: int = N_STEPS, cases: dict[str, tuple[str, dict, float]] | None = None) -> np.ndarray:
    """The fixed action sequence of a case (of ``cases``, default :data:`CASES`): a smoothed random walk scaled by
    the case's amplitude."""
    rng = np.random.default_rng(sum(map(ord, name)))
    raw = rng.uniform(-1.0, 1.0, (n, 18))
    out = np.zeros_like(raw)
    a = np.zeros(18)
    for k in range(n):
        a = 0.9 * a + 0.1 * raw[k]
        out[k] = (cases or CASES)[name][2] * a
    return out


KEYS: tuple[str, ...] = ("eta", "nu", "q", "qdot", "distances")
"""The ``info`` arrays recorded per step (besides the observation and the reward)."""


def record(
    name: str,
    cases: dict[str, tuple[str, dict, float]] | None = None,
    keys: tuple[str, ...] = KEYS,
    **extra: object,
) -> dict[str, np.ndarray]:
    """Roll out one case of ``cases`` (default :data:`CASES`; its kwargs updated with ``extra``) and return its
    arrays ``keys``, the observations and the rewards (keys prefixed with the case name)."""
    env_id, kwargs, _ = (cases or CASES)[name]
    env = gym.make(env_id, disable_env_checker=True, **kwargs, **extra)
    rows: dict[str, list] = {k: [] for k in (*keys, "obs", "reward")}
    try:
        env.reset(seed=7)
        for a in actions(name, cases=cases):
            obs, reward, terminated, truncated, info = env.step(a.astype(np.float32))
            for k in keys:
                rows[k].append(np.asarray(info[k], dtype=np.float64))
            rows["obs"].append(obs)
            rows["reward"].append(reward)
            if terminated or truncated:
                break
    finally:
        env.close()
    return {f"{name}/{k}": np.asarray(v) for k, v in rows.items()}


def main(path: str) -> None:
    """Record every case into one ``.npz`` file."""
    arrays: dict[str, np.ndarray] = {}
    for name in CASES:
        arrays.update(record(name))
    np.savez_compressed(path, **arrays)


if __name__ == "__main__":
    main(sys.argv[1])
