"""The ``uvdms`` command's first hour: one-line errors, no display, render metadata, timing provenance, --version.

The error cases run the real ``uvdms`` console script (next to ``sys.executable``) in a subprocess, with this
checkout first on ``PYTHONPATH``: what a user types, including the exit status and everything on stderr.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import socket
import subprocess
import sys
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import uvdms_gym  # noqa: F401  (registers the ids)
from uvdms_cli.main import main as uvdms_main
from uvdms_gym.utils import display, provenance

REPO = Path(__file__).resolve().parents[2]
UVDMS = Path(sys.executable).parent / "uvdms"
CIRCLE, TRANSPORT = "uvdms/CircleTrack-v0", "uvdms/Transport-v0"
SHIPPED = REPO / "trained_agents" / "ppo-circle-case1-v0"


def run_uvdms(args: list[str], cwd: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """Run the installed ``uvdms`` script on this checkout (headless: no ``DISPLAY``)."""
    environ = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "UVDMS_DEBUG")}
    environ["PYTHONPATH"] = os.pathsep.join([str(REPO), environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    environ.update(env or {})
    return subprocess.run(
        [str(UVDMS), *args], cwd=cwd, env=environ, capture_output=True, text=True, timeout=300, check=False
    )


@pytest.fixture
def workspace(tmp_path) -> Path:
    """A working directory with a corrupt zip, a truncated zip, an empty folder and a non-empty folder."""
    root = tmp_path
    (root / "corrupt.zip").write_bytes(b"this is not a zip archive")
    (root / "truncated.zip").write_bytes((SHIPPED / "model.zip").read_bytes()[:1000])
    (root / "empty").mkdir()
    (root / "occupied").mkdir()
    (root / "occupied" / "agent.json").write_text("{}")
    return root


# (argv, words the one-line message must contain); every case must exit 2 with exactly one stderr line
ERROR_CASES: dict[str, tuple[list[str], tuple[str, ...]]] = {
    "evaluate-unknown-env": (["evaluate", "--controller", "campc", "--env", "uvdms/Foo-v0"], ("uvdms/Foo-v0", CIRCLE)),
    "evaluate-unknown-kwarg": (
        ["evaluate", "--controller", "campc", "--env", CIRCLE, "--env-kwargs", "foo=1"],
        ("'foo'", "case"),
    ),
    "evaluate-bad-case": (["evaluate", "--controller", "campc", "--env", CIRCLE, "--env-kwargs", "case=7"], ("7",)),
    "evaluate-bad-yaml": (
        ["evaluate", "--controller", "campc", "--env", CIRCLE, "--env-kwargs", "case=[1"],
        ("--env-kwargs", "'case'", "YAML"),
    ),
    "evaluate-not-key-value": (
        ["evaluate", "--controller", "campc", "--env", CIRCLE, "--env-kwargs", "case"],
        ("key=value", "'case'"),
    ),
    "evaluate-zero-episodes": (
        ["evaluate", "--controller", "campc", "--env", CIRCLE, "--episodes", "0"],
        ("episodes",),
    ),
    "evaluate-unknown-controller": (["evaluate", "--controller", "nope", "--env", CIRCLE], ("'nope'", "campc")),
    "evaluate-wrong-action-mode": (
        ["evaluate", "--controller", "campc", "--env", CIRCLE, "--env-kwargs", "action_mode=torque"],
        ("action_mode",),
    ),
    "evaluate-corrupt-zip": (
        ["evaluate", "--controller", "corrupt.zip", "--env", CIRCLE, "--trust"],
        ("corrupt.zip", "zip"),
    ),
    "evaluate-untrusted-zip": (["evaluate", "--controller", "corrupt.zip", "--env", CIRCLE], ("--trust",)),
    "evaluate-empty-folder": (["evaluate", "--controller", "empty", "--env", CIRCLE], ("empty", "not an agent")),
    "train-unknown-kwarg": (["train", "--algo", "ppo", "--env", CIRCLE, "--env-kwargs", "foo=1"], ("'foo'",)),
    "train-bad-case": (
        ["train", "--algo", "ppo", "--env", CIRCLE, "--env-kwargs", "case=7", "max_episode_steps=5"],
        ("7",),
    ),
    "train-bad-yaml": (["train", "--algo", "ppo", "--env", CIRCLE, "--env-kwargs", "case=[1"], ("'case'", "YAML")),
    "train-bad-hyperparams": (
        ["train", "--algo", "ppo", "--env", CIRCLE, "--hyperparams", "learning_rate=[1"],
        ("--hyperparams", "YAML"),
    ),
    "train-unknown-env": (["train", "--algo", "ppo", "--env", "uvdms/Foo-v0"], ("uvdms/Foo-v0",)),
    "export-corrupt-zip": (["export-agent", "corrupt.zip", "exported", "--trust"], ("corrupt.zip", "zip")),
    "export-truncated-zip": (["export-agent", "truncated.zip", "exported", "--trust"], ("truncated.zip", "zip")),
    "export-untrusted": (["export-agent", "corrupt.zip", "exported"], ("--trust",)),
    "export-into-occupied-folder": (["export-agent", str(SHIPPED), "occupied"], ("occupied", "--overwrite")),
    "leaderboard-corrupt-zip": (
        ["leaderboard", "--entries", "corrupt.zip", "--trust", "--out", "lb"],
        ("corrupt.zip", "zip"),
    ),
    "leaderboard-untrusted-zip": (["leaderboard", "--entries", "corrupt.zip", "--out", "lb"], ("--trust",)),
    "leaderboard-empty-folder": (["leaderboard", "--entries", "empty", "--out", "lb"], ("empty", "not an agent")),
    "leaderboard-unknown-task": (["leaderboard", "--tasks", "nope", "--out", "lb"], ("'nope'", "case1")),
    "leaderboard-bad-steps": (["leaderboard", "--max-episode-steps", "0", "--out", "lb"], ("--max-episode-steps",)),
    "demo-png-missing-folder": (["demo", "--png", "missing/frame.png", "--seconds", "0.1"], ("missing",)),
    "demo-negative-seconds": (["demo", "--seconds", "-1"], ("seconds", "-1")),
    "demo-gui-headless": (["demo", "--gui", "--seconds", "0.1"], ("display", "--png")),
}


@pytest.mark.slow  # a uvdms process per case
@pytest.mark.parametrize("case", sorted(ERROR_CASES))
def test_user_errors_are_one_line_with_exit_status_2(case, workspace):
    argv, words = ERROR_CASES[case]
    proc = run_uvdms(argv, cwd=workspace)
    lines = proc.stderr.splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("uvdms: error: "), lines[0]
    assert "Traceback" not in proc.stderr and "trust=True" not in lines[0]
    for word in words:
        assert word in lines[0], (word, lines[0])
    assert not (workspace / "lb").exists() and not (workspace / "exported").exists()
    # train checks names and YAML before creating a run directory; a value only the environment can judge
    # (case=7) fails after it exists, and the failed fresh run removes it again, so the seed is not blocked
    runs = workspace / "runs"
    assert not runs.exists() or not any(p.is_dir() for p in runs.glob("*/*")), sorted(runs.rglob("*"))


def test_debug_keeps_the_traceback(workspace):
    for args, env in (
        (["--debug", "demo", "--seconds", "-1"], None),
        (["demo", "--seconds", "-1"], {"UVDMS_DEBUG": "1"}),
    ):
        proc = run_uvdms(args, cwd=workspace, env=env)
        assert proc.returncode == 1
        assert "Traceback" in proc.stderr and "ValueError: seconds" in proc.stderr


def test_demo_saves_a_frame_and_prints_the_trace(workspace):
    proc = run_uvdms(["demo", "--seconds", "0.2", "--trace-every", "0.1", "--png", "frame.png"], cwd=workspace)
    assert proc.returncode == 0, proc.stderr
    assert (workspace / "frame.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = proc.stdout.strip().splitlines()
    assert rows[0].split()[:2] == ["t", "[s]"] and len(rows) == 1 + 3  # t = 0, 0.1, 0.2
    assert "pybullet build time" not in proc.stderr  # the import line is silenced


def test_version_is_the_running_codes(workspace):
    """``uvdms --version`` names the code that runs, as the package's ``__init__`` states it (an editable install's
    metadata keeps the version it was installed at)."""
    init = (provenance.REPO_ROOT / "uvdms_gym" / "__init__.py").read_text()
    (stated,) = re.findall(r'^__version__ = "([^"]+)"$', init, flags=re.M)
    proc = run_uvdms(["--version"], cwd=workspace)
    assert proc.returncode == 0
    assert proc.stdout.strip() == f"uvdms {stated}"
    assert provenance.package_versions()["uvdms_gym"] == stated  # what every run's meta.json records


# ------------------------------------------------------------------------------------------------------
# No display
# ------------------------------------------------------------------------------------------------------
def test_gui_without_a_display_raises_instead_of_exiting(tmp_path):
    """PyBullet's GUI connect would call exit(1) here; the simulator raises a catchable exception instead."""
    code = (
        "from uvdms_gym.utils.display import DisplayUnavailableError\n"
        "from uvdms_gym.physics.sim import UVDMSSim\n"
        "try:\n"
        "    UVDMSSim(gui=True)\n"
        "except DisplayUnavailableError as exc:\n"
        "    print('caught:', exc)\n"
        "print('alive')\n"
    )
    for display_value in ("", ":87"):  # no $DISPLAY; a $DISPLAY nobody serves
        environ = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
        environ["PYTHONPATH"] = str(REPO)
        if display_value:
            environ["DISPLAY"] = display_value
        proc = subprocess.run(
            [sys.executable, "-c", code], cwd=tmp_path, env=environ, capture_output=True, text=True, timeout=120
        )
        assert proc.returncode == 0, proc.stderr
        assert "caught: PyBullet's GUI cannot open" in proc.stdout and proc.stdout.rstrip().endswith("alive")


