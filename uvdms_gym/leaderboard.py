"""Leaderboard: the baselines and trained agents ranked on collisions and tracking error, with bootstrap CIs.

:func:`run_leaderboard` evaluates a set of **entries** (the named baselines ``mpc``, ``campc``, ``campc-di``,
``campc-nndi``, every agent folder in the shipped-agents directory, and any agent checkpoint given by path)
on a **task suite** (:data:`TASKS`: the paper's Case 1, Case 2 and transport, plus held-out randomised
variants with ``hydro_randomization=0.3``) and writes ``leaderboard.md``, ``leaderboard.csv``, one JSON per
entry and PNG plots. The ``uvdms leaderboard`` command (:mod:`uvdms_gym.leaderboard_cli`) wraps it.

Tracks
    Entries are ranked separately in two tracks, by the action mode they command: ``velocity`` (``mpc``,
    ``campc``, agents unless their ``env_kwargs`` say ``action_mode: torque``) and ``torque``
    (``campc-di``, ``campc-nndi``). An entry runs only on its own track's action mode. An agent runs only on
    the tasks of the environment id it was trained on (a CircleTrack agent on every circle task, including
    the case it was not trained on; a Transport agent on the transport tasks); baselines run on every task.

Seeds
    Episode ``i`` of every task uses seed ``SEED_BASE + i`` (:data:`SEED_BASE` = 2,000,000,000), far above
    the training scheme of :mod:`agents.train` (training envs ``seed + 1000 k + i``, its evaluation envs
    ``seed + 1,000,000 + i``). Every integer stored under a key containing ``seed`` in an agent's
    ``meta.json``, ``config.yml`` or ``agent.json`` is collected and :func:`check_seed_disjointness` refuses
    to run if an evaluation seed is among them.

Statistics
    Per entry and task, every per-episode metric of :func:`baselines.evaluate.run_episode` is aggregated as
    its mean with a 95 % bootstrap confidence interval (:func:`bootstrap_ci`: ``scipy.stats.bootstrap``,
    BCa, 9,999 resamples, fixed seed; the percentile method if BCa is not finite; an all-equal sample gives
    the zero-width interval ``[x, x]``; fewer than two values give no interval). Two per-episode 0/1
    indicators are added, ``contact_free`` (no physical contact) and ``contact_free_success`` (the episode's
    ``success`` and no contact); their rates, like the success rate, are means of 0/1 values. The paper's
    tasks have a fixed start and no randomisation, so the episodes of a deterministic controller there are
    identical and their intervals have zero width; the randomised tasks carry the spread. Tables print an interval as
    ``mean ± h`` with ``h = max(mean - low, high - mean)`` (bootstrap intervals are asymmetric; the CSV and
    JSON hold the exact bounds).

Ranking (within each track and task, :func:`rank_rows`)
    1. Sort by contact-free success rate (higher first), then tracking RMSE ``rmse_pos`` (lower first; an
       entry without an RMSE sorts after those with one), then name.
    2. Walk the sorted list. An entry is **tied** with the first entry of the current tie group (its
       leader) if both their contact-free-success intervals and their RMSE intervals overlap (closed
       intervals, and two intervals less than :data:`TIE_TOLERANCE` apart (0.1 mm of RMSE) count as
       overlapping; a missing interval counts as the single point of its mean; two missing RMSEs overlap).
       Otherwise it starts a new group. Every member of a group gets the group's rank, which is one plus the
       number of entries ranked before the group (standard competition ranking: 1, 2=, 2=, 4); tied ranks
       print as ``2=``.

Cache
    Every (entry, task, seed) result is a JSON file under the cache directory, keyed by the SHA-256 of the
    entry identity (name and kind; for agents the SHA-256 of their model files), the task spec (env id,
    keyword arguments incl. the action mode, step limit, whether a trajectory is stored), the seed and the
    package version. Files are written atomically (temporary file + ``os.replace``) and reused on re-runs;
    ``force=True`` recomputes. A file that cannot be parsed or does not match its key is reported with
    ``logging.warning`` (by path) and recomputed.

Timings
    ``controller_ms_median`` is wall-clock time, so every computed episode stores a ``timing`` record
    (:func:`uvdms_gym.provenance.timing_record`: CPU model, core count, 1-minute load average at the start and
    end of the episode) in its cached result, and the run keeps one for itself. ``leaderboard.md`` states the
    machine(s) and loads, and marks with :data:`OVERLOAD_MARK` every timing cell of a row in which an episode
    ran with a load above the core count; ``leaderboard.csv`` has ``timing_episodes_overloaded``,
    ``timing_episodes_unknown_load``, ``timing_load_1min_max`` and ``timing_machine`` per row.

Safety
    Weights-only agent exports (:func:`agents.policy.load_weights_only`) evaluate without trust. A full SB3
    zip contains pickles: it is refused (:class:`agents.policy.UntrustedFileError`) unless it lies inside the
    repository's ``trained_agents/`` folder or ``trust=True``; the check runs before any evaluation.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import logging
import math
import os
import re
import sys
import tempfile
import warnings
import zipfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

import uvdms_gym
from uvdms_gym.provenance import timing_record

log = logging.getLogger("uvdms.leaderboard")

PACKAGE_VERSION = uvdms_gym.__version__
CACHE_FORMAT = 2
"""Version of the cached per-episode files (2: every result carries its ``timing`` record)."""
OVERLOAD_MARK = "†"
"""Marks a controller timing taken with a 1-minute load average above the core count (tables)."""
SEED_BASE = 2_000_000_000
"""Evaluation seed of episode ``i`` is ``SEED_BASE + i`` (see the module docstring)."""
D1, D2 = 0.05, 0.12
"""Collision-zone and anti-collision-zone thresholds (``uvdms_gym.envs.base.D1``/``D2``), m."""
CONFIDENCE = 0.95
N_RESAMPLES = 9999
BOOTSTRAP_SEED = 20240926

TRACKS: tuple[str, ...] = ("velocity", "torque")
BASELINES: dict[str, str] = {"mpc": "velocity", "campc": "velocity", "campc-di": "torque", "campc-nndi": "torque"}
"""Named baselines and their tracks."""
DEFAULT_ENTRIES: tuple[str, ...] = ("baselines", "agents")
"""``baselines`` stands for the four named baselines, ``agents`` for every agent folder in ``agents_dir``."""
DEFAULT_EPISODES = 20
QUICK_EPISODES = 2

REQUIRED_KEYS: tuple[str, ...] = ("seed", "contacts", "success", "rmse_pos", "min_distance", "steps")
"""Keys a cached per-episode result must have (a file without them is treated as corrupt)."""
METRICS: dict[str, dict[str, Any]] = {
    "contact_free_success": {"label": "Contact-free success", "fmt": ".2f", "better": "high"},
    "success": {"label": "Success", "fmt": ".2f", "better": "high"},
    "contact_free": {"label": "Contact-free", "fmt": ".2f", "better": "high"},
    "rmse_pos": {"label": "RMSE pos (mm)", "fmt": ".1f", "scale": 1e3, "better": "low"},
    "rmse_ori": {"label": "RMSE ori (deg)", "fmt": ".2f", "scale": 180 / math.pi, "better": "low"},
    "final_pos_error": {"label": "Final pos err (mm)", "fmt": ".1f", "scale": 1e3, "better": "low"},
    "final_ori_error": {"label": "Final ori err (deg)", "fmt": ".2f", "scale": 180 / math.pi, "better": "low"},
    "min_distance": {"label": "Min distance (m)", "fmt": ".3f", "better": "high"},
    "contacts": {"label": "Contacts", "fmt": ".1f", "better": "low"},
    "zone_steps": {"label": "Zone steps", "fmt": ".1f", "better": "low"},
    "cost": {"label": "Cost", "fmt": ".1f", "better": "low"},
    "return": {"label": "Return", "fmt": ".1f", "better": "high"},
    "steps": {"label": "Steps", "fmt": ".0f", "better": "high"},
    "controller_ms_median": {"label": "Ctrl ms", "fmt": ".2f", "better": "low"},
    "qp_slack_max": {"label": "QP slack max", "fmt": ".3g", "better": "low"},
}
"""Aggregated metrics (per-episode keys of ``run_episode`` plus the derived 0/1 indicators). Values are SI
(m, rad) everywhere but in the tables and plots, which multiply by ``scale`` (mm, degrees)."""
TIE_TOLERANCE: dict[str, float] = {"contact_free_success": 0.0, "rmse_pos": 1e-4}
"""Two intervals of a ranking metric closer than this count as overlapping (RMSE: 0.1 mm, the tables'
printed resolution; without it two deterministic controllers with zero-width intervals that print the same
value would be ranked apart)."""
TABLE_METRICS: tuple[str, ...] = (
    "contact_free_success",
    "success",
    "contact_free",
    "rmse_pos",
    "rmse_ori",
    "min_distance",
    "return",
    "controller_ms_median",
)
TIMING_METRICS: tuple[str, ...] = ("controller_ms_median",)
"""Metrics that are wall-clock timings (marked when taken under overload)."""
PLOT_METRICS: tuple[str, ...] = ("contact_free_success", "rmse_pos", "min_distance", "contacts", "return")
_AGENT_MODEL_SUFFIXES = (".zip", ".pkl", ".pt", ".npz")
_AGENT_CONFIG_NAMES = ("agent.json", "config.yml", "config.yaml")
_SEED_FILES = ("meta.json", "config.yml", "config.yaml", "agent.json")


# ------------------------------------------------------------------------------------------------------
# Tasks
# ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Task:
    """One task of the suite.

    Attributes:
        name: Short identifier (file names, CSV).
        label: Human-readable name (tables, plots).
        env_id: Gymnasium id.
        env_kwargs: ``gymnasium.make`` keyword arguments (the track adds ``action_mode``).
        paper: One of the paper's tasks (run by ``--quick``).
        trajectory: Store the minimum distance over time of the first episode (for the distance plot).
        max_episode_steps: Step limit override (``None``: the registered limit).
    """

    name: str
    label: str
    env_id: str
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    paper: bool = True
    trajectory: bool = False
    max_episode_steps: int | None = None

    def spec(self, track: str) -> dict[str, Any]:
        """The environment specification of this task on ``track`` (part of the cache key)."""
        return {
            "env_id": self.env_id,
            "env_kwargs": {**dict(self.env_kwargs), "action_mode": track},
            "max_episode_steps": self.max_episode_steps,
        }


CIRCLE_ID, TRANSPORT_ID = "uvdms/CircleTrack-v0", "uvdms/Transport-v0"
HYDRO_RANDOMIZATION = 0.3
TASKS: tuple[Task, ...] = (
    Task("case1", "Case 1", CIRCLE_ID, {"case": 1}, paper=True, trajectory=True),
    Task("case2", "Case 2", CIRCLE_ID, {"case": 2}, paper=True, trajectory=True),
    Task("transport", "Transport", TRANSPORT_ID, {"goal": "paper"}, paper=True),
    Task(
        "circle-random",
        "Random circles, hydro ±30 %",
        CIRCLE_ID,
        {"case": "random", "hydro_randomization": HYDRO_RANDOMIZATION},
        paper=False,
    ),
    Task(
        "transport-random",
        "Random goal, hydro ±30 %",
        TRANSPORT_ID,
        {"goal": "random", "hydro_randomization": HYDRO_RANDOMIZATION},
        paper=False,
    ),
)
"""The task suite: the paper's three tasks, then the held-out randomised variants."""


