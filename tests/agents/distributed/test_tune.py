"""``uvdms tune``: the search spaces against RL Zoo's samplers, their checks, a 4-trial search on Ray, bad input.

The search uses the tiny PPO configuration of ``tests/agents/distributed/test_sweep.py``; the ``ray_processes`` fixture
(``tests/support/ray_cluster.py``) fails the test if a process the search started outlives it.
"""

from __future__ import annotations

import json
import re
import zipfile
from pathlib import Path

import optuna
import pytest
import yaml
from test_sweep import ENV, TINY_PPO, tiny_config  # noqa: F401  (fixture)

from agents.config import ConfigError, default_config_path, load_config
from agents.config.policy_kwargs import ACTIVATIONS
from agents.distributed.search_space import default_search_space_path, load_search_space
from agents.distributed.tune import _check_space, _searcher
from agents.training.train import resolve_config
from uvdms_cli.main import main

ALGOS = ("ppo", "sac", "td3", "tqc")


# ------------------------------------------------------------------------------------------------------
# Search spaces
# ------------------------------------------------------------------------------------------------------
def _rl_zoo_distributions_and_params(algo: str, seed: int) -> tuple[dict, dict, dict]:
    """RL Zoo's sampler on a fresh Optuna trial: its distributions, its raw parameters, its hyperparameters."""
    hyperparams_opt = pytest.importorskip("rl_zoo3.hyperparams_opt")
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=seed))
    trial = study.ask()
    sampled = hyperparams_opt.HYPERPARAMS_SAMPLER[algo](trial, 18, 1, {"using_her_replay_buffer": False})
    return trial.distributions, trial.params, sampled


@pytest.mark.parametrize("algo", ALGOS)
def test_search_space_is_rl_zoos(algo):
    space = load_search_space(default_search_space_path(algo))
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    ours = study.ask()
    space.define_by_run(ours)
    zoo_distributions, _, _ = _rl_zoo_distributions_and_params(algo, 0)
    our_distributions = ours.distributions
    if algo == "tqc":  # RL Zoo's bound min(n_quantiles - 1, 5) depends on n_quantiles: 4 is the fixed bound
        assert zoo_distributions.pop("top_quantiles_to_drop_per_net").high in (4, 5)
        assert our_distributions.pop("top_quantiles_to_drop_per_net").high == 4
    assert our_distributions == zoo_distributions


@pytest.mark.parametrize("algo", ALGOS)
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_search_space_gives_rl_zoos_hyperparameters(algo, seed):
    """The same raw sample, converted by the YAML space and by RL Zoo's code, gives the same hyperparameters."""
    space = load_search_space(default_search_space_path(algo))
    _, params, zoo = _rl_zoo_distributions_and_params(algo, seed)
    if algo == "td3":  # RL Zoo builds the noise object; the project's config names it
        noise = zoo.pop("action_noise", None)
        assert (noise is None) == (params["noise_type"] is None)
        zoo.update(noise_type=params["noise_type"], noise_std=params["noise_std"])
    if algo == "tqc" and params["top_quantiles_to_drop_per_net"] > 4:
        params["top_quantiles_to_drop_per_net"] = zoo["top_quantiles_to_drop_per_net"] = 4
    ours = space.hyperparams(params, {})
    zoo_policy = zoo.pop("policy_kwargs")
    if "activation_fn" in zoo_policy:
        zoo_policy["activation_fn"] = {cls: name for name, cls in ACTIVATIONS.items()}[zoo_policy["activation_fn"]]
    assert ours.pop("policy_kwargs") == zoo_policy
    assert ours == pytest.approx(zoo)


