"""One training segment (a fresh run, or one ``--resume``) in the steps a reader can follow.

:class:`TrainingSegment` runs them in order, as RL Zoo's ``ExperimentManager`` splits a run: record the segment in
``meta.json`` (:meth:`~TrainingSegment.start_record`), build the training and evaluation envs
(:meth:`~TrainingSegment.make_envs`), build or load the model (:meth:`~TrainingSegment.make_model`), the callbacks
(:meth:`~TrainingSegment.make_callbacks`), learn and save (:meth:`~TrainingSegment.learn`), and close the record
whatever happened (:meth:`~TrainingSegment.finish`). The run directory's layout and the seed scheme are described
in :mod:`agents.training.train`.
"""

from __future__ import annotations

import dataclasses
import json
import shlex
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.logger import configure
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecNormalize

from agents.algos import ALGOS, is_off_policy
from agents.algos.ppo_lagrangian import HISTORY_FILE, LagrangianHistory, PPOLagrangian
from agents.common.envs import (
    MAX_SEGMENTS,
    EnvFactory,
    eval_env_seed,
    make_vec_env,
    train_env_seed,
)
from agents.common.learning_curve import LEARNING_CURVE_FILE, LearningCurve
from agents.common.legacy import old_pickles
from agents.common.threads import UpdateThreads, update_threads
from agents.config import ConfigError, TrainConfig
from agents.training.callbacks import (
    DelayActorUpdates,
    LatestBufferCheckpointCallback,
    SaveBestExtras,
    SeededEvalCallback,
)
from agents.training.models import (
    configured_buffer_size,
    grow_replay_buffer,
    planned_timesteps,
    replay_buffer_size,
    scale_action_layer,
)
from agents.training.rundir import CHECKPOINT_PREFIX, Checkpoint, RunDirError, _write_json, save_final, utc_now
from uvdms_gym.residual import ControllerFactory, FilterFactory
from uvdms_gym.utils.provenance import git_info, package_versions

Factories = tuple[ControllerFactory | None, FilterFactory | None, ControllerFactory | None]
"""``(base_factory, filter_factory, teacher_factory)`` (:func:`agents.training.composition.composition_factories`)."""


