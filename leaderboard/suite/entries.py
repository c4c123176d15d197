"""Leaderboard entries: the named baselines and agent folders or checkpoints, read without unpickling.

An agent's entry holds its training environment (it runs only on that environment's tasks), a checksum of its
model files (the cache key) and every seed recorded in its run files (:func:`check_seed_disjointness`). An agent
trained as a residual or with the safety filter (:mod:`uvdms_gym.residual`, recorded in its ``agent.json`` or
``config.yml``) is evaluated composed the same way, and its name says so: ``residual-<base>-<folder>``, with
``+filter`` when it was trained with the filter (a ``PATH+filter`` token then names the same entry).

A **multi-seed entry** is a folder of training seeds, each an agent folder of its own (a weights-only export, a
shipped agent folder or a run directory) named ``seed_<k>`` after its training seed ``k``
(:func:`multi_seed_entry`)::

    trained_agents/<entry>/seed_0/   agent.json, policy.pt, ...     (or model.zip, config.yml, meta.json, ...)
    trained_agents/<entry>/seed_1/
    trained_agents/<entry>/seed_2/

Its :class:`Entry` holds one member entry per seed (``<entry>/seed_<k>``), which the runner evaluates and caches
like any agent; the leaderboard reports one row per task for the whole entry
(:func:`leaderboard.stats.metrics.aggregate_runs`).
"""

from __future__ import annotations

import hashlib
import json
import logging
import re
import zipfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from leaderboard.suite.agent_files import (
    agent_checksum,
    agent_composition,
    agent_env,
    run_seed,
    training_seeds,
)
from leaderboard.suite.registry import (
    BASELINE_ENV,
    DEFAULT_BASELINES,
    GRASP_OF,
    GRASP_ONLY,
    PRIVILEGED,
    REALISM_ONLY,
    TRACK_OF,
    not_an_agent_folder,
    resolve_controller,
    unknown_controller,
)
from leaderboard.suite.tasks import TRACKS, Task, env_family

log = logging.getLogger("uvdms.leaderboard")

BASELINES: dict[str, str] = TRACK_OF
"""Named baselines and their tracks (:data:`leaderboard.suite.registry.TRACK_OF`)."""
FILTER_SUFFIX = "+filter"
"""Entry-token suffix: the entry's actions go through the safety filter (:mod:`baselines.safety.filter`)."""
DEFAULT_ENTRIES: tuple[str, ...] = ("baselines", "realism", "coop", "agents")
"""``baselines`` stands for the four named baselines, ``realism`` for the realism track's own baselines
(``campc-raw``, ``campc-privileged``: they run only on its tasks), ``coop`` for the baselines restricted to the
friction-grasp tasks (:data:`leaderboard.suite.registry.GRASP_ONLY`: ``campc-coop``), ``agents`` for every agent
folder in ``agents_dir``."""
SEED_FOLDER_PREFIX = "seed_"
"""Sub-folders of a multi-seed entry: ``seed_<k>``, ``k`` the training seed (``--seed``) of the run inside."""
_SEED_FOLDER = re.compile(rf"^{SEED_FOLDER_PREFIX}(\d+)$")
MIN_TRAINING_SEEDS = 2
"""Fewest seed folders of a multi-seed entry (an interval over training seeds needs two)."""
RECOMMENDED_TRAINING_SEEDS = 3
"""Seeds every shipped learned entry should have (issue 14); fewer are accepted with a warning."""


