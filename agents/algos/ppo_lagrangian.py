"""PPO-Lagrangian: PPO under a per-episode budget on the safety cost ``info["cost"]``, with a Lagrange multiplier.

The constrained problem is ``max_pi J_r(pi)`` subject to ``J_c(pi) <= d``, with ``J_c`` the expected *undiscounted*
sum of the per-step cost over an episode and ``d`` the budget ``cost_limit``. Its Lagrangian relaxation
``min_{lambda >= 0} max_pi J_r - lambda (J_c - d)`` is solved by alternating a PPO step on the policy with a
projected gradient step on ``lambda``. Variant: the PPO-Lagrangian of Ray, Achiam and Amodei (2019), "Benchmarking
Safe Exploration in Deep Reinforcement Learning" (OpenAI safety-starter-agents), as in Safety-Gymnasium's
reference algorithms (OmniSafe's ``PPOLag``), with a plain (not Adam) dual step:

* Cost. The per-step cost is read from ``info["cost"]`` (the Safety-Gymnasium convention; the uvdms envs report
  ``cost_contact + cost_zone``). It is taken from the ``infos`` of the vector env the trainer steps, above any
  ``VecNormalize`` (which normalises rewards and observations, never ``infos``), so it is the raw cost; with
  ``subproc``/``hybrid`` vector envs it reaches the trainer with the step's ``infos``
  (:class:`agents.common.wrappers.ScalarInfo` keeps scalar entries), with ``--vec-env rollout`` with each env's part of
  the rollout (:mod:`agents.common.rollouts`; the merged steps are recorded in step order). An env without
  ``info["cost"]`` is an error.
* Cost critic. The policy (:class:`CostActorCriticPolicy`) is SB3's ``ActorCriticPolicy`` plus a separate cost
  value network ``V_c`` (the ``vf`` layer sizes of ``net_arch``, no layers shared). Cost advantages ``A_c`` and
  returns come from the same GAE (``gamma``, ``gae_lambda``) as the reward ones, truncated episodes bootstrapped
  with ``V_c`` of the terminal observation as SB3 does for rewards. ``V_c`` is fitted to the cost returns after
  PPO's update (``n_epochs`` passes of ``batch_size`` minibatches, loss ``vf_coef * MSE``, the policy's optimizer,
  gradients clipped at ``max_grad_norm``); its minibatches come from a generator of their own, seeded with the
  model, so fitting it leaves PPO's random draws alone.
* Multiplier. After every rollout, before the policy update: ``lambda <- max(0, lambda + lagrangian_lr * (J_c -
  cost_limit))``, where ``J_c`` is the mean summed raw cost of the episodes that *ended* in the rollout (an episode
  spanning rollouts counts whole, in the rollout it ends in). A rollout in which no episode ended leaves
  ``lambda`` unchanged. The step is plain projected gradient ascent: its size reads directly as lambda per unit of
  cost excess, and it is easy to recompute from a run's episodes (the tests do); safety-starter-agents (Adam on a
  softplus parameter) and OmniSafe (Adam) take adaptive steps on the same objective.
* Policy update. PPO's clipped surrogate on ``A = (A_r - lambda A_c) / (1 + lambda)``, with ``A_r`` standardised
  over the rollout and ``A_c`` centred (as Ray et al. and OmniSafe do): ``lambda`` then weighs one standard
  deviation of reward advantage against one unit of cost advantage, whatever the reward's scale (VecNormalize's
  ``norm_reward`` changes that scale during training). ``normalize_advantage`` defaults to ``False`` here: SB3's
  per-minibatch normalisation would undo the ``1 / (1 + lambda)`` scaling (the direction of the step stays the
  same). The reward value function is PPO's, on the reward returns.

Why a cost critic and not reward shaping ``r - lambda c``: VecNormalize's ``norm_reward`` scales rewards by a
running return statistic, so a shaped reward would mix the cost into that statistic and move the reward scale
with ``lambda``; with separate critics ``lambda`` changes only the weighting of two advantages the rollout already
holds, and both value functions stay stationary in ``lambda``. SB3's classes need no change: the buffer is SB3's
``RolloutBuffer`` (the cost arrays live beside it), PPO's ``train`` runs unmodified on the combined advantages.

State. ``lagrangian_multiplier`` (and ``n_dual_updates``) are attributes of the model, saved in the SB3 zip's JSON
``data``: checkpoints, ``final_model.zip`` and ``--resume`` continue with the same ``lambda``. The SB3 logger
(``progress.csv``, TensorBoard) records ``lagrangian/lambda``, ``lagrangian/cost_limit``,
``lagrangian/episode_cost`` (``J_c``), ``lagrangian/n_episodes`` and ``train/cost_value_loss``;
:class:`LagrangianHistory` appends one row per rollout to ``lagrangian.csv`` in the run directory
(:mod:`agents.training.train` adds it). Only ``MlpPolicy`` (Box observations) is provided.
"""

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import RolloutBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.policies import ActorCriticPolicy, BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, Schedule
from stable_baselines3.common.utils import obs_as_tensor
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvStepReturn
from torch import nn
from torch.nn import functional as F

