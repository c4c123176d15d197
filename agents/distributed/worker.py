"""One run of a sweep on a worker (:mod:`agents.distributed.sweep`).

Train in a temporary directory, ship checkpoints, return it.

No shared filesystem is assumed between the driver and the workers. A run trains in a temporary directory on its
worker (:func:`run_job`, the body of the Ray task and of the local backend's loop) and its finished run
directory travels back to the driver as the bytes of a tar archive (:func:`pack_run_dir`), which the driver
unpacks under ``--out``.

Checkpoints leave the worker as they are written: :class:`ShipCheckpoints`, a training callback that runs
right after the checkpoint callback of :func:`agents.training.train.train`, archives the run directory with only its
newest checkpoint and hands the bytes to a :class:`CheckpointStore`. With ``--backend ray`` the store is a
small Ray actor (no CPU reserved) pinned to the driver's node, so it survives the death of any worker node
except the driver's. A task whose worker dies is retried by Ray (``max_retries``); the retry asks the store for
the run's newest checkpoint, unpacks it and continues with the ordinary resume (``train(resume_dir=...)``: the
same run directory, a new training segment, ``num_timesteps`` counted on; the lost segment is marked
``worker_lost`` in ``meta.json``). The store also counts the attempts of every run (the retries of the summary)
and records the process of the current attempt (its ``pid`` and node), which is what a fault-injection test
kills.
"""

from __future__ import annotations

import dataclasses
import io
import json
import os
import shutil
import tarfile
import tempfile
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback

from agents.training.rundir import CHECKPOINT_PREFIX, _write_json, run_dir_for
from agents.training.spec import RunSpec

WORKER_PREFIX = "uvdms-sweep-"
"""Prefix of the temporary directory a run trains in (removed when the run ends)."""


@dataclasses.dataclass(frozen=True)
class RunJob:
    """Everything a worker needs to train one run of a sweep (plain data: it is pickled to the worker).

    Attributes:
        key: The run directory relative to the sweep's ``--out`` (``[grid_<k>/]<env dir>/<algo>_<seed>``).
        out_subdir: The ``--out`` of the equivalent ``uvdms train`` relative to the sweep's (``""`` or ``grid_<k>``).
        spec: The run (its ``config_path`` is replaced by the worker's copy of ``config_text``).
        config_name: File name of the configuration (written into the worker's temporary directory).
        config_text: Text of the configuration file (the driver's file, shipped: no shared filesystem).
        num_cpus: CPUs the run declares (:func:`agents.distributed.sweep.run_cpus`).
        grid_index: Index of the grid point (``None`` without ``--grid``).
        grid_point: The grid point's values.
        components: The composition layer's base and filter factories (:class:`agents.common.envs.ActionComponents`)
            for a residual or filtered configuration (``None``: none; picklable, they travel to Ray workers).
    """

    key: str
    out_subdir: str
    spec: RunSpec
    config_name: str
    config_text: str
    num_cpus: int
    grid_index: int | None
    grid_point: Mapping[str, Any]
    components: Any = None


@dataclasses.dataclass(frozen=True)
class RunOutcome:
    """What a finished run sends back to the driver.

    Attributes:
        key: :attr:`RunJob.key`.
        archive: The run directory as an uncompressed tar archive (paths relative to the run directory).
        worker_root: The worker's temporary directory (the driver rewrites it to ``--out`` in the run's records).
        attempt: Attempt number of the run that finished (1: no retry).
        node_id: Ray node id of the worker (``"local"`` for the local backend).
    """

    key: str
    archive: bytes
    worker_root: str
    attempt: int
    node_id: str