@dataclass(frozen=True)
class Entry:
    """A competitor: a named baseline or an agent (folder or checkpoint).

    Attributes:
        name: Display name (unique within a run).
        kind: ``"baseline"`` or ``"agent"``.
        spec: What ``make_controller`` receives: the baseline name or the agent path.
        track: ``"velocity"`` or ``"torque"``.
        env_id: The environment id an agent was trained on (``None``: runs on every task).
        checksum: SHA-256 over the agent's model files (``None`` for baselines).
        training_seeds: Every seed recorded in the agent's run files.
        weights_only: The agent is a weights-only export (never unpickled).
        safety_filter: The controller's actions go through :class:`baselines.safety.filter.SafetyFilter` (an entry of
            its own, named ``<name>+filter``; always for an agent trained with the filter).
        residual_base: The base controller of a residual agent (``None``: not a residual agent).
        members: A multi-seed entry's per-seed agent entries (empty otherwise); the runner evaluates these.
        training_seed: A member's training seed (the ``k`` of its ``seed_<k>`` folder; ``None`` otherwise).
        realism_only: A baseline of the realism track only (runs on tasks with ``realism > 0``).
        privileged: A reference row that reads the true state at ``realism > 0`` (marked, not a competitor).
        grasp: A baseline of the tasks of this grasp only (``"friction"``: the cooperative tasks; ``None``: every
            task), from its spec's :data:`leaderboard.suite.registry.GRASP_KEY`.
    """

    name: str
    kind: str
    spec: str
    track: str
    env_id: str | None = None
    checksum: str | None = None
    training_seeds: frozenset[int] = frozenset()
    weights_only: bool = False
    safety_filter: bool = False
    residual_base: str | None = None
    members: tuple[Entry, ...] = ()
    training_seed: int | None = None
    realism_only: bool = False
    privileged: bool = False
    grasp: str | None = None

    @property
    def label(self) -> str:
        """The name in tables and plots: a multi-seed entry's with its number of seeds (``x (3 seeds)``)."""
        return f"{self.name} ({len(self.members)} seeds)" if self.members else self.name

    @property
    def multi_seed(self) -> bool:
        """Whether the entry aggregates several training seeds."""
        return bool(self.members)

    def runs(self) -> tuple[Entry, ...]:
        """The agents evaluated for this entry: its members, or the entry itself."""
        return self.members or (self,)

    def renamed(self, name: str) -> Entry:
        """The entry under another name (members renamed ``<name>/seed_<k>``)."""
        members = tuple(replace(m, name=f"{name}/{Path(m.spec).name}") for m in self.members)
        return replace(self, name=name, members=members)

    def filtered(self) -> Entry:
        """The same entry with the safety filter (named ``<name>+filter``, members too)."""
        members = tuple(replace(m, safety_filter=True) for m in self.members)
        return replace(self, safety_filter=True, members=members).renamed(self.name + FILTER_SUFFIX)

    def identity(self) -> dict[str, Any]:
        """What identifies the entry's behaviour in the cache key (agents: by content, not path)."""
        identity: dict[str, Any] = {"name": self.name, "kind": self.kind, "checksum": self.checksum}
        if self.safety_filter:  # (absent otherwise: unfiltered entries keep their cache keys)
            identity["safety_filter"] = True
        return identity

    def runs_on(self, task: Task) -> bool:
        """Whether the entry is evaluated on ``task`` (agents: only tasks of the environment they were trained on).

        Any version of the task's environment counts (:func:`leaderboard.suite.tasks.env_family`): an agent trained
        on ``uvdms/CircleTrack-v1`` runs the circle tasks, on ``-v1`` (:meth:`task_spec`). A baseline of the
        realism track runs only at ``realism > 0``, one restricted to a grasp (:attr:`grasp`) only on its tasks.
        """
        if self.realism_only and task.realism == 0:
            return False
        if self.grasp is not None and task.grasp != self.grasp:
            return False
        return self.env_id is None or env_family(self.env_id) == env_family(task.env_id)

    def task_spec(self, task: Task) -> dict[str, Any]:
        """The environment this entry runs ``task`` on: the task's, in the version the agent was trained on.

        Baselines (and agents of the task's own version) run the task's environment id; the versions differ
        only in the reward, so only the ``return`` metric depends on the version.
        """
        return task.spec(self.track, self.env_id if self.env_id is not None and self.runs_on(task) else None)

    @property
    def slug(self) -> str:
        """File-system-safe name."""
        return slugify(self.name)


