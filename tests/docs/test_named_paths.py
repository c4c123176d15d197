"""Every module, attribute and file path named in the docs, help texts, docstrings and configs exists.

Read: ``README.md``, ``docs/**/*.md``, the shipped agents' ``README.md``, the help text of ``uvdms`` and of every
subcommand (``--help``, built by :func:`uvdms_cli.main.build_parser`, unwrapped), the docstrings (module, class,
function and attribute) of the packages, ``scripts/`` and ``benchmarks/``, and ``train_configs/**/*.yml`` with
their comments. ``CHANGELOG.md`` is history (it names old paths on purpose) and is not read. Checked:

* dotted paths of the project's packages (``uvdms_gym.physics.sim``, ``agents.export.load_agent``,
  ``scripts.ship_agent``): the longest prefix that is a module must be found (``importlib.util.find_spec``), and
  any rest resolves as attributes (a dataclass field or an annotated attribute counts);
* repository paths (``agents/training/train.py``, ``train_configs/<algo>.yml``, ``docs/MODEL.md``): the file or
  folder exists; ``<placeholder>``, ``*`` and all-caps segments (``NAME``) are wildcards that must match something;
* package-relative paths of Python files (``physics/sim.py`` in the architecture tables): a file of that relative
  path exists under one of the packages; a bare ``name.py`` in backticks is a file somewhere in the repository;
* relative Markdown link targets, from the linking file's folder.

:data:`ALLOWED` lists the names that are not paths of this checkout, each with its reason; the old module paths of
the legacy tables may stand in :data:`LEGACY_FILES` only, which describe their removal. A failure lists every stale
name with ``file:line``.
"""

from __future__ import annotations

import argparse
import ast
import functools
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

_PATH_CHARS = r"(?:[\w.<>*+-]|\{[\w.,-]*\})"  # {a,b}: alternatives
DOTTED = re.compile(rf"(?<![\w./-])((?:{'|'.join((*PACKAGES, 'scripts'))})(?:\.[A-Za-z_]\w*)+)")
REPO_PATH = re.compile(  # not inside a Markdown link target: those are relative to the linking file
    rf"(?<![\w./-])(?<!\]\()((?:{'|'.join(re.escape(d) for d in TOP_DIRS)})(?:/{_PATH_CHARS}*|(?=[\s`'\"),;:]|$))"
    rf"(?:/?{_PATH_CHARS}*)*|{'|'.join(re.escape(f) for f in TOP_FILES)})"
)
RELATIVE_PY = re.compile(r"(?<![\w./<>-])((?:[a-z_][\w]*/)+[a-z_]\w*\.py)\b")
BARE_PY = re.compile(r"`([A-Za-z_]\w*\.py)`")
MD_LINK = re.compile(r"\]\(([^)\s]+)\)")

ALLOWED: dict[str, str] = {
    "agents.train_configs": "installed-only package: pyproject's package-dir installs train_configs/ there",
    "agents.trained_agents": "installed-only package: pyproject's package-dir installs trained_agents/ there",
    "agents.train_configs.search_spaces": "installed-only package (pyproject's package-dir)",
    "hyperparams_opt.py": "RL Zoo's file (rl_zoo3/hyperparams_opt.py), whose samplers the search spaces transcribe",
    "proxsuite/__init__.py": "ProxSuite's file (the installed proxsuite package), which picks the SIMD build",
    "rl_zoo3/hyperparams_opt.py": "RL Zoo's file, whose samplers the search spaces transcribe",
    "agents/train_configs/*.yml": "where an installed (non-editable) package holds the configs (agents.common.paths)",
    "agents/trained_agents/<name>/": "where an installed (non-editable) package holds the shipped agents",
    "trained_agents/x+filter": "a placeholder agent folder with the leaderboard's +filter suffix",
}
"""Names that are not paths of this checkout -> why they stand where they do."""
LEGACY_FILES = (
    "uvdms_gym/utils/legacy.py",
    "agents/common/legacy.py",
    "agents/__init__.py",
    "agents/config/zoo.py",
    "baselines/legacy.py",
    "baselines/__init__.py",
    "leaderboard/legacy.py",
    "leaderboard/__init__.py",
)
"""Files that describe the module paths removed or moved in 0.4.0 and may name them (the legacy tables' old names
only)."""
SHIPPED_ALIAS_FILES = ("agents/common/paths.py",)
"""Files that describe the former names of renamed shipped folders (``trained_agents/circle_case1_ppo``)."""

Source = tuple[str, int, str, "Path | None"]
"""Where (file or command), the line number of the text's first line, the text, the folder its links start from."""


