"""The run specification: what one training run trains, as one frozen value passed around.

``uvdms train``, ``python -m agents.training.train``, a sweep's run (:mod:`agents.distributed.worker`) and a tuning
trial (:mod:`agents.distributed.tune`) all describe a fresh run by the same fields; :class:`RunSpec` holds them, checks
them, resolves them into the :class:`~agents.config.TrainConfig` the run uses and writes them back as the equivalent
command line (``command.txt``, ``meta.json``). Where the run writes (``out_dir``) and how it reports (progress bar,
callbacks) are arguments of :func:`agents.training.train.train_run`, not part of the specification.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from agents.algos import ALGOS
from agents.common.names import DEFAULT_GYM_PACKAGES, NO_BASE, VEC_ENV_TYPES
from agents.config import ConfigError, TrainConfig, default_config_path, load_config, parse_entry

COMPOSITION_FIELDS: tuple[str, ...] = (
    "residual_base",
    "residual_scale",
    "residual_observation",
    "residual_space",
    "safety_filter",
)
"""The fields of :class:`RunSpec` that override the configuration's action composition (``None``: the config's)."""


@dataclasses.dataclass(frozen=True)
class RunSpec:
    """One fresh training run: algorithm, environment, configuration and its command-line overrides.

    Attributes:
        algo: Algorithm name (a key of :data:`agents.algos.ALGOS`).
        env_id: Gymnasium environment id.
        env_kwargs: Extra ``gymnasium.make`` keyword arguments (merged over the config's ``env_kwargs``).
        config_path: YAML config (``None``: ``train_configs/<algo>.yml``).
        seed: Base seed (seed scheme: :mod:`agents.training.train`).
        total_timesteps: Total steps (``None``: the config's ``n_timesteps``).
        n_envs: Training environments (``None``: the config's).
        hyperparams: Extra config keys overriding the file, validated like the file.
        vec_env: Vectorised env type (:data:`agents.common.names.VEC_ENV_TYPES`).
        gym_packages: Packages imported so that the env id is registered.
        residual_base: ``--residual`` (``None``: the config's ``residual_base``; :data:`NO_BASE`: none).
        residual_scale: ``--residual-scale``.
        residual_observation: ``--residual-observation``.
        residual_space: ``--residual-space``.
        safety_filter: ``--safety-filter`` (``None``: the config's).
    """

    algo: str
    env_id: str
    env_kwargs: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    config_path: Path | None = None
    seed: int = 0
    total_timesteps: int | None = None
    n_envs: int | None = None
    hyperparams: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    vec_env: str = "dummy"
    gym_packages: tuple[str, ...] = DEFAULT_GYM_PACKAGES
    residual_base: str | None = None
    residual_scale: float | None = None
    residual_observation: str | None = None
    residual_space: str | None = None
    safety_filter: bool | None = None

    def __post_init__(self) -> None:
        """Normalise the containers (plain dict/tuple/Path) and check the names."""
        object.__setattr__(self, "env_kwargs", dict(self.env_kwargs or {}))
        object.__setattr__(self, "hyperparams", dict(self.hyperparams or {}))
        object.__setattr__(self, "gym_packages", tuple(self.gym_packages))
        if self.config_path is not None:
            object.__setattr__(self, "config_path", Path(self.config_path))
        if self.algo not in ALGOS:
            raise ConfigError(f"unknown algorithm {self.algo!r}; choose one of {sorted(ALGOS)}")
        if self.vec_env not in VEC_ENV_TYPES:
            raise ConfigError(f"vec_env must be one of {VEC_ENV_TYPES}, got {self.vec_env!r}")

    @property
    def config_file(self) -> Path:
        """The configuration file the run reads (the given one or ``train_configs/<algo>.yml``)."""
        return self.config_path if self.config_path is not None else default_config_path(self.algo)

    def composition(self) -> dict[str, Any]:
        """The action-composition overrides that are set (``--residual`` ..., ``--safety-filter``).

        ``--residual none`` (:data:`NO_BASE`) sets ``residual_base`` to ``None``: no base, whatever the file says.
        """
        overrides = {name: getattr(self, name) for name in COMPOSITION_FIELDS if getattr(self, name) is not None}
        if overrides.get("residual_base") == NO_BASE:
            overrides["residual_base"] = None
        return overrides

    def replace(self, **changes: Any) -> RunSpec:
        """A copy with ``changes`` (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)

    def resolve(self) -> TrainConfig:
        """The configuration the run uses: the file's entry with this specification's overrides.

        Raises:
            ConfigError: An invalid file, key or value.
        """
        return resolve_config(
            self.config_file,
            self.algo,
            self.env_id,
            self.hyperparams,
            self.env_kwargs,
            self.n_envs,
            self.total_timesteps,
            composition=self.composition(),
        )

    def command(self, cfg: TrainConfig, out_dir: str | Path) -> list[str]:
        """The equivalent command line of this run (recorded in ``command.txt`` and ``meta.json``).

        Args:
            cfg: The resolved configuration (:meth:`resolve`).
            out_dir: The run directories' root (``--out``).
        """
        command = [
            *command_prefix(cfg),
            "--algo",
            self.algo,
            "--env",
            self.env_id,
            "--config",
            str(self.config_file),
            "--seed",
            str(self.seed),
            "--total-timesteps",
            str(cfg.n_timesteps),
            "--n-envs",
            str(cfg.n_envs),
            "--out",
            str(out_dir),
            "--vec-env",
            self.vec_env,
            "--gym-packages",
            *self.gym_packages,
        ]
        if self.env_kwargs:
            command += ["--env-kwargs", *(f"{k}={json.dumps(v)}" for k, v in self.env_kwargs.items())]
        if self.hyperparams:
            command += ["--hyperparams", *(f"{k}={json.dumps(v)}" for k, v in self.hyperparams.items())]
        return command + self._composition_options()

    def _composition_options(self) -> list[str]:
        options: list[str] = []
        if self.residual_base is not None:
            options += ["--residual", self.residual_base]
        if self.residual_scale is not None:
            options += ["--residual-scale", repr(float(self.residual_scale))]
        if self.residual_observation is not None:
            options += ["--residual-observation", self.residual_observation]
        if self.residual_space is not None:
            options += ["--residual-space", self.residual_space]
        if self.safety_filter:
            options.append("--safety-filter")
        return options


def command_prefix(cfg: TrainConfig) -> list[str]:
    """What runs ``cfg``: ``uvdms train`` with a component to compose, else ``python -m agents.training.train``."""
    plain = cfg.composition.is_plain and cfg.algo != "dagger"
    return ["python", "-m", "agents.training.train"] if plain else ["uvdms", "train"]


def resolve_config(
    config_path: str | Path,
    algo: str,
    env_id: str,
    hyperparams: Mapping[str, Any] | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    n_envs: int | None = None,
    total_timesteps: int | None = None,
    *,
    composition: Mapping[str, Any] | None = None,
) -> TrainConfig:
    """The configuration a fresh run uses: the file's entry with the command line's overrides.

    Args:
        config_path: The configuration file.
        algo: Algorithm name.
        env_id: Environment id (its entry, or ``default``).
        hyperparams: Config keys overriding the entry (``--hyperparams``).
        env_kwargs: Merged into the entry's ``env_kwargs`` (``--env-kwargs``).
        n_envs: Overrides ``n_envs`` (``--n-envs``).
        total_timesteps: Overrides ``n_timesteps`` (``--total-timesteps``).
        composition: Overrides of ``residual_base``, ``residual_scale``, ``residual_observation``,
            ``residual_space``, ``safety_filter`` (``--residual``, ``--residual-scale``, ``--residual-observation``,
            ``--residual-space``, ``--safety-filter``).

    Raises:
        ConfigError: An invalid file, key or value.
    """
    cfg = load_config(config_path, algo, env_id, overrides=hyperparams)
    entry = cfg.to_entry()
    if env_kwargs:
        entry["env_kwargs"] = {**entry["env_kwargs"], **dict(env_kwargs)}
    if n_envs is not None:
        entry["n_envs"] = n_envs
    if total_timesteps is not None:
        entry["n_timesteps"] = total_timesteps
    entry.update(composition or {})
    return parse_entry(entry, algo, source=f"{config_path} + command line", entry_name=env_id)
