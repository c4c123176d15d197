"""Shipped agent folders follow one naming scheme; their former names still load (agents.common.paths)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from agents.common.paths import SHIPPED_ALIASES, resolve_shipped, trained_agents_dir
from agents.export import load_agent

REPO = Path(__file__).resolve().parents[3]
SCHEME = re.compile(r"^[a-z0-9]+(-[a-z0-9]+)*-v\d+$")


def test_every_shipped_folder_follows_the_scheme():
    folders = [p.name for p in (REPO / "trained_agents").iterdir() if p.is_dir() and p.name != "reference"]
    assert folders and all(SCHEME.match(name) for name in folders), folders
    assert set(SHIPPED_ALIASES.values()) <= set(folders)
    assert not set(SHIPPED_ALIASES) & set(folders)  # the old names are gone from the folder


@pytest.mark.parametrize("old", sorted(SHIPPED_ALIASES))
def test_former_names_resolve_to_the_renamed_folder_from_any_directory(old, tmp_path, monkeypatch):
    new = trained_agents_dir() / SHIPPED_ALIASES[old]
    monkeypatch.chdir(REPO)
    assert resolve_shipped(f"trained_agents/{old}").resolve() == new.resolve()
    monkeypatch.chdir(tmp_path)  # no trained_agents/ here: the installed (or checkout) copy
    assert resolve_shipped(f"trained_agents/{old}").resolve() == new.resolve()
    assert resolve_shipped(old).resolve() == new.resolve()


def test_other_paths_are_unchanged(tmp_path):
    assert resolve_shipped(tmp_path / "circle_case1_ppo") == tmp_path / "circle_case1_ppo"  # not a trained_agents dir
    assert resolve_shipped("trained_agents/no_such_agent") == Path("trained_agents/no_such_agent")


def test_a_former_name_loads_the_same_agent(monkeypatch):
    monkeypatch.chdir(REPO)
    old, new = load_agent("trained_agents/circle_case1_ppo"), load_agent("trained_agents/ppo-circle-case1-v0")
    obs = np.linspace(-1.0, 1.0, old.observation_space.shape[0]).astype(old.observation_space.dtype)
    np.testing.assert_array_equal(old.predict(obs), new.predict(obs))
