"""The controller registry: a controller name or an agent path -> a controller (the composition of layer 1).

[D] A dict in the composition layer, not entry points: the competitors are the project's own four baselines
and agent *paths* (any folder or zip), so there is nothing for a third-party package to register by name, and
a dict is greppable and needs no installed metadata (a source checkout on ``PYTHONPATH`` works). A new named
controller is one line in :data:`CONTROLLERS`.

* a name of :data:`CONTROLLERS` (the baselines of :data:`baselines.controllers.BASELINES`) ->
  :func:`baselines.controllers.make_baseline`;
* an existing path -> :func:`agents.export.load_agent` (a weights-only export, a run directory or an SB3 zip),
  checked against the environment with :func:`agents.export.check_agent`, then composed as it was trained
  (:func:`compose_agent`): a residual agent (:mod:`uvdms_gym.residual`) gets its base baseline from the record
  of its export or run (:class:`uvdms_gym.residual.ResidualController`), and an agent trained with the safety
  filter is filtered.

``uvdms evaluate`` (:func:`leaderboard.running.evaluate.evaluate`, which evaluates what this module resolves) and
the leaderboard (:mod:`leaderboard.running.jobs`) resolve through here.
Training gets the same pieces injected (``agents`` does not import ``baselines``): :func:`action_components`
returns the picklable factories :class:`BaselineFactory`, :class:`SafetyFilterFactory` and :class:`TeacherFactory`
that ``uvdms train`` passes to :func:`agents.training.train.train`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from baselines.controllers import BASELINES, make_baseline
from baselines.mpc.config import MPCConfig
from uvdms_gym.physics.params import D1, D2
from uvdms_gym.residual import ResidualController

if TYPE_CHECKING:
    from agents.common.envs import ActionComponents

CONTROLLERS: dict[str, Callable[..., Any]] = {name: make_baseline for name in BASELINES}
"""Named controllers: name -> factory ``(name, env, **kwargs) -> controller``."""
TRACK_OF: dict[str, str] = {name: spec["action_mode"] for name, spec in BASELINES.items()}
"""The action mode (leaderboard track) each named controller needs."""
BASELINE_ENV: dict[str, str | None] = {name: spec.get("env_id") for name, spec in BASELINES.items()}
"""The environment a named baseline's leaderboard entry runs on (``None``: every task)."""
GRASP_KEY = "grasp"
"""The key of a :data:`baselines.controllers.BASELINES` spec that restricts a baseline to the tasks of one grasp:
``{"grasp": "friction", ...}`` (``campc-coop``) runs only on the friction-grasp tasks (``Task.grasp``,
:data:`leaderboard.suite.tasks.COOP_TASKS`), is left out of the ``baselines`` token and stands in the ``coop`` token
instead (:data:`GRASP_ONLY`). Without the key a baseline runs on every task of its track (on a friction-grasp
environment with a constant grip, which :func:`baselines.controllers.make_baseline` appends)."""
GRASP_OF: dict[str, str | None] = {name: spec.get(GRASP_KEY) for name, spec in BASELINES.items()}
"""The grasp each named baseline is restricted to (``None``: every task)."""
GRASP_ONLY: frozenset[str] = frozenset(name for name, grasp in GRASP_OF.items() if grasp is not None)
"""Baselines restricted to one grasp (:data:`GRASP_KEY`): the leaderboard's ``coop`` token."""
DEFAULT_BASELINES: tuple[str, ...] = tuple(
    name
    for name, spec in BASELINES.items()
    if spec.get("env_id") is None and spec.get("default", True) and name not in GRASP_ONLY
)
"""The baselines the leaderboard's ``baselines`` token stands for: those of every task but ``hold`` (named)."""
REALISM_ONLY: frozenset[str] = frozenset(name for name, spec in BASELINES.items() if spec.get("realism_only"))
"""Baselines of the realism track only (``campc-raw``, ``campc-privileged``: at ``realism=0`` they are ``campc``)."""
PRIVILEGED: frozenset[str] = frozenset(name for name, spec in BASELINES.items() if spec.get("state") == "truth")
"""Baselines that read the true state at ``realism > 0``: reference rows, marked as such, not competitors."""
WEIGHTS_ONLY_RECORD = "agent.json"
"""The record that makes a folder a weights-only export (``agents.export``)."""
AGENT_FILES: tuple[str, ...] = (WEIGHTS_ONLY_RECORD, "model.zip", "final_model.zip", "best_model.zip")
"""Files that make a folder an agent: a weights-only export, a shipped agent, or a run directory."""