@pytest.mark.parametrize("algo", ALGOS)
def test_every_choice_of_the_shipped_spaces_gives_a_valid_config(algo):
    space = load_search_space(default_search_space_path(algo))
    path = default_config_path(algo)
    base = resolve_config(path, algo, ENV)
    checked = []

    def check(sample):
        checked.append(sample)
        resolve_config(path, algo, ENV, space.hyperparams(sample, base.policy_kwargs))

    _check_space(space, check)
    assert len(checked) > len(space.params)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ({"lr": {"type": "float", "low": 1.0, "high": 0.1}}, "low < high"),
        ({"lr": {"type": "float", "low": 0.0, "high": 1.0, "log": True}}, "log scale needs low > 0"),
        ({"lr": {"type": "float", "low": 0.1, "high": 1.0, "lgo": True}}, "unknown key 'lgo'"),
        ({"lr": {"low": 0.1, "high": 1.0}}, "missing 'type'"),
        ({"lr": {"type": "uniform", "low": 0.1, "high": 1.0}}, "type must be one of"),
        ({"n": {"type": "float", "low": 1.0, "high": 4.0, "transform": "pow2"}}, "pow2 needs an int"),
        ({"a": {"type": "categorical"}}, "non-empty 'choices'"),
        ({"a": {"type": "categorical", "choices": [1, 1]}}, "listed twice"),
        ({"a": {"type": "categorical", "choices": [[64]]}}, "name others in 'values'"),
        ({"a": {"type": "categorical", "choices": ["s"], "values": {"m": 1}}}, "must name exactly the choices"),
        ({"a": {"type": "int", "low": 1, "high": 2, "key": "policy_kwargs"}}, "not a config key"),
        (
            {"a": {"type": "int", "low": 1, "high": 2}, "b": {"type": "int", "low": 1, "high": 2, "key": "a"}},
            "key 'a' is set by two parameters",
        ),
        ([1, 2], "non-empty mapping"),
    ],
)
def test_search_space_errors(tmp_path, spec, message):
    path = tmp_path / "space.yml"
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    with pytest.raises(ConfigError, match=re.escape(message)):
        load_search_space(path)


def test_fixed_keys_leave_the_search_and_the_sampler_is_seeded():
    space = load_search_space(default_search_space_path("ppo"))
    reduced = space.without({"n_steps", "gamma"})
    assert {p.name for p in space.params} - {p.name for p in reduced.params} == {"n_steps_pow", "one_minus_gamma"}
    first = [_searcher(reduced, seed=7, n_startup_trials=10).suggest(f"t{i}") for i in range(1)]
    again = [_searcher(reduced, seed=7, n_startup_trials=10).suggest(f"t{i}") for i in range(1)]
    other = [_searcher(reduced, seed=8, n_startup_trials=10).suggest(f"t{i}") for i in range(1)]
    assert first == again != other
    assert set(first[0]) == {p.name for p in reduced.params}


# ------------------------------------------------------------------------------------------------------
# Bad input
# ------------------------------------------------------------------------------------------------------
def _tune_argv(config: Path, out: Path, *extra: str) -> list[str]:
    return ["tune", "--algo", "ppo", "--env", ENV, "--env-kwargs", "case=1", "--config", str(config),
            "--n-trials", "4", "--total-timesteps", "400", "--hyperparams", "n_steps=64", "--out", str(out),
            *extra]  # fmt: skip


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--n-trials", "0"], "--n-trials must be >= 1"),
        (["--algo", "dqn"], "unknown algorithm 'dqn'"),
        (["--total-timesteps", "50"], "eval_freq (100) must be in 1 .. --total-timesteps (50)"),
        (["--grace-period", "500"], "--grace-period must be in 1 .. --total-timesteps (400)"),
        (["--reduction-factor", "1"], "--reduction-factor must be > 1"),
        (["--seed", "3000000000"], "--seed 3000000000: seed 3000000000 is in the test split"),
        (["--seed", "999999999"], "--seed 999999999 (its evaluation env 0: seed + 1000000 + rank): seed 1000999999"),
        (["--env", "uvdms/Nope-v0"], "is not registered"),
        # the command passes the composition layer's factories: a residual is checked by them, before Ray starts
        (["--hyperparams", "n_steps=64", "residual_base=campc-di", "residual_scale=0.5"], "is a torque-mode"),
    ],
)
def test_bad_input_is_one_line(tiny_config, tmp_path, capsys, extra, message):  # noqa: F811
    assert main(_tune_argv(tiny_config, tmp_path / "out", *extra)) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("uvdms: error: ") and "\n" not in err and message in err, err
    assert not (tmp_path / "out").exists()


