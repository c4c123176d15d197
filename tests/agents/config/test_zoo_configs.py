"""train_configs/*.yml as RL Baselines3 Zoo hyperparameter files, read the same by the project's loader.

* Every entry resolves to the training it resolved to before the files were rewritten in RL Zoo's vocabulary
  (``tests/data/train_configs_before.json``: ``TrainConfig.to_entry()`` of every entry, recorded with the
  loader and files of the commit before the change).
* Every env entry holds only keys RL Zoo accepts (its own keys or keyword arguments of the algorithm), and
  the classes it names exist and take the keyword arguments given.
* ``python -m rl_zoo3.train`` trains a few hundred steps from ``train_configs/sac.yml`` (skipped without rl_zoo3).
"""

from __future__ import annotations

import importlib
import inspect
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import yaml

from agents.algos import ALGOS
from agents.config import ConfigError, load_config, parse_entry, validate_config_file
from agents.config.zoo import TRAIN_OPTIONS

REPO = Path(__file__).resolve().parents[3]
CONFIGS = sorted((REPO / "train_configs").glob("*.yml"))
BEFORE = json.loads((REPO / "tests" / "data" / "train_configs_before.json").read_text(encoding="utf-8"))

# Keys RL Zoo takes out of an entry before passing the rest to the algorithm (rl_zoo3.exp_manager).
RL_ZOO_KEYS = {
    "n_timesteps",
    "n_envs",
    "normalize",
    "policy",
    "policy_kwargs",
    "env_kwargs",
    "noise_type",
    "noise_std",
    "env_wrapper",
    "callback",
    "vec_env_wrapper",
    "frame_stack",
    "monitor_kwargs",
    "replay_buffer_class",
    "replay_buffer_kwargs",
}


def _effective_policy_kwargs(cfg) -> dict:
    """SB3 policy keyword arguments with the policy class's defaults filled in (what the model is built with)."""
    policy_cls = ALGOS[cfg.algo].policy_aliases[cfg.policy]
    defaults = {
        name: p.default
        for name, p in inspect.signature(policy_cls.__init__).parameters.items()
        if p.default is not inspect.Parameter.empty
    }
    return {**defaults, **cfg.sb3_policy_kwargs()}


# Entries added after the rewrite (they have no "before" value; the RL Zoo key checks below cover them).
ADDED_SINCE = {f"{algo}/uvdms/{task}-v1" for algo in ("ppo", "sac") for task in ("CircleTrack", "Transport")}


def test_before_values_cover_every_entry():
    """Every entry of the files that existed at the rewrite (files added later, e.g. ppo_lagrangian.yml, aside)."""
    before_files = {key.split("/", 1)[0] for key in BEFORE}
    assert before_files <= {path.stem for path in CONFIGS}
    files = [path for path in CONFIGS if path.stem in before_files]
    now = {f"{path.stem}/{name}" for path in files for name in validate_config_file(path)}
    assert now - ADDED_SINCE == set(BEFORE)
    assert ADDED_SINCE <= now


@pytest.mark.parametrize("key", sorted(BEFORE))
def test_entry_resolves_as_before(key):
    algo, name = key.split("/", 1)
    new = validate_config_file(REPO / "train_configs" / f"{algo}.yml")[name]
    old = parse_entry(BEFORE[key], algo, source="before", entry_name=name)
    new_entry, old_entry = new.to_entry(), old.to_entry()
    new_policy, old_policy = new_entry.pop("policy_kwargs"), old_entry.pop("policy_kwargs")
    assert new_entry == old_entry
    # the files no longer name activation_fn where it is SB3's default (RL Zoo cannot read a class name)
    assert {k: v for k, v in old_policy.items() if k != "activation_fn"} == new_policy
    assert _effective_policy_kwargs(new) == _effective_policy_kwargs(old)
    assert new.sb3_hyperparams() == old.sb3_hyperparams()
    assert new.normalize_kwargs() == old.normalize_kwargs()


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_env_entries_hold_only_keys_rl_zoo_accepts(path):
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    algo_params = set(inspect.signature(ALGOS[path.stem].__init__).parameters) - {"self", "policy", "env"}
    env_ids = [k for k in data if k not in ("default", TRAIN_OPTIONS)]
    assert env_ids, path
    for env_id in env_ids:
        entry = data[env_id]
        unknown = set(entry) - RL_ZOO_KEYS - algo_params
        assert not unknown, f"{path.name} {env_id}: RL Zoo would pass {sorted(unknown)} to {ALGOS[path.stem].__name__}"
        for key in ("env_wrapper", "callback"):
            for item in entry.get(key, []):
                ((name, kwargs),) = item.items()
                module, _, cls_name = name.rpartition(".")
                cls = getattr(importlib.import_module(module), cls_name)
                inspect.signature(cls).bind(*(["env"] if key == "env_wrapper" else []), **kwargs)
        for value in entry.get("policy_kwargs", {}).values():
            assert not isinstance(value, str), f"{path.name} {env_id}: RL Zoo passes policy_kwargs strings as is"


