"""The per-episode result cache: keys, paths, reading with corruption checks, and compact results.

A result's key is the SHA-256 of its material (:func:`cache_material`): what decides the episode's result (the
cache format, the entry's identity, the task spec the entry runs, the seed, the trajectory flag and, for baselines,
the QP solver build). [D] Not the package version: a release that changes no result (a version bump, a
refactoring) keeps every key, so nothing is recomputed; a change of the code that does change results bumps
:data:`CACHE_FORMAT`. Keys of before 0.4 (:data:`LEGACY_FORMAT`) also hashed the package version;
:func:`legacy_cache_key` computes them, so that ``--reuse`` (:mod:`leaderboard.running.reuse`) still finds the
episodes of an output folder written then (``docs/leaderboard.md``, Cache).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from baselines.mpc.solver import PROXSUITE_BUILD
from leaderboard.suite.entries import Entry
from leaderboard.suite.tasks import Task
from uvdms_gym.seeds import PROTOCOL, split_of
from uvdms_gym.utils.io import to_jsonable

CACHE_FORMAT = 4
"""Version of the cache keys and files; bump it with a change of the code that changes episode results (4: the key
hashes the seed protocol, :data:`uvdms_gym.seeds.PROTOCOL`; 3: the key no longer hashes the package version; 2: every
result carries its ``timing`` record)."""
PROTOCOL_FORMAT = 4
"""The first format whose keys hash the seed protocol (:func:`earlier_cache_keys` gives the keys before it)."""
LEGACY_FORMAT = 2
"""The format of the keys that hashed the package version (:func:`legacy_cache_key`)."""
REQUIRED_KEYS: tuple[str, ...] = ("seed", "contacts", "success", "rmse_pos", "min_distance", "steps")
"""Keys a cached per-episode result must have (a file without them is treated as corrupt)."""


class CorruptCacheError(ValueError):
    """A cached result file that cannot be used."""


def cache_material(entry: Entry, task: Task, seed: int, save_trajectory: bool) -> dict[str, Any]:
    """Everything the cache key hashes: what decides the episode's result, not the package version (module docstring).

    The seed is recorded with the protocol that gave it and its split (:mod:`uvdms_gym.seeds`). Baselines also hash
    the ProxSuite build their QPs are solved with (:data:`baselines.mpc.solver.PROXSUITE_BUILD`):
    results of another build differ in the last bits and are not reused.
    """
    material = {
        "format": CACHE_FORMAT,
        "entry": entry.identity(),
        "task": entry.task_spec(task),
        "seed": int(seed),
        "seed_protocol": {"protocol": PROTOCOL, "split": split_of(int(seed))},
        "trajectory": bool(save_trajectory),
    }
    if entry.kind == "baseline":
        material["qp_solver"] = PROXSUITE_BUILD
    return material


def cache_key(material: Mapping[str, Any]) -> str:
    """SHA-256 of the canonical JSON of ``material``."""
    return hashlib.sha256(json.dumps(material, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def legacy_cache_key(material: Mapping[str, Any], package_version: str) -> str:
    """The key that ``material`` had before 0.4, when keys also hashed the package version of the run."""
    return cache_key({**_before_protocol(material), "format": LEGACY_FORMAT, "package_version": package_version})


def earlier_cache_keys(material: Mapping[str, Any], package_version: str | None) -> set[str]:
    """The keys ``material`` had in the formats before the seed protocol (3, and 2 with ``package_version``)."""
    keys = {cache_key({**_before_protocol(material), "format": PROTOCOL_FORMAT - 1})}
    if package_version is not None:
        keys.add(legacy_cache_key(material, package_version))
    return keys


def _before_protocol(material: Mapping[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in material.items() if k != "seed_protocol"}


def cache_path(cache_dir: str | Path, entry: Entry, task: Task, seed: int, key: str) -> Path:
    """``<cache_dir>/<entry>/<task>/seed<seed>-<key[:16]>.json``."""
    return Path(cache_dir) / entry.slug / task.name / f"seed{seed}-{key[:16]}.json"


def read_cached(path: str | Path, key: str) -> dict[str, Any]:
    """The per-episode result stored at ``path`` for ``key``.

    Raises:
        FileNotFoundError: No file.
        CorruptCacheError: Unparsable, truncated, for another key, or missing required result keys.
    """
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise CorruptCacheError(f"not valid JSON ({exc})") from exc
    if not isinstance(doc, dict) or doc.get("key") != key:
        raise CorruptCacheError("key mismatch")
    result = doc.get("result")
    if not isinstance(result, dict):
        raise CorruptCacheError("no result")
    missing = [k for k in REQUIRED_KEYS if k not in result]
    if missing:
        raise CorruptCacheError(f"result lacks {missing}")
    if result["seed"] != doc.get("material", {}).get("seed"):
        raise CorruptCacheError("seed mismatch")
    return result


def compact_result(result: Mapping[str, Any]) -> dict[str, Any]:
    """A JSON-safe copy of a per-episode result whose trajectory is reduced to ``t`` and the minimum distance."""
    out = {k: v for k, v in result.items() if k != "trajectory"}
    traj = result.get("trajectory")
    if isinstance(traj, Mapping) and "t" in traj and "distances" in traj:
        t = np.asarray(traj["t"], dtype=float)
        d = np.asarray(traj["distances"], dtype=float)
        d_min = d.min(axis=1) if d.ndim == 2 else d
        out["trajectory"] = {"t": np.round(t, 4).tolist(), "min_distance": np.round(d_min, 5).tolist()}
    return to_jsonable(out)
