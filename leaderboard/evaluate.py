"""``uvdms evaluate`` of any controller the leaderboard ranks: a baseline name, an agent, or a multi-seed entry.

:func:`evaluate_entry` resolves the controller (a shipped agent's name from any working directory, a former name
of a renamed shipped folder) and evaluates it with :func:`leaderboard.registry.evaluate`. A folder of training seeds
(``<entry>/seed_<k>/``, :func:`leaderboard.entries.multi_seed_entry`) is evaluated seed by seed on the same
evaluation seeds and aggregated as the leaderboard aggregates such an entry (:func:`leaderboard.stats.aggregate_runs`:
rates as the fraction of all seeds x episodes, every other metric as the interquartile mean, with the stratified
bootstrap interval). A path to one seed folder evaluates that seed alone.

The multi-seed result is ``{"episodes": [...], "summary": {...}, "meta": {...}}`` like a single controller's, where
``summary`` holds ``entry``, ``seeds`` (folder name -> training seed), ``aggregation`` (how), ``aggregate`` (metric
-> ``{"mean", "low", "high", "n"[, "estimator"]}``, the leaderboard's row) and ``per_seed`` (folder name -> that
seed's own summary); every episode carries its ``seed_folder`` and ``training_seed``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from leaderboard.cache import compact_result
from leaderboard.entries import is_multi_seed_folder, multi_seed_entry
from leaderboard.registry import CONTROLLERS, evaluate, resolve_controller
from leaderboard.stats import aggregate_runs
from uvdms_gym.utils.io import write_json_atomic

AGGREGATION = (
    "over training seeds x episodes: rates as the fraction, every other metric as the interquartile mean (IQM); "
    "95% stratified bootstrap intervals (the leaderboard's multi-seed rows)"
)
"""How a multi-seed summary's ``aggregate`` was computed."""


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

    The arguments are those of :func:`leaderboard.registry.evaluate` (``options``: ``save_trajectory``,
    ``progress``, ``trust``, ``safety_filter``).

    Raises:
        ValueError: As :func:`leaderboard.registry.evaluate`; for a multi-seed folder, as
            :func:`leaderboard.entries.multi_seed_entry` (a malformed folder of seeds).
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
