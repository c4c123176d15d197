"""Environment keyword arguments from the command line: the one ``k=v`` parser, and checking keys before ``make``.

Every command that takes ``--env-kwargs K=V ...`` or ``--hyperparams K=V ...`` (``uvdms evaluate``,
``uvdms train``, ``python -m agents.training.train``) parses it with :func:`parse_kv`, and checks environment keys
with :func:`check_make_kwargs` before any model loads, so that a typo is one clear error, not a traceback
from inside an environment constructor.
"""

from __future__ import annotations

import inspect
import numbers
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
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
        ValueError: The id is not registered (the message lists every registered ``uvdms/`` id).
    """
    import importlib

    import gymnasium as gym

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
            f"unknown environment id {name!r} ({exc}); the uvdms environments are {', '.join(registered_ids())}"
        ) from None


def registered_ids(namespace: str = "uvdms") -> list[str]:
    """Every id registered in Gymnasium's ``namespace`` (``uvdms``: importing :mod:`uvdms_gym` registers them)."""
    import gymnasium as gym

    import uvdms_gym  # noqa: F401  (registers the uvdms ids)

    return [env_id for env_id, spec in gym.registry.items() if spec.namespace == namespace]


def check_make_kwargs(env_id: str, kwargs: Mapping[str, Any], option: str | None = None) -> None:
    """Check that ``gymnasium.make(env_id, **kwargs)`` accepts every key and that each value fits its annotation.

    The accepted keys are :data:`GYM_MAKE_KWARGS` and the keyword parameters of the entry point's
    ``__init__`` along its class hierarchy (a ``**kwargs`` passes on to the base class); an entry point that
    takes arbitrary ``**kwargs`` accepts everything. Values are checked by :func:`kwarg_value_problem`.

    Args:
        env_id: The environment id.
        kwargs: The keyword arguments.
        option: The command-line option they came from (``--env-kwargs``), named first in a value's error.

    Raises:
        ValueError: Unknown id, keys the environment does not take (the message lists the accepted ones), or a
            value of the wrong type (the message names the key and the expected type).
    """
    from gymnasium.envs.registration import load_env_creator

    spec = env_spec(env_id)
    creator = spec.entry_point if callable(spec.entry_point) else load_env_creator(spec.entry_point)
    accepted, open_ended, annotations = init_keywords(creator)
    accepted |= set(GYM_MAKE_KWARGS)
    annotations = {**annotations, **GYM_MAKE_ANNOTATIONS}
    unknown = sorted(set(kwargs) - accepted)
    if unknown and not open_ended:
        raise ValueError(
            f"{env_id} takes no keyword argument {', '.join(map(repr, unknown))}; "
            f"it takes {', '.join(sorted(accepted))}"
        )
    check_kwarg_values(f"{option} " if option else f"{env_id}: ", kwargs, annotations)


GYM_MAKE_ANNOTATIONS: dict[str, str] = {"max_episode_steps": "int | None", "disable_env_checker": "bool | None"}
"""The annotations of :data:`GYM_MAKE_KWARGS` in ``gymnasium.make``."""


def init_keywords(creator: Any) -> tuple[set[str], bool, dict[str, str]]:
    """The keyword parameters of an entry point (a class: its ``__init__`` along the class hierarchy).

    Returns:
        The parameter names, whether the entry point also takes arbitrary ``**kwargs``, and the annotation (as
        text) of each annotated parameter (the most derived class's).
    """
    functions = (
        [k.__init__ for k in creator.__mro__ if "__init__" in vars(k)] if isinstance(creator, type) else [creator]
    )
    accepted: set[str] = set()
    annotations: dict[str, str] = {}
    for fn in functions:
        params = inspect.signature(fn).parameters.values()
        named = [p for p in params if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD) and p.name != "self"]
        accepted |= {p.name for p in named}
        for p in named:
            if p.annotation is not p.empty:
                annotations.setdefault(p.name, p.annotation if isinstance(p.annotation, str) else str(p.annotation))
        if not any(p.kind is p.VAR_KEYWORD for p in params):
            return accepted, False, annotations
    return accepted, True, annotations


def check_kwarg_values(where: str, kwargs: Mapping[str, Any], annotations: Mapping[str, str]) -> None:
    """Check each value against its keyword's annotation (keys without one, or unknown types, pass).

    Args:
        where: What the message starts with (``"uvdms/CircleTrack-v1: "``, ``"--env-kwargs "``).
        kwargs: The keyword arguments.
        annotations: Annotation text by keyword (:func:`init_keywords`).

    Raises:
        ValueError: ``<where><key>=<value>: expected <type>`` for the first value that does not fit.
    """
    for key, value in kwargs.items():
        problem = kwarg_value_problem(value, annotations[key]) if key in annotations else None
        if problem:
            raise ValueError(f"{where}{key}={value!r}: {problem}")


