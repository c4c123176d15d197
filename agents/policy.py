"""Loading trained agents for evaluation, and a weights-only export format that never unpickles.

Two ways to get an :class:`AgentController` (``reset(seed)``, ``predict(obs, info) -> action``,
deterministic, VecNormalize observation statistics applied without a VecEnv):

* :func:`load_agent` on a run directory or an SB3 zip. SB3 zips and VecNormalize ``.pkl`` files contain
  pickles (arbitrary code on load), so this goes through :func:`load_sb3_zip`, which refuses unless the
  caller passes ``trust=True`` or the file lies inside the repository's ``trained_agents/`` folder.
* :func:`load_weights_only` on a directory written by :func:`export_agent`::

      agent.json          format, algo, env id/kwargs, policy alias, policy_kwargs (plain data, class names
                          whitelisted), observation/action spaces (shape, dtype, bounds), normalisation
                          settings, action_scale, the composition (residual_base, residual_scale,
                          safety_filter: :mod:`uvdms_gym.residual`), num_timesteps, package versions,
                          SHA-256 of the two files below
      policy.pt           ``torch.save(policy.state_dict())``: tensors only, loaded with
                          ``torch.load(..., weights_only=True)``
      normalization.npz   ``obs_mean``, ``obs_var`` (only when observations are normalised), loaded with
                          ``numpy.load(..., allow_pickle=False)``
      learning_curve.json the run's evaluation metrics against steps (:mod:`agents.learning_curve`; if recorded)
      meta.json           the run's record: seeds, versions, git revision, each segment's command, steps and
                          wall time (:mod:`agents.rundir`; if recorded). Neither is read to rebuild the policy
                          nor part of the agent's checksum.

  The policy is rebuilt from the JSON by constructing the algorithm's policy class with the saved spaces
  and keyword arguments; no file of the export is unpickled.
"""

from __future__ import annotations

import json
import pickle
import warnings
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
import yaml
from gymnasium import spaces
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.vec_env import VecNormalize

from agents.algos import ALGOS
from agents.config import is_unit_scale
from agents.paths import trained_agents_dir
from uvdms_gym.evaluation import check_action_mode
from uvdms_gym.residual import ActionComposition, residual_observation_space

TRUSTED_DIR = trained_agents_dir()
"""The shipped agents (the checkout's ``trained_agents/`` or its installed copy, :mod:`agents.paths`): SB3 zips
and pickles inside this folder (committed, reviewed agents) load without ``trust=True``."""

SHIPPED_MODEL = "model.zip"
"""Model file of a shipped agent folder (``trained_agents/<name>/``, written by :mod:`agents.ship`)."""
SHIPPED_STATS = "vecnormalize.pkl"
"""VecNormalize statistics of a shipped agent folder."""

Which = Literal["final", "best"]


class UntrustedFileError(ValueError):
    """Refused to unpickle a file that is neither trusted by the caller nor inside ``trained_agents/``."""


class ExportFormatError(ValueError):
    """A weights-only export is malformed, tampered with, or cannot represent the policy."""


class EnvMismatchWarning(UserWarning):
    """An agent is evaluated on an environment id other than the one it was trained on."""


