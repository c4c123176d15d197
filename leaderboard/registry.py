"""The controller registry: a controller name or an agent path -> a controller (the composition of layer 1).

[D] A dict in the composition layer, not entry points: the competitors are the project's own four baselines
and agent *paths* (any folder or zip), so there is nothing for a third-party package to register by name, and
a dict is greppable and needs no installed metadata (a source checkout on ``PYTHONPATH`` works). A new named
controller is one line in :data:`CONTROLLERS`.

* a name of :data:`CONTROLLERS` (the baselines of :data:`baselines.controllers.BASELINES`) ->
  :func:`baselines.controllers.make_baseline`;
* an existing path -> :func:`agents.policy.load_agent` (a weights-only export, a run directory or an SB3 zip),
  checked against the environment with :func:`agents.policy.check_agent`.

``uvdms evaluate`` (:func:`evaluate`) and the leaderboard (:mod:`leaderboard.runner`) resolve through here.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from baselines.controllers import BASELINES, make_baseline

CONTROLLERS: dict[str, Callable[..., Any]] = {name: make_baseline for name in BASELINES}
"""Named controllers: name -> factory ``(name, env, **kwargs) -> controller``."""
TRACK_OF: dict[str, str] = {name: spec["action_mode"] for name, spec in BASELINES.items()}
"""The action mode (leaderboard track) each named controller needs."""
AGENT_FILES: tuple[str, ...] = ("agent.json", "model.zip", "final_model.zip", "best_model.zip")
"""Files that make a folder an agent: a weights-only export, a shipped agent, or a run directory."""


def required_action_mode(spec: str) -> str | None:
    """The action mode a named controller needs (``None`` for an agent path: the agent's own env kwargs decide)."""
    return TRACK_OF.get(spec)


def load_agent(path: str | Path, trust: bool = False) -> Any:
    """:func:`agents.policy.load_agent` with the errors of a wrong path or a corrupt archive named.

    Raises:
        ValueError: A folder holding none of :data:`AGENT_FILES`, or a model that is not a valid zip archive.
    """
    import zipfile

    from agents.policy import load_agent as _load

    path = Path(path)
    if path.is_dir() and not any((path / name).is_file() for name in AGENT_FILES):
        raise ValueError(
            f"{path} is not an agent folder: it holds none of {', '.join(AGENT_FILES)} (a weights-only export, "
            "a shipped agent or a run directory)"
        )
    try:
        return _load(path, trust=trust)
    except zipfile.BadZipFile as exc:
        raise ValueError(f"{path}: a model file is not a valid zip archive, corrupt or truncated ({exc})") from None


def with_safety_filter(controller: Any, env: Any) -> Any:
    """``controller`` with its velocity commands projected onto the collision rows (:mod:`baselines.safety`)."""
    from baselines.safety import SafetyFilter

    return SafetyFilter(controller, env)


def make_controller(spec: str, env: Any, *, trust: bool = False, **kwargs: Any) -> Any:
    """A controller from a name of :data:`CONTROLLERS` or a path to a trained agent.

    Args:
        spec: A controller name, or a path: a weights-only export directory, a run directory or an SB3 zip.
        env: The environment the controller will drive.
        trust: Allow unpickling an agent's SB3/VecNormalize files (see :mod:`agents.policy`).
        **kwargs: Options of a named controller (``mpc_overrides``, ``di_overrides``).

    Returns:
        The controller (:class:`uvdms_gym.evaluation.Controller`).

    Raises:
        ValueError: Unknown name / missing path, or an action-mode or observation/action-space mismatch.
    """
    if spec in CONTROLLERS:
        return CONTROLLERS[spec](spec, env, **kwargs)
    path = Path(spec)
    if not path.exists():
        raise ValueError(f"{spec!r} is neither a baseline ({', '.join(CONTROLLERS)}) nor an existing agent path")
    from agents.policy import check_agent

    agent = load_agent(path, trust=trust)
    check_agent(agent, env, spec)
    return agent


def evaluate(
    controller_spec: str,
    env_id: str,
    env_kwargs: dict | None = None,
    episodes: int = 5,
    seed: int = 0,
    *,
    out: str | None = None,
    save_trajectory: bool = False,
    progress: bool = True,
    trust: bool = False,
    safety_filter: bool = False,
) -> dict:
    """Evaluate a named controller or an agent over ``episodes`` seeded episodes (seeds ``seed, seed + 1, ...``).

    A named controller's required ``action_mode`` is filled into ``env_kwargs`` when not given (an explicit,
    different one raises ``ValueError``); an agent's environment gets the ``action_mode`` the agent was trained
    with unless given. The episodes run through :func:`uvdms_gym.evaluation.evaluate_controller`.

    Args:
        controller_spec: A baseline name (``mpc``, ``campc``, ``campc-di``, ``campc-nndi``) or a path to an agent.
        env_id: Gymnasium id, e.g. ``"uvdms/CircleTrack-v0"``.
        env_kwargs: ``gymnasium.make`` keyword arguments.
        episodes: Number of episodes (>= 1).
        seed: Seed of the first episode.
        out: JSON file to write (atomically); ``None`` writes nothing.
        save_trajectory: Keep each episode's time series.
        progress: Show a tqdm progress bar.
        trust: Allow unpickling an agent's SB3 files.
        safety_filter: Project every velocity command onto the collision rows (:func:`with_safety_filter`).

    Returns:
        ``{"episodes": [...], "summary": {...}, "meta": {...}}`` (:func:`uvdms_gym.evaluation.evaluate_controller`).

    Raises:
        ValueError: ``episodes < 1``, unknown controller, a folder that is not an agent, a corrupt agent
            archive, or an action-mode mismatch.
    """
    from uvdms_gym.evaluation import evaluate_controller

    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    kwargs = dict(env_kwargs or {})
    check = None
    if controller_spec in CONTROLLERS:
        kwargs.setdefault("action_mode", TRACK_OF[controller_spec])

        def factory(env: Any) -> Any:
            controller = make_controller(controller_spec, env, trust=trust)
            return with_safety_filter(controller, env) if safety_filter else controller

    else:
        path = Path(controller_spec)
        if not path.exists():
            raise ValueError(f"{controller_spec!r} is neither a baseline ({', '.join(CONTROLLERS)}) nor an agent path")
        from agents.policy import check_agent

        agent = load_agent(path, trust)
        kwargs.setdefault("action_mode", (agent.env_kwargs or {}).get("action_mode", "velocity"))

        def factory(env: Any) -> Any:
            return with_safety_filter(agent, env) if safety_filter else agent

        def check(controller: Any, env: Any) -> None:
            check_agent(agent, env, controller_spec)  # the agent itself, filtered or not

    return evaluate_controller(
        factory,
        env_id,
        kwargs,
        episodes,
        seed,
        label=controller_spec,
        out=out,
        save_trajectory=save_trajectory,
        progress=progress,
        check=check,
    )
