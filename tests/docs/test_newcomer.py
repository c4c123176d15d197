"""A newcomer's afternoon with the docs (issue 37): the pages, followed literally, work and leave the checkout clean.

* the built site links to the interactive leaderboard page (not a text page written over it) and requests nothing
  from the network (no web fonts, no scripts or styles from elsewhere, no repository API);
* a Python block that needs an extra names the extra's install command before it;
* every file or folder the documented commands write is one git ignores (or a committed output they regenerate);
* ``docs/submit.md`` end to end at a tiny budget: train, export (what the export holds, when ``--trust`` is needed,
  what ``--which best`` says after a run without evaluation), rank.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
UVDMS = Path(sys.executable).parent / "uvdms"
INTERACTIVE_MARKER = "<title>uvdms-gym leaderboard</title>"
"""What the interactive page (``docs/leaderboard/index.html``) has and a rendered Markdown page has not."""
COMMITTED_OUTPUTS = ("docs/leaderboard", "docs/figures")
"""Folders the docs' commands regenerate on purpose (their files are committed)."""


def pages() -> list[Path]:
    """README.md and the hand-written pages of the site."""
    return [REPO / "README.md", *sorted(p for p in DOCS.rglob("*.md") if not p.is_relative_to(DOCS / "leaderboard"))]


SHELL_LANGUAGES = ("bash", "sh", "shell", "console", "")
"""Info strings of a fenced block that may hold shell commands: ```bash, ```sh (and ```shell, ```console) or none."""


def fenced_blocks(text: str) -> list[tuple[str, str]]:
    """The fenced code blocks of ``text``: ``(info string, body)`` pairs, fences paired in order."""
    blocks, info, body = [], None, []
    for line in text.splitlines():
        if info is None:
            if line.startswith("```"):
                info, body = line[3:].strip(), []
        elif line.strip() == "```":
            blocks.append((info, "\n".join(body) + "\n"))
            info = None
        else:
            body.append(line)
    return blocks


def bash_commands(text: str) -> list[list[str]]:
    """The ``uvdms`` commands of the shell blocks of ``text`` (tokens; comments dropped, chains split).

    ```bash, ```sh and plain ``` blocks count alike (:data:`SHELL_LANGUAGES`; not ```python, ```yaml, ...). A
    command is a line (or ``&&`` part) run by ``uvdms`` or ``.venv/bin/uvdms``.
    """
    out = []
    for info, block in fenced_blocks(text):
        if info not in SHELL_LANGUAGES:
            continue
        for line in block.replace("\\\n", " ").splitlines():
            for part in line.split("&&"):
                try:
                    tokens = shlex.split(part, comments=True)
                except ValueError:  # not shell (an unbalanced quote in a plain block's text)
                    continue
                if tokens and (tokens[0] == "uvdms" or tokens[0].endswith("/uvdms")):
                    out.append(["uvdms", *tokens[1:]])
    return out


