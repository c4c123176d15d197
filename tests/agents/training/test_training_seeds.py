"""Training under the seed protocol (``uvdms_gym.seeds``): only training seeds reach ``reset()``, bad seeds refused.

A tiny PPO run (2 training envs, an evaluation every 32 steps) records every seed passed to an environment's
``reset()`` (``tests/support/reset_seeds.py``), in the trainer and in ``SubprocVecEnv`` workers; a resume too. A
training seed whose derived seeds would leave the ``training`` split (3_000_000_000, 999_999_999, -1) is refused in
one line before a run directory exists, by :func:`agents.training.train.train`, by a resume and by ``uvdms train``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from stable_baselines3.common.vec_env import DummyVecEnv

from agents.common.envs import EnvFactory, eval_env_seed, train_env_seed
from agents.training.callbacks import SeededEvalCallback
from agents.training.rundir import create_run_dir
from agents.training.train import resolve_config, train
from tests.support.reset_seeds import ENV, ENV_KWARGS, assert_protocol_seeds, record_reset_seeds, write_tiny_config
from uvdms_cli.main import main
from uvdms_gym.seeds import PROTOCOL, SeedProtocolError

REFUSED = [
    (3_000_000_000, r"--seed 3000000000: seed 3000000000 is in the test split"),
    (999_999_999, r"--seed 999999999 \(its evaluation env 0: seed \+ 1000000 \+ rank\): seed 1000999999 is in no"),
    (-1, r"--seed -1: seed -1 is in no split"),
]


@pytest.fixture
def tiny_config(tmp_path) -> Path:
    return write_tiny_config(tmp_path)


@pytest.mark.parametrize("vec_env", ["dummy", pytest.param("subproc", marks=pytest.mark.slow)])
def test_training_resets_only_training_seeds(tmp_path, monkeypatch, tiny_config, vec_env):
    recorded = record_reset_seeds(monkeypatch, tmp_path / "seeds.txt")
    run_dir = train("ppo", ENV, ENV_KWARGS, tiny_config, seed=11, out_dir=tmp_path / "runs", progress=False,
                    vec_env=vec_env)  # fmt: skip
    seeds = recorded.seeds()
    assert_protocol_seeds(seeds)
    # the recorder saw what the seed scheme says: both training envs (in their process) and an evaluation
    assert {train_env_seed(11, 0, 0), train_env_seed(11, 0, 1), eval_env_seed(11, 0)} <= set(seeds)
    assert seeds.count(eval_env_seed(11, 0)) >= 4  # an evaluation every 32 of 128 steps, each reseeded
    meta = json.loads((run_dir / "meta.json").read_text(encoding="utf-8"))
    assert (meta["seed_protocol"], meta["seed_split"], meta["seed"]) == (PROTOCOL, "training", 11)
    assert "seed_scheme" in meta

    recorded.clear()
    train(resume_dir=run_dir, total_timesteps=64, progress=False)
    seeds = recorded.seeds()
    assert_protocol_seeds(seeds)
    assert {train_env_seed(11, 1, 0), train_env_seed(11, 1, 1), eval_env_seed(11, 0)} <= set(seeds)


@pytest.mark.parametrize(("seed", "message"), REFUSED)
def test_a_seed_leaving_the_training_split_is_refused(tmp_path, tiny_config, seed, message):
    with pytest.raises(SeedProtocolError, match=message):
        train("ppo", ENV, ENV_KWARGS, tiny_config, seed=seed, out_dir=tmp_path / "runs", progress=False)
    assert not (tmp_path / "runs").exists()


def test_the_largest_seed_trains_and_one_more_is_refused(tmp_path, tiny_config):
    """With 2 evaluation envs the last one reaches ``seed + 1_000_001``: 998_999_998 is the largest seed."""
    with pytest.raises(SeedProtocolError, match=r"evaluation env 1: .*seed 1000000000 is in no split"):
        train("ppo", ENV, ENV_KWARGS, tiny_config, seed=998_999_999, out_dir=tmp_path, progress=False,
              hyperparams={"n_eval_envs": 2})  # fmt: skip
    run_dir = train("ppo", ENV, ENV_KWARGS, tiny_config, seed=998_999_998, out_dir=tmp_path, progress=False,
                    total_timesteps=64, hyperparams={"n_eval_envs": 2, "eval_freq": 0})  # fmt: skip
    assert json.loads((run_dir / "meta.json").read_text())["segments"][0]["eval_env_seeds"][-1] == 999_999_999


def test_a_resume_of_a_run_with_a_bad_seed_is_refused(tmp_path, tiny_config):
    cfg = resolve_config(tiny_config, "ppo", ENV)
    run_dir = create_run_dir(tmp_path / "run", "ppo", ENV, 999_999_999, ["uvdms_gym"], tiny_config, cfg)
    with pytest.raises(SeedProtocolError, match=rf"--resume {run_dir}: the run's seed 999999999 \(its evaluation"):
        train(resume_dir=run_dir, total_timesteps=64, progress=False)


def test_the_evaluation_callback_refuses_test_seeds():
    venv = DummyVecEnv([EnvFactory("Pendulum-v1", {})] * 2)
    SeededEvalCallback(venv, eval_seed=2_000_000_000)  # validation seeds are allowed
    for seed in (3_000_000_000, 2_999_999_999):  # the second env's seed is a test seed
        with pytest.raises(SeedProtocolError, match="the evaluation callback's seeds: seed 3000000000 is in the test"):
            SeededEvalCallback(venv, eval_seed=seed)
    venv.close()


def test_uvdms_train_refuses_in_one_line(tmp_path, tiny_config, capsys):
    argv = ["train", "--algo", "ppo", "--env", ENV, "--config", str(tiny_config), "--seed", "3000000000",
            "--out", str(tmp_path / "runs"), "--no-progress"]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("uvdms: error: --seed 3000000000: seed 3000000000 is in the test split"), err
    assert "\n" not in err and "[0, 1000000000)" in err
    assert not (tmp_path / "runs").exists()
