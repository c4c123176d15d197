"""Private temporary folders that do not outlive their process, also a worker process or a killed one.

A folder from :func:`owned_tempdir` is named ``<prefix><pid>-<random>`` after the process that made it, and removed

* when that process exits normally: an interpreter's exit, and also a ``multiprocessing`` worker's, which ends with
  ``os._exit`` and so skips ``atexit`` and ``weakref.finalize`` (``SubprocVecEnv`` workers left one URDF folder each
  that way); the removal is registered with :class:`multiprocessing.util.Finalize`, which both run;
* otherwise (the process was killed: a Ray worker at ``ray.shutdown`` or by a test, a worker given ``SIGKILL``) by
  :func:`sweep_stale`, which removes the folders of a prefix whose process has ended. It runs when a process makes
  such a folder and when it exits (after its ``multiprocessing`` children have ended), and where a driver knows that
  its workers ended (:func:`leaderboard.running.distributed.run_on_ray` after its Ray session).

Only folders of the calling user are swept; a process id reused by an unrelated process keeps its folder until
that process ends. A process id is read in the caller's PID namespace: processes of other namespaces (containers)
that share the temporary directory and the user should each have a temporary directory of their own (``TMPDIR``).
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Collection
from multiprocessing.util import Finalize
from pathlib import Path

_SWEEPING: set[tuple[str, int]] = set()
"""(prefix, process id) of the sweeps at exit registered here."""


def owned_tempdir(prefix: str) -> Path:
    """A new folder ``<prefix><pid>-<random>`` in the temporary directory, removed when this process ends.

    Args:
        prefix: The folder name's start, e.g. ``uvdms_gym_urdf-``.
    """
    sweep_stale(prefix)
    pid = os.getpid()
    path = Path(tempfile.mkdtemp(prefix=f"{prefix}{pid}-"))
    Finalize(None, _remove_own, args=(str(path), pid), exitpriority=0)
    if (prefix, pid) not in _SWEEPING:
        _SWEEPING.add((prefix, pid))  # after the children have been joined (multiprocessing's exit runs -1 later)
        Finalize(None, _sweep_own, args=(prefix, pid), exitpriority=-1)
    return path


def _remove_own(path: str, pid: int) -> None:
    """Remove ``path`` in the process that made it only (a forked child inherits the finaliser)."""
    if os.getpid() == pid:
        shutil.rmtree(path, ignore_errors=True)


def _sweep_own(prefix: str, pid: int) -> None:
    if os.getpid() == pid:
        sweep_stale(prefix)


def _owner(path: Path, prefix: str) -> int | None:
    pid = path.name[len(prefix) :].split("-", 1)[0]
    return int(pid) if pid.isdigit() else None


def process_ended(pid: int) -> bool:
    """Whether process ``pid`` has ended (a zombie, ended but not yet reaped, counts as ended)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:
        return False
    try:
        with open(f"/proc/{pid}/stat", encoding="utf-8", errors="replace") as f:
            return f.read().rsplit(")", 1)[1].split()[0] == "Z"
    except (OSError, IndexError):
        return False


def sweep_stale(prefix: str, *, wait: float = 0.0, not_waiting_for: Collection[str] = ()) -> list[Path]:
    """Remove this user's ``<prefix><pid>-*`` folders of the temporary directory whose process has ended.

    Args:
        prefix: As for :func:`owned_tempdir`.
        wait: Seconds to wait for the owners still running to end (a driver after shutting its workers down).
        not_waiting_for: Names of folders not to wait for (those that existed before the driver's workers started:
            another run's); they are removed only if their owner has already ended.

    Returns:
        The folders removed.
    """
    deadline = time.monotonic() + wait
    removed: list[Path] = []
    while True:
        waiting = False
        for path in Path(tempfile.gettempdir()).glob(f"{prefix}*"):
            pid = _owner(path, prefix)
            if pid is None or pid == os.getpid() or not _mine(path):
                continue
            if process_ended(pid):
                shutil.rmtree(path, ignore_errors=True)
                removed.append(path)
            elif path.name not in not_waiting_for:
                waiting = True
        if not waiting or time.monotonic() >= deadline:
            return removed
        time.sleep(0.1)


def _mine(path: Path) -> bool:
    try:
        return path.stat().st_uid == os.getuid()
    except OSError:
        return False