from agents.algos.lagrangian import (  # noqa: F401 (the pure pieces, importable from here as before)
    ADVANTAGE_EPS,
    COST_KEY,
    HISTORY_FIELDS,
    HISTORY_FILE,
    DualUpdate,
    LagrangianHistory,
    check_lagrangian_args,
    dual_ascent,
    gae,
    lagrangian_advantages,
    read_history,
    step_costs,
)
from agents.common.rollouts import RolloutPPO, is_rollout_env

# NOTE: no ``from __future__ import annotations`` here: agents.config.schema validates YAML keys against the evaluated
# annotations of PPOLagrangian.__init__ (as it does for SB3's classes).

HIDDEN_GAIN = math.sqrt(2.0)
"""Orthogonal-init gain of the cost critic's hidden layers (SB3's value for the value network's MLP)."""
OUTPUT_GAIN = 1.0
"""Orthogonal-init gain of the cost critic's output layer (SB3's value for ``value_net``)."""


# ------------------------------------------------------------------------------------------------------
# Policy with a cost critic
# ------------------------------------------------------------------------------------------------------
class CostActorCriticPolicy(ActorCriticPolicy):
    """SB3's ``ActorCriticPolicy`` plus a cost value network ``cost_net`` (same keyword arguments).

    ``cost_net`` has the layer sizes of the value branch (``net_arch["vf"]``, or the list ``net_arch``) and its
    own weights, and reads the value branch's features. Acting (``forward``, ``predict``) is the parent's, so a
    trained agent evaluates and exports like a PPO agent (the export holds ``cost_net`` too).
    """

    cost_net: nn.Sequential

    def _build(self, lr_schedule: Schedule) -> None:
        super()._build(lr_schedule)
        arch = self.net_arch.get("vf", []) if isinstance(self.net_arch, dict) else list(self.net_arch)
        # built on a fork of torch's generator, so the actor, the value net and the rollouts draw what PPO's do
        with th.random.fork_rng(devices=[]):
            layers: list[nn.Module] = []
            width = self.features_dim
            for size in arch:
                layers += [nn.Linear(width, size), self.activation_fn()]
                width = size
            layers.append(nn.Linear(width, 1))
            self.cost_net = nn.Sequential(*layers)
            if self.ortho_init:
                for layer in layers[:-1]:
                    self.init_weights(layer, gain=HIDDEN_GAIN)
                self.init_weights(layers[-1], gain=OUTPUT_GAIN)
        self.optimizer = self.optimizer_class(self.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs)

    def predict_costs(self, obs: th.Tensor) -> th.Tensor:
        """Cost values ``V_c(obs)``, shape ``(batch, 1)``."""
        features = BasePolicy.extract_features(self, obs, self.vf_features_extractor)
        return self.cost_net(features)


