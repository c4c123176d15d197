"""Full Stable-Baselines3 zips and VecNormalize pickles: loading them unpickles, so it is trust-gated.

:func:`load_sb3_zip` refuses unless the caller passes ``trust=True`` or the file lies inside the shipped agents'
folder ``trained_agents/`` (committed, reviewed agents); :func:`load_sb3_agent` builds the
:class:`~agents.export.controller.AgentController` of a run directory, a shipped folder or a zip. A weights-only
export (:mod:`agents.export.weights`) never unpickles and needs no trust.
"""

from __future__ import annotations

import json
import pickle
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from agents.algos import ALGOS
from agents.common.legacy import new_module, old_pickles
from agents.common.paths import trained_agents_dir
from agents.export.controller import (
    SHIPPED_MODEL,
    SHIPPED_STATS,
    AgentController,
    ExportFormatError,
    ObsNormalizer,
    UntrustedFileError,
    Which,
    recorded_composition,
)

TRUSTED_DIR = trained_agents_dir()
"""The shipped agents (the checkout's ``trained_agents/`` or its installed copy, :mod:`agents.common.paths`): SB3 zips
and pickles inside this folder (committed, reviewed agents) load without ``trust=True``."""


def is_trusted_path(path: str | Path) -> bool:
    """Whether ``path`` (symlinks resolved) lies inside the repository's ``trained_agents/`` folder."""
    return Path(path).resolve().is_relative_to(TRUSTED_DIR.resolve())


def _require_trust(path: Path, trust: bool) -> None:
    if not (trust or is_trusted_path(path)):
        raise UntrustedFileError(
            f"{path} contains pickled objects, which can run arbitrary code when loaded; pass trust=True if "
            f"you trust its origin, put it under {TRUSTED_DIR}, or use a weights-only export "
            "(export_agent / load_weights_only)",
            path=path,
        )


def load_sb3_zip(path: str | Path, trust: bool, algo: str | None = None, device: str = "cpu") -> BaseAlgorithm:
    """Load a full SB3 model zip (this unpickles: allowed only if trusted).

    Args:
        path: The ``.zip`` file.
        trust: The caller trusts the file. Without it, only files inside ``trained_agents/`` load.
        algo: Algorithm name; by default inferred from the zip's JSON data (policy class module).
        device: Torch device.

    Returns:
        The SB3 model (without an environment).

    Raises:
        UntrustedFileError: If not trusted.
        FileNotFoundError: If the file does not exist.
        ExportFormatError: If the file is not a readable SB3 zip (corrupt or truncated).
    """
    path = Path(path)
    _require_trust(path, trust)
    if not path.is_file():
        raise FileNotFoundError(path)
    algo = algo if algo is not None else zip_algo(path)
    try:
        with old_pickles():  # a zip written before 0.3.0 names its policy class by the old module path
            return ALGOS[algo].load(str(path), device=device, print_system_info=False)
    except (zipfile.BadZipFile, EOFError) as exc:
        raise ExportFormatError(f"{path}: not a readable SB3 zip, corrupt or truncated ({exc})") from exc
    except ValueError as exc:  # SB3 turns a BadZipFile into ValueError("Error: the file ... wasn't a zip-file")
        if isinstance(exc.__cause__, zipfile.BadZipFile):
            raise ExportFormatError(f"{path}: not a readable SB3 zip, corrupt or truncated ({exc.__cause__})") from exc
        raise


def zip_algo(path: str | Path) -> str:
    """Algorithm of an SB3 zip, read from the module name of its policy class (no unpickling; old names mapped)."""
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data").decode("utf-8"))
    module = new_module(data.get("policy_class", {}).get("__module__"))
    for name, cls in ALGOS.items():
        if any(p.__module__ == module for p in cls.policy_aliases.values()):
            return name
    raise ValueError(f"{path}: cannot infer the algorithm from policy module {module!r}; pass algo=")


def load_vecnormalize_stats(path: str | Path, trust: bool) -> ObsNormalizer | None:
    """Observation statistics of a VecNormalize pickle (this unpickles: allowed only if trusted).

    Returns:
        The normaliser, or ``None`` if the VecNormalize did not normalise observations.
    """
    path = Path(path)
    _require_trust(path, trust)
    with path.open("rb") as f:
        vec_normalize = pickle.load(f)  # guarded by the trust check above
    if not isinstance(vec_normalize, VecNormalize):
        raise ValueError(f"{path} does not contain VecNormalize statistics")
    return _normalizer_from_vecnormalize(vec_normalize)


