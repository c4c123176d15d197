"""The documentation site: it builds in strict mode, its code runs, its generated pages are current, and a newcomer
finds the essentials from the front page.

The ``uvdms`` commands of the pages' ```bash blocks run in ``tests/docs/test_readme_commands.py`` (with the
README's); here every ```python block of the README and of the pages runs as a script of its own.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest

import uvdms_gym
from scripts import docs_env_pages

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
GENERATED = (DOCS / "leaderboard",)
"""Folders whose pages are written by a program (``uvdms leaderboard``), not by hand."""


def doc_pages() -> list[Path]:
    """README.md and every Markdown page of the site written by hand."""
    pages = sorted(p for p in DOCS.rglob("*.md") if not any(p.is_relative_to(g) for g in GENERATED))
    return [REPO / "README.md", *pages]


def python_blocks() -> list[tuple[str, int, str]]:
    """``(page, index, code)`` of every ```python block."""
    out = []
    for page in doc_pages():
        blocks = re.findall(r"^```python\n(.*?)^```", page.read_text(encoding="utf-8"), flags=re.M | re.S)
        out += [(str(page.relative_to(REPO)), i, code) for i, code in enumerate(blocks)]
    return out


BLOCKS = python_blocks()


def test_there_are_python_blocks_to_run():
    pages = {page for page, _, _ in BLOCKS}
    assert {"README.md", "docs/getting-started.md", "docs/simulator.md"} <= pages


@pytest.mark.slow
@pytest.mark.parametrize(("page", "index", "code"), BLOCKS, ids=[f"{p}:{i}" for p, i, _ in BLOCKS])
def test_python_block_runs(page, index, code, tmp_path):
    if "RecordVideo" in code:  # the video extra (its page names it before the block: tests/docs/test_newcomer.py)
        pytest.importorskip("moviepy", reason="the video extra is not installed")
    environ = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "UVDMS_DEBUG")}
    environ["PYTHONPATH"] = os.pathsep.join([str(REPO), environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    environ["MPLBACKEND"] = "Agg"
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env=environ, capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, f"{page} python block {index} failed:\n{proc.stderr[-3000:]}"


@pytest.mark.slow
def test_the_site_builds_in_strict_mode(tmp_path):
    """``mkdocs build --strict``: a broken link or anchor, a page missing from the nav or an API reference that
    does not load is an error."""
    mkdocs = Path(sys.executable).parent / "mkdocs"
    environ = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    proc = subprocess.run(
        [str(mkdocs), "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=REPO,
        env=environ,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-5000:]
    assert "WARNING" not in proc.stderr, proc.stderr[-5000:]
    site = tmp_path / "site"
    assert (site / "environments" / "Transport-v1.html").exists()  # use_directory_urls: false (mkdocs.yml)
    assert (site / "leaderboard.html").exists()  # the leaderboard page is part of the site
    api = (site / "api" / "uvdms_gym.html").read_text(encoding="utf-8")
    assert "run_episode" in api and "CircleTrackEnv" in api  # the reference was generated from the docstrings


def test_environment_pages_are_current():
    """The committed pages equal what ``scripts/docs_env_pages.py`` writes from the code today."""
    stale = []
    for env_id in uvdms_gym.ENV_IDS:
        path = DOCS / "environments" / docs_env_pages.page_name(env_id)
        if not path.exists() or path.read_text(encoding="utf-8") != docs_env_pages.page(env_id):
            stale.append(path.name)
    assert not stale, f"run python scripts/docs_env_pages.py: stale pages {stale}"


def test_environment_page_keywords_are_the_constructor_keywords():
    """Every keyword the constructor takes is in the table with the default the environment really uses."""
    env = gym.make("uvdms/Transport-v1")
    try:
        weights = env.unwrapped.weights
        table = (DOCS / "environments" / "Transport-v1.md").read_text(encoding="utf-8")
        for name in ("track", "orientation", "effort", "proximity", "contact", "precision"):
            assert f"| `{name}_weight` | `{weights[name]!r}` |" in table, name
        assert f"| `track_scale` | `{env.unwrapped.track_scale!r}` |" in table
    finally:
        env.close()
    defaults = docs_env_pages.keyword_defaults(type(env.unwrapped))
    assert {"goal", "move_time", "hydro_randomization", "current", "precision_weight"} <= set(defaults)


def _links(page: Path) -> list[Path]:
    text = page.read_text(encoding="utf-8")
    return [(page.parent / m.split("#")[0]).resolve() for m in re.findall(r"\]\(([^)#\s]+\.md)(?:#[^)]*)?\)", text)]


def test_a_newcomer_finds_the_essentials_within_two_clicks_of_the_front_page():
    front = DOCS / "index.md"
    one_click = set(_links(front))
    two_clicks = one_click | {target for page in one_click if page.exists() for target in _links(page)}
    transport = (DOCS / "environments" / "Transport-v1.md").resolve()
    assert transport in two_clicks
    layout = transport.read_text(encoding="utf-8")
    assert "## Observation Space" in layout and "| `62:80` | 18 |" in layout
    getting_started = (DOCS / "getting-started.md").resolve()
    assert getting_started in one_click
    assert "## Evaluate your own agent" in getting_started.read_text(encoding="utf-8")
    submit = (DOCS / "submit.md").resolve()
    assert submit in one_click
    assert "uvdms leaderboard --entries baselines agents out/my_export" in submit.read_text(encoding="utf-8")
