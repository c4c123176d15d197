"""Policy keyword arguments: the whitelisted class names a config may use, and the name <-> class conversion.

A config names classes by whitelisted strings (``activation_fn: tanh``), never by import path, so that loading a
YAML file imports and evaluates nothing; :func:`resolve_policy_kwargs` turns the names into classes for SB3 and
:func:`plain_policy_kwargs` turns them back for the weights-only export.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, FlattenExtractor

from agents.config.typecheck import ConfigError, plain

ACTIVATIONS: dict[str, type[torch.nn.Module]] = {
    "tanh": torch.nn.Tanh,
    "relu": torch.nn.ReLU,
    "elu": torch.nn.ELU,
    "leaky_relu": torch.nn.LeakyReLU,
    "gelu": torch.nn.GELU,
    "silu": torch.nn.SiLU,
    "softplus": torch.nn.Softplus,
}
"""Whitelist of ``activation_fn`` names."""

OPTIMIZERS: dict[str, type[torch.optim.Optimizer]] = {
    "adam": torch.optim.Adam,
    "adamw": torch.optim.AdamW,
    "rmsprop": torch.optim.RMSprop,
}
"""Whitelist of ``optimizer_class`` names."""

FEATURES_EXTRACTORS: dict[str, type[BaseFeaturesExtractor]] = {"flatten": FlattenExtractor}
"""Whitelist of ``features_extractor_class`` names."""

CLASS_WHITELISTS: tuple[tuple[type, dict[str, type]], ...] = (
    (torch.nn.Module, ACTIVATIONS),
    (torch.optim.Optimizer, OPTIMIZERS),
    (BaseFeaturesExtractor, FEATURES_EXTRACTORS),
)
"""Base class -> whitelist of names, for the config type-checker."""

CLASS_KEYS = {
    "activation_fn": ACTIVATIONS,
    "optimizer_class": OPTIMIZERS,
    "features_extractor_class": FEATURES_EXTRACTORS,
}
"""Policy keyword arguments that take a class, with the whitelist of names for each."""


def resolve_policy_kwargs(policy_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """Replace whitelisted class names (``activation_fn: tanh``) by the classes.

    Args:
        policy_kwargs: Plain-data policy keyword arguments.

    Returns:
        Keyword arguments ready for the SB3 policy constructor.

    Raises:
        ConfigError: If a class name is not whitelisted.
    """
    out = dict(policy_kwargs)
    for key, table in CLASS_KEYS.items():
        if key in out and isinstance(out[key], str):
            if out[key] not in table:
                raise ConfigError(f"policy_kwargs {key!r}: {out[key]!r} is not one of {sorted(table)}")
            out[key] = table[out[key]]
    if isinstance(out.get("net_arch"), dict):
        out["net_arch"] = {k: list(v) for k, v in out["net_arch"].items()}
    return out


def plain_policy_kwargs(policy_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """Inverse of :func:`resolve_policy_kwargs`: classes -> whitelisted names (for JSON export).

    Raises:
        ConfigError: If a class is not in a whitelist or a value is not plain data.
    """
    out: dict[str, Any] = {}
    for key, value in policy_kwargs.items():
        if isinstance(value, type):
            for table in CLASS_KEYS.values():
                names = [name for name, cls in table.items() if cls is value]
                if names:
                    out[key] = names[0]
                    break
            else:
                raise ConfigError(f"policy_kwargs {key!r}: class {value.__qualname__} is not whitelisted")
        else:
            out[key] = plain(value, f"policy_kwargs {key!r}")
    return out
