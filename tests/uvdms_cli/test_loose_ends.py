"""Issue 37's loose ends of the command line, each one line naming the problem (``uvdms: error: ...``, exit 2)."""

from __future__ import annotations

import argparse
import json

import pytest

from uvdms_cli.main import build_parser, main


def _error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err  # one line
    assert err[0].startswith("uvdms: error: ")
    return err[0]


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    (action,) = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(action.choices)


def _typo(parser: argparse.ArgumentParser) -> tuple[str, str]:
    """A long option of ``parser`` with one letter left out, not a prefix of any of its options."""
    options = [s for a in parser._actions for s in a.option_strings]
    for option in sorted(o for o in options if o.startswith("--") and len(o) >= 6 and o != "--help"):
        typo = option[:-2] + option[-1]
        if not any(o.startswith(typo) for o in options):
            return option, typo
    raise AssertionError(f"no option to misspell in {parser.prog}")


def test_a_misspelt_option_is_named_with_the_option_meant(capsys):
    # argparse said "the following arguments are required: --controller" without naming the typo
    with pytest.raises(SystemExit) as exc:
        main(["evaluate", "--controler", "campc", "--env", "uvdms/CircleTrack-v1"])
    assert exc.value.code == 2
    line = _error_line(capsys)
    assert "unrecognized arguments: --controler (did you mean --controller?)" in line
    assert "(see uvdms evaluate --help)" in line


@pytest.mark.parametrize("command", sorted(_subcommands()))
def test_every_subcommand_names_a_misspelt_option(command, capsys):
    option, typo = _typo(_subcommands()[command])
    with pytest.raises(SystemExit) as exc:
        main([command, typo])
    assert exc.value.code == 2
    assert f"unrecognized arguments: {typo} (did you mean {option}" in _error_line(capsys)


def test_a_misspelt_option_after_valid_ones_is_named_too(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--controller", "campc", "--env", "uvdms/CircleTrack-v1", "--epsiodes", "2"])
    assert "unrecognized arguments: --epsiodes (did you mean --episodes?)" in _error_line(capsys)


def test_negative_numbers_and_abbreviations_are_not_typos(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--controller", "campc", "--env", "uvdms/CircleTrack-v1", "--seed", "-1", "--episodes", "x"])
    line = _error_line(capsys)
    assert "invalid int value: 'x'" in line and "unrecognized" not in line
    with pytest.raises(SystemExit):  # an abbreviation argparse accepts: its own error, not a typo
        main(["evaluate", "--controller", "campc", "--env", "uvdms/CircleTrack-v1", "--epi", "x"])
    line = _error_line(capsys)
    assert "argument --episodes: invalid int value: 'x'" in line and "unrecognized" not in line
    with pytest.raises(SystemExit):  # bundled short flags are not a typo either
        main(["-vv", "evalute"])
    line = _error_line(capsys)
    assert "invalid choice: 'evalute'" in line and "unrecognized" not in line


@pytest.mark.parametrize(
    ("kwarg", "expected"),
    [
        ("left_center=abc", "--env-kwargs left_center='abc': expected a sequence of 3 floats or None"),
        ("radius=[1,2]", "--env-kwargs radius=[1, 2]: expected a float or None"),
        ("max_episode_steps=abc", "--env-kwargs max_episode_steps='abc': expected an integer or None"),
    ],
)
def test_an_env_kwarg_of_the_wrong_type_names_its_key_and_type(kwarg, expected, capsys):
    argv = ["evaluate", "--controller", "hold", "--env", "uvdms/CircleTrack-v1", "--episodes", "1"]
    assert main([*argv, "--no-progress", "--env-kwargs", kwarg]) == 2
    assert _error_line(capsys) == f"uvdms: error: {expected}"


def test_env_kwargs_of_the_right_types_pass():
    from uvdms_gym.utils.kwargs import check_make_kwargs

    good = {"left_center": [0.1, 0.2, 0.3], "radius": 0.2, "max_episode_steps": 5, "case": 2, "current": "none"}
    check_make_kwargs("uvdms/CircleTrack-v1", good, "--env-kwargs")
    check_make_kwargs("uvdms/Transport-v1", {"start_pose": [0.0] * 6, "goal": "random"}, "--env-kwargs")


@pytest.mark.parametrize("command", ["evaluate", "train"])
def test_an_unknown_id_lists_every_registered_uvdms_id(command, capsys):
    import gymnasium as gym

    ids = [env_id for env_id, spec in gym.registry.items() if spec.namespace == "uvdms"]
    assert "uvdms/TransportObstacles-v1" in ids
    argv = {"evaluate": ["--controller", "hold"], "train": ["--algo", "sac", "--total-timesteps", "10"]}[command]
    assert main([command, *argv, "--env", "uvdms/Nope-v1"]) == 2
    line = _error_line(capsys)
    assert all(env_id in line for env_id in ids), line


def test_evaluate_and_leaderboard_word_a_wrong_folder_alike(tmp_path, capsys):
    empty, missing = tmp_path / "empty", tmp_path / "missing"
    empty.mkdir()
    lines = {}
    for folder in (empty, missing):
        assert main(["evaluate", "--controller", str(folder), "--env", "uvdms/CircleTrack-v1", "--episodes", "1"]) == 2
        evaluate = _error_line(capsys)
        argv = ["leaderboard", "--entries", str(folder), "--tasks", "case1", "--episodes", "1"]
        assert main([*argv, "--out", str(tmp_path / "out"), "--no-progress", "--no-plots"]) == 2
        lines[folder] = (evaluate, _error_line(capsys))
    assert lines[empty][0] == lines[empty][1]  # the same words for the same folder
    assert "is not an agent folder: it holds none of agent.json" in lines[empty][0]
    common = f"{str(missing)!r} is neither a baseline (mpc, "
    tail = "nor an existing agent folder or checkpoint"
    assert all(common in line and line.endswith(tail) for line in lines[missing])


def test_evaluate_cuts_episodes_with_max_episode_steps_as_leaderboard_does(tmp_path, capsys):
    argv = ["evaluate", "--controller", "hold", "--env", "uvdms/CircleTrack-v1", "--episodes", "1", "--no-progress"]
    out = tmp_path / "eval.json"
    assert main([*argv, "--max-episode-steps", "3", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["summary"]["steps"] == 3
    capsys.readouterr()
    for command in (argv, ["leaderboard", "--entries", "hold", "--tasks", "case1", "--out", str(tmp_path / "lb")]):
        assert main([*command, "--max-episode-steps", "0"]) == 2
        assert _error_line(capsys) == "uvdms: error: --max-episode-steps must be >= 1, got 0"
    assert main([*argv, "--max-episode-steps", "3", "--env-kwargs", "max_episode_steps=5"]) == 2
    assert _error_line(capsys) == (
        "uvdms: error: --max-episode-steps 3 and --env-kwargs max_episode_steps=5 disagree; give one of them"
    )
    assert main([*argv, "--max-episode-steps", "3", "--env-kwargs", "max_episode_steps=3", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["summary"]["steps"] == 3


def test_export_of_a_best_model_a_run_never_wrote_says_what_to_do(tmp_path, capsys):
    run = tmp_path / "runs" / "sac_0"
    run.mkdir(parents=True)
    (run / "final_model.zip").write_bytes(b"")  # a short run: its final model, no evaluation, so no best model
    assert main(["export-agent", str(run), str(tmp_path / "out"), "--which", "best", "--trust"]) == 2
    line = _error_line(capsys)
    assert f"no model at {run / 'best_model.zip'}: a run writes best_model.zip at its evaluations" in line
    assert "--which final" in line