def required_action_mode(spec: str) -> str | None:
    """The action mode a named controller needs (``None`` for an agent path: the agent's own env kwargs decide)."""
    return TRACK_OF.get(spec)


def not_an_agent_folder(path: str | Path) -> ValueError:
    """The error of a folder that holds no agent (one wording for ``uvdms evaluate`` and ``uvdms leaderboard``)."""
    return ValueError(
        f"{path} is not an agent folder: it holds none of {', '.join(AGENT_FILES)} (a weights-only export, "
        "a shipped agent or a run directory)"
    )


def unknown_controller(spec: str, keywords: tuple[str, ...] = ()) -> ValueError:
    """The error of a name that is no baseline and a path that does not exist (``keywords``: other names taken)."""
    also = f", {', '.join(map(repr, keywords))}" if keywords else ""
    return ValueError(
        f"{spec!r} is neither a baseline ({', '.join(CONTROLLERS)}){also} nor an existing agent folder or checkpoint"
    )


def load_agent(path: str | Path, trust: bool = False) -> Any:
    """:func:`agents.export.load_agent` with the errors of a wrong path or a corrupt archive named.

    Raises:
        ValueError: A folder holding none of :data:`AGENT_FILES`, or a model that is not a valid zip archive.
    """
    import zipfile

    from agents.export import load_agent as _load

    path = Path(path)
    if path.is_dir() and not any((path / name).is_file() for name in AGENT_FILES):
        raise not_an_agent_folder(path)
    try:
        return _load(path, trust=trust)
    except zipfile.BadZipFile as exc:
        raise ValueError(f"{path}: a model file is not a valid zip archive, corrupt or truncated ({exc})") from None


RESIDUAL_BASES: tuple[str, ...] = tuple(
    name for name in DEFAULT_BASELINES if TRACK_OF[name] == "velocity" and name not in REALISM_ONLY
)
"""The baselines a residual agent can be trained on: those whose action is a velocity command."""


@dataclass(frozen=True)
class BaselineFactory:
    """A picklable ``(env) -> controller`` for a residual agent's base: the named velocity-mode baseline.

    Module-level and plain data, so it travels to ``SubprocVecEnv`` / hybrid workers by reference.

    Attributes:
        name: One of :data:`RESIDUAL_BASES`.
        collision_margin: Metres added to both thresholds ``d1`` and ``d2`` of the baseline's collision rows (0:
            the baseline as registered). A teacher for imitation (``agents.algos.dagger``'s ``teacher_margin``) keeps
            this
            much farther from every obstacle than the benchmark's ``d1``, so that a learner that imitates it to
            within the margin stays out of the collision zone. Only for a baseline with collision rows.

    Raises:
        ValueError: An unknown name, or a torque-mode baseline (the message lists the valid names); a negative or
            non-finite margin, or a margin on a baseline without collision rows.
    """

    name: str
    collision_margin: float = 0.0

    def __post_init__(self) -> None:
        _check_collision_margin(self.collision_margin, self.name)
        if self.name not in TRACK_OF:
            raise ValueError(
                f"unknown residual base {self.name!r}: a residual agent's base is a velocity-mode baseline, one of "
                f"{', '.join(RESIDUAL_BASES)}"
            )
        if self.name not in RESIDUAL_BASES:
            raise ValueError(
                f"residual base {self.name!r} is a {TRACK_OF[self.name]}-mode baseline, but a residual is added to "
                f"a velocity command: choose one of {', '.join(RESIDUAL_BASES)}"
            )

    def __call__(self, env: Any) -> Any:
        """The baseline for ``env`` (:func:`baselines.controllers.make_baseline`), thresholds moved by the margin."""
        return _baseline_with_margin(self.name, env, self.collision_margin)


