"""Training configurations: RL-Zoo hyperparameter files validated into typed :class:`TrainConfig` dataclasses.

A file ``train_configs/<algo>.yml`` is an RL Baselines3 Zoo hyperparameter file: a mapping from Gymnasium
environment ids to *entries*, plus an optional ``default`` entry and an optional ``train_options`` mapping
(:mod:`agents.config.zoo`). The entry used for an environment is the ``default`` entry shallow-merged with the
environment's own entry (the environment's keys win; ``policy_kwargs`` etc. are replaced, not merged). RL Zoo
itself only reads the env's entry, so the shipped files write each env entry as ``<<: *default`` (a YAML merge
key: the same shallow merge) and both trainers see the same keys. Example::

    default: &default
      n_timesteps: 1000000
      n_envs: 2
      normalize: {norm_obs: true, norm_reward: false}
      learning_rate: 3.0e-4           # algorithm hyperparameters sit beside the fields below
      policy_kwargs: {net_arch: [256, 256]}
    uvdms/CircleTrack-v0:
      <<: *default
      n_timesteps: 2000000
      env_wrapper: [{agents.common.wrappers.AliveBonus: {bonus: 2.0}}]
    train_options:                    # what RL Zoo takes from its command line (--eval-freq, --env-kwargs ...)
      uvdms/CircleTrack-v0: {eval_freq: 20000, env_kwargs: {case: random}}

Keys of an entry are the fields of :class:`TrainConfig` (except ``algo`` and ``hyperparams``), RL Zoo's
``env_wrapper``/``callback`` lists naming the project's wrappers and callbacks (:mod:`agents.config.zoo` turns them
into ``action_scale``, ``alive_bonus``, ``action_init_scale``), or keyword arguments of the algorithm class
(``SAC.__init__`` etc.), which are collected into ``TrainConfig.hyperparams``. Every value is type-checked
against the dataclass field or the SB3 annotation (:mod:`agents.config.typecheck`); unknown keys and wrong types raise
:class:`ConfigError` naming the key and the file. Classes are written as whitelisted names
(``activation_fn: tanh``), schedules as ``lin_<initial value>`` (RL-Zoo convention: linear decay to zero),
action noise as ``noise_type``/``noise_std`` (RL Zoo's keys). Nothing is ever evaluated or imported. YAML 1.1
reads ``3e-4`` (no dot) as a string; numeric strings are accepted for numeric keys.
"""

from __future__ import annotations

import dataclasses
import inspect
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.noise import ActionNoise, NormalActionNoise, OrnsteinUhlenbeckActionNoise

from agents.algos import ALGOS

# ACTIVATIONS, CLASS_KEYS, FEATURES_EXTRACTORS, OPTIMIZERS and plain_policy_kwargs are re-exported for old imports
from agents.config.policy_kwargs import (  # noqa: F401
    ACTIVATIONS,
    CLASS_KEYS,
    CLASS_WHITELISTS,
    FEATURES_EXTRACTORS,
    OPTIMIZERS,
    plain_policy_kwargs,
    resolve_policy_kwargs,
)
from agents.config.typecheck import (
    ConfigError,
    TypeChecker,
    accepts_tuple,
    copy_plain,
)
from uvdms_gym.residual import ActionComposition

DEFAULT_ENTRY = "default"

NOISE_TYPES = ("normal", "ornstein-uhlenbeck")
"""Values of ``noise_type`` (Gaussian or OU exploration noise for off-policy algorithms)."""

# Algorithm keyword arguments that the training script sets itself (or that have their own field).
_SCHEDULE_RE = re.compile(r"^lin_(.+)$")
_CHECKER = TypeChecker(CLASS_WHITELISTS, _SCHEDULE_RE, "a schedule string 'lin_<initial value>'")


@dataclass(frozen=True)
class LinearSchedule:
    """Linear schedule from ``initial`` (start of training) to 0 (end), as RL Zoo's ``lin_<x>``.

    Attributes:
        initial: Value at the start of training.
    """

    initial: float

    def __call__(self, progress_remaining: float) -> float:
        """Value at ``progress_remaining`` (1 at the start of training, 0 at the end)."""
        return progress_remaining * self.initial


