"""``uvdms evaluate``: one controller the leaderboard ranks over seeded episodes (a baseline, an agent, an entry).

:func:`evaluate` evaluates a named baseline or an agent path, resolved and composed by
:mod:`leaderboard.suite.registry`, through :func:`uvdms_gym.evaluation.evaluate_controller`.
:func:`evaluate_entry` resolves the controller (a shipped agent's name from any working directory, a former name
of a renamed shipped folder) and evaluates it with :func:`evaluate`. The episodes' seeds are given as a list of
draws (``uvdms evaluate`` passes those of a split, :func:`uvdms_gym.seeds.split_seeds`) or as a first seed.

A folder of training seeds (``<entry>/seed_<k>/``, :func:`leaderboard.suite.entries.multi_seed_entry`) is
evaluated seed by seed. By default the draws are spread over the training seeds as the leaderboard spreads them on
its randomised tasks (:func:`uvdms_gym.seeds.assign_draws`: draw ``i`` is evaluated once, by the ``i % n``-th
seed folder), so that ``N`` draws cost ``N`` episodes; with ``every_seed`` every training seed evaluates every draw.
Either way the row is aggregated as the leaderboard aggregates it (:func:`leaderboard.stats.metrics.aggregate_runs`:
rates as the fraction, every other metric as the interquartile mean, with a hierarchical bootstrap interval that
resamples the draws, then the training seeds within each draw).
A path to one seed folder evaluates that seed alone, on every draw.

The multi-seed result is ``{"episodes": [...], "summary": {...}, "meta": {...}}`` like a single controller's, where
``summary`` holds ``entry``, ``seeds`` (folder name -> training seed), ``aggregation`` (how), ``aggregate`` (metric
-> ``{"mean", "low", "high", "n"[, "estimator"]}``, the entry's row) and ``per_seed`` (folder name -> that seed's
own summary); every episode carries its ``seed_folder`` and ``training_seed``. ``meta`` is the first seed's, with
``episodes``, ``seeds`` and ``seed_protocol`` of all the draws and ``draw_assignment`` (``rule``: ``"spread"`` or
``"every_seed"``, ``description``, and ``by_seed_folder``: folder name -> the draws it evaluated).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
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
from uvdms_gym.evaluation import seed_protocol
from uvdms_gym.seeds import assign_draws
from uvdms_gym.utils.io import write_json_atomic

AGGREGATION = (
    "over the episodes of all training seeds: rates as the fraction, every other metric as the interquartile mean "
    "(IQM); 95% hierarchical bootstrap intervals (draws, then training seeds within each draw; the leaderboard's "
    "multi-seed rows)"
)
"""How a multi-seed summary's ``aggregate`` was computed."""
DRAW_RULES = {
    "spread": "draw i is evaluated once, by the (i % n)-th of the n seed folders (uvdms_gym.seeds.assign_draws)",
    "every_seed": "every seed folder evaluates every draw",
}
"""How a multi-seed evaluation gives the draws to the training seeds (``meta["draw_assignment"]["rule"]``)."""
Factory = Callable[[Any], Any]
"""Builds the controller for one episode's environment."""
Check = Callable[[Any, Any], None]
"""Checks a built controller against its environment (an agent's observation and action spaces)."""


