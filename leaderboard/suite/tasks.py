"""The task suite (paper tasks, randomised variants, realism track, cooperative group), tracks and draws.

The draws are the seeds of the protocol of :mod:`uvdms_gym.seeds`: draw ``i`` of a split is its seed ``start + i``;
a deterministic task (the paper's and ``coop``: a fixed start, no randomisation) has one draw, a randomised task
:data:`DEFAULT_EPISODES` (fewer where :attr:`Task.max_draws` caps them).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from gymnasium.envs.registration import parse_env_id

from uvdms_gym.seeds import split_seeds
from uvdms_gym.utils.kwargs import env_family  # re-exported: the one home of the versionless id

TRACKS: tuple[str, ...] = ("velocity", "torque")
"""The two tracks, by the action mode their entries command."""
DEFAULT_EPISODES = 100
"""Draws of a randomised task (a rate near 0.5 then has a 95 % interval of about +-0.1)."""
QUICK_EPISODES = 2
"""Draws of a randomised task with ``--quick`` (which runs the deterministic paper tasks only)."""
DEFAULT_SPLIT = "test"
"""The split the leaderboard ranks on (:mod:`uvdms_gym.seeds`)."""
CHECK_SPLIT = "test2"
"""The second test set: the randomised tasks' generalisation check (:mod:`leaderboard.stats.generalization`)."""


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
        deterministic: A fixed start and no randomisation: every seed gives the same episode, so the task has one
            draw, which every training seed of an entry evaluates (:meth:`draws`).
        realism: The sensing and actuation realism level of the task (0: the oracle; its ``env_kwargs`` hold it).
        check: A randomised task that also runs the generalisation check on the second test set.
        max_draws: At most this many draws, whatever the run's ``episodes`` (``None``: no cap).
        grasp: How the task's environment holds the object: ``"rigid"`` (welded; also the circle tasks, which
            hold none) or ``"friction"`` (the cooperative tasks, :data:`COOP_TASKS`). A baseline restricted to a
            grasp (``BASELINES[name]["grasp"]``, :data:`leaderboard.suite.registry.GRASP_OF`) runs only on the
            tasks of that grasp; the friction tasks' tables add :data:`leaderboard.stats.metrics.GRASP_METRICS`.
    """

    name: str
    label: str
    env_id: str
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    paper: bool = True
    trajectory: bool = False
    max_episode_steps: int | None = None
    deterministic: bool = False
    realism: int = 0
    check: bool = True
    max_draws: int | None = None
    grasp: str = "rigid"

    def draws(self, split: str, episodes: int) -> list[int]:
        """The task's draws on ``split``: one for a deterministic task, else ``episodes`` (``split_seeds``)."""
        n = 1 if self.deterministic else episodes if self.max_draws is None else min(episodes, self.max_draws)
        return split_seeds(split, n)

    def spec(self, track: str, env_id: str | None = None) -> dict[str, Any]:
        """The environment specification of this task on ``track`` (part of the cache key).

        Args:
            track: ``"velocity"`` or ``"torque"`` (the ``action_mode``).
            env_id: Another version of the task's environment (same :func:`env_family`, e.g. ``-v1`` for an
                agent trained on it); ``None``: :attr:`env_id`.

        Raises:
            ValueError: ``env_id`` is not a version of the task's environment.
        """
        if env_id is not None and env_family(env_id) != env_family(self.env_id):
            raise ValueError(f"task {self.name!r} runs {self.env_id!r}, not {env_id!r} (another environment)")
        return {
            "env_id": env_id or self.env_id,
            "env_kwargs": {**dict(self.env_kwargs), "action_mode": track},
            "max_episode_steps": self.max_episode_steps,
        }


def env_version(env_id: str) -> str:
    """The version tag of an environment id (``uvdms/CircleTrack-v1`` -> ``v1``; ``""`` without a version)."""
    _namespace, _name, version = parse_env_id(env_id.split(":")[-1])
    return "" if version is None else f"v{version}"


