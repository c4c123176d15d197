"""What a configuration composes: the residual base, the safety filter and an imitation learner's teacher.

:func:`composition_factories` turns a configuration's ``residual_base``, ``safety_filter`` and ``dagger``'s
``teacher`` into the factories the training envs use (``components`` are injected by the composition layer: this
package never imports ``baselines``); :func:`check_vec_env` refuses ``--vec-env rollout`` for the algorithms that
cannot collect parallel rollouts.
"""

from __future__ import annotations

from agents.algos.dagger import teacher_margin, teacher_name
from agents.common.envs import ActionComponents
from agents.common.rollouts import check_rollout_vec_env
from agents.config import ConfigError, TrainConfig
from uvdms_gym.residual import ControllerFactory, FilterFactory


def composition_factories(
    cfg: TrainConfig, components: ActionComponents | None
) -> tuple[ControllerFactory | None, FilterFactory | None, ControllerFactory | None]:
    """The base, filter and teacher factories of a configuration's residual base, safety filter and teacher.

    Args:
        cfg: The configuration.
        components: The composition layer's factories (``None``: none available).

    Returns:
        ``(base_factory, filter_factory, teacher_factory)``, each ``None`` when not configured; the teacher is that
        of an imitation learner (``dagger``'s ``teacher`` hyperparameter, :mod:`agents.algos.dagger`), built like a
        base.

    Raises:
        ConfigError: A residual base or the filter without ``components`` (the message names ``uvdms train``), a
            base or teacher name the components reject, a ``residual_penalty`` without a residual base, or a
            ``dagger`` configuration without a residual base, with ``residual_space: nullspace`` or with
            ``action_scale`` other than 1 (its labels are residuals in the base's action units, on the full space).
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
    if composition.is_plain:
        return None, None, None
    if components is None:
        parts = []
        if composition.is_residual:
            parts.append(f"a residual on {composition.residual_base!r}")
        if composition.safety_filter:
            parts.append("the safety filter")
        raise ConfigError(
            f"this configuration trains {' with '.join(parts)}, whose controllers live in the baselines package, "
            "which agents does not import: train it with `uvdms train` (python -m agents.train cannot), or pass "
            "components= to agents.train.train"
        )
    base_factory = teacher_factory = None
    if composition.is_residual:
        base_factory, teacher_factory = _base_and_teacher(cfg, components, imitation)
    return base_factory, components.filter_factory if composition.safety_filter else None, teacher_factory


def _check_imitation(cfg: TrainConfig) -> None:
    """DAgger labels residuals of a base on the full action space in the residual's own units."""
    composition = cfg.composition
    problems = []
    if not composition.is_residual:
        problems.append("no residual_base (--residual mpc)")
    if composition.residual_space != "full":
        problems.append(f"residual_space={composition.residual_space!r} (its labels live on the full space)")
    if cfg.action_scale != 1.0:
        problems.append(f"action_scale={cfg.action_scale} (its labels are in the residual's own units: use 1.0)")
    if problems:
        raise ConfigError(
            f"dagger imitates a teacher's correction of a residual base, but this configuration has "
            f"{'; '.join(problems)}"
        )


def _base_and_teacher(
    cfg: TrainConfig, components: ActionComponents, imitation: bool
) -> tuple[ControllerFactory, ControllerFactory | None]:
    """The residual base's factory and, for an imitation learner, its teacher's (a base with a collision margin)."""
    try:
        base_factory = components.base_factory(str(cfg.composition.residual_base))
        teacher_factory = None
        if imitation:
            margin = teacher_margin(cfg.hyperparams)
            teacher_factory = components.base_factory(teacher_name(cfg.hyperparams), collision_margin=margin)
    except ValueError as exc:
        raise ConfigError(f"{exc}" if not imitation else f"dagger's teacher or base: {exc}") from None
    return base_factory, teacher_factory


def check_vec_env(cfg: TrainConfig, vec_env: str) -> None:
    """``--vec-env rollout`` only for the algorithms that collect parallel rollouts (:mod:`agents.common.rollouts`)."""
    if vec_env == "rollout":
        try:
            check_rollout_vec_env(cfg.algo, bool(cfg.hyperparams.get("use_sde", False)))
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