# ------------------------------------------------------------------------------------------------------
# The cost tap: the vector env as collect_rollouts sees it
# ------------------------------------------------------------------------------------------------------
class _CostTap(VecEnvWrapper):
    """Passes every call through to the training env and records each step's ``info["cost"]``.

    Holds the rollout's costs, the truncated steps (for bootstrapping) and the per-env running episode sums.
    """

    def __init__(self, venv: VecEnv) -> None:
        super().__init__(venv)
        self.episode_sums = np.zeros(self.num_envs, dtype=np.float64)
        self.start(0)

    def start(self, n_steps: int) -> None:
        """Begin a rollout of ``n_steps`` steps per env."""
        self.costs = np.zeros((n_steps, self.num_envs), dtype=np.float32)
        self.step_index = 0
        self.truncations: list[tuple[int, int, np.ndarray]] = []
        self.finished: list[float] = []

    def reset(self) -> Any:
        """Reset the wrapped env (collect_rollouts never calls it; for completeness)."""
        self.episode_sums[:] = 0.0
        return self.venv.reset()

    def step_wait(self) -> VecEnvStepReturn:
        """Step the wrapped env and record the step's costs and ended episodes."""
        obs, rewards, dones, infos = self.venv.step_wait()
        self.record(infos, dones)
        return obs, rewards, dones, infos

    def record(self, infos: list[dict[str, Any]], dones: np.ndarray) -> None:
        """Record one vector step's costs and ended episodes (from ``step_wait``, or a merged parallel rollout)."""
        costs = step_costs(infos)
        self.costs[self.step_index] = costs
        self.episode_sums += costs
        for i in np.flatnonzero(dones):
            self.finished.append(float(self.episode_sums[i]))
            self.episode_sums[i] = 0.0
            terminal = infos[i].get("terminal_observation")
            if terminal is not None and infos[i].get("TimeLimit.truncated", False):
                self.truncations.append((self.step_index, int(i), terminal))
        self.step_index += 1