def markdown_sources() -> list[Source]:
    """The README, the docs and the shipped agents' READMEs (not CHANGELOG.md: history)."""
    files = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md")), *sorted(REPO.glob("trained_agents/*/*.md"))]
    return [(str(p.relative_to(REPO)), 1, p.read_text(encoding="utf-8"), p.parent) for p in files]


def help_sources() -> list[Source]:
    """``uvdms [sub ...] --help`` of the command and of every subcommand (set ``COLUMNS`` wide first)."""
    from uvdms_cli.main import build_parser

    sources: list[Source] = []

    def walk(parser: argparse.ArgumentParser, command: str) -> None:
        sources.append((f"{command} --help", 1, parser.format_help(), None))
        seen: set[int] = set()
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    if id(sub) not in seen:
                        seen.add(id(sub))
                        walk(sub, f"{command} {name}")

    walk(build_parser(), "uvdms")
    return sources


def docstring_sources() -> list[Source]:
    """Every string statement (module, class, function and attribute docstrings) of the project's Python files."""
    sources: list[Source] = []
    for folder in (*PACKAGES, "scripts", "benchmarks"):
        for path in sorted((REPO / folder).rglob("*.py")):
            where = str(path.relative_to(REPO))
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
                    if isinstance(node.value.value, str):
                        sources.append((where, node.lineno, node.value.value, None))
    return sources


def config_sources() -> list[Source]:
    """The training configurations and search spaces, comments included."""
    files = sorted((REPO / "train_configs").rglob("*.yml"))
    return [(str(p.relative_to(REPO)), 1, p.read_text(encoding="utf-8"), None) for p in files]


def _names_in_line(line: str, folder: Path | None) -> Iterator[tuple[str, str]]:
    """``(kind, name)`` of every path named in one line."""
    yield from (("module", n) for n in DOTTED.findall(line) if n.rsplit(".", 1)[1] not in FILE_SUFFIXES)
    yield from (("file", n.rstrip(".:,")) for n in REPO_PATH.findall(line))
    yield from (("package file", n) for n in RELATIVE_PY.findall(line) if n.split("/", 1)[0] not in TOP_DIRS)
    yield from (("file name", n) for n in BARE_PY.findall(line))
    if folder is not None:
        for target in MD_LINK.findall(line):
            if not re.match(r"[a-z]+:|#", target):
                yield "link", str((folder / target.split("#", 1)[0]).resolve().relative_to(REPO))


def named_paths(where: str, first_line: int, text: str, folder: Path | None) -> Iterator[tuple[str, str, str]]:
    """``(file:line, kind, name)`` of every path named in ``text`` (``folder``: where its Markdown links start)."""
    for number, line in enumerate(text.splitlines(), start=first_line):
        for kind, name in _names_in_line(line, folder):
            yield f"{where}:{number}", kind, name


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


def _alternatives(name: str) -> list[str]:
    """``a/{b,c}.json`` -> ``["a/b.json", "a/c.json"]`` (every brace group expanded)."""
    match = re.search(r"\{([^{}]*)\}", name)
    if match is None:
        return [name]
    head, tail = name[: match.start()], name[match.end() :]
    return [path for option in match.group(1).split(",") for path in _alternatives(head + option + tail)]


def _one_exists(pattern: str, roots: tuple[Path, ...]) -> bool:
    if "*" not in pattern:
        return any((root / pattern).exists() for root in roots)
    return any(next(root.glob(pattern), None) is not None for root in roots)


def file_exists(name: str, roots: tuple[Path, ...] = (REPO,)) -> bool:
    """Whether the file or folder ``name`` (placeholders as wildcards, each ``{a,b}`` alternative) exists."""
    return all(_one_exists(_pattern(path).rstrip("/"), roots) for path in _alternatives(name))


@functools.cache
def _repo_file_names() -> frozenset[str]:
    skip = {".venv", ".git", "site", "runs"}
    return frozenset(p.name for p in REPO.rglob("*.py") if not skip & set(p.relative_to(REPO).parts))


def _legacy_names() -> set[str]:
    from agents.common.legacy import MOVED as AGENTS_MOVED
    from baselines.legacy import REGROUPED as BASELINES_REGROUPED
    from leaderboard.legacy import REGROUPED as LEADERBOARD_REGROUPED
    from uvdms_gym.utils.legacy import MOVED, REGROUPED

    return {*MOVED, *AGENTS_MOVED, *REGROUPED, *BASELINES_REGROUPED, *LEADERBOARD_REGROUPED}


@functools.cache
def exists(kind: str, name: str) -> bool:
    """Whether the named ``kind`` of path exists in this checkout (or is allowed: :data:`ALLOWED`)."""
    if name in ALLOWED:
        return True
    if kind == "module":
        return module_exists(name)
    if kind == "package file":
        return file_exists(name, tuple(REPO / p for p in PACKAGES))
    if kind == "file name":
        return name in _repo_file_names()
    return file_exists(name)


def _legacy_mention(place: str, kind: str, name: str) -> bool:
    """An old module path (or a name in it), or a former shipped folder name, in a file that describes it."""
    from agents.common.paths import SHIPPED_ALIASES

    where = place.rsplit(":", 1)[0]
    if where in SHIPPED_ALIAS_FILES and kind == "file":
        return name.rstrip("/").removeprefix("trained_agents/") in SHIPPED_ALIASES
    legacy = _legacy_names()
    return where in LEGACY_FILES and kind == "module" and (name in legacy or name.rsplit(".", 1)[0] in legacy)


def stale_paths(sources: list[Source]) -> list[str]:
    """``file:line: kind name`` of every named path that does not exist, in the order found."""
    stale = []
    for where, first_line, text, folder in sources:
        for place, kind, name in named_paths(where, first_line, text, folder):
            if not exists(kind, name) and not _legacy_mention(place, kind, name):
                stale.append(f"{place}: {kind} {name}")
    return stale


def test_the_collector_finds_each_kind_and_refuses_what_is_gone():
    text = (
        "`uvdms_gym.physics.sim.UVDMSSim` and agents.config.TrainConfig.alive_bonus; `uvdms_gym.sim`, "
        "uvdms_gym.physics.sim.NoSuchName; see docs/MODEL.md. and train_configs/<algo>.yml, "
        "trained_agents/NAME/seed_<k>/, agents/no_such.py; `physics/sim.py`, `physics/nope.py`, `legacy.py`, "
        "`_moved.py`, [a](MODEL.md#x) [b](nope.md) [c](https://x.y/z.md) [d](leaderboard/index.html), "
        "docs/leaderboard.md, /abs/docs/nope.md, leaderboard.md, python -m scripts.ship_agent\n"
        "second line: uvdms_gym.utils.legacy.MOVED, `agents.wrappers.*`, the leaderboard. Then\n"
        "trained_agents/reference/<task>_{campc,random}.json, docs/{MODEL,NOPE}.md, trained_agents/circle_case1_ppo\n"
    )
    found = list(named_paths("x.md", 7, text, REPO / "docs"))
    assert [(kind, name) for _, kind, name in found] == [
        ("module", "uvdms_gym.physics.sim.UVDMSSim"),
        ("module", "agents.config.TrainConfig.alive_bonus"),
        ("module", "uvdms_gym.sim"),
        ("module", "uvdms_gym.physics.sim.NoSuchName"),
        ("module", "scripts.ship_agent"),
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
        ("link", "docs/leaderboard/index.html"),
        ("module", "uvdms_gym.utils.legacy.MOVED"),
        ("module", "agents.wrappers"),
        ("file", "trained_agents/reference/<task>_{campc,random}.json"),
        ("file", "docs/{MODEL,NOPE}.md"),
        ("file", "trained_agents/circle_case1_ppo"),
    ]
    assert {place for place, _, _ in found} == {"x.md:7", "x.md:8", "x.md:9"}
    assert stale_paths([("x.md", 7, text, REPO / "docs")]) == [
        "x.md:7: module uvdms_gym.sim",
        "x.md:7: module uvdms_gym.physics.sim.NoSuchName",
        "x.md:7: file agents/no_such.py",
        "x.md:7: package file physics/nope.py",
        "x.md:7: file name _moved.py",
        "x.md:7: link docs/nope.md",
        "x.md:8: module agents.wrappers",
        "x.md:9: file docs/{MODEL,NOPE}.md",
        "x.md:9: file trained_agents/circle_case1_ppo",
    ]
    assert stale_paths([("agents/config/zoo.py", 1, "``agents.wrappers.AliveBonus`` and agents.nope", None)]) == [
        "agents/config/zoo.py:1: module agents.nope"  # an old path of the legacy tables may stand there, no other
    ]
    assert stale_paths(
        [("agents/common/paths.py", 3, "trained_agents/circle_case1_ppo, trained_agents/nope", None)]
    ) == [
        "agents/common/paths.py:3: file trained_agents/nope"  # a former shipped name may stand there
    ]


def test_docstrings_are_read_with_their_line_numbers():
    sources = [s for s in docstring_sources() if s[0] == "uvdms_gym/utils/legacy.py"]
    lines = (REPO / "uvdms_gym" / "utils" / "legacy.py").read_text(encoding="utf-8").splitlines()
    for _, first_line, text, _ in sources:
        assert lines[first_line - 1].lstrip().startswith('"""' + text.splitlines()[0])
    assert len(sources) >= 5


@pytest.fixture
def wide_help(monkeypatch):
    """Help texts unwrapped: argparse wraps at ``COLUMNS`` and may break a path at a hyphen."""
    monkeypatch.setenv("COLUMNS", "10000")


def test_every_path_named_in_the_docs_help_texts_docstrings_and_configs_exists(wide_help):
    help_texts = help_sources()
    assert {"uvdms --help", "uvdms sweep --help", "uvdms tune --help", "uvdms train --help"} <= {
        where for where, _, _, _ in help_texts
    }
    sources = [*markdown_sources(), *help_texts, *docstring_sources(), *config_sources()]
    stale = stale_paths(sources)
    assert not stale, f"{len(stale)} stale path(s):\n" + "\n".join(stale)