def _check_collision_margin(margin: Any, name: str) -> None:
    """A margin is a finite number >= 0, and nonzero only for a baseline with collision rows."""
    if isinstance(margin, bool) or not isinstance(margin, int | float) or not math.isfinite(margin) or margin < 0:
        raise ValueError(f"collision_margin must be a finite number >= 0 (metres), got {margin!r}")
    if margin and not BASELINES.get(name, {}).get("collision", False):
        raise ValueError(f"collision_margin={margin} widens collision rows, but {name!r} has none (use campc)")


def _baseline_with_margin(name: str, env: Any, margin: float, outer_margin: float = 0.0) -> Any:
    """The baseline ``name`` for ``env`` with both collision thresholds ``d1``, ``d2`` moved out by ``margin``.

    With ``outer_margin`` also the outer-obstacle rows' ``outer_d1`` and ``outer_d2`` (their defaults of
    :class:`baselines.mpc.config.MPCConfig`), in an environment with obstacles.
    """
    overrides = {"d1": D1 + margin, "d2": D2 + margin} if margin else {}
    if outer_margin and hasattr(env.unwrapped, "obstacles"):
        defaults = MPCConfig()
        overrides |= {"outer_d1": defaults.outer_d1 + outer_margin, "outer_d2": defaults.outer_d2 + outer_margin}
    return make_baseline(name, env, mpc_overrides=overrides) if overrides else make_baseline(name, env)


@dataclass(frozen=True)
class TeacherFactory:
    """A picklable ``(env) -> controller`` for an imitation learner's teacher (``agents.algos.dagger``).

    Unlike a residual base, a teacher may command either action mode (the learner imitates it in that mode) and may
    be a trained agent: a path to a weights-only export (e.g. a shipped residual entry's ``seed_0``), composed as
    it was trained (:func:`compose_agent`).

    Attributes:
        name: A baseline of :data:`CONTROLLERS` or the path of a weights-only agent export (shipped names resolve
            as in :func:`resolve_controller`).
        collision_margin: Metres added to both collision thresholds of a baseline with collision rows
            (:class:`BaselineFactory`); 0 for an agent.
        outer_margin: Metres added to both thresholds of the outer-obstacle rows (``outer_d1``, ``outer_d2``) of a
            baseline with collision rows, in an environment with obstacles: a teacher that evades earlier and
            wider, whose evasions a learner imitates with room to spare; 0 for an agent.

    Raises:
        ValueError: An unknown name that is no weights-only export, a negative or non-finite margin, or a margin
            on a teacher without collision rows.
    """

    name: str
    collision_margin: float = 0.0
    outer_margin: float = 0.0

    def __post_init__(self) -> None:
        _check_collision_margin(self.collision_margin, self.name)
        _check_collision_margin(self.outer_margin, self.name)
        if self.name in CONTROLLERS:
            return
        path = Path(resolve_controller(self.name))
        if not (path / WEIGHTS_ONLY_RECORD).is_file():
            raise ValueError(
                f"unknown teacher {self.name!r}: name a baseline ({', '.join(CONTROLLERS)}) or the folder of a "
                "weights-only agent export (holding agent.json)"
            )

    @property
    def action_mode(self) -> str:
        """The action mode the teacher commands (a baseline's registered one, an agent's training env's)."""
        if self.name in TRACK_OF:
            return TRACK_OF[self.name]
        from leaderboard.suite.agent_files import agent_env

        _env_id, kwargs = agent_env(resolve_controller(self.name))
        return str(kwargs.get("action_mode", "velocity"))

    def __call__(self, env: Any) -> Any:
        """The teacher for ``env``: the baseline (thresholds moved by the margin) or the composed agent."""
        if self.name in CONTROLLERS:
            return _baseline_with_margin(self.name, env, self.collision_margin, self.outer_margin)
        return make_controller(self.name, env)


@dataclass(frozen=True)
class SafetyFilterFactory:
    """A picklable ``(controller, env) -> controller`` that wraps the controller in the safety filter."""

    def __call__(self, controller: Any, env: Any) -> Any:
        """``controller`` filtered (:func:`with_safety_filter`)."""
        return with_safety_filter(controller, env)


def action_components() -> ActionComponents:
    """What ``uvdms train`` injects into :func:`agents.training.train.train`: the residual bases and the filter."""
    from agents.common.envs import ActionComponents

    return ActionComponents(
        base_factory=BaselineFactory, filter_factory=SafetyFilterFactory(), teacher_factory=TeacherFactory
    )