@dataclasses.dataclass
class TrainingSegment:
    """One segment of a run: its inputs, and what the steps build (envs, model, record).

    Attributes:
        run_dir: The run directory (exists, with ``config.yml`` and ``meta.json``).
        cfg: The run's configuration.
        env_id: Environment id.
        seed: The run's base seed.
        gym_packages: Packages imported so that the env id is registered.
        timesteps: Steps of this segment.
        command: The equivalent command line (``command.txt``).
        checkpoint: The checkpoint a resume continues from (``None``: a fresh run).
        vec_env: Vectorised env type.
        verbose: SB3 verbosity.
        factories: The composition's base, filter and teacher factories.
    """

    run_dir: Path
    cfg: TrainConfig
    env_id: str
    seed: int
    gym_packages: tuple[str, ...]
    timesteps: int
    command: list[str]
    checkpoint: Checkpoint | None
    vec_env: str
    verbose: int
    factories: Factories = (None, None, None)
    venv: VecEnv | None = dataclasses.field(default=None, init=False)
    eval_venv: VecEnv | None = dataclasses.field(default=None, init=False)
    model: BaseAlgorithm | None = dataclasses.field(default=None, init=False)
    meta: dict[str, Any] = dataclasses.field(default_factory=dict, init=False)
    record: dict[str, Any] = dataclasses.field(default_factory=dict, init=False)

    @property
    def index(self) -> int:
        """This segment's number (0 for a fresh run)."""
        return int(self.record["index"])

    @property
    def start_timesteps(self) -> int:
        """The model's step count when the segment starts."""
        return self.checkpoint.num_timesteps if self.checkpoint else 0

    def run(
        self, progress: bool, extra_callbacks: Sequence[BaseCallback] = (), after_eval: Sequence[BaseCallback] = ()
    ) -> None:
        """Run the steps in order; the record is closed (and the envs) whatever happens."""
        self.start_record()
        start = time.perf_counter()
        try:
            self.make_envs()
            self.make_model()
            callbacks = self.make_callbacks(extra_callbacks, after_eval)
            self.learn(callbacks, progress)
        except KeyboardInterrupt:
            if self.model is not None:
                self.save()
            self.record["status"] = "interrupted"
            raise
        except BaseException as exc:
            self.record["status"] = "failed"
            self.record["error"] = f"{type(exc).__name__}: {exc}"
            raise
        finally:
            self.finish(time.perf_counter() - start)

    # -- steps ----------------------------------------------------------------------------------------
    def start_record(self) -> None:
        """Append the command and the segment's record (seeds, composition, versions) to the run's files."""
        self.meta = json.loads((self.run_dir / "meta.json").read_text(encoding="utf-8"))
        segment = len(self.meta["segments"])
        if segment >= MAX_SEGMENTS:
            raise RunDirError(f"{self.run_dir}: too many segments for the seed scheme ({MAX_SEGMENTS} at most)")
        with (self.run_dir / "command.txt").open("a", encoding="utf-8") as f:
            f.write(shlex.join(self.command) + "\n")
        (self.run_dir / "monitor").mkdir(exist_ok=True)
        cfg, checkpoint = self.cfg, self.checkpoint
        base_factory, filter_factory, teacher_factory = self.factories
        self.record = {
            "index": segment,
            "command": shlex.join(self.command),
            "resumed_from": str(checkpoint.model.relative_to(self.run_dir)) if checkpoint else None,
            "start_num_timesteps": checkpoint.num_timesteps if checkpoint else 0,
            "requested_timesteps": self.timesteps,
            "model_seed": train_env_seed(self.seed, segment, 0),
            "train_env_seeds": [train_env_seed(self.seed, segment, i) for i in range(cfg.n_envs)],
            "eval_env_seeds": [eval_env_seed(self.seed, i) for i in range(cfg.n_eval_envs)],
            "vec_env": self.vec_env,
            "action_composition": {
                **cfg.composition.to_record(),
                "base_factory": repr(base_factory) if base_factory is not None else None,
                "filter_factory": repr(filter_factory) if filter_factory is not None else None,
                "teacher_factory": repr(teacher_factory) if teacher_factory is not None else None,
            },
            "torch_num_threads": torch.get_num_threads(),
            "torch_update_threads": update_threads(cfg.n_envs, self.vec_env, not is_off_policy(cfg.algo)),
            "versions": package_versions(),
            "git": git_info(),
            "started_utc": utc_now(),
            "status": "running",
        }
        self.meta["segments"].append(self.record)
        _write_json(self.run_dir / "meta.json", self.meta)

    def env_factories(self) -> tuple[list[EnvFactory], list[EnvFactory]]:
        """The training envs' and the evaluation envs' factories (monitor files per segment and env)."""
        cfg = self.cfg
        base_factory, filter_factory, teacher_factory = self.factories
        composed = {
            "base_factory": base_factory,
            "residual_scale": cfg.residual_scale if base_factory is not None else None,
            "residual_penalty": cfg.residual_penalty if base_factory is not None else 0.0,
            "residual_observation": cfg.residual_observation if base_factory is not None else "base",
            "residual_space": cfg.residual_space if base_factory is not None else "full",
            "filter_factory": filter_factory,
            "navigation_filter": cfg.navigation_filter,
            "frame_stack": cfg.frame_stack,
            "action_history": cfg.action_history,
            "obstacle_features": cfg.obstacle_features,
            "tracking_features": cfg.tracking_features,
        }
        # the teacher labels training states only: the evaluation callback needs no labels
        train = self._factories(
            "train",
            [cfg.variant_kwargs(i) for i in range(cfg.n_envs)],
            scalar_info=True,
            **composed,
            teacher_factory=teacher_factory,
        )
        evaluation = self._factories("eval", [self.eval_kwargs] * cfg.n_eval_envs, **composed, episode_metrics=True)
        return train, evaluation

    def _factories(self, kind: str, env_kwargs: list[dict[str, Any]], **options: Any) -> list[EnvFactory]:
        """One env factory of a kind (``train`` or ``eval``) per ``env_kwargs``, each with its own monitor file."""
        cfg, monitor = self.cfg, self.run_dir / "monitor"
        return [
            EnvFactory(
                self.env_id,
                kwargs,
                self.gym_packages,
                str(monitor / f"seg{self.index}_{kind}_{i}"),
                cfg.max_episode_steps,
                cfg.alive_bonus,
                cfg.action_scale,
                **options,
            )
            for i, kwargs in enumerate(env_kwargs)
        ]

    @property
    def eval_kwargs(self) -> dict[str, Any]:
        """The evaluation envs' ``gymnasium.make`` keyword arguments (the first of ``env_variants``, if any)."""
        return {**self.cfg.variant_kwargs(0), **self.cfg.eval_env_kwargs}

    def make_envs(self) -> None:
        """The training vector env and the evaluation env; a bad ``env_kwargs`` value is a :class:`ConfigError`."""
        train, evaluation = self.env_factories()
        try:
            self.venv = make_vec_env(train, self.vec_env)
            self.eval_venv = DummyVecEnv(evaluation)
        except Exception as exc:  # a bad --env-kwargs value surfaces here: report it as a config error
            variants = f" and env_variants {self.cfg.env_variants}" if self.cfg.env_variants else ""
            raise ConfigError(
                f"cannot create {self.env_id} with env_kwargs {dict(self.cfg.env_kwargs)}{variants} "
                f"(eval: {self.eval_kwargs}): {type(exc).__name__}: {exc}"
            ) from exc

    def make_model(self) -> None:
        """A new model (fresh run) or the checkpoint's (resume), with VecNormalize on both envs when configured."""
        if self.checkpoint is None:
            self._new_model()
        else:
            self._load_model(self.checkpoint)
        cfg, model = self.cfg, self.model
        if is_off_policy(cfg.algo):
            self.record["replay_buffer_size"] = int(model.replay_buffer.buffer_size * model.replay_buffer.n_envs)
        self.record["planned_timesteps"] = planned_timesteps(model, cfg, self.timesteps)
        normalize_kwargs = cfg.normalize_kwargs()
        if normalize_kwargs is not None:
            self.eval_venv = VecNormalize(
                self.eval_venv,
                training=False,
                norm_reward=False,
                **{k: v for k, v in normalize_kwargs.items() if k != "norm_reward"},
            )
        formats = ["csv", "tensorboard"] + (["stdout"] if self.verbose else [])
        model.set_logger(configure(str(self.log_dir), formats))

    @property
    def log_dir(self) -> Path:
        """``logs/seg<k>/``: SB3's progress.csv, TensorBoard events, evaluations.npz."""
        return self.run_dir / "logs" / f"seg{self.index}"

    def _new_model(self) -> None:
        cfg = self.cfg
        normalize_kwargs = cfg.normalize_kwargs()
        if normalize_kwargs is not None:
            self.venv = VecNormalize(self.venv, **normalize_kwargs)
        kwargs = cfg.sb3_hyperparams()
        if is_off_policy(cfg.algo):
            kwargs["buffer_size"] = replay_buffer_size(configured_buffer_size(cfg), cfg.n_envs, self.timesteps)
        if cfg.noise_type is not None:
            kwargs["action_noise"] = cfg.action_noise(self.venv.action_space)
        self.model = ALGOS[cfg.algo](
            cfg.policy,
            self.venv,
            policy_kwargs=cfg.sb3_policy_kwargs(),
            seed=self.record["model_seed"],
            verbose=self.verbose,
            **kwargs,
        )
        if cfg.action_init_scale is not None:
            scale_action_layer(self.model, cfg.action_init_scale)

    def _load_model(self, checkpoint: Checkpoint) -> None:
        cfg = self.cfg
        if checkpoint.vecnormalize is not None:
            self.venv = VecNormalize.load(str(checkpoint.vecnormalize), self.venv)
            self.venv.training = True
        with old_pickles():  # a checkpoint written before 0.3.0 names its policy class by the old module path
            model = ALGOS[cfg.algo].load(str(checkpoint.model), env=self.venv, print_system_info=False)
        self.model = model
        model.verbose = self.verbose
        model.set_random_seed(self.record["model_seed"])
        if is_off_policy(cfg.algo):
            if checkpoint.replay_buffer is not None:
                model.load_replay_buffer(str(checkpoint.replay_buffer))
            else:
                warnings.warn(
                    f"{checkpoint.model.name} has no saved replay buffer (save_replay_buffer: false): "
                    "training continues from an empty buffer",
                    stacklevel=2,
                )
            self.record["replay_buffer_loaded"] = checkpoint.replay_buffer is not None
            grow_replay_buffer(
                model,
                replay_buffer_size(configured_buffer_size(cfg), cfg.n_envs, self.start_timesteps + self.timesteps),
            )

    def make_callbacks(
        self, extra_callbacks: Sequence[BaseCallback] = (), after_eval: Sequence[BaseCallback] = ()
    ) -> list[BaseCallback]:
        """Checkpoints, the seeded evaluation (learning curve, best model), thread and algorithm callbacks, extras."""
        cfg, model = self.cfg, self.model
        callbacks: list[BaseCallback] = []
        if cfg.checkpoint_freq > 0:
            callbacks.append(
                LatestBufferCheckpointCallback(
                    save_freq=max(cfg.checkpoint_freq // cfg.n_envs, 1),
                    save_path=str(self.run_dir / "checkpoints"),
                    name_prefix=CHECKPOINT_PREFIX,
                    save_replay_buffer=cfg.save_replay_buffer,
                    save_vecnormalize=True,
                )
            )
        if cfg.eval_freq > 0:
            callbacks.append(self._eval_callback(after_eval))
        if self.record["torch_update_threads"] > 1:  # the envs idle during an on-policy update (agents.common.threads)
            callbacks.append(UpdateThreads(self.record["torch_update_threads"]))
        if isinstance(model, PPOLagrangian):
            callbacks.append(LagrangianHistory(self.run_dir / HISTORY_FILE, self.index))
        if cfg.actor_warmup_steps > model.num_timesteps:
            callbacks.append(DelayActorUpdates(cfg.actor_warmup_steps))
        callbacks.extend(extra_callbacks)
        return callbacks

    def _eval_callback(self, after_eval: Sequence[BaseCallback]) -> SeededEvalCallback:
        cfg, run_dir = self.cfg, self.run_dir
        eval_callback = SeededEvalCallback(
            self.eval_venv,
            eval_seed=eval_env_seed(self.seed, 0),
            learning_curve=LearningCurve.resume(
                run_dir / LEARNING_CURVE_FILE, self.env_id, self.seed, self.start_timesteps
            ),
            segment=self.index,
            callback_on_new_best=SaveBestExtras(run_dir, self.index),
            callback_after_eval=CallbackList(list(after_eval)) if after_eval else None,
            n_eval_episodes=cfg.n_eval_episodes,
            eval_freq=max(cfg.eval_freq // cfg.n_envs, 1),
            log_path=str(self.log_dir),
            best_model_save_path=str(run_dir),
            deterministic=True,
            verbose=self.verbose,
        )
        best_file = run_dir / "best_model.json"
        if best_file.is_file():
            best = json.loads(best_file.read_text(encoding="utf-8")).get("mean_reward")
            if best is not None:
                eval_callback.best_mean_reward = float(best)
        return eval_callback

    def learn(self, callbacks: list[BaseCallback], progress: bool) -> None:
        """Train for the segment's steps, then save the final model (and replay buffer)."""
        self.model.learn(
            total_timesteps=self.timesteps,
            callback=CallbackList(callbacks),
            reset_num_timesteps=self.checkpoint is None,
            progress_bar=progress,
        )
        self.save()
        self.record["status"] = "completed"

    def save(self) -> None:
        """``final_model.zip`` and its companions (:func:`agents.training.rundir.save_final`)."""
        save_final(self.run_dir, self.model, self.cfg.save_replay_buffer and is_off_policy(self.cfg.algo))

    def finish(self, wall_time_s: float) -> None:
        """Close the segment's record (steps, time) and the envs and the logger."""
        model = self.model
        self.record["end_num_timesteps"] = int(model.num_timesteps) if model is not None else None
        self.record["finished_utc"] = utc_now()
        self.record["wall_time_s"] = round(wall_time_s, 3)
        _write_json(self.run_dir / "meta.json", self.meta)
        for env in (self.venv, self.eval_venv):
            if env is not None:
                env.close()
        if model is not None and getattr(model, "_logger", None) is not None:
            model.logger.close()  # progress.csv and TensorBoard files
