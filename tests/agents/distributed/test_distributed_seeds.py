"""``uvdms sweep`` and ``uvdms tune`` under the seed protocol: only training seeds reach ``reset()``, bad ones refused.

A local sweep of two tiny runs (seed 3 and 998_999_999, the largest training seed of a run with one evaluation env)
and an in-process search of two trials record every seed passed to an environment's ``reset()``
(``tests/support/reset_seeds.py``). The search runs its trials with :func:`agents.distributed.tune.run_trial` in this
process, samples from its own seeded ``OptunaSearch``, and reports to a list instead of Ray Tune: everything of
:func:`agents.distributed.tune.tune` but Ray's scheduling (which ``tests/agents/distributed/test_tune.py`` runs).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from agents.common.envs import eval_env_seed, train_env_seed
from agents.distributed import tune as tune_module
from agents.distributed.sweep import check_seeds, sweep
from agents.distributed.tune import METRIC, TIME_ATTR, run_trial, tune
from tests.support.reset_seeds import ENV, ENV_KWARGS, assert_protocol_seeds, record_reset_seeds, write_tiny_config
from uvdms_gym.seeds import SeedProtocolError

LARGEST = 998_999_999
"""The largest training seed of a run with one evaluation env (its evaluation env's seed is 999_999_999)."""


@pytest.fixture
def tiny_config(tmp_path) -> Path:
    return write_tiny_config(tmp_path)


@pytest.fixture
def learning_rate_space(tmp_path) -> Path:
    path = tmp_path / "space.yml"
    space = {"lr": {"type": "float", "low": 1.0e-4, "high": 1.0e-3, "log": True, "key": "learning_rate"}}
    path.write_text(yaml.safe_dump(space), encoding="utf-8")
    return path


def test_a_sweep_resets_only_training_seeds(tmp_path, monkeypatch, tiny_config):
    recorded = record_reset_seeds(monkeypatch, tmp_path / "seeds.txt")
    result = sweep("ppo", ENV, [3, LARGEST], env_kwargs=ENV_KWARGS, config_path=tiny_config, total_timesteps=64,
                   out_dir=tmp_path / "out")  # fmt: skip
    assert not result.failed
    seeds = recorded.seeds()
    assert_protocol_seeds(seeds)
    for seed in (3, LARGEST):
        assert {train_env_seed(seed, 0, 0), train_env_seed(seed, 0, 1), eval_env_seed(seed, 0)} <= set(seeds)
    assert max(seeds) == eval_env_seed(LARGEST, 0) == 999_999_999


def _run_trials_here(monkeypatch: Any) -> None:
    """Replace Ray Tune by a loop in this process: each sample of the search's own searcher, trained by run_trial."""
    from ray import tune as ray_tune

    def run_trials(setup, searcher, scheduler_options, cpus, *, n_trials, **_) -> list[dict[str, Any]]:
        search, rows = searcher(), []
        for i in range(n_trials):
            config, reports = search.suggest(f"t{i}"), []
            monkeypatch.setattr(ray_tune, "report", reports.append)
            run_trial(config, setup)
            params = {p.name: config[p.name] for p in setup.space.params}
            rows.append({"trial": f"t{i}", "status": "completed", METRIC: reports[-1][METRIC],
                         TIME_ATTR: reports[-1][TIME_ATTR], "eval_episode_length": None, "params": params,
                         "hyperparams": setup.hyperparams(params), "error": None})  # fmt: skip
        return rows

    monkeypatch.setattr(tune_module, "_run_trials", run_trials)


def test_a_search_resets_only_training_seeds(tmp_path, monkeypatch, tiny_config, learning_rate_space):
    monkeypatch.chdir(tmp_path)  # run_trial trains under the working directory (Tune's trial directory)
    _run_trials_here(monkeypatch)
    recorded = record_reset_seeds(monkeypatch, tmp_path / "seeds.txt")
    result = tune("ppo", ENV, 2, env_kwargs=ENV_KWARGS, config_path=tiny_config, search_space_path=learning_rate_space,
                  total_timesteps=64, seed=LARGEST, out_dir=tmp_path / "out")  # fmt: skip
    assert len(result.trials) == 2 and result.best_config.is_file()
    assert len({t["params"]["lr"] for t in result.trials}) == 2  # two samples, one training seed
    seeds = recorded.seeds()
    assert_protocol_seeds(seeds)
    assert {train_env_seed(LARGEST, 0, 0), train_env_seed(LARGEST, 0, 1), eval_env_seed(LARGEST, 0)} <= set(seeds)
    assert json.loads((tmp_path / "out" / "tune.json").read_text())["tune"]["seed"] == LARGEST


@pytest.mark.parametrize(
    ("seeds", "grid", "message"),
    [
        ([0, 3_000_000_000], None, r"^--seeds: training seed 3000000000: seed 3000000000 is in the test split"),
        ([-1], None, r"^--seeds: training seed -1: seed -1 is in no split"),
        ([999_999_999], None, r"training seed 999999999 \(its evaluation env 0: .*\): seed 1000999999 is in no split"),
        # every grid point's envs count: with 2 evaluation envs the largest seed reaches 1_000_000_000
        ([0, LARGEST], {"n_eval_envs": [1, 2]}, r"^grid point 1 \(n_eval_envs=2\): --seeds: training seed 998999999"),
    ],
)
def test_a_sweep_refuses_seeds_leaving_the_training_split(tmp_path, tiny_config, seeds, grid, message):
    with pytest.raises(SeedProtocolError, match=message):
        sweep("ppo", ENV, seeds, env_kwargs=ENV_KWARGS, config_path=tiny_config, grid=grid, out_dir=tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_check_seeds_counts_the_envs():
    assert check_seeds([LARGEST]) == [LARGEST]
    with pytest.raises(SeedProtocolError, match=r"evaluation env 1: seed \+ 1000000 \+ rank\): seed 1000000000"):
        check_seeds([LARGEST], n_envs=2, n_eval_envs=2)


@pytest.mark.parametrize(
    ("seed", "message"),
    [
        (3_000_000_000, r"^--seed 3000000000: seed 3000000000 is in the test split"),
        (999_999_999, r"^--seed 999999999 \(its evaluation env 0: seed \+ 1000000 \+ rank\): seed 1000999999"),
        (-5, r"^--seed -5: seed -5 is in no split"),
    ],
)
def test_a_search_refuses_seeds_leaving_the_training_split(tmp_path, tiny_config, learning_rate_space, seed, message):
    with pytest.raises(SeedProtocolError, match=message):
        tune("ppo", ENV, 2, env_kwargs=ENV_KWARGS, config_path=tiny_config, search_space_path=learning_rate_space,
             total_timesteps=64, seed=seed, out_dir=tmp_path / "out")  # fmt: skip
    assert not (tmp_path / "out").exists()
