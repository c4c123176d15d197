"""The weights-only agent format: export a trained policy, and rebuild it without unpickling anything.

A directory written by :func:`export_controller` (also through :func:`agents.export.export_agent`) loads with
:func:`load_weights_only` (also through :func:`agents.export.load_agent`): the policy is rebuilt from the
JSON by constructing the algorithm's policy class with the saved spaces and keyword arguments; the weights load
with ``torch.load(..., weights_only=True)`` and the normalisation with ``numpy.load(..., allow_pickle=False)``.
An export also carries the run's ``learning_curve.json`` (:mod:`agents.common.learning_curve`) and its ``meta.json``
(seeds, package versions, git revision and every training segment's command, budget and wall time;
:mod:`agents.training.rundir`) when the agent's folder has them; they are plain data about the training, not part of the
policy (nor of its checksum).
"""

from __future__ import annotations

import hashlib
import inspect
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch
from gymnasium import spaces

from agents.algos import ALGOS
from agents.common.learning_curve import copy_learning_curve
from agents.common.wrappers import is_unit_scale
from agents.config import ConfigError
from agents.config.policy_kwargs import plain_policy_kwargs, resolve_policy_kwargs
from agents.export.controller import AgentController, ExportFormatError, ObsNormalizer, recorded_composition
from uvdms_gym.residual import ActionComposition
from uvdms_gym.utils.io import mirror_file, write_json_atomic
from uvdms_gym.utils.provenance import package_versions

FORMAT_NAME = "uvdms-agent-weights"
FORMAT_VERSION = 1
AGENT_JSON = "agent.json"
RUN_META = "meta.json"
WEIGHTS_FILE = "policy.pt"
NORMALIZATION_FILE = "normalization.npz"
_DTYPES = {"float32": np.float32, "float64": np.float64}
_SPACE_ARGS = ("observation_space", "action_space", "lr_schedule")


def run_time_record(composition: ActionComposition) -> dict[str, Any]:
    """What runs besides the network when the agent acts: ``network_only`` says nothing does.

    A residual agent's base (an MPC: a QP every step) and the safety filter (a QP) run with it, and the navigation
    filter (an extended Kalman filter) when the agent observes its estimate; an agent with none of them is the
    network alone (a distilled controller: no QP, no distance query beyond its observation). ``memory`` is how
    many observations and own past actions the network sees (``frame_stack``, ``action_history``);
    ``obstacle_features`` whether it also sees the obstacle features, which its observation's obstacle slots give
    through the kinematic model (distances and ``J_dis`` rows, no optimisation: still the network alone);
    ``tracking_features`` whether it sees its tracking error magnified (its observation rescaled).
    """
    return {
        "network_only": composition.is_plain and not composition.navigation_filter,
        "base": composition.residual_base,
        "safety_filter": composition.safety_filter,
        "navigation_filter": composition.navigation_filter,
        "memory": {"observations": composition.frame_stack, "actions": composition.action_history},
        "obstacle_features": composition.obstacle_features,
        "tracking_features": composition.tracking_features,
    }


def export_controller(agent: AgentController, out_path: str | Path, *, overwrite: bool = False) -> Path:
    """Write an :class:`AgentController` in the weights-only format (see :func:`export_agent`)."""
    out = Path(out_path)
    if out.exists() and any(out.iterdir()) and not overwrite:
        raise FileExistsError(f"{out} exists and is not empty (pass overwrite=True)")
    policy = agent.policy
    params = dict(policy._get_constructor_parameters())
    observation_space, action_space = params["observation_space"], params["action_space"]
    for name in _SPACE_ARGS:
        params.pop(name, None)
    try:
        policy_kwargs = plain_policy_kwargs(params)
    except ConfigError as exc:
        raise ExportFormatError(str(exc)) from exc
    aliases = [name for name, cls in ALGOS[agent.algo].policy_aliases.items() if cls is type(policy)]
    if not aliases:
        raise ExportFormatError(f"policy class {type(policy).__qualname__} is not a {agent.algo} policy alias")

    out.mkdir(parents=True, exist_ok=True)
    state = {key: value.detach().cpu().clone() for key, value in policy.state_dict().items()}
    torch.save(state, out / WEIGHTS_FILE)
    files = {WEIGHTS_FILE: _sha256(out / WEIGHTS_FILE)}
    normalization: dict[str, Any] = {"norm_obs": agent.normalizer is not None}
    if agent.normalizer is not None:
        np.savez(out / NORMALIZATION_FILE, obs_mean=agent.normalizer.mean, obs_var=agent.normalizer.var)
        normalization.update(clip_obs=agent.normalizer.clip_obs, epsilon=agent.normalizer.epsilon)
        files[NORMALIZATION_FILE] = _sha256(out / NORMALIZATION_FILE)
    elif (out / NORMALIZATION_FILE).exists():
        (out / NORMALIZATION_FILE).unlink()

    document = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "algo": agent.algo,
        "env_id": agent.env_id,
        "env_kwargs": agent.env_kwargs,
        "policy": aliases[0],
        "policy_class": f"{type(policy).__module__}.{type(policy).__qualname__}",
        "policy_kwargs": policy_kwargs,
        "observation_space": _space_to_json(observation_space),
        "action_space": _space_to_json(action_space),
        "normalization": normalization,
        "action_scale": agent.action_scale,
        **agent.composition.to_record(),
        "run_time": run_time_record(agent.composition),
        "num_timesteps": agent.num_timesteps,
        "source": Path(agent.source).name,
        "versions": package_versions(),
        "files": files,
    }
    write_json_atomic(out / AGENT_JSON, document)
    copy_learning_curve(agent.source, out)  # the training history, if the agent's run recorded one
    copy_run_meta(agent.source, out)
    return out


