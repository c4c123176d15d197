"""Leaderboard episodes as Ray tasks: ``uvdms leaderboard --backend ray [--address ADDR] [--num-cpus N]``.

Each (entry, task, seed) episode that is not cached is one Ray task declaring one CPU (the episode is one
single-threaded process: PyBullet, numpy, and a policy with ``torch.set_num_threads(1)``). The driver connects
through :func:`uvdms_gym.utils.cluster.ray_session` (a local instance sized to the machine, or the cluster at
``address``), keeps the cache and writes every result itself as it arrives, so workers need the package
installed but neither a shared filesystem nor write access to the driver's folders.

Controllers reach the workers as data:

* a baseline as its name (the worker builds it with :func:`leaderboard.suite.registry.make_controller`);
* an agent as its weights-only export (:mod:`agents.export.weights`: ``agent.json``, ``policy.pt``,
  ``normalization.npz``), read or exported once by the driver (an SB3 zip is loaded there, with ``--trust``
  where it needs it, and exported) and put in the object store once per entry as ``{file name: bytes}``. A
  worker writes it to a private temporary folder once per process and loads it with
  :func:`agents.export.weights.load_weights_only`, which never unpickles; no SB3 zip or pickle reaches a worker.
  The folder (``uvdms-agent-<pid>-*``, :func:`uvdms_gym.utils.tempdirs.owned_tempdir`) goes when the worker
  exits; a worker killed meanwhile (by Ray at shutdown, or lost) leaves it to the next sweep: on a local
  instance the driver's, after the session ends.

Faults: a task whose worker process dies (killed, out of memory, node lost) is run again by Ray, up to
``max_retries`` times; an episode is a pure function of its job (seeded, fresh baseline controller), so the
retried result is the one a first attempt would have given, and the driver, which alone writes the cache, writes
each episode once. An exception raised by an episode is not retried: it stops the run and is reported with the
episode's entry, task and seed, as with the local backends.
"""

from __future__ import annotations

import contextlib
import logging
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from leaderboard.suite.entries import Entry
from uvdms_gym.utils.tempdirs import owned_tempdir, sweep_stale

log = logging.getLogger("uvdms.leaderboard")

DEFAULT_MAX_RETRIES = 3
"""Retries of an episode whose worker process dies (Ray's default for tasks)."""

_MATERIALISED: dict[str, Path] = {}
"""Per worker process: agent checksum -> the folder its weights-only export was written to."""
AGENT_FOLDER_PREFIX = "uvdms-agent-"
"""Start of the name of a worker's agent folder (``uvdms-agent-<pid>-<random>``)."""
SWEEP_WAIT_S = 10.0
"""How long the driver waits for the workers of its ended local Ray instance to exit before sweeping."""


def agent_files(entry: Entry, trust: bool) -> dict[str, bytes]:
    """The weights-only export of an agent entry as ``{file name: bytes}`` (what the object store carries).

    A weights-only export is read as it is; any other agent (a run directory, a shipped agent or an SB3 zip)
    is loaded here, in the driver (``trust`` as for :func:`leaderboard.suite.registry.load_agent`), and exported to a
    temporary folder with :func:`agents.export.weights.export_controller` first.

    Raises:
        ValueError: The entry is not an agent, or its files cannot be loaded or exported.
    """
    if entry.kind != "agent":
        raise ValueError(f"{entry.name} is a {entry.kind}, not an agent: it reaches the workers by name")
    if entry.weights_only:
        return _read_folder(Path(entry.spec))
    from agents.export.weights import export_controller
    from leaderboard.suite.registry import load_agent

    agent = load_agent(entry.spec, trust=trust)
    with tempfile.TemporaryDirectory(prefix="uvdms-export-") as tmp:
        return _read_folder(export_controller(agent, Path(tmp) / "export"))


def _read_folder(folder: Path) -> dict[str, bytes]:
    return {path.name: path.read_bytes() for path in sorted(folder.iterdir()) if path.is_file()}


def materialise(checksum: str, files: Mapping[str, bytes]) -> Path:
    """Write an agent's export to a private temporary folder of this process, once per ``checksum``."""
    folder = _MATERIALISED.get(checksum)
    if folder is None or not folder.is_dir():
        bad = [name for name in files if Path(name).name != name or name in ("", ".", "..")]
        if bad:  # the driver sends a flat folder: anything else would write outside the temporary folder
            raise ValueError(f"agent export file names {bad} are not plain file names")
        folder = owned_tempdir(AGENT_FOLDER_PREFIX)  # removed at exit, or by a sweep if the worker is killed
        for name, data in files.items():
            (folder / name).write_bytes(data)
        _MATERIALISED[checksum] = folder
    return folder


