"""Stable-Baselines3 callbacks of :mod:`agents.training.train`: checkpoints, seeded evaluation, best-model extras.

They extend SB3's ``CheckpointCallback`` and ``EvalCallback`` (the ones RL Zoo uses too) with what the
project's run directories need: one replay-buffer checkpoint kept instead of all of them, evaluation envs
reseeded before every evaluation (and their benchmark metrics recorded as the learning curve,
:mod:`agents.common.learning_curve`), and the best model's VecNormalize statistics and step count saved with it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback, EvalCallback

from agents.common.learning_curve import INFO_KEY, LearningCurve, curve_point
from agents.training.rundir import _write_json
from uvdms_gym.seeds import check_not_test


class LatestBufferCheckpointCallback(CheckpointCallback):
    """``CheckpointCallback`` that keeps only the newest replay-buffer checkpoint (each holds the whole buffer)."""

    def _on_step(self) -> bool:
        result = super()._on_step()
        if self.save_replay_buffer and self.n_calls % self.save_freq == 0:
            newest = Path(self._checkpoint_path("replay_buffer_", extension="pkl"))
            for old in Path(self.save_path).glob(f"{self.name_prefix}_replay_buffer_*_steps.pkl"):
                if old != newest:
                    old.unlink()
        return result


class SeededEvalCallback(EvalCallback):
    """``EvalCallback`` that reseeds the evaluation envs before every evaluation (same episodes each time).

    With a ``learning_curve``, every evaluation also adds a point to it (:mod:`agents.common.learning_curve`): the
    benchmark's metrics of the evaluation episodes, which the evaluation envs' :class:`EpisodeMetrics` wrapper
    puts into each episode's last ``info`` (an evaluation whose episodes carry none adds no point).

    Args:
        *args: ``EvalCallback`` arguments.
        eval_seed: Seed passed to ``eval_env.seed`` before each evaluation (env ``i`` gets ``eval_seed + i``): never a
            test seed of :mod:`uvdms_gym.seeds` (training runs pass :func:`agents.common.envs.eval_env_seed`, a
            training seed).
        learning_curve: Where the evaluations' metrics are recorded (``None``: not recorded).
        segment: Index of the training segment (recorded in each point).
        **kwargs: ``EvalCallback`` keyword arguments.
    """

    def __init__(
        self, *args: Any, eval_seed: int, learning_curve: LearningCurve | None = None, segment: int = 0, **kwargs: Any
    ) -> None:
        super().__init__(*args, **kwargs)
        n_envs = getattr(self.eval_env, "num_envs", 1)
        check_not_test([eval_seed, eval_seed + n_envs - 1], "the evaluation callback's seeds")
        self.eval_seed = eval_seed
        self.learning_curve = learning_curve
        self.segment = segment
        self._episode_metrics: list[dict[str, Any]] = []

    def _log_success_callback(self, locals_: dict[str, Any], globals_: dict[str, Any]) -> None:
        super()._log_success_callback(locals_, globals_)
        if locals_["done"]:
            metrics = locals_["info"].get(INFO_KEY)
            if metrics is not None:
                self._episode_metrics.append(metrics)

    def _on_step(self) -> bool:
        evaluating = self.eval_freq > 0 and self.n_calls % self.eval_freq == 0
        if evaluating:
            self.eval_env.seed(self.eval_seed)
            self._episode_metrics = []
        continue_training = super()._on_step()
        if evaluating and self.learning_curve is not None and self._episode_metrics:
            point = curve_point(self.num_timesteps, self.segment, self._episode_metrics, self.last_mean_reward)
            self.learning_curve.add(point)
        return continue_training


class SaveBestExtras(BaseCallback):
    """Called by ``EvalCallback`` on a new best model: saves its VecNormalize stats and ``best_model.json``.

    Args:
        run_dir: The run directory.
        segment: Index of the training segment (recorded in ``best_model.json``).
    """

    def __init__(self, run_dir: Path, segment: int) -> None:
        super().__init__()
        self.run_dir = run_dir
        self.segment = segment

    def _on_step(self) -> bool:
        vec_normalize = self.model.get_vec_normalize_env()
        if vec_normalize is not None:
            vec_normalize.save(str(self.run_dir / "best_vecnormalize.pkl"))
        best = float(self.parent.best_mean_reward) if self.parent is not None else None
        _write_json(
            self.run_dir / "best_model.json",
            {"num_timesteps": int(self.num_timesteps), "mean_reward": best, "segment": self.segment},
        )
        return True


class ScaleInitialActions(BaseCallback):
    """Multiplies a fresh model's last action layer by ``scale`` when training starts (``action_init_scale``).

    Named in a config as RL Zoo names callbacks (``callback: [{agents.training.callbacks.ScaleInitialActions:
    {scale: 0.01}}]``), so that ``python -m rl_zoo3.train`` starts from the same near-zero policy as
    :mod:`agents.training.train` (which reads the entry into ``TrainConfig.action_init_scale`` and scales the layer
    right
    after building the model, :func:`agents.training.models.scale_action_layer`). A model that has already trained
    (``num_timesteps > 0``, a resumed run) is left alone.

    Args:
        scale: Factor in (0, 1].
    """

    def __init__(self, scale: float) -> None:
        super().__init__()
        from agents.common.wrappers import is_unit_scale

        if not is_unit_scale(scale):
            raise ValueError(f"ScaleInitialActions: scale must be in (0, 1], got {scale}")
        self.scale = float(scale)

    def _init_callback(self) -> None:
        from agents.training.models import scale_action_layer

        if self.model.num_timesteps == 0:
            scale_action_layer(self.model, self.scale)

    def _on_step(self) -> bool:
        return True


class DelayActorUpdates(BaseCallback):
    """Keeps an off-policy learner's actor fixed until ``steps`` environment steps (``actor_warmup_steps``).

    A critic burn-in (Silver et al., "Residual Policy Learning", 2018): from ``learning_starts`` the critic learns
    the value of the behaviour it sees, while the actor, and with it the behaviour, stays the initial one (with
    ``action_init_scale``: a near-zero action, i.e. the base controller alone for a residual agent, plus the
    exploration noise). An actor that climbs the gradient of an untrained critic drives the behaviour toward
    the action bounds within a few thousand steps (for a residual agent, into contacts that the base alone
    avoids). The actor's optimizer skips its ``step`` while ``model.num_timesteps < steps`` (the loss is still
    computed, so the algorithm's code path is unchanged); the target networks follow an unchanged actor. A
    resumed run past ``steps`` is unaffected. Named in a config as RL Zoo names callbacks
    (``callback: [{agents.training.callbacks.DelayActorUpdates: {steps: 20000}}]``).

    Args:
        steps: Environment steps before the actor's first update (>= 0).

    Raises:
        ValueError: A negative or non-integer ``steps``; at training start, a model without ``actor.optimizer``
            (not an off-policy actor-critic algorithm).
    """

    def __init__(self, steps: int) -> None:
        super().__init__()
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
            raise ValueError(f"DelayActorUpdates: steps must be an integer >= 0, got {steps!r}")
        self.steps = steps
        self.skipped = 0
        """Actor updates skipped so far."""

    def _init_callback(self) -> None:
        optimizer = getattr(getattr(self.model, "actor", None), "optimizer", None)
        if optimizer is None:
            raise ValueError(
                f"actor_warmup_steps needs an off-policy actor-critic model, not {type(self.model).__name__}"
            )
        if self.model.num_timesteps >= self.steps or getattr(optimizer, "_uvdms_delayed", False):
            return
        step = optimizer.step
        model = self.model

        def delayed_step(*args: Any, **kwargs: Any) -> Any:
            if model.num_timesteps < self.steps:
                self.skipped += 1
                return None
            return step(*args, **kwargs)

        optimizer.step = delayed_step
        optimizer._uvdms_delayed = True

    def _on_step(self) -> bool:
        return True