def copy_run_meta(source: str | Path, out_dir: str | Path) -> Path | None:
    """Copy the ``meta.json`` of the folder of ``source`` into ``out_dir``; ``None`` if it has none.

    ``source`` is the agent's model file or folder (a run directory, a shipped folder or an export). A stale record
    in ``out_dir`` is removed when the source has none.
    """
    path = Path(source)
    return mirror_file((path if path.is_dir() else path.parent) / RUN_META, Path(out_dir) / RUN_META)


def load_weights_only(path: str | Path, device: str = "cpu") -> AgentController:
    """Rebuild an agent from a weights-only export without unpickling anything.

    Args:
        path: Export directory (or its ``agent.json``).
        device: Torch device.

    Returns:
        The controller.

    Raises:
        ExportFormatError: Malformed JSON, unknown algorithm/policy/class names, checksum mismatch, or
            a weights file that is not a plain tensor dictionary.
        pickle.UnpicklingError: If the weights file contains pickled objects (refused by
            ``torch.load(weights_only=True)``).
    """
    path = Path(path)
    folder = path.parent if path.name == AGENT_JSON else path
    doc = _read_document(folder)
    algo = doc.get("algo")
    if algo not in ALGOS:
        raise ExportFormatError(f"{folder}: unknown algo {algo!r}")
    policy = _rebuild_policy(folder, doc, algo, device)
    return AgentController(
        policy,
        algo=algo,
        env_id=doc.get("env_id"),
        env_kwargs=doc.get("env_kwargs") or {},
        normalizer=_normalizer(folder, doc),
        num_timesteps=doc.get("num_timesteps"),
        source=str(folder),
        action_scale=_action_scale(doc, folder),
        composition=recorded_composition(doc, str(folder)),
    )


