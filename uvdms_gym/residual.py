"""Action compositions shared by training and evaluation: a bounded learned residual and a command filter.

Residual agent. A learned policy corrects a base controller's velocity command by a bounded amount::

    a_base = base.predict(obs, info)
    a_env  = clip(a_base + residual_scale * a_policy, -1, 1)

``a_policy`` is the policy's output in ``[-1, 1]^18`` (already multiplied by the agent's own ``action_scale``, if
any), so the residual moves each normalised command by at most ``residual_scale``. The policy observes
``[obs; a_base]``: the environment's observation followed by the base's action at the same state (18 entries in
``[-1, 1]``), so it knows what it corrects (:func:`residual_observation`, :func:`residual_observation_space`).
With ``residual_observation="clearance"`` it also observes 36 clearance features (:class:`ClearanceFeatures`): the
direction in action space that opens the clearances closer than ``d2``, and the rate at which the base's command
changes each clearance. They are computed from ``info`` with the environment's explicit kinematic model, the same
way in training and at evaluation; they tell the policy where the obstacles are, not what to do about them.
With ``residual_space="nullspace"`` the policy's output is first projected onto the null space of the two
end-effector positions (:class:`NullspaceProjection`): ``a_env = clip(a_base + residual_scale * clip(P a_policy,
-1, 1), -1, 1)``, so that, to first order, the residual moves the vehicle and the arms without moving the hands
and leaves the tracking to the base; what to move, and when, is still learned.
:func:`compose_residual` is the one implementation of the formula: :class:`ResidualAction` applies it in training
(a Gymnasium wrapper around the training and evaluation-callback environments) and :class:`ResidualController`
at evaluation (around the trained agent's controller), so that for the same inputs both send the same action,
bit for bit.

Command filter. :class:`FilteredAction` passes every action through a controller-wrapping filter (in this project
``baselines.safety.SafetyFilter``), the training-time counterpart of wrapping the evaluated controller in the same
filter. With both, the order is the residual first, then the filter: ``FilteredAction`` is the inner wrapper
(``env -> FilteredAction -> ResidualAction``), and at evaluation ``filter(ResidualController(...))``.

[D] The base and the filter are *injected* as factories (:data:`ControllerFactory`, :data:`FilterFactory`): this
module, like all of layer 0, imports no other package of the project; the composition layer
(``leaderboard.registry.BaselineFactory``, ``SafetyFilterFactory``) provides picklable module-level factories, so
that the wrappers also build in ``SubprocVecEnv`` / hybrid workers. :class:`ActionComposition` is what a run's
``config.yml`` and an export's ``agent.json`` record (names, not objects), so evaluation rebuilds the same
composition from the record alone.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import gymnasium as gym
import numpy as np

from uvdms_gym.distances import compute_distances, distance_jacobian, velocity_damper
from uvdms_gym.evaluation import Controller
from uvdms_gym.kinematics import KinematicModel
from uvdms_gym.params import D1, D2

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
)
"""The keys of an :class:`ActionComposition` in a run's config entry and in an export's ``agent.json``."""
RESIDUAL_OBSERVATIONS: tuple[str, ...] = ("base", "clearance")
"""What a residual policy observes besides the environment's observation: ``"base"``, the base's action;
``"clearance"``, the base's action and the :class:`ClearanceFeatures`."""
RESIDUAL_SPACES: tuple[str, ...] = ("full", "nullspace")
"""Where a residual acts: ``"full"``, on the whole command; ``"nullspace"``, projected onto the null space of the
end-effector positions first (:class:`NullspaceProjection`)."""
CLEARANCE_RATE_SCALE = 0.1
"""Scale (m/s) of the clearance rates among the :class:`ClearanceFeatures` (a rate of 0.1 m/s observes as 1)."""
FEATURE_CLIP = 10.0
"""The clearance features are clipped to ``[-FEATURE_CLIP, FEATURE_CLIP]`` (the environments' observation clip)."""


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

    Raises:
        ValueError: A scale outside (0, 1], a scale without a base or a base without a scale, a base that is
            not a non-empty string, or an unknown residual observation or space (or one other than ``"base"`` /
            ``"full"`` without a base).
    """

    residual_base: str | None = None
    residual_scale: float | None = None
    safety_filter: bool = False
    residual_observation: str = "base"
    residual_space: str = "full"

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
        return cls(
            residual_base=record.get("residual_base"),
            residual_scale=float(scale) if is_residual_scale(scale) else scale,
            safety_filter=False if safety_filter is None else safety_filter,
            residual_observation="base" if observation is None else observation,
            residual_space="full" if space is None else space,
        )

    def describe(self, name: str) -> str:
        """``name`` prefixed with what the agent is made of: ``residual-<base>-<name>`` for a residual agent."""
        if not self.is_residual:
            return name
        prefix = f"residual-{self.residual_base}-"
        return name if name.startswith(prefix) else prefix + name


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


TEACHER_KEY = "teacher_residual"
"""``info`` key of :class:`ResidualAction`'s teacher label (:func:`teacher_residual`)."""


