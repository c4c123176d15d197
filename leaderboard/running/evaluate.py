"""``uvdms evaluate``: one controller the leaderboard ranks over seeded episodes (a baseline, an agent, an entry).

:func:`evaluate` evaluates a named baseline or an agent path, resolved and composed by
:mod:`leaderboard.suite.registry`, through :func:`uvdms_gym.evaluation.evaluate_controller`.
:func:`evaluate_entry` resolves the controller (a shipped agent's name from any working directory, a former name
of a renamed shipped folder) and evaluates it with :func:`evaluate`. A folder of training seeds
(``<entry>/seed_<k>/``, :func:`leaderboard.suite.entries.multi_seed_entry`) is evaluated seed by seed on the same
evaluation seeds and aggregated as the leaderboard aggregates such an entry
(:func:`leaderboard.stats.metrics.aggregate_runs`: rates as the fraction of all seeds x episodes, every other metric
as the interquartile mean, with the stratified bootstrap interval). A path to one seed folder evaluates that seed
alone.

The multi-seed result is ``{"episodes": [...], "summary": {...}, "meta": {...}}`` like a single controller's, where
``summary`` holds ``entry``, ``seeds`` (folder name -> training seed), ``aggregation`` (how), ``aggregate`` (metric
-> ``{"mean", "low", "high", "n"[, "estimator"]}``, the leaderboard's row) and ``per_seed`` (folder name -> that
seed's own summary); every episode carries its ``seed_folder`` and ``training_seed``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from leaderboard.running.cache import compact_result
from leaderboard.stats.metrics import aggregate_runs
from leaderboard.suite.entries import is_multi_seed_folder, multi_seed_entry
from leaderboard.suite.registry import (
    CONTROLLERS,
    TRACK_OF,
    compose_agent,
    load_agent,
    make_controller,
    resolve_controller,
    unknown_controller,
    with_safety_filter,
)
from uvdms_gym.utils.io import write_json_atomic

AGGREGATION = (
    "over training seeds x episodes: rates as the fraction, every other metric as the interquartile mean (IQM); "
    "95% stratified bootstrap intervals (the leaderboard's multi-seed rows)"
)
"""How a multi-seed summary's ``aggregate`` was computed."""


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
        safety_filter: Project every velocity command onto the collision rows (:func:`with_safety_filter`); an
            agent trained with the filter is filtered anyway (once), a residual agent gets its base composed
            (:func:`compose_agent`).

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
        if safety_filter and TRACK_OF[controller_spec] != "velocity":
            raise ValueError(
                f"--safety-filter filters velocity commands, but {controller_spec} is a {TRACK_OF[controller_spec]}-"
                "track controller (it commands forces and torques); evaluate it without the filter, or filter a "
                f"velocity controller ({', '.join(n for n, track in TRACK_OF.items() if track == 'velocity')})"
            )
        kwargs.setdefault("action_mode", TRACK_OF[controller_spec])

        def factory(env: Any) -> Any:
            controller = make_controller(controller_spec, env, trust=trust)
            return with_safety_filter(controller, env) if safety_filter else controller

    else:
        path = Path(resolve_controller(controller_spec))
        if not path.exists():
            raise unknown_controller(controller_spec)
        from agents.export import check_agent

        agent = load_agent(path, trust)
        kwargs.setdefault("action_mode", (agent.env_kwargs or {}).get("action_mode", "velocity"))
        if safety_filter and kwargs["action_mode"] != "velocity":
            raise ValueError(
                f"--safety-filter filters velocity commands, but {controller_spec} acts in action_mode="
                f"{kwargs['action_mode']!r}; evaluate it without the filter"
            )

        def factory(env: Any) -> Any:
            return compose_agent(agent, env, safety_filter=safety_filter)

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


def evaluate_entry(
    controller_spec: str,
    env_id: str,
    env_kwargs: dict | None = None,
    episodes: int = 5,
    seed: int = 0,
    *,
    out: str | None = None,
    **options: Any,
) -> dict[str, Any]:
    """Evaluate a baseline, an agent or a multi-seed entry folder over seeded episodes (module docstring).

    The arguments are those of :func:`evaluate` (``options``: ``save_trajectory``,
    ``progress``, ``trust``, ``safety_filter``).

    Raises:
        ValueError: As :func:`evaluate`; for a multi-seed folder, as
            :func:`leaderboard.suite.entries.multi_seed_entry` (a malformed folder of seeds).
    """
    spec = resolve_controller(controller_spec)
    if spec in CONTROLLERS or not is_multi_seed_folder(spec):
        return evaluate(spec, env_id, env_kwargs, episodes, seed, out=out, **options)
    entry = multi_seed_entry(spec, trust=bool(options.get("trust", False)))
    per_seed = {
        Path(member.spec).name: (member, evaluate(member.spec, env_id, env_kwargs, episodes, seed, **options))
        for member in entry.members
    }
    runs = [[compact_result(ep) for ep in result["episodes"]] for _, result in per_seed.values()]
    stats = aggregate_runs(runs)
    result = {
        "episodes": [
            {**ep, "seed_folder": name, "training_seed": member.training_seed}
            for name, (member, one) in per_seed.items()
            for ep in one["episodes"]
        ],
        "summary": {
            "entry": spec,
            "seeds": {name: member.training_seed for name, (member, _) in per_seed.items()},
            "aggregation": AGGREGATION,
            "aggregate": {metric: stat.to_json() for metric, stat in stats.items()},
            "per_seed": {name: one["summary"] for name, (_, one) in per_seed.items()},
        },
        "meta": next(iter(per_seed.values()))[1]["meta"],
    }
    if out is not None:
        write_json_atomic(out, result)
    return result
