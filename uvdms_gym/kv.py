"""The one ``key=value`` parser of the command lines (``--env-kwargs``, ``--hyperparams``, ...).

Values are YAML literals read with ``yaml.safe_load`` (``case=1`` -> 1, ``goal=paper`` -> ``"paper"``,
``left_center=[1, 0, 2]`` -> a list, ``name=`` -> ``""``). It lives in the ground-floor package so that every
command (``uvdms``, ``python -m agents.train``) can use it without importing another layer.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import yaml


def parse_key_values(items: Sequence[str] | None, option: str = "--env-kwargs") -> dict[str, Any]:
    """Parse ``key=value`` strings into a mapping; values are YAML literals (``yaml.safe_load``).

    Args:
        items: Strings such as ``["case=1", "goal=paper", "hydro_randomization=0.3"]`` (``None``: none).
        option: The command-line option they came from, named in error messages.

    Returns:
        The mapping, in the order of ``items`` (a repeated key keeps its last value), e.g.
        ``{"case": 1, "goal": "paper", "hydro_randomization": 0.3}``.

    Raises:
        ValueError: An item without ``=`` or without an identifier key (the message names the option and the
            item), or a value that is not a YAML literal (the message names the option, the key and the value).
    """
    out: dict[str, Any] = {}
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
