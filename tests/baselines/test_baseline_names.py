"""One meaning per name: the baselines' registry names, and the shims of 0.2 that are gone."""

from __future__ import annotations

import importlib

import pytest

from baselines import controllers
from baselines.controllers import BASELINES, baseline_action_mode


@pytest.mark.parametrize("name", sorted(BASELINES))
def test_baseline_action_mode_is_the_registry_s(name):
    assert baseline_action_mode(name) == BASELINES[name]["action_mode"]


def test_a_name_that_is_no_baseline_has_no_action_mode():
    assert baseline_action_mode("trained_agents/some-agent") is None


@pytest.mark.parametrize("name", ["make_controller", "required_action_mode"])
def test_the_leaderboard_s_names_are_not_defined_in_baselines(name):
    """``leaderboard.suite.registry`` defines them (names and agent paths); ``baselines`` has ``make_baseline`` and
    ``baseline_action_mode``."""
    assert not hasattr(controllers, name)


def test_the_deprecated_evaluate_module_is_gone():
    with pytest.raises(ImportError):
        importlib.import_module("baselines.evaluate")
