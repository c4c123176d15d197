"""RL Baselines3 Zoo's config vocabulary, read into the flat entries of :class:`agents.config.schema.TrainConfig`.

The files ``train_configs/<algo>.yml`` are RL Zoo hyperparameter files: ``python -m rl_zoo3.train --algo sac
--env uvdms/CircleTrack-v0 --gym-packages uvdms_gym -conf train_configs/sac.yml`` trains from them unchanged.
An RL Zoo entry may only hold algorithm keyword arguments and the keys RL Zoo takes out before building the
model (``n_timesteps``, ``n_envs``, ``normalize``, ``policy``, ``policy_kwargs``, ``env_kwargs``, ``noise_type``,
``noise_std``, ``env_wrapper``, ``callback``, ...); everything else goes to the algorithm and fails. So the project's
training-side options are written the way RL Zoo writes them:

* ``env_wrapper: [{agents.common.wrappers.ScaledAction: {scale: 0.3}},
  {agents.common.wrappers.AliveBonus: {bonus: 2.0}}]`` -> ``action_scale: 0.3``, ``alive_bonus: 2.0``;
* ``callback: [{agents.training.callbacks.ScaleInitialActions: {scale: 0.01}}]`` -> ``action_init_scale: 0.01``, and
  ``{agents.training.callbacks.DelayActorUpdates: {steps: 20000}}`` -> ``actor_warmup_steps: 20000``;
* ``env_kwargs`` is an RL Zoo key already (the ``gymnasium.make`` keyword arguments);
* options RL Zoo takes only from its command line (``--eval-freq``, ``--eval-episodes``, ``--n-eval-envs``,
  ``--save-freq``, ``--eval-env-kwargs``, ``--save-replay-buffer``) sit in the top-level mapping
  ``train_options`` (keyed by env id or ``default``, merged like the entries), which RL Zoo never reads (it
  looks up the env id, else ``default``): ``eval_freq``, ``n_eval_episodes``, ``n_eval_envs``,
  ``checkpoint_freq``, ``eval_env_kwargs``, ``save_replay_buffer``, ``max_episode_steps``.

Only the four class names above are accepted (nothing named in a config is imported here; RL Zoo imports
them itself; the names of before 0.4.0, ``agents.wrappers.*`` and ``agents.callbacks.*``, are refused with the
new one). The flat keys (``alive_bonus``, ``eval_freq``, ...) stay valid in an entry, in ``--hyperparams``
and in a run's ``config.yml``; giving one both ways is an error.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from agents.common.legacy import MOVED
from agents.config.typecheck import ConfigError, check_known_keys, tname

TRAIN_OPTIONS = "train_options"
"""Top-level key of the options RL Zoo takes from its command line (see the module docstring)."""
TRAIN_OPTION_KEYS: tuple[str, ...] = (
    "eval_freq",
    "n_eval_episodes",
    "n_eval_envs",
    "checkpoint_freq",
    "eval_env_kwargs",
    "save_replay_buffer",
    "max_episode_steps",
)
"""Keys of a ``train_options`` mapping (``TrainConfig`` fields)."""

WRAPPERS: dict[str, tuple[str, str]] = {
    "agents.common.wrappers.ScaledAction": ("scale", "action_scale"),
    "agents.common.wrappers.AliveBonus": ("bonus", "alive_bonus"),
}
"""``env_wrapper`` class name -> (its keyword argument, the ``TrainConfig`` field it sets)."""
CALLBACKS: dict[str, tuple[str, str]] = {
    "agents.training.callbacks.ScaleInitialActions": ("scale", "action_init_scale"),
    "agents.training.callbacks.DelayActorUpdates": ("steps", "actor_warmup_steps"),
}
"""``callback`` class name -> (its keyword argument, the ``TrainConfig`` field it sets)."""


def flatten_entry(entry: Mapping[str, Any], where: str) -> dict[str, Any]:
    """Replace an entry's ``env_wrapper`` and ``callback`` lists by the ``TrainConfig`` fields they stand for.

    Args:
        entry: One merged entry (RL Zoo keys and/or flat keys).
        where: Source named in errors.

    Returns:
        A flat entry (a new dict; ``entry`` is unchanged).

    Raises:
        ConfigError: An unknown class, a bad list item, or a field given both ways.
    """
    flat = dict(entry)
    for key, table in (("env_wrapper", WRAPPERS), ("callback", CALLBACKS)):
        if key not in flat:
            continue
        for name, kwargs in _class_items(flat.pop(key), f"{where}: key {key!r}"):
            if name not in table:
                raise ConfigError(f"{where}: key {key!r}: {_unknown_class(name, table)}")
            argument, field_name = table[name]
            check_known_keys(kwargs, [argument], f"{where}: key {key!r}: {name}", "arguments")
            if argument not in kwargs:
                raise ConfigError(f"{where}: key {key!r}: {name} needs {{{argument}: ...}}")
            if field_name in flat or field_name in entry:
                raise ConfigError(f"{where}: {field_name!r} is given twice (as a key and through {key!r} {name})")
            flat[field_name] = kwargs[argument]
    return flat


def _unknown_class(name: str, table: Mapping[str, Any]) -> str:
    """Why ``name`` is refused: a name of before 0.4.0 (with the new one), or not one of ``table``."""
    module, _, attribute = name.rpartition(".")
    if module in MOVED and f"{MOVED[module]}.{attribute}" in table:
        return f"{name!r} was renamed {MOVED[module]}.{attribute} in 0.4.0 (the alias {module} was removed)"
    return f"{name!r} is not one of {sorted(table)} (the project's loader imports nothing named in a config)"


def _class_items(value: Any, where: str) -> list[tuple[str, dict[str, Any]]]:
    """RL Zoo's ``env_wrapper``/``callback`` forms: a name, ``{name: kwargs}``, or a list of these."""
    items = value if isinstance(value, list) else [value]
    out = []
    for item in items:
        if isinstance(item, str):
            out.append((item, {}))
        elif isinstance(item, dict) and len(item) == 1:
            ((name, kwargs),) = item.items()
            if kwargs is None:
                kwargs = {}
            if not isinstance(name, str) or not isinstance(kwargs, dict):
                raise ConfigError(f"{where}: expected {{class name: {{keyword: value}}}}, got {item!r}")
            out.append((name, kwargs))
        else:
            raise ConfigError(f"{where}: expected a class name or {{class name: {{...}}}}, got {tname(item)} {item!r}")
    names = [name for name, _ in out]
    for name in names:
        if names.count(name) > 1:
            raise ConfigError(f"{where}: {name!r} is listed twice")
    return out


