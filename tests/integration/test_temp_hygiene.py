"""Commands and the library leave nothing in the system temp directory.

SB3 makes an empty ``SB3-<date>`` folder per model that learns without a configured logger (``uvdms bench train``
made ~35); the simulator's URDF files live in a per-process folder removed at exit, also in ``SubprocVecEnv``
workers (which end with ``os._exit``: they left one folder each) and killed processes
(:mod:`uvdms_gym.utils.tempdirs`); so do the agent files a Ray worker writes (``uvdms-agent-<pid>-*``), also when
the worker is killed. The one folder that may appear is torch's own compilation cache (``torchinductor_<user>``, made
by torch's Adam on its first step, reused).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest

from tests.support.ray_cluster import in_background, kill_when

pytestmark = pytest.mark.slow  # a process (a Ray instance) per test

REPO = Path(__file__).resolve().parents[2]

SCRIPT = textwrap.dedent(
    """
    import gymnasium as gym
    import uvdms_gym
    from agents.training.bench import _block, _build

    env = gym.make("uvdms/Transport-v1")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    env.close()
    for algo in ("ppo", "sac"):
        model = _build(algo, 1, "dummy", 64)
        assert _block(model, 32 if algo == "sac" else 64)[0] > 0
        model.get_env().close()
    print("ok")
    """
)


SUBPROC_SCRIPT = textwrap.dedent(
    """
    import os, signal, sys
    from agents.training.bench import _block, _build

    model = _build("ppo", 2, "subproc", 64)
    assert _block(model, 64)[0] > 0
    pids = [p.pid for p in model.get_env().unwrapped.processes]
    model.get_env().close()
    print("ok", *pids)
    """
)


@pytest.fixture
def short_temp() -> Iterator[Path]:
    """A temporary folder with a short path: the forkserver's socket lives in TMPDIR, and an AF_UNIX path holds at
    most 107 bytes (pytest's ``tmp_path`` under xdist is longer)."""
    folder = Path(tempfile.mkdtemp(prefix="uvh-", dir="/tmp"))
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


def _run_with_temp(script: str, temp) -> str:
    temp.mkdir(exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k != "SB3_LOGDIR"}  # SB3 would fall back to the temp directory
    env["TMPDIR"] = str(temp)
    proc = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and "ok" in proc.stdout, proc.stderr[-2000:]
    return proc.stdout


def _left(temp) -> list[str]:
    return sorted(p.name for p in temp.iterdir() if not p.name.startswith("torchinductor_"))


def test_an_env_and_bench_train_models_leave_the_temp_directory_as_they_found_it(tmp_path):
    temp = tmp_path / "system_temp"
    _run_with_temp(SCRIPT, temp)
    assert _left(temp) == []


def test_a_two_worker_subprocess_model_leaves_the_temp_directory_as_it_found_it(short_temp):
    temp = short_temp / "t"
    _run_with_temp(SUBPROC_SCRIPT, temp)
    assert _left(temp) == []


def test_a_killed_process_urdf_folder_is_removed_by_the_next_sweep(tmp_path):
    """A worker given SIGKILL runs no exit code: its folder goes at the next sweep (a new folder, an exit)."""
    temp = tmp_path / "system_temp"
    killed = textwrap.dedent(
        """
        import os, signal
        from uvdms_gym.physics import model

        model._cache_dir()
        print("ok")
        os.kill(os.getpid(), signal.SIGKILL)
        """
    )
    env = {**os.environ, "TMPDIR": str(temp)}
    temp.mkdir()
    proc = subprocess.run([sys.executable, "-c", killed], env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == -9 and _left(temp) != []  # killed: its folder is there
    _run_with_temp("from uvdms_gym.physics import model\nmodel._cache_dir()\nprint('ok')", temp)
    assert _left(temp) == []


@pytest.mark.slow
def test_a_killed_ray_worker_leaves_no_agent_folder(tmp_path, ray_processes, monkeypatch):
    import leaderboard as lb

    temp = tmp_path / "system_temp"
    temp.mkdir()
    monkeypatch.setenv("RAY_TMPDIR", os.environ.get("RAY_TMPDIR", tempfile.gettempdir()))  # Ray's session: as ever
    monkeypatch.setenv("TMPDIR", str(temp))  # the workers' temporary directory
    monkeypatch.setattr(tempfile, "tempdir", str(temp))  # the driver's (tempfile caches it)
    entries = lb.resolve_entries([str(REPO / "trained_agents" / "sac-circle-case1-v0")])
    tasks = [replace(t, max_episode_steps=300) for t in lb.TASKS if t.name == "case1"]
    thread, outcome = in_background(
        lambda: lb.run_leaderboard(
            entries,
            out_dir=tmp_path / "out",
            tasks=tasks,
            episodes=1,
            executor="ray",
            num_cpus=1,
            progress=False,
            plots=False,
        )
    )
    # kill the episode's worker once it has written the agent's files
    killed = kill_when("ray::episode ", thread, ready=lambda: any(temp.glob("uvdms-agent-*")))
    thread.join(timeout=400)
    assert "error" not in outcome, outcome.get("error")
    assert killed is not None, "no episode was seen running with its agent folder: nothing was killed"
    assert outcome["result"].computed == 1  # the episode was retried in another worker
    assert sorted(p.name for p in temp.glob("uvdms-agent-*")) == []