class CheckpointStore:
    """Newest checkpoint archive and attempt record of every run of one sweep (a Ray actor, or in-process).

    Methods are called through :class:`StoreClient`. Only the attempt that is current may store a
    checkpoint, and only a newer one than what is stored (a late message of a dead attempt changes nothing).
    """

    def __init__(self) -> None:
        self._runs: dict[str, dict[str, Any]] = {}
        self._checkpoints: dict[str, tuple[int, bytes, str]] = {}

    def begin(
        self, key: str, pid: int, node_id: str, worker_root: str
    ) -> tuple[int, tuple[bytes, str] | None, tuple[str, str] | None]:
        """Register a new attempt of run ``key`` (its process, node and temporary directory).

        Returns:
            The attempt number (1, 2, ...); the run's newest checkpoint, if any: the archive and the temporary
            directory of the attempt that wrote it (named in the run's records); the node and temporary
            directory of the previous attempt, if any (left behind by its dead worker).
        """
        record = self._runs.setdefault(key, {"attempts": 0, "first_start": time.time()})
        previous = (record["node_id"], record["worker_root"]) if record["attempts"] else None
        record.update(
            attempts=record["attempts"] + 1, pid=pid, node_id=node_id, worker_root=worker_root, started=time.time()
        )
        checkpoint = self._checkpoints.get(key)
        return record["attempts"], (checkpoint[1:] if checkpoint else None), previous

    def put(self, key: str, attempt: int, num_timesteps: int, archive: bytes, worker_root: str) -> bool:
        """Keep ``archive`` as the newest checkpoint of ``key``; ``False`` if it is stale (ignored)."""
        current = self._runs.get(key, {}).get("attempts")
        stored = self._checkpoints.get(key)
        if attempt != current or (stored is not None and stored[0] >= num_timesteps):
            return False
        self._checkpoints[key] = (num_timesteps, archive, worker_root)
        self._runs[key]["checkpoint_timesteps"] = num_timesteps
        return True

    def status(self) -> dict[str, dict[str, Any]]:
        """The record of every run.

        Returns:
            Per run key: ``attempts``, ``pid``, ``node_id``, ``worker_root`` and ``started`` of the current attempt,
            ``first_start``
            (epoch seconds, on the store's node) and ``checkpoint_timesteps`` of the stored checkpoint (absent
            before the first).
        """
        return {key: dict(record) for key, record in self._runs.items()}

    def forget(self, key: str) -> None:
        """Drop the stored checkpoint of a finished run (frees its memory; the attempt record stays)."""
        self._checkpoints.pop(key, None)


class StoreClient:
    """Calls the methods of a :class:`CheckpointStore`: a Ray actor handle (``remote``) or a local instance.

    Args:
        target: The actor handle or the instance.
        remote: ``True`` for an actor handle (each call waits for the actor's answer).
    """

    def __init__(self, target: Any, remote: bool) -> None:
        self.target = target
        self.remote = remote

    def call(self, method: str, *args: Any) -> Any:
        """Call ``method`` of the store with ``args`` and return its result."""
        if self.remote:
            import ray

            return ray.get(getattr(self.target, method).remote(*args))
        return getattr(self.target, method)(*args)


class ShipCheckpoints(BaseCallback):
    """Sends every new checkpoint of a run to the store as it is written (run after the checkpoint callback).

    A checkpoint is shipped as the run directory with only that checkpoint's files (:func:`pack_run_dir`), so
    that a resume from it has the configuration, ``meta.json``, the best model and the logs so far. Checkpoints
    at or past the end of the segment are not shipped (a resume would have no steps left to train).

    Args:
        run_dir: The run directory (its ``checkpoints/`` folder is watched).
        ship: Called with ``(num_timesteps, archive bytes)``.
    """

    def __init__(self, run_dir: Path, ship: Callable[[int, bytes], Any]) -> None:
        super().__init__()
        self.run_dir = Path(run_dir)
        self.ship = ship
        self.shipped: list[int] = []

    def _on_step(self) -> bool:
        n = int(self.num_timesteps)
        if self.shipped and self.shipped[-1] == n:
            return True
        if n >= self.model._total_timesteps:
            return True
        if (self.run_dir / "checkpoints" / f"{CHECKPOINT_PREFIX}_{n}_steps.zip").is_file():
            self.ship(n, pack_run_dir(self.run_dir, checkpoint=n))
            self.shipped.append(n)
        return True


def _is_other_checkpoint(relative: Path, checkpoint: int) -> bool:
    """``True`` for a file of ``checkpoints/`` that does not belong to checkpoint ``checkpoint``."""
    if relative.parts[:1] != ("checkpoints",) or len(relative.parts) != 2:
        return False
    return not relative.name.endswith(f"_{checkpoint}_steps.zip") and not relative.name.endswith(
        f"_{checkpoint}_steps.pkl"
    )


def pack_run_dir(run_dir: str | Path, checkpoint: int | None = None) -> bytes:
    """A run directory as the bytes of an uncompressed tar archive (member names relative to the directory).

    Args:
        run_dir: The run directory.
        checkpoint: Keep only this checkpoint's files of ``checkpoints/`` (``None``: every file).
    """
    run_dir = Path(run_dir)
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w") as archive:
        for path in sorted(run_dir.rglob("*")):
            relative = path.relative_to(run_dir)
            if path.is_symlink() or not (path.is_file() or path.is_dir()):
                continue
            if checkpoint is not None and _is_other_checkpoint(relative, checkpoint):
                continue
            archive.add(path, arcname=relative.as_posix(), recursive=False)
    return buffer.getvalue()