def _run(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    environ = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "UVDMS_DEBUG")}
    environ["PYTHONPATH"] = os.pathsep.join([str(REPO), environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return subprocess.run([str(UVDMS), *argv[1:]], cwd=cwd, env=environ, capture_output=True, text=True, timeout=900)


# --- the site ---------------------------------------------------------------------------------------------------

EXTERNAL_LOADS = re.compile(
    r"<link\b[^>]*\bhref=[\"'](?:https?:)?//|<script\b[^>]*\bsrc=[\"'](?:https?:)?//|<img\b[^>]*\bsrc=[\"'](?:https?:)?//"
    r"|@import\s+url\([\"']?(?:https?:)?//|fonts\.googleapis|fonts\.gstatic|api\.github\.com",
    re.I,
)
"""What makes a browser fetch from another host: a stylesheet, script or image, a CSS import, a font, an API."""


def test_the_site_config_has_no_placeholder_repository_and_no_web_fonts():
    text = (REPO / "mkdocs.yml").read_text(encoding="utf-8")
    config = yaml.load(text, Loader=yaml.BaseLoader)  # BaseLoader: strings only, no tags
    assert "repo_url" not in config  # material fetches the repository's stars from api.github.com
    assert config["theme"].get("font") == "false"  # no Google Fonts


@pytest.mark.slow
def test_the_built_site_links_to_the_interactive_page_and_loads_nothing_from_elsewhere(tmp_path):
    mkdocs = Path(sys.executable).parent / "mkdocs"
    site = tmp_path / "site"
    proc = subprocess.run(
        [str(mkdocs), "build", "--strict", "--site-dir", str(site)],
        cwd=REPO,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    linking = 0
    for page in site.rglob("*.html"):
        html = page.read_text(encoding="utf-8")
        if page.is_relative_to(site / "leaderboard") and page.name == "index.html":
            assert INTERACTIVE_MARKER in html  # the static page survived the build
        for href in re.findall(r"<a\b[^>]*href=\"([^\"#]+)[^\"]*\"[^>]*>\s*interactive page\s*</a>", html):
            target = (page.parent / href).resolve()
            assert target.is_file(), f"{page.relative_to(site)}: {href} does not exist"
            assert INTERACTIVE_MARKER in target.read_text(encoding="utf-8"), f"{page.relative_to(site)}: {href}"
            linking += 1
        loads = EXTERNAL_LOADS.findall(html)
        assert not loads, f"{page.relative_to(site)} loads from the network: {loads[:5]}"
    assert linking >= 2  # the front page and the leaderboard page
    for css in site.rglob("*.css"):
        assert not EXTERNAL_LOADS.findall(css.read_text(encoding="utf-8")), css.relative_to(site)


# --- the pages' Python blocks and outputs --------------------------------------------------------------------------

EXTRAS = {"video": ("RecordVideo", "moviepy"), "zoo": ("rl_zoo3",), "ray": ("import ray", "from ray")}
"""Extra -> what in a Python block needs it."""


def test_a_python_block_that_needs_an_extra_names_it_before_the_block():
    found = 0
    for page in pages():
        text = page.read_text(encoding="utf-8")
        for match in re.finditer(r"^```python\n(.*?)^```", text, flags=re.M | re.S):
            for extra, markers in EXTRAS.items():
                if any(marker in match.group(1) for marker in markers):
                    found += 1
                    before = text[: match.start()].rsplit("\n#", 1)[-1]  # this section, up to the block
                    install = f'pip install -c constraints.txt -e ".[{extra}]"'
                    assert install in before, f"{page.name}: a block needs the {extra} extra; name {install} first"
    assert found >= 1  # getting-started's RecordVideo block


OUTPUT_OPTIONS = ("--out", "--cache-dir", "--png")
"""Options whose value is a file or folder the command writes (``uvdms demo --png``: a rendered frame)."""


FOLDER_COMMANDS = ("train", "sweep", "tune", "leaderboard", "reproduce")
"""Subcommands whose ``--out`` (and ``--cache-dir``) is a folder."""


def _outputs(argv: list[str]) -> list[str]:
    """What a documented command writes, relative to the working directory."""
    command = argv[1] if len(argv) > 1 else ""
    outputs = [argv[i + 1] for i, t in enumerate(argv[:-1]) if t in OUTPUT_OPTIONS]
    if command in FOLDER_COMMANDS:  # a folder: a trailing slash, so that git's folder-only patterns (runs/) match
        outputs = [o if o.endswith("/") else o + "/" for o in outputs]
    if command == "export-agent":
        outputs.append([t for t in argv[2:] if not t.startswith("-")][1])
    if command in ("train", "sweep") and "--out" not in argv:
        outputs.append("runs/")
    if command == "leaderboard" and "--out" not in argv:
        outputs.append("leaderboard_out/")
    return outputs


def _python_outputs(code: str) -> list[str]:
    return re.findall(r"(?:video_folder|save_path|log_path)=[\"']([^\"']+)[\"']", code) + re.findall(
        r"\.(?:save|savefig)\([\"']([^\"']+)[\"']", code
    )


def test_what_the_documented_commands_write_is_ignored_by_git():
    outputs = set()
    for page in pages():
        text = page.read_text(encoding="utf-8")
        outputs |= {out for argv in bash_commands(text) for out in _outputs(argv)}
        for code in re.findall(r"^```python\n(.*?)^```", text, flags=re.M | re.S):
            outputs |= set(_python_outputs(code))
    outputs = {o for o in outputs if not o.startswith(COMMITTED_OUTPUTS) and not o.startswith(("/", "$"))}
    # git check-ignore prints the ignored ones (--no-index: whether tracked or not)
    proc = subprocess.run(
        ["git", "check-ignore", "--no-index", *sorted(outputs)], cwd=REPO, capture_output=True, text=True
    )
    ignored = set(proc.stdout.split())
    assert sorted(outputs - ignored) == [], "the docs' commands write files git would list as untracked"
    assert {"out/eval.json", "out/my_export", "runs/", "out/videos"} <= outputs


# --- docs/submit.md end to end ------------------------------------------------------------------------------------

TINY_SAC = ["learning_starts=50", "eval_freq=100000", "n_eval_episodes=1", "checkpoint_freq=0"]
"""SAC at a tiny budget, with no evaluation in the run (so no best_model.zip)."""
SHRINK = ["--tasks", "case1", "--episodes", "1", "--max-episode-steps", "10", "--no-progress", "--no-plots"]
"""What the test adds to the leaderboard commands of submit.md: one task, one short episode."""


@pytest.mark.slow
def test_submit_md_end_to_end_at_a_tiny_budget(tmp_path):
    (tmp_path / "trained_agents").symlink_to(REPO / "trained_agents", target_is_directory=True)
    text = (DOCS / "submit.md").read_text(encoding="utf-8")
    # 1. train (on the v1 circle task's randomised variant, as step 1 asks)
    train = ["uvdms", "train", "--algo", "sac", "--env", "uvdms/CircleTrack-v1", "--env-kwargs", "case=random"]
    train += ["max_episode_steps=20", "--total-timesteps", "150", "--hyperparams", *TINY_SAC, "--no-progress"]
    proc = _run(train, tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run_dir,) = (tmp_path / "runs").glob("*/sac_0")
    # 2. export, with the command of step 2 (RUN_DIR substituted)
    (export,) = re.findall(r"`(uvdms export-agent RUN_DIR [^`]*)`", text)
    argv = [str(run_dir) if t == "RUN_DIR" else t for t in shlex.split(export)]
    refused = _run([t for t in argv if t != "--trust"], tmp_path)  # a run under runs/ needs --trust too
    assert refused.returncode == 2 and "--trust" in refused.stderr, refused.stderr
    best = _run([*argv[:3], "out/best", "--which", "best", "--trust"], tmp_path)
    assert best.returncode == 2 and "--which final" in best.stderr, best.stderr  # no evaluation ran: what to do
    proc = _run(argv, tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    held = sorted(p.name for p in (tmp_path / argv[3]).iterdir())
    assert held == ["agent.json", "meta.json", "policy.pt"]  # a SAC run without evaluation: what step 2 says
    assert "a SAC run\n   exports `agent.json`, `meta.json` and `policy.pt`" in text
    # 3. rank, with the block of step 3 (its first line exports a shipped agent instead of ours: skipped)
    commands = [c for c in bash_commands(text) if c[1] == "leaderboard" and "--entries" in c]
    assert any("--quick" in c for c in commands) and any("--quick" not in c for c in commands)
    quick = next(c for c in commands if "--quick" in c)
    proc = _run([*quick, *SHRINK], tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "leaderboard_out" / "entries" / "my_export.json").is_file()
    assert "my_export" in (tmp_path / "leaderboard_out" / "leaderboard.md").read_text(encoding="utf-8")
    full = re.search(r"Without `--quick` this is the full suite \(([^)]*)\)", text.replace("\n   ", " "))
    assert full and "hours" in full.group(1)
