"""Every module, attribute and file path named in the docs, the README and the ``--help`` texts exists.

Read: ``README.md``, ``docs/**/*.md`` (``CHANGELOG.md`` is history: it names old paths on purpose and is not
read) and the help text of ``uvdms`` and of every subcommand (``--help``, built from
:func:`uvdms_cli.main.build_parser`, unwrapped). Checked:

* dotted paths of the project's packages (``uvdms_gym.physics.sim``, ``agents.export.load_agent``,
  ``scripts.ship_agent``): the longest prefix that is a module must be found (``importlib.util.find_spec``), and
  any rest resolves as attributes (a dataclass field or an annotated attribute counts);
* repository paths (``agents/training/train.py``, ``train_configs/<algo>.yml``, ``docs/MODEL.md``): the file or
  folder exists; ``<placeholder>``, ``*`` and all-caps segments (``NAME``) are wildcards that must match something;
* package-relative paths of Python files (``physics/sim.py`` in the architecture tables): a file of that relative
  path exists under one of the packages; a bare ``name.py`` in backticks is a file somewhere in the repository;
* relative Markdown link targets, from the linking file's folder.

:data:`ALLOWED` lists the names that are not paths of this checkout, each with its reason. A failure lists every
stale name with ``file:line``.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PACKAGES = ("uvdms_gym", "agents", "baselines", "leaderboard", "uvdms_cli")
TOP_DIRS = (*PACKAGES, "docs", "scripts", "benchmarks", "tests", "train_configs", "trained_agents", ".ci")
TOP_FILES = ("README.md", "CHANGELOG.md", "pyproject.toml", "mkdocs.yml", "constraints.txt", ".gitignore")
FILE_SUFFIXES = {"md", "py", "json", "csv", "yml", "yaml", "html", "zip", "png", "gif", "txt", "toml", "npz", "pt"}
FILE_SUFFIXES |= {"pkl", "sh", "js", "css", "svg", "log"}

_PATH_CHARS = r"[\w.<>*+-]"
DOTTED = re.compile(rf"(?<![\w./-])((?:{'|'.join((*PACKAGES, 'scripts'))})(?:\.[A-Za-z_]\w*)+)")
REPO_PATH = re.compile(
    rf"(?<![\w./-])((?:{'|'.join(re.escape(d) for d in TOP_DIRS)})(?:/{_PATH_CHARS}*|(?=[\s`'\"),;:]|$))"
    rf"(?:/?{_PATH_CHARS}*)*|{'|'.join(re.escape(f) for f in TOP_FILES)})"
)
RELATIVE_PY = re.compile(r"(?<![\w./<>-])((?:[a-z_][\w]*/)+[a-z_]\w*\.py)\b")
BARE_PY = re.compile(r"`([A-Za-z_]\w*\.py)`")
MD_LINK = re.compile(r"\]\(([^)\s]+)\)")

ALLOWED: dict[str, str] = {
    "agents.train_configs": "installed-only package: pyproject's package-dir installs train_configs/ there",
    "agents.trained_agents": "installed-only package: pyproject's package-dir installs trained_agents/ there",
    "agents.train_configs.search_spaces": "installed-only package (pyproject's package-dir)",
}
"""Names that are not paths of this checkout -> why they stand in the docs."""


def doc_files() -> list[Path]:
    """The Markdown files read: the README and the docs (CHANGELOG.md is history and not read)."""
    return [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]


def help_texts() -> dict[str, str]:
    """``uvdms [sub ...] --help`` text of the command and of every subcommand, by command line."""
    from uvdms_cli.main import build_parser

    texts: dict[str, str] = {}

    def walk(parser: argparse.ArgumentParser, prefix: str) -> None:
        texts[f"{prefix} --help"] = parser.format_help()
        seen: set[int] = set()
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    if id(sub) not in seen:
                        seen.add(id(sub))
                        walk(sub, f"{prefix} {name}")

    walk(build_parser(), "uvdms")
    return texts


def _lines(where: str, text: str) -> Iterator[tuple[str, str]]:
    for number, line in enumerate(text.splitlines(), start=1):
        yield f"{where}:{number}", line


def named_paths(where: str, text: str, folder: Path | None) -> Iterator[tuple[str, str, str]]:
    """``(file:line, kind, name)`` of every path named in ``text`` (``folder``: where its Markdown links start)."""
    for place, line in _lines(where, text):
        for name in DOTTED.findall(line):
            if name.rsplit(".", 1)[1] not in FILE_SUFFIXES:
                yield place, "module", name
        for name in REPO_PATH.findall(line):
            yield place, "file", name.rstrip(".:,")
        for name in RELATIVE_PY.findall(line):
            if name.split("/", 1)[0] not in TOP_DIRS:
                yield place, "package file", name
        for name in BARE_PY.findall(line):
            yield place, "file name", name
        if folder is not None:
            for target in MD_LINK.findall(line):
                if not re.match(r"[a-z]+:|#", target):
                    yield place, "link", str((folder / target.split("#", 1)[0]).resolve().relative_to(REPO))


def _module_prefix(parts: list[str]) -> int:
    """How many leading parts of a dotted name are a module (0: none)."""
    for n in range(len(parts), 0, -1):
        try:
            if importlib.util.find_spec(".".join(parts[:n])) is not None:
                return n
        except (ImportError, ValueError):  # a parent that is not a package, or a path removed in 0.4.0
            continue
    return 0


def module_exists(name: str) -> bool:
    """Whether ``name`` is a module, or a module and attributes that resolve (a module is never run)."""
    parts = name.split(".")
    n = _module_prefix(parts)
    if n == 0:
        return False
    if n == len(parts):
        return True
    obj = importlib.import_module(".".join(parts[:n]))
    for attribute in parts[n:]:
        if hasattr(obj, attribute):
            obj = getattr(obj, attribute)
        else:
            return attribute in getattr(obj, "__dataclass_fields__", {}) or attribute in getattr(
                obj, "__annotations__", {}
            )
    return True


def _pattern(name: str) -> str:
    """A path with its placeholders (``<x>``, ``*``, ``...``, all-caps segments) as ``*`` wildcards."""
    name = re.sub(r"<[^>/]*>|\.\.\.", "*", name.removesuffix("+filter"))  # `+filter`: a leaderboard entry suffix
    return "/".join("*" if re.fullmatch(r"[A-Z][A-Z0-9_]+", part) else part for part in name.split("/"))


def file_exists(name: str, roots: tuple[Path, ...] = (REPO,)) -> bool:
    """Whether the file or folder ``name`` (placeholders as wildcards) exists under one of ``roots``."""
    pattern = _pattern(name).rstrip("/")
    if "*" not in pattern:
        return any((root / pattern).exists() for root in roots)
    return any(next(root.glob(pattern), None) is not None for root in roots)


def _repo_file_names() -> set[str]:
    skip = {".venv", ".git", "site", "runs"}
    return {p.name for p in REPO.rglob("*.py") if not skip & set(p.relative_to(REPO).parts)}


def exists(kind: str, name: str) -> bool:
    """Whether the named ``kind`` of path exists in this checkout."""
    if name in ALLOWED:
        return True
    if kind == "module":
        return module_exists(name)
    if kind == "package file":
        return file_exists(name, tuple(REPO / p for p in PACKAGES))
    if kind == "file name":
        return name in _repo_file_names()
    return file_exists(name)


def stale_paths(sources: list[tuple[str, str, Path | None]]) -> list[str]:
    """``file:line: kind name`` of every named path that does not exist, in the order found."""
    stale = []
    for where, text, folder in sources:
        for place, kind, name in named_paths(where, text, folder):
            if not exists(kind, name):
                stale.append(f"{place}: {kind} {name}")
    return stale


def test_the_collector_finds_each_kind_and_refuses_what_is_gone(tmp_path):
    text = (
        "`uvdms_gym.physics.sim.UVDMSSim` and agents.config.TrainConfig.alive_bonus; `uvdms_gym.sim`, "
        "uvdms_gym.physics.sim.NoSuchName; see docs/MODEL.md. and train_configs/<algo>.yml, "
        "trained_agents/NAME/seed_<k>/, agents/no_such.py; `physics/sim.py`, `physics/nope.py`, `legacy.py`, "
        "`_moved.py`, [a](MODEL.md#x) [b](nope.md) [c](https://x.y/z.md), docs/leaderboard.md, /abs/docs/nope.md\n"
    )
    found = list(named_paths("x.md", text, REPO / "docs"))
    assert [(kind, name) for _, kind, name in found] == [
        ("module", "uvdms_gym.physics.sim.UVDMSSim"),
        ("module", "agents.config.TrainConfig.alive_bonus"),
        ("module", "uvdms_gym.sim"),
        ("module", "uvdms_gym.physics.sim.NoSuchName"),
        ("file", "docs/MODEL.md"),
        ("file", "train_configs/<algo>.yml"),
        ("file", "trained_agents/NAME/seed_<k>/"),
        ("file", "agents/no_such.py"),
        ("file", "docs/leaderboard.md"),
        ("package file", "physics/sim.py"),
        ("package file", "physics/nope.py"),
        ("file name", "legacy.py"),
        ("file name", "_moved.py"),
        ("link", "docs/MODEL.md"),
        ("link", "docs/nope.md"),
    ]
    assert stale_paths([("x.md", text, REPO / "docs")]) == [
        "x.md:1: module uvdms_gym.sim",
        "x.md:1: module uvdms_gym.physics.sim.NoSuchName",
        "x.md:1: file agents/no_such.py",
        "x.md:1: package file physics/nope.py",
        "x.md:1: file name _moved.py",
        "x.md:1: link docs/nope.md",
    ]


@pytest.fixture
def wide_help(monkeypatch):
    """Help texts unwrapped: argparse wraps at ``COLUMNS`` and may break a path at a hyphen."""
    monkeypatch.setenv("COLUMNS", "10000")


def test_every_path_named_in_the_docs_and_help_texts_exists(wide_help):
    sources = [(str(p.relative_to(REPO)), p.read_text(encoding="utf-8"), p.parent) for p in doc_files()]
    sources += [(command, text, None) for command, text in help_texts().items()]
    assert len(sources) > 40 and any(command == "uvdms sweep --help" for command, _, _ in sources)
    stale = stale_paths(sources)
    assert not stale, f"{len(stale)} stale path(s) in the docs or help texts:\n" + "\n".join(stale)
