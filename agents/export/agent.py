"""Loading any trained agent by its folder's format, and exporting one to the weights-only format.

:func:`load_agent` dispatches on what the path holds: a weights-only export (``agent.json``; no trust needed,
:mod:`agents.export.weights`), or a run directory, a shipped agent folder or an SB3 zip (pickles, trust-gated;
:mod:`agents.export.sb3`). :func:`export_agent` loads an agent that way and writes it as a weights-only export.
"""

from __future__ import annotations

from pathlib import Path

from agents.common.paths import resolve_shipped
from agents.export.controller import AgentController, Which
from agents.export.sb3 import load_sb3_agent
from agents.export.weights import AGENT_JSON, export_controller, load_weights_only


def load_agent(
    path: str | Path, *, which: Which = "final", trust: bool = False, algo: str | None = None
) -> AgentController:
    """Load a trained agent for evaluation.

    Args:
        path: A weights-only export directory (no trust needed), a shipped agent folder (``model.zip`` and
            ``vecnormalize.pkl``, see :mod:`scripts.ship_agent`), a run directory, or an SB3 zip
            (``final_model.zip``, ``best_model.zip``, ``checkpoints/rl_model_<N>_steps.zip``) whose
            VecNormalize statistics sit beside it with the names written by ``agents.training.train``.
        which: For a run directory: ``final`` (``final_model.zip``) or ``best`` (``best_model.zip``);
            ignored for a shipped agent folder (one model).
        trust: Allow unpickling the run's files (see :func:`load_sb3_zip`).
        algo: Algorithm name if it cannot be read from ``config.yml`` or the zip.

    Returns:
        The controller.

    Raises:
        UntrustedFileError: If SB3/VecNormalize pickles would have to be loaded without trust.
        FileNotFoundError: If the model or its required normalisation statistics are missing.
    """
    path = resolve_shipped(path)  # a shipped agent's former name loads the renamed folder
    if path.is_dir() and (path / AGENT_JSON).is_file():
        return load_weights_only(path)
    return load_sb3_agent(path, which=which, trust=trust, algo=algo)


def export_agent(
    run_dir: str | Path,
    out_path: str | Path,
    *,
    which: Which = "final",
    trust: bool = False,
    overwrite: bool = False,
) -> Path:
    """Export a trained agent to the weights-only format (a directory; see the module docstring).

    Args:
        run_dir: Run directory or SB3 zip (as for :func:`load_agent`).
        out_path: Output directory (created).
        which: ``final`` or ``best`` model of a run directory.
        trust: Allow unpickling the run's files (reading them is the one unpickling step).
        overwrite: Replace the files of an existing export in ``out_path``.

    Returns:
        The export directory.

    Raises:
        ExportFormatError: If the policy uses a class or space the format cannot represent.
        FileExistsError: If ``out_path`` is not empty and ``overwrite`` is false.
    """
    agent = load_agent(run_dir, which=which, trust=trust)
    return export_controller(agent, out_path, overwrite=overwrite)
