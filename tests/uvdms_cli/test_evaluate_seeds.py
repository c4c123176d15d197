"""``uvdms evaluate --split`` and ``--seed``: which seeds the episodes use and what the JSON records of them.

The default is the validation split (``uvdms_gym.seeds``): draws ``0..N-1`` are the seeds ``VALIDATION.start + i``;
``--split test|test2`` takes the test draws; ``--seed S`` names the seeds ``S, S+1, ...``, recorded with the split
holding them. The multi-seed folder cases: ``tests/leaderboard/running/test_evaluate_multiseed.py``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from uvdms_cli.evaluate import episode_seeds
from uvdms_cli.main import main
from uvdms_gym.evaluation import evaluate_controller, seed_protocol
from uvdms_gym.seeds import PROTOCOL, TEST, TEST2, VALIDATION, SeedProtocolError

BASE = ["evaluate", "--controller", "hold", "--env", "uvdms/CircleTrack-v1", "--max-episode-steps", "2"]


def _evaluate(tmp_path: Path, *flags: str) -> dict:
    out = tmp_path / "eval.json"
    assert main([*BASE, "--episodes", "2", *flags, "--out", str(out), "--no-progress"]) == 0
    return json.loads(out.read_text())


def _error_line(capsys) -> str:
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


@pytest.mark.parametrize(
    ("flags", "start", "split"),
    [
        ((), VALIDATION.start, "validation"),
        (("--split", "test"), TEST.start, "test"),
        (("--split", "test2"), TEST2.start, "test2"),
    ],
)
def test_the_episodes_are_the_draws_of_the_split_validation_by_default(tmp_path, flags, start, split):
    result = _evaluate(tmp_path, *flags)
    assert [ep["seed"] for ep in result["episodes"]] == [start, start + 1]
    meta = result["meta"]
    assert meta["seeds"] == [start, start + 1] and meta["episodes"] == 2
    assert meta["seed_protocol"] == {"protocol": PROTOCOL, "split": split}
    assert {"controller", "env_id", "env_kwargs", "versions", "git", "wall_s", "timing"} <= set(meta)  # kept


@pytest.mark.parametrize(
    ("seed", "split"),
    [(0, "training"), (VALIDATION.start + 7, "validation"), (1_500_000_000, None), (VALIDATION.stop - 1, None)],
)
def test_an_explicit_seed_records_the_split_holding_the_seeds(tmp_path, seed, split):
    result = _evaluate(tmp_path, "--seed", str(seed))
    assert result["meta"]["seeds"] == [seed, seed + 1]  # the last case straddles validation and test: no one split
    assert result["meta"]["seed_protocol"] == {"protocol": PROTOCOL, "split": split}


def test_seed_and_split_together_are_refused_in_one_line(capsys):
    with pytest.raises(SystemExit) as exc:
        main([*BASE, "--split", "test", "--seed", "3"])
    assert exc.value.code == 2
    line = _error_line(capsys)
    assert "--seed: not allowed with argument --split" in line and "uvdms evaluate --help" in line
    with pytest.raises(SystemExit):
        main([*BASE, "--split", "training"])  # training seeds are not an evaluation split
    assert "invalid choice: 'training'" in _error_line(capsys)


def test_more_draws_than_the_split_holds_is_a_one_line_error(capsys):
    assert main([*BASE, "--split", "test", "--episodes", str(TEST.size + 1), "--no-progress"]) == 2
    assert _error_line(capsys) == f"uvdms: error: the test split holds {TEST.size} seeds, not {TEST.size + 1}"


def test_episode_seeds():
    assert episode_seeds(3) == [VALIDATION.start, VALIDATION.start + 1, VALIDATION.start + 2]
    assert episode_seeds(2, "test2") == [TEST2.start, TEST2.start + 1]
    assert episode_seeds(2, seed=5) == [5, 6]
    with pytest.raises(ValueError, match="--episodes must be >= 1, got 0"):
        episode_seeds(0)
    with pytest.raises(ValueError, match="not both"):
        episode_seeds(1, "test", 5)
    with pytest.raises(SeedProtocolError, match="unknown seed split 'training2'"):
        episode_seeds(1, "training2")


def test_evaluate_controller_takes_explicit_seeds_and_records_their_split():
    from leaderboard.suite.registry import make_controller

    seeds = [TEST.start + 4, TEST.start + 1]
    kwargs = {"action_mode": "velocity", "max_episode_steps": 2}
    result = evaluate_controller(
        lambda env: make_controller("hold", env), "uvdms/CircleTrack-v1", kwargs, 2, seeds=seeds, progress=False
    )
    assert [ep["seed"] for ep in result["episodes"]] == seeds and result["meta"]["seeds"] == seeds
    assert result["meta"]["seed_protocol"] == {"protocol": PROTOCOL, "split": "test"}
    with pytest.raises(ValueError, match="episodes=3 but 2 seeds were given"):
        evaluate_controller(lambda env: None, "uvdms/CircleTrack-v1", kwargs, 3, seeds=seeds, progress=False)
    assert seed_protocol([TEST.start, TEST2.start]) == {"protocol": PROTOCOL, "split": None}  # two splits: none