# ------------------------------------------------------------------------------------------------------
# The algorithm
# ------------------------------------------------------------------------------------------------------
class PPOLagrangian(RolloutPPO):
    """PPO-Lagrangian (Ray et al. 2019) on ``info["cost"]``: see the module docstring for the variant.

    Args:
        policy: ``"MlpPolicy"`` or a :class:`CostActorCriticPolicy` subclass.
        env: The training environment; every step's ``info`` must hold ``cost``.
        learning_rate: As PPO.
        n_steps: As PPO (also the dual-update period: one update per rollout).
        batch_size: As PPO (also the cost critic's minibatch size).
        n_epochs: As PPO (also the cost critic's passes per rollout).
        gamma: As PPO (also the cost GAE's discount).
        gae_lambda: As PPO (also the cost GAE's factor).
        clip_range: As PPO.
        clip_range_vf: As PPO (the cost critic is not clipped).
        normalize_advantage: SB3's per-minibatch normalisation on top of the Lagrangian advantages; ``False`` by
            default (the reward advantages are standardised per rollout already, see the module docstring).
        ent_coef: As PPO.
        vf_coef: As PPO (also the cost value loss's factor).
        max_grad_norm: As PPO (also for the cost critic).
        use_sde: As PPO.
        sde_sample_freq: As PPO.
        rollout_buffer_class: As PPO.
        rollout_buffer_kwargs: As PPO.
        target_kl: As PPO.
        stats_window_size: As PPO.
        tensorboard_log: As PPO.
        policy_kwargs: As PPO.
        verbose: As PPO.
        seed: As PPO (also seeds the cost critic's minibatch generator).
        device: As PPO.
        cost_limit: Per-episode cost budget ``d`` (undiscounted sum of ``info["cost"]``), >= 0 (default 25, the
            budget of Safety-Gymnasium's benchmarks).
        lagrangian_lr: Step size of the dual ascent, > 0.
        lagrangian_init: Initial multiplier ``lambda``, >= 0.
        _init_setup_model: As PPO.
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {"MlpPolicy": CostActorCriticPolicy}
    policy: CostActorCriticPolicy

    def __init__(
        self,
        policy: str | type[CostActorCriticPolicy],
        env: GymEnv | str,
        learning_rate: float | Schedule = 3e-4,
        n_steps: int = 2048,
        batch_size: int = 64,
        n_epochs: int = 10,
        gamma: float = 0.99,
        gae_lambda: float = 0.95,
        clip_range: float | Schedule = 0.2,
        clip_range_vf: float | Schedule | None = None,
        normalize_advantage: bool = False,
        ent_coef: float = 0.0,
        vf_coef: float = 0.5,
        max_grad_norm: float = 0.5,
        use_sde: bool = False,
        sde_sample_freq: int = -1,
        rollout_buffer_class: type[RolloutBuffer] | None = None,
        rollout_buffer_kwargs: dict[str, Any] | None = None,
        target_kl: float | None = None,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "auto",
        cost_limit: float = 25.0,
        lagrangian_lr: float = 0.01,
        lagrangian_init: float = 0.0,
        _init_setup_model: bool = True,
    ) -> None:
        check_lagrangian_args(
            {"cost_limit": cost_limit, "lagrangian_lr": lagrangian_lr, "lagrangian_init": lagrangian_init}
        )
        self.cost_limit = float(cost_limit)
        self.lagrangian_lr = float(lagrangian_lr)
        self.lagrangian_init = float(lagrangian_init)
        self.lagrangian_multiplier = float(lagrangian_init)
        self.n_dual_updates = 0
        self.last_dual_update: DualUpdate | None = None
        self._cost_tap: _CostTap | None = None
        self._cost_rng = np.random.default_rng(seed)
        self._reward_advantages: np.ndarray | None = None
        self._cost_advantages: np.ndarray | None = None
        self._cost_returns: np.ndarray | None = None
        super().__init__(
            policy,
            env,
            learning_rate=learning_rate,
            n_steps=n_steps,
            batch_size=batch_size,
            n_epochs=n_epochs,
            gamma=gamma,
            gae_lambda=gae_lambda,
            clip_range=clip_range,
            clip_range_vf=clip_range_vf,
            normalize_advantage=normalize_advantage,
            ent_coef=ent_coef,
            vf_coef=vf_coef,
            max_grad_norm=max_grad_norm,
            use_sde=use_sde,
            sde_sample_freq=sde_sample_freq,
            rollout_buffer_class=rollout_buffer_class,
            rollout_buffer_kwargs=rollout_buffer_kwargs,
            target_kl=target_kl,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs,
            verbose=verbose,
            seed=seed,
            device=device,
            _init_setup_model=_init_setup_model,
        )

    @classmethod
    def check_hyperparams(cls, hyperparams: Mapping[str, Any]) -> None:
        """Range checks of the Lagrangian keyword arguments (called by :mod:`agents.config.schema`).

        Raises:
            ValueError: Naming the offending key.
        """
        check_lagrangian_args(hyperparams)

    def _excluded_save_params(self) -> list[str]:
        return [
            *super()._excluded_save_params(),
            "last_dual_update",
            "_cost_tap",
            "_cost_rng",
            "_reward_advantages",
            "_cost_advantages",
            "_cost_returns",
        ]

    def _setup_model(self) -> None:
        super()._setup_model()
        if not isinstance(self.policy, CostActorCriticPolicy):
            raise TypeError(f"PPOLagrangian needs a CostActorCriticPolicy, got {type(self.policy).__name__}")
        if not isinstance(self.observation_space, spaces.Box):
            raise TypeError(f"PPOLagrangian supports Box observations only, got {self.observation_space}")

    def set_random_seed(self, seed: int | None = None) -> None:
        """Seed SB3's generators and the cost critic's minibatch generator."""
        super().set_random_seed(seed)
        if seed is not None:
            self._cost_rng = np.random.default_rng(seed)

    def _setup_learn(
        self,
        total_timesteps: int,
        callback: MaybeCallback = None,
        reset_num_timesteps: bool = True,
        tb_log_name: str = "run",
        progress_bar: bool = False,
    ) -> tuple[int, BaseCallback]:
        env_reset = reset_num_timesteps or self._last_obs is None
        result = super()._setup_learn(total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar)
        if self._cost_tap is None or self._cost_tap.venv is not self.env:
            self._cost_tap = _CostTap(self.env)
        elif env_reset:
            self._cost_tap.episode_sums[:] = 0.0  # SB3 reset the envs: no episode is running
        return result

    # --------------------------------------------------------------------------------------------------
    def collect_rollouts(
        self,
        env: VecEnv,
        callback: BaseCallback,
        rollout_buffer: RolloutBuffer,
        n_rollout_steps: int,
    ) -> bool:
        """PPO's rollout through the cost tap, then the cost GAE and the multiplier update.

        Returns:
            ``False`` if a callback stopped the rollout (nothing is updated then), else ``True``.
        """
        if self._cost_tap is None or self._cost_tap.venv is not env:
            self._cost_tap = _CostTap(env)
        tap = self._cost_tap
        tap.start(n_rollout_steps)
        # a parallel rollout (--vec-env rollout) is not stepped through the tap: its merged steps are recorded
        source = env if is_rollout_env(env) else tap
        if not super().collect_rollouts(source, callback, rollout_buffer, n_rollout_steps):
            return False
        self._cost_gae(rollout_buffer, tap)
        self._dual_update(tap.finished)
        return True

    def _on_merged_step(self, infos: list[dict[str, Any]], dones: np.ndarray) -> None:
        """A merged step of a parallel rollout: record its costs (:meth:`RolloutPPO._on_merged_step`)."""
        assert self._cost_tap is not None
        self._cost_tap.record(infos, dones)

    def _cost_gae(self, buffer: RolloutBuffer, tap: _CostTap) -> None:
        n_steps, n_envs = buffer.buffer_size, buffer.n_envs
        with th.no_grad():
            flat = buffer.observations.reshape((n_steps * n_envs, *buffer.obs_shape))
            values = self.policy.predict_costs(obs_as_tensor(flat, self.device)).cpu().numpy().reshape(n_steps, n_envs)
            last = self.policy.predict_costs(obs_as_tensor(self._last_obs, self.device)).cpu().numpy().flatten()
            costs = tap.costs.copy()
            for step, i, terminal in tap.truncations:
                terminal_obs = self.policy.obs_to_tensor(terminal)[0]
                costs[step, i] += self.gamma * float(self.policy.predict_costs(terminal_obs)[0, 0])
        self._cost_advantages, self._cost_returns = gae(
            costs,
            values.astype(np.float32),
            buffer.episode_starts,
            last.astype(np.float32),
            np.asarray(self._last_episode_starts),
            self.gamma,
            self.gae_lambda,
        )
        self._reward_advantages = buffer.advantages.copy()

    def _dual_update(self, episode_costs: list[float]) -> None:
        self.n_dual_updates += 1
        mean_cost = float(np.mean(episode_costs)) if episode_costs else None
        if mean_cost is not None:
            self.lagrangian_multiplier = dual_ascent(
                self.lagrangian_multiplier, mean_cost, self.cost_limit, self.lagrangian_lr
            )
            self.logger.record("lagrangian/episode_cost", mean_cost)
        self.last_dual_update = DualUpdate(
            update=self.n_dual_updates,
            num_timesteps=int(self.num_timesteps),
            n_episodes=len(episode_costs),
            episode_cost=mean_cost,
            cost_limit=self.cost_limit,
            multiplier=self.lagrangian_multiplier,
        )
        self.logger.record("lagrangian/lambda", self.lagrangian_multiplier)
        self.logger.record("lagrangian/cost_limit", self.cost_limit)
        self.logger.record("lagrangian/n_episodes", len(episode_costs))

    # --------------------------------------------------------------------------------------------------
    def train(self) -> None:
        """PPO's update on the Lagrangian advantages, then the cost critic's fit to the cost returns."""
        if self._reward_advantages is None or self._cost_advantages is None or self._cost_returns is None:
            raise RuntimeError("PPOLagrangian.train needs a rollout collected by PPOLagrangian.collect_rollouts")
        self.rollout_buffer.advantages = lagrangian_advantages(
            self._reward_advantages, self._cost_advantages, self.lagrangian_multiplier
        )
        super().train()
        self._train_cost_critic()

    def _train_cost_critic(self) -> None:
        assert self._cost_returns is not None
        buffer = self.rollout_buffer
        observations = buffer.observations  # flattened to (n_steps * n_envs, ...) by PPO's pass over the buffer
        if not buffer.generator_ready:
            observations = buffer.swap_and_flatten(observations)
        targets = buffer.swap_and_flatten(self._cost_returns).flatten()
        n = targets.shape[0]
        optimizer = self.policy.optimizer
        params = list(self.policy.cost_net.parameters())
        losses = []
        self.policy.set_training_mode(True)
        for _ in range(self.n_epochs):
            order = self._cost_rng.permutation(n)
            for start in range(0, n, self.batch_size):
                idx = order[start : start + self.batch_size]
                obs = obs_as_tensor(observations[idx], self.device)
                target = th.as_tensor(targets[idx], device=self.device)
                loss = self.vf_coef * F.mse_loss(self.policy.predict_costs(obs).flatten(), target)
                optimizer.zero_grad()
                loss.backward()
                th.nn.utils.clip_grad_norm_(params, self.max_grad_norm)
                optimizer.step()
                losses.append(loss.item())
        self.logger.record("train/cost_value_loss", float(np.mean(losses)))