def evaluate(
    controller_spec: str,
    env_id: str,
    env_kwargs: dict | None = None,
    episodes: int = 5,
    seed: int = 0,
    *,
    seeds: Sequence[int] | None = None,
    out: str | None = None,
    save_trajectory: bool = False,
    progress: bool = True,
    trust: bool = False,
    safety_filter: bool = False,
) -> dict:
    """Evaluate a named controller or an agent over ``episodes`` seeded episodes (``seed, seed + 1, ...`` or ``seeds``).

    A named controller's required ``action_mode`` is filled into ``env_kwargs`` when not given (an explicit,
    different one raises ``ValueError``); an agent's environment gets the ``action_mode`` the agent was trained
    with unless given. The episodes run through :func:`uvdms_gym.evaluation.evaluate_controller`.

    Args:
        controller_spec: A baseline name (``mpc``, ``campc``, ``campc-di``, ``campc-nndi``) or a path to an agent.
        env_id: Gymnasium id, e.g. ``"uvdms/CircleTrack-v0"``.
        env_kwargs: ``gymnasium.make`` keyword arguments.
        episodes: Number of episodes (>= 1).
        seed: Seed of the first episode (not used when ``seeds`` is given).
        seeds: The episodes' seeds (e.g. draws of a split); ``len(seeds)`` must equal ``episodes``.
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
    if controller_spec in CONTROLLERS:
        factory, check = _baseline_parts(controller_spec, kwargs, trust, safety_filter)
    else:
        factory, check = _agent_parts(controller_spec, kwargs, trust, safety_filter)
    return evaluate_controller(
        factory,
        env_id,
        kwargs,
        episodes,
        seed,
        seeds=seeds,
        label=controller_spec,
        out=out,
        save_trajectory=save_trajectory,
        progress=progress,
        check=check,
    )


def _baseline_parts(name: str, kwargs: dict, trust: bool, safety_filter: bool) -> tuple[Factory, Check | None]:
    """The factory of a named baseline; fills its ``action_mode`` into ``kwargs`` (:func:`evaluate`)."""
    if safety_filter and TRACK_OF[name] != "velocity":
        raise ValueError(
            f"--safety-filter filters velocity commands, but {name} is a {TRACK_OF[name]}-"
            "track controller (it commands forces and torques); evaluate it without the filter, or filter a "
            f"velocity controller ({', '.join(n for n, track in TRACK_OF.items() if track == 'velocity')})"
        )
    kwargs.setdefault("action_mode", TRACK_OF[name])

    def factory(env: Any) -> Any:
        controller = make_controller(name, env, trust=trust)
        return with_safety_filter(controller, env) if safety_filter else controller

    return factory, None


def _agent_parts(controller_spec: str, kwargs: dict, trust: bool, safety_filter: bool) -> tuple[Factory, Check]:
    """The factory and the space check of an agent; fills its training ``action_mode`` into ``kwargs``."""
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

    return factory, check


def evaluate_entry(
    controller_spec: str,
    env_id: str,
    env_kwargs: dict | None = None,
    episodes: int = 5,
    seed: int = 0,
    *,
    seeds: Sequence[int] | None = None,
    every_seed: bool = False,
    out: str | None = None,
    **options: Any,
) -> dict[str, Any]:
    """Evaluate a baseline, an agent or a multi-seed entry folder over seeded episodes (module docstring).

    The arguments are those of :func:`evaluate` (``options``: ``save_trajectory``, ``progress``, ``trust``,
    ``safety_filter``); the draws are ``seeds`` if given, else ``seed, ..., seed + episodes - 1``. A multi-seed
    folder spreads them over its training seeds (:func:`draw_shares`) unless ``every_seed``.

    Raises:
        ValueError: As :func:`evaluate`; ``every_seed`` for a controller that is not a folder of training seeds;
            for a multi-seed folder, fewer draws than training seeds to spread them over, or as
            :func:`leaderboard.suite.entries.multi_seed_entry` (a malformed folder of seeds).
    """
    draws = [int(seed) + i for i in range(episodes)] if seeds is None else [int(s) for s in seeds]
    spec = resolve_controller(controller_spec)
    if spec in CONTROLLERS or not is_multi_seed_folder(spec):
        if every_seed:
            raise ValueError(
                f"--every-seed applies to a folder of training seeds (seed_<k>/ sub-folders); {controller_spec} is "
                "one controller, which evaluates every draw anyway"
            )
        return evaluate(spec, env_id, env_kwargs, len(draws), seeds=draws, out=out, **options)
    entry = multi_seed_entry(spec, trust=bool(options.get("trust", False)))
    members = {Path(member.spec).name: member for member in entry.members}
    shares = draw_shares(list(members), draws, every_seed)
    per_seed = {
        name: (member, evaluate(member.spec, env_id, env_kwargs, len(shares[name]), seeds=shares[name], **options))
        for name, member in members.items()
    }
    runs = [[compact_result(ep) for ep in result["episodes"]] for _, result in per_seed.values()]
    stats = aggregate_runs(runs)
    rule = "every_seed" if every_seed else "spread"
    result = {
        "episodes": [
            {**ep, "seed_folder": name, "training_seed": member.training_seed}
            for name, (member, one) in per_seed.items()
            for ep in one["episodes"]
        ],
        "summary": {
            "entry": spec,
            "seeds": {name: member.training_seed for name, member in members.items()},
            "aggregation": AGGREGATION,
            "aggregate": {metric: stat.to_json() for metric, stat in stats.items()},
            "per_seed": {name: one["summary"] for name, (_, one) in per_seed.items()},
        },
        "meta": {
            **next(iter(per_seed.values()))[1]["meta"],
            "episodes": len(draws),
            "seeds": draws,
            "seed_protocol": seed_protocol(draws),
            "draw_assignment": {"rule": rule, "description": DRAW_RULES[rule], "by_seed_folder": shares},
        },
    }
    if out is not None:
        write_json_atomic(out, result)
    return result


def draw_shares(folders: Sequence[str], draws: Sequence[int], every_seed: bool = False) -> dict[str, list[int]]:
    """The draws each seed folder of a multi-seed entry evaluates: all of them (``every_seed``) or its share.

    The share of the ``k``-th of ``n`` folders is ``draws[i]`` for ``i % n == k``
    (:func:`uvdms_gym.seeds.assign_draws`).

    Raises:
        ValueError: Fewer draws than folders to spread them over (a folder would evaluate nothing).
    """
    if every_seed:
        return {name: list(draws) for name in folders}
    if len(draws) < len(folders):
        raise ValueError(
            f"{len(draws)} episode(s) cannot be spread over {len(folders)} training seeds (draw i goes to seed "
            f"folder i % {len(folders)}): give --episodes {len(folders)} or more, or --every-seed"
        )
    return {name: assign_draws(draws, len(folders), k) for k, name in enumerate(folders)}
