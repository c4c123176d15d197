"""The shipped agents: a run packaged as a folder, and every shipped folder loads and acts."""

from __future__ import annotations

import json
import re

import gymnasium as gym
import numpy as np
import pytest

from agents.export import (
    UntrustedFileError,
    load_agent,
)
from agents.export import sb3 as agent_sb3
from tests.support.agent_runs import REPO, TEST_ENVS, sample_observations


def test_shipped_agent_folder(runs, tmp_path, monkeypatch):
    """scripts.ship_agent packages a run; load_agent loads the folder (trusted inside trained_agents/)."""
    from scripts.ship_agent import package_run

    env_id, env_kwargs = TEST_ENVS[2]
    run_dir = runs["sac", env_id]
    trusted = tmp_path / "trained_agents"
    folder = package_run(run_dir, trusted / "sac-circle-case1-v0", which="best")
    names = {p.name for p in folder.iterdir()}
    assert {"model.zip", "vecnormalize.pkl", "config.yml", "meta.json", "training_curve.png", "training_logs"} <= names
    assert (folder / "model.zip").stat().st_size < 5 * 2**20
    meta = json.loads((folder / "meta.json").read_text())
    shipped = meta["shipped"]
    assert shipped["which"] == "best" and shipped["seed"] == 7 and shipped["budget_timesteps"] == 300
    assert shipped["wall_time_s"] > 0 and shipped["env_kwargs"] == env_kwargs
    assert re.fullmatch(r"[0-9a-f]{40}", shipped["packaged_with"]["git"]["revision"])
    with pytest.raises(FileExistsError):
        package_run(run_dir, folder)

    with pytest.raises(UntrustedFileError):
        load_agent(folder)
    monkeypatch.setattr(agent_sb3, "TRUSTED_DIR", trusted)
    agent = load_agent(folder)
    reference = load_agent(run_dir, which="best", trust=True)
    assert agent.env_id == env_id and agent.env_kwargs == env_kwargs and agent.normalizer is not None
    for obs in sample_observations(env_id, env_kwargs, n=5):
        np.testing.assert_array_equal(agent.predict(obs), reference.predict(obs))


def test_shipped_agents_load_and_act():
    """Every folder of trained_agents/ loads without trust=True and acts on its own environment."""
    folders = sorted(p for p in (REPO / "trained_agents").glob("*") if (p / "model.zip").is_file())
    if not folders:
        pytest.skip("no shipped agents")
    for folder in folders:
        assert (folder / "model.zip").stat().st_size < 5 * 2**20
        for name in ("config.yml", "meta.json", "training_curve.png"):
            assert (folder / name).is_file(), f"{folder.name}/{name}"
        agent = load_agent(folder)
        env = gym.make(agent.env_id, **agent.env_kwargs)
        obs, info = env.reset(seed=1000)
        agent.reset(seed=1000)
        action = agent.predict(obs, info)
        assert env.action_space.contains(action.astype(np.float32))
        env.close()


def test_every_seed_of_every_multi_seed_entry_loads_and_acts():
    """The weights-only seeds load without trust=True, also those whose agent.json names a policy class by a path
    removed in 0.4.0 (agents.ppo_lagrangian...: a record only, the policy is rebuilt from the ``policy`` alias)."""
    seeds = sorted((REPO / "trained_agents").glob("*/seed_*"))
    assert len(seeds) >= 3 * 15
    old_paths = 0
    for folder in seeds:
        old_paths += "agents.ppo_lagrangian." in (folder / "agent.json").read_text(encoding="utf-8")
        agent = load_agent(folder)
        space = agent.observation_space
        obs = np.linspace(-1.0, 1.0, space.shape[0]).astype(space.dtype)
        action = agent.predict(obs)
        assert action.shape == agent.action_space.shape and np.all(np.isfinite(action)), folder
    assert old_paths == 6  # ppo-lagrangian-{circle,transport}-v1, 3 seeds each