def select_tasks(names: Sequence[str] | None = None, *, quick: bool = False) -> tuple[Task, ...]:
    """Tasks by name (all of :data:`TASKS` by default; only the paper's with ``quick``).

    Raises:
        ValueError: An unknown task name.
    """
    by_name = {t.name: t for t in TASKS}
    if names:
        unknown = [n for n in names if n not in by_name]
        if unknown:
            raise ValueError(f"unknown task(s) {unknown}; choose from {sorted(by_name)}")
        tasks = tuple(by_name[n] for n in names)
    else:
        tasks = TASKS
    return tuple(t for t in tasks if t.paper) if quick else tasks


# ------------------------------------------------------------------------------------------------------
# Entries
# ------------------------------------------------------------------------------------------------------
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
    """

    name: str
    kind: str
    spec: str
    track: str
    env_id: str | None = None
    checksum: str | None = None
    training_seeds: frozenset[int] = frozenset()
    weights_only: bool = False

    def identity(self) -> dict[str, Any]:
        """What identifies the entry's behaviour in the cache key (agents: by content, not path)."""
        return {"name": self.name, "kind": self.kind, "checksum": self.checksum}

    def runs_on(self, task: Task) -> bool:
        """Whether the entry is evaluated on ``task`` (agents: only their training environment id)."""
        return self.env_id is None or self.env_id == task.env_id

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
        tokens: Baseline names, agent paths (a folder or an SB3 zip), ``baselines`` (the four baselines) or
            ``agents`` (every agent folder in ``agents_dir``). Default :data:`DEFAULT_ENTRIES`.
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
        from agents.policy import TRUSTED_DIR

        agents_dir = Path("trained_agents") if Path("trained_agents").is_dir() else TRUSTED_DIR
    entries: list[Entry] = []
    seen_specs: set[str] = set()
    for token in tokens or DEFAULT_ENTRIES:
        if token == "baselines":
            candidates: list[str] = list(BASELINES)
        elif token == "agents":
            candidates = [str(p) for p in find_agent_folders(agents_dir)]
        else:
            candidates = [token]
        for spec in candidates:
            if spec in BASELINES:
                key = spec
                entry = Entry(name=spec, kind="baseline", spec=spec, track=BASELINES[spec])
            else:
                path = Path(spec)
                if not path.exists():
                    raise ValueError(
                        f"entry {spec!r} is neither a baseline ({', '.join(BASELINES)}), 'baselines', 'agents', "
                        "nor an existing agent folder or checkpoint"
                    )
                key = str(path.resolve())
                entry = agent_entry(path, trust=trust)
            if key in seen_specs:
                continue
            seen_specs.add(key)
            entries.append(entry)
    return _unique_names(entries)


