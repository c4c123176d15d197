"""Environment keyword arguments from the command line: the one ``k=v`` parser, and checking keys before ``make``.

Every command that takes ``--env-kwargs K=V ...`` or ``--hyperparams K=V ...`` (``uvdms evaluate``,
``uvdms train``, ``python -m agents.training.train``) parses it with :func:`parse_kv`, and checks environment keys
with :func:`check_make_kwargs` before any model loads, so that a typo is one clear error, not a traceback
from inside an environment constructor.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping, Sequence
from typing import Any

import yaml

GYM_MAKE_KWARGS: tuple[str, ...] = ("max_episode_steps", "disable_env_checker")
"""Keyword arguments ``gymnasium.make`` takes itself (not passed to the environment)."""


def parse_kv(items: Sequence[str] | None, option: str = "--env-kwargs") -> dict:
    """Parse ``k=v`` strings; values are YAML literals (``case=1``, ``radius=0.15``, ``goal=random``).

    Args:
        items: The strings.
        option: The option they came from (for error messages).

    Raises:
        ValueError: An item without ``=`` or an identifier key, or a value that is not valid YAML.
    """
    out: dict = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        if not sep or not key.isidentifier():
            raise ValueError(f"{option}: expected key=value with an identifier key, got {item!r}")
        try:
            out[key] = yaml.safe_load(value) if value else ""
        except yaml.YAMLError as exc:
            problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
            raise ValueError(f"{option}: the value of {key!r} ({value!r}) is not a YAML literal: {problem}") from None
    return out


def env_spec(env_id: str) -> Any:
    """The Gymnasium spec of ``env_id`` (``module:Id`` imports the module first).

    Raises:
        ValueError: The id is not registered (the message lists the ``uvdms/`` ids).
    """
    import importlib

    import gymnasium as gym

    import uvdms_gym

    module, sep, name = env_id.rpartition(":")
    if sep:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise ValueError(f"environment id {env_id!r}: cannot import {module!r} ({exc})") from None
    try:
        return gym.spec(name)
    except gym.error.Error as exc:
        raise ValueError(
            f"unknown environment id {name!r} ({exc}); the uvdms environments are {', '.join(uvdms_gym.ENV_IDS)}"
        ) from None


def check_make_kwargs(env_id: str, kwargs: Mapping[str, Any]) -> None:
    """Check that ``gymnasium.make(env_id, **kwargs)`` accepts every key (values are the environment's to check).

    The accepted keys are :data:`GYM_MAKE_KWARGS` and the keyword parameters of the entry point's
    ``__init__`` along its class hierarchy (a ``**kwargs`` passes on to the base class); an entry point that
    takes arbitrary ``**kwargs`` accepts everything.

    Raises:
        ValueError: Unknown id, or keys the environment does not take (the message lists the accepted ones).
    """
    from gymnasium.envs.registration import load_env_creator

    spec = env_spec(env_id)
    creator = spec.entry_point if callable(spec.entry_point) else load_env_creator(spec.entry_point)
    accepted = set(GYM_MAKE_KWARGS)
    functions = (
        [k.__init__ for k in creator.__mro__ if "__init__" in vars(k)] if isinstance(creator, type) else [creator]
    )
    open_ended = True
    annotations: dict[str, str] = {}
    for fn in functions:
        params = inspect.signature(fn).parameters.values()
        named = [p for p in params if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD) and p.name != "self"]
        accepted |= {p.name for p in named}
        for p in named:
            if p.annotation is not p.empty:
                annotations.setdefault(p.name, p.annotation if isinstance(p.annotation, str) else str(p.annotation))
        if not any(p.kind is p.VAR_KEYWORD for p in params):
            open_ended = False
            break
    unknown = sorted(set(kwargs) - accepted)
    if unknown and not open_ended:
        raise ValueError(
            f"{env_id} takes no keyword argument {', '.join(map(repr, unknown))}; "
            f"it takes {', '.join(sorted(accepted))}"
        )
    for key, value in kwargs.items():
        _check_text_value(env_id, key, value, annotations.get(key))


def _check_text_value(env_id: str, key: str, value: Any, annotation: str | None) -> None:
    """A text value for a keyword that takes no text (``radius=abc``): an error naming the key and the type."""
    if not isinstance(value, str) or annotation is None:
        return
    types = {t.strip() for t in annotation.replace("Optional[", "").replace("]", "").split("|")}
    if types & {"str", "Any", "object"} or "Literal" in annotation or not types & {"float", "int", "bool"}:
        return
    raise ValueError(f"{env_id}: {key}={value!r} is not a valid value; {key} takes {annotation}")


def env_family(env_id: str) -> str:
    """The environment id without its version (``uvdms/CircleTrack-v1`` -> ``uvdms/CircleTrack``).

    The versions of a uvdms task share dynamics, task, observations and costs and differ only in the reward
    (``uvdms_gym/envs/bounded_reward.py``). A ``module:`` prefix is ignored.
    """
    from gymnasium.envs.registration import parse_env_id

    namespace, name, _version = parse_env_id(env_id.split(":")[-1])
    return f"{namespace}/{name}" if namespace else name