def test_zoo_keys_and_flat_keys_read_the_same(tmp_path):
    zoo = {
        "Pendulum-v1": {
            "n_timesteps": 100,
            "env_wrapper": [
                {"agents.common.wrappers.ScaledAction": {"scale": 0.5}},
                {"agents.common.wrappers.AliveBonus": {"bonus": 1.5}},
            ],
            "callback": [{"agents.training.callbacks.ScaleInitialActions": {"scale": 0.1}}],
        },
        TRAIN_OPTIONS: {"default": {"eval_freq": 7}, "Pendulum-v1": {"n_eval_episodes": 3}},
    }
    flat = {
        "Pendulum-v1": {
            "n_timesteps": 100,
            "action_scale": 0.5,
            "alive_bonus": 1.5,
            "action_init_scale": 0.1,
            "eval_freq": 7,
            "n_eval_episodes": 3,
        }
    }
    (tmp_path / "zoo.yml").write_text(yaml.safe_dump(zoo), encoding="utf-8")
    (tmp_path / "flat.yml").write_text(yaml.safe_dump(flat), encoding="utf-8")
    a = load_config(tmp_path / "zoo.yml", "sac", "Pendulum-v1")
    assert a == load_config(tmp_path / "flat.yml", "sac", "Pendulum-v1")
    assert (a.action_scale, a.alive_bonus, a.action_init_scale, a.eval_freq, a.n_eval_episodes) == (0.5, 1.5, 0.1, 7, 3)
    # a command-line override of a flat key wins over the file's wrapper
    assert load_config(tmp_path / "zoo.yml", "sac", "Pendulum-v1", overrides={"alive_bonus": 3.0}).alive_bonus == 3.0


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ({"env_wrapper": [{"gymnasium.wrappers.ClipAction": {}}]}, "is not one of"),
        ({"env_wrapper": [{"agents.common.wrappers.AliveBonus": {"bonsu": 1.0}}]}, "unknown key 'bonsu'"),
        ({"env_wrapper": [{"agents.common.wrappers.AliveBonus": {}}]}, "needs"),
        ({"env_wrapper": [{"agents.common.wrappers.AliveBonus": {"bonus": 2.0}}], "alive_bonus": 1.0}, "given twice"),
        ({"env_wrapper": [{"agents.common.wrappers.AliveBonus": {"bonus": 1.0}}] * 2}, "listed twice"),
        ({"env_wrapper": [3]}, "expected a class name"),
        ({"callback": [{"agents.training.callbacks.ScaleInitialActions": {"scale": "x"}}]}, "action_init_scale"),
        ({"env_wrapper": [{"agents.common.wrappers.ScaledAction": {"scale": 2.0}}]}, "action_scale"),
        (  # the names of before 0.4.0 are refused with the new one
            {"env_wrapper": [{"agents.wrappers.AliveBonus": {"bonus": 2.0}}]},
            r"'agents\.wrappers\.AliveBonus' was renamed agents\.common\.wrappers\.AliveBonus in 0\.4\.0",
        ),
        (
            {"callback": [{"agents.callbacks.ScaleInitialActions": {"scale": 0.1}}]},
            r"'agents\.callbacks\.ScaleInitialActions' was renamed agents\.training\.callbacks\.ScaleInitialActions",
        ),
        ({"callback": [{"agents.callbacks.Nope": {"scale": 0.1}}]}, "is not one of"),
    ],
)
def test_bad_zoo_keys_are_named(tmp_path, entry, message):
    path = tmp_path / "bad.yml"
    path.write_text(yaml.safe_dump({"Pendulum-v1": {"n_timesteps": 10, **entry}}), encoding="utf-8")
    with pytest.raises(ConfigError, match=message):
        load_config(path, "sac", "Pendulum-v1")


