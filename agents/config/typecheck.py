"""Generic checking of plain YAML data against Python type annotations (no evaluation, strict keys).

:class:`TypeChecker` validates a value read with ``yaml.safe_load`` against an annotation (a dataclass
field's type or a keyword argument's annotation of a library class): ``bool``, ``int``, ``float``, ``str``,
``None``, unions, ``Literal``, lists, tuples, mappings, ``Callable`` (only strings matching a pattern, such as
schedule names) and ``type[...]`` (only names of a whitelist, such as ``tanh`` for ``torch.nn.Tanh``).
Numeric strings are accepted for numbers (YAML 1.1 reads ``3e-4`` without a dot as a string); nothing is ever
evaluated or imported. :func:`check_known_keys` rejects unknown keys with close matches. Errors are
:class:`ConfigError` naming where (file and entry) and which key. :mod:`agents.config.schema` builds the training
configuration schema on top of this.
"""

from __future__ import annotations

import collections.abc
import dataclasses
import difflib
import inspect
import math
import re
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from typing import Any, Literal, Union

_NUMBER_RE = re.compile(r"^[-+]?(\d[\d_]*(\.\d*)?|\.\d+)([eE][-+]?\d+)?$")


class ConfigError(ValueError):
    """Invalid configuration (unknown key, wrong type, missing entry, bad file)."""


class _Mismatch(Exception):
    """A value does not match an annotation (message: what was expected)."""