def _read_document(folder: Path) -> dict[str, Any]:
    """``agent.json``, checked: the format and its version, and the SHA-256 of every file it lists."""
    try:
        doc = json.loads((folder / AGENT_JSON).read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise ExportFormatError(f"{folder}: cannot read {AGENT_JSON}: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != FORMAT_NAME:
        raise ExportFormatError(f"{folder}: not a {FORMAT_NAME} export")
    if doc.get("format_version") != FORMAT_VERSION:
        raise ExportFormatError(f"{folder}: unsupported format_version {doc.get('format_version')!r}")
    files = doc.get("files", {})
    for name, digest in files.items():
        if name not in (WEIGHTS_FILE, NORMALIZATION_FILE):
            raise ExportFormatError(f"{folder}: unexpected file entry {name!r}")
        if _sha256(folder / name) != digest:
            raise ExportFormatError(f"{folder / name}: SHA-256 does not match {AGENT_JSON}")
    if WEIGHTS_FILE not in files:
        raise ExportFormatError(f"{folder}: {AGENT_JSON} lists no {WEIGHTS_FILE}")
    return doc


def _rebuild_policy(folder: Path, doc: Mapping[str, Any], algo: str, device: str) -> Any:
    """The algorithm's policy class built from the recorded spaces and keywords, with the weights loaded."""
    policy_cls = ALGOS[algo].policy_aliases.get(doc.get("policy"))
    if policy_cls is None:
        raise ExportFormatError(f"{folder}: unknown {algo} policy {doc.get('policy')!r}")
    allowed = set(inspect.signature(policy_cls.__init__).parameters) - {"self", *_SPACE_ARGS}
    policy_kwargs = doc.get("policy_kwargs", {})
    if not isinstance(policy_kwargs, dict) or set(policy_kwargs) - allowed:
        raise ExportFormatError(
            f"{folder}: policy_kwargs has keys unknown to {policy_cls.__name__}: {sorted(set(policy_kwargs) - allowed)}"
        )
    try:
        kwargs = resolve_policy_kwargs(policy_kwargs)
    except ConfigError as exc:
        raise ExportFormatError(f"{folder}: {exc}") from exc
    policy = policy_cls(
        observation_space=_space_from_json(doc["observation_space"]),
        action_space=_space_from_json(doc["action_space"]),
        lr_schedule=_zero_schedule,
        **kwargs,
    ).to(device)
    state = torch.load(folder / WEIGHTS_FILE, map_location=device, weights_only=True)
    if not isinstance(state, dict) or not all(
        isinstance(k, str) and isinstance(v, torch.Tensor) for k, v in state.items()
    ):
        raise ExportFormatError(f"{folder / WEIGHTS_FILE}: not a mapping of parameter names to tensors")
    policy.load_state_dict(state, strict=True)
    return policy


def _normalizer(folder: Path, doc: Mapping[str, Any]) -> ObsNormalizer | None:
    """The observation normaliser of an export that normalises observations (``None`` otherwise)."""
    normalization = doc.get("normalization", {})
    if not normalization.get("norm_obs"):
        return None
    if NORMALIZATION_FILE not in doc.get("files", {}):
        raise ExportFormatError(f"{folder}: norm_obs is set but {NORMALIZATION_FILE} is not listed")
    with np.load(folder / NORMALIZATION_FILE, allow_pickle=False) as stats:
        return ObsNormalizer(
            mean=np.asarray(stats["obs_mean"], dtype=np.float64),
            var=np.asarray(stats["obs_var"], dtype=np.float64),
            clip_obs=float(normalization["clip_obs"]),
            epsilon=float(normalization["epsilon"]),
        )


def _action_scale(doc: Mapping[str, Any], folder: Path) -> float:
    """``action_scale`` of an export (absent in exports written before it existed: 1.0)."""
    scale = doc.get("action_scale", 1.0)
    if not is_unit_scale(scale):
        raise ExportFormatError(f"{folder}: action_scale must be a number in (0, 1], got {scale!r}")
    return float(scale)


def _zero_schedule(_progress_remaining: float) -> float:
    return 0.0


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _encode_floats(array: np.ndarray) -> list[Any]:
    return [x if math.isfinite(x) else str(x) for x in np.asarray(array, dtype=np.float64).ravel().tolist()]


def _decode_floats(values: list[Any], shape: tuple[int, ...], dtype: type) -> np.ndarray:
    if not isinstance(values, list) or not all(isinstance(v, int | float | str) for v in values):
        raise ExportFormatError("space bounds must be a list of numbers or 'inf'/'-inf'/'nan'")
    try:
        flat = np.array([float(v) for v in values], dtype=np.float64)
    except ValueError as exc:
        raise ExportFormatError(f"bad space bound: {exc}") from exc
    return flat.reshape(shape).astype(dtype)


def _space_to_json(space: spaces.Space) -> dict[str, Any]:
    if not isinstance(space, spaces.Box):
        raise ExportFormatError(f"only Box spaces can be exported, got {type(space).__name__}")
    dtype = np.dtype(space.dtype).name
    if dtype not in _DTYPES:
        raise ExportFormatError(f"unsupported Box dtype {dtype}")
    return {
        "type": "Box",
        "shape": list(space.shape),
        "dtype": dtype,
        "low": _encode_floats(space.low),
        "high": _encode_floats(space.high),
    }


def _space_from_json(data: Any) -> spaces.Box:
    if not isinstance(data, dict) or data.get("type") != "Box" or data.get("dtype") not in _DTYPES:
        raise ExportFormatError(f"unsupported space description {data!r:.200}")
    shape = tuple(int(n) for n in data["shape"])
    dtype = _DTYPES[data["dtype"]]
    low = _decode_floats(data["low"], shape, dtype)
    high = _decode_floats(data["high"], shape, dtype)
    return spaces.Box(low=low, high=high, shape=shape, dtype=dtype)