def test_bad_train_options_are_named(tmp_path):
    path = tmp_path / "bad.yml"
    path.write_text(
        yaml.safe_dump({"Pendulum-v1": {"n_timesteps": 10}, TRAIN_OPTIONS: {"Pendulum-v1": {"eval_frq": 5}}}),
        encoding="utf-8",
    )
    with pytest.raises(ConfigError, match=r"unknown key 'eval_frq'.*did you mean 'eval_freq'"):
        load_config(path, "sac", "Pendulum-v1")
    path.write_text(
        yaml.safe_dump(
            {"Pendulum-v1": {"n_timesteps": 10, "eval_freq": 4}, TRAIN_OPTIONS: {"Pendulum-v1": {"eval_freq": 5}}}
        ),
        encoding="utf-8",
    )
    with pytest.raises(ConfigError, match="both in the entry and in 'train_options'"):
        load_config(path, "sac", "Pendulum-v1")


@pytest.mark.slow
def test_rl_zoo_trains_from_the_shipped_sac_config(tmp_path):
    pytest.importorskip("rl_zoo3", reason="rl_zoo3 is not installed (pip install -e .[zoo])")
    steps = 300
    cmd = [
        sys.executable,
        "-m",
        "rl_zoo3.train",
        "--algo",
        "sac",
        "--env",
        "uvdms/CircleTrack-v0",
        "--gym-packages",
        "uvdms_gym",
        "-conf",
        str(REPO / "train_configs" / "sac.yml"),
        "-n",
        str(steps),
        "--hyperparams",
        "learning_starts:100",
        "buffer_size:1000",
        "batch_size:32",
        "policy_kwargs:dict(net_arch=[16])",
        "--env-kwargs",
        "case:1",
        "max_episode_steps:50",
        "--eval-freq",
        "-1",
        "--seed",
        "0",
        "-f",
        str(tmp_path),
    ]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    result = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    (model,) = tmp_path.glob("sac/uvdms-CircleTrack-v0_*/uvdms-CircleTrack-v0.zip")
    with zipfile.ZipFile(model) as archive:
        assert json.loads(archive.read("data"))["num_timesteps"] >= steps
    (saved,) = model.parent.glob("uvdms-CircleTrack-v0/config.yml")
    hyperparams = dict(yaml.unsafe_load(saved.read_text(encoding="utf-8")))
    assert hyperparams["env_wrapper"] == [
        {"agents.common.wrappers.ScaledAction": {"scale": 0.3}},
        {"agents.common.wrappers.AliveBonus": {"bonus": 2.0}},
    ]
    assert hyperparams["callback"] == [{"agents.training.callbacks.ScaleInitialActions": {"scale": 0.01}}]


@pytest.mark.parametrize("algo", sorted(ALGOS))
def test_scale_initial_actions_callback_scales_like_the_trainer(algo):
    """RL Zoo applies ``action_init_scale`` through the callback; agents.training.train calls scale_action_layer
    directly."""
    import gymnasium as gym
    import torch

    from agents.training.callbacks import ScaleInitialActions
    from agents.training.models import scale_action_layer

    def fresh():
        return ALGOS[algo]("MlpPolicy", gym.make("Pendulum-v1"), policy_kwargs={"net_arch": [8]}, seed=3)

    direct, through_callback, untouched = fresh(), fresh(), fresh()
    scale_action_layer(direct, 0.1)
    ScaleInitialActions(scale=0.1).init_callback(through_callback)
    a, b, c = (m.policy.state_dict() for m in (direct, through_callback, untouched))
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert any(not torch.equal(a[k], c[k]) for k in a)  # the layer did change
    trained = fresh()
    trained.num_timesteps = 10  # a model that has trained (RL Zoo's --trained-agent) is left alone
    ScaleInitialActions(scale=0.1).init_callback(trained)
    assert all(torch.equal(v, c[k]) for k, v in trained.policy.state_dict().items())
    with pytest.raises(ValueError, match="scale"):
        ScaleInitialActions(scale=0.0)


