"""TrainConfig files, their keys and types, and the light parser's names (agents.config)."""

from __future__ import annotations

import re

import pytest
import torch
import yaml

from agents.algos import ALGOS
from agents.config import ConfigError, load_config, parse_entry, validate_config_file
from agents.training.train import (
    parse_key_values,
)
from tests.support.agent_runs import ALGO_NAMES, REPO, UVDMS_IDS


@pytest.mark.parametrize("path", sorted((REPO / "train_configs").glob("*.yml")), ids=lambda p: p.name)
def test_every_train_config_validates(path):
    configs = validate_config_file(path)
    assert path.stem in ALGOS
    assert "default" in configs
    for env_id in UVDMS_IDS:
        cfg = configs[env_id]
        assert cfg.n_timesteps >= 100_000
        assert cfg.algo == path.stem
    for cfg in configs.values():
        assert parse_entry(cfg.to_entry(), cfg.algo) == cfg  # the resolved form round-trips
        cfg.sb3_policy_kwargs()
        cfg.sb3_hyperparams()


def test_all_algos_have_a_config():
    assert sorted(p.stem for p in (REPO / "train_configs").glob("*.yml")) == ALGO_NAMES


@pytest.mark.parametrize(
    ("entry", "key"),
    [
        ({"n_timesteps": 10, "learning_rat": 1.0e-3}, "learning_rat"),
        ({"n_timesteps": 10, "policy_kwargs": {"net_arc": [8]}}, "policy_kwargs.net_arc"),
        ({"n_timesteps": 10, "normalize": {"clip": 5.0}}, "normalize.clip"),
        ({"n_timesteps": 10, "seed": 3}, "seed"),
        ({"n_timesteps": 10, "action_noise": "normal"}, "action_noise"),
    ],
)
def test_unknown_key_is_rejected_with_its_name(tmp_path, entry, key):
    path = tmp_path / "sac.yml"
    path.write_text(yaml.safe_dump({"default": entry}), encoding="utf-8")
    with pytest.raises(ConfigError, match=re.escape(f"'{key}'")) as info:
        load_config(path, "sac", "Pendulum-v1")
    assert str(path) in str(info.value)


@pytest.mark.parametrize(
    ("entry", "key"),
    [
        ({"n_timesteps": "many"}, "n_timesteps"),
        ({"n_timesteps": 10, "n_envs": 1.5}, "n_envs"),
        ({"n_timesteps": 10, "batch_size": "32x"}, "batch_size"),
        ({"n_timesteps": 10, "gamma": [0.9]}, "gamma"),
        ({"n_timesteps": 10, "normalize": "yes"}, "normalize"),
        ({"n_timesteps": 10, "learning_rate": "fast"}, "learning_rate"),
        ({"n_timesteps": 10, "policy_kwargs": {"activation_fn": "sigmoid"}}, "policy_kwargs.activation_fn"),
        ({"n_timesteps": 10, "policy_kwargs": {"net_arch": "big"}}, "policy_kwargs.net_arch"),
        ({"n_timesteps": 10, "use_sde": 1}, "use_sde"),
        ({"n_timesteps": 10, "env_kwargs": ["case", 1]}, "env_kwargs"),
    ],
)
def test_wrong_type_is_rejected_with_key_and_file(tmp_path, entry, key):
    path = tmp_path / "sac.yml"
    path.write_text(yaml.safe_dump({"default": entry, "Pendulum-v1": {}}), encoding="utf-8")
    with pytest.raises(ConfigError, match=re.escape(f"'{key}'")) as info:
        load_config(path, "sac", "Pendulum-v1")
    assert str(path) in str(info.value)