def _normalizer_from_vecnormalize(vec_normalize: VecNormalize) -> ObsNormalizer | None:
    if not vec_normalize.norm_obs:
        return None
    if isinstance(vec_normalize.obs_rms, dict):
        raise NotImplementedError("dict observations are not supported by AgentController")
    return ObsNormalizer(
        mean=np.asarray(vec_normalize.obs_rms.mean, dtype=np.float64),
        var=np.asarray(vec_normalize.obs_rms.var, dtype=np.float64),
        clip_obs=float(vec_normalize.clip_obs),
        epsilon=float(vec_normalize.epsilon),
    )


def _stats_path(model_path: Path) -> Path | None:
    name = model_path.name
    if name == "final_model.zip":
        candidate = model_path.with_name("vecnormalize.pkl")
    elif name == "best_model.zip":
        candidate = model_path.with_name("best_vecnormalize.pkl")
    elif name == SHIPPED_MODEL:
        candidate = model_path.with_name(SHIPPED_STATS)
    elif name.startswith("rl_model_") and name.endswith("_steps.zip"):
        steps = name[len("rl_model_") : -len("_steps.zip")]
        candidate = model_path.with_name(f"rl_model_vecnormalize_{steps}_steps.pkl")
    else:
        candidate = model_path.with_suffix(".vecnormalize.pkl")
    return candidate if candidate.is_file() else None


def _find_run_config(model_path: Path) -> dict[str, Any]:
    for folder in (model_path.parent, model_path.parent.parent):
        config_file = folder / "config.yml"
        if config_file.is_file():
            data = yaml.safe_load(config_file.read_text(encoding="utf-8"))
            return data if isinstance(data, dict) else {}
    return {}


def _no_model_message(model_path: Path) -> str:
    """``no model at PATH``; for a run's missing ``best_model.zip``, why there is none and what to export instead."""
    if model_path.name != "best_model.zip" or not (model_path.parent / "final_model.zip").is_file():
        return f"no model at {model_path}"
    return (
        f"no model at {model_path}: a run writes best_model.zip at its evaluations (every eval_freq steps, "
        "train_options of the training config) and this run had none (it ended before its first one, or eval_freq "
        "was 0); export its final model (which='final', uvdms export-agent --which final) or train with evaluations "
        "for more than eval_freq steps"
    )


def load_sb3_agent(
    path: str | Path, *, which: Which = "final", trust: bool = False, algo: str | None = None
) -> AgentController:
    """The controller of a run directory, a shipped agent folder or an SB3 zip (see :func:`agents.export.load_agent`).

    Raises:
        UntrustedFileError: If SB3/VecNormalize pickles would have to be loaded without trust.
        FileNotFoundError: If the model or its required normalisation statistics are missing.
    """
    path = Path(path)
    if path.is_dir() and (path / SHIPPED_MODEL).is_file():
        model_path = path / SHIPPED_MODEL
    elif path.is_dir():
        if which not in ("final", "best"):
            raise ValueError(f"which must be 'final' or 'best', got {which!r}")
        model_path = path / f"{which}_model.zip"
    else:
        model_path = path
    if not model_path.is_file():
        raise FileNotFoundError(_no_model_message(model_path))
    stats_path = _stats_path(model_path)
    resolved = _find_run_config(model_path)
    config = resolved.get("config", {})
    if stats_path is None and config.get("normalize", False) not in (False, None):
        raise FileNotFoundError(f"{model_path}: the run normalises observations but no statistics beside it")
    model = load_sb3_zip(model_path, trust=trust, algo=algo or resolved.get("algo"))
    normalizer = load_vecnormalize_stats(stats_path, trust=trust) if stats_path is not None else None
    return AgentController(
        model.policy,
        algo=algo or resolved.get("algo") or zip_algo(model_path),
        env_id=resolved.get("env_id"),
        env_kwargs=config.get("env_kwargs", {}),
        normalizer=normalizer,
        num_timesteps=int(model.num_timesteps),
        source=str(model_path),
        action_scale=float(config.get("action_scale", 1.0)),
        composition=recorded_composition(config, str(model_path)),
    )
