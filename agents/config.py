"""Training configurations: RL-Zoo hyperparameter files validated into typed :class:`TrainConfig` dataclasses.

A file ``train_configs/<algo>.yml`` is an RL Baselines3 Zoo hyperparameter file: a mapping from Gymnasium
environment ids to *entries*, plus an optional ``default`` entry and an optional ``train_options`` mapping
(:mod:`agents.zoo`). The entry used for an environment is the ``default`` entry shallow-merged with the
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
      env_wrapper: [{agents.wrappers.AliveBonus: {bonus: 2.0}}]
    train_options:                    # what RL Zoo takes from its command line (--eval-freq, --env-kwargs ...)
      uvdms/CircleTrack-v0: {eval_freq: 20000, env_kwargs: {case: random}}

Keys of an entry are the fields of :class:`TrainConfig` (except ``algo`` and ``hyperparams``), RL Zoo's
``env_wrapper``/``callback`` lists naming the project's wrappers and callbacks (:mod:`agents.zoo` turns them
into ``action_scale``, ``alive_bonus``, ``action_init_scale``), or keyword arguments of the algorithm class
(``SAC.__init__`` etc.), which are collected into ``TrainConfig.hyperparams``. Every value is type-checked
against the dataclass field or the SB3 annotation (:mod:`agents.typecheck`); unknown keys and wrong types raise
:class:`ConfigError` naming the key and the file. Classes are written as whitelisted names
(``activation_fn: tanh``), schedules as ``lin_<initial value>`` (RL-Zoo convention: linear decay to zero),
action noise as ``noise_type``/``noise_std`` (RL Zoo's keys). Nothing is ever evaluated or imported. YAML 1.1
reads ``3e-4`` (no dot) as a string; numeric strings are accepted for numeric keys.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import re
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from gymnasium import spaces
from stable_baselines3.common.noise import ActionNoise, NormalActionNoise, OrnsteinUhlenbeckActionNoise
from stable_baselines3.common.vec_env import VecNormalize

from agents.algos import ALGOS, is_off_policy
from agents.paths import train_configs_dir

# ACTIVATIONS, CLASS_KEYS, FEATURES_EXTRACTORS, OPTIMIZERS and plain_policy_kwargs are re-exported for old imports
from agents.policy_kwargs import (  # noqa: F401
    ACTIVATIONS,
    CLASS_KEYS,
    CLASS_WHITELISTS,
    FEATURES_EXTRACTORS,
    OPTIMIZERS,
    plain_policy_kwargs,
    resolve_policy_kwargs,
)
from agents.typecheck import (
    ConfigError,
    TypeChecker,
    accepts_tuple,
    close_matches,
    copy_plain,
    tname,
)
from agents.wrappers import is_unit_scale
from agents.zoo import TRAIN_OPTIONS, flatten_entry, train_options
from uvdms_gym.residual import ActionComposition, is_residual_penalty

DEFAULT_ENTRY = "default"

NOISE_TYPES = ("normal", "ornstein-uhlenbeck")
"""Values of ``noise_type`` (Gaussian or OU exploration noise for off-policy algorithms)."""

# Algorithm keyword arguments that the training script sets itself (or that have their own field).
_MANAGED_HYPERPARAMS = {
    "policy": "use the 'policy' field",
    "policy_kwargs": "use the 'policy_kwargs' field",
    "env": "the environment comes from the command line",
    "seed": "the seed comes from the command line (--seed)",
    "tensorboard_log": "the run directory is chosen by the training script",
    "verbose": "verbosity is a command-line option",
    "_init_setup_model": "internal SB3 argument",
    "action_noise": "use 'noise_type' and 'noise_std'",
}
# Policy keyword arguments that are set by the algorithm or the environment.
_MANAGED_POLICY_KWARGS = {
    "observation_space": "taken from the environment",
    "action_space": "taken from the environment",
    "lr_schedule": "set by the algorithm from 'learning_rate'",
    "use_sde": "set 'use_sde' as an algorithm hyperparameter",
}
_VECNORMALIZE_MANAGED = {"venv", "training"}

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
    fields RL Zoo has no entry key for are written its way (:mod:`agents.zoo`): ``alive_bonus`` and
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
            :func:`agents.models.replay_buffer_size`): about 0.7 kB per step for the uvdms envs.
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
            :class:`agents.callbacks.DelayActorUpdates`; 0: none). With ``action_init_scale`` the behaviour until
            then is the near-zero initial action plus the exploration noise.
        action_scale: Part of the policy, not of the environment: the network's output ``a`` in [-1, 1] is
            sent to the environment as ``action_scale * a`` (a wrapper in training, applied again by
            :class:`agents.policy.AgentController` at evaluation and recorded in exports). The tasks need
            commands of a few percent of ``zeta_max``; a squashed-Gaussian (SAC) policy over the full range
            explores with motions large enough to hit the frame within seconds. 1.0: no scaling.
        residual_base: Train a residual agent on this base controller (a velocity-mode baseline name, ``mpc`` or
            ``campc``; ``None``: a plain agent): the environment receives
            ``clip(a_base + residual_scale * a, -1, 1)`` and the policy observes ``[obs; a_base]``
            (:mod:`uvdms_gym.residual`). Only ``uvdms train`` can build the base (``python -m agents.train``
            refuses); which names are valid is checked there.
        residual_scale: Bound of the residual, in (0, 1]; required with ``residual_base``, not allowed without.
        residual_penalty: Training-side shaping of a residual agent (only with ``residual_base``; 0: none): the
            reward gains ``-residual_penalty * |a|^2 / 18`` (``a``: the policy's output), so that the residual
            stays at zero where the base needs no correction (:class:`uvdms_gym.residual.ResidualAction`).
            Evaluation and the exported agent are unaffected.
        safety_filter: The training envs' velocity command (after the residual, if any) goes through the safety
            filter (``baselines.safety.SafetyFilter``, injected by ``uvdms train``); evaluation composes the same.
        residual_observation: What a residual policy observes besides the environment's observation (only with
            ``residual_base``): ``"base"`` (default), the base's action; ``"clearance"``, the base's action and
            36 clearance features (the direction that opens the clearances below ``d2`` and the clearance rates
            under the base's command, :class:`uvdms_gym.residual.ClearanceFeatures`). Recorded in the export, so
            evaluation computes the same observation.
        residual_space: Where a residual acts (only with ``residual_base``): ``"full"`` (default), the whole
            command; ``"nullspace"``, the policy's output projected onto the null space of the two end-effector
            positions first (:class:`uvdms_gym.residual.NullspaceProjection`). Recorded in the export.
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
        )

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
def default_config_path(algo: str) -> Path:
    """``train_configs/<algo>.yml``: the installed package data or the checkout's file (:mod:`agents.paths`)."""
    return train_configs_dir() / f"{algo}.yml"


