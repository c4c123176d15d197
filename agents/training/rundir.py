"""Run directories of :mod:`agents.training.train`: naming, checkpoints found for ``--resume``, meta records, files.

Layout of ``<out>/<env id, '/' and ':' replaced by '_'>/<algo>_<seed>/`` (see :mod:`agents.training.train`)::

    config.yml, command.txt, meta.json, final_model.zip, vecnormalize.pkl, replay_buffer.pkl,
    best_model.zip, best_vecnormalize.pkl, best_model.json, learning_curve.json, checkpoints/, logs/seg<k>/,
    monitor/
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import logging
import re
import shutil
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml
from stable_baselines3.common.base_class import BaseAlgorithm

from agents.common.envs import EVAL_SEED_OFFSET, SEGMENT_SEED_STRIDE, TRAINING_SPLIT
from uvdms_gym.seeds import PROTOCOL
from uvdms_gym.utils.io import to_jsonable, write_json_atomic
from uvdms_gym.utils.provenance import git_info, package_versions

log = logging.getLogger("agents.train")

CHECKPOINT_PREFIX = "rl_model"
"""File-name prefix of the checkpoints (``checkpoints/rl_model_<N>_steps.zip``)."""


class RunDirError(ValueError):
    """The run directory exists (fresh run) or is not a valid run to resume."""


def run_dir_for(out_dir: str | Path, env_id: str, algo: str, seed: int) -> Path:
    """Run directory ``<out_dir>/<env id with '/' and ':' replaced by '_'>/<algo>_<seed>``."""
    return Path(out_dir) / re.sub(r"[/:\\]", "_", env_id) / f"{algo}_{seed}"


@dataclasses.dataclass(frozen=True)
class Checkpoint:
    """A saved model of a run with its companion files.

    Attributes:
        model: The SB3 zip.
        num_timesteps: Its step count (read from the zip's JSON data, nothing unpickled).
        vecnormalize: Its VecNormalize statistics, if any.
        replay_buffer: Its replay buffer, if saved.
    """

    model: Path
    num_timesteps: int
    vecnormalize: Path | None
    replay_buffer: Path | None


def zip_num_timesteps(path: str | Path) -> int:
    """``num_timesteps`` stored in an SB3 zip (read from its JSON ``data`` member, no unpickling)."""
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data").decode("utf-8"))
    return int(data["num_timesteps"])


def latest_checkpoint(run_dir: str | Path) -> Checkpoint | None:
    """The newest model of a run: ``final_model.zip`` or the checkpoint with the most steps.

    Ties go to ``final_model.zip``.
    """
    run_dir = Path(run_dir)
    candidates: list[Checkpoint] = []
    final = run_dir / "final_model.zip"
    if final.is_file():
        candidates.append(
            Checkpoint(
                final,
                zip_num_timesteps(final),
                _existing(run_dir / "vecnormalize.pkl"),
                _existing(run_dir / "replay_buffer.pkl"),
            )
        )
    pattern = re.compile(rf"^{CHECKPOINT_PREFIX}_(\d+)_steps\.zip$")
    for path in sorted((run_dir / "checkpoints").glob(f"{CHECKPOINT_PREFIX}_*_steps.zip")):
        match = pattern.match(path.name)
        if match:
            n = int(match.group(1))
            candidates.append(
                Checkpoint(
                    path,
                    n,
                    _existing(path.with_name(f"{CHECKPOINT_PREFIX}_vecnormalize_{n}_steps.pkl")),
                    _existing(path.with_name(f"{CHECKPOINT_PREFIX}_replay_buffer_{n}_steps.pkl")),
                )
            )
    if not candidates:
        return None
    # max() keeps the first of equal keys: final_model.zip comes first.
    return max(candidates, key=lambda c: c.num_timesteps)


def remove_if_no_model(run_dir: Path, quiet: bool = False) -> None:
    """Delete a fresh run's directory that holds no model, so that rerunning the same command works.

    A fresh run that fails (or is interrupted) before its first checkpoint or final model leaves only its
    config, meta record and partial logs, which would otherwise block the seed ("exists but holds no model").
    ``quiet`` logs the removal at debug level instead of as a warning.
    """
    if latest_checkpoint(run_dir) is not None:
        return
    shutil.rmtree(run_dir, ignore_errors=True)
    (log.debug if quiet else log.warning)(
        "removed %s: the run failed before saving a model; the same command can be rerun", run_dir
    )


def save_final(run_dir: Path, model: BaseAlgorithm, save_replay_buffer: bool) -> None:
    """Write ``final_model.zip`` and, if any, ``vecnormalize.pkl`` and ``replay_buffer.pkl``.

    Args:
        run_dir: The run directory.
        model: The model.
        save_replay_buffer: Also pickle the replay buffer (off-policy models only).
    """
    model.save(str(run_dir / "final_model.zip"))
    vec_normalize = model.get_vec_normalize_env()
    if vec_normalize is not None:
        vec_normalize.save(str(run_dir / "vecnormalize.pkl"))
    if save_replay_buffer and getattr(model, "replay_buffer", None) is not None:
        model.save_replay_buffer(str(run_dir / "replay_buffer.pkl"))


def create_run_dir(
    run_dir: Path,
    algo: str,
    env_id: str,
    seed: int,
    gym_packages: Sequence[str],
    config_source: str | Path,
    cfg: Any,
) -> Path:
    """Create a fresh run directory with its ``config.yml`` and a ``meta.json`` without segments.

    ``meta.json`` records the seed, the seed protocol (``seed_protocol``: :data:`uvdms_gym.seeds.PROTOCOL`) and
    the split of the seed and its derived seeds (``seed_split``: ``training``), and the seed scheme.

    Args:
        run_dir: The directory (:func:`run_dir_for`).
        algo: Algorithm name.
        env_id: Environment id.
        seed: Base seed.
        gym_packages: Packages that register the env id.
        config_source: The config file the entry came from.
        cfg: The resolved ``agents.config.schema.TrainConfig`` (written flat, ``cfg.to_entry()``).

    Returns:
        ``run_dir``.

    Raises:
        RunDirError: The directory exists and is not empty.
    """
    if run_dir.exists() and any(run_dir.iterdir()):
        if latest_checkpoint(run_dir) is None:
            raise RunDirError(
                f"run directory {run_dir} exists but holds no model (a run still starting, or one killed before "
                "its first checkpoint: see its meta.json); delete it or use another --seed/--out"
            )
        raise RunDirError(f"run directory {run_dir} exists; use --resume {run_dir} or another --seed/--out")
    run_dir.mkdir(parents=True, exist_ok=True)
    resolved = {
        "algo": algo,
        "env_id": env_id,
        "seed": seed,
        "gym_packages": list(gym_packages),
        "config_source": str(config_source),
        "config": cfg.to_entry(),
    }
    (run_dir / "config.yml").write_text(yaml.safe_dump(resolved, sort_keys=False), encoding="utf-8")
    meta = {
        "algo": algo,
        "env_id": env_id,
        "seed": seed,
        "seed_protocol": PROTOCOL,  # uvdms_gym.seeds: the seed and all its derived seeds are in this split
        "seed_split": TRAINING_SPLIT,
        "seed_scheme": {
            "train_env": f"seed + {SEGMENT_SEED_STRIDE} * segment + rank",
            "model": f"seed + {SEGMENT_SEED_STRIDE} * segment",
            "eval_env": f"seed + {EVAL_SEED_OFFSET} + rank (reset before every evaluation)",
        },
        "versions": package_versions(),
        "git": git_info(),
        "segments": [],
    }
    _write_json(run_dir / "meta.json", meta)
    return run_dir


def _existing(path: Path) -> Path | None:
    return path if path.is_file() else None


def utc_now() -> str:
    """The current UTC time, ISO 8601 to the second."""
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def _write_json(path: Path, data: Any) -> None:
    """A run record through the project's one JSON writer (NaN and infinities become ``null``)."""
    write_json_atomic(path, to_jsonable(data))
