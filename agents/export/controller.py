"""The controller of a trained agent: :class:`AgentController`, its observation normaliser and the format's errors.

Every way of loading an agent (:mod:`agents.export.agent`: an SB3 run or zip through :mod:`agents.export.sb3`, a
weights-only export through :mod:`agents.export.weights`) ends in an :class:`AgentController` (``reset(seed)``,
``predict(obs, info) -> action``, deterministic, VecNormalize observation statistics applied without a VecEnv).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
from gymnasium import spaces
from stable_baselines3.common.policies import BasePolicy

from agents.common.history import PolicyMemory, unstacked_space
from agents.common.wrappers import is_unit_scale
from agents.export.fast_actor import FastActor
from uvdms_gym.evaluation import check_action_mode
from uvdms_gym.residual import (
    ActionComposition,
    ObstacleFeatures,
    TrackingFeatures,
    obstacle_feature_space,
    residual_observation_space,
    tracking_feature_space,
)
from uvdms_gym.utils.kwargs import env_family

SHIPPED_MODEL = "model.zip"
"""Model file of a shipped agent folder (``trained_agents/<name>/``, written by :mod:`scripts.ship_agent`)."""
SHIPPED_STATS = "vecnormalize.pkl"
"""VecNormalize statistics of a shipped agent folder."""

Which = Literal["final", "best"]


class UntrustedFileError(ValueError):
    """Refused to unpickle a file that is neither trusted by the caller nor inside ``trained_agents/``.

    Args:
        message: The error message.
        path: The refused file (``None``: not given).
    """

    def __init__(self, message: str, path: str | Path | None = None) -> None:
        super().__init__(message)
        self.path = path


class ExportFormatError(ValueError):
    """A weights-only export is malformed, tampered with, or cannot represent the policy."""


class EnvMismatchWarning(UserWarning):
    """An agent is evaluated on an environment id other than the one it was trained on."""


# ------------------------------------------------------------------------------------------------------
# Controller
# ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ObsNormalizer:
    """VecNormalize observation normalisation without a VecEnv (same formula and dtype as SB3).

    Attributes:
        mean: Running mean of the observations (float64).
        var: Running variance of the observations (float64).
        clip_obs: Normalised observations are clipped to ``[-clip_obs, clip_obs]``.
        epsilon: Added to the variance.
    """

    mean: np.ndarray
    var: np.ndarray
    clip_obs: float
    epsilon: float

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Normalise ``obs`` (any leading batch dimensions) and return float32."""
        normalized = np.clip((obs - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip_obs, self.clip_obs)
        return normalized.astype(np.float32)


class AgentController:
    """A trained policy as a deterministic controller: ``reset(seed)`` then ``predict(obs, info)``.

    Attributes:
        policy: The SB3 policy (evaluation mode).
        algo: Algorithm name.
        env_id: Environment id the agent was trained on (``None`` if unknown).
        env_kwargs: ``gymnasium.make`` keyword arguments of the training environment.
        normalizer: Observation normalisation (``None`` if the agent was trained without it).
        num_timesteps: Training steps of the loaded model (``None`` if unknown).
        source: Where the agent was loaded from.
        action_scale: The network's output is multiplied by this (``TrainConfig.action_scale``).
        fast_actor: The policy's actor called directly (:class:`agents.export.fast_actor.FastActor`; ``None`` for a
            policy it cannot call, which ``policy.predict`` evaluates): the same actions, without SB3's per-call
            overhead.
        composition: The residual base and safety filter the agent was trained with
            (:class:`uvdms_gym.residual.ActionComposition`). A residual agent observes ``[obs; a_base]`` and its
            output is a residual: evaluate it through ``leaderboard.suite.registry.make_controller``, which composes the
            base (and the filter) from this record. With ``frame_stack > 1`` or ``action_history`` the controller
            keeps the policy's memory (:class:`agents.common.history.PolicyMemory`), cleared by :meth:`reset`; with
            ``navigation_filter`` the composition layer feeds it the filter's estimate.
        memory: The memory of a policy with memory (``None``: ``frame_stack`` 1 and no ``action_history``).
    """

    def __init__(
        self,
        policy: BasePolicy,
        *,
        algo: str,
        env_id: str | None = None,
        env_kwargs: Mapping[str, Any] | None = None,
        normalizer: ObsNormalizer | None = None,
        num_timesteps: int | None = None,
        source: str = "",
        action_scale: float = 1.0,
        composition: ActionComposition | None = None,
    ) -> None:
        if not is_unit_scale(action_scale):
            raise ValueError(f"action_scale must be in (0, 1], got {action_scale}")
        self.policy = policy
        self.policy.set_training_mode(False)
        self.algo = algo
        self.env_id = env_id
        self.env_kwargs = dict(env_kwargs or {})
        self.normalizer = normalizer
        self.num_timesteps = num_timesteps
        self.source = source
        self.action_scale = float(action_scale)
        self.composition = composition or ActionComposition()
        self.seed: int | None = None
        self.fast_actor = FastActor.from_policy(policy)
        k, m = self.composition.frame_stack, self.composition.action_history
        size = int(np.prod(policy.action_space.shape))
        self.memory = PolicyMemory(k, m, size) if k > 1 or m else None

    @property
    def observation_space(self) -> spaces.Space:
        """The space of the observation :meth:`predict` takes (un-normalised).

        For a policy with memory, one observation: the policy's own input is the memory's
        (``policy.observation_space``).
        """
        space = self.policy.observation_space
        if self.memory is None:
            return space
        composition = self.composition
        size = int(np.prod(self.policy.action_space.shape))
        return unstacked_space(space, composition.frame_stack, composition.action_history, size)

    @property
    def action_space(self) -> spaces.Space:
        """Action space of the policy's outputs."""
        return self.policy.action_space

    def check_env_id(self, env_id: str | None) -> bool:
        """Warn if the agent is about to run on another environment than the one it was trained on.

        An agent's observation layout and reward are those of its training environment: a CircleTrack agent
        evaluated on Transport gets observations of the same shape but another meaning. Evaluation code
        (:func:`check_agent`, used by ``uvdms evaluate`` and the leaderboard) calls this.

        Args:
            env_id: Id of the evaluation environment (``None``: unknown, nothing to check).

        Returns:
            Whether the ids agree (``True`` when either is unknown).

        Warns:
            EnvMismatchWarning: The ids differ (the message names both).
        """
        if env_id is None or self.env_id is None or env_id == self.env_id:
            return True
        if env_family(env_id) == env_family(self.env_id):  # v0 <-> v1 of the same task
            message = (
                f"agent {self.source or self.algo} was trained on {self.env_id} but runs on {env_id}: the "
                "observations and actions are the same, only the reward differs (its return is not comparable)"
            )
        else:
            message = (
                f"agent {self.source or self.algo} was trained on {self.env_id} but runs on {env_id}: its "
                "observations there mean something else, so its actions are not those of a trained policy"
            )
        warnings.warn(message, EnvMismatchWarning, stacklevel=2)
        return False

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: clear the policy's memory (if any); the seed is only recorded (deterministic)."""
        self.seed = seed
        if self.memory is not None:
            self.memory.reset()

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """The observation as the network sees it (normalised if the agent was trained with VecNormalize)."""
        obs = np.asarray(obs, dtype=self.policy.observation_space.dtype)
        return self.normalizer(obs) if self.normalizer is not None else obs

    def predict(self, obs: np.ndarray, info: Mapping[str, Any] | None = None) -> np.ndarray:
        """Deterministic action for one observation (or a batch with a leading dimension).

        Args:
            obs: Raw environment observation (one, not a batch, for a policy with memory: it joins the memory,
                and so does the action returned).
            info: The environment's info dict (unused; for interface parity with other controllers).

        Returns:
            The action (``action_scale`` times the network's), within the action space bounds.
        """
        if self.memory is not None:
            obs = self.memory.observe(obs)
        if self.fast_actor is not None:
            action = self.fast_actor(self.normalize(obs))
        else:
            with torch.no_grad():
                action, _ = self.policy.predict(self.normalize(obs), deterministic=True)
        if self.memory is not None:
            self.memory.actions.push(action)  # the network's output, as the training wrapper records it
        return action if self.action_scale == 1.0 else (self.action_scale * action).astype(action.dtype)


def check_agent(agent: Any, env: Any, name: str = "agent") -> None:
    """Check that a loaded agent fits ``env``: its action mode and its observation/action shapes.

    An agent trained on another environment id gets a warning (:class:`EnvMismatchWarning`), not an error:
    running it elsewhere is allowed, but never silently. A residual agent (its ``composition``) observes the
    environment's observation extended by the base's action (:func:`uvdms_gym.residual.residual_observation_space`).

    Raises:
        ValueError: On a mismatch (the message names the expected and found values).
    """
    mode = (getattr(agent, "env_kwargs", None) or {}).get("action_mode", "velocity")
    check_action_mode(f"agent {name}", env, mode)
    if hasattr(agent, "check_env_id") and env.spec is not None:
        agent.check_env_id(env.spec.id)  # warns (EnvMismatchWarning) on another env id
    composition = getattr(agent, "composition", None) or ActionComposition()
    expected = _expected_observation_space(composition, env)
    if tuple(agent.observation_space.shape) != tuple(expected.shape):
        raise ValueError(
            f"agent {name} expects observations of shape {agent.observation_space.shape}, the environment gives "
            f"{expected.shape}{_observation_parts(composition, env)}"
        )
    if tuple(agent.action_space.shape) != tuple(env.action_space.shape):
        raise ValueError(f"agent {name} outputs actions of shape {agent.action_space.shape}")


def _expected_observation_space(composition: ActionComposition, env: Any) -> spaces.Box:
    """The observation space a policy of ``composition`` was trained on, in ``env`` (one observation of its memory)."""
    expected = env.observation_space
    if composition.is_residual:
        expected = residual_observation_space(env.observation_space, env.action_space, composition.residual_observation)
    if composition.obstacle_features:
        expected = obstacle_feature_space(env.observation_space, ObstacleFeatures.for_env(env))
    if composition.tracking_features:
        TrackingFeatures.for_env(env)  # a clear error on an environment without tracking rows
        expected = tracking_feature_space(expected)
    return expected


def _observation_parts(composition: ActionComposition, env: Any) -> str:
    """What a policy of ``composition`` observes besides the environment's observation (for an error message)."""
    what = ""
    if composition.is_residual:
        what = f" (with the residual base's {env.action_space.shape[0]} actions"
        if composition.residual_observation != "base":
            what += f" and the {composition.residual_observation} features"
        what += ")"
    if composition.obstacle_features:
        what += " (with the obstacle features)"
    if composition.tracking_features:
        what += " (with the tracking features)"
    if composition.frame_stack > 1 or composition.action_history:
        what += f" (each of the {composition.frame_stack} observations its memory holds)"
    return what


def recorded_composition(record: Mapping[str, Any], where: str) -> ActionComposition:
    """The residual base and safety filter recorded in a run's config entry or an export's ``agent.json``.

    Records written before these keys existed hold none of them: a plain agent.

    Raises:
        ExportFormatError: Invalid recorded values (the message names ``where``).
    """
    try:
        return ActionComposition.from_record(record)
    except ValueError as exc:
        raise ExportFormatError(f"{where}: {exc}") from None
