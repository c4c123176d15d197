"""The training keys ``navigation_filter``, ``frame_stack`` and ``env_variants`` of ``TrainConfig``.

Checked: ``variant_kwargs`` cycles over the variants (computed here independently); bad values are one-line
``ConfigError`` s naming the key; unknown keys are still rejected.
"""

from __future__ import annotations

import re

import pytest
import yaml

from agents.config import ConfigError, load_config, parse_entry

CIRCLE = "uvdms/CircleTrack-v1"


def _parse(**extra):
    return parse_entry({"n_timesteps": 10, **extra}, "dagger", source="test.yml", entry_name=CIRCLE)


def test_variant_kwargs_cycle_over_the_training_envs():
    variants = [{"realism": 2}, {"realism": 3, "case": 1}, {}]
    cfg = _parse(env_kwargs={"case": "random", "realism": 1}, env_variants=variants, n_envs=5)
    for rank in range(7):
        expected = dict(cfg.env_kwargs)
        expected.update(variants[rank % 3])
        assert cfg.variant_kwargs(rank) == expected
    assert cfg.variant_kwargs(1) == {"case": 1, "realism": 3}
    cfg.variant_kwargs(0)["case"] = "changed"  # a copy
    assert cfg.env_kwargs == {"case": "random", "realism": 1}
    plain = _parse(env_kwargs={"case": 2})
    assert plain.env_variants == [] and [plain.variant_kwargs(r) for r in range(3)] == [{"case": 2}] * 3


def test_the_keys_reach_the_composition_and_round_trip_through_the_entry():
    cfg = _parse(navigation_filter=True, frame_stack=3, env_variants=[{"realism": 2}])
    assert (cfg.composition.navigation_filter, cfg.composition.frame_stack) == (True, 3)
    assert not cfg.composition.is_residual
    entry = cfg.to_entry()
    assert (entry["navigation_filter"], entry["frame_stack"], entry["env_variants"]) == (True, 3, [{"realism": 2}])
    assert parse_entry(entry, "dagger") == cfg
    default = _parse()
    assert (default.navigation_filter, default.frame_stack, default.env_variants) == (False, 1, [])


@pytest.mark.parametrize(
    ("extra", "key"),
    [
        ({"frame_stack": 0}, "frame_stack"),
        ({"frame_stack": 65}, "frame_stack"),
        ({"frame_stack": True}, "frame_stack"),
        ({"frame_stack": [2]}, "frame_stack"),
        ({"navigation_filter": 1}, "navigation_filter"),
        ({"navigation_filter": "on"}, "navigation_filter"),
        ({"env_variants": 3}, "env_variants"),
        ({"env_variants": {"realism": 2}}, "env_variants"),
        ({"env_variants": [3]}, "env_variants"),
        ({"env_variants": [{"realism": 2}, "realism=3"]}, "env_variants"),
    ],
)
def test_bad_values_are_config_errors_naming_the_key(extra, key):
    with pytest.raises(ConfigError, match=re.escape(key)) as info:
        _parse(**extra)
    message = str(info.value)
    assert message.startswith("test.yml: entry 'uvdms/CircleTrack-v1': ") and "\n" not in message


def test_a_bad_frame_stack_in_a_config_file_names_the_file_and_the_key(tmp_path):
    path = tmp_path / "dagger.yml"
    path.write_text(yaml.safe_dump({"default": {"n_timesteps": 10}, CIRCLE: {"frame_stack": 0}}), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"frame_stack must be an integer in \[1, 64\].*got 0") as info:
        load_config(path, "dagger", CIRCLE)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("key", ["frame_stacks", "env_variant", "navigation_filters"])
def test_unknown_keys_near_the_new_ones_are_still_rejected(tmp_path, key):
    path = tmp_path / "dagger.yml"
    path.write_text(yaml.safe_dump({"default": {"n_timesteps": 10, key: 2}}), encoding="utf-8")
    with pytest.raises(ConfigError, match=re.escape(f"'{key}'")) as info:
        load_config(path, "dagger", CIRCLE)
    assert key.rstrip("s") in str(info.value).replace(f"'{key}'", "")  # the close match is suggested
