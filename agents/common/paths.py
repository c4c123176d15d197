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
    """``path``, or, where it does not exist, the shipped agent (or seed folder) it names.

    A relative ``trained_agents/NAME[/seed_k]`` (or ``NAME[/seed_k]``) resolves in the working directory's
    ``trained_agents/`` if it is there, else in :func:`trained_agents_dir` (the checkout's or the installed copy),
    with a former name of a renamed shipped folder mapped to its new one (:data:`SHIPPED_ALIASES`):
    ``trained_agents/circle_case1_ppo`` loads ``trained_agents/ppo-circle-case1-v0``. An absolute path is only
    mapped by the former name of its last part inside a ``trained_agents`` folder. Every other path is returned
    unchanged (as a :class:`~pathlib.Path`).
    """
    path = Path(path)
    if path.exists() or not path.parts:
        return path
    if path.is_absolute():
        new = SHIPPED_ALIASES.get(path.name)
        renamed = path.parent / new if new is not None and path.parent.name == TRAINED_AGENTS else None
        return renamed if renamed is not None and renamed.is_dir() else path
    local = path.parts[0] == TRAINED_AGENTS and len(path.parts) > 1
    parts = path.parts[1:] if local else path.parts
    relative = Path(SHIPPED_ALIASES.get(parts[0], parts[0]), *parts[1:])
    for candidate in ((Path(TRAINED_AGENTS) / relative) if local else None, trained_agents_dir() / relative):
        if candidate is not None and candidate.exists():
            return candidate
    return path
