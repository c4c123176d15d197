"""The residual and the filter as a training wrapper and as an evaluation controller.

:class:`ResidualAction` (training) and :class:`ResidualController` (evaluation) apply the same formula to the same
inputs, bit for bit; :class:`FilteredAction` filters every action in training; :class:`TeacherLabel` labels the
steps of a policy with no base for imitation learning (package docstring:
:mod:`uvdms_gym.residual`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from uvdms_gym.evaluation import Controller, check_action_mode
from uvdms_gym.residual.clearance import FEATURE_CLIP, ClearanceFeatures
from uvdms_gym.residual.composition import (
    ACTION_HIGH,
    ACTION_LOW,
    RESIDUAL_OBSERVATIONS,
    RESIDUAL_SPACES,
    TEACHER_KEY,
    ControllerFactory,
    FilterFactory,
    compose_residual,
    is_residual_penalty,
    is_residual_scale,
    teacher_action,
    teacher_residual,
)
from uvdms_gym.residual.nullspace import NullspaceProjection


def residual_observation(obs: np.ndarray, base_action: np.ndarray, features: np.ndarray | None = None) -> np.ndarray:
    """What a residual policy observes: ``[obs; base_action]`` (and ``features``, if any) in the observation's dtype."""
    obs = np.asarray(obs)
    parts = [obs, np.asarray(base_action, dtype=obs.dtype)]
    if features is not None:
        parts.append(np.asarray(features, dtype=obs.dtype))
    return np.concatenate(parts)


def residual_observation_space(
    observation_space: gym.spaces.Box, action_space: gym.spaces.Box, observation: str = "base"
) -> gym.spaces.Box:
    """The observation space of a residual policy: the environment's, extended by the action box.

    With ``observation="clearance"``, also by the 36 clearance features, in ``[-FEATURE_CLIP, FEATURE_CLIP]``.

    Raises:
        ValueError: Either space is not a one-dimensional ``Box``, or an unknown ``observation``.
    """
    if observation not in RESIDUAL_OBSERVATIONS:
        raise ValueError(f"residual_observation must be one of {RESIDUAL_OBSERVATIONS}, got {observation!r}")
    for what, space in (("observation", observation_space), ("action", action_space)):
        if not isinstance(space, gym.spaces.Box) or len(space.shape) != 1:
            raise ValueError(f"a residual agent needs a one-dimensional Box {what} space, got {space}")
    dtype = observation_space.dtype
    lows = [observation_space.low, action_space.low.astype(dtype)]
    highs = [observation_space.high, action_space.high.astype(dtype)]
    if observation == "clearance":
        lows.append(np.full(ClearanceFeatures.size, -FEATURE_CLIP, dtype))
        highs.append(np.full(ClearanceFeatures.size, FEATURE_CLIP, dtype))
    return gym.spaces.Box(low=np.concatenate(lows), high=np.concatenate(highs), dtype=dtype)  # type: ignore[arg-type]


def _check_unit_box(env: gym.Env, what: str) -> None:
    space = env.action_space
    if not (
        isinstance(space, gym.spaces.Box) and np.all(space.low == ACTION_LOW) and np.all(space.high == ACTION_HIGH)
    ):
        raise ValueError(f"{what} needs the normalised action space Box(-1, 1), got {space}")


