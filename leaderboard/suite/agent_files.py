"""An agent folder's plain-text records, read without unpickling: environment, composition, seeds, checksum.

An agent folder (a weights-only export, a shipped folder, a run directory, or the folder of an SB3 zip) records
its training in ``agent.json`` / ``config.yml`` / ``meta.json``; :mod:`leaderboard.suite.entries` builds an entry from
them. Nothing here loads a model.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import yaml

from uvdms_gym.residual import ActionComposition

AGENT_MODEL_SUFFIXES = (".zip", ".pkl", ".pt", ".npz")
"""The model files an agent's checksum covers."""
AGENT_CONFIG_NAMES = ("agent.json", "config.yml", "config.yaml")
"""The records that hold an agent's environment and composition."""
SEED_FILES = ("meta.json", "config.yml", "config.yaml", "agent.json")
"""The records whose seeds count as the agent's training seeds."""

log = logging.getLogger("uvdms.leaderboard")


def run_seed(folder: Path) -> int | None:
    """The base seed (``seed``) recorded at the top of a run's ``config.yml`` or ``meta.json`` (``None``: none)."""
    for file_name in ("config.yml", "config.yaml", "meta.json"):
        file = folder / file_name
        if not file.is_file():
            continue
        try:
            doc = read_structured(file)
        except (OSError, ValueError, yaml.YAMLError):
            continue
        seed = doc.get("seed") if isinstance(doc, dict) else None
        if isinstance(seed, int) and not isinstance(seed, bool):
            return seed
    return None


def _agent_folders(path: Path) -> list[Path]:
    """Where an agent's plain-text run files may be: the folder (or a zip's folder) and its parent."""
    folder = path if path.is_dir() else path.parent
    return [folder, folder.parent]


def read_structured(path: Path) -> Any:
    """A JSON or YAML record (by its suffix), parsed safely."""
    text = path.read_text(encoding="utf-8")
    return json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)


def _agent_config_docs(path: Path) -> Iterator[tuple[Path, dict[str, Any]]]:
    """``(file, mapping)`` of every readable configuration file of an agent (``agent.json``, ``config.yml``), in order.

    An unreadable file is logged and skipped; a file that does not hold a mapping is skipped.
    """
    for folder in _agent_folders(path):
        for name in AGENT_CONFIG_NAMES:
            file = folder / name
            if not file.is_file():
                continue
            try:
                doc = read_structured(file)
            except (OSError, ValueError, yaml.YAMLError) as exc:
                log.warning("cannot read %s: %s", file, exc)
                continue
            if isinstance(doc, dict):
                yield file, doc


def agent_env(path: str | Path) -> tuple[str | None, dict[str, Any]]:
    """The training environment id and keyword arguments of an agent, from ``agent.json`` or ``config.yml``.

    Returns:
        ``(env_id, env_kwargs)``; ``(None, {})`` if no configuration file is found.
    """
    for _file, doc in _agent_config_docs(Path(path)):
        config = doc.get("config") if isinstance(doc.get("config"), dict) else {}
        env_kwargs = doc.get("env_kwargs") or config.get("env_kwargs") or {}
        env_id = doc.get("env_id") or config.get("env_id")
        if env_id is not None:
            return str(env_id).split(":")[-1], dict(env_kwargs)
    return None, {}


def agent_composition(path: str | Path) -> ActionComposition:
    """The residual base and safety filter an agent was trained with, from ``agent.json`` or ``config.yml``.

    Read from the first configuration file found (as :func:`agent_env`); none found: a plain agent.

    Raises:
        ValueError: The recorded values are invalid (the message names the file).
    """
    for file, doc in _agent_config_docs(Path(path)):
        record = doc["config"] if isinstance(doc.get("config"), dict) else doc
        try:
            return ActionComposition.from_record(record)
        except ValueError as exc:
            raise ValueError(f"{file}: {exc}") from None
    return ActionComposition()


def _collect_seeds(node: Any, under_seed_key: bool = False) -> set[int]:
    found: set[int] = set()
    if isinstance(node, Mapping):
        for key, value in node.items():
            found |= _collect_seeds(value, under_seed_key or "seed" in str(key).lower())
    elif isinstance(node, list | tuple):
        for value in node:
            found |= _collect_seeds(value, under_seed_key)
    elif under_seed_key and isinstance(node, int) and not isinstance(node, bool):
        found.add(int(node))
    return found


def training_seeds(path: str | Path) -> set[int]:
    """Every integer stored under a key containing ``seed`` in the agent's run files (see module docstring)."""
    seeds: set[int] = set()
    for folder in _agent_folders(Path(path)):
        for name in SEED_FILES:
            file = folder / name
            if file.is_file():
                try:
                    seeds |= _collect_seeds(read_structured(file))
                except (OSError, ValueError, yaml.YAMLError) as exc:
                    log.warning("cannot read %s for training seeds: %s", file, exc)
    return seeds