@pytest.mark.filterwarnings("ignore:.*is different from the unwrapped version")
@pytest.mark.parametrize("env_id", [CIRCLE, TRANSPORT])
def test_check_env_with_default_arguments_passes_headless(env_id, monkeypatch):
    from gymnasium.utils.env_checker import check_env

    monkeypatch.delenv("DISPLAY", raising=False)
    env = gym.make(env_id, max_episode_steps=5)
    try:
        assert env.metadata["render_modes"] == ["rgb_array"]  # "human" is not offered without a display
        check_env(env)  # includes the render sweep over metadata["render_modes"]
        check_env(env.unwrapped)
    finally:
        env.close()
    with pytest.raises(display.DisplayUnavailableError, match="rgb_array"):
        gym.make(env_id, render_mode="human")
    assert "human" in type(env.unwrapped).metadata["render_modes"]  # the class still declares it


def test_display_probe(tmp_path):
    assert display.gui_unavailable_reason({}, "linux") is not None
    assert display.gui_unavailable_reason({}, "darwin") is None  # native window, no X server
    assert display.gui_unavailable_reason({}, "win32") is None
    assert "form" in display.gui_unavailable_reason({"DISPLAY": "garbage"}, "linux")
    # an X server is simulated by a listening socket: the probe only needs a connection
    path = str(tmp_path / "X0")
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as server:
        server.bind(path)
        server.listen(1)
        assert display.gui_unavailable_reason({"DISPLAY": f"{path}:0"}, "linux") is None
    assert display.gui_unavailable_reason({"DISPLAY": f"{path}:0"}, "linux") is not None  # closed
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as server:
        server.bind(("127.0.0.1", 0))
        port = server.getsockname()[1]
        server.listen(1)
        if port <= 6000:  # X displays are ports 6000 + N; Linux's ephemeral ports start far above
            pytest.skip(f"ephemeral port {port} below 6000")
        remote = f"127.0.0.1:{port - 6000}"
        assert display.gui_unavailable_reason({"DISPLAY": remote + ".0"}, "linux") is None
    reason = display.gui_unavailable_reason({"DISPLAY": remote}, "linux")  # closed again
    assert reason is not None and str(port) in reason


