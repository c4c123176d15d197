"""Two leaderboards into one output folder: the second refuses in one line (exit 2) instead of computing it all again.

The lock is held by another process (as a second ``uvdms leaderboard`` would meet it); a lock file left by a process
that died does not block; after a run the lock is free and its file gone.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from leaderboard.running.lock import LOCK_NAME, OutputFolderInUseError, output_lock
from tests.support.leaderboard_fakes import CALLS, _run
from uvdms_cli.main import main as uvdms_main

HOLD = """
import sys
from leaderboard.running.lock import output_lock
with output_lock(sys.argv[1]):
    print("locked", flush=True)
    sys.stdin.read()
"""


@pytest.fixture
def held(tmp_path):
    """The output folder ``tmp_path / "out"``, locked by another process until the test ends; yields its pid."""
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(tmp_path / "out")], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        yield holder.pid
    finally:
        holder.stdin.close()
        holder.wait(timeout=60)
    assert holder.returncode == 0


def test_a_second_leaderboard_into_a_folder_in_use_refuses_in_one_line(tmp_path, held, capsys):
    argv = ["leaderboard", "--entries", "hold", "--tasks", "case1", "--episodes", "1", "--max-episode-steps", "2"]
    status = uvdms_main([*argv, "--no-plots", "--no-progress", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2
    assert err.count("\n") == 1 and err.startswith("uvdms: error: ")
    assert f"in use by another uvdms leaderboard (pid {held})" in err and str(tmp_path / "out") in err
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [LOCK_NAME]  # nothing computed, nothing written


def test_the_library_raises_and_computes_nothing(tmp_path, held):
    CALLS.clear()
    with pytest.raises(OutputFolderInUseError, match=f"pid {held}"):
        _run(tmp_path)
    assert CALLS == []


def test_a_lock_left_by_a_dead_process_does_not_block(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / LOCK_NAME).write_text(dead.stdout)  # its pid, but no process holds the lock any more
    result = _run(tmp_path)
    assert result.computed == len(CALLS) > 0
    assert not (tmp_path / "out" / LOCK_NAME).exists()  # released and removed
    with output_lock(tmp_path / "out"):  # free again
        pass
