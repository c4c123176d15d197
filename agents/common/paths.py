"""Where the training configurations and the shipped agents live, in a source checkout and in an install.

In the repository they are the top-level folders ``train_configs/`` and ``trained_agents/``. A regular
(non-editable) ``pip install .`` copies them into the ``agents`` package as package data
(``agents/train_configs/*.yml``; ``agents/trained_agents/<name>/`` with ``model.zip``, ``vecnormalize.pkl``,
``config.yml``, ``meta.json``, ``evaluation.json`` and ``README.md``, without the training logs and plots;
``pyproject.toml`` lists them). The functions below return the installed copy when it exists, else the
checkout's folder, so ``uvdms train`` and ``uvdms leaderboard`` work from any working directory either way.
"""

from __future__ import annotations

from pathlib import Path

from uvdms_gym.utils.provenance import REPO_ROOT  # the one repository-root lookup (site-packages after an install)

PACKAGE_DIR = Path(__file__).resolve().parents[1]
"""The ``agents`` package directory."""
TRAIN_CONFIGS = "train_configs"
"""Folder name of the training configurations."""
TRAINED_AGENTS = "trained_agents"
"""Folder name of the shipped agents."""


def data_dir(name: str) -> Path:
    """The installed package-data folder ``agents/<name>`` if it exists, else ``<checkout>/<name>``.

    Args:
        name: :data:`TRAIN_CONFIGS` or :data:`TRAINED_AGENTS`.

    Returns:
        The folder (it may be missing if neither exists; callers report that with its path).
    """
    installed = PACKAGE_DIR / name
    return installed if installed.is_dir() else REPO_ROOT / name


def train_configs_dir() -> Path:
    """Folder of the ``<algo>.yml`` training configurations."""
    return data_dir(TRAIN_CONFIGS)


def trained_agents_dir() -> Path:
    """Folder of the shipped agents (``<name>/model.zip`` ...)."""
    return data_dir(TRAINED_AGENTS)


SHIPPED_ALIASES: dict[str, str] = {
    "circle_case1_ppo": "ppo-circle-case1-v0",
    "circle_case1_sac": "sac-circle-case1-v0",
    "circle_case2_ppo": "ppo-circle-case2-v0",
    "circle_case2_sac": "sac-circle-case2-v0",
    "transport_paper_ppo": "ppo-transport-paper-v0",
    "transport_paper_sac": "sac-transport-paper-v0",
}
"""Former names of shipped agent folders -> their names under the one scheme
``<family>-<task>[-<variant>]-<env version>`` (``sac-circle-v1``, ``residual-mpc-sac-transport-v1``,
``ppo-circle-case1-v0``); the documented old paths still load."""


def resolve_shipped(path: str | Path) -> Path:
    """``path``, or, for a shipped agent's former name that no longer exists, the folder it was renamed to.

    ``trained_agents/circle_case1_ppo`` (or just ``circle_case1_ppo``) resolves to
    ``trained_agents/ppo-circle-case1-v0``
    in the same ``trained_agents`` folder if it is there, else in :func:`trained_agents_dir`. Every other path is
    returned unchanged (as a :class:`~pathlib.Path`).
    """
    path = Path(path)
    new = SHIPPED_ALIASES.get(path.name)
    if new is None or path.exists() or path.parent.name not in ("", TRAINED_AGENTS):
        return path
    for candidate in (path.parent / new, trained_agents_dir() / new):
        if candidate.is_dir():
            return candidate
    return path