def is_residual_penalty(value: Any) -> bool:
    """Whether ``value`` is a finite real number >= 0 (a valid ``residual_penalty``)."""
    return (
        isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value) and float(value) >= 0.0
    )


_Helper = TypeVar("_Helper", bound="_KinematicHelper")


class _KinematicHelper:
    """What :class:`ClearanceFeatures` and :class:`NullspaceProjection` share: a kinematic model and ``zeta_max``.

    Args:
        kin: A kinematic model of the environment's vehicle (its state is overwritten on every call).
        zeta_max: The velocity-mode action scale (18).
    """

    option = ""
    """The composition option that needs the helper (for the error of :meth:`for_env`)."""

    def __init__(self, kin: Any, zeta_max: np.ndarray) -> None:
        self.kin = kin
        self.zeta_max = np.asarray(zeta_max, dtype=np.float64).copy()
        if self.zeta_max.shape != (18,):
            raise ValueError(f"zeta_max must have 18 entries, got shape {self.zeta_max.shape}")

    @classmethod
    def for_env(cls: type[_Helper], env: Any) -> _Helper:
        """The helper for a UVDMS environment (through wrappers).

        It uses a kinematic model of its own, built from the environment's ``params`` (not shared with the
        base controller), and the environment's ``zeta_max``.

        Raises:
            ValueError: ``env`` is not a UVDMS environment.
        """
        base = getattr(env, "unwrapped", env)
        if not hasattr(base, "params") or not hasattr(base, "zeta_max"):
            raise ValueError(f"{cls.option} needs a UVDMS environment (params, zeta_max), got {base!r}")
        return cls(KinematicModel(base.params), base.zeta_max)


class ClearanceFeatures(_KinematicHelper):
    """The 36 clearance features of ``residual_observation="clearance"``, from ``info`` and a kinematic model.

    With ``d`` the 18 clearances (m), ``G = -J_dis diag(zeta_max)`` (18 x 18: the rate of each clearance per unit
    of normalised action, since ``d_dot = -J_dis zeta`` and ``zeta = a * zeta_max``) and ``w = 1 - S(d)`` (0
    beyond ``d2``, 1 inside ``d1``)::

        direction = sum_i w_i G_i / |G_i|                 (18): opens the clearances closer than d2
        rate      = G a_base / CLEARANCE_RATE_SCALE        (18): each clearance's rate under the base's command

    both clipped to ``[-FEATURE_CLIP, FEATURE_CLIP]``. The direction is zero when every clearance is beyond
    ``d2``. The features are a function of ``info``'s configuration (``eta``, ``q``) and of ``a_base`` only,
    evaluated on a kinematic model built from the environment's parameters, so training and evaluation compute
    the same values for the same inputs.

    Args:
        kin: A kinematic model of the environment's vehicle (its state is overwritten on every call).
        zeta_max: The velocity-mode action scale (18).
    """

    size = 36
    """Number of features."""
    option = "residual_observation='clearance'"

    def __call__(self, info: Mapping[str, Any], base_action: np.ndarray) -> np.ndarray:
        """``[direction; rate]`` (36, float64) at the configuration of ``info``."""
        self.kin.set_state(np.asarray(info["eta"], dtype=np.float64), np.asarray(info["q"], dtype=np.float64))
        res = compute_distances(self.kin, "exact")
        gain = -distance_jacobian(self.kin, res) * self.zeta_max
        weight = 1.0 - velocity_damper(res.d, D1, D2)
        norms = np.sqrt(np.einsum("ij,ij->i", gain, gain))
        direction = (weight / np.maximum(norms, 1e-12)) @ gain
        rate = gain @ np.asarray(base_action, dtype=np.float64) / CLEARANCE_RATE_SCALE
        return np.clip(np.concatenate([direction, rate]), -FEATURE_CLIP, FEATURE_CLIP)


