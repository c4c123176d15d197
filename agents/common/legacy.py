"""The module paths ``agents`` removed in 0.4.0, and the loading of files pickled under them.

:data:`MOVED` lists the old paths that were aliases in 0.3.0 (the re-export modules ``agents.train``,
``agents.policy``, ``agents.wrappers``, ``agents.callbacks`` and the ``sys.modules`` alias
``agents.ppo_lagrangian``); ``import agents`` installs the finder that makes importing one fail in one line naming
its new home (:mod:`uvdms_gym.utils.legacy`). :data:`PICKLED` is the part of it that old files name: SB3 zips of
PPO-Lagrangian runs written before 0.3.0 record their policy class as ``agents.ppo_lagrangian.CostActorCriticPolicy``;
they load and resume inside :func:`old_pickles` (and :func:`new_module` maps the module a zip names).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from uvdms_gym.utils.legacy import old_modules_aliased

MOVED: dict[str, str] = {
    "agents.train": "agents.training.train",
    "agents.policy": "agents.export",
    "agents.wrappers": "agents.common.wrappers",
    "agents.callbacks": "agents.training.callbacks",
    "agents.ppo_lagrangian": "agents.algos.ppo_lagrangian",
}
"""Old module paths of ``agents`` (aliases in 0.3.0, removed in 0.4.0) -> their homes."""

PICKLED: dict[str, str] = {"agents.ppo_lagrangian": MOVED["agents.ppo_lagrangian"]}
"""The old module paths that saved files name (the module of a pickled class) -> their homes."""


def new_module(module: str | None) -> str | None:
    """The home of a module named by a saved file (``module`` itself unless it is an old name of :data:`PICKLED`)."""
    return PICKLED.get(module, module)


@contextlib.contextmanager
def old_pickles() -> Iterator[None]:
    """Within the block, trusted files pickled under the old module paths of :data:`PICKLED` unpickle."""
    with old_modules_aliased(PICKLED):
        yield