def _unique_names(entries: list[Entry]) -> list[Entry]:
    counts: dict[str, int] = {}
    out = []
    for entry in entries:
        n = counts.get(entry.name, 0)
        counts[entry.name] = n + 1
        if n:
            entry = replace(entry, name=f"{entry.name}-{n + 1}")
        out.append(entry)
    return out


def find_agent_folders(agents_dir: str | Path) -> list[Path]:
    """Sub-folders of ``agents_dir`` holding an agent (a weights-only ``agent.json`` or an SB3 ``.zip``)."""
    root = Path(agents_dir)
    if not root.is_dir():
        log.warning("agents folder %s does not exist: no shipped agents are evaluated", root)
        return []
    return [p for p in sorted(root.iterdir()) if p.is_dir() and (is_weights_only(p) or any(p.glob("*.zip")))]


def is_weights_only(path: str | Path) -> bool:
    """Whether ``path`` is a weights-only export folder (``agent.json`` of :mod:`agents.policy`)."""
    return Path(path).is_dir() and (Path(path) / "agent.json").is_file()


def agent_entry(path: str | Path, *, trust: bool = False) -> Entry:
    """An :class:`Entry` for an agent folder or checkpoint, read from its plain-text files (no unpickling).

    Raises:
        UntrustedFileError: The agent is a full SB3 zip outside ``trained_agents/`` and ``trust`` is false.
        ValueError: A folder without an agent, or a model archive that is not a valid zip file.
    """
    from agents.policy import UntrustedFileError, is_trusted_path

    path = Path(path)
    weights_only = is_weights_only(path)
    archives = sorted(path.glob("*.zip")) if path.is_dir() else [path]
    if path.is_dir() and not weights_only and not archives:
        raise ValueError(f"{path} is not an agent folder: it holds neither agent.json (weights-only export) nor a .zip")
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
    name = path.name if path.is_dir() else f"{path.parent.name}/{path.stem}"
    return Entry(
        name=name,
        kind="agent",
        spec=str(path),
        track=track,
        env_id=env_id,
        checksum=agent_checksum(path),
        training_seeds=frozenset(training_seeds(path)),
        weights_only=weights_only,
    )


def _agent_folders(path: Path) -> list[Path]:
    """Where an agent's plain-text run files may be: the folder (or a zip's folder) and its parent."""
    folder = path if path.is_dir() else path.parent
    return [folder, folder.parent]


def _read_structured(path: Path) -> Any:
    text = path.read_text(encoding="utf-8")
    return json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)


def agent_env(path: str | Path) -> tuple[str | None, dict[str, Any]]:
    """The training environment id and keyword arguments of an agent, from ``agent.json`` or ``config.yml``.

    Returns:
        ``(env_id, env_kwargs)``; ``(None, {})`` if no configuration file is found.
    """
    for folder in _agent_folders(Path(path)):
        for name in _AGENT_CONFIG_NAMES:
            file = folder / name
            if not file.is_file():
                continue
            try:
                doc = _read_structured(file)
            except (OSError, ValueError, yaml.YAMLError) as exc:
                log.warning("cannot read %s: %s", file, exc)
                continue
            if not isinstance(doc, dict):
                continue
            config = doc.get("config") if isinstance(doc.get("config"), dict) else {}
            env_kwargs = doc.get("env_kwargs") or config.get("env_kwargs") or {}
            env_id = doc.get("env_id") or config.get("env_id")
            if env_id is not None:
                return str(env_id).split(":")[-1], dict(env_kwargs)
    return None, {}


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
        for name in _SEED_FILES:
            file = folder / name
            if file.is_file():
                try:
                    seeds |= _collect_seeds(_read_structured(file))
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
            if p.is_file() and (p.suffix in _AGENT_MODEL_SUFFIXES or p.name in _AGENT_CONFIG_NAMES)
        ]
    else:
        files = [path, *sorted(p for p in path.parent.glob("*.pkl") if p.is_file())]
    digest = hashlib.sha256()
    for file in files:
        digest.update(file.name.encode() + b"\0")
        digest.update(hashlib.sha256(file.read_bytes()).digest())
    return digest.hexdigest()


def evaluation_seeds(episodes: int, base: int = SEED_BASE) -> list[int]:
    """The evaluation seeds ``base + i`` for ``i < episodes``."""
    return [base + i for i in range(episodes)]