def unpack_run_dir(data: bytes, dest: str | Path) -> Path:
    """Unpack an archive of :func:`pack_run_dir` into ``dest`` (created; regular files and folders only).

    Raises:
        ValueError: A member is a link or device, absolute, or leaves ``dest`` (``..``).
    """
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    with tarfile.open(fileobj=io.BytesIO(data), mode="r") as archive:
        members = archive.getmembers()
        for member in members:
            name = Path(member.name)
            if not (member.isfile() or member.isdir()) or name.is_absolute() or ".." in name.parts:
                raise ValueError(f"run archive: refusing member {member.name!r} (only relative files and folders)")
        if hasattr(tarfile, "data_filter"):
            archive.extractall(dest, members=members, filter="data")
        else:  # pragma: no cover - Python < 3.11.4; the members were checked above
            archive.extractall(dest, members=members)
    return dest


def mark_lost_segments(run_dir: Path, note: str) -> int:
    """Mark the segments of ``meta.json`` still ``running`` (their worker died) as ``worker_lost``; return how many."""
    meta_file = run_dir / "meta.json"
    meta = json.loads(meta_file.read_text(encoding="utf-8"))
    lost = 0
    for segment in meta.get("segments", []):
        if segment.get("status") == "running":
            segment["status"] = "worker_lost"
            segment["error"] = note
            lost += 1
    _write_json(meta_file, meta)
    return lost


def _replace_in_strings(value: Any, old: str, new: str) -> Any:
    if isinstance(value, str):
        return value.replace(old, new)
    if isinstance(value, dict):
        return {k: _replace_in_strings(v, old, new) for k, v in value.items()}
    if isinstance(value, list):
        return [_replace_in_strings(v, old, new) for v in value]
    return value


def relocate_records(run_dir: str | Path, old_root: str, new_root: str) -> None:
    """Replace the directory ``old_root`` by ``new_root`` in a run's ``command.txt``, ``meta.json`` and ``config.yml``.

    A run trains under a temporary directory of its worker, whose path its records name (``--out``,
    ``--resume``, ``--config``); this points them at where the run directory and the configuration now are.
    """
    import shlex

    import yaml

    run_dir = Path(run_dir)
    commands = run_dir / "command.txt"
    if commands.is_file():
        lines = commands.read_text(encoding="utf-8").splitlines()
        fixed = [shlex.join(_replace_in_strings(shlex.split(line), old_root, new_root)) for line in lines if line]
        commands.write_text("".join(line + "\n" for line in fixed), encoding="utf-8")
    meta_file = run_dir / "meta.json"
    if meta_file.is_file():
        meta = json.loads(meta_file.read_text(encoding="utf-8"))
        _write_json(meta_file, _replace_in_strings(meta, old_root, new_root))
    config_file = run_dir / "config.yml"
    if config_file.is_file():
        resolved = yaml.safe_load(config_file.read_text(encoding="utf-8"))
        resolved = _replace_in_strings(resolved, old_root, new_root)
        config_file.write_text(yaml.safe_dump(resolved, sort_keys=False), encoding="utf-8")


def _node_id() -> str:
    try:
        import ray

        if ray.is_initialized():
            return str(ray.get_runtime_context().get_node_id())
    except ImportError:  # pragma: no cover - the local backend without Ray installed
        pass
    return "local"


def run_job(job: RunJob, store: StoreClient) -> RunOutcome:
    """Train one run in a temporary directory (resuming from the store's newest checkpoint if there is one).

    Args:
        job: The run.
        store: The sweep's checkpoint store.

    Returns:
        The finished run directory as an archive, with the attempt that finished it.
    """
    from agents.training.train import train, train_run

    node_id = _node_id()
    root = Path(tempfile.mkdtemp(prefix=WORKER_PREFIX))
    try:
        attempt, checkpoint, previous = store.call("begin", job.key, os.getpid(), node_id, str(root))
        if previous is not None and previous[0] == node_id and Path(previous[1]).name.startswith(WORKER_PREFIX):
            shutil.rmtree(previous[1], ignore_errors=True)  # the dead attempt's directory, on this node
        config_path = root / "configs" / job.config_name
        config_path.parent.mkdir()
        config_path.write_text(job.config_text, encoding="utf-8")
        out_dir = root / job.out_subdir if job.out_subdir else root
        spec = job.spec.replace(config_path=config_path)
        run_dir = run_dir_for(out_dir, spec.env_id, spec.algo, spec.seed)
        ship = ShipCheckpoints(run_dir, lambda n, data: store.call("put", job.key, attempt, n, data, str(root)))
        if checkpoint is None:
            train_run(spec, out_dir=out_dir, progress=False, callbacks=[ship], components=job.components)
        else:
            archive, previous_root = checkpoint
            unpack_run_dir(archive, run_dir)
            relocate_records(run_dir, previous_root, str(root))
            mark_lost_segments(run_dir, f"the worker died; attempt {attempt} resumed from the newest checkpoint")
            train(resume_dir=run_dir, progress=False, vec_env=spec.vec_env, callbacks=[ship], components=job.components)
        return RunOutcome(job.key, pack_run_dir(run_dir), str(root), attempt, node_id)
    finally:
        shutil.rmtree(root, ignore_errors=True)