def ray_episode(job: Any, backend: Any, trust: bool, files: Mapping[str, bytes] | None) -> dict[str, Any]:
    """Body of one Ray task: the episode of ``job`` (:func:`leaderboard.running.jobs.compute_job`) in a worker.

    ``files`` is the agent's weights-only export (``None`` for a baseline); the job's entry is pointed at the
    folder it is written to. Nothing is written to the cache here.
    """
    from leaderboard.running.jobs import compute_job, worker_setup

    worker_setup()
    if files is not None:
        folder = materialise(_payload_key(job.entry), files)
        job = replace(job, entry=replace(job.entry, spec=str(folder), weights_only=True))
    return compute_job(job, backend, trust)


@contextlib.contextmanager
def _sweep_after_local_session(address: str | None) -> Iterator[None]:
    """Remove the agent folders of the workers of a local Ray instance started here, once it has ended.

    Ray ends its workers at shutdown with a signal, so they run no exit code (:mod:`uvdms_gym.utils.tempdirs`).
    """
    try:
        import ray

        started_here = address is None and not ray.is_initialized()
    except ImportError:  # ray_session says how to install it
        started_here = False
    before = {path.name for path in Path(tempfile.gettempdir()).glob(f"{AGENT_FOLDER_PREFIX}*")}  # other runs'
    try:
        yield
    finally:
        if started_here:
            sweep_stale(AGENT_FOLDER_PREFIX, wait=SWEEP_WAIT_S, not_waiting_for=before)


def _payload_key(entry: Entry) -> str:
    """What identifies an agent's files: their checksum (the name where there is none)."""
    return entry.checksum or entry.name


def run_on_ray(
    todo: Sequence[Any],
    backend: Any,
    trust: bool,
    *,
    address: str | None = None,
    num_cpus: int | None = None,
    max_retries: int = DEFAULT_MAX_RETRIES,
) -> Iterator[tuple[Any, dict[str, Any]]]:
    """Run the episodes of ``todo`` as Ray tasks and yield ``(job, result)`` as each finishes.

    Args:
        todo: :class:`leaderboard.running.jobs.Job` s to compute.
        backend: :class:`leaderboard.running.jobs.Backend` (module-level callables: Ray pickles them by reference).
        trust: Allow unpickling agents outside ``trained_agents/`` (in the driver only, for the export).
        address: Ray cluster address (``None``: a local instance of ``num_cpus`` CPUs).
        num_cpus: CPUs of the local instance (default: every core of this machine).
        max_retries: Re-runs of an episode whose worker process dies.

    Raises:
        RuntimeError: Ray is not installed.
        ConnectionError: The cluster at ``address`` cannot be reached.
        Exception: The first episode that raised, re-raised with the episode named in the log.
    """
    from uvdms_gym.utils.cluster import ray_session

    if max_retries < 0:
        raise ValueError(f"max_retries must be >= 0, got {max_retries}")
    with _sweep_after_local_session(address), ray_session(address=address, num_cpus=num_cpus) as ray:
        payloads: dict[str, Any] = {}  # one export per agent (an agent and its ``+filter`` entry share it)
        for job in todo:
            if job.entry.kind == "agent" and _payload_key(job.entry) not in payloads:
                payloads[_payload_key(job.entry)] = ray.put(agent_files(job.entry, trust))
        task = ray.remote(num_cpus=1, max_retries=max_retries, retry_exceptions=False)(ray_episode)
        refs = {
            task.options(name=f"episode {job.entry.name} / {job.task.name} / seed {job.seed}").remote(
                job, backend, trust, payloads.get(_payload_key(job.entry))
            ): job
            for job in todo
        }
        pending = list(refs)
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    job = refs[ref]
                    try:
                        result = ray.get(ref)
                    except ray.exceptions.RayTaskError as exc:  # the episode raised: report its own error
                        log.error("episode failed: %s on %s, seed %d", job.entry.name, job.task.name, job.seed)
                        cause = exc.as_instanceof_cause()
                        raise cause from None
                    except ray.exceptions.RayError:  # its worker died more than max_retries times
                        log.error("episode lost: %s on %s, seed %d", job.entry.name, job.task.name, job.seed)
                        raise
                    yield job, result
        finally:
            for ref in pending:
                ray.cancel(ref, force=True)