@dataclasses.dataclass(frozen=True)
class TypeChecker:
    """Validates plain data against annotations.

    Attributes:
        class_whitelists: ``(base class, {name: class})`` pairs: a ``type[X]`` annotation accepts the names of
            the first table whose classes are all subclasses of ``X`` (and whose base is related to ``X``).
        callable_pattern: Strings accepted for ``Callable`` annotations (``None``: none); group 1, if any,
            must be a number.
        callable_description: How such a string is described in error messages.
    """

    class_whitelists: tuple[tuple[type, Mapping[str, type]], ...] = ()
    callable_pattern: re.Pattern[str] | None = None
    callable_description: str = "a callable (not expressible in YAML)"

    def validate(self, value: Any, annotation: Any, where: str, key: str) -> Any:
        """Check ``value`` against ``annotation``; return it (numbers coerced, tuples as lists).

        Exact matches win over coercions (a numeric string for an ``int | str`` stays a string).

        Args:
            value: Plain data.
            annotation: The expected type.
            where: Source named in errors (``"file.yml: entry 'x'"``).
            key: Key named in errors.

        Returns:
            The checked value.

        Raises:
            ConfigError: The value does not match (the message says what was expected).
        """
        try:
            return self._check(value, annotation, coerce=False)
        except _Mismatch:
            pass
        try:
            return self._check(value, annotation, coerce=True)
        except _Mismatch as exc:
            raise ConfigError(f"{where}: key {key!r}: expected {exc}, got {tname(value)} {_short(value)}") from None

    def accepts_callable(self, ann: Any) -> bool:
        """Whether ``ann`` is (or is a union containing) ``Callable``."""
        if ann is collections.abc.Callable or typing.get_origin(ann) is collections.abc.Callable:
            return True
        if typing.get_origin(ann) in (Union, types.UnionType):
            return any(self.accepts_callable(a) for a in typing.get_args(ann))
        return False

    def class_table(self, ann: Any) -> Mapping[str, type] | None:
        """The whitelist usable for a ``type[X]`` annotation (``None``: none)."""
        (base,) = typing.get_args(ann) or (None,)
        if not isinstance(base, type):
            return None
        for root, table in self.class_whitelists:
            if issubclass(base, root) or issubclass(root, base):
                if all(issubclass(cls, base) for cls in table.values()):
                    return table
        return None

    def _check(self, value: Any, ann: Any, coerce: bool) -> Any:
        if ann is Any or ann is inspect.Parameter.empty:
            try:
                return plain(value, "value")
            except ConfigError as exc:
                raise _Mismatch("plain YAML data") from exc
        if ann is type(None) or ann is None:
            if value is None:
                return None
            raise _Mismatch("null")
        origin = typing.get_origin(ann)
        if origin in (Union, types.UnionType):
            return self._check_union(value, typing.get_args(ann), coerce)
        if ann in _SCALAR_CHECKS:
            return _SCALAR_CHECKS[ann](value, coerce)
        checker = self._structured_check(ann, origin)
        if checker is None:
            raise _Mismatch(self.describe(ann))
        return checker(value, ann, coerce)

    def _check_union(self, value: Any, members: tuple[Any, ...], coerce: bool) -> Any:
        """The first member that accepts ``value`` as it is, else (``coerce``) the first that accepts it converted."""
        for coerce_now in (False, True) if coerce else (False,):
            for member in members:
                try:
                    return self._check(value, member, coerce=coerce_now)
                except _Mismatch:
                    pass
        raise _Mismatch(" or ".join(d for d in (self.describe(m) for m in members) if d))

    def _structured_check(self, ann: Any, origin: Any) -> Callable[[Any, Any, bool], Any] | None:
        """The check of a literal, list, tuple, mapping, schedule or class annotation (``None``: none applies)."""
        if origin is Literal:
            return self._check_literal
        if origin in (list, collections.abc.Sequence):
            return self._check_list
        if origin is tuple:
            return self._check_tuple
        if origin in (dict, collections.abc.Mapping):
            return self._check_mapping
        if ann is collections.abc.Callable or origin is collections.abc.Callable:
            return self._check_callable
        if origin is type:
            return self._check_class
        return None

    def _check_literal(self, value: Any, ann: Any, coerce: bool) -> Any:
        if value in typing.get_args(ann):
            return value
        raise _Mismatch(self.describe(ann))

    def _check_list(self, value: Any, ann: Any, coerce: bool) -> Any:
        (item,) = typing.get_args(ann) or (Any,)
        if isinstance(value, list):
            return [self._check(v, item, coerce) for v in value]
        raise _Mismatch(self.describe(ann))

    def _check_tuple(self, value: Any, ann: Any, coerce: bool) -> Any:
        args = typing.get_args(ann)
        if isinstance(value, list | tuple):
            if len(args) == 2 and args[1] is Ellipsis:
                return [self._check(v, args[0], coerce) for v in value]
            if len(value) == len(args):
                return [self._check(v, a, coerce) for v, a in zip(value, args)]
        raise _Mismatch(self.describe(ann))

    def _check_mapping(self, value: Any, ann: Any, coerce: bool) -> Any:
        key_t, val_t = typing.get_args(ann) or (str, Any)
        if isinstance(value, dict):
            return {self._check(k, key_t, False): self._check(v, val_t, coerce) for k, v in value.items()}
        raise _Mismatch(self.describe(ann))

    def _check_callable(self, value: Any, ann: Any, coerce: bool) -> Any:
        if isinstance(value, str) and self.callable_pattern is not None:
            match = self.callable_pattern.match(value)
            if match and (not match.groups() or as_number(match.group(1)) is not None):
                return value
        raise _Mismatch(self.describe(ann))

    def _check_class(self, value: Any, ann: Any, coerce: bool) -> Any:
        table = self.class_table(ann)
        if table is not None and value in table:
            return value
        raise _Mismatch(self.describe(ann))

    def describe(self, ann: Any) -> str:
        """What ``ann`` accepts, in words (empty for types that cannot be written in YAML)."""
        if ann is type(None) or ann is None:
            return "null"
        origin = typing.get_origin(ann)
        if origin in (Union, types.UnionType):
            return " or ".join(d for d in (self.describe(m) for m in typing.get_args(ann)) if d)
        if ann in (bool, int, float, str):
            return ann.__name__
        if origin is Literal:
            return "one of " + ", ".join(repr(a) for a in typing.get_args(ann))
        if ann is Any:
            return "plain data"
        return self._describe_structured(ann, origin)

    def _describe_structured(self, ann: Any, origin: Any) -> str:
        if origin in (list, collections.abc.Sequence):
            (item,) = typing.get_args(ann) or (Any,)
            return f"a list of {self.describe(item)}"
        if origin is tuple:
            return "a list [" + ", ".join(self.describe(a) for a in typing.get_args(ann) if a is not Ellipsis) + "]"
        if origin in (dict, collections.abc.Mapping):
            return "a mapping"
        if ann is collections.abc.Callable or origin is collections.abc.Callable:
            return self.callable_description
        if origin is type:
            table = self.class_table(ann)
            if table is not None:
                return "one of " + ", ".join(repr(k) for k in table)
            return ""  # a class that cannot be written in YAML
        return ""  # objects (action noise, torch.device, ...) cannot be written in YAML