@dataclass(frozen=True)
class TrainConfig:
    """One validated training configuration (an entry of ``train_configs/<algo>.yml``).

    Frequencies are in environment steps summed over all training environments. In ``train_configs/`` the
    fields RL Zoo has no entry key for are written its way (:mod:`agents.config.zoo`): ``alive_bonus`` and
    ``action_scale`` as ``env_wrapper`` entries, ``action_init_scale`` as a ``callback`` entry, the evaluation,
    checkpoint and replay-buffer options under ``train_options``; a run's ``config.yml`` holds the flat fields.

    Attributes:
        algo: Algorithm name (key of :data:`agents.algos.ALGOS`); not a YAML key (comes from the file).
        n_timesteps: Total environment steps of a fresh training run.
        policy: Policy alias of the algorithm (``MlpPolicy``, ``MultiInputPolicy``, ...).
        n_envs: Number of parallel training environments.
        normalize: ``VecNormalize`` on the training env: ``false``, ``true`` or a mapping of its keyword
            arguments (``norm_obs``, ``norm_reward``, ``clip_obs``, ``clip_reward``, ``gamma``, ``epsilon``).
        policy_kwargs: Policy keyword arguments as plain data (class names are whitelisted strings).
        hyperparams: Algorithm keyword arguments as plain data (schedules as ``lin_<x>`` strings).
        eval_freq: Evaluate every this many steps (0 disables evaluation and ``best_model.zip``).
        n_eval_episodes: Episodes per evaluation.
        n_eval_envs: Number of evaluation environments.
        checkpoint_freq: Save a checkpoint every this many steps (0 disables checkpoints).
        env_kwargs: Keyword arguments of ``gymnasium.make`` for training and evaluation environments.
        eval_env_kwargs: Keyword arguments for the evaluation environments only (override ``env_kwargs``).
        noise_type: Exploration noise of off-policy algorithms: ``None``, ``normal``, ``ornstein-uhlenbeck``.
        noise_std: Standard deviation of the exploration noise (in normalised action units).
        save_replay_buffer: Save the replay buffer with the final model and the latest checkpoint, so that
            ``--resume`` continues with a filled buffer. The file holds the whole allocated buffer, so the
            training script caps ``buffer_size`` at the transitions the run can store (and grows it on resume;
            :func:`agents.training.models.replay_buffer_size`): about 0.7 kB per step for the uvdms envs.
        max_episode_steps: Episode length limit passed to ``gymnasium.make`` for training and evaluation
            environments (``None``: the registered limit). Useful for short test runs.
        alive_bonus: Constant added to every training/evaluation-callback reward (a training-side shaping
            wrapper; the environment itself is unchanged). The uvdms rewards are negative on every step
            (-tracking error, ...) while a contact costs only -10 and ends the episode, so without a bonus
            ending the episode early is the return-maximising behaviour. Monitor logs record the shaped
            return; the environment's return is ``r - alive_bonus * l``.
        action_init_scale: Multiply the freshly initialised last action layer by this (``None``: no change),
            so that the untrained policy starts near the zero command.
        actor_warmup_steps: Off-policy actor-critic algorithms only: the actor is not updated before this many
            environment steps, while the critic learns from ``learning_starts`` (a critic burn-in,
            :class:`agents.training.callbacks.DelayActorUpdates`; 0: none). With ``action_init_scale`` the behaviour
            until
            then is the near-zero initial action plus the exploration noise.
        action_scale: Part of the policy, not of the environment: the network's output ``a`` in [-1, 1] is
            sent to the environment as ``action_scale * a`` (a wrapper in training, applied again by
            :class:`agents.export.AgentController` at evaluation and recorded in exports). The tasks need
            commands of a few percent of ``zeta_max``; a squashed-Gaussian (SAC) policy over the full range
            explores with motions large enough to hit the frame within seconds. 1.0: no scaling.
        residual_base: Train a residual agent on this base controller (a velocity-mode baseline name, ``mpc`` or
            ``campc``; ``None``: a plain agent): the environment receives
            ``clip(a_base + residual_scale * a, -1, 1)`` and the policy observes ``[obs; a_base]``
            (:mod:`uvdms_gym.residual`). Only ``uvdms train`` can build the base (``python -m agents.training.train``
            refuses); which names are valid is checked there.
        residual_scale: Bound of the residual, in (0, 1]; required with ``residual_base``, not allowed without.
        residual_penalty: Training-side shaping of a residual agent (only with ``residual_base``; 0: none): the
            reward gains ``-residual_penalty * |a|^2 / 18`` (``a``: the policy's output), so that the residual
            stays at zero where the base needs no correction (:class:`uvdms_gym.residual.ResidualAction`).
            Evaluation and the exported agent are unaffected.
        safety_filter: The training envs' velocity command (after the residual, if any) goes through the safety
            filter (``baselines.safety.filter.SafetyFilter``, injected by ``uvdms train``); evaluation composes the
            same.
        residual_observation: What a residual policy observes besides the environment's observation (only with
            ``residual_base``): ``"base"`` (default), the base's action; ``"clearance"``, the base's action and
            36 clearance features (the direction that opens the clearances below ``d2`` and the clearance rates
            under the base's command, :class:`uvdms_gym.residual.ClearanceFeatures`). Recorded in the export, so
            evaluation computes the same observation.
        residual_space: Where a residual acts (only with ``residual_base``): ``"full"`` (default), the whole
            command; ``"nullspace"``, the policy's output projected onto the null space of the two end-effector
            positions first (:class:`uvdms_gym.residual.NullspaceProjection`). Recorded in the export.
        navigation_filter: The policy observes the navigation filter's estimate where the measured state was
            (``realism > 0``; :class:`uvdms_gym.realism.navigation.NavigationFilterWrapper` in training,
            ``FilteredController`` at evaluation). Recorded in the export.
        frame_stack: The policy observes its last ``frame_stack`` observations, oldest first, concatenated: a
            policy with memory (:class:`agents.common.history.FrameStack`; 1: none). Recorded in the export,
            whose controller keeps the history and clears it in ``reset(seed)``.
        action_history: The policy also observes its own last ``action_history`` actions (0: none; the same
            wrapper and record): under an action delay, the commands still on their way.
        obstacle_features: The policy also observes the obstacle features computed from its observation (each
            observed obstacle's nearest robot part: the gap, its rates and the action direction that opens it;
            :class:`uvdms_gym.residual.ObstacleFeatures`): environments with obstacle slots, no residual base.
            Recorded in the export, whose evaluation computes the same features.
        tracking_features: The policy also observes its current tracking error magnified to the scale of success
            (:class:`uvdms_gym.residual.TrackingFeatures`: ``tanh`` of the error over 2 cm and 2 degrees), after the
            obstacle features: UVDMS circle and transport environments, no residual base. Recorded in the export.
        env_variants: Keyword overrides of ``env_kwargs`` cycled over the training envs: training env ``i`` is
            made with ``{**env_kwargs, **env_variants[i % len(env_variants)]}`` and the evaluation envs with the
            first variant (empty: every env alike). Domain randomisation over settings that are fixed for an
            environment's lifetime, e.g. ``[{realism: 2}, {realism: 3}]`` trains one policy on two realism levels.
    """

    algo: str
    n_timesteps: int
    policy: str = "MlpPolicy"
    n_envs: int = 2
    normalize: bool | dict[str, Any] = False
    policy_kwargs: dict[str, Any] = field(default_factory=dict)
    hyperparams: dict[str, Any] = field(default_factory=dict)
    eval_freq: int = 10_000
    n_eval_episodes: int = 5
    n_eval_envs: int = 1
    checkpoint_freq: int = 50_000
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    eval_env_kwargs: dict[str, Any] = field(default_factory=dict)
    noise_type: str | None = None
    noise_std: float = 0.1
    save_replay_buffer: bool = False
    max_episode_steps: int | None = None
    alive_bonus: float = 0.0
    action_init_scale: float | None = None
    actor_warmup_steps: int = 0
    action_scale: float = 1.0
    residual_base: str | None = None
    residual_scale: float | None = None
    residual_penalty: float = 0.0
    safety_filter: bool = False
    residual_observation: str = "base"
    residual_space: str = "full"
    navigation_filter: bool = False
    frame_stack: int = 1
    action_history: int = 0
    obstacle_features: bool = False
    tracking_features: bool = False
    env_variants: list[dict[str, Any]] = field(default_factory=list)

    # ----------------------------------------------------------------------------------------------
    def to_entry(self) -> dict[str, Any]:
        """Plain flat mapping (YAML entry) that :func:`parse_entry` turns back into this config."""
        entry: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            if f.name in ("algo", "hyperparams"):
                continue
            entry[f.name] = copy_plain(getattr(self, f.name))
        entry.update(copy_plain(self.hyperparams))
        return entry

    @property
    def composition(self) -> ActionComposition:
        """The residual base and safety filter of the run (:class:`uvdms_gym.residual.ActionComposition`)."""
        return ActionComposition(
            self.residual_base,
            self.residual_scale,
            self.safety_filter,
            residual_observation=self.residual_observation,
            residual_space=self.residual_space,
            navigation_filter=self.navigation_filter,
            frame_stack=self.frame_stack,
            action_history=self.action_history,
            obstacle_features=self.obstacle_features,
            tracking_features=self.tracking_features,
        )

    def variant_kwargs(self, rank: int) -> dict[str, Any]:
        """``env_kwargs`` with the :attr:`env_variants` override of env ``rank`` (``env_kwargs`` without variants)."""
        if not self.env_variants:
            return dict(self.env_kwargs)
        return {**self.env_kwargs, **self.env_variants[rank % len(self.env_variants)]}

    def normalize_kwargs(self) -> dict[str, Any] | None:
        """Keyword arguments for ``VecNormalize`` or ``None`` when normalisation is off.

        ``gamma`` defaults to the algorithm's discount factor.
        """
        if self.normalize is False:
            return None
        kwargs = {} if self.normalize is True else dict(self.normalize)
        kwargs.setdefault("gamma", self.gamma)
        return kwargs

    @property
    def gamma(self) -> float:
        """Discount factor (hyperparameter or the algorithm's default)."""
        if "gamma" in self.hyperparams:
            return float(self.hyperparams["gamma"])
        return float(inspect.signature(ALGOS[self.algo].__init__).parameters["gamma"].default)

    def sb3_policy_kwargs(self) -> dict[str, Any]:
        """Policy keyword arguments with class names resolved through the whitelists."""
        return resolve_policy_kwargs(self.policy_kwargs)

    def sb3_hyperparams(self) -> dict[str, Any]:
        """Algorithm keyword arguments with schedules and ``train_freq`` converted for SB3."""
        params = inspect.signature(ALGOS[self.algo].__init__).parameters
        out: dict[str, Any] = {}
        for key, value in self.hyperparams.items():
            if isinstance(value, str) and _CHECKER.accepts_callable(params[key].annotation):
                match = _SCHEDULE_RE.match(value)
                if match:
                    value = LinearSchedule(float(match.group(1)))
            if isinstance(value, list) and accepts_tuple(params[key].annotation):
                value = tuple(value)
            out[key] = value
        return out

    def action_noise(self, action_space: spaces.Space) -> ActionNoise | None:
        """Exploration noise object for off-policy algorithms (``None`` when ``noise_type`` is unset)."""
        if self.noise_type is None:
            return None
        if not isinstance(action_space, spaces.Box):
            raise ConfigError(f"noise_type {self.noise_type!r} needs a Box action space")
        n = int(np.prod(action_space.shape))
        mean, sigma = np.zeros(n), self.noise_std * np.ones(n)
        if self.noise_type == "normal":
            return NormalActionNoise(mean=mean, sigma=sigma)
        return OrnsteinUhlenbeckActionNoise(mean=mean, sigma=sigma)


# ------------------------------------------------------------------------------------------------------
# Public loading functions
# ------------------------------------------------------------------------------------------------------
