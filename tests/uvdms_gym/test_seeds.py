"""The seed protocol (``uvdms_gym/seeds.py``): disjoint split ranges, draws, their assignment, one-line refusals."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from uvdms_gym import seeds
from uvdms_gym.seeds import (
    EVALUATION_SPLITS,
    PROTOCOL,
    SPLITS,
    TEST,
    TEST2,
    TEST_SPLITS,
    TRAINING,
    VALIDATION,
    SeedProtocolError,
    assign_draws,
    check_not_test,
    check_seeds,
    protocol_record,
    seed_range,
    split_of,
    split_seeds,
)


def test_the_ranges_are_disjoint_ordered_and_fit_a_32_bit_seed():
    ranges = list(SPLITS.values())
    assert [r.name for r in ranges] == ["training", "validation", "test", "test2"]
    assert (TRAINING.start, TRAINING.stop) == (0, 1_000_000_000)
    assert (VALIDATION.start, VALIDATION.stop) == (2_000_000_000, 3_000_000_000)
    assert (TEST.start, TEST.stop) == (3_000_000_000, 3_500_000_000)
    assert (TEST2.start, TEST2.stop) == (3_500_000_000, 4_000_000_000)
    for a, b in itertools.combinations(ranges, 2):
        assert a.stop <= b.start or b.stop <= a.start, (a, b)
    assert all(0 <= r.start < r.stop <= 2**32 for r in ranges)
    np.random.default_rng(TEST2.stop - 1)  # the largest seed is a valid numpy seed
    np.random.SeedSequence(TEST2.stop - 1).generate_state(1, dtype=np.uint32)
    assert TRAINING.size == 1_000_000_000 and TEST.size == TEST2.size == 500_000_000
    assert EVALUATION_SPLITS == ("validation", "test", "test2") and TEST_SPLITS == ("test", "test2")
    assert set(EVALUATION_SPLITS) | {"training"} == set(SPLITS)


@pytest.mark.parametrize(
    ("seed", "split"),
    [
        (0, "training"),
        (999_999_999, "training"),
        (1_000_000_000, None),  # between the ranges: no split
        (1_999_999_999, None),
        (2_000_000_000, "validation"),
        (2_999_999_999, "validation"),
        (3_000_000_000, "test"),
        (3_499_999_999, "test"),
        (3_500_000_000, "test2"),
        (3_999_999_999, "test2"),
        (4_000_000_000, None),
        (-1, None),
        (np.int64(3_000_000_001), "test"),  # a numpy integer is a seed too
    ],
)
def test_split_of(seed, split):
    assert split_of(seed) == split


def test_range_membership_is_of_integers_only():
    assert 5 in TRAINING and 5.0 not in TRAINING and "5" not in TRAINING
    assert TEST.start in TEST and TEST.stop not in TEST and TEST.stop in TEST2


def test_split_seeds_are_the_draws_from_the_start_of_the_split():
    for name, rng in SPLITS.items():
        assert split_seeds(name, 3) == [rng.start, rng.start + 1, rng.start + 2]
        assert split_seeds(name, 2, first=5) == [rng.start + 5, rng.start + 6]
        assert split_seeds(name, 0) == []
        assert split_seeds(name, 1, first=rng.size - 1) == [rng.stop - 1]  # the last seed of the range
        with pytest.raises(SeedProtocolError, match=f"the {name} split holds {rng.size} seeds"):
            split_seeds(name, 2, first=rng.size - 1)
        assert {split_of(s) for s in split_seeds(name, 100)} == {name}
    with pytest.raises(SeedProtocolError, match="count >= 0 and first >= 0"):
        split_seeds("test", -1)
    with pytest.raises(SeedProtocolError, match="count >= 0 and first >= 0"):
        split_seeds("test", 1, first=-1)
    with pytest.raises(SeedProtocolError, match="unknown seed split 'nope'; choose from training, validation"):
        split_seeds("nope", 1)
    with pytest.raises(SeedProtocolError):
        seed_range("Test")
    assert issubclass(SeedProtocolError, ValueError)


@pytest.mark.parametrize(("n_draws", "runs"), [(100, 3), (100, 1), (7, 3), (2, 3), (0, 2), (10, 10), (5, 7)])
def test_assign_draws_partitions_the_draws_by_index_modulo_the_runs(n_draws, runs):
    draws = split_seeds("test", n_draws)
    shares = [assign_draws(draws, runs, run) for run in range(runs)]
    assert sorted(itertools.chain.from_iterable(shares)) == draws  # every draw exactly once
    for run, share in enumerate(shares):
        assert share == [d for i, d in enumerate(draws) if i % runs == run]  # draw i to run i % runs, in order
        assert len(share) in (n_draws // runs, -(-n_draws // runs))  # balanced
    if runs == 1:
        assert shares == [draws]


def test_assign_draws_refuses_a_run_out_of_range():
    for runs, run in ((0, 0), (3, 3), (3, -1)):
        with pytest.raises(ValueError, match=rf"run must be in \[0, {runs}\), got {run}"):
            assign_draws([1, 2, 3], runs, run)


def test_check_seeds_names_the_seed_its_split_and_the_allowed_range():
    check_seeds([0, 5, 999_999_999], "training", "training seeds")
    check_seeds(split_seeds("test", 3), "test", "the draws")
    with pytest.raises(SeedProtocolError) as error:
        check_seeds([3, TEST.start + 7], "training", "training seed 3 (its evaluation envs)")
    message = str(error.value)
    assert message == (
        f"training seed 3 (its evaluation envs): seed {TEST.start + 7} is in the test split; training seeds are "
        f"[0, 1000000000) (test seeds are for the leaderboard's ranking only)"
    )
    assert "\n" not in message
    with pytest.raises(SeedProtocolError, match=r"seed 1500000000 is in no split; validation seeds are \[2000000000"):
        check_seeds([1_500_000_000], "validation", "x")
    with pytest.raises(SeedProtocolError, match=r"seed 2000000000 is in the validation split; test seeds") as error:
        check_seeds([VALIDATION.start], "test", "x")
    assert "ranking only" not in str(error.value)  # only a seed of a test split gets the reminder
    with pytest.raises(SeedProtocolError, match="unknown seed split"):
        check_seeds([1], "nope", "x")


def test_check_not_test_refuses_both_test_splits_and_names_the_seed_and_split():
    check_not_test([0, 999_999_999, 1_500_000_000, VALIDATION.start, VALIDATION.stop - 1, 4_000_000_000], "tuning")
    for seed, split in ((TEST.start, "test"), (TEST2.stop - 1, "test2")):
        with pytest.raises(SeedProtocolError) as error:
            check_not_test([1, seed], "uvdms sweep --seeds")
        message = str(error.value)
        assert message.startswith(f"uvdms sweep --seeds: seed {seed} is in the {split} split")
        assert "[0, 1000000000)" in message and "[2000000000, 3000000000)" in message and "\n" not in message


def test_protocol_record():
    assert protocol_record("test") == {"protocol": PROTOCOL, "split": "test"}
    assert protocol_record("validation") == {"protocol": "uvdms-seeds-1", "split": "validation"}
    with pytest.raises(SeedProtocolError, match="unknown seed split"):
        protocol_record("dev")
    assert seeds.PROTOCOL == PROTOCOL