# ------------------------------------------------------------------------------------------------------
# Controller
# ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ObsNormalizer:
    """VecNormalize observation normalisation without a VecEnv (same formula and dtype as SB3).

    Attributes:
        mean: Running mean of the observations (float64).
        var: Running variance of the observations (float64).
        clip_obs: Normalised observations are clipped to ``[-clip_obs, clip_obs]``.
        epsilon: Added to the variance.
    """

    mean: np.ndarray
    var: np.ndarray
    clip_obs: float
    epsilon: float

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Normalise ``obs`` (any leading batch dimensions) and return float32."""
        normalized = np.clip((obs - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip_obs, self.clip_obs)
        return normalized.astype(np.float32)


class AgentController:
    """A trained policy as a deterministic controller: ``reset(seed)`` then ``predict(obs, info)``.

    Attributes:
        policy: The SB3 policy (evaluation mode).
        algo: Algorithm name.
        env_id: Environment id the agent was trained on (``None`` if unknown).
        env_kwargs: ``gymnasium.make`` keyword arguments of the training environment.
        normalizer: Observation normalisation (``None`` if the agent was trained without it).
        num_timesteps: Training steps of the loaded model (``None`` if unknown).
        source: Where the agent was loaded from.
        action_scale: The network's output is multiplied by this (``TrainConfig.action_scale``).
        composition: The residual base and safety filter the agent was trained with
            (:class:`uvdms_gym.residual.ActionComposition`). A residual agent observes ``[obs; a_base]`` and its
            output is a residual: evaluate it through ``leaderboard.registry.make_controller``, which composes the
            base (and the filter) from this record.
    """

    def __init__(
        self,
        policy: BasePolicy,
        *,
        algo: str,
        env_id: str | None = None,
        env_kwargs: Mapping[str, Any] | None = None,
        normalizer: ObsNormalizer | None = None,
        num_timesteps: int | None = None,
        source: str = "",
        action_scale: float = 1.0,
        composition: ActionComposition | None = None,
    ) -> None:
        if not is_unit_scale(action_scale):
            raise ValueError(f"action_scale must be in (0, 1], got {action_scale}")
        self.policy = policy
        self.policy.set_training_mode(False)
        self.algo = algo
        self.env_id = env_id
        self.env_kwargs = dict(env_kwargs or {})
        self.normalizer = normalizer
        self.num_timesteps = num_timesteps
        self.source = source
        self.action_scale = float(action_scale)
        self.composition = composition or ActionComposition()
        self.seed: int | None = None

    @property
    def observation_space(self) -> spaces.Space:
        """Observation space the policy expects (un-normalised observations)."""
        return self.policy.observation_space

    @property
    def action_space(self) -> spaces.Space:
        """Action space of the policy's outputs."""
        return self.policy.action_space

    def check_env_id(self, env_id: str | None) -> bool:
        """Warn if the agent is about to run on another environment than the one it was trained on.

        An agent's observation layout and reward are those of its training environment: a CircleTrack agent
        evaluated on Transport gets observations of the same shape but another meaning. Evaluation code
        (:func:`check_agent`, used by ``uvdms evaluate`` and the leaderboard) calls this.

        Args:
            env_id: Id of the evaluation environment (``None``: unknown, nothing to check).

        Returns:
            Whether the ids agree (``True`` when either is unknown).

        Warns:
            EnvMismatchWarning: The ids differ (the message names both).
        """
        if env_id is None or self.env_id is None or env_id == self.env_id:
            return True
        warnings.warn(
            f"agent {self.source or self.algo} was trained on {self.env_id} but runs on {env_id}: its observations "
            "there mean something else, so its actions are not those of a trained policy",
            EnvMismatchWarning,
            stacklevel=2,
        )
        return False

    def reset(self, seed: int | None = None) -> None:
        """Start an episode. The MLP policies are stateless and deterministic; the seed is only recorded."""
        self.seed = seed

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """The observation as the network sees it (normalised if the agent was trained with VecNormalize)."""
        obs = np.asarray(obs, dtype=self.observation_space.dtype)
        return self.normalizer(obs) if self.normalizer is not None else obs

    def predict(self, obs: np.ndarray, info: Mapping[str, Any] | None = None) -> np.ndarray:
        """Deterministic action for one observation (or a batch with a leading dimension).

        Args:
            obs: Raw environment observation.
            info: The environment's info dict (unused; for interface parity with other controllers).

        Returns:
            The action (``action_scale`` times the network's), within the action space bounds.
        """
        with torch.no_grad():
            action, _ = self.policy.predict(self.normalize(obs), deterministic=True)
        return action if self.action_scale == 1.0 else (self.action_scale * action).astype(action.dtype)


def check_agent(agent: Any, env: Any, name: str = "agent") -> None:
    """Check that a loaded agent fits ``env``: its action mode and its observation/action shapes.

    An agent trained on another environment id gets a warning (:class:`EnvMismatchWarning`), not an error:
    running it elsewhere is allowed, but never silently. A residual agent (its ``composition``) observes the
    environment's observation extended by the base's action (:func:`uvdms_gym.residual.residual_observation_space`).

    Raises:
        ValueError: On a mismatch (the message names the expected and found values).
    """
    mode = (getattr(agent, "env_kwargs", None) or {}).get("action_mode", "velocity")
    check_action_mode(f"agent {name}", env, mode)
    if hasattr(agent, "check_env_id") and env.spec is not None:
        agent.check_env_id(env.spec.id)  # warns (EnvMismatchWarning) on another env id
    composition = getattr(agent, "composition", None) or ActionComposition()
    expected = env.observation_space
    if composition.is_residual:
        expected = residual_observation_space(env.observation_space, env.action_space, composition.residual_observation)
    if tuple(agent.observation_space.shape) != tuple(expected.shape):
        what = ""
        if composition.is_residual:
            what = f" (with the residual base's {env.action_space.shape[0]} actions"
            if composition.residual_observation != "base":
                what += f" and the {composition.residual_observation} features"
            what += ")"
        raise ValueError(
            f"agent {name} expects observations of shape {agent.observation_space.shape}, the environment gives "
            f"{expected.shape}{what}"
        )
    if tuple(agent.action_space.shape) != tuple(env.action_space.shape):
        raise ValueError(f"agent {name} outputs actions of shape {agent.action_space.shape}")


