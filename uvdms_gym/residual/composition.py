"""The record of an action composition and its arithmetic: the residual formula, the teacher's label.

:class:`ActionComposition` is what a run's ``config.yml`` and an export's ``agent.json`` record;
:func:`compose_residual` is the one implementation of ``clip(a_base + s * a_policy, -1, 1)`` (package docstring:
:mod:`uvdms_gym.residual`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from uvdms_gym.evaluation import Controller

ControllerFactory = Callable[[Any], Controller]
"""``(env) -> controller``: builds a base controller for an environment (picklable in training)."""
FilterFactory = Callable[[Controller, Any], Controller]
"""``(controller, env) -> controller``: wraps a controller so that its actions are filtered (picklable in training)."""

ACTION_LOW = -1.0
"""Lower bound of the normalised action space (the composed action is clipped to it)."""
ACTION_HIGH = 1.0
"""Upper bound of the normalised action space."""
RECORD_KEYS: tuple[str, ...] = (
    "residual_base",
    "residual_scale",
    "residual_observation",
    "residual_space",
    "safety_filter",
    "navigation_filter",
    "frame_stack",
    "action_history",
    "obstacle_features",
    "tracking_features",
)
"""The keys of an :class:`ActionComposition` in a run's config entry and in an export's ``agent.json``."""
MAX_FRAME_STACK = 64
"""The most observations a policy's history may hold (``frame_stack``): far beyond the delays it stands for (a few
control steps); a bound that keeps a typo from building a network of a million inputs."""
RESIDUAL_OBSERVATIONS: tuple[str, ...] = ("base", "clearance")
"""What a residual policy observes besides the environment's observation: ``"base"``, the base's action;
``"clearance"``, the base's action and the :class:`ClearanceFeatures`."""
RESIDUAL_SPACES: tuple[str, ...] = ("full", "nullspace")
"""Where a residual acts: ``"full"``, on the whole command; ``"nullspace"``, projected onto the null space of the
end-effector positions first (:class:`NullspaceProjection`)."""


def is_residual_scale(value: Any) -> bool:
    """Whether ``value`` is a real number in (0, 1] (a valid ``residual_scale``)."""
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(value)
        and 0.0 < float(value) <= 1.0
    )


