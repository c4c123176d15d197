"""A policy's memory: :class:`ObservationHistory`, :class:`ActionHistory` and the training wrapper :class:`FrameStack`.

A policy trained with ``frame_stack = k`` (:attr:`agents.config.schema.TrainConfig.frame_stack`) observes the
concatenation of its last ``k`` observations, oldest first. At an episode's start the history holds ``k`` copies of
its first observation (Gymnasium's ``FrameStackObservation`` with ``padding_type="reset"``). With
``action_history = m`` it also observes its own last ``m`` actions, oldest first, zeros before its first (the
environment holds the zero action until the first one acts): under an action delay these are the commands still on
their way, which the observations cannot show. The one implementation of each is here: the training envs'
:class:`FrameStack` wrapper and the evaluation controller (:class:`agents.export.AgentController`) both keep them,
so training and evaluation see the same input to the bit.
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


class ActionHistory:
    """The policy's last ``m`` actions, oldest first, zeros before its first (see the module).

    Args:
        m: How many actions (``action_history``, in [0, ``MAX_FRAME_STACK``]; 0 keeps none).
        size: The length of an action.
    """

    def __init__(self, m: int, size: int) -> None:
        if m != 0:
            check_frame_stack(m, "action_history")
        self.m, self.size = int(m), int(size)
        self._actions = np.zeros((self.m, self.size), dtype=np.float32)

    def reset(self) -> None:
        """Forget the episode: zeros."""
        self._actions[:] = 0.0

    def push(self, action: np.ndarray) -> None:
        """Add the action the policy just took (its own output, as float32)."""
        if self.m:
            self._actions = np.concatenate([self._actions[1:], np.asarray(action, np.float32).reshape(1, -1)])

    def values(self) -> np.ndarray:
        """The ``m * size`` values, oldest first (a new array)."""
        return self._actions.reshape(-1).copy()


def stacked_space(
    space: spaces.Space, k: int, actions: int = 0, action_space: spaces.Space | None = None
) -> spaces.Box:
    """The observation space of ``k`` stacked 1-D ``Box`` observations and ``actions`` actions of ``action_space``.

    Raises:
        ValueError: ``space`` (or ``action_space``, with ``actions``) is not a 1-D ``Box``.
    """
    if not isinstance(space, spaces.Box) or len(space.shape) != 1:
        raise ValueError(f"frame_stack stacks 1-D Box observations, got {space}")
    low, high = np.tile(space.low, k), np.tile(space.high, k)
    if actions:
        if not isinstance(action_space, spaces.Box) or len(action_space.shape) != 1:
            raise ValueError(f"action_history keeps 1-D Box actions, got {action_space}")
        low = np.concatenate([low, np.tile(action_space.low, actions).astype(space.dtype)])
        high = np.concatenate([high, np.tile(action_space.high, actions).astype(space.dtype)])
    return spaces.Box(low, high, dtype=space.dtype)


def unstacked_space(space: spaces.Space, k: int, actions: int = 0, action_size: int = 0) -> spaces.Box:
    """One observation's space of a policy input space built by :func:`stacked_space` (its oldest entry's bounds).

    Raises:
        ValueError: ``space`` is not a 1-D ``Box`` whose size is ``k`` observations and ``actions * action_size``.
    """
    size = 0 if not isinstance(space, spaces.Box) or len(space.shape) != 1 else space.shape[0] - actions * action_size
    if size <= 0 or size % k:
        raise ValueError(f"{space} is not {k} observations and {actions} actions of size {action_size}")
    n = size // k
    return spaces.Box(space.low[:n], space.high[:n], dtype=space.dtype)


class PolicyMemory:
    """What a policy with memory observes: its observation history, then its action history.

    Args:
        k: Observations (``frame_stack``).
        m: Actions (``action_history``).
        action_size: The length of an action.
    """

    def __init__(self, k: int, m: int, action_size: int) -> None:
        self.observations = ObservationHistory(k)
        self.actions = ActionHistory(m, action_size)

    def reset(self) -> None:
        """Forget the episode."""
        self.observations.reset()
        self.actions.reset()

    def observe(self, obs: np.ndarray) -> np.ndarray:
        """The policy's input once ``obs`` joins the history."""
        stacked = self.observations.push(obs)
        if not self.actions.m:
            return stacked
        return np.concatenate([stacked, self.actions.values().astype(stacked.dtype)])


class FrameStack(gym.Wrapper):
    """The environment's observation replaced by the policy's memory (:class:`PolicyMemory`).

    Args:
        env: An environment with 1-D ``Box`` observation and action spaces.
        k: How many observations (``frame_stack``).
        actions: How many of the policy's last actions (``action_history``; 0: none). The action recorded is the
            one this wrapper receives: the policy's output.
    """

    def __init__(self, env: gym.Env, k: int, actions: int = 0) -> None:
        super().__init__(env)
        self.memory = PolicyMemory(k, actions, int(np.prod(env.action_space.shape)))
        self.history = self.memory.observations
        self.observation_space = stacked_space(env.observation_space, k, actions, env.action_space)

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset the environment and start the history at its first observation."""
        self.memory.reset()
        obs, info = self.env.reset(**kwargs)
        return self.memory.observe(obs), info

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Step the environment; the action joins the action history, the new observation the observations'."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.memory.actions.push(action)
        return self.memory.observe(obs), reward, terminated, truncated, info