def read_config_file(path: str | Path) -> dict[str, dict[str, Any]]:
    """Read a config file with ``yaml.safe_load`` and check its shape (env id -> mapping).

    Args:
        path: The YAML file.

    Returns:
        The raw entries, keyed by environment id (and ``default``).

    Raises:
        ConfigError: If the file is missing, not valid YAML, or not a mapping of mappings.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read config file ({exc})") from exc
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: invalid YAML: {exc}") from exc
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: top level must be a mapping of env id -> entry, got {tname(data)}")
    for key, entry in data.items():
        if not isinstance(key, str):
            raise ConfigError(f"{path}: top-level key {key!r} must be an env id string")
        if entry is None:
            data[key] = {}
        elif not isinstance(entry, dict):
            raise ConfigError(f"{path}: entry {key!r} must be a mapping, got {tname(entry)}")
    return data


def load_config(
    path: str | Path,
    algo: str,
    env_id: str,
    overrides: Mapping[str, Any] | None = None,
) -> TrainConfig:
    """Load the configuration of ``env_id`` from ``path`` (``default`` merged with the env entry).

    Every entry of the file is validated, so a typo anywhere in the file is reported.

    Args:
        path: ``train_configs/<algo>.yml``-style file.
        algo: Algorithm name; hyperparameters are validated against this algorithm.
        env_id: Environment id to look up.
        overrides: Extra keys applied on top of the merged entry (validated the same way).

    Returns:
        The validated configuration.

    Raises:
        ConfigError: Unknown key, wrong type, or no entry for ``env_id`` and no ``default``.
    """
    _check_algo(algo, str(path))
    entries = read_config_file(path)
    for name in _entry_names(entries):
        parse_entry(_merged(entries, name, str(path)), algo, source=str(path), entry_name=name)
    if env_id not in entries and DEFAULT_ENTRY not in entries:
        raise ConfigError(f"{path}: no entry for env {env_id!r} and no {DEFAULT_ENTRY!r} entry")
    entry = _merged(entries, env_id, str(path))
    name = env_id if env_id in entries else DEFAULT_ENTRY
    if overrides:
        entry.update(flatten_entry(overrides, f"{path}: overrides"))
        name = f"{name} + overrides"
    return parse_entry(entry, algo, source=str(path), entry_name=name)


def validate_config_file(path: str | Path, algo: str | None = None) -> dict[str, TrainConfig]:
    """Validate every entry of a config file.

    Args:
        path: The YAML file.
        algo: Algorithm name; defaults to the file stem (``sac.yml`` -> ``sac``).

    Returns:
        The validated configurations keyed by entry name (``default`` merged into each).
    """
    algo = algo if algo is not None else Path(path).stem
    _check_algo(algo, str(path))
    entries = read_config_file(path)
    return {
        name: parse_entry(_merged(entries, name, str(path)), algo, source=str(path), entry_name=name)
        for name in _entry_names(entries)
    }


def parse_entry(
    entry: Mapping[str, Any],
    algo: str,
    source: str = "<mapping>",
    entry_name: str = "<entry>",
) -> TrainConfig:
    """Validate one flat entry into a :class:`TrainConfig`.

    Args:
        entry: Mapping of field names and algorithm hyperparameters.
        algo: Algorithm name.
        source: File name used in error messages.
        entry_name: Entry name used in error messages.

    Returns:
        The validated configuration.

    Raises:
        ConfigError: Unknown key, wrong type or out-of-range value (the message names key and file).
    """
    where = f"{source}: entry {entry_name!r}"
    _check_algo(algo, source)
    entry = flatten_entry(entry, where)
    algo_cls = ALGOS[algo]
    hints = typing.get_type_hints(TrainConfig)
    yaml_fields = [f.name for f in dataclasses.fields(TrainConfig) if f.name not in ("algo", "hyperparams")]
    algo_params = inspect.signature(algo_cls.__init__).parameters

    values: dict[str, Any] = {}
    hyperparams: dict[str, Any] = {}
    for key, value in entry.items():
        if not isinstance(key, str):
            raise ConfigError(f"{where}: key {key!r} must be a string")
        if key in yaml_fields:
            values[key] = _CHECKER.validate(value, hints[key], where, key)
        elif key in _MANAGED_HYPERPARAMS:
            raise ConfigError(f"{where}: key {key!r} cannot be set here ({_MANAGED_HYPERPARAMS[key]})")
        elif key in algo_params and key != "self":
            hyperparams[key] = _CHECKER.validate(value, algo_params[key].annotation, where, key)
        else:
            close = close_matches(key, [*yaml_fields, *algo_params])
            raise ConfigError(
                f"{where}: unknown key {key!r} (neither a TrainConfig field nor a {algo_cls.__name__} argument){close}"
            )
    if "n_timesteps" not in values:
        raise ConfigError(f"{where}: missing required key 'n_timesteps'")

    policy = values.get("policy", "MlpPolicy")
    if policy not in algo_cls.policy_aliases:
        raise ConfigError(
            f"{where}: key 'policy': unknown policy {policy!r} for {algo_cls.__name__}; "
            f"choose one of {sorted(algo_cls.policy_aliases)}"
        )
    if "policy_kwargs" in values:
        values["policy_kwargs"] = _validate_policy_kwargs(values["policy_kwargs"], algo, policy, where)
    if isinstance(values.get("normalize"), dict):
        values["normalize"] = _validate_normalize(values["normalize"], where)
    _check_ranges(values, algo, where)
    _check_hyperparam_ranges(algo_cls, hyperparams, where)
    return TrainConfig(algo=algo, hyperparams=hyperparams, **values)


def _validate_policy_kwargs(kwargs: dict[str, Any], algo: str, policy: str, where: str) -> dict[str, Any]:
    policy_cls = ALGOS[algo].policy_aliases[policy]
    params = inspect.signature(policy_cls.__init__).parameters
    out = {}
    for key, value in kwargs.items():
        full_key = f"policy_kwargs.{key}"
        if key in _MANAGED_POLICY_KWARGS:
            raise ConfigError(f"{where}: key {full_key!r} cannot be set here ({_MANAGED_POLICY_KWARGS[key]})")
        if key not in params or key == "self":
            close = close_matches(key, [p for p in params if p != "self"])
            raise ConfigError(f"{where}: unknown key {full_key!r} for {policy_cls.__name__}{close}")
        out[key] = _CHECKER.validate(value, params[key].annotation, where, full_key)
    net_arch = out.get("net_arch")
    if isinstance(net_arch, dict):
        allowed = {"pi", "qf"} if is_off_policy(algo) else {"pi", "vf"}
        extra = set(net_arch) - allowed
        if extra:
            raise ConfigError(
                f"{where}: key 'policy_kwargs.net_arch': unknown sub-keys {sorted(extra)}; use {sorted(allowed)}"
            )
    return out


def _validate_normalize(kwargs: dict[str, Any], where: str) -> dict[str, Any]:
    params = inspect.signature(VecNormalize.__init__).parameters
    allowed = [p for p in params if p not in _VECNORMALIZE_MANAGED and p != "self"]
    out = {}
    for key, value in kwargs.items():
        if key not in allowed:
            raise ConfigError(f"{where}: unknown key 'normalize.{key}' (VecNormalize arguments: {', '.join(allowed)})")
        out[key] = _CHECKER.validate(value, params[key].annotation, where, f"normalize.{key}")
    return out


def _check_ranges(values: dict[str, Any], algo: str, where: str) -> None:
    minimum = {
        "n_timesteps": 1,
        "n_envs": 1,
        "n_eval_episodes": 1,
        "n_eval_envs": 1,
        "eval_freq": 0,
        "checkpoint_freq": 0,
    }
    for key, low in minimum.items():
        if key in values and values[key] < low:
            raise ConfigError(f"{where}: key {key!r} must be >= {low}, got {values[key]}")
    if values.get("max_episode_steps") is not None and values["max_episode_steps"] < 1:
        raise ConfigError(f"{where}: key 'max_episode_steps' must be >= 1 or null, got {values['max_episode_steps']}")
    scale = values.get("action_init_scale")
    if scale is not None and not is_unit_scale(scale):
        raise ConfigError(f"{where}: key 'action_init_scale' must be in (0, 1] or null, got {scale}")
    if not is_unit_scale(values.get("action_scale", 1.0)):
        raise ConfigError(f"{where}: key 'action_scale' must be in (0, 1], got {values['action_scale']}")
    warmup = values.get("actor_warmup_steps", 0)
    if warmup < 0:
        raise ConfigError(f"{where}: key 'actor_warmup_steps' must be >= 0, got {warmup}")
    if warmup and not is_off_policy(algo):
        raise ConfigError(f"{where}: key 'actor_warmup_steps' is only for off-policy algorithms, not {algo}")
    penalty = values.get("residual_penalty", 0.0)
    if not is_residual_penalty(penalty):
        raise ConfigError(f"{where}: key 'residual_penalty' must be a finite number >= 0, got {penalty}")
    if not math.isfinite(values.get("alive_bonus", 0.0)):
        raise ConfigError(f"{where}: key 'alive_bonus' must be a finite number")
    if values.get("n_envs", 1) > 1000:
        raise ConfigError(f"{where}: key 'n_envs' must be <= 1000 (seed scheme), got {values['n_envs']}")
    if values.get("noise_std", 0.0) < 0:
        raise ConfigError(f"{where}: key 'noise_std' must be >= 0")
    noise_type = values.get("noise_type")
    if noise_type is not None:
        if noise_type not in NOISE_TYPES:
            raise ConfigError(f"{where}: key 'noise_type' must be one of {NOISE_TYPES} or null")
        if not is_off_policy(algo):
            raise ConfigError(f"{where}: key 'noise_type' is only for off-policy algorithms, not {algo}")
    if values.get("save_replay_buffer") and not is_off_policy(algo):
        raise ConfigError(f"{where}: key 'save_replay_buffer' is only for off-policy algorithms")
    _check_composition(values, where)


def _check_composition(values: dict[str, Any], where: str) -> None:
    """``residual_base`` / ``residual_scale`` / ``safety_filter``: consistent, and only on a velocity-mode env."""
    try:
        composition = ActionComposition.from_record(values)
    except ValueError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    if composition.is_plain:
        return
    mode = values.get("env_kwargs", {}).get("action_mode", "velocity")
    if mode != "velocity":
        what = "residual_base" if composition.is_residual else "safety_filter"
        raise ConfigError(f"{where}: key {what!r} composes velocity commands, but env_kwargs has action_mode={mode!r}")


def _check_hyperparam_ranges(algo_cls: type, hyperparams: Mapping[str, Any], where: str) -> None:
    """The algorithm's own range checks of its keyword arguments (``check_hyperparams``, if it has one)."""
    check = getattr(algo_cls, "check_hyperparams", None)
    if check is None:
        return
    try:
        check(hyperparams)
    except ValueError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def _check_algo(algo: str, source: str) -> None:
    if algo not in ALGOS:
        raise ConfigError(f"{source}: unknown algorithm {algo!r}; choose one of {sorted(ALGOS)}")


def _entry_names(data: Mapping[str, Any]) -> list[str]:
    """The entries of a file: every top-level key except ``train_options``."""
    return [name for name in data if name != TRAIN_OPTIONS]


def _merged(entries: dict[str, dict[str, Any]], name: str, source: str) -> dict[str, Any]:
    """Flat entry ``name``: ``default`` merged with its entry, RL Zoo keys translated, train options added."""
    merged = dict(entries.get(DEFAULT_ENTRY, {}))
    if name != DEFAULT_ENTRY:
        merged.update(entries.get(name, {}))
    where = f"{source}: entry {name!r}"
    flat = flatten_entry(merged, where)
    for key, value in train_options(entries, name, DEFAULT_ENTRY, source).items():
        if key in flat:
            raise ConfigError(f"{where}: key {key!r} is given both in the entry and in {TRAIN_OPTIONS!r}")
        flat[key] = value
    return flat