def check_init_kwargs(cls: type, kwargs: Mapping[str, Any]) -> None:
    """Check the values of a class's constructor keywords against their annotations (see :func:`check_kwarg_values`).

    Raises:
        ValueError: A value does not fit its keyword's annotation (the message names the key and the type).
    """
    check_kwarg_values(f"{cls.__name__}: ", kwargs, init_keywords(cls)[2])


def kwarg_value_problem(value: Any, annotation: str) -> str | None:
    """``"expected <type>"`` when ``value`` fits no alternative of ``annotation`` (text), else ``None``.

    Understood: ``None``, ``float`` (any real number), ``int``, ``bool``, ``str``, ``Any``, ``Optional[...]``
    and sequences (``tuple[float, float, float]``, ``tuple[float, ...]``, ``Sequence[float]``, ``list[...]``;
    a list, tuple or one-dimensional array). An annotation naming anything else (a class, a ``Literal``) lets
    every value pass: the constructor checks it.
    """
    if not set(re.findall(r"[A-Za-z_]\w*", annotation)) <= _KNOWN_NAMES:
        return None  # it names a class or a Literal: the constructor's own check has the better message
    alternatives = _split(_unwrap_optional(annotation), "|")
    for alternative in alternatives:
        if _fits(value, alternative) is not False:
            return None
    return "expected " + " or ".join(_describe(a) for a in alternatives)


def _unwrap_optional(annotation: str) -> str:
    annotation = annotation.strip()
    if annotation.startswith("Optional[") and annotation.endswith("]"):
        return f"{annotation[9:-1]} | None"
    return annotation


def _split(text: str, separator: str) -> list[str]:
    """``text`` split at ``separator`` outside brackets, each part stripped."""
    parts, depth, current = [], 0, ""
    for char in text:
        depth += {"[": 1, "]": -1}.get(char, 0)
        if char == separator and depth == 0:
            parts.append(current.strip())
            current = ""
        else:
            current += char
    return [*parts, current.strip()]


_SCALARS: dict[str, tuple[str, str]] = {
    "float": ("a float", "floats"),
    "int": ("an integer", "integers"),
    "bool": ("true or false", "booleans"),
    "str": ("a string", "strings"),
    "None": ("None", "None"),
}
_SEQUENCES = ("tuple[", "Sequence[", "list[")
_KNOWN_NAMES = {*_SCALARS, "tuple", "Sequence", "list", "Optional", "Any", "object"}


def _fits_scalar(value: Any, name: str) -> bool | None:
    is_bool = isinstance(value, bool | np.bool_)
    checks = {
        "float": lambda: isinstance(value, numbers.Real) and not is_bool,
        "int": lambda: isinstance(value, numbers.Integral) and not is_bool,
        "bool": lambda: is_bool,
        "str": lambda: isinstance(value, str),
        "None": lambda: value is None,
    }
    return checks[name]() if name in checks else None


def _fits(value: Any, annotation: str) -> bool | None:
    """Whether ``value`` fits ``annotation`` (``None``: a type this check does not know)."""
    if annotation in ("Any", "object"):
        return True
    if not annotation.startswith(_SEQUENCES):
        return _fits_scalar(value, annotation)
    items = _split(annotation[annotation.index("[") + 1 : -1], ",")
    if isinstance(value, np.ndarray):
        value = list(value) if value.ndim == 1 else None
    if not isinstance(value, list | tuple):
        return False
    fixed = annotation.startswith("tuple[") and items[-1] != "..."
    if fixed and len(value) != len(items):
        return False
    kinds = items if fixed else [items[0]] * len(value)
    return all(_fits(v, _unwrap_optional(k)) is not False for v, k in zip(value, kinds, strict=True))


def _describe(annotation: str) -> str:
    """``a float``, ``a sequence of 3 floats``, ``a sequence of floats``; other names as they are written."""
    if annotation in _SCALARS:
        return _SCALARS[annotation][0]
    if not annotation.startswith(_SEQUENCES):
        return annotation
    items = _split(annotation[annotation.index("[") + 1 : -1], ",")
    plural = _SCALARS.get(items[0], ("", "items"))[1]
    if annotation.startswith("tuple[") and items[-1] != "..." and len(set(items)) == 1:
        return f"a sequence of {len(items)} {plural}"
    return f"a sequence of {plural}"


def env_family(env_id: str) -> str:
    """The environment id without its version (``uvdms/CircleTrack-v1`` -> ``uvdms/CircleTrack``).

    The versions of a uvdms task share dynamics, task, observations and costs and differ only in the reward
    (``uvdms_gym/envs/bounded_reward.py``). A ``module:`` prefix is ignored.
    """
    from gymnasium.envs.registration import parse_env_id

    namespace, name, _version = parse_env_id(env_id.split(":")[-1])
    return f"{namespace}/{name}" if namespace else name