class NullspaceProjection(_KinematicHelper):
    """The projection of ``residual_space="nullspace"``: residual commands that leave both hands where they are.

    With ``J`` the (6, 18) Jacobian of the two end-effector positions (world-aligned) per unit of normalised
    action, ``J = J_pos diag(zeta_max)``, at the configuration of ``info``, and ``J^+`` its Moore-Penrose
    pseudo-inverse, ``P = I - J^+ J`` (18 x 18, symmetric, ``J P = 0``); a policy output ``u`` becomes
    ``clip(P u, -1, 1)``. To first order the projected command moves the vehicle and the arms without moving the
    end effectors; the clip (and the base's own command, which is not projected) can break this at large commands.
    Evaluated on a kinematic model built from the environment's parameters, from ``info`` alone, so training and
    evaluation project alike.

    Args:
        kin: A kinematic model of the environment's vehicle (its state is overwritten on every call).
        zeta_max: The velocity-mode action scale (18).
    """

    option = "residual_space='nullspace'"

    def matrix(self, info: Mapping[str, Any]) -> np.ndarray:
        """``P`` (18, 18) at the configuration of ``info``."""
        self.kin.set_state(np.asarray(info["eta"], dtype=np.float64), np.asarray(info["q"], dtype=np.float64))
        jac = self.kin.ee_jacobian()[_EE_POSITION_ROWS] * self.zeta_max
        return np.eye(jac.shape[1]) - np.linalg.pinv(jac) @ jac

    def __call__(self, info: Mapping[str, Any], policy_action: np.ndarray) -> tuple[np.ndarray, bool]:
        """``clip(P u, -1, 1)`` (18, float64) for the policy output ``u`` at ``info``'s configuration, and a flag.

        The flag says whether the clip changed anything (``P`` is a projection, but single entries of ``P u`` can
        exceed 1).
        """
        raw = self.matrix(info) @ np.asarray(policy_action, dtype=np.float64)
        projected = np.clip(raw, ACTION_LOW, ACTION_HIGH)
        return projected, bool(np.any(projected != raw))


_EE_POSITION_ROWS = [0, 1, 2, 6, 7, 8]
"""Rows of :meth:`uvdms_gym.kinematics.KinematicModel.ee_jacobian` that are the two end-effector positions."""


def residual_projection(composition: ActionComposition, env: Any) -> NullspaceProjection | None:
    """The projection a composition's residual goes through on ``env`` (``None``: the full command space)."""
    if composition.residual_space == "nullspace":
        return NullspaceProjection.for_env(env)
    return None


def residual_features(composition: ActionComposition, env: Any) -> ClearanceFeatures | None:
    """The extra features a composition's residual policy observes on ``env`` (``None``: only the base's action)."""
    if composition.residual_observation == "clearance":
        return ClearanceFeatures.for_env(env)
    return None


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
        env: The environment (velocity mode for ``baselines.safety.SafetyFilter``).
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