def check_seed_disjointness(eval_seeds: Iterable[int], entries: Iterable[Entry]) -> None:
    """Raise ``ValueError`` if an evaluation seed is a seed recorded in any agent's training files."""
    eval_set = set(eval_seeds)
    for entry in entries:
        clash = sorted(eval_set & entry.training_seeds)
        if clash:
            raise ValueError(
                f"evaluation seeds {clash[:5]} of the leaderboard are training seeds of {entry.name}; "
                "the held-out evaluation must use seeds disjoint from training"
            )


# ------------------------------------------------------------------------------------------------------
# Statistics and ranking
# ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Stat:
    """A mean with its bootstrap confidence interval (``low``/``high`` NaN when undefined)."""

    mean: float
    low: float
    high: float
    n: int

    @property
    def half_width(self) -> float:
        """``max(mean - low, high - mean)`` (NaN without an interval)."""
        return max(self.mean - self.low, self.high - self.mean)

    def interval(self) -> tuple[float, float]:
        """The interval used for tie decisions: the CI, or the point ``[mean, mean]`` without one."""
        if math.isfinite(self.low) and math.isfinite(self.high):
            return self.low, self.high
        return self.mean, self.mean

    def to_json(self) -> dict[str, Any]:
        """Plain dict (NaN as ``None``)."""
        return {k: _finite_or_none(getattr(self, k)) for k in ("mean", "low", "high")} | {"n": self.n}

    def format(self, fmt: str = ".3f", scale: float = 1.0) -> str:
        """``mean ± half-width`` times ``scale`` (``—`` without data, ``mean (n=1)`` without an interval)."""
        if self.n == 0 or not math.isfinite(self.mean):
            return "—"
        if not math.isfinite(self.half_width):
            return f"{self.mean * scale:{fmt}} (n={self.n})"
        return f"{self.mean * scale:{fmt}} ± {self.half_width * scale:{fmt}}"


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def bootstrap_ci(
    values: Sequence[float] | np.ndarray,
    *,
    confidence: float = CONFIDENCE,
    n_resamples: int = N_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Stat:
    """Mean and bootstrap CI of the mean of ``values`` (non-finite values are dropped).

    Degenerate samples: no value gives NaN everything; one value gives the mean with no interval (NaN
    bounds); all-equal values give the zero-width interval at that value. Otherwise ``scipy.stats.bootstrap``
    (BCa; the percentile method if BCa returns a non-finite bound), seeded, and the bounds are widened to
    contain the mean if numerical noise would leave it outside.
    """
    from scipy import stats

    x = np.asarray(values, dtype=float).ravel()
    x = x[np.isfinite(x)]
    n = int(x.size)
    if n == 0:
        return Stat(math.nan, math.nan, math.nan, 0)
    mean = float(x.mean())
    if n < 2:
        return Stat(mean, math.nan, math.nan, n)
    if np.all(x == x[0]):
        value = float(x[0])  # exactly the common value (the float mean may differ in the last bit)
        return Stat(value, value, value, n)
    low = high = math.nan
    for method in ("BCa", "percentile"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = stats.bootstrap(
                (x,),
                np.mean,
                confidence_level=confidence,
                n_resamples=n_resamples,
                method=method,
                rng=np.random.default_rng(seed),
            )
        low, high = float(res.confidence_interval.low), float(res.confidence_interval.high)
        if math.isfinite(low) and math.isfinite(high):
            break
    return Stat(mean, min(low, mean), max(high, mean), n)


def intervals_overlap(a: Stat, b: Stat, tolerance: float = 0.0) -> bool:
    """Closed-interval overlap of two statistics' CIs, up to a gap of ``tolerance``.

    See :meth:`Stat.interval` for a statistic without an interval; two statistics without data overlap.
    """
    if a.n == 0 or b.n == 0 or not (math.isfinite(a.mean) and math.isfinite(b.mean)):
        return (a.n == 0 or not math.isfinite(a.mean)) and (b.n == 0 or not math.isfinite(b.mean))
    (a_lo, a_hi), (b_lo, b_hi) = a.interval(), b.interval()
    return a_lo <= b_hi + tolerance and b_lo <= a_hi + tolerance


@dataclass
class RankedRow:
    """A (track, task, entry) cell of the leaderboard."""

    entry: Entry
    task: Task
    stats: dict[str, Stat]
    episodes: list[dict[str, Any]]
    rank: int = 0
    tied: bool = False

    @property
    def rank_label(self) -> str:
        """``3`` or ``3=`` for a tie."""
        return f"{self.rank}=" if self.tied else str(self.rank)

    @property
    def timing(self) -> dict[str, Any]:
        """Where and under what load this row's controller timings ran (:func:`timing_summary` of its episodes)."""
        return timing_summary(self.episodes)


def timing_summary(episodes: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Summary of the per-episode timing records (:func:`uvdms_gym.provenance.timing_record`).

    Returns:
        ``{"overloaded": episodes whose 1-minute load exceeded the core count, "unknown": episodes without a
        load record, "load_1min_max": highest load seen (``None`` if none), "machines": sorted distinct
        ``"<cpu model> (<n> cores)"``}``.
    """
    overloaded = unknown = 0
    loads: list[float] = []
    machines: set[str] = set()
    for ep in episodes:
        record = ep.get("timing")
        flag = record.get("overloaded") if isinstance(record, Mapping) else None
        if flag is None:
            unknown += 1
        overloaded += int(flag is True)
        if isinstance(record, Mapping):
            loads += [x for x in (record.get("load_1min_start"), record.get("load_1min_end")) if x is not None]
            machine = record.get("machine") or {}
            machines.add(f"{machine.get('cpu_model', 'unknown')} ({machine.get('cpu_count', '?')} cores)")
    return {
        "overloaded": overloaded,
        "unknown": unknown,
        "load_1min_max": max(loads) if loads else None,
        "machines": sorted(machines),
    }


def _sort_key(row: RankedRow) -> tuple[float, float, str]:
    cfs = row.stats["contact_free_success"].mean
    rmse = row.stats["rmse_pos"].mean
    return (
        -(cfs if math.isfinite(cfs) else -1.0),
        rmse if math.isfinite(rmse) else math.inf,
        row.entry.name,
    )


def rank_rows(rows: Sequence[RankedRow]) -> list[RankedRow]:
    """Rank one (track, task) group in place and return it sorted (rule in the module docstring)."""
    ordered = sorted(rows, key=_sort_key)
    leader: RankedRow | None = None
    group: list[RankedRow] = []
    for position, row in enumerate(ordered, start=1):
        if leader is not None and all(
            intervals_overlap(leader.stats[m], row.stats[m], TIE_TOLERANCE[m]) for m in _RANK_METRICS
        ):
            row.rank = leader.rank
            group.append(row)
        else:
            leader, group = row, [row]
            row.rank = position
        if len(group) > 1:
            for member in group:
                member.tied = True
    return ordered


_RANK_METRICS = ("contact_free_success", "rmse_pos")


def episode_indicators(result: Mapping[str, Any]) -> dict[str, float]:
    """The derived 0/1 indicators of one episode: ``contact_free`` and ``contact_free_success``."""
    contact_free = float((result.get("contacts") or 0) == 0)
    return {"contact_free": contact_free, "contact_free_success": float(bool(result.get("success")) and contact_free)}


def aggregate(results: Sequence[Mapping[str, Any]]) -> dict[str, Stat]:
    """Mean and bootstrap CI of every metric in :data:`METRICS` over the episodes ``results``."""
    out = {}
    for index, metric in enumerate(METRICS):
        values = []
        for result in results:
            value = episode_indicators(result)[metric] if metric in ("contact_free", "contact_free_success") else None
            if value is None:
                raw = result.get(metric)
                if raw is None or isinstance(raw, str):
                    continue
                value = float(raw)
            values.append(value)
        out[metric] = bootstrap_ci(values, seed=BOOTSTRAP_SEED + index)
    return out


# ------------------------------------------------------------------------------------------------------
# Cache
# ------------------------------------------------------------------------------------------------------
class CorruptCacheError(ValueError):
    """A cached result file that cannot be used."""


def cache_material(entry: Entry, task: Task, seed: int, save_trajectory: bool) -> dict[str, Any]:
    """Everything the cache key hashes (see the module docstring)."""
    return {
        "format": CACHE_FORMAT,
        "package_version": PACKAGE_VERSION,
        "entry": entry.identity(),
        "task": task.spec(entry.track),
        "seed": int(seed),
        "trajectory": bool(save_trajectory),
    }


def cache_key(material: Mapping[str, Any]) -> str:
    """SHA-256 of the canonical JSON of ``material``."""
    return hashlib.sha256(json.dumps(material, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def cache_path(cache_dir: str | Path, entry: Entry, task: Task, seed: int, key: str) -> Path:
    """``<cache_dir>/<entry>/<task>/seed<seed>-<key[:16]>.json``."""
    return Path(cache_dir) / entry.slug / task.name / f"seed{seed}-{key[:16]}.json"


def atomic_write_json(path: str | Path, data: Any) -> None:
    """Write ``data`` as JSON to ``path`` atomically (temporary file in the same folder, then ``os.replace``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(data, f, allow_nan=False, separators=(",", ":"))
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give the file the usual permissions
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def read_cached(path: str | Path, key: str) -> dict[str, Any]:
    """The per-episode result stored at ``path`` for ``key``.

    Raises:
        FileNotFoundError: No file.
        CorruptCacheError: Unparsable, truncated, for another key, or missing required result keys.
    """
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise CorruptCacheError(f"not valid JSON ({exc})") from exc
    if not isinstance(doc, dict) or doc.get("key") != key:
        raise CorruptCacheError("key mismatch")
    result = doc.get("result")
    if not isinstance(result, dict):
        raise CorruptCacheError("no result")
    missing = [k for k in REQUIRED_KEYS if k not in result]
    if missing:
        raise CorruptCacheError(f"result lacks {missing}")
    if result["seed"] != doc.get("material", {}).get("seed"):
        raise CorruptCacheError("seed mismatch")
    return result


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, np.bool_ | bool):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    return value


def compact_result(result: Mapping[str, Any]) -> dict[str, Any]:
    """A JSON-safe copy of a per-episode result whose trajectory is reduced to ``t`` and the minimum distance."""
    out = {k: v for k, v in result.items() if k != "trajectory"}
    traj = result.get("trajectory")
    if isinstance(traj, Mapping) and "t" in traj and "distances" in traj:
        t = np.asarray(traj["t"], dtype=float)
        d = np.asarray(traj["distances"], dtype=float)
        d_min = d.min(axis=1) if d.ndim == 2 else d
        out["trajectory"] = {"t": np.round(t, 4).tolist(), "min_distance": np.round(d_min, 5).tolist()}
    return _jsonable(out)


# ------------------------------------------------------------------------------------------------------
# Evaluation
# ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Backend:
    """How episodes are run (module-level callables, so that worker processes can receive them).

    Attributes:
        make_env: ``(task spec) -> env``.
        make_controller: ``(spec, env, trust) -> controller``.
        run_episode: ``(env, controller, seed, save_trajectory) -> dict`` (per-episode metrics).
    """

    make_env: Callable[[Mapping[str, Any]], Any]
    make_controller: Callable[[str, Any, bool], Any]
    run_episode: Callable[[Any, Any, int, bool], dict[str, Any]]


def make_env(spec: Mapping[str, Any]) -> Any:
    """``gymnasium.make`` of a task spec (:meth:`Task.spec`)."""
    import gymnasium as gym

    kwargs = dict(spec["env_kwargs"])
    if spec.get("max_episode_steps") is not None:
        kwargs["max_episode_steps"] = spec["max_episode_steps"]
    return gym.make(spec["env_id"], **kwargs)


def _real_make_controller(spec: str, env: Any, trust: bool) -> Any:
    from baselines.controllers import make_controller

    return make_controller(spec, env, trust=trust)


def _real_run_episode(env: Any, controller: Any, seed: int, save_trajectory: bool) -> dict[str, Any]:
    from baselines.evaluate import run_episode

    return run_episode(env, controller, seed, save_trajectory=save_trajectory)


DEFAULT_BACKEND = Backend(make_env=make_env, make_controller=_real_make_controller, run_episode=_real_run_episode)


@dataclass(frozen=True)
class Job:
    """One episode to compute."""

    entry: Entry
    task: Task
    seed: int
    save_trajectory: bool
    key: str
    material: dict[str, Any]
    path: Path


_WORKER: dict[str, Any] = {}
"""Per-process reuse of the environment (and of stateless agent controllers) across consecutive jobs."""


def _worker_init() -> None:
    import atexit

    atexit.register(_close_worker_env)  # disconnect the worker's last simulator before interpreter teardown
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # pragma: no cover - torch is a dependency
        pass


def _close_worker_env() -> None:
    env = _WORKER.pop("env", None)
    _WORKER.pop("controller", None)
    _WORKER.pop("key", None)
    if env is not None:
        env.close()


def compute_job(job: Job, backend: Backend, trust: bool) -> dict[str, Any]:
    """Run one episode, store it atomically in the cache, and return the compact result."""
    group = (job.entry.name, job.entry.checksum, json.dumps(job.task.spec(job.entry.track), sort_keys=True))
    if _WORKER.get("key") != group:
        _close_worker_env()
        _WORKER["env"] = backend.make_env(job.task.spec(job.entry.track))
        _WORKER["key"] = group
    env = _WORKER["env"]
    controller = _WORKER.get("controller") if job.entry.kind == "agent" else None
    if controller is None:  # baselines are stateful (adaptive networks, warm starts): a fresh one per episode
        controller = backend.make_controller(job.entry.spec, env, trust)
        if job.entry.kind == "agent":
            _WORKER["controller"] = controller
    with timing_record() as timing:
        raw = backend.run_episode(env, controller, job.seed, job.save_trajectory)
    result = compact_result(raw)
    result["seed"] = int(job.seed)
    result["timing"] = timing
    atomic_write_json(job.path, {"key": job.key, "material": job.material, "result": result})
    return result


@dataclass
class LeaderboardResult:
    """What :func:`run_leaderboard` computed."""

    rows: list[RankedRow]
    entries: list[Entry]
    tasks: tuple[Task, ...]
    seeds: list[int]
    computed: int
    cached: int
    corrupt: list[Path]
    out_dir: Path
    markdown: str = ""
    timing: dict[str, Any] = field(default_factory=dict)


def plan_jobs(
    entries: Sequence[Entry], tasks: Sequence[Task], seeds: Sequence[int], cache_dir: str | Path
) -> list[Job]:
    """Every (entry, task, seed) episode of the run, grouped by entry and task."""
    jobs = []
    for entry in entries:
        for task in tasks:
            if not entry.runs_on(task):
                continue
            for i, seed in enumerate(seeds):
                save = task.trajectory and i == 0
                material = cache_material(entry, task, seed, save)
                key = cache_key(material)
                jobs.append(Job(entry, task, seed, save, key, material, cache_path(cache_dir, entry, task, seed, key)))
    return jobs


def run_leaderboard(
    entries: Sequence[Entry],
    *,
    out_dir: str | Path = "leaderboard_out",
    cache_dir: str | Path | None = None,
    tasks: Sequence[Task] = TASKS,
    episodes: int = DEFAULT_EPISODES,
    force: bool = False,
    trust: bool = False,
    jobs: int = 1,
    progress: bool = True,
    plots: bool = True,
    backend: Backend | None = None,
    command: str | None = None,
) -> LeaderboardResult:
    """Evaluate ``entries`` on ``tasks`` (cached), rank them per track and task, and write the outputs.

    Args:
        entries: From :func:`resolve_entries`.
        out_dir: Output folder (``leaderboard.md``, ``leaderboard.csv``, ``entries/*.json``, ``plots/*.png``).
        cache_dir: Per-episode cache (default ``<out_dir>/cache``; a ``.gitignore`` inside keeps it out of git).
        tasks: The task suite.
        episodes: Episodes per (entry, task).
        force: Recompute every episode (overwriting the cache).
        trust: Passed to ``make_controller`` (unpickling agents outside ``trained_agents/``).
        jobs: Worker processes (1: in this process).
        progress: Show a tqdm progress bar (stderr).
        plots: Write the PNG plots.
        backend: How environments, controllers and episodes are made (default :data:`DEFAULT_BACKEND`; tests
            substitute a fake one).
        command: The command line, recorded in ``leaderboard.md``.

    Returns:
        The ranked rows and run statistics.

    Raises:
        ValueError: No entries, ``episodes < 1``, or evaluation seeds that clash with training seeds.
    """
    from tqdm.auto import tqdm

    backend = backend if backend is not None else DEFAULT_BACKEND
    if not entries:
        raise ValueError("no entries to evaluate")
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    out = Path(out_dir)
    cache = Path(cache_dir) if cache_dir is not None else out / "cache"
    seeds = evaluation_seeds(episodes)
    check_seed_disjointness(seeds, entries)
    cache.mkdir(parents=True, exist_ok=True)
    if not (cache / ".gitignore").exists():
        (cache / ".gitignore").write_text("*\n", encoding="utf-8")

    all_jobs = plan_jobs(entries, tasks, seeds, cache)
    results: dict[Path, dict[str, Any]] = {}
    corrupt: list[Path] = []
    todo: list[Job] = []
    for job in all_jobs:
        if force:
            todo.append(job)
            continue
        try:
            results[job.path] = read_cached(job.path, job.key)
        except FileNotFoundError:
            todo.append(job)
        except (CorruptCacheError, OSError, UnicodeDecodeError) as exc:
            log.warning("corrupt cached result %s (%s): recomputing", job.path, exc)
            corrupt.append(job.path)
            todo.append(job)
    n_cached = len(all_jobs) - len(todo)
    log.info(
        "leaderboard: %d entries, %d tasks, %d episodes each: %d cached, %d to compute",
        len(entries),
        len(tasks),
        episodes,
        n_cached,
        len(todo),
    )
    with timing_record() as run_record:  # the run's machine and load (each episode has its own record)
        bar = tqdm(
            total=len(all_jobs),
            initial=n_cached,
            desc="leaderboard",
            unit="ep",
            disable=not progress,
            mininterval=0.1 if sys.stderr.isatty() else 30.0,  # a log file gets a line every 30 s, not every episode
        )
        try:
            if jobs <= 1 or len(todo) <= 1:
                try:
                    for job in todo:
                        bar.set_postfix_str(f"{job.entry.name} / {job.task.name}", refresh=False)
                        try:
                            results[job.path] = compute_job(job, backend, trust)
                        except Exception:
                            log.error("episode failed: %s on %s, seed %d", job.entry.name, job.task.name, job.seed)
                            raise
                        bar.update()
                finally:
                    _close_worker_env()
            else:
                import multiprocessing

                context = multiprocessing.get_context("spawn")
                pool = ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=_worker_init)
                try:
                    futures = {pool.submit(compute_job, job, backend, trust): job for job in todo}
                    for future in as_completed(futures):
                        job = futures[future]
                        try:
                            results[job.path] = future.result()
                        except Exception:
                            log.error("episode failed: %s on %s, seed %d", job.entry.name, job.task.name, job.seed)
                            raise
                        bar.set_postfix_str(f"{job.entry.name} / {job.task.name}", refresh=False)
                        bar.update()
                finally:
                    pool.shutdown(wait=True, cancel_futures=True)
        finally:
            bar.close()

    rows = []
    for entry in entries:
        for task in tasks:
            if not entry.runs_on(task):
                continue
            episodes_ = [results[j.path] for j in all_jobs if j.entry is entry and j.task is task]
            rows.append(RankedRow(entry, task, aggregate(episodes_), episodes_))
    ranked: list[RankedRow] = []
    for track in TRACKS:
        for task in tasks:
            group = [r for r in rows if r.entry.track == track and r.task is task]
            if group:
                ranked.extend(rank_rows(group))
    result = LeaderboardResult(
        rows=ranked,
        entries=list(entries),
        tasks=tuple(tasks),
        seeds=seeds,
        computed=len(todo),
        cached=n_cached,
        corrupt=corrupt,
        out_dir=out,
        timing=run_record,
    )
    write_outputs(result, command=command, plots=plots)
    return result


# ------------------------------------------------------------------------------------------------------
# Outputs
# ------------------------------------------------------------------------------------------------------
def markdown_tables(result: LeaderboardResult, metrics: Sequence[str] = TABLE_METRICS) -> str:
    """One markdown table per track (ranked within each task), with the columns ``metrics``."""
    lines: list[str] = []
    for track in TRACKS:
        rows = [r for r in result.rows if r.entry.track == track]
        if not rows:
            continue
        lines.append(f"### {track.capitalize()} track")
        lines.append("")
        header = ["Task", "Rank", "Entry", *[METRICS[m]["label"] for m in metrics], "n"]
        lines.append("| " + " | ".join(header) + " |")
        lines.append("|" + "|".join(["---"] * 3 + ["--:"] * (len(metrics) + 1)) + "|")
        marked = False
        for row in rows:
            cells = [row.task.label, row.rank_label, row.entry.name]
            for m in metrics:
                cell = row.stats[m].format(METRICS[m]["fmt"], METRICS[m].get("scale", 1.0))
                if m in TIMING_METRICS and row.timing["overloaded"]:
                    cell += f" {OVERLOAD_MARK}"
                    marked = True
                cells.append(cell)
            cells.append(str(len(row.episodes)))
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
        if marked:
            lines.append(
                f"{OVERLOAD_MARK} timed with a 1-minute load average above the machine's core count in some of the "
                "row's episodes (other processes shared the CPU): the timing reads long."
            )
            lines.append("")
    return "\n".join(lines)


def timing_text(result: LeaderboardResult) -> str:
    """One sentence: the machine(s) and the load under which the run's timings were taken."""
    summary = timing_summary([ep for row in result.rows for ep in row.episodes])
    run = result.timing or {}
    machines = ", ".join(summary["machines"]) or "unknown"
    n = sum(len(row.episodes) for row in result.rows)
    text = (
        f"Timings (`Ctrl ms`, `controller_ms_median`) were taken on {machines}; 1-minute load average "
        f"{run.get('load_1min_start')} at the start and {run.get('load_1min_end')} at the end of this run "
        f"(episodes from the cache keep the record of the run that computed them), highest seen in an episode "
        f"{summary['load_1min_max']}; {summary['overloaded']} of {n} episodes ran with a load above the core count"
    )
    if summary["unknown"]:
        text += f", {summary['unknown']} without a load record"
    return text + f" (marked {OVERLOAD_MARK})."


def _markdown_document(result: LeaderboardResult, command: str | None, plot_files: Sequence[str]) -> str:
    seeds = result.seeds
    seed_text = f"{seeds[0]}" if len(seeds) == 1 else f"{seeds[0]}–{seeds[-1]}"
    task_lines = [
        f"- **{t.label}** (`{t.name}`): `{t.env_id}` with `{json.dumps(dict(t.env_kwargs))}`" for t in result.tasks
    ]
    parts = [
        "# uvdms-gym leaderboard",
        "",
        f"Generated by `{command or 'uvdms leaderboard'}` (uvdms-gym {PACKAGE_VERSION}); "
        f"{len(seeds)} episode(s) per entry and task, evaluation seeds {seed_text} "
        "(disjoint from every training seed).",
        "",
        "Tasks:",
        "",
        *task_lines,
        "",
        "Each cell is the mean over episodes ± the half-width of its 95 % bootstrap confidence interval "
        "(`max(mean - low, high - mean)`; exact bounds in `leaderboard.csv`). Rates are fractions of episodes: "
        "*contact-free* = no physical contact, *contact-free success* = task success without contact. "
        "Ranking within each track and task: contact-free success rate (higher first), then position RMSE "
        "(lower first); an entry whose contact-free-success and RMSE intervals both overlap those of the "
        "first entry of the current group (RMSE intervals less than 0.1 mm apart count as overlapping) is tied "
        "with it (`2=`). Success: the episode ran to its time limit without contact and, on the circle tasks, "
        "with RMSE <= 30 mm; on transport, with the object at the goal at the end (`baselines/evaluate.py`). "
        "The paper's tasks have a fixed start and no randomisation: a deterministic controller repeats the "
        "same episode there (zero-width intervals); the randomised tasks carry the spread. Agents run only on "
        "the tasks of the environment they were trained on.",
        "",
        timing_text(result),
        "",
        markdown_tables(result),
    ]
    if plot_files:
        parts += ["## Plots", ""]
        parts += [f"![{Path(p).stem}]({p})" for p in plot_files]
        parts.append("")
    return "\n".join(parts)


def _csv_text(result: LeaderboardResult) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    header = ["track", "task", "rank", "tied", "entry", "kind", "episodes"]
    for metric in METRICS:
        header += [f"{metric}_mean", f"{metric}_ci_low", f"{metric}_ci_high"]
    header += ["timing_episodes_overloaded", "timing_episodes_unknown_load", "timing_load_1min_max", "timing_machine"]
    writer.writerow(header)
    for row in result.rows:
        cells: list[Any] = [
            row.entry.track,
            row.task.name,
            row.rank,
            int(row.tied),
            row.entry.name,
            row.entry.kind,
            len(row.episodes),
        ]
        for metric in METRICS:
            stat = row.stats[metric]
            cells += ["" if not math.isfinite(v) else f"{v:.6g}" for v in (stat.mean, stat.low, stat.high)]
        timing = row.timing
        load_max = timing["load_1min_max"]
        cells += [timing["overloaded"], timing["unknown"], "" if load_max is None else load_max]
        cells.append("; ".join(timing["machines"]))
        writer.writerow(cells)
    return buffer.getvalue()


def _entry_document(entry: Entry, rows: Sequence[RankedRow]) -> dict[str, Any]:
    return {
        "name": entry.name,
        "kind": entry.kind,
        "spec": entry.spec if entry.kind == "baseline" else Path(entry.spec).name,
        "track": entry.track,
        "env_id": entry.env_id,
        "checksum": entry.checksum,
        "weights_only": entry.weights_only,
        "package_version": PACKAGE_VERSION,
        "tasks": {
            row.task.name: {
                "rank": row.rank,
                "tied": row.tied,
                "timing": row.timing,
                "stats": {m: s.to_json() for m, s in row.stats.items()},
                "episodes": [{k: v for k, v in ep.items() if k != "trajectory"} for ep in row.episodes],
            }
            for row in rows
        },
    }


def write_outputs(result: LeaderboardResult, *, command: str | None = None, plots: bool = True) -> None:
    """Write ``leaderboard.md``, ``leaderboard.csv``, ``entries/<entry>.json`` and (optionally) the plots."""
    out = result.out_dir
    out.mkdir(parents=True, exist_ok=True)
    plot_files = write_plots(result, out / "plots") if plots else []
    rel = [str(Path(p).relative_to(out)) for p in plot_files]
    result.markdown = _markdown_document(result, command, rel)
    (out / "leaderboard.md").write_text(result.markdown, encoding="utf-8")
    (out / "leaderboard.csv").write_text(_csv_text(result), encoding="utf-8")
    entries_dir = out / "entries"
    entries_dir.mkdir(exist_ok=True)
    for entry in result.entries:
        rows = [r for r in result.rows if r.entry is entry]
        atomic_write_json(entries_dir / f"{entry.slug}.json", _entry_document(entry, rows))


def write_plots(result: LeaderboardResult, plot_dir: str | Path) -> list[Path]:
    """Bar charts with CI whiskers per track and metric, and minimum distance over time on the circle tasks.

    Returns:
        The written PNG paths.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    plot_dir = Path(plot_dir)
    plot_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for track in TRACKS:
        rows = [r for r in result.rows if r.entry.track == track]
        if not rows:
            continue
        names = list(dict.fromkeys(r.entry.name for r in rows))
        tasks = [t for t in result.tasks if any(r.task is t for r in rows)]
        for metric in PLOT_METRICS:
            fig, ax = plt.subplots(figsize=(max(6.0, 1.2 * len(tasks) * max(1, len(names)) * 0.35 + 3), 4.0))
            width = 0.8 / max(1, len(names))
            plotted: list[float] = []
            for k, name in enumerate(names):
                xs, ys, lo, hi = [], [], [], []
                for i, task in enumerate(tasks):
                    row = next((r for r in rows if r.task is task and r.entry.name == name), None)
                    if row is None or not math.isfinite(row.stats[metric].mean):
                        continue
                    stat = row.stats[metric]
                    scale = METRICS[metric].get("scale", 1.0)
                    a, b = stat.interval()
                    xs.append(i - 0.4 + width * (k + 0.5))
                    ys.append(stat.mean * scale)
                    lo.append((stat.mean - a) * scale)
                    hi.append((b - stat.mean) * scale)
                if xs:
                    ax.bar(xs, ys, width, yerr=[lo, hi], capsize=3, label=name)
                    plotted.extend(ys)
            ax.set_xticks(range(len(tasks)), [t.label for t in tasks], rotation=15, ha="right")
            ax.set_ylabel(METRICS[metric]["label"])
            positive = [v for v in plotted if v > 0]
            if METRICS[metric].get("scale") and positive and max(positive) > 30 * min(positive):
                ax.set_yscale("log")  # errors spanning orders of magnitude (sub-mm MPC vs. cm agents)
            ax.set_title(f"{track} track: {METRICS[metric]['label']} (mean, 95 % bootstrap CI)")
            if metric == "min_distance":
                ax.axhline(D1, color="black", linestyle="--", linewidth=1, label="d1")
                ax.axhline(D2, color="0.4", linestyle=":", linewidth=1.2, label="d2")
            ax.legend(fontsize=7, ncol=2)
            ax.grid(axis="y", alpha=0.3)
            fig.tight_layout()
            path = plot_dir / f"{track}_{metric}.png"
            fig.savefig(path, dpi=110)
            plt.close(fig)
            written.append(path)
    for task in result.tasks:
        if not task.trajectory:
            continue
        curves = []
        for row in result.rows:
            if row.task is not task:
                continue
            traj = next((ep.get("trajectory") for ep in row.episodes if ep.get("trajectory")), None)
            if traj:
                curves.append((row.entry, traj))
        if not curves:
            continue
        fig, ax = plt.subplots(figsize=(8.0, 4.5))
        for entry, traj in curves:
            style = "-" if entry.track == "velocity" else "--"
            ax.plot(traj["t"], traj["min_distance"], style, linewidth=1.2, label=f"{entry.name} ({entry.track})")
        ax.axhline(D1, color="black", linestyle="--", linewidth=1, label="d1 = 0.05 m")
        ax.axhline(D2, color="0.4", linestyle=":", linewidth=1.2, label="d2 = 0.12 m")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("minimum of the 18 distances (m)")
        ax.set_title(f"{task.label}: minimum distance over time (first evaluation seed)")
        ax.legend(fontsize=7, ncol=2)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        path = plot_dir / f"min_distance_{task.name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written