def train_options(data: Mapping[str, Any], name: str, default: str, where: str) -> dict[str, Any]:
    """The ``train_options`` of entry ``name``: its ``default`` mapping shallow-merged with its own.

    Args:
        data: The whole file (``yaml.safe_load``).
        name: Env id (or ``default``).
        default: Name of the default entry.
        where: Source named in errors.

    Returns:
        The options (flat ``TrainConfig`` keys; empty without a ``train_options`` mapping).

    Raises:
        ConfigError: A malformed ``train_options`` mapping or an unknown key in it.
    """
    section = data.get(TRAIN_OPTIONS) or {}
    if not isinstance(section, dict):
        raise ConfigError(f"{where}: {TRAIN_OPTIONS!r} must be a mapping of env id -> options, got {tname(section)}")
    merged: dict[str, Any] = {}
    for key in dict.fromkeys((default, name)):
        options = section.get(key) or {}
        if not isinstance(options, dict):
            raise ConfigError(f"{where}: {TRAIN_OPTIONS}[{key!r}] must be a mapping, got {tname(options)}")
        check_known_keys(options, TRAIN_OPTION_KEYS, f"{where}: {TRAIN_OPTIONS}[{key!r}]", "train options")
        merged.update(options)
    return merged


_FIELD_DEFAULTS: dict[str, Any] = {
    "action_scale": 1.0,
    "alive_bonus": 0.0,
    "action_init_scale": None,
    "actor_warmup_steps": 0,
}
"""Values of the ``env_wrapper``/``callback`` fields that need no list item (no wrapper, no callback)."""


def zoo_entry(flat: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """A flat entry (``TrainConfig.to_entry()``) written the way ``train_configs/<algo>.yml`` write entries.

    The inverse of :func:`flatten_entry` and :func:`train_options`.

    Args:
        flat: The flat entry.

    Returns:
        ``(entry, options)``: the entry with ``env_wrapper``/``callback`` lists (items only for fields that are
        not at their no-op value) and without the noise keys when ``noise_type`` is unset (RL Zoo reads
        ``noise_type`` as a string), and the ``train_options`` of the entry.
    """
    entry = dict(flat)
    options = {key: entry.pop(key) for key in TRAIN_OPTION_KEYS if key in entry}
    if entry.get("noise_type", "unset") is None:
        entry.pop("noise_type")
        entry.pop("noise_std", None)
    for key, table in (("env_wrapper", WRAPPERS), ("callback", CALLBACKS)):
        items = []
        for name, (argument, field_name) in table.items():
            if field_name in entry:
                value = entry.pop(field_name)
                if value != _FIELD_DEFAULTS[field_name]:
                    items.append({name: {argument: value}})
        if items:
            entry[key] = items
    return entry, options