def test_kv_parser_names_option_and_key():
    from agents.training.train import parse_key_values as agents_parser
    from uvdms_gym.utils.kwargs import parse_kv as parse_key_values

    items = ["case=1", "radius=0.15", "goal=paper", "left_center=[1, 0, 2]", "name=", "flag=true"]
    expected = {"case": 1, "radius": 0.15, "goal": "paper", "left_center": [1, 0, 2], "name": "", "flag": True}
    assert parse_key_values(items, "--env-kwargs") == expected == agents_parser(items)
    assert parse_key_values(None, "--x") == {}
    with pytest.raises(ValueError, match=r"--hyperparams: expected key=value .*'novalue'"):
        parse_key_values(["novalue"], "--hyperparams")
    with pytest.raises(ValueError, match="--env-kwargs: expected key=value"):
        parse_key_values(["2x=1"], "--env-kwargs")
    with pytest.raises(ValueError, match=r"--env-kwargs: the value of 'radius' \('\{'\) is not a YAML literal"):
        parse_key_values(["radius={"], "--env-kwargs")
    with pytest.raises(ConfigError, match="--hyperparams: the value of 'lr'"):
        agents_parser(["lr=[1"], "--hyperparams")


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_delay_actor_updates_keeps_the_actor_and_trains_the_critic(algo):
    """actor_warmup_steps: no actor change before the step count (critic updated meanwhile), changes after."""
    import gymnasium as gym
    import torch

    from agents.training.callbacks import DelayActorUpdates

    def fresh():
        kwargs = {"learning_starts": 10, "policy_kwargs": {"net_arch": [8]}, "seed": 5}
        return ALGOS[algo]("MlpPolicy", gym.make("Pendulum-v1"), **kwargs)

    def params(module: torch.nn.Module) -> list[torch.Tensor]:
        return [p.detach().clone() for p in module.parameters()]

    model = fresh()
    actor0, critic0 = params(model.actor), params(model.critic)
    callback = DelayActorUpdates(61)  # the update after step 60 sees num_timesteps == 60 < 61
    model.learn(60, callback=callback)
    assert model.num_timesteps == 60 and callback.skipped > 0
    assert all(torch.equal(a, b) for a, b in zip(actor0, params(model.actor), strict=True))
    assert not all(torch.equal(a, b) for a, b in zip(critic0, params(model.critic), strict=True))
    model.learn(20, callback=DelayActorUpdates(61), reset_num_timesteps=False)  # past the warm-up: the actor learns
    assert not all(torch.equal(a, b) for a, b in zip(actor0, params(model.actor), strict=True))
    undelayed = fresh()  # and without the callback the actor moves within the same 60 steps
    undelayed.learn(60)
    assert not all(torch.equal(a, b) for a, b in zip(actor0, params(undelayed.actor), strict=True))
    with pytest.raises(ValueError, match="steps must be an integer >= 0"):
        DelayActorUpdates(-1)
    ppo = ALGOS["ppo"]("MlpPolicy", gym.make("Pendulum-v1"), n_steps=16, batch_size=16, seed=0)
    with pytest.raises(ValueError, match="needs an off-policy actor-critic model"):
        ppo.learn(16, callback=DelayActorUpdates(10))


def test_actor_warmup_steps_reads_from_the_zoo_callback_and_is_refused_for_ppo(tmp_path):
    path = tmp_path / "zoo.yml"
    entry = {"n_timesteps": 10, "callback": [{"agents.training.callbacks.DelayActorUpdates": {"steps": 500}}]}
    path.write_text(yaml.safe_dump({"Pendulum-v1": entry}), encoding="utf-8")
    assert load_config(path, "sac", "Pendulum-v1").actor_warmup_steps == 500
    with pytest.raises(ConfigError, match="'actor_warmup_steps' is only for off-policy algorithms, not ppo"):
        load_config(path, "ppo", "Pendulum-v1")
    path.write_text(yaml.safe_dump({"Pendulum-v1": {"n_timesteps": 10, "actor_warmup_steps": -3}}), encoding="utf-8")
    with pytest.raises(ConfigError, match="'actor_warmup_steps' must be >= 0"):
        load_config(path, "sac", "Pendulum-v1")