@pytest.mark.parametrize("control_dt", [0.04, 0.02, 0.1])
def test_render_fps_follows_control_dt(control_dt):
    env = gym.make(CIRCLE, control_dt=control_dt, render_mode="rgb_array")
    try:
        assert env.metadata["render_fps"] == pytest.approx(1.0 / control_dt)
        assert env.unwrapped.metadata is not type(env.unwrapped).metadata  # per instance, the class is untouched
        assert type(env.unwrapped).metadata["render_fps"] == 25
        env.reset(seed=0)
        t0 = env.unwrapped.t
        env.step(np.zeros(18, np.float32))
        frames_per_second = 1.0 / (env.unwrapped.t - t0)  # one rendered frame per step
        assert env.metadata["render_fps"] == pytest.approx(frames_per_second)
    finally:
        env.close()


# ------------------------------------------------------------------------------------------------------
# Timing provenance
# ------------------------------------------------------------------------------------------------------
def test_timing_record_reports_machine_and_load(monkeypatch):
    loads = iter([0.5, 3.5])
    monkeypatch.setattr(provenance, "load_average", lambda: next(loads))
    with provenance.timing_record() as record:
        assert "load_1min_end" not in record
    machine = record["machine"]
    assert machine["cpu_count"] == os.cpu_count() and machine["cpu_model"]
    assert (record["load_1min_start"], record["load_1min_end"]) == (0.5, 3.5)
    assert record["overloaded"] is (3.5 > os.cpu_count())
    assert provenance.is_overloaded({"machine": {"cpu_count": 2}, "load_1min_start": 1.0, "load_1min_end": 2.5})
    assert not provenance.is_overloaded({"machine": {"cpu_count": 2}, "load_1min_start": 2.0, "load_1min_end": 1})
    assert provenance.is_overloaded({"machine": {"cpu_count": 2}, "load_1min_start": None}) is None
    monkeypatch.undo()
    assert provenance.load_average() == pytest.approx(os.getloadavg()[0], abs=0.5)


