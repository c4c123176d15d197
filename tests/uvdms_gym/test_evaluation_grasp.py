"""The friction grasp's episode metrics of :func:`uvdms_gym.evaluation.run_episode` (``None`` with the rigid grasp).

A drop or a crush ends the episode (``terminated``), so such an episode is never a success.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import uvdms_gym  # noqa: F401  (registers the environments)
from uvdms_gym.evaluation import EPISODE_KEYS, GRASP_EPISODE_KEYS, run_episode, summarize
from uvdms_gym.physics.params import GripperParams

COOP = "uvdms/CooperativeTransport-v1"


class ConstantGrip:
    """A constant action: the velocity command ``sway`` (normalised) of the vehicle's sway only, both grippers at
    one command ``grip`` in ``[-1, 1]``."""

    def __init__(self, dim: int, grip: float | None, sway: float = 0.0) -> None:
        self.action = np.zeros(dim)
        self.action[1] = sway
        if grip is not None:
            self.action[-2:] = grip

    def reset(self, seed: int | None = None) -> None:
        """Nothing to reset."""

    def predict(self, obs: np.ndarray, info: dict) -> np.ndarray:
        """The constant action."""
        return self.action.copy()


def _episode(env_id: str, grip: float | None, steps: int, sway: float = 0.0) -> dict:
    env = gym.make(env_id, max_episode_steps=steps)
    try:
        return run_episode(env, ConstantGrip(env.action_space.shape[0], grip, sway), seed=3)
    finally:
        env.close()


def test_the_grasp_keys_are_among_the_episode_keys_and_none_with_the_rigid_grasp():
    assert set(GRASP_EPISODE_KEYS) <= set(EPISODE_KEYS)
    ep = _episode("uvdms/Transport-v1", None, 5)
    assert list(ep)[: len(EPISODE_KEYS)] == list(EPISODE_KEYS)
    assert all(ep[key] is None for key in GRASP_EPISODE_KEYS)
    summary = summarize([ep, {k: v for k, v in ep.items() if k not in GRASP_EPISODE_KEYS}])  # an older episode
    assert all(summary[key] is None for key in GRASP_EPISODE_KEYS)


def test_a_held_object_records_its_slip_and_internal_force():
    ep = _episode(COOP, 0.0, 20)
    assert ep["truncated"] and not ep["terminated"]
    assert ep["dropped"] is False and ep["crushed"] is False
    assert 0.0 <= ep["slip_max"] < 1e-3
    assert 0.0 <= ep["internal_force_rms"] <= ep["internal_force_max"]


def test_a_crush_terminates_the_episode_and_is_no_success():
    ep = _episode(COOP, 1.0, 20)  # squeezing at grip_max (300 N) beyond crush_force (200 N)
    assert ep["crushed"] is True and ep["terminated"] and not ep["truncated"]
    assert ep["success"] is False and ep["steps"] == 1


def test_a_drop_terminates_the_episode_and_is_no_success():
    ep = _episode(COOP, -1.0, 40, sway=1.0)  # open grippers, the vehicle sways along the object: it slides out
    assert ep["dropped"] is True and ep["terminated"] and not ep["truncated"]
    assert ep["success"] is False and ep["crushed"] is False
    assert ep["slip_max"] >= GripperParams.drop_slip
