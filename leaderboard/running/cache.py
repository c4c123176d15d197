"""The per-episode result cache: keys, paths, reading with corruption checks, and compact results."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

import uvdms_gym
from baselines.mpc import PROXSUITE_BUILD
from leaderboard.suite.entries import Entry
from leaderboard.suite.tasks import Task
from uvdms_gym.utils.io import to_jsonable

PACKAGE_VERSION = uvdms_gym.__version__
CACHE_FORMAT = 2
"""Version of the cached per-episode files (2: every result carries its ``timing`` record)."""
REQUIRED_KEYS: tuple[str, ...] = ("seed", "contacts", "success", "rmse_pos", "min_distance", "steps")
"""Keys a cached per-episode result must have (a file without them is treated as corrupt)."""


class CorruptCacheError(ValueError):
    """A cached result file that cannot be used."""


def cache_material(entry: Entry, task: Task, seed: int, save_trajectory: bool) -> dict[str, Any]:
    """Everything the cache key hashes (see the module docstring).

    Baselines also hash the ProxSuite build their QPs are solved with (:data:`baselines.mpc.PROXSUITE_BUILD`):
    results of another build differ in the last bits and are not reused.
    """
    material = {
        "format": CACHE_FORMAT,
        "package_version": PACKAGE_VERSION,
        "entry": entry.identity(),
        "task": entry.task_spec(task),
        "seed": int(seed),
        "trajectory": bool(save_trajectory),
    }
    if entry.kind == "baseline":
        material["qp_solver"] = PROXSUITE_BUILD
    return material


def cache_key(material: Mapping[str, Any]) -> str:
    """SHA-256 of the canonical JSON of ``material``."""
    return hashlib.sha256(json.dumps(material, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


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
