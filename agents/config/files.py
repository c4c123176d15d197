"""Reading ``train_configs/<algo>.yml`` files and checking one entry into a :class:`~agents.config.schema.TrainConfig`.

The file format and the rules are described in :mod:`agents.config.schema`.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from stable_baselines3.common.vec_env import VecNormalize

from agents.algos import ALGOS, is_off_policy
from agents.common.paths import train_configs_dir
from agents.common.wrappers import is_unit_scale
from agents.config.schema import _CHECKER, DEFAULT_ENTRY, NOISE_TYPES, TrainConfig
from agents.config.typecheck import (
    ConfigError,
    close_matches,
    tname,
)
from agents.config.zoo import TRAIN_OPTIONS, flatten_entry, train_options
from uvdms_gym.residual import ActionComposition, is_residual_penalty

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


def default_config_path(algo: str) -> Path:
    """``train_configs/<algo>.yml``: the installed package data or the checkout's file (:mod:`agents.common.paths`)."""
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
                f"{where}: unknown key {key!r} (neither a TrainConfig field nor a {algo_display_name(algo_cls)} "
                f"argument){close}"
            )
    if "n_timesteps" not in values:
        raise ConfigError(f"{where}: missing required key 'n_timesteps'")

    policy = values.get("policy", "MlpPolicy")
    if policy not in algo_cls.policy_aliases:
        raise ConfigError(
            f"{where}: key 'policy': unknown policy {policy!r} for {algo_display_name(algo_cls)}; "
            f"choose one of {sorted(algo_cls.policy_aliases)}"
        )
    if "policy_kwargs" in values:
        values["policy_kwargs"] = _validate_policy_kwargs(values["policy_kwargs"], algo, policy, where)
    if isinstance(values.get("normalize"), dict):
        values["normalize"] = _validate_normalize(values["normalize"], where)
    _check_ranges(values, algo, where)
    _check_hyperparam_ranges(algo_cls, hyperparams, where)
    _check_prior(values, hyperparams, where)
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
    """The ranges of the numeric keys, the off-policy-only keys and the composition (in this order)."""
    _check_counts(values, where)
    _check_scales(values, where)
    _check_off_policy_keys(values, algo, where)
    _check_composition(values, where)


def _check_counts(values: dict[str, Any], where: str) -> None:
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


def _check_scales(values: dict[str, Any], where: str) -> None:
    scale = values.get("action_init_scale")
    if scale is not None and not is_unit_scale(scale):
        raise ConfigError(f"{where}: key 'action_init_scale' must be in (0, 1] or null, got {scale}")
    if not is_unit_scale(values.get("action_scale", 1.0)):
        raise ConfigError(f"{where}: key 'action_scale' must be in (0, 1], got {values['action_scale']}")


def _check_off_policy_keys(values: dict[str, Any], algo: str, where: str) -> None:
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
    _check_noise(values, algo, where)


def _check_noise(values: dict[str, Any], algo: str, where: str) -> None:
    noise_type = values.get("noise_type")
    if noise_type is not None:
        if noise_type not in NOISE_TYPES:
            raise ConfigError(f"{where}: key 'noise_type' must be one of {NOISE_TYPES} or null")
        if not is_off_policy(algo):
            raise ConfigError(f"{where}: key 'noise_type' is only for off-policy algorithms, not {algo}")
    if values.get("save_replay_buffer") and not is_off_policy(algo):
        raise ConfigError(f"{where}: key 'save_replay_buffer' is only for off-policy algorithms")


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


def _check_prior(values: dict[str, Any], hyperparams: Mapping[str, Any], where: str) -> None:
    """A run that starts from a prior policy's actor (``prior_policy``) must not shrink it (``action_init_scale``)."""
    scale = values.get("action_init_scale")
    if hyperparams.get("prior_policy") is not None and scale not in (None, 1.0):
        raise ConfigError(
            f"{where}: key 'action_init_scale' ({scale}) would shrink the actor that prior_policy starts from: "
            "set action_init_scale=null"
        )


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


def algo_display_name(algo_cls: type) -> str:
    """The algorithm's name in messages: the class's own ``display_name`` if it sets one, else its class name."""
    return str(vars(algo_cls).get("display_name", algo_cls.__name__))
