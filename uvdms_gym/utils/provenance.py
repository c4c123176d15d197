"""Provenance recorded with every run: package versions, the git revision, and where and under what load timings ran.

A timing is only meaningful with the machine it was taken on and the load beside it (a 2 ms controller step
read 30 ms under two trainings on a 2-core machine). :func:`timing_record` is the one helper every timing
writer uses (``uvdms evaluate``, the leaderboard, ``uvdms bench``): it records the machine
(:func:`machine_info`: CPU model, logical cores) and the 1-minute load average at the start and at the end,
and flags the timing ``overloaded`` when either load exceeds the core count (:func:`is_overloaded`).
"""

from __future__ import annotations

import contextlib
import functools
import importlib.metadata
import os
import platform
import subprocess
import sys
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

REPO_ROOT = Path(__file__).resolve().parents[2]
"""The checkout holding this package (for ``git``, and the project's one repository-root lookup:
``agents.common.paths`` and
the tools import it); ``site-packages`` after a regular install."""

PACKAGES: Mapping[str, str] = {
    "uvdms_gym": "uvdms-gym",
    "numpy": "numpy",
    "scipy": "scipy",
    "torch": "torch",
    "stable_baselines3": "stable-baselines3",
    "sb3_contrib": "sb3-contrib",
    "gymnasium": "gymnasium",
    "pybullet": "pybullet",
    "pin": "pin",
    "proxsuite": "proxsuite",
    "osqp": "osqp",
}
"""Reported name -> distribution name of the packages a run depends on."""


def package_versions(packages: Mapping[str, str] = PACKAGES) -> dict[str, str]:
    """Versions of Python and of ``packages`` (those not installed are left out).

    ``uvdms_gym`` reports the version of the code that runs (``uvdms_gym.__version__``), not its installed
    metadata: an editable install keeps the metadata of the version it was installed at (a checkout installed
    at 0.5.0 and updated since reported 0.5.0).
    """
    versions = {"python": platform.python_version()}
    for key, dist in packages.items():
        # this package: Python imported it (this module's parent) before this module; importing it here would
        # break the layers (its __init__ imports the physics)
        running = getattr(sys.modules.get(key), "__version__", None) if key == "uvdms_gym" else None
        if running is not None:
            versions[key] = running
            continue
        try:
            versions[key] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            pass
    return versions


def git_info(repo: str | Path = REPO_ROOT) -> dict[str, Any]:
    """Git revision of ``repo`` and whether its tracked files have uncommitted changes.

    Returns:
        ``{"revision": sha or None, "dirty": bool or None}`` (``None`` when git or the repository is missing).
    """
    try:
        rev = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=repo, capture_output=True, text=True, timeout=20, check=True
        ).stdout.strip()
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=repo,
            capture_output=True,
            text=True,
            timeout=20,
            check=True,
        ).stdout
    except (OSError, subprocess.SubprocessError):
        return {"revision": None, "dirty": None}
    return {"revision": rev or None, "dirty": bool(status.strip())}


@functools.lru_cache(maxsize=1)
def cpu_model() -> str:
    """The CPU model name (``/proc/cpuinfo`` on Linux, ``sysctl`` on macOS, else :func:`platform.processor`).

    Returns:
        The model string, or ``"unknown"``.
    """
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() in ("model name", "Hardware", "Processor", "cpu model") and value.strip():
                    return value.strip()
    except OSError:
        pass
    if platform.system() == "Darwin":
        try:
            out = subprocess.run(
                ["sysctl", "-n", "machdep.cpu.brand_string"], capture_output=True, text=True, timeout=5, check=True
            ).stdout.strip()
            if out:
                return out
        except (OSError, subprocess.SubprocessError):
            pass
    return platform.processor() or platform.machine() or "unknown"


def machine_info() -> dict[str, Any]:
    """The machine a timing runs on.

    Returns:
        ``{"cpu_model": str, "cpu_count": logical CPUs of the machine, "cpu_affinity": CPUs this process may
        use (``None`` where the platform cannot tell), "platform": OS and architecture}``.
    """
    try:
        affinity: int | None = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        affinity = None
    return {
        "cpu_model": cpu_model(),
        "cpu_count": os.cpu_count(),
        "cpu_affinity": affinity,
        "platform": f"{platform.system()} {platform.release()} {platform.machine()}",
    }


def load_average() -> float | None:
    """The 1-minute load average of the machine (``None`` where the platform has none, e.g. Windows)."""
    try:
        return round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):
        return None


def is_overloaded(record: Mapping[str, Any]) -> bool | None:
    """Whether a :func:`timing_record` saw a 1-minute load above the machine's logical core count.

    The load average counts runnable processes machine-wide, so above the core count the timed process
    shared its CPU with others and its timings read long.

    Returns:
        ``True``/``False``, or ``None`` if the load or the core count is unknown.
    """
    cores = (record.get("machine") or {}).get("cpu_count")
    loads = [x for x in (record.get("load_1min_start"), record.get("load_1min_end")) if x is not None]
    if not cores or not loads:
        return None
    return max(loads) > cores


@contextlib.contextmanager
def timing_record() -> Iterator[dict[str, Any]]:
    """Record the machine and the 1-minute load average around a timed block.

    Usage::

        with timing_record() as timing:
            ...  # the timed work
        result["timing"] = timing

    Yields:
        A dict holding ``machine`` (:func:`machine_info`) and ``load_1min_start``; at the end of the block
        (also on an exception) ``load_1min_end`` and ``overloaded`` (:func:`is_overloaded`) are added.
    """
    record: dict[str, Any] = {"machine": machine_info(), "load_1min_start": load_average()}
    try:
        yield record
    finally:
        record["load_1min_end"] = load_average()
        record["overloaded"] = is_overloaded(record)
