"""``uvdms bench train`` (agents/training/bench.py): its figures are what its blocks say, with the thread rule."""

from __future__ import annotations

import numpy as np
import pytest

from agents.common.threads import update_threads
from agents.training.bench import CONFIGURATIONS, bench_train


@pytest.mark.slow
def test_bench_train_quick_reports_consistent_figures():
    result = bench_train(quick=True, sac_block_steps=150)
    for algo, on_policy in (("ppo", True), ("sac", False)):
        entry = result[algo]
        configurations = [c for c in CONFIGURATIONS if c[2] != "rollout" or on_policy]  # (rollout: PPO only)
        assert ("2_rollout" in entry) == on_policy
        for key, n_envs, vec_env in configurations:
            row = entry[key]
            assert (row["n_envs"], row["vec_env"]) == (n_envs, vec_env)
            assert row["torch_update_threads"] == update_threads(n_envs, vec_env, on_policy)
            assert row["steps_per_s"] == np.median(row["blocks_steps_per_s"]) > 0
        for key, _, _ in configurations[1:]:
            suffix = key[1:]
            ones, twos = entry["1"]["blocks_steps_per_s"], entry[key]["blocks_steps_per_s"]
            assert entry[f"speedup_2{suffix}_vs_1"] == entry[key]["steps_per_s"] / entry["1"]["steps_per_s"]
            assert entry[f"speedup_2{suffix}_vs_1_paired"] == np.median(np.divide(twos, ones))
    assert entry["1"]["block_steps"] == 150  # SAC's blocks have the requested size
    assert result["ppo"]["1"]["block_steps"] * 2 == result["ppo"]["2_hybrid"]["block_steps"]  # one rollout each
    assert result["ppo"]["2_rollout"]["block_steps"] == result["ppo"]["2_hybrid"]["block_steps"]