@dataclass(frozen=True)
class ActionComposition:
    """How an agent's output reaches the environment: an optional residual base and an optional safety filter.

    Recorded as plain data (the keys of :data:`RECORD_KEYS`) in a run's ``config.yml`` and an export's
    ``agent.json``; the composition layer turns the names back into controllers.

    Attributes:
        residual_base: Name of the base controller the policy's output is added to (``None``: a plain agent).
            Which names are valid (velocity-mode baselines) is the composition layer's to check.
        residual_scale: Bound of the residual, in (0, 1]; given exactly when ``residual_base`` is.
        safety_filter: The (composed) velocity command goes through the safety filter.
        residual_observation: What the residual policy observes besides the environment's observation (one of
            :data:`RESIDUAL_OBSERVATIONS`; anything but ``"base"`` needs a residual base). Records written before
            this key existed are ``"base"``.
        residual_space: Where the residual acts (one of :data:`RESIDUAL_SPACES`; ``"nullspace"`` needs a residual
            base). Records written before this key existed are ``"full"``.
        navigation_filter: The policy observes the navigation filter's estimate where the measured state was
            (:class:`uvdms_gym.realism.navigation.NavigationFilterWrapper` in training, ``FilteredController`` at
            evaluation; at ``realism=0`` nothing changes). The filter is the vehicle's software, so the agent
            still sees only measurements. Records written before this key existed are ``False``.
        frame_stack: The policy observes its last ``frame_stack`` observations, oldest first, concatenated (1: the
            current one only; a policy with memory otherwise). At an episode's start the history holds copies of
            its first observation. Records written before this key existed are ``1``.
        action_history: The policy also observes its own last ``action_history`` actions, oldest first, zeros
            before its first (0: none): under an action delay, the commands still on their way. Records written
            before this key existed are ``0``.
        obstacle_features: The policy also observes the obstacle features of its observation
            (:class:`uvdms_gym.residual.ObstacleFeatures`: each observed obstacle's nearest robot part, its gap, rates
            and the action direction that opens it), computed from the observation with the environment's kinematic
            model; only for an agent without a residual base. Records written before this key existed are ``False``.
        tracking_features: The policy also observes its current tracking error magnified to the scale of success
            (:class:`uvdms_gym.residual.TrackingFeatures`, after the obstacle features); only for an agent without a
            residual base. Records written before this key existed are ``False``.

    Raises:
        ValueError: A scale outside (0, 1], a scale without a base or a base without a scale, a base that is
            not a non-empty string, an unknown residual observation or space (or one other than ``"base"`` /
            ``"full"`` without a base), a ``navigation_filter`` that is not a bool, a ``frame_stack`` that is
            not an integer in [1, :data:`MAX_FRAME_STACK`], an ``action_history`` not in [0, it], or
            ``obstacle_features`` or ``tracking_features`` that is not a bool or comes with a residual base.
    """

    residual_base: str | None = None
    residual_scale: float | None = None
    safety_filter: bool = False
    residual_observation: str = "base"
    residual_space: str = "full"
    navigation_filter: bool = False
    frame_stack: int = 1
    action_history: int = 0
    obstacle_features: bool = False
    tracking_features: bool = False

    def __post_init__(self) -> None:
        if self.residual_base is not None and (not isinstance(self.residual_base, str) or not self.residual_base):
            raise ValueError(f"residual_base must be a controller name, got {self.residual_base!r}")
        if self.residual_base is None and self.residual_scale is not None:
            raise ValueError(f"residual_scale {self.residual_scale} is given without a residual_base")
        if self.residual_base is not None and not is_residual_scale(self.residual_scale):
            raise ValueError(
                f"residual_scale must be a number in (0, 1] for residual_base {self.residual_base!r}, "
                f"got {self.residual_scale!r}"
            )
        if not isinstance(self.safety_filter, bool):
            raise ValueError(f"safety_filter must be true or false, got {self.safety_filter!r}")
        if self.residual_observation not in RESIDUAL_OBSERVATIONS:
            raise ValueError(
                f"residual_observation must be one of {RESIDUAL_OBSERVATIONS}, got {self.residual_observation!r}"
            )
        if self.residual_observation != "base" and self.residual_base is None:
            raise ValueError(
                f"residual_observation={self.residual_observation!r} is what a residual policy observes, but there is "
                "no residual_base"
            )
        if self.residual_space not in RESIDUAL_SPACES:
            raise ValueError(f"residual_space must be one of {RESIDUAL_SPACES}, got {self.residual_space!r}")
        if self.residual_space != "full" and self.residual_base is None:
            raise ValueError(
                f"residual_space={self.residual_space!r} is where a residual acts, but there is no residual_base"
            )
        self._check_memory()

    def _check_memory(self) -> None:
        """The navigation filter's flag, the history lengths and the features' flags (see the class)."""
        if not isinstance(self.navigation_filter, bool):
            raise ValueError(f"navigation_filter must be true or false, got {self.navigation_filter!r}")
        check_frame_stack(self.frame_stack)
        if self.action_history != 0:
            check_frame_stack(self.action_history, "action_history")
        for key in ("obstacle_features", "tracking_features"):
            value = getattr(self, key)
            if not isinstance(value, bool):
                raise ValueError(f"{key} must be true or false, got {value!r}")
            if value and self.residual_base is not None:
                raise ValueError(
                    f"{key} is for a policy that outputs the whole command; a residual policy observes "
                    "residual_observation's features instead"
                )

    @property
    def is_residual(self) -> bool:
        """Whether the agent is a residual on a base controller."""
        return self.residual_base is not None

    @property
    def is_plain(self) -> bool:
        """Whether the policy's output is the environment's action (no residual, no filter)."""
        return not self.is_residual and not self.safety_filter

    def to_record(self) -> dict[str, Any]:
        """The record: ``{"residual_base": ..., "residual_scale": ..., "residual_observation": ..., ...}``."""
        scale = None if self.residual_scale is None else float(self.residual_scale)
        return {
            "residual_base": self.residual_base,
            "residual_scale": scale,
            "residual_observation": self.residual_observation,
            "residual_space": self.residual_space,
            "safety_filter": self.safety_filter,
            "navigation_filter": self.navigation_filter,
            "frame_stack": self.frame_stack,
            "action_history": self.action_history,
            "obstacle_features": self.obstacle_features,
            "tracking_features": self.tracking_features,
        }

    @classmethod
    def from_record(cls, record: Mapping[str, Any] | None) -> ActionComposition:
        """The composition of a record (a config entry or ``agent.json``; absent keys: a plain agent).

        Raises:
            ValueError: The record's values are invalid (see the class).
        """
        record = record or {}
        scale = record.get("residual_scale")
        safety_filter = record.get("safety_filter")
        observation = record.get("residual_observation")
        space = record.get("residual_space")
        navigation_filter = record.get("navigation_filter")
        frame_stack = record.get("frame_stack")
        action_history = record.get("action_history")
        obstacle_features = record.get("obstacle_features")
        tracking_features = record.get("tracking_features")
        return cls(
            residual_base=record.get("residual_base"),
            residual_scale=float(scale) if is_residual_scale(scale) else scale,
            safety_filter=False if safety_filter is None else safety_filter,
            residual_observation="base" if observation is None else observation,
            residual_space="full" if space is None else space,
            navigation_filter=False if navigation_filter is None else navigation_filter,
            frame_stack=1 if frame_stack is None else frame_stack,
            action_history=0 if action_history is None else action_history,
            obstacle_features=False if obstacle_features is None else obstacle_features,
            tracking_features=False if tracking_features is None else tracking_features,
        )

    def describe(self, name: str) -> str:
        """``name`` prefixed with what the agent is made of: ``residual-<base>-<name>`` for a residual agent."""
        if not self.is_residual:
            return name
        prefix = f"residual-{self.residual_base}-"
        return name if name.startswith(prefix) else prefix + name


