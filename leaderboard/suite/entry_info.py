"""What an entry is made of and how it was trained, beside its scores (entry documents and the leaderboard page).

:func:`entry_details` reads an :class:`~leaderboard.suite.entries.Entry`'s composition (base controller, residual,
safety filter) and each run's training record (algorithm, network, budget, wall time) from its plain-text files; the
report writes them into ``entries/<entry>.json``. :func:`details_from_agents_dir` recovers the same for an entry
document written before these keys existed, from the agent folder, only when the folder's model files have the
checksums the document recorded (the files that were evaluated).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from leaderboard.suite.agent_files import agent_checksum, agent_composition, training_record
from leaderboard.suite.entries import FILTER_SUFFIX, Entry

log = logging.getLogger("uvdms.leaderboard")

KINDS: tuple[str, ...] = ("baseline", "learned", "residual", "agent")
"""Kinds of an entry on the page: a named baseline; an agent whose policy output is the command (``learned``) or is
added to a base controller's (``residual``); ``agent``: an agent whose composition is not recorded."""


def composition_record(kind: str, spec: str | Path, evaluated_with_filter: bool) -> dict[str, Any]:
    """An entry's composition: its controller (baseline) or residual base, residual settings and safety filter.

    Args:
        kind: ``"baseline"`` or ``"agent"`` (:attr:`Entry.kind`).
        spec: The baseline name, or the folder of (one seed of) the agent.
        evaluated_with_filter: The entry's actions went through the safety filter (:attr:`Entry.safety_filter`).

    Raises:
        ValueError: The agent's recorded composition is invalid (the message names the file).
    """
    if kind == "baseline":
        return {"controller": str(spec), "evaluated_with_filter": evaluated_with_filter}
    record = agent_composition(spec).to_record()
    record["trained_with_filter"] = record.pop("safety_filter")
    return {**record, "evaluated_with_filter": evaluated_with_filter}


def entry_details(entry: Entry) -> dict[str, Any]:
    """``{"composition": ..., "training": [one record per run]}`` of an entry (baselines: no training records).

    Each training record is :func:`~leaderboard.suite.agent_files.training_record` of a run's folder with its
    ``training_seed`` (a multi-seed entry's ``k``; ``None`` for a single agent).
    """
    if entry.kind != "agent":
        return {"composition": composition_record(entry.kind, entry.spec, entry.safety_filter), "training": []}
    runs = entry.runs()
    return {
        "composition": composition_record("agent", runs[0].spec, entry.safety_filter),
        "training": [{"training_seed": run.training_seed, **training_record(run.spec)} for run in runs],
    }


def entry_kind(document: Mapping[str, Any]) -> str:
    """The page's kind of an entry document (one of :data:`KINDS`), from its ``kind`` and ``composition``."""
    if document.get("kind") == "baseline":
        return "baseline"
    composition = document.get("composition")
    if not isinstance(composition, Mapping):
        return "agent"
    return "residual" if composition.get("residual_base") else "learned"


def _run_folders(document: Mapping[str, Any], agents_dir: Path) -> list[tuple[int | None, Path, str | None]]:
    """``(training seed, folder, recorded checksum)`` of each run of an agent entry document, under ``agents_dir``."""
    root = agents_dir / str(document.get("spec", ""))
    seeds = document.get("seeds")
    if isinstance(seeds, list):
        return [(s.get("training_seed"), root / str(s.get("folder", "")), s.get("checksum")) for s in seeds]
    return [(None, root, document.get("checksum"))]


def details_from_agents_dir(document: Mapping[str, Any], agents_dir: str | Path) -> dict[str, Any] | None:
    """:func:`entry_details` of an agent entry document from its folder in ``agents_dir``, if it is the one evaluated.

    The folder is ``agents_dir/<spec>`` (``spec``: the folder name the document records); every run's model files
    must have the checksum the document recorded (a single agent's ``checksum``, each seed's in ``seeds``).

    Returns:
        The details, or ``None``: not an agent, no such folder, or different files (logged).
    """
    if document.get("kind") != "agent" or not document.get("spec"):
        return None
    runs = _run_folders(document, Path(agents_dir))
    if not all(folder.is_dir() for _seed, folder, _checksum in runs):
        return None
    if any(agent_checksum(folder) != checksum for _seed, folder, checksum in runs):
        log.warning("%s: its files differ from the evaluated ones; training details not shown", runs[0][1])
        return None
    return {
        "composition": composition_record("agent", runs[0][1], FILTER_SUFFIX in str(document.get("name", ""))),
        "training": [{"training_seed": seed, **training_record(folder)} for seed, folder, _checksum in runs],
    }
