"""The size rules of docs/ARCHITECTURE.md ("Size rules"): short modules, short functions, grouped packages.

- No library module over :data:`MAX_MODULE_LINES` lines.
- No function over :data:`MAX_FUNCTION_LINES` lines of code (its docstring not counted), except a hot path that
  says why in one comment line starting ``# hot path:`` within its first lines (see :func:`is_hot_path`).
- ``leaderboard/`` and ``baselines/`` each hold at least :data:`MIN_SUBPACKAGES` subpackages and at most
  :data:`MAX_TOP_MODULES` top-level modules (``__init__.py`` not counted); ``leaderboard/__init__.py`` is short.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("uvdms_gym", "baselines", "agents", "leaderboard", "uvdms_cli")
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80
MIN_SUBPACKAGES = 3
MAX_TOP_MODULES = 8
MAX_INIT_LINES = 60
HOT_PATH_MARK = "# hot path:"
HOT_PATH_WINDOW = 3  # the mark stands above the decorators and def, on the def line or on one of the next lines


def library_modules() -> list[Path]:
    """Every Python file of the library packages."""
    return sorted(p for package in PACKAGES for p in (ROOT / package).rglob("*.py"))


def code_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """The function's lines, decorators excluded, less its docstring's lines."""
    lines = node.end_lineno - node.lineno + 1
    body = node.body
    first = body[0] if body else None
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        lines -= first.end_lineno - first.lineno + 1
    return lines


def is_hot_path(node: ast.FunctionDef | ast.AsyncFunctionDef, source_lines: list[str]) -> bool:
    """Whether one of the function's first lines carries the ``# hot path: <why>`` comment."""
    first = min([d.lineno for d in node.decorator_list] + [node.lineno])  # the first decorator's line, or the def's
    window = source_lines[max(first - 2, 0) : node.lineno + HOT_PATH_WINDOW]
    return any(HOT_PATH_MARK in line and line.split(HOT_PATH_MARK, 1)[1].strip() for line in window)


def long_functions(source: str) -> list[tuple[str, int, int]]:
    """(name, line, code lines) of every function over the limit that is not a marked hot path."""
    lines = source.splitlines()
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            n = code_lines(node)
            if n > MAX_FUNCTION_LINES and not is_hot_path(node, lines):
                found.append((node.name, node.lineno, n))
    return found


def test_the_checker_counts_code_not_docstrings_and_honours_the_mark():
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES))
    doc = '    """A docstring\n\n    of several lines.\n    """\n'
    one_too_many = f"def f():\n{doc}{body}\n"  # the def line and MAX_FUNCTION_LINES body lines
    assert long_functions(one_too_many) == [("f", 1, MAX_FUNCTION_LINES + 1)]
    assert long_functions(f"def f():\n{doc}{body[: body.rfind(chr(10))]}\n") == []  # one line fewer
    assert long_functions(f"def f():  # hot path: one kernel, numba inlines it whole\n{doc}{body}\n") == []
    assert long_functions(f"# hot path: one kernel, numba inlines it whole\ndef f():\n{doc}{body}\n") == []
    assert long_functions(f"def f():  # hot path:\n{doc}{body}\n") != []  # the mark must say why


@pytest.mark.parametrize("path", library_modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_module_and_function_sizes(path: Path):
    source = path.read_text()
    n_lines = len(source.splitlines())
    assert n_lines <= MAX_MODULE_LINES, f"{path.relative_to(ROOT)}: {n_lines} lines > {MAX_MODULE_LINES}"
    too_long = long_functions(source)
    assert not too_long, f"{path.relative_to(ROOT)}: functions over {MAX_FUNCTION_LINES} lines of code: {too_long}"


@pytest.mark.parametrize("package", ["leaderboard", "baselines"])
def test_grouped_packages(package: str):
    root = ROOT / package
    subpackages = [p for p in root.iterdir() if (p / "__init__.py").is_file()]
    top_modules = [p for p in root.glob("*.py") if p.name != "__init__.py"]
    assert len(subpackages) >= MIN_SUBPACKAGES, f"{package}/: subpackages {sorted(p.name for p in subpackages)}"
    assert len(top_modules) <= MAX_TOP_MODULES, f"{package}/: top-level modules {sorted(p.name for p in top_modules)}"


def test_leaderboard_init_is_short():
    n_lines = len((ROOT / "leaderboard" / "__init__.py").read_text().splitlines())
    assert n_lines <= MAX_INIT_LINES, f"leaderboard/__init__.py: {n_lines} lines > {MAX_INIT_LINES}"