def with_safety_filter(controller: Any, env: Any) -> Any:
    """``controller`` with its velocity commands projected onto the collision rows (:mod:`baselines.safety.filter`).

    A controller that already is a :class:`~baselines.safety.filter.SafetyFilter` (an agent trained with the filter,
    composed by :func:`compose_agent`) is returned as it is: the filter is applied once.
    """
    from baselines.safety.filter import SafetyFilter

    if isinstance(controller, SafetyFilter):
        return controller
    return SafetyFilter(controller, env)


def compose_agent(agent: Any, env: Any, *, safety_filter: bool = False) -> Any:
    """An agent as it was trained: its residual base, safety filter and navigation filter, as recorded.

    An agent that observes the obstacle or tracking features gets them computed from its observation
    (``FeatureController``, innermost; the tracking features inside, as the training wrappers nest them). The
    residual base is added, then the safety filter if the agent was trained with one; an agent that observed the
    navigation filter's estimate gets it as its input (``FilteredController``, outermost: the base and the safety
    filter see the estimate too, as in training).

    Args:
        agent: A loaded agent (:class:`agents.export.AgentController`; its ``composition`` says what to add).
        env: The environment the controller will drive.
        safety_filter: Filter the result also if the agent was trained without the filter.

    Returns:
        The agent itself when there is nothing to compose, else a
        :class:`uvdms_gym.residual.ResidualController` and/or a :class:`baselines.safety.filter.SafetyFilter`,
        in a :class:`uvdms_gym.realism.navigation.FilteredController` for an agent that observed the filter.

    Raises:
        ValueError: The recorded base is not a velocity-mode baseline, or an action-mode mismatch.
    """
    from uvdms_gym.residual import (
        ActionComposition,
        FeatureController,
        ObstacleFeatures,
        TrackingFeatures,
        residual_features,
        residual_projection,
    )

    composition = getattr(agent, "composition", None) or ActionComposition()
    controller = agent
    if composition.tracking_features:
        controller = FeatureController(controller, TrackingFeatures.for_env(env))
    if composition.obstacle_features:
        controller = FeatureController(controller, ObstacleFeatures.for_env(env))
    if composition.is_residual:
        base = BaselineFactory(str(composition.residual_base))(env)
        controller = ResidualController(
            base,
            agent,
            float(composition.residual_scale),
            residual_features(composition, env),  # type: ignore[arg-type]
            residual_projection(composition, env),
        )
    if composition.safety_filter or safety_filter:
        controller = with_safety_filter(controller, env)
    if composition.navigation_filter:
        from uvdms_gym.realism.navigation import FilteredController

        controller = FilteredController(controller, env)
    return controller


def resolve_controller(spec: str) -> str:
    """``spec`` as given if it is a baseline name or an existing path; else the shipped agent it names.

    Shipped names resolve from any working directory, former names of renamed shipped folders included
    (:func:`agents.common.paths.resolve_shipped`).
    """
    if spec in CONTROLLERS:
        return spec
    from agents.common.paths import resolve_shipped

    resolved = resolve_shipped(spec)
    return spec if resolved == Path(spec) else str(resolved)


def make_controller(spec: str, env: Any, *, trust: bool = False, **kwargs: Any) -> Any:
    """A controller from a name of :data:`CONTROLLERS` or a path to a trained agent.

    Args:
        spec: A controller name, or a path: a weights-only export directory, a run directory or an SB3 zip.
        env: The environment the controller will drive.
        trust: Allow unpickling an agent's SB3/VecNormalize files (see :mod:`agents.export`).
        **kwargs: Options of a named controller (``mpc_overrides``, ``di_overrides``).

    Returns:
        The controller (:class:`uvdms_gym.evaluation.Controller`).

    Raises:
        ValueError: Unknown name / missing path, or an action-mode or observation/action-space mismatch.
    """
    if spec in CONTROLLERS:
        return CONTROLLERS[spec](spec, env, **kwargs)
    path = Path(resolve_controller(spec))
    if not path.exists():
        raise unknown_controller(spec)
    from agents.export import check_agent

    agent = load_agent(path, trust=trust)
    check_agent(agent, env, spec)
    return compose_agent(agent, env)
