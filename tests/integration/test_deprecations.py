"""The deprecated aliases of release 0.2 (CHANGELOG.md): they still resolve, warn, and are the new objects."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

import uvdms_gym  # noqa: F401  (registers the environments)
from uvdms_gym._moved import MOVED


@pytest.mark.parametrize("old", sorted(MOVED))
def test_old_module_paths_are_aliases_of_the_new_homes_with_a_warning(old):
    """``import uvdms_gym.sim`` (a path before the subpackages) gives the module at its home, and says where."""
    code = (
        "import importlib, warnings\n"
        "warnings.simplefilter('error', DeprecationWarning)\n"
        "import uvdms_gym\n"
        f"new = importlib.import_module({MOVED[old]!r})\n"
        "try:\n"
        f"    importlib.import_module({old!r})\n"
        "except DeprecationWarning as w:\n"
        "    print('warned:', w)\n"
        "warnings.simplefilter('ignore', DeprecationWarning)\n"
        f"alias = importlib.import_module({old!r})\n"
        "assert alias is new and alias.__spec__.name == new.__name__, (alias, new, alias.__spec__)\n"
        "print('same module')\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert f"warned: {old} moved to {MOVED[old]}" in proc.stdout and "same module" in proc.stdout


def test_the_removed_cli_alias_is_gone():
    """``uvdms_gym.cli`` (deprecated in 0.2) was removed with the package's regrouping; the command is ``uvdms``."""
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("uvdms_gym.cli")
