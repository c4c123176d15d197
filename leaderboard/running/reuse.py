"""Reuse the per-episode results of a previous leaderboard output (``uvdms leaderboard --reuse DIR``).

A leaderboard output folder keeps every episode's result in ``entries/<entry>.json`` (the ranking's under each
task's ``episodes``, the generalisation check's under its ``check``). Adding an entry to a
published leaderboard (``docs/leaderboard``) should not recompute the episodes of every other entry: for each
planned episode that is not in the cache, :func:`reusable_results` looks for the same episode in such a folder,
and the runner stores what it finds in the cache as if it had computed it (with the timing record of the run
that did compute it).

Which episode is "the same":

* Documents that record each episode's cache key (``cache_key``, written since ``--reuse`` exists): the
  episode whose key equals the planned one. The key hashes the entry's identity (name, model checksum, safety
  filter), the environment spec the entry runs the task on, the evaluation seed, the trajectory flag and, for
  baselines, the ProxSuite build (:func:`leaderboard.running.cache.cache_material`). A document written before
  0.4, whose keys also hashed its ``package_version``, matches on that key, and one written before the seed
  protocol (0.4), whose keys did not hash it, on that key (:func:`leaderboard.running.cache.earlier_cache_keys`): a
  version bump alone does not make an episode new.
* Older documents (no keys): the document of the entry's name with the same package version, kind and model
  checksum (for a multi-seed entry, the member's checksum under ``seeds``), then the episode of the task's name,
  the evaluation seed and the member's training seed. The environment spec and the QP solver build are not
  recorded there and are taken as unchanged within a package version; a warning names each such document.

Episodes whose job stores a trajectory (the first episode of the tasks with a distance plot) are never reused:
the documents keep no trajectories.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import uvdms_gym
from leaderboard.running.cache import REQUIRED_KEYS, earlier_cache_keys
from leaderboard.suite.entries import Entry

if TYPE_CHECKING:
    from leaderboard.running.jobs import Job

log = logging.getLogger(__name__)

CACHE_KEY_FIELD = "cache_key"
"""Episode field of the entry documents: the episode's cache key (:func:`leaderboard.running.cache.cache_key`)."""
_EPISODE_ONLY_FIELDS = (CACHE_KEY_FIELD, "training_seed")
"""Fields the documents add to a cached result (removed again when the result is reused)."""


def reusable_results(jobs: Sequence[Job], entries: Sequence[Entry], reuse_dir: str | Path) -> dict[Path, dict]:
    """The results of ``jobs`` found in the leaderboard output folder ``reuse_dir``, by the job's cache path.

    Args:
        jobs: Planned episodes (:func:`leaderboard.running.jobs.plan_jobs`); the runner passes those not in the cache.
        entries: The run's entries (each job's entry is one of them or one of their members).
        reuse_dir: A folder written by :func:`leaderboard.run_leaderboard` (``entries/*.json`` inside).

    Returns:
        ``{job.path: result}`` for every job with a matching episode (the rules in the module docstring).

    Raises:
        FileNotFoundError: ``reuse_dir`` has no ``entries/`` folder.
        ValueError: A document of ``reuse_dir`` that is needed is not valid JSON.
    """
    entries_dir = check_reuse_dir(reuse_dir)
    parent_of = {run: entry for entry in entries for run in entry.runs()}
    docs: dict[str, dict[str, Any] | None] = {}
    found: dict[Path, dict] = {}
    legacy: set[str] = set()
    for job in jobs:
        if job.save_trajectory:
            continue
        parent = parent_of[job.entry]
        if parent.slug not in docs:
            docs[parent.slug] = _read_document(entries_dir / f"{parent.slug}.json")
        doc = docs[parent.slug]
        if doc is None:
            continue
        result, keyless = _match(job, parent, doc, _recorded_episodes(doc, job.task.name))
        if result is not None:
            found[job.path] = result
            if keyless:
                legacy.add(parent.slug)
    for slug in sorted(legacy):
        log.warning(
            "--reuse: %s records no cache keys (an older leaderboard): its episodes were matched on package "
            "version, entry name and checksum, task and seeds; the environment spec and QP solver build are "
            "taken as unchanged",
            entries_dir / f"{slug}.json",
        )
    return found


def _recorded_episodes(doc: Mapping[str, Any], task: str) -> list[Any]:
    """Every episode a document records for ``task``: the ranking's and the generalisation check's (``check``)."""
    row = doc.get("tasks", {}).get(task)
    if not isinstance(row, Mapping):
        return []
    check = row.get("check")
    extra = check.get("episodes", []) if isinstance(check, Mapping) else []
    return [*row.get("episodes", []), *(extra if isinstance(extra, list) else [])]


def check_reuse_dir(reuse_dir: str | Path) -> Path:
    """The ``entries/`` folder of the leaderboard output ``reuse_dir``.

    Raises:
        FileNotFoundError: ``reuse_dir`` has no ``entries/`` folder.
    """
    entries_dir = Path(reuse_dir) / "entries"
    if not entries_dir.is_dir():
        raise FileNotFoundError(f"--reuse {reuse_dir}: not a leaderboard output folder (no entries/ inside)")
    return entries_dir


def _read_document(path: Path) -> dict[str, Any] | None:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise ValueError(f"--reuse: {path} is not valid JSON ({exc})") from exc
    return doc if isinstance(doc, dict) else None


def _match(
    job: Job, parent: Entry, doc: Mapping[str, Any], episodes: Sequence[Any]
) -> tuple[dict[str, Any] | None, bool]:
    """``job``'s episode among ``episodes`` as a cached result (or ``None``), and whether it matched without a key."""
    keyed = [ep for ep in episodes if isinstance(ep, Mapping) and CACHE_KEY_FIELD in ep]
    if keyed:
        version = doc.get("package_version")
        keys = {job.key} | earlier_cache_keys(job.material, version if isinstance(version, str) else None)
        hit = next((ep for ep in keyed if ep[CACHE_KEY_FIELD] in keys), None)
        return _as_result(hit), False
    if not _same_entry(job.entry, parent, doc):
        return None, False
    seed = job.entry.training_seed
    for ep in episodes:
        if isinstance(ep, Mapping) and ep.get("seed") == job.seed and (seed is None or ep.get("training_seed") == seed):
            result = _as_result(ep)
            return result, result is not None
    return None, False


def _same_entry(run: Entry, parent: Entry, doc: Mapping[str, Any]) -> bool:
    """Whether a keyless document describes ``run`` (a member of ``parent``, or ``parent`` itself)."""
    if doc.get("package_version") != uvdms_gym.__version__ or doc.get("name") != parent.name:
        return False
    if doc.get("kind") != parent.kind:
        return False
    if run.training_seed is None:
        return doc.get("checksum") == run.checksum
    seeds = doc.get("seeds")
    if not isinstance(seeds, list):
        return False
    return any(
        isinstance(s, Mapping) and s.get("training_seed") == run.training_seed and s.get("checksum") == run.checksum
        for s in seeds
    )


def _as_result(episode: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """A document's episode as the cached result it was made from (``None`` if it lacks a required key)."""
    if episode is None or any(k not in episode for k in REQUIRED_KEYS):
        return None
    return {k: v for k, v in episode.items() if k not in _EPISODE_ONLY_FIELDS}
