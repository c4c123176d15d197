"""One leaderboard at a time per output folder: the folder's lock.

A second ``uvdms leaderboard`` into a folder that another one is writing would compute every episode a second time
(the cache is read once, before computing). :func:`output_lock` makes it refuse at once instead, with
:class:`OutputFolderInUseError` naming the holder's process id (``uvdms: error: ...``, exit status 2); run again
when the first one has finished, and its episodes come from the cache.

[D] The lock is an advisory ``flock`` on ``<out>/.leaderboard.lock``, taken without waiting. The kernel releases
it when its holder exits, however it exits, so a lock left by a killed process never blocks: the file may remain,
but nobody holds it, and the next run takes it (the process id written into it is only for the message). A holder
removes the file when it is done. Platforms without ``fcntl`` (Windows) run without the lock.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: no lock
    fcntl = None  # type: ignore[assignment]

LOCK_NAME = ".leaderboard.lock"
"""The lock file inside the output folder."""


class OutputFolderInUseError(OSError):
    """Another leaderboard run holds the output folder's lock."""


@contextlib.contextmanager
def output_lock(out_dir: str | Path) -> Iterator[Path]:
    """Hold the lock of the output folder ``out_dir`` (created if missing) for the duration of the block.

    Yields:
        The lock file.

    Raises:
        OutputFolderInUseError: A live process holds the lock.
    """
    path = Path(out_dir) / LOCK_NAME
    path.parent.mkdir(parents=True, exist_ok=True)
    if fcntl is None:  # pragma: no cover
        yield path
        return
    fd = _acquire(path)
    try:
        yield path
    finally:
        with contextlib.suppress(OSError):
            path.unlink()  # before unlocking: a run that opens the path afterwards gets a new file
        os.close(fd)  # releases the lock


def _acquire(path: Path) -> int:
    """An open descriptor of ``path`` holding its exclusive lock, the holder's pid written into the file."""
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_pid(fd)
            os.close(fd)
            raise OutputFolderInUseError(
                f"{path.parent} is in use by another uvdms leaderboard (pid {holder}): run again when it has "
                "finished (with the same --cache-dir, the episodes it computed are then read from the cache)"
            ) from None
        if _is_current(fd, path):
            break
        os.close(fd)  # the holder removed the file between our open and our lock: lock the new one
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    return fd


def _is_current(fd: int, path: Path) -> bool:
    """Whether ``fd`` is still the file at ``path`` (not one unlinked by its previous holder)."""
    try:
        return os.stat(path).st_ino == os.fstat(fd).st_ino
    except FileNotFoundError:
        return False


def _read_pid(fd: int) -> str:
    """The process id recorded in the lock file (``unknown`` if it has none yet)."""
    text = os.pread(fd, 32, 0).decode(errors="replace").strip()
    return text if text.isdigit() else "unknown"
