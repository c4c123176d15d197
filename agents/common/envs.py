"""Environment construction for training: env-id lookup, the picklable env factory, vector envs, env seeds.

Residual agents and the safety filter (:mod:`uvdms_gym.residual`) compose the policy with controllers of
``baselines``, which ``agents`` never imports: the composition layer injects them as :class:`ActionComponents`
(``uvdms train`` passes ``leaderboard.suite.registry.action_components()``), and :class:`EnvFactory` holds the
resulting picklable factories.

Seed scheme (``seed`` = ``--seed``; segment k = 0 for a fresh run, k = 1, 2, ... for each ``--resume``):
training env ``i`` of segment ``k`` is reset with seed ``seed + 1000 * k + i`` (:func:`train_env_seed`); the
evaluation envs with ``seed + 1_000_000 + i`` before every evaluation (:func:`eval_env_seed`). Under the seed
protocol :data:`uvdms_gym.seeds.PROTOCOL` (:mod:`uvdms_gym.seeds`) ``seed`` and every seed derived from it are
``training`` seeds (``[0, 1e9)``), never test seeds: :func:`check_training_seed` refuses, in one line, a seed
whose derived seeds (:func:`largest_derived_seeds`: every training env of every segment up to
:data:`MAX_SEGMENTS`, every evaluation env) would leave that range, e.g. any seed above ``1e9 - 1_000_001``.
``uvdms train`` (fresh runs and resumes), ``uvdms sweep`` (each of ``--seeds``) and ``uvdms tune`` (the trials'
``--seed``) check it before anything runs.
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import torch
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv

from agents.common.history import FrameStack
from agents.common.learning_curve import EpisodeMetrics, has_tracking_metrics
from agents.common.names import DEFAULT_GYM_PACKAGES, VEC_ENV_TYPES
from agents.common.rollouts import RolloutVecEnv
from agents.common.vecenv import HybridVecEnv
from agents.common.wrappers import AliveBonus, ScalarInfo, ScaledAction
from uvdms_gym.residual import (
    ControllerFactory,
    FilteredAction,
    FilterFactory,
    ObstacleFeatureObservation,
    ResidualAction,
    TeacherLabel,
    TrackingFeatureObservation,
)
from uvdms_gym.seeds import check_seeds

SEGMENT_SEED_STRIDE = 1000
"""Seed distance between training segments (so at most 1000 training envs)."""
EVAL_SEED_OFFSET = 1_000_000
"""Seed offset of the evaluation envs (so fewer than 1000 segments)."""
MAX_SEGMENTS = EVAL_SEED_OFFSET // SEGMENT_SEED_STRIDE
"""Segments a run may have (a fresh run and its resumes): more would reset training envs with evaluation seeds."""
TRAINING_SPLIT = "training"
"""The split of :mod:`uvdms_gym.seeds` that training seeds and all their derived seeds belong to."""


class EnvironmentNotFoundError(LookupError):
    """The environment id is not registered (possibly because a gym package failed to import)."""


def import_gym_packages(packages: Sequence[str]) -> dict[str, str]:
    """Import the packages that register Gymnasium environments.

    Args:
        packages: Module names (e.g. ``["uvdms_gym"]``).

    Returns:
        Import errors as ``{package: "ExceptionType: message"}`` (empty if all imported).
    """
    errors = {}
    for name in packages:
        try:
            importlib.import_module(name)
        except Exception as exc:  # any error while importing an env package is reported, not fatal
            errors[name] = f"{type(exc).__name__}: {exc}"
    return errors


def check_env_id(env_id: str, packages: Sequence[str]) -> None:
    """Import ``packages`` and check that ``env_id`` is registered.

    Args:
        env_id: Gymnasium environment id (``module:Id`` ids are left to ``gymnasium.make``).
        packages: Packages to import first.

    Raises:
        EnvironmentNotFoundError: If the id is not registered; the message lists failed imports and
            close matches.
    """
    from uvdms_gym.utils.kwargs import registered_ids

    errors = import_gym_packages(packages)
    if ":" in env_id or env_id in gym.registry:
        return
    msg = f"environment id {env_id!r} is not registered."
    if errors:
        failed = "; ".join(f"{name} -> {err}" for name, err in errors.items())
        msg += f" These gym packages failed to import: {failed}."
    imported = [p for p in packages if p not in errors]
    if imported:
        msg += f" Imported gym packages: {', '.join(imported)}."
    else:
        msg += " No gym package was imported (use --gym-packages to name the package that registers it)."
    close = difflib.get_close_matches(env_id, list(gym.registry), n=3)
    if close:
        msg += f" Close matches: {', '.join(close)}."
    namespace = env_id.split("/")[0] if "/" in env_id else None
    known = registered_ids(namespace) if namespace else []
    if known:
        msg += f" The {namespace} environments are {', '.join(known)}."
    raise EnvironmentNotFoundError(msg)


@dataclasses.dataclass(frozen=True)
class ActionComponents:
    """The controllers training may compose with the policy, injected by the composition layer.

    Both must return picklable module-level objects (they travel to ``SubprocVecEnv`` / hybrid workers inside
    :class:`EnvFactory`).

    Attributes:
        base_factory: ``residual_base`` name -> the factory of that base controller; raises ``ValueError`` for a
            name that cannot be a residual base (unknown, or not a velocity-mode controller). Also builds an
            imitation learner's teacher when ``teacher_factory`` is ``None``, with the keyword ``collision_margin``
            (m added to its collision thresholds).
        filter_factory: Wraps a controller in the safety filter.
        teacher_factory: Teacher name (a controller of either action mode, or a trained agent's folder) and the
            keyword ``collision_margin`` -> the factory of an imitation learner's teacher; the factory's
            ``action_mode`` attribute, if any, names the mode the teacher commands. ``None``: ``base_factory``.
    """

    base_factory: Callable[..., ControllerFactory]
    filter_factory: FilterFactory
    teacher_factory: Callable[..., ControllerFactory] | None = None


@dataclasses.dataclass(frozen=True)
class EnvFactory:
    """Picklable environment constructor (works with ``SubprocVecEnv``).

    Attributes:
        env_id: Gymnasium id.
        env_kwargs: Keyword arguments of ``gymnasium.make``.
        gym_packages: Packages imported first (in the worker process) to register the id.
        monitor_file: ``Monitor`` log file (``None``: no file).
        max_episode_steps: ``gymnasium.make``'s episode length limit (``None``: the registered one).
        alive_bonus: Constant added to every reward inside the ``Monitor`` (0: no wrapper).
        action_scale: The policy's action is multiplied by this before the env sees it (1: no wrapper).
        scalar_info: Drop the array entries of ``info`` (:class:`agents.common.wrappers.ScalarInfo`; training envs).
        base_factory: Base controller of a residual agent (``None``: no residual; :class:`ResidualAction`).
        residual_scale: Bound of the residual (with ``base_factory``).
        residual_penalty: Shaping of the residual's magnitude in the reward (with ``base_factory``; 0: none).
        residual_observation: What the residual policy observes besides the env's observation (with
            ``base_factory``; :data:`uvdms_gym.residual.RESIDUAL_OBSERVATIONS`).
        residual_space: Where the residual acts (with ``base_factory``; :data:`uvdms_gym.residual.RESIDUAL_SPACES`).
        filter_factory: Safety filter of the velocity command, applied after the residual (``None``: none;
            :class:`FilteredAction`).
        episode_metrics: Put each episode's benchmark metrics into its last ``info``
            (:class:`agents.common.learning_curve.EpisodeMetrics`; evaluation envs of a uvdms id, else no effect).
        teacher_factory: A teacher that labels every step, for :mod:`agents.algos.dagger` (``None``: none): with
            ``base_factory`` its correction of the base (:class:`ResidualAction`'s ``teacher_factory``), without
            one its own command (:class:`TeacherLabel`).
        navigation_filter: The state in the observation and ``info`` is the navigation filter's estimate
            (:class:`uvdms_gym.realism.navigation.NavigationFilterWrapper`, innermost: every controller composed with
            the policy sees it too; no effect at ``realism=0``; an error on an env that is not UVDMS's:
            :func:`with_navigation_filter`).
        frame_stack: The policy observes its last ``frame_stack`` observations (:class:`FrameStack`, outermost
            but for the ``Monitor``; 1 and no ``action_history``: no wrapper).
        action_history: ... and its own last ``action_history`` actions (the same wrapper; 0: none).
        obstacle_features: The policy observes its observation followed by the obstacle features
            (:class:`uvdms_gym.residual.ObstacleFeatureObservation`, just inside :class:`FrameStack`).
        tracking_features: ... then its tracking error magnified
            (:class:`uvdms_gym.residual.TrackingFeatureObservation`, outside the obstacle features).
    """

    env_id: str
    env_kwargs: Mapping[str, Any]
    gym_packages: tuple[str, ...] = DEFAULT_GYM_PACKAGES
    monitor_file: str | None = None
    max_episode_steps: int | None = None
    alive_bonus: float = 0.0
    action_scale: float = 1.0
    scalar_info: bool = False
    base_factory: ControllerFactory | None = None
    residual_scale: float | None = None
    residual_penalty: float = 0.0
    residual_observation: str = "base"
    residual_space: str = "full"
    filter_factory: FilterFactory | None = None
    episode_metrics: bool = False
    teacher_factory: ControllerFactory | None = None
    navigation_filter: bool = False
    frame_stack: int = 1
    action_history: int = 0
    obstacle_features: bool = False
    tracking_features: bool = False

    def __call__(self) -> gym.Env:
        """Create the environment wrapped in a ``Monitor`` (filter, residual, action scaling and alive bonus inside).

        From the inside out: ``gymnasium.make``, :class:`agents.common.learning_curve.EpisodeMetrics` (evaluation envs),
        ``NavigationFilterWrapper``, :class:`FilteredAction`, :class:`ResidualAction` or :class:`TeacherLabel` (both
        see the full ``info``), ``ScaledAction``, ``AliveBonus``, ``ScalarInfo``, ``ObstacleFeatureObservation``,
        ``TrackingFeatureObservation``,
        :class:`FrameStack`, ``Monitor``;
        so the policy's ``action_scale * a`` is the residual, and the filter gets the composed command.

        Also sets ``torch.set_num_threads(1)`` in the calling process: in a ``SubprocVecEnv`` worker (which
        imports torch with this module but never uses it) as in the trainer (see :func:`agents.training.train.train`).
        """
        torch.set_num_threads(1)
        check_env_id(self.env_id, self.gym_packages)
        make_kwargs = dict(self.env_kwargs)
        if self.max_episode_steps is not None:
            make_kwargs["max_episode_steps"] = self.max_episode_steps
        env = gym.make(self.env_id, **make_kwargs)
        if self.episode_metrics and has_tracking_metrics(env):
            env = EpisodeMetrics(env)
        if self.navigation_filter:
            env = with_navigation_filter(env)
        env = self._compose(env)
        if self.action_scale != 1.0:
            env = ScaledAction(env, self.action_scale)
        if self.alive_bonus:
            env = AliveBonus(env, self.alive_bonus)
        if self.scalar_info:
            env = ScalarInfo(env)
        if self.obstacle_features:
            env = ObstacleFeatureObservation(env)
        if self.tracking_features:
            env = TrackingFeatureObservation(env)
        if self.frame_stack > 1 or self.action_history:
            env = FrameStack(env, self.frame_stack, self.action_history)
        return Monitor(env, filename=self.monitor_file)

    def _compose(self, env: gym.Env) -> gym.Env:
        """The safety filter, then the residual base or the teacher's label, around ``env``."""
        if self.filter_factory is not None:
            env = FilteredAction(env, self.filter_factory)
        if self.base_factory is not None:
            if self.residual_scale is None:
                raise ValueError("a residual base needs residual_scale")
            return ResidualAction(
                env,
                self.base_factory,
                self.residual_scale,
                self.residual_penalty,
                self.residual_observation,
                self.residual_space,
                self.teacher_factory,
            )
        return env if self.teacher_factory is None else TeacherLabel(env, self.teacher_factory)


def with_navigation_filter(env: gym.Env) -> gym.Env:
    """``env`` in the navigation filter's wrapper at a realism level; unchanged at ``realism=0``.

    Raises:
        ValueError: ``env`` is not a UVDMS environment (it has no ``realism`` attribute).
    """
    if not hasattr(env.unwrapped, "realism"):
        name = env.spec.id if env.spec is not None else type(env.unwrapped).__name__
        raise ValueError(f"navigation_filter needs a UVDMS environment (one with a realism level), not {name}")
    if env.unwrapped.realism is None:
        return env
    from uvdms_gym.realism.navigation import NavigationFilterWrapper

    return NavigationFilterWrapper(env)


def make_vec_env(factories: list[Callable[[], gym.Env]], vec_env: str) -> VecEnv:
    """The vector env ``vec_env`` over ``factories``.

    ``"dummy"``: every env in this process (``DummyVecEnv``); ``"subproc"``: every env in a worker process
    (``SubprocVecEnv``); ``"hybrid"``: env 0 in this process, the others in workers, stepped at the same time
    (:class:`agents.common.vecenv.HybridVecEnv`; with a single factory, ``DummyVecEnv``); ``"rollout"``: as
    ``"hybrid"``, and PPO collects each env's part of a rollout in that env's process
    (:class:`agents.common.rollouts.RolloutVecEnv`; with a single factory, ``DummyVecEnv``).
    """
    if vec_env not in VEC_ENV_TYPES:
        raise ValueError(f"unknown vec_env {vec_env!r}: expected one of {', '.join(VEC_ENV_TYPES)}")
    if vec_env == "subproc":
        return SubprocVecEnv(factories)
    if vec_env == "hybrid" and len(factories) > 1:
        return HybridVecEnv(factories)
    if vec_env == "rollout" and len(factories) > 1:
        return RolloutVecEnv(factories)
    return DummyVecEnv(factories)


def train_env_seed(seed: int, segment: int, rank: int) -> int:
    """Seed of training env ``rank`` in training segment ``segment`` (see the module docstring)."""
    return seed + SEGMENT_SEED_STRIDE * segment + rank


def eval_env_seed(seed: int, rank: int) -> int:
    """Seed of evaluation env ``rank`` (the same for every evaluation and segment)."""
    return seed + EVAL_SEED_OFFSET + rank


def largest_derived_seeds(seed: int, n_envs: int, n_eval_envs: int, segments: int = MAX_SEGMENTS) -> dict[str, int]:
    """The largest seed each derivation of the training seed ``seed`` reaches, by derivation (for messages).

    The training envs of segment ``segments - 1`` (the last one allowed; rank ``n_envs - 1``) and the evaluation
    envs (rank ``n_eval_envs - 1``); every other derived seed lies between ``seed`` and these.
    """
    derived = {
        f"training env {n_envs - 1} of segment {segments - 1}: seed + {SEGMENT_SEED_STRIDE} * segment + rank": (
            train_env_seed(seed, segments - 1, n_envs - 1)
        )
    }
    if n_eval_envs > 0:
        derived[f"evaluation env {n_eval_envs - 1}: seed + {EVAL_SEED_OFFSET} + rank"] = eval_env_seed(
            seed, n_eval_envs - 1
        )
    return derived


def check_training_seed(seed: int, n_envs: int, n_eval_envs: int, what: str = "training seed") -> None:
    """Refuse, in one line, a training seed outside the ``training`` split or whose derived seeds leave it.

    Args:
        seed: The base seed (``--seed``).
        n_envs: Training envs per segment.
        n_eval_envs: Evaluation envs.
        what: What the seed is, for the message (``"--seed"``, ``"--seeds"``).

    Raises:
        uvdms_gym.seeds.SeedProtocolError: The seed, or the largest seed one of its derivations reaches
            (:func:`largest_derived_seeds`), is not a training seed; the message names the seed and the derivation.
    """
    check_seeds([seed], TRAINING_SPLIT, f"{what} {seed}")
    derivations = largest_derived_seeds(seed, n_envs, n_eval_envs).items()
    for derivation, derived in sorted(derivations, key=lambda item: -item[1]):  # the farthest one is named
        check_seeds([derived], TRAINING_SPLIT, f"{what} {seed} (its {derivation})")
