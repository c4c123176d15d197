"""DAgger: imitate a teacher's command (or its correction of a residual base) on the states the learner visits.

Imitation learning with dataset aggregation (Ross, Gordon & Bagnell, "A Reduction of Imitation Learning and
Structured Prediction to No-Regret Online Learning", AISTATS 2011), in its online form: the learner's own
deterministic policy plus Gaussian exploration noise acts (DAgger with ``beta = 0``, the noise as in DART,
Laskey et al., CoRL 2017), every visited state is labelled with the teacher's action there, all labelled
states stay in a replay buffer, and each gradient step fits the policy to a batch of them by least squares::

    loss = mean((pi(s) - a_teacher(s))^2)

With no base (``--residual none``: a distilled controller, the network outputs the whole command) the label is
:func:`uvdms_gym.residual.teacher_action`, the teacher's command clipped to the action box, which
:class:`uvdms_gym.residual.TeacherLabel` computes at every state. The teacher may command either action mode (the
training env's), and may be a trained agent (e.g. a shipped residual entry). At evaluation such an agent is the
network alone: no base, no QP, no distance query beyond its observation.

For a residual agent (:mod:`uvdms_gym.residual`) the label is :func:`uvdms_gym.residual.teacher_residual`, the
residual output closest to the teacher's command, which :class:`uvdms_gym.residual.ResidualAction` computes at
every state when it is given a ``teacher_factory`` and reports in ``info[TEACHER_KEY]``; :class:`TeacherReplayBuffer`
stores it with each transition. The teacher never acts on the environment and is not part of the trained agent:
at evaluation the agent is its base plus the learned network, and whatever the teacher did that the base does
not (for CAMPC over plain MPC: the collision rows) has to be in the network's weights.

Everything else is SB3's ``TD3`` (its deterministic actor, exploration noise, rollout collection, checkpoints and
exports); the critics are built but never trained, and the reward is not used for learning (only for the
evaluation callback's reports). ``uvdms train`` builds the teacher named by the ``teacher`` hyperparameter
(``--hyperparams teacher=campc``), with its collision thresholds moved outward by ``teacher_margin``; this module
only learns from the labels.
"""

# NOTE: no ``from __future__ import annotations`` here: agents.config.schema validates YAML keys against the evaluated
# annotations of ``DAgger.__init__`` (as for agents.algos.td3_prior).
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3 import TD3
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.type_aliases import GymEnv, Schedule
from stable_baselines3.common.vec_env import VecNormalize
from stable_baselines3.td3.policies import TD3Policy
from torch.nn import functional as F

TEACHER_INFO_KEY = "teacher_residual"
"""``info`` key of the label (``uvdms_gym.residual.TEACHER_KEY``; a test checks that they agree)."""
DEFAULT_TEACHER = "campc"
"""The teacher ``uvdms train`` builds when the configuration names none."""
PREVIEW_ROWS = 3
"""Rows of the reference preview, one per ``uvdms_gym.envs.base.PREVIEW_TIMES`` (a test checks; importing the
environments here would load PyBullet on every ``agents`` command)."""
PREVIEW_SIZE = 18
"""Values of the reference preview at the start of every UVDMS observation (``uvdms_gym.envs.base``)."""
REST_TOLERANCE = 1e-4
"""Largest difference between preview rows (scaled as observed) of a reference at rest."""


def teacher_margin(hyperparams: Mapping[str, Any]) -> float:
    """The teacher's collision margin a DAgger configuration names (``teacher_margin``, m, default 0).

    Raises:
        ValueError: ``teacher_margin`` is not a finite number >= 0.
    """
    return _metres(hyperparams, "teacher_margin")


def teacher_outer_margin(hyperparams: Mapping[str, Any]) -> float:
    """The teacher's outer-obstacle margin a DAgger configuration names (``teacher_outer_margin``, m, default 0).

    Raises:
        ValueError: ``teacher_outer_margin`` is not a finite number >= 0.
    """
    return _metres(hyperparams, "teacher_outer_margin")