def check_frame_stack(value: Any, key: str = "frame_stack") -> int:
    """``value`` if it is a valid history length ``key`` (an integer in [1, :data:`MAX_FRAME_STACK`]).

    Raises:
        ValueError: Anything else (the message names ``key`` and the value).
    """
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_FRAME_STACK:
        raise ValueError(f"{key} must be an integer in [1, {MAX_FRAME_STACK}], got {value!r}")
    return value


def compose_residual(base_action: np.ndarray, policy_action: np.ndarray, scale: float) -> tuple[np.ndarray, bool]:
    """``clip(base_action + scale * policy_action, -1, 1)`` and whether the clip changed anything.

    Computed in float64 and returned as float32 (the action space's dtype), so the training wrapper and the
    evaluation controller, which both call this, agree to the bit.

    Args:
        base_action: The base controller's action (18).
        policy_action: The policy's output (18, in ``[-1, 1]``).
        scale: ``residual_scale``, in (0, 1].

    Returns:
        ``(action, clipped)``.
    """
    raw = np.asarray(base_action, dtype=np.float64) + float(scale) * np.asarray(policy_action, dtype=np.float64)
    action = np.clip(raw, ACTION_LOW, ACTION_HIGH)
    return action.astype(np.float32), bool(np.any(action != raw))


def teacher_residual(teacher_action: np.ndarray, base_action: np.ndarray, scale: float) -> np.ndarray:
    """The residual policy output closest to a teacher's command: ``clip((a_teacher - a_base) / scale, -1, 1)``.

    :func:`compose_residual` of ``base_action`` and this output is the teacher's action wherever the teacher
    stays within ``scale`` of the base, and the teacher's action clipped to that bound elsewhere. It is the label
    of imitation learning on a residual (:class:`ResidualAction`'s ``teacher_factory``), computed in float64 and
    returned as float32 (the action space's dtype).
    """
    raw = (np.asarray(teacher_action, dtype=np.float64) - np.asarray(base_action, dtype=np.float64)) / float(scale)
    return np.clip(raw, ACTION_LOW, ACTION_HIGH).astype(np.float32)


def teacher_action(command: np.ndarray) -> np.ndarray:
    """The label of imitation learning with no base: the teacher's ``command`` clipped to the action box, float32.

    :func:`teacher_residual` over a zero base with scale 1 (a policy that outputs the whole command).
    """
    return teacher_residual(command, np.zeros(np.shape(command)), 1.0)


TEACHER_KEY = "teacher_residual"
"""``info`` key of the teacher's label: :class:`ResidualAction`'s (:func:`teacher_residual`) and
:class:`TeacherLabel`'s (:func:`teacher_action`, the label of a policy with no base)."""


def is_residual_penalty(value: Any) -> bool:
    """Whether ``value`` is a finite real number >= 0 (a valid ``residual_penalty``)."""
    return (
        isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value) and float(value) >= 0.0
    )