def agent_checksum(path: str | Path) -> str:
    """SHA-256 over the agent's model files.

    Name and content of each ``.zip``/``.pkl``/``.pt``/``.npz`` and configuration file of the folder, or of a
    checkpoint and its sibling ``.pkl`` statistics.
    """
    path = Path(path)
    if path.is_dir():
        files = [
            p
            for p in sorted(path.iterdir())
            if p.is_file() and (p.suffix in AGENT_MODEL_SUFFIXES or p.name in AGENT_CONFIG_NAMES)
        ]
    else:
        files = [path, *sorted(p for p in path.parent.glob("*.pkl") if p.is_file())]
    digest = hashlib.sha256()
    for file in files:
        digest.update(file.name.encode() + b"\0")
        digest.update(hashlib.sha256(file.read_bytes()).digest())
    return digest.hexdigest()


def _record(folder: Path, name: str) -> dict[str, Any]:
    """The mapping a run file holds (``{}``: absent, unreadable or not a mapping)."""
    file = folder / name
    if not file.is_file():
        return {}
    try:
        doc = read_structured(file)
    except (OSError, ValueError, yaml.YAMLError) as exc:
        log.warning("cannot read %s: %s", file, exc)
        return {}
    return doc if isinstance(doc, dict) else {}


def _segments(meta: Mapping[str, Any]) -> list[dict[str, Any]]:
    segments = meta.get("segments")
    return [s for s in segments if isinstance(s, dict)] if isinstance(segments, list) else []


def _budget(meta: Mapping[str, Any], config: Mapping[str, Any]) -> dict[str, Any]:
    """Steps and wall time of the training (``scripts.ship_agent``'s ``shipped`` record, else the segments').

    ``budget_timesteps``: the steps asked for (the segments' ``requested_timesteps`` summed, else the config's
    ``n_timesteps``); ``trained_timesteps``: the last segment's step count; ``wall_time_s``: the segments' wall
    times summed (``None`` unless every segment recorded one).
    """
    shipped = meta.get("shipped") if isinstance(meta.get("shipped"), dict) else {}
    segments = _segments(meta)
    requested = [s.get("requested_timesteps") for s in segments]
    walls = [s.get("wall_time_s") for s in segments]
    budget = shipped.get("budget_timesteps")
    if budget is None and segments and all(isinstance(r, int) for r in requested):
        budget = sum(requested)
    if budget is None:
        budget = config.get("n_timesteps")
    wall = shipped.get("wall_time_s")
    if wall is None and segments and all(isinstance(w, int | float) for w in walls):
        wall = round(float(sum(walls)), 1)
    trained = shipped.get("trained_timesteps")
    if trained is None and segments:
        trained = segments[-1].get("end_num_timesteps")
    return {"budget_timesteps": budget, "trained_timesteps": trained, "wall_time_s": wall, "segments": len(segments)}


def training_record(path: str | Path) -> dict[str, Any]:
    """What an agent's plain-text run files record of its training (``None`` where a file does not say).

    Read from ``agent.json``, ``config.yml`` and ``meta.json`` of the agent's folder (nothing is loaded).

    Returns:
        ``algo``, ``policy`` (the SB3 policy name), ``net_arch``, ``activation_fn``, ``budget_timesteps``,
        ``trained_timesteps``, ``model_timesteps`` (the steps of the saved model), ``wall_time_s``, ``segments``
        (training segments, ``--resume`` adds one) and ``teacher`` (a distilled policy's teacher, as recorded).
    """
    folder = Path(path) if Path(path).is_dir() else Path(path).parent
    agent, meta = _record(folder, "agent.json"), _record(folder, "meta.json")
    run_config = _record(folder, "config.yml") or _record(folder, "config.yaml")
    config = run_config.get("config") if isinstance(run_config.get("config"), dict) else {}
    policy_kwargs = agent.get("policy_kwargs") or config.get("policy_kwargs") or {}
    shipped = meta.get("shipped") if isinstance(meta.get("shipped"), dict) else {}
    composition = next((s.get("action_composition") for s in reversed(_segments(meta))), None) or {}
    return {
        "algo": agent.get("algo") or meta.get("algo") or run_config.get("algo"),
        "policy": agent.get("policy") or config.get("policy"),
        "net_arch": policy_kwargs.get("net_arch") if isinstance(policy_kwargs, dict) else None,
        "activation_fn": policy_kwargs.get("activation_fn") if isinstance(policy_kwargs, dict) else None,
        **_budget(meta, config),
        "model_timesteps": agent.get("num_timesteps", shipped.get("model_num_timesteps")),
        "teacher": composition.get("teacher_factory") if isinstance(composition, dict) else None,
    }
