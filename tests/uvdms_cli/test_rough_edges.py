"""The rough edges a new user met, each now one clear line naming the problem (issue: a house to live in)."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from agents.export import EnvMismatchWarning, load_agent
from uvdms_cli.main import main

REPO = Path(__file__).resolve().parents[2]
SHIPPED_ZIP = REPO / "trained_agents" / "ppo-circle-case1-v0" / "model.zip"


def _error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err  # one line
    assert err[0].startswith("uvdms: error: ")
    return err[0]


def test_a_bad_env_kwarg_value_names_its_key(capsys):
    argv = ["evaluate", "--controller", "campc", "--env", "uvdms/CircleTrack-v1", "--env-kwargs", "radius=abc"]
    assert main(argv) == 2
    line = _error_line(capsys)
    assert "radius='abc'" in line and "float" in line


def test_a_bad_env_kwarg_value_in_train_names_its_key(tmp_path, capsys):
    argv = ["train", "--algo", "sac", "--env", "uvdms/CircleTrack-v1", "--env-kwargs", "hydro_randomization=lots"]
    assert main([*argv, "--total-timesteps", "10", "--out", str(tmp_path)]) == 2
    assert "hydro_randomization='lots'" in _error_line(capsys)
    assert not any(tmp_path.iterdir())  # nothing started, nothing written


@pytest.mark.parametrize("damage", ["truncate", "corrupt"])
def test_a_damaged_model_zip_is_named_as_such(tmp_path, capsys, damage):
    data = bytearray(SHIPPED_ZIP.read_bytes())
    if damage == "truncate":
        data = data[: len(data) // 2]
    else:
        data[30000:30100] = bytes(100)  # inside policy.pth: the zip's directory is intact, a member is not
    bad = tmp_path / "model.zip"
    bad.write_bytes(bytes(data))
    assert main(["evaluate", "--controller", str(bad), "--env", "uvdms/CircleTrack-v0", "--trust"]) == 2
    line = _error_line(capsys)
    assert str(bad) in line and ("corrupt or truncated" in line) and "Error: " not in line.removeprefix("uvdms: error:")


def test_export_agent_without_trust_advises_its_own_flag(tmp_path, capsys):
    outside = tmp_path / "model.zip"
    outside.write_bytes(SHIPPED_ZIP.read_bytes())
    assert main(["export-agent", str(outside), str(tmp_path / "out")]) == 2
    advice = _error_line(capsys).split("contains pickled objects")[1]
    assert "pass --trust" in advice and "export_agent" not in advice and "load_weights_only" not in advice


def test_the_safety_filter_on_a_torque_controller_says_so(capsys):
    argv = ["evaluate", "--controller", "campc-nndi", "--env", "uvdms/CircleTrack-v1", "--safety-filter"]
    assert main([*argv, "--episodes", "1"]) == 2
    line = _error_line(capsys)
    assert "velocity commands" in line and "campc-nndi is a torque-track controller" in line
    assert "action_mode='torque'" not in line


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["evaluate", "--controler", "campc", "--env", "uvdms/CircleTrack-v1"], "--controller"),
        (["evaluate", "--controller", "campc", "--env", "uvdms/CircleTrack-v1", "--episodes", "two"], "'two'"),
        (["train", "--algo", "nope", "--env", "uvdms/CircleTrack-v1"], "'nope'"),
        (["nosuch"], "'nosuch'"),
    ],
)
def test_argument_mistakes_are_one_line(capsys, argv, expected):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    line = _error_line(capsys)
    assert expected in line and "--help" in line


def test_python_m_agents_train_argument_mistake_is_one_line():
    proc = subprocess.run(
        [sys.executable, "-m", "agents.training.train", "--algo", "nope"], capture_output=True, text=True, timeout=120
    )
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and "'nope'" in lines[0], proc.stderr


def test_v0_agent_on_v1_says_only_the_reward_differs():
    agent = load_agent(SHIPPED_ZIP.parent)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert not agent.check_env_id("uvdms/CircleTrack-v1")
        assert not agent.check_env_id("uvdms/Transport-v0")
    same_task, other_task = (str(w.message) for w in caught if w.category is EnvMismatchWarning)
    assert "only the reward differs" in same_task and "mean something else" not in same_task
    assert "mean something else" in other_task


def test_rl_zoo_logs_folder_is_ignored():
    proc = subprocess.run(
        ["git", "check-ignore", "-q", "logs/sac/uvdms-CircleTrack-v0_1/x.zip"], cwd=REPO, capture_output=True
    )
    assert proc.returncode == 0
