"""One version: ``uvdms_gym.__version__``, ``pyproject.toml`` and the newest release heading of ``CHANGELOG.md``."""

from __future__ import annotations

import re
from pathlib import Path

import uvdms_gym

REPO = Path(__file__).resolve().parents[2]
HEADING = re.compile(r"^## (\d+\.\d+\.\d+)\b", re.MULTILINE)


def changelog_versions(text: str) -> list[str]:
    """The release versions of a changelog's ``## X.Y.Z ...`` headings, in file order (newest first)."""
    return HEADING.findall(text)


def test_the_heading_parser():
    text = "# Changelog\n\n## 1.2.0 (unreleased): x\n\n- a\n\n### 1.0.0 no\n## 1.1.10\n## Performance history\n"
    assert changelog_versions(text) == ["1.2.0", "1.1.10"]


def test_the_package_version_is_the_newest_changelog_release():
    versions = changelog_versions((REPO / "CHANGELOG.md").read_text(encoding="utf-8"))
    newest = max(versions, key=lambda v: tuple(int(part) for part in v.split(".")))
    assert versions[0] == newest, f"CHANGELOG.md: the newest release {newest} is not the first heading"
    assert uvdms_gym.__version__ == newest, f"uvdms_gym.__version__ {uvdms_gym.__version__}, CHANGELOG.md {newest}"
    project = (REPO / "pyproject.toml").read_text(encoding="utf-8").split("\n[project]\n", 1)[1].split("\n[", 1)[0]
    assert re.findall(r'^version = "([^"]+)"$', project, re.MULTILINE) == [uvdms_gym.__version__]  # no tomllib on 3.10
