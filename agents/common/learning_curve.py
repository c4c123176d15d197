"""Learning curves: the benchmark's own metrics of the evaluation callback's episodes against environment steps.

During training, every evaluation of :class:`agents.training.callbacks.SeededEvalCallback` adds one **point** to
``learning_curve.json`` in the run directory: the step count, the training segment and, over the evaluation
episodes, the success rate, the contact-free rate, the contact-free success rate and the mean position RMSE,
each as defined in :mod:`uvdms_gym.evaluation` (computed by its :class:`~uvdms_gym.evaluation.EpisodeTracker`,
fed by the :class:`EpisodeMetrics` wrapper of the evaluation envs), plus the per-episode values and the
callback's mean (training) reward. File layout::

    {"format": "uvdms-learning-curve", "format_version": 1, "env_id": ..., "seed": ...,
     "points": [{"num_timesteps": N, "segment": k, "episodes": n, "success_rate": ..., "contact_free_rate": ...,
                 "contact_free_success_rate": ..., "rmse_pos_mean": ... (m, null if no episode has one),
                 "mean_reward": ..., "episode": {"success": [...], "contact_free": [...], "rmse_pos": [...]}}]}

[D] Through ``--resume`` the file is kept and continued: a resumed segment starts from a checkpoint, so the
points recorded after that checkpoint's step count (by an interrupted or failed continuation) are dropped before
the new segment adds its own; the points stay sorted by step count with one point per step count.
Environments without the uvdms tracking interface (``Pendulum-v1``) get no wrapper and write no curve.
:func:`agents.export.weights.export_controller` and :func:`scripts.ship_agent.package_run` copy the file into the
agent folder (:func:`copy_learning_curve`); the leaderboard plots it (:mod:`leaderboard.output.plots`). It is
written through :func:`uvdms_gym.utils.io.write_json_atomic`.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym

from uvdms_gym.utils.io import mirror_file, to_jsonable, write_json_atomic

log = logging.getLogger("agents.train")

LEARNING_CURVE_FILE = "learning_curve.json"
"""File name of the learning curve in a run directory and an agent folder."""
FORMAT_NAME = "uvdms-learning-curve"
FORMAT_VERSION = 1
INFO_KEY = "episode_metrics"
"""Key of the final step's ``info`` under which :class:`EpisodeMetrics` puts the episode's metrics."""
CURVE_METRICS: tuple[str, ...] = ("success_rate", "contact_free_rate", "contact_free_success_rate", "rmse_pos_mean")
"""The summary values of a point (rates in [0, 1]; ``rmse_pos_mean`` in m)."""


class LearningCurveError(ValueError):
    """A learning-curve file that cannot be read (not JSON, another format, malformed points)."""


def has_tracking_metrics(env: gym.Env) -> bool:
    """Whether ``env`` is a uvdms environment with the tracking interface the metrics need."""
    return hasattr(env.unwrapped, "tracking_transient")


class EpisodeMetrics(gym.Wrapper):
    """Adds the episode's benchmark metrics to the ``info`` of its last step (``info["episode_metrics"]``).

    The metrics are those of :class:`uvdms_gym.evaluation.EpisodeTracker` (the same as
    :func:`uvdms_gym.evaluation.run_episode` reports for the episode): ``rmse_pos`` (``None`` when no sample lies
    past the transient), ``success``, ``contacts``, ``contact_free``, ``contact_free_success``, ``steps``.
    Observations, rewards and flags pass unchanged. Applied to evaluation envs by
    :class:`agents.common.envs.EnvFactory` (``episode_metrics=True``) inside the ``Monitor``.

    Args:
        env: A uvdms environment (:func:`has_tracking_metrics`).
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        if not has_tracking_metrics(env):
            raise ValueError(f"{env.spec.id if env.spec else env}: not a uvdms environment (no tracking_transient)")
        self._tracker: Any = None

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset and start a new episode record."""
        from uvdms_gym.evaluation import EpisodeTracker

        obs, info = self.env.reset(**kwargs)
        self._tracker = EpisodeTracker(self.env, info)
        return obs, info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        """Step; on the episode's last step, ``info`` also holds the episode's metrics."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self._tracker is None:
            raise RuntimeError("EpisodeMetrics: step() before reset()")
        self._tracker.step(info, terminated)
        if terminated or truncated:
            info = {**info, INFO_KEY: episode_summary(self._tracker.outcome())}
            self._tracker = None
        return obs, reward, terminated, truncated, info


def episode_summary(outcome: Mapping[str, Any]) -> dict[str, Any]:
    """The learning-curve values of one episode from an :meth:`EpisodeTracker.outcome` (JSON-safe)."""
    contact_free = outcome["contacts"] == 0
    rmse = outcome["rmse_pos"]
    return {
        "rmse_pos": float(rmse) if rmse is not None and math.isfinite(rmse) else None,
        "success": bool(outcome["success"]),
        "contacts": int(outcome["contacts"]),
        "contact_free": bool(contact_free),
        "contact_free_success": bool(outcome["success"]) and bool(contact_free),
        "steps": int(outcome["steps"]),
    }


