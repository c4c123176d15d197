"""A policy's memory of its last observations: :class:`ObservationHistory` and the training wrapper :class:`FrameStack`.

A policy trained with ``frame_stack = k`` (:attr:`agents.config.schema.TrainConfig.frame_stack`) observes the
concatenation of its last ``k`` observations, oldest first. At an episode's start the history holds ``k`` copies of
its first observation (Gymnasium's ``FrameStackObservation`` with ``padding_type="reset"``). The one
implementation is :class:`ObservationHistory`: the training envs' :class:`FrameStack` wrapper and the evaluation
controller (:class:`agents.export.AgentController`) both keep one, so training and evaluation see the same input
to the bit.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from uvdms_gym.residual import check_frame_stack


class ObservationHistory:
    """The last ``k`` observations, concatenated oldest first (see the module).

    Args:
        k: How many observations (``frame_stack``, in [1, ``MAX_FRAME_STACK``]).

    Raises:
        ValueError: ``k`` is not a valid ``frame_stack``.
    """

    def __init__(self, k: int) -> None:
        self.k = check_frame_stack(k)
        self._frames: np.ndarray | None = None

    def reset(self) -> None:
        """Forget the episode: the next :meth:`push` fills the history with copies of its observation."""
        self._frames = None

    def push(self, obs: np.ndarray) -> np.ndarray:
        """Add ``obs`` (1-D) and return the history, ``k * obs.size`` values, oldest first (a new array)."""
        obs = np.asarray(obs)
        if obs.ndim != 1:
            raise ValueError(f"an observation history holds 1-D observations, got shape {obs.shape}")
        if self._frames is None or self._frames.shape[1] != obs.size:
            self._frames = np.repeat(obs[None, :], self.k, axis=0)
        else:
            self._frames = np.concatenate([self._frames[1:], obs[None, :]], axis=0)
        return self._frames.reshape(-1).copy()


def stacked_space(space: spaces.Space, k: int) -> spaces.Box:
    """The observation space of ``k`` stacked observations of the 1-D ``Box`` ``space``.

    Raises:
        ValueError: ``space`` is not a 1-D ``Box``.
    """
    if not isinstance(space, spaces.Box) or len(space.shape) != 1:
        raise ValueError(f"frame_stack stacks 1-D Box observations, got {space}")
    return spaces.Box(np.tile(space.low, k), np.tile(space.high, k), dtype=space.dtype)


class FrameStack(gym.ObservationWrapper):
    """The environment's observation replaced by the history of its last ``k`` (:class:`ObservationHistory`).

    Args:
        env: An environment with a 1-D ``Box`` observation space.
        k: How many observations (``frame_stack``).
    """

    def __init__(self, env: gym.Env, k: int) -> None:
        super().__init__(env)
        self.history = ObservationHistory(k)
        self.observation_space = stacked_space(env.observation_space, k)

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset the environment and start the history at its first observation."""
        self.history.reset()
        return super().reset(**kwargs)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        """The history with ``observation`` as its newest entry."""
        return self.history.push(observation)
