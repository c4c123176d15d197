"""Module paths removed with the compatibility layer: importing one fails in one line naming its new home.

Release 0.3.0 grouped the packages into subpackages and kept the old module paths as deprecated aliases; 0.4.0
removed the aliases. A package keeps a table ``{old module: new module}`` of what it moved and installs a
:class:`MovedModuleFinder` for it on import (:func:`install_moved_finder`; ``uvdms_gym`` for :data:`MOVED`,
``agents`` for :data:`agents.common.legacy.MOVED`), in the style of Gymnasium's ``_renamed_wrapper``:
``import uvdms_gym.sim`` raises ``ModuleNotFoundError: uvdms_gym.sim was moved to uvdms_gym.physics.sim in 0.3.0
and the alias removed in 0.4.0; import uvdms_gym.physics.sim``.

The modules that 0.4.0 moved when it regrouped ``uvdms_gym.envs``, ``baselines`` and ``leaderboard`` (no alias was
ever kept for them) fail the same way, with :func:`regrouped_message` (:data:`REGROUPED`, and the tables of
``baselines`` and ``leaderboard``): ``import baselines.campc`` raises ``ModuleNotFoundError: baselines.campc was
moved in 0.4.0: import from baselines.mpc.campc``.

Files pickled before a move (trusted SB3 zips that name a class by its old module) load inside
:func:`old_modules_aliased`, which makes the old names aliases of the new modules for the time of the load only.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.abc
import importlib.machinery
import sys
import types
from collections.abc import Callable, Iterator, Mapping, Sequence

MOVED_IN = "0.3.0"
"""The release that moved the modules of the tables (and kept the old paths as deprecated aliases)."""
REMOVED_IN = "0.4.0"
"""The release that removed the aliases."""

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
"""Old module paths of ``uvdms_gym`` (aliases in 0.3.0, removed in 0.4.0) -> their homes."""

REGROUPED_IN = "0.4.0"
"""The release that regrouped ``baselines``, ``leaderboard`` and ``uvdms_gym.envs`` (no aliases were kept)."""

REGROUPED: dict[str, str] = {
    "uvdms_gym.envs.v1": (
        "uvdms_gym.envs.circle (CircleTrackV1Env), uvdms_gym.envs.transport (TransportV1Env) and "
        "uvdms_gym.envs.bounded_reward (BoundedReward)"
    ),
    "uvdms_gym.envs.errors": "uvdms_gym.envs.tracking",
    "uvdms_gym.envs.tasks": "uvdms_gym.envs.references",
}
"""Module paths of ``uvdms_gym`` that 0.4.0 moved without an alias -> where their names live now."""

MOVED_NAMES: dict[str, dict[str, str]] = {
    "uvdms_gym.physics.sim": {
        **dict.fromkeys(
            ["NU_LIMIT", "POSITION_LIMIT", "PhysicsError", "QDOT_LIMIT", "StepInfo"], "uvdms_gym.physics.state"
        ),
        **dict.fromkeys(["GRASP_MAX_FORCE", "GRASP_TOLERANCE"], "uvdms_gym.physics.grasp"),
        **dict.fromkeys(["CONSTRAINT_CFM", "CONSTRAINT_ERP", "MAX_JOINT_VELOCITY"], "uvdms_gym.physics.body"),
        "MIN_VIRTUAL_MASS": "uvdms_gym.physics.water",
    },
    "uvdms_gym.envs.base": dict.fromkeys(["POS_SCALE", "errors_pose", "errors_positions"], "uvdms_gym.envs.tracking"),
}
"""Modules of ``uvdms_gym`` whose names 0.4.0 moved to other modules -> those names -> their module now
(``from uvdms_gym.physics.sim import PhysicsError`` fails in one line naming ``uvdms_gym.physics.state``)."""


def moved_message(old: str, new: str) -> str:
    """The one line that answers an import of ``old``: where it lives now and which release removed the alias."""
    return f"{old} was moved to {new} in {MOVED_IN} and the alias removed in {REMOVED_IN}; import {new}"


def regrouped_message(old: str, new: str) -> str:
    """The one line that answers an import of ``old``, moved by the regrouping of 0.4.0: where its names live now."""
    return f"{old} was moved in {REGROUPED_IN}: import from {new}"


class MovedModuleFinder(importlib.abc.MetaPathFinder):
    """A ``sys.meta_path`` finder that raises :func:`moved_message` for the old names of its table.

    Appended after the standard finders, it is asked only about names no other finder found, so a module that
    exists is never shadowed.
    """

    def __init__(self, table: Mapping[str, str], message: Callable[[str, str], str] = moved_message) -> None:
        self.table = dict(table)
        self.message = message

    def find_spec(
        self, fullname: str, path: Sequence[str] | None = None, target: types.ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        """``None`` for a name not in the table (the usual ``No module named ...`` follows).

        Raises:
            ModuleNotFoundError: For an old name, with the one-line message naming its new home.
        """
        new = self.table.get(fullname)
        if new is None:
            return None
        raise ModuleNotFoundError(self.message(fullname, new), name=fullname)


def moved_names(package: str, table: Mapping[str, str]) -> Callable[[str], object]:
    """A module ``__getattr__`` for ``package`` that names the new module of each name of ``table``.

    Each name of ``table`` (moved to another module by the regrouping of 0.4.0) raises an ``ImportError`` in one
    line naming its new module; any other missing name is missing as usual. ``ImportError``, not
    ``AttributeError``: ``from baselines.mpc import KinematicMPC`` would replace an ``AttributeError``'s message
    with its own ``cannot import name``.
    """

    def __getattr__(name: str) -> object:
        home = table.get(name)
        if home is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        raise ImportError(f"{package}.{name} was moved in {REGROUPED_IN}: import it from {home}", name=package)

    return __getattr__


def install_moved_finder(table: Mapping[str, str], message: Callable[[str, str], str] = moved_message) -> None:
    """Put a :class:`MovedModuleFinder` for ``table`` at the end of ``sys.meta_path`` (once per table).

    Args:
        table: Old module path -> its new home.
        message: The one line for an old path (:func:`moved_message`, or :func:`regrouped_message` for the
            modules 0.4.0 moved).
    """
    if not any(isinstance(f, MovedModuleFinder) and f.table == dict(table) for f in sys.meta_path):
        sys.meta_path.append(MovedModuleFinder(table, message))


@contextlib.contextmanager
def old_modules_aliased(table: Mapping[str, str]) -> Iterator[None]:
    """Within the block, each old name of ``table`` is an alias of its new module (for unpickling old files).

    The new modules are imported; the aliases this block added to ``sys.modules`` are removed when it ends.
    """
    added = []
    try:
        for old, new in table.items():
            if old not in sys.modules:
                sys.modules[old] = importlib.import_module(new)
                added.append(old)
        yield
    finally:
        for old in added:
            sys.modules.pop(old, None)
