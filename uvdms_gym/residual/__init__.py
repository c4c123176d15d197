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
``baselines.safety.filter.SafetyFilter``), the training-time counterpart of wrapping the evaluated controller in the
same filter. With both, the order is the residual first, then the filter: ``FilteredAction`` is the inner wrapper
(``env -> FilteredAction -> ResidualAction``), and at evaluation ``filter(ResidualController(...))``.

[D] The base and the filter are *injected* as factories (:data:`ControllerFactory`, :data:`FilterFactory`): this
module, like all of layer 0, imports no other package of the project; the composition layer
(``leaderboard.suite.registry.BaselineFactory``, ``SafetyFilterFactory``) provides picklable module-level factories, so
that the wrappers also build in ``SubprocVecEnv`` / hybrid workers. :class:`ActionComposition` is what a run's
``config.yml`` and an export's ``agent.json`` record (names, not objects), so evaluation rebuilds the same
composition from the record alone.

Modules: :mod:`~uvdms_gym.residual.composition` (the record and the formula), :mod:`~uvdms_gym.residual.clearance`
(the clearance features), :mod:`~uvdms_gym.residual.obstacle_features` (the obstacle features of a policy that
outputs the whole command), :mod:`~uvdms_gym.residual.nullspace` (the null-space projection),
:mod:`~uvdms_gym.residual.wrappers` (the training wrappers and the evaluation controller); their public names are
importable from here.
"""

from uvdms_gym.residual.clearance import (
    CLEARANCE_RATE_SCALE,
    FEATURE_CLIP,
    ClearanceFeatures,
    KinematicHelper,
    residual_features,
)
from uvdms_gym.residual.composition import (
    ACTION_HIGH,
    ACTION_LOW,
    MAX_FRAME_STACK,
    RECORD_KEYS,
    RESIDUAL_OBSERVATIONS,
    RESIDUAL_SPACES,
    TEACHER_KEY,
    ActionComposition,
    ControllerFactory,
    FilterFactory,
    check_frame_stack,
    compose_residual,
    is_residual_penalty,
    is_residual_scale,
    teacher_action,
    teacher_residual,
)
from uvdms_gym.residual.nullspace import (
    NullspaceProjection,
    residual_projection,
)
from uvdms_gym.residual.obstacle_features import (
    FeatureController,
    ObstacleFeatureController,
    ObstacleFeatureObservation,
    ObstacleFeatures,
    obstacle_feature_space,
    opening_columns,
)
from uvdms_gym.residual.tracking_features import (
    TRACKING_ORIENTATION,
    TRACKING_POSITION,
    TrackingFeatureObservation,
    TrackingFeatures,
    tracking_feature_space,
)
from uvdms_gym.residual.wrappers import (
    FilteredAction,
    ResidualAction,
    ResidualController,
    TeacherLabel,
    residual_observation,
    residual_observation_space,
)

__all__ = [
    "ACTION_HIGH",
    "ACTION_LOW",
    "CLEARANCE_RATE_SCALE",
    "FEATURE_CLIP",
    "MAX_FRAME_STACK",
    "RECORD_KEYS",
    "RESIDUAL_OBSERVATIONS",
    "RESIDUAL_SPACES",
    "TEACHER_KEY",
    "TRACKING_ORIENTATION",
    "TRACKING_POSITION",
    "ActionComposition",
    "ClearanceFeatures",
    "ControllerFactory",
    "FeatureController",
    "FilterFactory",
    "FilteredAction",
    "KinematicHelper",
    "NullspaceProjection",
    "ObstacleFeatureController",
    "ObstacleFeatureObservation",
    "ObstacleFeatures",
    "ResidualAction",
    "ResidualController",
    "TeacherLabel",
    "TrackingFeatureObservation",
    "TrackingFeatures",
    "check_frame_stack",
    "compose_residual",
    "is_residual_penalty",
    "is_residual_scale",
    "obstacle_feature_space",
    "opening_columns",
    "residual_features",
    "residual_observation",
    "residual_observation_space",
    "residual_projection",
    "teacher_action",
    "teacher_residual",
    "tracking_feature_space",
]