def _check_bool(value: Any, coerce: bool) -> bool:
    if isinstance(value, bool):
        return value
    raise _Mismatch("bool")


def _check_int(value: Any, coerce: bool) -> int:
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    if coerce:
        number = as_number(value)
        if number is not None and math.isfinite(number) and float(number).is_integer():
            return int(number)
    raise _Mismatch("int")


def _check_float(value: Any, coerce: bool) -> float:
    if isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    if coerce:
        number = as_number(value)
        if number is not None:
            return float(number)
    raise _Mismatch("float")


def _check_str(value: Any, coerce: bool) -> str:
    if isinstance(value, str):
        return value
    raise _Mismatch("str")


_SCALAR_CHECKS: dict[Any, Callable[[Any, bool], Any]] = {
    bool: _check_bool,
    int: _check_int,
    float: _check_float,
    str: _check_str,
}
"""The checks of the scalar annotations (``coerce``: numeric strings of YAML 1.1 such as ``3e-4`` count as numbers)."""


def accepts_tuple(ann: Any) -> bool:
    """Whether ``ann`` is (or is a union containing) a ``tuple`` type."""
    if typing.get_origin(ann) is tuple:
        return True
    if typing.get_origin(ann) in (Union, types.UnionType):
        return any(accepts_tuple(a) for a in typing.get_args(ann))
    return False


def check_known_keys(mapping: Mapping[Any, Any], allowed: Iterable[str], where: str, what: str) -> None:
    """Reject keys of ``mapping`` outside ``allowed`` (non-string keys too), suggesting close matches.

    Args:
        mapping: The mapping read from YAML.
        allowed: The accepted keys.
        where: Source named in errors.
        what: What the allowed keys are, for the message (``"VecNormalize arguments"``).

    Raises:
        ConfigError: The first unknown key.
    """
    allowed = list(allowed)
    for key in mapping:
        if not isinstance(key, str):
            raise ConfigError(f"{where}: key {key!r} must be a string")
        if key not in allowed:
            raise ConfigError(
                f"{where}: unknown key {key!r} ({what}: {', '.join(allowed)}){close_matches(key, allowed)}"
            )


def as_number(value: Any) -> float | None:
    """The number a numeric string (or float) stands for, else ``None``."""
    if isinstance(value, str) and _NUMBER_RE.match(value.strip()):
        return float(value.strip().replace("_", ""))
    if isinstance(value, float) and not isinstance(value, bool):
        return value
    return None


def plain(value: Any, where: str) -> Any:
    """Check that ``value`` is JSON-like plain data (tuples become lists).

    Raises:
        ConfigError: A value or mapping key that is not plain data.
    """
    if value is None or isinstance(value, bool | int | str | float):
        return value
    if isinstance(value, list | tuple):
        return [plain(v, where) for v in value]
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise ConfigError(f"{where}: mapping key {k!r} must be a string")
            out[k] = plain(v, where)
        return out
    raise ConfigError(f"{where}: {tname(value)} is not plain data (null, bool, number, string, list, mapping)")


def copy_plain(value: Any) -> Any:
    """Deep copy of nested dicts and lists (tuples become lists)."""
    if isinstance(value, dict):
        return {k: copy_plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [copy_plain(v) for v in value]
    return value


def close_matches(key: str, candidates: Iterable[str]) -> str:
    """``"; did you mean 'a', 'b'?"`` for close matches of ``key`` (empty if none)."""
    close = difflib.get_close_matches(key, list(candidates), n=3)
    return f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""


def tname(value: Any) -> str:
    """YAML-ish name of a value's type (``mapping``, ``list``, ``null``, ``int``, ...)."""
    return {dict: "mapping", list: "list", type(None): "null"}.get(type(value), type(value).__name__)


def _short(value: Any) -> str:
    text = repr(value)
    return f"({text[:60]}...)" if len(text) > 60 else f"({text})"