# ------------------------------------------------------------------------------------------------------
# Full SB3 zips (pickles: trust required)
# ------------------------------------------------------------------------------------------------------
def is_trusted_path(path: str | Path) -> bool:
    """Whether ``path`` (symlinks resolved) lies inside the repository's ``trained_agents/`` folder."""
    return Path(path).resolve().is_relative_to(TRUSTED_DIR.resolve())


def _require_trust(path: Path, trust: bool) -> None:
    if not (trust or is_trusted_path(path)):
        raise UntrustedFileError(
            f"{path} contains pickled objects, which can run arbitrary code when loaded; pass trust=True if "
            f"you trust its origin, put it under {TRUSTED_DIR}, or use a weights-only export "
            "(export_agent / load_weights_only)"
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
    """
    path = Path(path)
    _require_trust(path, trust)
    if not path.is_file():
        raise FileNotFoundError(path)
    algo = algo if algo is not None else zip_algo(path)
    return ALGOS[algo].load(str(path), device=device, print_system_info=False)


def zip_algo(path: str | Path) -> str:
    """Algorithm of an SB3 zip, read from the module name of its policy class (no unpickling)."""
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data").decode("utf-8"))
    module = data.get("policy_class", {}).get("__module__")
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


def load_agent(
    path: str | Path, *, which: Which = "final", trust: bool = False, algo: str | None = None
) -> AgentController:
    """Load a trained agent for evaluation.

    Args:
        path: A weights-only export directory (no trust needed), a shipped agent folder (``model.zip`` and
            ``vecnormalize.pkl``, see :mod:`agents.ship`), a run directory, or an SB3 zip
            (``final_model.zip``, ``best_model.zip``, ``checkpoints/rl_model_<N>_steps.zip``) whose
            VecNormalize statistics sit beside it with the names written by ``agents.train``.
        which: For a run directory: ``final`` (``final_model.zip``) or ``best`` (``best_model.zip``);
            ignored for a shipped agent folder (one model).
        trust: Allow unpickling the run's files (see :func:`load_sb3_zip`).
        algo: Algorithm name if it cannot be read from ``config.yml`` or the zip.

    Returns:
        The controller.

    Raises:
        UntrustedFileError: If SB3/VecNormalize pickles would have to be loaded without trust.
        FileNotFoundError: If the model or its required normalisation statistics are missing.
    """
    path = Path(path)
    from agents.export import AGENT_JSON, load_weights_only

    if path.is_dir() and (path / AGENT_JSON).is_file():
        return load_weights_only(path)
    if path.is_dir() and (path / SHIPPED_MODEL).is_file():
        model_path = path / SHIPPED_MODEL
    elif path.is_dir():
        if which not in ("final", "best"):
            raise ValueError(f"which must be 'final' or 'best', got {which!r}")
        model_path = path / f"{which}_model.zip"
    else:
        model_path = path
    if not model_path.is_file():
        raise FileNotFoundError(f"no model at {model_path}")
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


def recorded_composition(record: Mapping[str, Any], where: str) -> ActionComposition:
    """The residual base and safety filter recorded in a run's config entry or an export's ``agent.json``.

    Records written before these keys existed hold none of them: a plain agent.

    Raises:
        ExportFormatError: Invalid recorded values (the message names ``where``).
    """
    try:
        return ActionComposition.from_record(record)
    except ValueError as exc:
        raise ExportFormatError(f"{where}: {exc}") from None


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


def __getattr__(name: str) -> Any:
    """The weights-only export's names (:mod:`agents.export`), importable from here as before (PEP 562)."""
    from agents import export

    try:
        return getattr(export, name)
    except AttributeError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