def curve_point(
    num_timesteps: int, segment: int, episodes: Sequence[Mapping[str, Any]], mean_reward: float | None
) -> dict[str, Any]:
    """One point of the curve from the :func:`episode_summary` of an evaluation's episodes.

    Raises:
        ValueError: No episodes.
    """
    if not episodes:
        raise ValueError("a learning-curve point needs at least one episode")
    n = len(episodes)
    rmse = [ep["rmse_pos"] for ep in episodes]
    finite = [r for r in rmse if r is not None]
    return to_jsonable(
        {
            "num_timesteps": int(num_timesteps),
            "segment": int(segment),
            "episodes": n,
            "success_rate": sum(bool(ep["success"]) for ep in episodes) / n,
            "contact_free_rate": sum(bool(ep["contact_free"]) for ep in episodes) / n,
            "contact_free_success_rate": sum(bool(ep["contact_free_success"]) for ep in episodes) / n,
            "rmse_pos_mean": sum(finite) / len(finite) if finite else None,
            "mean_reward": mean_reward,
            "episode": {
                "success": [bool(ep["success"]) for ep in episodes],
                "contact_free": [bool(ep["contact_free"]) for ep in episodes],
                "rmse_pos": rmse,
            },
        }
    )


class LearningCurve:
    """The learning curve of one run: its points, kept in ``path`` (see the module docstring).

    Args:
        path: The file (``<run dir>/learning_curve.json``).
        env_id: The run's environment id (recorded in the file).
        seed: The run's base seed (recorded in the file).
        points: The points so far.
    """

    def __init__(self, path: str | Path, env_id: str, seed: int, points: Sequence[Mapping[str, Any]] = ()) -> None:
        self.path = Path(path)
        self.env_id = env_id
        self.seed = int(seed)
        self.points: list[dict[str, Any]] = [dict(p) for p in points]

    @classmethod
    def resume(cls, path: str | Path, env_id: str, seed: int, start_timesteps: int) -> LearningCurve:
        """The curve of a segment that starts at ``start_timesteps``: the file's points up to that step count.

        A missing file starts an empty curve; points past ``start_timesteps`` (recorded after the checkpoint
        the segment resumes from) are dropped, with a log message.

        Raises:
            LearningCurveError: The file exists but cannot be read.
        """
        path = Path(path)
        if not path.is_file():
            return cls(path, env_id, seed)
        points = read_learning_curve(path)["points"]
        kept = [p for p in points if p["num_timesteps"] <= start_timesteps]
        if len(kept) < len(points):
            log.info(
                "%s: dropped %d point(s) recorded after step %d (the checkpoint this segment resumes from)",
                path,
                len(points) - len(kept),
                start_timesteps,
            )
        return cls(path, env_id, seed, kept)

    def add(self, point: Mapping[str, Any]) -> None:
        """Append ``point`` (replacing one at the same step count) and write the file."""
        steps = int(point["num_timesteps"])
        self.points = [p for p in self.points if p["num_timesteps"] != steps] + [dict(point)]
        self.points.sort(key=lambda p: p["num_timesteps"])
        self.save()

    def document(self) -> dict[str, Any]:
        """The file's content."""
        return {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "env_id": self.env_id,
            "seed": self.seed,
            "points": self.points,
        }

    def save(self) -> Path:
        """Write the file atomically (:func:`uvdms_gym.utils.io.write_json_atomic`)."""
        return write_json_atomic(self.path, to_jsonable(self.document()))


def read_learning_curve(path: str | Path) -> dict[str, Any]:
    """Read and check a learning-curve file.

    Returns:
        The document, its points sorted by ``num_timesteps``.

    Raises:
        LearningCurveError: Not JSON, not a learning curve of this format version, or malformed points.
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise LearningCurveError(f"{path}: cannot read the learning curve: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != FORMAT_NAME:
        raise LearningCurveError(f"{path}: not a {FORMAT_NAME} file")
    if doc.get("format_version") != FORMAT_VERSION:
        raise LearningCurveError(f"{path}: unsupported format_version {doc.get('format_version')!r}")
    points = doc.get("points")
    if not isinstance(points, list):
        raise LearningCurveError(f"{path}: 'points' is not a list")
    for i, point in enumerate(points):
        if not isinstance(point, dict) or not isinstance(point.get("num_timesteps"), int):
            raise LearningCurveError(f"{path}: point {i} has no integer num_timesteps")
        for key in CURVE_METRICS:
            value = point.get(key)
            if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)):
                raise LearningCurveError(f"{path}: point {i}: {key} is not a number")
    doc["points"] = sorted(points, key=lambda p: p["num_timesteps"])
    return doc


def find_learning_curve(agent_path: str | Path) -> Path | None:
    """The learning curve of an agent: in its folder (run directory, agent folder, export) or beside its zip."""
    path = Path(agent_path)
    if not path.exists():
        return None
    folder = path if path.is_dir() else path.parent
    candidate = folder / LEARNING_CURVE_FILE
    return candidate if candidate.is_file() else None


def copy_learning_curve(source: str | Path, out_dir: str | Path) -> Path | None:
    """Copy the learning curve of ``source`` (:func:`find_learning_curve`) into ``out_dir``; ``None`` if it has none.

    A stale curve in ``out_dir`` is removed when the source has none.
    """
    return mirror_file(find_learning_curve(source), Path(out_dir) / LEARNING_CURVE_FILE)
