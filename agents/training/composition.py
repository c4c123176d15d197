"""What a configuration composes: the residual base, the safety filter and an imitation learner's teacher.

:func:`composition_factories` turns a configuration's ``residual_base``, ``safety_filter`` and ``dagger``'s
``teacher`` into the factories the training envs use (``components`` are injected by the composition layer: this
package never imports ``baselines``); :func:`check_vec_env` refuses ``--vec-env rollout`` for the algorithms that
cannot collect parallel rollouts.
"""

from __future__ import annotations

from agents.algos.dagger import teacher_margin, teacher_name, teacher_outer_margin
from agents.common.envs import ActionComponents
from agents.common.rollouts import check_rollout_vec_env
from agents.config import ConfigError, TrainConfig
from uvdms_gym.residual import ControllerFactory, FilterFactory

DEFAULT_ACTION_MODE = "velocity"
"""The uvdms environments' default ``action_mode`` (a training env without one commands velocities)."""


def composition_factories(
    cfg: TrainConfig, components: ActionComponents | None
) -> tuple[ControllerFactory | None, FilterFactory | None, ControllerFactory | None]:
    """The base, filter and teacher factories of a configuration's residual base, safety filter and teacher.

    Args:
        cfg: The configuration.
        components: The composition layer's factories (``None``: none available).

    Returns:
        ``(base_factory, filter_factory, teacher_factory)``, each ``None`` when not configured; the teacher is that
        of an imitation learner (``dagger``'s ``teacher`` hyperparameter, :mod:`agents.algos.dagger`): with a
        residual base it labels its correction of the base, without one its whole command.

    Raises:
        ConfigError: A residual base, the filter or a teacher without ``components`` (the message names
            ``uvdms train``), a base or teacher name the components reject, a teacher that commands the other
            action mode, a ``residual_penalty`` without a residual base, or a ``dagger`` configuration with
            ``residual_space: nullspace``, with ``action_scale`` other than 1 (its labels are in the action's own
            units, on the full space) or with the safety filter but no base (the filter would change the
            imitated command).
    """
    composition = cfg.composition
    if cfg.residual_penalty and not composition.is_residual:
        raise ConfigError(
            f"residual_penalty={cfg.residual_penalty} shapes a residual agent's reward, but the configuration has no "
            "residual_base (--residual)"
        )
    imitation = cfg.algo == "dagger"
    if imitation:
        _check_imitation(cfg)
    if composition.is_plain and not imitation:
        return None, None, None
    if components is None:
        parts = []
        if composition.is_residual:
            parts.append(f"a residual on {composition.residual_base!r}")
        if composition.safety_filter:
            parts.append("the safety filter")
        if imitation:
            parts.append(f"the teacher {teacher_name(cfg.hyperparams)!r}")
        raise ConfigError(
            f"this configuration needs {' with '.join(parts)}, whose controllers live in the baselines package, "
            "which agents does not import: train it with `uvdms train` (python -m agents.training.train cannot), or "
            "pass components= to agents.training.train.train"
        )
    base_factory = None
    try:
        if composition.is_residual:
            base_factory = components.base_factory(str(composition.residual_base))
        teacher_factory = _teacher(cfg, components) if imitation else None
    except ValueError as exc:
        raise ConfigError(f"{exc}" if not imitation else f"dagger's teacher or base: {exc}") from None
    return base_factory, components.filter_factory if composition.safety_filter else None, teacher_factory


def _check_imitation(cfg: TrainConfig) -> None:
    """DAgger labels the whole command, or residuals of a base on the full action space, in the action's own units."""
    composition = cfg.composition
    problems = []
    if composition.residual_space != "full":
        problems.append(f"residual_space={composition.residual_space!r} (its labels live on the full space)")
    if cfg.action_scale != 1.0:
        problems.append(f"action_scale={cfg.action_scale} (its labels are in the action's own units: use 1.0)")
    if composition.safety_filter and not composition.is_residual:
        problems.append("the safety filter but no residual base (the filter would change the command it imitates)")
    if problems:
        raise ConfigError(f"dagger imitates a teacher's command, but this configuration has {'; '.join(problems)}")


def _teacher(cfg: TrainConfig, components: ActionComponents) -> ControllerFactory:
    """The factory of an imitation learner's teacher, its thresholds moved out by ``teacher_margin``.

    Raises:
        ValueError: A name or margin the components reject, or a teacher in the other action mode than the
            training environment's.
    """
    name, margin = teacher_name(cfg.hyperparams), teacher_margin(cfg.hyperparams)
    outer = teacher_outer_margin(cfg.hyperparams)
    if components.teacher_factory is None:
        return components.base_factory(name, collision_margin=margin)
    factory = components.teacher_factory(name, collision_margin=margin, **({"outer_margin": outer} if outer else {}))
    teacher_mode = getattr(factory, "action_mode", None)
    env_mode = cfg.env_kwargs.get("action_mode", DEFAULT_ACTION_MODE)
    if cfg.composition.is_residual and teacher_mode not in (None, "velocity"):
        raise ValueError(f"teacher {name!r} commands joint torques, but a residual corrects a velocity command")
    if not cfg.composition.is_residual and teacher_mode not in (None, env_mode):
        raise ValueError(
            f"teacher {name!r} commands action_mode={teacher_mode!r}, but the training env has "
            f"action_mode={env_mode!r}: set --env-kwargs action_mode={teacher_mode} or choose a {env_mode}-mode teacher"
        )
    return factory


def check_vec_env(cfg: TrainConfig, vec_env: str) -> None:
    """``--vec-env rollout`` only for the algorithms that collect parallel rollouts (:mod:`agents.common.rollouts`)."""
    if vec_env == "rollout":
        try:
            check_rollout_vec_env(cfg.algo, bool(cfg.hyperparams.get("use_sde", False)))
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