def hard_fraction(hyperparams: Mapping[str, Any]) -> float:
    """The share of each batch's hardest samples whose loss counts twice (``hard_fraction``, default 0).

    Raises:
        ValueError: ``hard_fraction`` is not a number in [0, 1].
    """
    value = hyperparams.get("hard_fraction", 0.0)
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 <= value <= 1.0:
        raise ValueError(f"hard_fraction must be a number in [0, 1], got {value!r}")
    return float(value)


def evasion_weight(hyperparams: Mapping[str, Any]) -> float:
    """The weight of the evasion term of the imitation loss (``evasion_weight``, default 0: none).

    Raises:
        ValueError: ``evasion_weight`` is not a finite number >= 0.
    """
    return _non_negative(hyperparams, "evasion_weight")


def hold_weight(hyperparams: Mapping[str, Any]) -> float:
    """The extra weight of the samples whose reference is at rest (``hold_weight``, default 0: none).

    Raises:
        ValueError: ``hold_weight`` is not a finite number >= 0.
    """
    return _non_negative(hyperparams, "hold_weight")


def reference_at_rest(observations: np.ndarray) -> np.ndarray:
    """Which observations (rows, as the environment gave them) see their reference at rest: a transport's hold.

    Every UVDMS observation begins with its reference preview (``uvdms_gym.envs.base``): :data:`PREVIEW_ROWS`
    rows of ``y_ref(t + h) - y``. The reference is at rest over the preview when every row equals the first to
    within :data:`REST_TOLERANCE` (a frame stack's first rows are its oldest frame's).

    Raises:
        ValueError: The observations are not rows of at least :data:`PREVIEW_SIZE` values.
    """
    observations = np.asarray(observations)
    if observations.ndim != 2 or observations.shape[1] < PREVIEW_SIZE:
        raise ValueError(
            f"hold_weight needs the observations of a UVDMS environment, which begin with the {PREVIEW_SIZE} values "
            f"of the reference preview; got observations of shape {observations.shape}"
        )
    rows = observations[:, :PREVIEW_SIZE].reshape(len(observations), PREVIEW_ROWS, -1)
    return np.abs(rows - rows[:, :1]).max(axis=(1, 2)) <= REST_TOLERANCE


def _metres(hyperparams: Mapping[str, Any], key: str) -> float:
    """``hyperparams[key]`` (default 0) as a finite number of metres >= 0."""
    return _non_negative(hyperparams, key, " (metres)")


def _non_negative(hyperparams: Mapping[str, Any], key: str, unit: str = "") -> float:
    """``hyperparams[key]`` (default 0) as a finite number >= 0 (``unit`` names its unit in the error)."""
    value = hyperparams.get(key, 0.0)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
        raise ValueError(f"{key} must be a finite number >= 0{unit}, got {value!r}")
    return float(value)


def teacher_name(hyperparams: Mapping[str, Any]) -> str:
    """The teacher a DAgger configuration names (``teacher``, default :data:`DEFAULT_TEACHER`).

    Raises:
        ValueError: ``teacher`` is not a non-empty string.
    """
    name = hyperparams.get("teacher", DEFAULT_TEACHER)
    if not isinstance(name, str) or not name:
        raise ValueError(f"teacher must be the name of a velocity-mode baseline (e.g. campc), got {name!r}")
    return name