def test_a_space_fixed_entirely_or_with_a_bad_key_is_an_error(tiny_config, tmp_path, capsys):  # noqa: F811
    space = tmp_path / "space.yml"
    space.write_text(yaml.safe_dump({"n_steps_pow": {"type": "int", "low": 5, "high": 6, "key": "n_steps",
                                                     "transform": "pow2"}}), encoding="utf-8")  # fmt: skip
    assert main(_tune_argv(tiny_config, tmp_path / "out", "--search-space", str(space))) == 2
    assert "nothing to search" in capsys.readouterr().err
    space.write_text(yaml.safe_dump({"lr": {"type": "float", "low": 0.1, "high": 0.2, "key": "learning_rat"}}))
    assert main(_tune_argv(tiny_config, tmp_path / "out", "--search-space", str(space))) == 2
    assert "unknown key 'learning_rat'" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------------------
# A search on a local Ray instance
# ------------------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_tune_writes_a_config_that_trains(tiny_config, tmp_path, capsys, ray_processes):  # noqa: F811
    out = tmp_path / "out"
    assert main(_tune_argv(tiny_config, out, "--num-cpus", "2", "--seed", "3")) == 0
    assert "best config" in capsys.readouterr().out
    record = json.loads((out / "tune.json").read_text(encoding="utf-8"))
    trials = record["trials"]
    assert len(trials) == 4 and {t["status"] for t in trials} <= {"completed", "pruned"}
    completed = [t for t in trials if t["status"] == "completed"]
    assert completed and all(t["timesteps"] == 448 for t in completed)  # 400 steps in rollouts of 64
    # a pruned trial stopped at an ASHA rung (100 * 3**k steps), before the end
    assert all(t["timesteps"] in (100, 300) for t in trials if t["status"] == "pruned")
    best = max(completed, key=lambda t: t["eval_return"])
    assert record["best"]["trial"] == best["trial"]

    cfg = load_config(out / "ppo.yml", "ppo", ENV)
    params = best["params"]
    space = yaml.safe_load(default_search_space_path("ppo").read_text(encoding="utf-8"))
    expected = {
        "n_steps": 64,  # fixed by --hyperparams
        "batch_size": 2 ** params["batch_size_pow"],
        "gamma": 1 - params["one_minus_gamma"],
        "gae_lambda": 1 - params["one_minus_gae_lambda"],
        "n_epochs": params["n_epochs"],
        "clip_range": params["clip_range"],
        "learning_rate": params["learning_rate"],
        "ent_coef": params["ent_coef"],
        "max_grad_norm": params["max_grad_norm"],
    }
    assert {k: cfg.hyperparams[k] for k in expected} == pytest.approx(expected)
    assert cfg.policy_kwargs["net_arch"] == space["net_arch"]["values"][params["net_arch"]]
    assert cfg.policy_kwargs["activation_fn"] == params["activation_fn"]
    assert (cfg.n_timesteps, cfg.n_envs, cfg.eval_freq, cfg.env_kwargs) == (400, 1, 100, {"case": 1})
    assert cfg.max_episode_steps == TINY_PPO["max_episode_steps"]

    runs = tmp_path / "runs"
    argv = ["train", "--algo", "ppo", "--env", ENV, "--config", str(out / "ppo.yml"), "--total-timesteps", "128",
            "--out", str(runs), "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    with zipfile.ZipFile(runs / "uvdms_CircleTrack-v0" / "ppo_0" / "final_model.zip") as archive:
        assert json.loads(archive.read("data"))["num_timesteps"] == 128


def test_tune_without_the_composition_layer_refuses_a_residual(tiny_config, tmp_path):  # noqa: F811
    from agents.distributed.tune import tune

    with pytest.raises(ConfigError, match="uvdms train"):
        residual = {"n_steps": 64, "residual_base": "mpc", "residual_scale": 0.5}
        tune("ppo", ENV, 2, env_kwargs={"case": 1}, config_path=tiny_config, total_timesteps=400,
             hyperparams=residual, out_dir=tmp_path / "out")  # fmt: skip
    assert not (tmp_path / "out").exists()
