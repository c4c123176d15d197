"""The seed scheme of ``agents.common.envs`` under the seed protocol: derived seeds and the one-line refusal."""

from __future__ import annotations

import pytest

from agents.common.envs import (
    EVAL_SEED_OFFSET,
    MAX_SEGMENTS,
    SEGMENT_SEED_STRIDE,
    check_training_seed,
    eval_env_seed,
    largest_derived_seeds,
    train_env_seed,
)
from uvdms_gym.seeds import TRAINING, SeedProtocolError


def test_largest_derived_seeds_are_the_last_segment_and_the_last_evaluation_env():
    derived = largest_derived_seeds(5, n_envs=4, n_eval_envs=3)
    assert sorted(derived.values()) == [train_env_seed(5, MAX_SEGMENTS - 1, 3), eval_env_seed(5, 2)]
    assert sorted(derived.values()) == [5 + 999_003, 5 + 1_000_002]
    assert MAX_SEGMENTS == EVAL_SEED_OFFSET // SEGMENT_SEED_STRIDE == 1000
    # every seed of every segment and evaluation lies between the seed and these
    every = [train_env_seed(5, k, i) for k in range(MAX_SEGMENTS) for i in range(4)]
    every += [eval_env_seed(5, i) for i in range(3)]
    assert min(every) == 5 and max(every) == max(derived.values())
    assert "evaluation env 2" in " ".join(derived) and "segment 999" in " ".join(derived)


@pytest.mark.parametrize("n_eval_envs", [1, 2, 5])
def test_the_largest_training_seed(n_eval_envs):
    largest = TRAINING.stop - 1 - EVAL_SEED_OFFSET - (n_eval_envs - 1)
    check_training_seed(0, 1000, n_eval_envs)
    check_training_seed(largest, 1000, n_eval_envs)
    with pytest.raises(SeedProtocolError, match=rf"its evaluation env {n_eval_envs - 1}: .*seed 1000000000 is in no"):
        check_training_seed(largest + 1, 1000, n_eval_envs)


@pytest.mark.parametrize(
    ("seed", "message"),
    [
        (-1, "--seed -1: seed -1 is in no split; training seeds are [0, 1000000000)"),
        (3_000_000_000, "--seed 3000000000: seed 3000000000 is in the test split; training seeds are [0, 1000000000) "
         "(test seeds are for the leaderboard's ranking only)"),
        (3_600_000_000, "--seed 3600000000: seed 3600000000 is in the test2 split"),
        (2_000_000_000, "--seed 2000000000: seed 2000000000 is in the validation split"),
        (999_999_999, "--seed 999999999 (its evaluation env 1: seed + 1000000 + rank): seed 1001000000 is in no split"),
    ],
)  # fmt: skip
def test_a_seed_leaving_the_training_split_is_refused_in_one_line(seed, message):
    with pytest.raises(SeedProtocolError) as info:
        check_training_seed(seed, n_envs=2, n_eval_envs=2, what="--seed")
    assert str(info.value).startswith(message) and "\n" not in str(info.value)