CIRCLE_ID, TRANSPORT_ID = "uvdms/CircleTrack-v0", "uvdms/Transport-v0"
OBSTACLES_ID = "uvdms/TransportObstacles-v1"
HYDRO_RANDOMIZATION = 0.3
TASKS: tuple[Task, ...] = (
    Task("case1", "Case 1", CIRCLE_ID, {"case": 1}, paper=True, trajectory=True, deterministic=True),
    Task("case2", "Case 2", CIRCLE_ID, {"case": 2}, paper=True, trajectory=True, deterministic=True),
    Task("transport", "Transport", TRANSPORT_ID, {"goal": "paper"}, paper=True, deterministic=True),
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
    Task(
        "transport-obstacles",
        "Moving obstacles, current",
        OBSTACLES_ID,
        {"obstacles": "random", "current": "random"},
        paper=False,
    ),
)
REALISM_DRAWS = 30
"""Draws per task of the realism track (fewer than :data:`DEFAULT_EPISODES`: nine tasks; intervals about ±0.18 at
rates near 0.5, narrower near 0 and 1)."""
REALISM_LEVELS: tuple[int, ...] = (1, 2, 3)
"""The realism track's levels (:mod:`uvdms_gym.realism`)."""
REALISM_BASES: tuple[str, ...] = ("circle-random", "transport-random", "transport-obstacles")
"""The randomised tasks the realism track runs at every level."""


def _realism_tasks(tasks: Sequence[Task]) -> tuple[Task, ...]:
    """The realism track: each of :data:`REALISM_BASES` at each level (named ``<task>-r<level>``).

    The same environments and draws as the oracle tasks, with ``realism=<level>`` added to their keywords; at most
    :data:`REALISM_DRAWS` draws and no generalisation check (at 100 draws with the check, the track would cost
    more than three times the rest of the leaderboard).
    """
    out = []
    for level in REALISM_LEVELS:
        for task in (t for t in tasks if t.name in REALISM_BASES):
            out.append(
                replace(
                    task,
                    name=f"{task.name}-r{level}",
                    label=f"{task.label}, realism {level}",
                    env_kwargs={**dict(task.env_kwargs), "realism": level},
                    realism=level,
                    check=False,
                    max_draws=REALISM_DRAWS,
                )
            )
    return tuple(out)


COOP_ID, COOP_OBSTACLES_ID = "uvdms/CooperativeTransport-v1", "uvdms/CooperativeTransportObstacles-v1"
COOP_OBSTACLE_DRAWS = 30
"""Draws of ``coop-obstacles`` (fewer than :data:`DEFAULT_EPISODES`, as the realism track's
:data:`REALISM_DRAWS`: the MPC's outer-obstacle rows make its episodes dearer than
those of ``coop-random``; intervals about ±0.18 at rates near 0.5). The randomised cooperative tasks run no
generalisation check: it would double their cost (as many ``test2`` draws again), and the friction grasp changes
the object's hold, not the draw distributions the check is about, which ``transport-random`` and
``transport-obstacles`` check already; ``coop-random`` keeps the default :data:`DEFAULT_EPISODES` draws."""
COOP_TASKS: tuple[Task, ...] = (
    Task(
        "coop", "Cooperative transport", COOP_ID, {"goal": "paper"}, paper=False, deterministic=True, grasp="friction"
    ),
    Task(
        "coop-random",
        "Cooperative, random goal, hydro ±30 %",
        COOP_ID,
        {"goal": "random", "hydro_randomization": HYDRO_RANDOMIZATION},
        paper=False,
        check=False,
        grasp="friction",
    ),
    Task(
        "coop-obstacles",
        "Cooperative, moving obstacles, current",
        COOP_OBSTACLES_ID,
        {"obstacles": "random", "current": "random"},
        paper=False,
        check=False,
        max_draws=COOP_OBSTACLE_DRAWS,
        grasp="friction",
    ),
)
"""The cooperative group: the transports with the object held by friction (``grasp="friction"``,
:mod:`uvdms_gym.envs.cooperative`): the paper's goal (deterministic, one draw), random goals with hydrodynamic
randomisation, and moving obstacles in a current (:data:`COOP_OBSTACLE_DRAWS` draws)."""

TASKS = TASKS + _realism_tasks(TASKS) + COOP_TASKS
"""The task suite: the paper's three tasks, then the held-out randomised variants and the obstacle task (the paper's
stated future work: moving outer obstacles in a current), then the realism track (:data:`REALISM_LEVELS`), then the
cooperative group (:data:`COOP_TASKS`)."""


def friction_tasks(tasks: Sequence[Task]) -> tuple[Task, ...]:
    """The tasks of ``tasks`` whose environment holds the object by friction (``grasp == "friction"``)."""
    return tuple(t for t in tasks if t.grasp == "friction")


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