def test_error_in_another_entry_is_reported(tmp_path):
    path = tmp_path / "ppo.yml"
    path.write_text("default: {n_timesteps: 10}\nOther-v0: {n_stepz: 3}\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"n_stepz.*did you mean 'n_steps'"):
        load_config(path, "ppo", "Pendulum-v1")


def test_anchors_default_merge_and_conversions(tmp_path):
    path = tmp_path / "ppo.yml"
    path.write_text(
        "base: &base\n"
        "  n_timesteps: 1000\n"
        "  learning_rate: 3e-4\n"  # YAML 1.1 reads this as a string; accepted as a float
        "  policy_kwargs: {net_arch: {pi: [32], vf: [64]}, activation_fn: elu}\n"
        "default:\n  <<: *base\n  n_envs: 4\n"
        "My-v0:\n  <<: *base\n  clip_range: lin_0.2\n  env_kwargs: {case: 2}\n",
        encoding="utf-8",
    )
    cfg = load_config(path, "ppo", "My-v0")
    assert cfg.n_envs == 4  # from default
    assert cfg.hyperparams["learning_rate"] == pytest.approx(3e-4)
    assert cfg.env_kwargs == {"case": 2}
    kwargs = cfg.sb3_policy_kwargs()
    assert kwargs["activation_fn"] is torch.nn.ELU
    schedule = cfg.sb3_hyperparams()["clip_range"]
    assert schedule(1.0) == pytest.approx(0.2) and schedule(0.5) == pytest.approx(0.1)
    assert load_config(path, "ppo", "Unlisted-v0").n_envs == 4


def test_missing_entry_and_bad_files(tmp_path):
    path = tmp_path / "sac.yml"
    path.write_text("Other-v0: {n_timesteps: 10}\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="no entry for env 'Pendulum-v1'"):
        load_config(path, "sac", "Pendulum-v1")
    path.write_text("- 1\n- 2\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="top level must be a mapping"):
        load_config(path, "sac", "Pendulum-v1")
    path.write_text("default: !!python/object/apply:os.system ['true']\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="invalid YAML"):
        load_config(path, "sac", "Pendulum-v1")
    with pytest.raises(ConfigError, match="unknown algorithm"):
        load_config(path, "dqn", "Pendulum-v1")


def test_parse_key_values():
    assert parse_key_values(["case=1", "goal=paper", "hydro_randomization=true", "scale=1.5e-2", "goals=[1, 2]"]) == {
        "case": 1,
        "goal": "paper",
        "hydro_randomization": True,
        "scale": 0.015,
        "goals": [1, 2],
    }
    with pytest.raises(ConfigError, match="key=value"):
        parse_key_values(["novalue"])


def test_algo_names_of_the_light_parser_match_algos():
    from agents.training.args import ALGO_NAMES as PARSER_ALGOS

    assert list(PARSER_ALGOS) == ALGO_NAMES


def test_residual_observation_choices_of_the_light_parser_match_the_composition():
    from agents.training.args import RESIDUAL_OBSERVATION_NAMES
    from uvdms_gym.residual import RESIDUAL_OBSERVATIONS

    assert RESIDUAL_OBSERVATION_NAMES == RESIDUAL_OBSERVATIONS


def test_the_full_range_variant_differs_from_ppo_lagrangian_only_where_it_says():
    """``variants/ppo_lagrangian_full_range.yml``: no action cap, a smaller initial log-std, 1.2M steps."""
    for env_id in ("uvdms/CircleTrack-v1", "uvdms/Transport-v1"):
        base = load_config(REPO / "train_configs" / "ppo_lagrangian.yml", "ppo_lagrangian", env_id)
        variant_file = REPO / "train_configs" / "variants" / "ppo_lagrangian_full_range.yml"
        variant = load_config(variant_file, "ppo_lagrangian", env_id)
        a, b = base.to_entry(), variant.to_entry()
        assert variant.action_scale == 1.0  # the capped entries pass --hyperparams action_scale=0.3
        assert b["policy_kwargs"]["log_std_init"] == -2.0 and a["policy_kwargs"]["log_std_init"] == -1.0
        assert b["n_timesteps"] == 1_200_000
        changed = {k for k in set(a) | set(b) if a.get(k) != b.get(k)}
        assert changed == {"policy_kwargs", "n_timesteps"}, changed
