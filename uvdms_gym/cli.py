"""Deprecated (0.2; removed in 0.3): the ``uvdms`` command moved to the top-level package :mod:`uvdms_cli`.

The environment package may not import the packages above it, and the command composes all of them, so
``uvdms_gym.cli.main`` and ``python -m uvdms_gym.cli`` are gone: use ``uvdms`` or ``python -m uvdms_cli``
(``CHANGELOG.md``). The argument helpers that lived here still resolve, with a ``DeprecationWarning``, from
their new home :mod:`uvdms_gym.kwargs`: ``parse_kv``, ``env_spec``, ``check_make_kwargs``, ``GYM_MAKE_KWARGS``.
"""

from __future__ import annotations

import warnings
from typing import Any

_MOVED: tuple[str, ...] = ("parse_kv", "env_spec", "check_make_kwargs", "GYM_MAKE_KWARGS")


def __getattr__(name: str) -> Any:
    """The moved argument helpers, with a ``DeprecationWarning`` (PEP 562)."""
    if name not in _MOVED:
        hint = " (the command is uvdms_cli.main.main)" if name == "main" else ""
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}{hint}")
    from uvdms_gym import kwargs

    warnings.warn(
        f"uvdms_gym.cli.{name} is deprecated; import it from uvdms_gym.kwargs", DeprecationWarning, stacklevel=2
    )
    return getattr(kwargs, name)


if __name__ == "__main__":
    raise SystemExit("python -m uvdms_gym.cli was removed in 0.2: run `uvdms` or `python -m uvdms_cli`")