class ResidualAction(gym.Wrapper):
    """Training-side residual: the agent's action is added to a base controller's (module docstring).

    ``reset`` resets the environment, then the base (``base.reset(seed)``, as :func:`uvdms_gym.evaluation.run_episode`
    does) and returns ``[obs; a_base]``; ``step(a)`` sends :func:`compose_residual` of the current ``a_base`` and
    ``a`` to the environment, then computes the base's action at the new state for the next observation (also at
    the last state of an episode: the learner bootstraps from it on truncation). ``info`` gains
    ``residual_clipped`` (a clip changed the sum or, with ``space="nullspace"``, the projected output),
    ``residual_base_action`` (the ``a_base`` that was used) and ``residual_action`` (the action sent); the base
    reads the environment's own ``info``.

    Args:
        env: A velocity-mode environment with the action space ``Box(-1, 1)``.
        base_factory: Builds the base controller for ``env``.
        scale: ``residual_scale``, in (0, 1].
        penalty: ``residual_penalty``, a training-side shaping term (0: none): ``reward_residual =
            -penalty * |action|^2 / dim`` is added to the reward (and reported in ``info``), so that the policy
            keeps the residual at zero where the base needs no correction. ``action`` is the policy's output in
            ``[-1, 1]``, so the term lies in ``[-penalty, 0]``.
        observation: ``residual_observation`` (:data:`RESIDUAL_OBSERVATIONS`): ``"clearance"`` appends the
            :class:`ClearanceFeatures` of the new state (after the base's action at it) to every observation.
        space: ``residual_space`` (:data:`RESIDUAL_SPACES`): ``"nullspace"`` projects the policy's output with
            the :class:`NullspaceProjection` at the current state before it is scaled and added.
        teacher_factory: Builds a teacher controller for ``env`` (``None``: none), for imitation learning
            (``agents.algos.dagger``): at every state the teacher acts on the same ``(obs, info)`` as the base, and
            ``step``'s ``info[TEACHER_KEY]`` is :func:`teacher_residual` at the state *the action was taken in* (the
            label of the observation the policy acted on). The teacher never acts on the environment.

    Raises:
        ValueError: A scale outside (0, 1], a negative or non-finite penalty, an action space other than
            ``Box(-1, 1)``, an unknown observation or space (or either on a non-UVDMS environment), or what the
            factory raises.
    """

    def __init__(
        self,
        env: gym.Env,
        base_factory: ControllerFactory,
        scale: float,
        penalty: float = 0.0,
        observation: str = "base",
        space: str = "full",
        teacher_factory: ControllerFactory | None = None,
    ) -> None:
        super().__init__(env)
        if not is_residual_scale(scale):
            raise ValueError(f"residual_scale must be a number in (0, 1], got {scale!r}")
        if not is_residual_penalty(penalty):
            raise ValueError(f"residual_penalty must be a finite number >= 0, got {penalty!r}")
        if space not in RESIDUAL_SPACES:
            raise ValueError(f"residual_space must be one of {RESIDUAL_SPACES}, got {space!r}")
        _check_unit_box(env, "a residual agent")
        self.scale = float(scale)
        self.penalty = float(penalty)
        self.base = base_factory(env)
        self.observation_space = residual_observation_space(env.observation_space, env.action_space, observation)
        self.features = ClearanceFeatures.for_env(env) if observation == "clearance" else None
        self.projection = NullspaceProjection.for_env(env) if space == "nullspace" else None
        self.teacher = None if teacher_factory is None else teacher_factory(env)
        self._base_action: np.ndarray | None = None
        self._teacher_label: np.ndarray | None = None
        self._info: Mapping[str, Any] = {}

    def _label(self, obs: Any, info: Mapping[str, Any]) -> np.ndarray | None:
        """The teacher's label at this state (``None`` without a teacher); call after the base's action."""
        if self.teacher is None:
            return None
        return teacher_residual(np.asarray(self.teacher.predict(obs, info)), self._base_action, self.scale)  # type: ignore[arg-type]

    def _observation(self, obs: Any, info: Mapping[str, Any]) -> np.ndarray:
        features = None if self.features is None else self.features(info, self._base_action)  # type: ignore[arg-type]
        return residual_observation(obs, self._base_action, features)  # type: ignore[arg-type]

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset the environment and the base; the observation is ``[obs; a_base]`` (and the features)."""
        obs, info = self.env.reset(seed=seed, options=options)
        self.base.reset(seed)
        if self.teacher is not None:
            self.teacher.reset(seed)
        self._base_action = np.asarray(self.base.predict(obs, info))
        self._teacher_label = self._label(obs, info)
        self._info = info
        return self._observation(obs, info), info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        """Send ``clip(a_base + scale * action)``; the next observation is ``[obs; a_base(next state)]``."""
        if self._base_action is None:
            raise RuntimeError("ResidualAction.step called before reset")
        base_action = self._base_action
        residual, clipped_projection = (
            (action, False) if self.projection is None else self.projection(self._info, action)
        )
        sent, clipped = compose_residual(base_action, residual, self.scale)
        clipped = clipped or clipped_projection
        obs, reward, terminated, truncated, info = self.env.step(sent)
        label = self._teacher_label
        self._base_action = np.asarray(self.base.predict(obs, info))
        self._teacher_label = self._label(obs, info)
        self._info = info
        observation = self._observation(obs, info)
        info = {**info, "residual_clipped": clipped, "residual_base_action": base_action, "residual_action": sent}
        if label is not None:
            info[TEACHER_KEY] = label
        if self.penalty:
            residual = np.asarray(action, dtype=np.float64)
            info["reward_residual"] = -self.penalty * float(residual @ residual) / residual.size
            reward = float(reward) + info["reward_residual"]
        return observation, reward, terminated, truncated, info


class TeacherLabel(gym.Wrapper):
    """Labels every step with a teacher's command, for imitation learning of a policy with no base.

    At every state the teacher acts on the same ``(obs, info)`` the policy sees, and ``step``'s
    ``info[TEACHER_KEY]`` is :func:`teacher_action` (the teacher's command clipped to ``Box(-1, 1)``) at the state
    *the action was taken in*: the label of the observation the policy acted on. The teacher never acts on the
    environment; the observation and the action pass through unchanged. ``reset`` resets the teacher with the
    environment's seed (as :func:`uvdms_gym.evaluation.run_episode` does).

    Args:
        env: The environment, in the teacher's action mode, with the action space ``Box(-1, 1)``.
        teacher_factory: Builds the teacher for ``env``.

    Raises:
        ValueError: An action space other than ``Box(-1, 1)``, a teacher whose ``action_mode`` is not the
            environment's (the message names both), or what the factory raises.
    """

    def __init__(self, env: gym.Env, teacher_factory: ControllerFactory) -> None:
        super().__init__(env)
        _check_unit_box(env, "imitation of a teacher's command")
        self.teacher = teacher_factory(env)
        mode = getattr(self.teacher, "action_mode", None)
        if mode is not None:
            check_action_mode(f"teacher {getattr(teacher_factory, 'name', type(self.teacher).__name__)}", env, mode)
        self._label: np.ndarray | None = None

    def _teacher_label(self, obs: Any, info: Mapping[str, Any]) -> np.ndarray:
        return teacher_action(np.asarray(self.teacher.predict(obs, info)))  # type: ignore[arg-type]

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset the environment and the teacher; label the first state."""
        obs, info = self.env.reset(seed=seed, options=options)
        self.teacher.reset(seed)
        self._label = self._teacher_label(obs, info)
        return obs, info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        """Step with ``action``; ``info[TEACHER_KEY]`` is the label of the state it was taken in."""
        if self._label is None:
            raise RuntimeError("TeacherLabel.step called before reset")
        label = self._label
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._label = self._teacher_label(obs, info)
        return obs, reward, terminated, truncated, {**info, TEACHER_KEY: label}


class ResidualController:
    """Evaluation-side residual: a base controller plus a trained policy's bounded correction (module docstring).

    ``predict(obs, info)`` computes ``a_base = base.predict(obs, info)``, asks the policy for its output on
    ``[obs; a_base]`` and returns :func:`compose_residual` of the two: for the same ``(obs, info)`` sequence the
    actions :class:`ResidualAction` sends in training. ``last_record`` holds the base's record (its QP slack and
    status feed the episode metrics) with ``zeta_cmd`` renamed ``base_zeta_cmd`` (the command sent is not the
    base's), plus ``residual_clipped``.

    Args:
        base: The base controller (velocity action mode).
        policy: The trained policy's controller; it receives ``[obs; a_base]`` (and ``features(info, a_base)``).
        scale: ``residual_scale``, in (0, 1].
        features: The :class:`ClearanceFeatures` of an agent trained with ``residual_observation="clearance"``
            (:func:`residual_features`; ``None``: none).
        projection: The :class:`NullspaceProjection` of an agent trained with ``residual_space="nullspace"``
            (:func:`residual_projection`; ``None``: none).

    Raises:
        ValueError: A scale outside (0, 1].
    """

    action_mode = "velocity"

    def __init__(
        self,
        base: Controller,
        policy: Controller,
        scale: float,
        features: ClearanceFeatures | None = None,
        projection: NullspaceProjection | None = None,
    ) -> None:
        if not is_residual_scale(scale):
            raise ValueError(f"residual_scale must be a number in (0, 1], got {scale!r}")
        self.base = base
        self.policy = policy
        self.residual_scale = float(scale)
        self.features = features
        self.projection = projection
        self.last_record: dict[str, Any] = {}
        for attr in ("algo", "env_id", "num_timesteps", "source"):  # what evaluation records of an agent
            if hasattr(policy, attr):
                setattr(self, attr, getattr(policy, attr))
        if getattr(base, "mpc", None) is not None:
            self.mpc = base.mpc  # type: ignore[attr-defined]

    def reset(self, seed: int | None = None) -> None:
        """Start an episode (the base's and the policy's ``reset``)."""
        self.base.reset(seed)
        self.policy.reset(seed)
        self.last_record = {}

    def predict(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """``clip(a_base + scale * a_policy, -1, 1)``, ``a_policy`` the policy's output on ``[obs; a_base]``.

        With a projection (``residual_space="nullspace"``) ``a_policy`` is projected first.
        """
        base_action = np.asarray(self.base.predict(obs, info))
        record = dict(getattr(self.base, "last_record", None) or {})
        if "zeta_cmd" in record:
            record["base_zeta_cmd"] = record.pop("zeta_cmd")
        features = None if self.features is None else self.features(info, base_action)
        policy_action = self.policy.predict(residual_observation(obs, base_action, features), info)
        clipped_projection = False
        if self.projection is not None:
            policy_action, clipped_projection = self.projection(info, policy_action)
        action, clipped = compose_residual(base_action, policy_action, self.residual_scale)
        clipped = clipped or clipped_projection
        self.last_record = {**record, "residual_clipped": clipped}
        return action


class _GivenAction:
    """The controller a filter wraps in training: it returns the action it was last given."""

    def __init__(self) -> None:
        self.action: np.ndarray | None = None

    def reset(self, seed: int | None = None) -> None:
        """Nothing to reset."""

    def predict(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The given action."""
        if self.action is None:
            raise RuntimeError("no action given")
        return self.action


class FilteredAction(gym.Wrapper):
    """Training-side command filter: every action goes through a controller-wrapping filter before the environment.

    The filter is built once, as ``filter_factory(inner, env)`` around a controller that returns the action being
    stepped, and is reset with the environment; on ``step(a)`` it receives the observation and ``info`` of the
    current state, exactly as the same filter wrapped around an evaluated controller does. ``info`` gains
    ``filter_active`` and ``filter_change`` from the filter's ``last_record`` (``False`` / 0 when it has none).

    Args:
        env: The environment (velocity mode for ``baselines.safety.filter.SafetyFilter``).
        filter_factory: Wraps a controller in the filter.

    Raises:
        ValueError: An action space other than ``Box(-1, 1)``, or what the factory raises.
    """

    def __init__(self, env: gym.Env, filter_factory: FilterFactory) -> None:
        super().__init__(env)
        _check_unit_box(env, "the command filter")
        self._given = _GivenAction()
        self.filter = filter_factory(self._given, env)
        self._obs: Any = None
        self._info: dict[str, Any] | None = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset the environment and the filter."""
        obs, info = self.env.reset(seed=seed, options=options)
        self.filter.reset(seed)
        self._obs, self._info = obs, info
        return obs, info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        """Step with the filtered action."""
        if self._info is None:
            raise RuntimeError("FilteredAction.step called before reset")
        self._given.action = np.asarray(action)
        filtered = self.filter.predict(self._obs, self._info)
        record = getattr(self.filter, "last_record", None) or {}
        obs, reward, terminated, truncated, info = self.env.step(filtered)
        self._obs, self._info = obs, info
        info = {
            **info,
            "filter_active": bool(record.get("filter_active", False)),
            "filter_change": float(record.get("filter_change", 0.0)),
        }
        return obs, reward, terminated, truncated, info
