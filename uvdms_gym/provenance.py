"""Provenance recorded with every run: package versions and the git revision of the repository."""

from __future__ import annotations

import importlib.metadata
import platform
import subprocess
from collections.abc import Mapping
from pathlib import Path
from typing import Any

REPO_ROOT = Path(__file__).resolve().parents[1]
"""The checkout holding this package (for ``git``)."""

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
    """Versions of Python and of ``packages`` (those not installed are left out)."""
    versions = {"python": platform.python_version()}
    for key, dist in packages.items():
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