def test_bench_json_records_machine_and_load(monkeypatch, capsys):
    from uvdms_cli import bench

    monkeypatch.setattr(bench, "bench_sim", lambda quick: {"physics_step_us": 1.0})
    monkeypatch.setattr(provenance, "load_average", lambda: 99.0)
    assert uvdms_main(["bench", "sim", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["physics_step_us"] == 1.0
    assert doc["timing"]["load_1min_start"] == doc["timing"]["load_1min_end"] == 99.0
    assert doc["timing"]["machine"]["cpu_count"] == os.cpu_count()
    assert doc["timing"]["overloaded"] is (99.0 > os.cpu_count())


def test_evaluate_json_records_machine_and_load(tmp_path):
    from leaderboard.running.evaluate import evaluate

    result = evaluate("campc", CIRCLE, {"max_episode_steps": 3}, episodes=1, out=str(tmp_path / "e.json"))
    timing = json.loads((tmp_path / "e.json").read_text())["meta"]["timing"]
    assert timing == result["meta"]["timing"]
    assert set(timing) == {"machine", "load_1min_start", "load_1min_end", "overloaded"}
    assert timing["machine"]["cpu_count"] == os.cpu_count()


class _FakeEnv:
    def close(self):
        pass


def _fake_episode(env, controller, seed, save_trajectory):
    return {
        "seed": seed,
        "contacts": 0,
        "success": True,
        "rmse_pos": 0.001,
        "min_distance": 0.1,
        "steps": 3,
        "controller_ms_median": 1.5,
    }


@pytest.mark.parametrize("load, marked", [(0.0, False), (1000.0, True)])
def test_leaderboard_marks_timings_taken_under_overload(load, marked, tmp_path, monkeypatch):
    import leaderboard as lb
    from leaderboard.running.jobs import Backend
    from leaderboard.stats.metrics import OVERLOAD_MARK

    backend = Backend(make_env=lambda spec: _FakeEnv(), make_controller=lambda s, e, t: None, run_episode=_fake_episode)
    monkeypatch.setattr(provenance, "load_average", lambda: load)
    # a randomised task: 2 draws per entry, and 2 of the generalisation check's second test set
    tasks = (lb.Task("circle-random", "Random circles", CIRCLE, {"case": "random"}, paper=False, max_episode_steps=3),)
    entries = lb.resolve_entries(["campc", "mpc"])
    result = lb.run_leaderboard(
        entries, out_dir=tmp_path, tasks=tasks, episodes=2, backend=backend, progress=False, plots=False
    )
    md = (tmp_path / "leaderboard.md").read_text()
    rows = list(csv.DictReader(io.StringIO((tmp_path / "leaderboard.csv").read_text())))
    assert len(rows) == 2
    for row in rows:
        assert int(row["timing_episodes_overloaded"]) == (2 if marked else 0)
        assert float(row["timing_load_1min_max"]) == load
        assert f"({os.cpu_count()} cores)" in row["timing_machine"]
    assert (f"1.50 ± 0.00 {OVERLOAD_MARK}" in md) is marked
    assert f"{2 * marked * 2} of 4 episodes ran with a load above the core count" in md
    cached = [json.loads(p.read_text())["result"]["timing"] for p in (tmp_path / "cache").rglob("*.json")]
    assert len(cached) == 2 * 2 * 2 and all(c["overloaded"] is marked for c in cached)  # the check's episodes too
    assert result.timing["load_1min_start"] == load


def test_corrupt_archives_are_named_before_any_episode(workspace):
    import leaderboard as lb

    with pytest.raises(ValueError, match=r"truncated\.zip"):
        lb.resolve_entries([str(workspace / "truncated.zip")], trust=True)
    assert zipfile.is_zipfile(SHIPPED / "model.zip")
    assert lb.resolve_entries([str(SHIPPED)])[0].kind == "agent"  # a valid shipped agent still resolves


def test_make_kwargs_are_checked_against_the_entry_points_signature():
    from uvdms_gym.utils.kwargs import check_make_kwargs, parse_kv

    check_make_kwargs(CIRCLE, {"case": 1, "control_dt": 0.02, "max_episode_steps": 5})  # subclass and base keys
    check_make_kwargs("uvdms_gym:" + TRANSPORT, {"goal": "paper", "hydro_randomization": 0.3})
    check_make_kwargs("Pendulum-v1", {"g": 9.81, "render_mode": "rgb_array"})
    with pytest.raises(ValueError, match="'goal'"):
        check_make_kwargs(CIRCLE, {"goal": "paper"})  # a Transport keyword
    with pytest.raises(ValueError, match="'foo'"):
        check_make_kwargs("Pendulum-v1", {"foo": 1})
    with pytest.raises(ValueError, match="uvdms/CircleTrack-v0"):
        check_make_kwargs("uvdms/Circle-v0", {})
    assert parse_kv(["case=1", "radius=0.15", "goal=random", "left_center=[1, 0, 2]", "name="]) == {
        "case": 1,
        "radius": 0.15,
        "goal": "random",
        "left_center": [1, 0, 2],
        "name": "",
    }
    with pytest.raises(ValueError, match="not a YAML literal"):
        parse_kv(["radius={"])
