"""Ray process bookkeeping shared by the Ray tests: the ``ray_processes`` fixture and :class:`ProcessWatch`.

Every Ray test starts its own Ray (a local instance or a ``ray.cluster_utils.Cluster`` on this machine), shuts
it down, and checks that no process it started outlives it. Processes that already descended from the test
process when the watch started (an earlier test's ``multiprocessing`` forkserver or resource tracker in the
same pytest-xdist worker, say) are not the test's, and neither are Python's own long-lived ``multiprocessing``
helpers started during the test (they live as long as the interpreter by design, are not Ray's, and are
reaped when the worker exits).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable
from typing import Any

import pytest

# Command-line fragments of the long-lived helpers ``multiprocessing`` starts once per interpreter.
_MP_HELPERS = ("multiprocessing.forkserver", "multiprocessing.resource_tracker")


def _proc_table() -> dict[int, tuple[int, str, int]]:
    """pid -> (parent pid, state, start time in clock ticks), from /proc."""
    table = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", encoding="utf-8", errors="replace") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        table[int(entry)] = (int(fields[1]), fields[0], int(fields[19]))
    return table


def _cmdline(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read().replace(b"\0", b" ").decode("utf-8", "replace")
    except OSError:
        return ""


def _descendants(table: dict[int, tuple[int, str, int]], root: int) -> set[tuple[int, int]]:
    children: dict[int, list[int]] = {}
    for pid, (ppid, _, _) in table.items():
        children.setdefault(ppid, []).append(pid)
    found = set()
    stack = list(children.get(root, []))
    while stack:
        pid = stack.pop()
        found.add((pid, table[pid][2]))
        stack.extend(children.get(pid, []))
    return found


class ProcessWatch:
    """Records every process that descends from this one while it runs (sampled every 0.1 s).

    Ray's local instance (GCS, raylet, workers, ...) and the nodes of a ``Cluster`` are started by the test
    process, so they are its descendants for as long as they run; a process that later loses its parent is
    still checked because it was recorded while it had one. Descendants alive when the watch starts, and
    ``multiprocessing``'s forkserver and resource tracker, are not recorded. :meth:`leftovers` lists the
    recorded processes still alive (zombies count as ended).
    """

    def __init__(self) -> None:
        self.preexisting = _descendants(_proc_table(), os.getpid())
        self.seen: set[tuple[int, int]] = set()
        self._ignored: set[tuple[int, int]] = set()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _sample(self) -> None:
        for proc in _descendants(_proc_table(), os.getpid()) - self.preexisting - self.seen - self._ignored:
            if any(helper in _cmdline(proc[0]) for helper in _MP_HELPERS):
                self._ignored.add(proc)
            else:
                self.seen.add(proc)

    def _run(self) -> None:
        while not self._stop.is_set():
            self._sample()
            self._stop.wait(0.1)

    def stop(self) -> None:
        self._sample()
        self._stop.set()
        self._thread.join()

    def leftovers(self, timeout: float = 20.0) -> list[int]:
        """The recorded processes still alive after waiting up to ``timeout`` seconds for them to end."""
        deadline = time.monotonic() + timeout
        while True:
            table = _proc_table()
            alive = [p for p, start in self.seen if p in table and table[p][2] == start and table[p][1] != "Z"]
            if not alive or time.monotonic() > deadline:
                return sorted(alive)
            time.sleep(0.2)


def describe(pids: list[int]) -> list[str]:
    """``pid: command line`` of each process, for an assertion message."""
    return [f"{pid}: {_cmdline(pid)[:160]}" for pid in pids]


@pytest.fixture
def ray_processes():
    """A :class:`ProcessWatch` for the test; fails the test if a process it started outlives it."""
    import ray

    assert not ray.is_initialized()
    watch = ProcessWatch()
    yield watch
    if ray.is_initialized():
        ray.shutdown()
    watch.stop()
    assert len(watch.seen) > 0, "the test started no process: the watch saw nothing"
    leftovers = watch.leftovers()
    assert leftovers == [], f"processes the test started outlive it: {describe(leftovers)}"


def descendants_matching(fragment: str) -> list[int]:
    """Live descendants of this process whose command line (Ray's process title, say) contains ``fragment``."""
    table = _proc_table()
    return sorted(
        pid for pid, _ in _descendants(table, os.getpid()) if table[pid][1] != "Z" and fragment in _cmdline(pid)
    )


def kill_when(
    fragment: str,
    thread: threading.Thread,
    *,
    ready: Callable[[], bool] = lambda: True,
    settle: float = 0.0,
    timeout: float = 240.0,
) -> int | None:
    """While ``thread`` runs, ``SIGKILL`` the first descendant whose command line contains ``fragment``.

    Args:
        fragment: E.g. ``"ray::episode "`` (a Ray task's process title).
        thread: The run the process belongs to (:func:`in_background`); nothing is killed once it has ended.
        ready: Kill only once this holds (e.g. the process has written a file).
        settle: Seconds to wait after seeing the process (into its work); it is killed if it still runs then.
        timeout: Seconds to wait in all.

    Returns:
        The process killed, or ``None`` if none was seen in time.
    """
    deadline = time.monotonic() + timeout
    while thread.is_alive() and time.monotonic() < deadline:
        running = descendants_matching(fragment)
        if running and ready():
            time.sleep(settle)
            if running[0] in descendants_matching(fragment):
                os.kill(running[0], signal.SIGKILL)
                return running[0]
        time.sleep(0.01)
    return None


def in_background(fn: Callable[[], Any]) -> tuple[threading.Thread, dict[str, Any]]:
    """Start ``fn()`` in a thread; the returned dict gets ``"result"`` or ``"error"`` (any exception) when it ends."""
    outcome: dict[str, Any] = {}

    def run() -> None:
        try:
            outcome["result"] = fn()
        except BaseException as exc:  # reported by the caller's assertions
            outcome["error"] = exc

    thread = threading.Thread(target=run)
    thread.start()
    return thread, outcome