def slugify(name: str) -> str:
    """``name`` with every character outside ``[A-Za-z0-9._-]`` replaced by ``_``."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", name) or "_"


def resolve_entries(
    tokens: Sequence[str] | None = None,
    *,
    agents_dir: str | Path | None = None,
    trust: bool = False,
) -> list[Entry]:
    """Turn command-line entry tokens into :class:`Entry` objects (and check that loading them is safe).

    Args:
        tokens: Baseline names, agent paths (a folder or an SB3 zip), ``baselines`` (the four baselines),
            ``realism`` and ``coop`` (the baselines of the realism track and of the friction-grasp tasks only) or
            ``agents`` (every agent folder in ``agents_dir``). Default :data:`DEFAULT_ENTRIES`. A token ending in
            :data:`FILTER_SUFFIX` (``mpc+filter``, ``trained_agents/x+filter``, ``agents+filter``) stands for the
            same entries with the safety filter (velocity track only).
        agents_dir: The shipped-agents folder (default: ``trained_agents`` in the working directory if it exists,
            else the repository's; a missing folder contributes no agents, with a warning).
        trust: Allow full SB3 zips from outside the repository's ``trained_agents/`` folder.

    Returns:
        The entries, in the given order, without duplicates.

    Raises:
        UntrustedFileError: A pickle-bearing agent outside ``trained_agents/`` without ``trust``.
        ValueError: A token that is neither a baseline name, a keyword nor an existing path.
    """
    if agents_dir is None:
        agents_dir = default_agents_dir()
    entries: list[Entry] = []
    seen_specs: set[str] = set()
    for raw_token in tokens or DEFAULT_ENTRIES:
        filtered = raw_token.endswith(FILTER_SUFFIX)
        token = raw_token.removesuffix(FILTER_SUFFIX) if filtered else raw_token
        for spec in _token_specs(token, agents_dir):
            keyed = _token_entry(spec, raw_token, token, filtered, trust)
            if keyed is None or keyed[0] in seen_specs:
                continue
            seen_specs.add(keyed[0])
            entries.append(keyed[1])
    return _unique_names(entries)


def default_agents_dir() -> Path:
    """The shipped-agents folder: ``trained_agents`` in the working directory if it exists, else the repository's."""
    from agents.export import TRUSTED_DIR

    return Path("trained_agents") if Path("trained_agents").is_dir() else Path(TRUSTED_DIR)


def _token_specs(token: str, agents_dir: str | Path) -> list[str]:
    """The controller specs a token stands for: the baselines, the agent folders, or the token itself."""
    if token == "baselines":  # the four of every task; campc-inner (one task) and hold are named explicitly
        return list(DEFAULT_BASELINES)
    if token == "realism":
        return sorted(REALISM_ONLY)
    if token == "coop":
        return sorted(GRASP_ONLY)
    if token == "agents":
        return [str(p) for p in find_agent_folders(agents_dir)]
    return [token]


def _token_entry(spec: str, raw_token: str, token: str, filtered: bool, trust: bool) -> tuple[str, Entry] | None:
    """``(dedup key, entry)`` of one spec of a token; ``None`` for a torque member of a filtered keyword."""
    if spec in BASELINES:
        key = spec
        entry = Entry(
            name=spec,
            kind="baseline",
            spec=spec,
            track=BASELINES[spec],
            env_id=BASELINE_ENV[spec],
            realism_only=spec in REALISM_ONLY,
            privileged=spec in PRIVILEGED,
            grasp=GRASP_OF[spec],
        )
    else:
        path = Path(resolve_controller(spec))  # a shipped name from any directory, a former name
        if not path.exists():
            raise unknown_controller(spec, ("baselines", "agents"))
        key = str(path.resolve())
        entry = agent_entry(path, trust=trust)
    if filtered and not entry.safety_filter:
        if entry.track != "velocity":
            if token != spec:  # a keyword: its torque-track members are simply not filtered
                return None
            raise ValueError(f"{raw_token}: the safety filter projects velocity commands; {spec} is torque")
        entry = entry.filtered()
    if entry.safety_filter:  # (an agent trained with the filter is the same entry with or without +filter)
        key += FILTER_SUFFIX
    return key, entry


def _unique_names(entries: list[Entry]) -> list[Entry]:
    counts: dict[str, int] = {}
    out = []
    for entry in entries:
        n = counts.get(entry.name, 0)
        counts[entry.name] = n + 1
        if n:
            entry = entry.renamed(f"{entry.name}-{n + 1}")
        out.append(entry)
    return out


def find_agent_folders(agents_dir: str | Path) -> list[Path]:
    """Sub-folders of ``agents_dir`` holding an agent (a weights-only ``agent.json`` or an SB3 ``.zip``) or seeds.

    A folder with ``seed_*`` sub-folders is a multi-seed entry (:func:`is_multi_seed_folder`).
    """
    root = Path(agents_dir)
    if not root.is_dir():
        log.warning("agents folder %s does not exist: no shipped agents are evaluated", root)
        return []
    return [
        p
        for p in sorted(root.iterdir())
        if p.is_dir() and (is_weights_only(p) or any(p.glob("*.zip")) or is_multi_seed_folder(p))
    ]


def is_multi_seed_folder(path: str | Path) -> bool:
    """Whether ``path`` is a folder with ``seed_*`` sub-folders (a multi-seed entry, :func:`multi_seed_entry`)."""
    path = Path(path)
    return path.is_dir() and any(p.is_dir() and p.name.startswith(SEED_FOLDER_PREFIX) for p in path.iterdir())


def is_weights_only(path: str | Path) -> bool:
    """Whether ``path`` is a weights-only export folder (``agent.json`` of :mod:`agents.export`)."""
    return Path(path).is_dir() and (Path(path) / "agent.json").is_file()


def agent_entry(path: str | Path, *, trust: bool = False) -> Entry:
    """An :class:`Entry` for an agent folder or checkpoint, read from its plain-text files (no unpickling).

    Raises:
        UntrustedFileError: The agent is a full SB3 zip outside ``trained_agents/`` and ``trust`` is false.
        ValueError: A folder without an agent, or a model archive that is not a valid zip file.
    """
    from agents.export import UntrustedFileError, is_trusted_path

    path = Path(path)
    if is_multi_seed_folder(path):
        return multi_seed_entry(path, trust=trust)
    weights_only = is_weights_only(path)
    archives = sorted(path.glob("*.zip")) if path.is_dir() else [path]
    if path.is_dir() and not weights_only and not archives:
        raise not_an_agent_folder(path)
    if not weights_only and not (trust or is_trusted_path(path)):
        raise UntrustedFileError(
            f"refusing to load {path}: it is a full Stable-Baselines3 model, whose pickled objects can run "
            "arbitrary code when loaded, and it lies outside the repository's trained_agents/ folder. Pass "
            "--trust if you trust its origin, or submit a weights-only export instead (uvdms export-agent)."
        )
    if not weights_only:
        bad = [str(a) for a in archives if not zipfile.is_zipfile(a)]
        if bad:
            raise ValueError(f"{', '.join(bad)}: not a valid zip archive (corrupt or truncated)")
    env_id, env_kwargs = agent_env(path)
    track = str(env_kwargs.get("action_mode", "velocity"))
    if track not in TRACKS:
        raise ValueError(f"{path}: unknown action_mode {track!r} in its configuration")
    composition = agent_composition(path)
    name = composition.describe(path.name if path.is_dir() else f"{path.parent.name}/{path.stem}")
    if composition.safety_filter:
        name += FILTER_SUFFIX
    return Entry(
        name=name,
        kind="agent",
        spec=str(path),
        track=track,
        env_id=env_id,
        checksum=agent_checksum(path),
        training_seeds=frozenset(training_seeds(path)),
        weights_only=weights_only,
        safety_filter=composition.safety_filter,
        residual_base=composition.residual_base,
    )


def multi_seed_entry(path: str | Path, *, trust: bool = False) -> Entry:
    """The :class:`Entry` of a folder of training seeds (layout in the module docstring).

    Every ``seed_<k>`` sub-folder becomes a member (:func:`agent_entry`, named ``<entry>/seed_<k>``, with ``k``
    among its training seeds); other sub-folders and files (a README, plots) are ignored. The entry is named
    after the folder as a single agent would be (``residual-<base>-<folder>``, ``+filter`` when trained with the
    filter); its checksum hashes its members' checksums; its training seeds are the union of theirs.

    Raises:
        ValueError: The folder is also an agent itself; a ``seed_*`` name that is not ``seed_<integer>``, or
            two folders of the same seed; fewer than :data:`MIN_TRAINING_SEEDS` seeds; a seed folder that is
            not an agent (or is itself a multi-seed folder); a run inside ``seed_<k>`` recorded with another
            seed; seeds trained on different environments (id, keyword arguments, action mode, residual base or
            safety filter); two seeds with identical model files.
        UntrustedFileError: A seed is a full SB3 zip outside ``trained_agents/`` and ``trust`` is false.
    """
    path = Path(path)
    if is_weights_only(path) or any(path.glob("*.zip")):
        raise ValueError(
            f"{path} holds both an agent (agent.json or a .zip) and seed_* folders: a multi-seed entry holds only "
            "its seed folders"
        )
    seeds = _seed_folders(path)
    members = _seed_members(path, seeds, trust)
    first = members[0]
    name = agent_composition(Path(first.spec)).describe(path.name) + (FILTER_SUFFIX if first.safety_filter else "")
    members = [replace(m, name=f"{name}/{Path(m.spec).name}") for m in members]
    _check_distinct_runs(path, members)
    digest = hashlib.sha256()
    for member in members:
        digest.update(f"{Path(member.spec).name}\0{member.checksum}\0".encode())
    return Entry(
        name=name,
        kind="agent",
        spec=str(path),
        track=first.track,
        env_id=first.env_id,
        checksum=digest.hexdigest(),
        training_seeds=frozenset().union(*(m.training_seeds for m in members)),
        weights_only=all(m.weights_only for m in members),
        safety_filter=first.safety_filter,
        residual_base=first.residual_base,
        members=tuple(members),
    )


def _seed_folders(path: Path) -> dict[int, Path]:
    """The ``seed_<k>`` folders of a multi-seed entry by training seed (checked: names, duplicates, how many)."""
    seeds: dict[int, Path] = {}
    for sub in sorted(p for p in path.iterdir() if p.is_dir() and p.name.startswith(SEED_FOLDER_PREFIX)):
        match = _SEED_FOLDER.match(sub.name)
        if match is None:
            raise ValueError(f"{sub}: a seed folder is named {SEED_FOLDER_PREFIX}<training seed>, e.g. seed_0")
        k = int(match.group(1))
        if k in seeds:
            raise ValueError(f"{path}: {seeds[k].name} and {sub.name} are both training seed {k}")
        seeds[k] = sub
    if len(seeds) < MIN_TRAINING_SEEDS:
        raise ValueError(
            f"{path}: a multi-seed entry needs at least {MIN_TRAINING_SEEDS} seed folders, found {len(seeds)}"
        )
    if len(seeds) < RECOMMENDED_TRAINING_SEEDS:
        log.warning(
            "%s: %d training seeds; shipped learned entries should have at least %d",
            path,
            len(seeds),
            RECOMMENDED_TRAINING_SEEDS,
        )
    return seeds


def _seed_members(path: Path, seeds: dict[int, Path], trust: bool) -> list[Entry]:
    """The member entry of each seed folder (each an agent, trained with its seed, all on one environment)."""
    members = []
    environments: dict[str, tuple[str | None, dict[str, Any], str, str | None, bool]] = {}
    for k, folder in sorted(seeds.items()):
        if is_multi_seed_folder(folder):
            raise ValueError(f"{folder}: a seed folder must be an agent, not another folder of seeds")
        member = agent_entry(folder, trust=trust)
        recorded = run_seed(folder)
        if recorded is not None and recorded != k:
            raise ValueError(f"{folder}: the run inside was trained with seed {recorded}, not {k}")
        env_id, env_kwargs = agent_env(folder)
        environments[folder.name] = (env_id, env_kwargs, member.track, member.residual_base, member.safety_filter)
        members.append(replace(member, training_seed=k, training_seeds=member.training_seeds | {k}))
    if len({json.dumps(env, sort_keys=True, default=str) for env in environments.values()}) > 1:
        listing = "; ".join(
            f"{seed}: {env[0]} {env[1]} ({env[2]}{f', residual on {env[3]}' if env[3] else ''}"
            f"{', safety filter' if env[4] else ''})"
            for seed, env in environments.items()
        )
        raise ValueError(f"{path}: its seeds were trained on different environments ({listing})")
    return members


def _check_distinct_runs(path: Path, members: list[Entry]) -> None:
    """Refuse two seeds with identical model files (the same run twice, not two training seeds)."""
    by_checksum: dict[str | None, str] = {}
    for member in members:
        if member.checksum in by_checksum:
            raise ValueError(
                f"{path}: {by_checksum[member.checksum]} and {member.name} hold identical model files "
                "(the same run twice, not two training seeds)"
            )
        by_checksum[member.checksum] = member.name


def check_seed_disjointness(eval_seeds: Iterable[int], entries: Iterable[Entry]) -> None:
    """Raise ``ValueError`` if an evaluation seed is a seed recorded in any agent's training files.

    A multi-seed entry is checked seed by seed (the message names the ``<entry>/seed_<k>`` that clashes).
    """
    eval_set = set(eval_seeds)
    for entry in entries:
        for run in entry.runs():
            clash = sorted(eval_set & run.training_seeds)
            if clash:
                raise ValueError(
                    f"evaluation seeds {clash[:5]} of the leaderboard are training seeds of {run.name}; "
                    "the held-out evaluation must use seeds disjoint from training"
                )
