"""What release 0.2 deprecated is gone (the aliases of 0.3 fail with a message: test_removed_aliases.py)."""

from __future__ import annotations

import importlib

import pytest

import uvdms_gym  # noqa: F401  (registers the environments)


def test_the_removed_cli_alias_is_gone():
    """``uvdms_gym.cli`` (deprecated in 0.2) was removed with the package's regrouping; the command is ``uvdms``."""
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("uvdms_gym.cli")


@pytest.mark.parametrize("old", ["baselines.evaluate"])
def test_the_removed_baselines_shim_is_gone(old):
    """``baselines.evaluate`` (deprecated in 0.2): its names live in ``uvdms_gym.evaluation`` and the leaderboard."""
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module(old)
