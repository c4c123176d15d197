"""The module paths ``uvdms_gym`` had before it was grouped into subpackages, importable with a warning.

``import uvdms_gym.sim`` (or ``from uvdms_gym.params import UVDMSParams``) still works: the old name is an alias
of the module at its new home (the same module object), and importing it warns with a ``DeprecationWarning`` that
names the new path. New code imports the new paths (``CHANGELOG.md``).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import types
import warnings

MOVED: dict[str, str] = {
    "uvdms_gym.params": "uvdms_gym.physics.params",
    "uvdms_gym.frames": "uvdms_gym.physics.frames",
    "uvdms_gym.model": "uvdms_gym.physics.model",
    "uvdms_gym.kinematics": "uvdms_gym.physics.kinematics",
    "uvdms_gym.nominal": "uvdms_gym.physics.nominal",
    "uvdms_gym.hydro": "uvdms_gym.physics.hydro",
    "uvdms_gym.sim": "uvdms_gym.physics.sim",
    "uvdms_gym.geometry": "uvdms_gym.distances.geometry",
    "uvdms_gym.distances_pybullet": "uvdms_gym.distances.pybullet_queries",
    "uvdms_gym.io": "uvdms_gym.utils.io",
    "uvdms_gym.kwargs": "uvdms_gym.utils.kwargs",
    "uvdms_gym.provenance": "uvdms_gym.utils.provenance",
    "uvdms_gym.cluster": "uvdms_gym.utils.cluster",
    "uvdms_gym.display": "uvdms_gym.utils.display",
}
"""Old module name -> its home."""


class MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Resolves the names of :data:`MOVED` to the modules at their new homes (installed on ``sys.meta_path``)."""

    def __init__(self) -> None:
        self._home_specs: dict[str, importlib.machinery.ModuleSpec] = {}

    def find_spec(
        self, fullname: str, path: object = None, target: types.ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        """A spec for an old name (loaded by this finder), ``None`` for every other name."""
        if fullname not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        """The module at the new home (imported if needed), with a ``DeprecationWarning`` naming it."""
        new = MOVED[spec.name]
        warnings.warn(f"{spec.name} moved to {new}; import it from there", DeprecationWarning, stacklevel=2)
        module = importlib.import_module(new)
        self._home_specs[spec.name] = module.__spec__
        return module

    def exec_module(self, module: types.ModuleType) -> None:
        """Nothing to run; the module keeps its own spec (the import system set the alias's)."""
        module.__spec__ = self._home_specs.pop(module.__spec__.name)
