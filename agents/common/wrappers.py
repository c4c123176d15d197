"""Training-side Gymnasium wrappers, named in ``train_configs/<algo>.yml`` the way RL Zoo names wrappers.

An entry's ``env_wrapper`` list (RL Baselines3 Zoo's key) names them with their keyword arguments::

    env_wrapper:
      - agents.common.wrappers.ScaledAction: {scale: 0.3}
      - agents.common.wrappers.AliveBonus: {bonus: 2.0}

``python -m rl_zoo3.train`` imports and applies them itself; :mod:`agents.config.schema` reads the same list into
``TrainConfig.action_scale`` / ``TrainConfig.alive_bonus`` (only these two classes are accepted there: nothing
named in a config is imported by the project's loader) and :class:`agents.common.envs.EnvFactory` applies them. This
module imports only Gymnasium and NumPy, so RL Zoo's wrapper lookup stays cheap.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np


def is_unit_scale(value: Any) -> bool:
    """Whether ``value`` is a real number in (0, 1] (``action_scale``, ``action_init_scale``)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and 0 < value <= 1


class AliveBonus(gym.RewardWrapper):
    """Adds a constant to every reward (training-side shaping; see ``TrainConfig.alive_bonus``).

    Args:
        env: The environment.
        bonus: Constant added to each step's reward.
    """

    def __init__(self, env: gym.Env, bonus: float) -> None:
        super().__init__(env)
        self.bonus = float(bonus)

    def reward(self, reward: float) -> float:
        """Shaped reward."""
        return float(reward) + self.bonus


class ScaledAction(gym.ActionWrapper):
    """Sends ``scale * action`` to the environment (see ``TrainConfig.action_scale``).

    The action space stays the wrapped env's ``Box(-1, 1)``; the scaled action lies in ``[-scale, scale]``.

    Args:
        env: The environment (a ``Box`` action space symmetric about 0).
        scale: Factor in (0, 1].
    """

    def __init__(self, env: gym.Env, scale: float) -> None:
        super().__init__(env)
        if not is_unit_scale(scale):
            raise ValueError(f"action scale must be in (0, 1], got {scale}")
        self.scale = float(scale)

    def action(self, action: np.ndarray) -> np.ndarray:
        """Scaled action."""
        return self.scale * np.asarray(action)


class ScalarInfo(gym.Wrapper):
    """Drops the array entries of every step's and reset's ``info`` (training envs; scalars are kept).

    The uvdms environments put the state (``eta``, ``q``, ``distances``, ``tau``, ...) in ``info`` for
    model-based controllers; a trainer reads none of it (SB3 reads ``episode``, ``is_success`` and the time-limit
    flags; the costs and reward terms are scalars), yet in ``subproc`` and ``hybrid`` vector envs every step's
    ``info`` is pickled in a worker and unpickled in the trainer: about 70 µs of a ~1.6 ms step here, and the
    unpickling is on the trainer's critical path. Evaluation envs are not wrapped. The one array kept is a
    teacher's label (``uvdms_gym.residual.TEACHER_KEY``), which an imitation learner stores with each transition.
    """

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset, with the array entries of ``info`` removed."""
        obs, info = self.env.reset(**kwargs)
        return obs, _scalars(info)

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        """Step, with the array entries of ``info`` removed."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, _scalars(info)


KEPT_ARRAYS: tuple[str, ...] = ("teacher_residual",)
"""The array entries :class:`ScalarInfo` keeps: ``uvdms_gym.residual.TEACHER_KEY`` (spelled out here, as this module
imports only Gymnasium and NumPy; a test checks that they agree)."""


def _scalars(info: dict[str, Any]) -> dict[str, Any]:
    return {key: value for key, value in info.items() if not isinstance(value, np.ndarray) or key in KEPT_ARRAYS}