class TeacherReplayBuffer(ReplayBuffer):
    """SB3's ``ReplayBuffer`` that also stores the teacher's label of each transition's observation.

    ``add`` reads the label from each env's ``info[TEACHER_INFO_KEY]`` (the label of the observation the action
    was taken on, see :class:`uvdms_gym.residual.ResidualAction`); :meth:`sample_labelled` draws observations and
    their labels. Saved and loaded with the rest of the buffer (``save_replay_buffer``).

    Raises:
        ValueError: (``add``) an ``info`` without a label of the action's shape.
    """

    def __init__(
        self,
        buffer_size: int,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        device: th.device | str = "auto",
        n_envs: int = 1,
        optimize_memory_usage: bool = False,
        handle_timeout_termination: bool = True,
    ) -> None:
        super().__init__(
            buffer_size,
            observation_space,
            action_space,
            device=device,
            n_envs=n_envs,
            optimize_memory_usage=optimize_memory_usage,
            handle_timeout_termination=handle_timeout_termination,
        )
        self.labels = np.zeros((self.buffer_size, self.n_envs, self.action_dim), dtype=np.float32)

    def add(
        self,
        obs: np.ndarray,
        next_obs: np.ndarray,
        action: np.ndarray,
        reward: np.ndarray,
        done: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        """Store the transition and the label of ``obs`` from ``infos``."""
        labels = []
        for i, info in enumerate(infos):
            label = info.get(TEACHER_INFO_KEY)
            if label is None or np.shape(label) != (self.action_dim,):
                raise ValueError(
                    f"DAgger needs the teacher's label in info[{TEACHER_INFO_KEY!r}] of shape ({self.action_dim},) "
                    f"(env {i} gave {None if label is None else np.shape(label)}): train with `uvdms train`, which "
                    "builds the teacher named by --hyperparams teacher=... in every training env"
                )
            labels.append(label)
        self.labels[self.pos] = np.asarray(labels, dtype=np.float32)
        super().add(obs, next_obs, action, reward, done, infos)

    def sample_labelled(
        self, batch_size: int, env: VecNormalize | None = None, rest_flags: bool = False
    ) -> tuple[th.Tensor, th.Tensor, np.ndarray | None]:
        """``batch_size`` stored observations (normalised as the policy sees them), their labels and rest flags.

        The flags (with ``rest_flags``, else None) are :func:`reference_at_rest` of the stored, unnormalised
        observations.

        Draws indices as SB3's ``ReplayBuffer.sample`` does (NumPy's global generator, which SB3 seeds).
        """
        upper = self.buffer_size if self.full else self.pos
        # SB3's buffers draw from NumPy's global generator, which SB3's set_random_seed seeds: the same here
        batch_inds = np.random.randint(0, upper, size=batch_size)  # noqa: NPY002
        env_inds = np.random.randint(0, high=self.n_envs, size=(batch_size,))  # noqa: NPY002
        raw = self.observations[batch_inds, env_inds, :]
        obs = self._normalize_obs(raw, env)
        flags = reference_at_rest(raw) if rest_flags else None
        return self.to_torch(obs), self.to_torch(self.labels[batch_inds, env_inds, :]), flags


class DAgger(TD3):
    """SB3's TD3 with the actor fitted to a teacher's labels instead of the critic (see the module).

    Args:
        policy: As ``TD3`` (and every other argument but ``teacher``; ``replay_buffer_class`` is always
            :class:`TeacherReplayBuffer`).
        env: The environment; its ``info`` must carry the teacher's label.
        teacher: Name of the teacher controller, built by ``uvdms train`` (recorded here for the run's record).
        teacher_margin: Metres by which ``uvdms train`` moves the teacher's collision thresholds ``d1`` and ``d2``
            outward (``leaderboard.suite.registry.BaselineFactory``'s ``collision_margin``): the learner imitates a
            teacher that keeps this much clear of the collision zone, which its imitation error then may use.
        teacher_outer_margin: Metres by which ``uvdms train`` moves the teacher's outer-obstacle thresholds
            (``outer_d1``, ``outer_d2``) outward in an environment with obstacles: a teacher that evades earlier
            and wider, so more of the visited states carry an evasion and the learner's lag has room.
        hard_fraction: Hard-example emphasis of the imitation loss: the mean squared error over the batch plus the
            mean over its ``hard_fraction`` largest per-sample errors (0: plain least squares). The teacher's
            evasions are rare, sharp labels among many tracking states; plain least squares fits them last.
        evasion_weight: Weight of the evasion term of the imitation loss (0: none; needs a policy that observes
            the obstacle features, ``obstacle_features: true``, without ``frame_stack``). The term is the squared
            error along each observed obstacle's weighted opening direction, ``sum_k (w_k u_k . (pi(s) -
            a_teacher))^2`` (:func:`uvdms_gym.residual.opening_columns`): zero far from the obstacles, the error of
            the commanded gap rate per unit of ``|G|`` near them. Least squares over 18 commands lets a student
            track well and still miss the one direction that evades (``docs/challenged.md``).
        hold_weight: Extra weight of the samples whose reference is at rest (:func:`reference_at_rest`: a
            transport's hold, where success is judged): each counts ``1 + hold_weight`` times in a weighted mean
            squared error (0: plain least squares). Tried on the obstacle task, it did not make the hold more
            precise there (``docs/challenged.md``).

    Raises:
        ValueError: ``teacher`` is not a non-empty string, ``teacher_margin`` or ``teacher_outer_margin`` not a
            finite number >= 0, ``hard_fraction`` not in [0, 1], ``evasion_weight`` or ``hold_weight`` not a finite
            number >= 0, or another replay buffer class is requested.
    """

    def __init__(
        self,
        policy: str | type[TD3Policy],
        env: GymEnv | str,
        learning_rate: float | Schedule = 1e-3,
        buffer_size: int = 1_000_000,
        learning_starts: int = 0,
        batch_size: int = 256,
        tau: float = 0.005,
        gamma: float = 0.99,
        train_freq: int | tuple[int, str] = 1,
        gradient_steps: int = 1,
        action_noise: ActionNoise | None = None,
        replay_buffer_class: type[ReplayBuffer] | None = None,
        replay_buffer_kwargs: dict[str, Any] | None = None,
        optimize_memory_usage: bool = False,
        n_steps: int = 1,
        policy_delay: int = 1,
        target_policy_noise: float = 0.2,
        target_noise_clip: float = 0.5,
        teacher: str = DEFAULT_TEACHER,
        teacher_margin: float = 0.0,
        teacher_outer_margin: float = 0.0,
        hard_fraction: float = 0.0,
        evasion_weight: float = 0.0,
        hold_weight: float = 0.0,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "auto",
        _init_setup_model: bool = True,
    ) -> None:
        options = {"teacher": teacher, "teacher_margin": teacher_margin, "teacher_outer_margin": teacher_outer_margin}
        options |= {"hard_fraction": hard_fraction, "evasion_weight": evasion_weight, "hold_weight": hold_weight}
        self.check_hyperparams(options)
        if replay_buffer_class not in (None, TeacherReplayBuffer):
            raise ValueError(
                f"DAgger stores its labels in TeacherReplayBuffer, got replay_buffer_class={replay_buffer_class}"
            )
        self.teacher = teacher
        self.teacher_margin, self.teacher_outer_margin = float(teacher_margin), float(teacher_outer_margin)
        self.hard_fraction, self.evasion_weight = float(hard_fraction), float(evasion_weight)
        self.hold_weight = float(hold_weight)
        self._opening: th.Tensor | None = None  # the feature columns of the evasion term (found at the first update)
        super().__init__(
            policy,
            env,
            learning_rate=learning_rate,
            buffer_size=buffer_size,
            learning_starts=learning_starts,
            batch_size=batch_size,
            tau=tau,
            gamma=gamma,
            train_freq=train_freq,
            gradient_steps=gradient_steps,
            action_noise=action_noise,
            replay_buffer_class=TeacherReplayBuffer,
            replay_buffer_kwargs=replay_buffer_kwargs,
            optimize_memory_usage=optimize_memory_usage,
            n_steps=n_steps,
            policy_delay=policy_delay,
            target_policy_noise=target_policy_noise,
            target_noise_clip=target_noise_clip,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs,
            verbose=verbose,
            seed=seed,
            device=device,
            _init_setup_model=_init_setup_model,
        )

    @staticmethod
    def check_hyperparams(hyperparams: Mapping[str, Any]) -> None:
        """Range checks of the keyword arguments of this class (``agents.config.schema`` calls it on a config entry).

        Raises:
            ValueError: ``teacher`` is not a non-empty string, ``teacher_margin`` or ``teacher_outer_margin`` not a
                finite number >= 0, ``hard_fraction`` not in [0, 1], or ``evasion_weight`` or ``hold_weight`` not a
                finite number >= 0.
        """
        teacher_name(hyperparams)
        teacher_margin(hyperparams)
        teacher_outer_margin(hyperparams)
        hard_fraction(hyperparams)
        evasion_weight(hyperparams)
        hold_weight(hyperparams)

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        """``gradient_steps`` least-squares steps of the actor toward the teacher's labels (the module's loss)."""
        self.policy.set_training_mode(True)
        self._update_learning_rate([self.actor.optimizer])
        buffer = self.replay_buffer
        assert isinstance(buffer, TeacherReplayBuffer)
        losses = []
        for _ in range(gradient_steps):
            self._n_updates += 1
            obs, labels, at_rest = buffer.sample_labelled(batch_size, self._vec_normalize_env, bool(self.hold_weight))
            actions = self.actor(obs)
            weights = None if at_rest is None else th.as_tensor(1.0 + self.hold_weight * at_rest, device=self.device)
            loss = self.imitation_loss(actions, labels, weights)
            if self.evasion_weight:
                loss = loss + self.evasion_weight * self.evasion_loss(obs, actions, labels)
            losses.append(loss.item())
            self.actor.optimizer.zero_grad()
            loss.backward()
            self.actor.optimizer.step()
        self.policy.set_training_mode(False)
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/imitation_loss", float(np.mean(losses)))

    def evasion_loss(self, obs: th.Tensor, actions: th.Tensor, labels: th.Tensor) -> th.Tensor:
        """The evasion term (see the class): the batch mean of ``sum_k (w_k u_k . (actions - labels))^2``."""
        columns = self._opening_index(obs.shape[1])
        directions = obs[:, columns]  # (batch, slots, 18): w_k u_k, zero far from every obstacle
        along = th.einsum("bkj,bj->bk", directions, actions - labels)
        return (along**2).sum(dim=1).mean()

    def _opening_index(self, obs_dim: int) -> th.Tensor:
        """The observation columns of the opening directions (``ObstacleFeatureObservation.opening_index``).

        Raises:
            ValueError: The policy does not observe the obstacle features as the training wrapper gives them
                (``obstacle_features: true``, no ``frame_stack`` or ``action_history`` around them).
        """
        if self._opening is None:
            try:
                index = self.env.get_attr("opening_index", [0])[0] if self.env is not None else None
                featured_dim = self.env.get_attr("featured_dim", [0])[0] if self.env is not None else None
            except AttributeError:
                index = featured_dim = None
            if index is None or featured_dim != obs_dim:
                raise ValueError(
                    "evasion_weight needs a policy that observes the obstacle features (obstacle_features: true) "
                    "without frame_stack or action_history"
                )
            self._opening = th.as_tensor(np.asarray(index), device=self.device)
        return self._opening

    def imitation_loss(self, actions: th.Tensor, labels: th.Tensor, weights: th.Tensor | None = None) -> th.Tensor:
        """The mean squared error, plus that of the batch's ``hard_fraction`` hardest samples (see the class).

        With ``weights`` (one per sample) the first term is their weighted mean of the per-sample errors.
        """
        n_hard = int(self.hard_fraction * actions.shape[0])
        if weights is None and n_hard == 0:
            return F.mse_loss(actions, labels)
        per_sample = ((actions - labels) ** 2).mean(dim=1)
        if weights is None:
            loss = F.mse_loss(actions, labels)
        else:
            weights = weights.to(per_sample.dtype)
            loss = (weights * per_sample).sum() / weights.sum()
        return loss if n_hard == 0 else loss + th.topk(per_sample, n_hard).values.mean()
