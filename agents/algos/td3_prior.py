"""TD3 with its actor held near a prior: TD3+BC's actor loss with the zero action (or a prior policy's) as behaviour.

For a residual agent (:mod:`uvdms_gym.residual`) the zero action is the base controller alone, so this is "stay
with the base unless the critic is sure a correction pays". The actor minimises::

    actor_loss = -mean(Q1(s, pi(s))) / mean(|Q1(s, pi(s))|)  +  prior_coef * mean(pi(s)^2)

over each batch, with the normalisation ``mean(|Q1|)`` detached (Fujimoto & Gu, "A Minimalist Approach to Offline
Reinforcement Learning", NeurIPS 2021, TD3+BC: ``-lambda Q + (pi(s) - a)^2`` with ``lambda = alpha / mean|Q|``;
here ``a = 0`` and ``prior_coef = 1 / alpha``, so TD3+BC's default ``alpha = 2.5`` is ``prior_coef = 0.4``). The
normalisation makes the trade-off independent of the reward's scale. Why: an actor that follows an untrained
critic's gradient goes to the action bounds within a few thousand updates, since the critic has only seen
actions near the behaviour's and extrapolates beyond them; for a residual over ``mpc`` on the circle tasks that
drove the arms into contacts that the base alone avoids (TD3 and SAC runs, ``docs/training/learned-entries.md``).
The penalty keeps the actor where the data is, while a consistent gain in Q still moves it.

Everything else (critics, target smoothing, delayed updates, exploration noise) is SB3's ``TD3``; with
``prior_coef = 0`` the actor's update direction is TD3's, its step scaled by ``1 / mean|Q|``.

Fine-tuning (``prior_policy``: a weights-only export of a TD3-family agent, e.g. a distilled controller trained by
DAgger): the actor and its target start from the prior's actor, and the penalty holds the actor near the prior's
action instead of zero::

    actor_loss = -mean(Q1(s, pi(s))) / mean(|Q1(s, pi(s))|)  +  prior_coef * mean((pi(s) - pi_prior(s))^2)

``pi_prior`` is a frozen copy of the starting actor: RL improves on it where the critic is sure, and stays with it
elsewhere (the same TD3+BC trade-off, with the prior policy as the behaviour).
"""

# NOTE: no ``from __future__ import annotations`` here: agents.config.schema validates YAML keys against the evaluated
# annotations of ``TD3Prior.__init__`` (as for agents.algos.ppo_lagrangian).
import copy
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch as th
from stable_baselines3 import TD3
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.type_aliases import GymEnv, Schedule
from stable_baselines3.common.utils import polyak_update
from stable_baselines3.td3.policies import TD3Policy
from torch.nn import functional as F

from agents.algos.prior import load_prior_actor

DEFAULT_PRIOR_COEF = 0.4
"""TD3+BC's ``alpha = 2.5``."""
Q_SCALE_EPS = 1e-6
"""Floor of the detached ``mean(|Q1|)`` normalisation (a critic that outputs zeros)."""


def actor_loss(
    q: th.Tensor, actions: th.Tensor, prior_coef: float, prior_actions: th.Tensor | None = None
) -> th.Tensor:
    """``-mean(q) / mean(|q|).detach() + prior_coef * mean((actions - prior_actions)^2)`` (the module's formulas).

    ``prior_actions`` ``None``: the zero action.
    """
    scale = q.abs().mean().detach().clamp_min(Q_SCALE_EPS)
    deviation = actions if prior_actions is None else actions - prior_actions
    return -q.mean() / scale + prior_coef * deviation.pow(2).mean()


def _check_prior_name(prior: Any) -> None:
    """``prior_policy`` is ``None`` or a non-empty string (a folder; its files are checked when they are read)."""
    if prior is not None and (not isinstance(prior, str) or not prior):
        raise ValueError(f"prior_policy must be the folder of a weights-only agent export, got {prior!r}")


class TD3Prior(TD3):
    """SB3's TD3 whose actor is regularised toward the zero action (see the module).

    Args:
        policy: As ``TD3`` (and every other argument but ``prior_coef``).
        env: The environment.
        prior_coef: Weight of ``mean((pi(s) - pi_prior(s))^2)`` in the actor loss, >= 0.
        prior_policy: Folder of a weights-only export whose actor the actor starts from and is held near
            (``None``: start fresh, held near the zero action). Its network must have the same shape.

    Raises:
        ValueError: A negative or non-finite ``prior_coef``; a ``prior_policy`` that is no TD3-family export
            (:func:`agents.algos.prior.load_prior_actor`) or whose actor has another shape (the message names
            both).
    """

    def __init__(
        self,
        policy: str | type[TD3Policy],
        env: GymEnv | str,
        learning_rate: float | Schedule = 1e-3,
        buffer_size: int = 1_000_000,
        learning_starts: int = 100,
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
        policy_delay: int = 2,
        target_policy_noise: float = 0.2,
        target_noise_clip: float = 0.5,
        prior_coef: float = DEFAULT_PRIOR_COEF,
        prior_policy: str | None = None,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "auto",
        _init_setup_model: bool = True,
    ) -> None:
        # the prior's files are read once, by _setup_model (check_hyperparams reads them when a config is checked)
        self.check_hyperparams({"prior_coef": prior_coef})
        _check_prior_name(prior_policy)
        self.prior_coef = float(prior_coef)
        self.prior_policy = prior_policy
        self.prior_actor: th.nn.Module | None = None
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
            replay_buffer_class=replay_buffer_class,
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
            ValueError: ``prior_coef`` is negative, not finite or not a number.
        """
        value = hyperparams.get("prior_coef", DEFAULT_PRIOR_COEF)
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
            raise ValueError(f"prior_coef must be a finite number >= 0, got {value!r}")
        prior = hyperparams.get("prior_policy")
        _check_prior_name(prior)
        if prior is not None:
            load_prior_actor(prior)

    def _setup_model(self) -> None:
        """SB3's setup; with a ``prior_policy``, the actor and its target start from the prior's actor."""
        super()._setup_model()
        if self.prior_policy is None:
            return
        weights, _record = load_prior_actor(self.prior_policy)
        try:
            self.actor.load_state_dict(weights)
        except RuntimeError as exc:
            first = str(exc).strip().splitlines()[-1].strip()
            raise ValueError(
                f"prior_policy {self.prior_policy!r}: its actor does not fit this policy (net_arch "
                f"{self.policy_kwargs.get('net_arch')}, observation {self.observation_space.shape}): {first}"
            ) from None
        self.actor_target.load_state_dict(weights)
        self.prior_actor = copy.deepcopy(self.actor).requires_grad_(False).eval()

    def _excluded_save_params(self) -> list[str]:
        """SB3's, and the frozen prior (rebuilt from ``prior_policy`` when a saved model is loaded)."""
        return [*super()._excluded_save_params(), "prior_actor"]

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        """SB3's ``TD3.train`` with the actor loss of :func:`actor_loss`."""
        self.policy.set_training_mode(True)
        self._update_learning_rate([self.actor.optimizer, self.critic.optimizer])
        actor_losses, critic_losses, prior_terms = [], [], []
        for _ in range(gradient_steps):
            self._n_updates += 1
            replay_data = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)  # type: ignore[union-attr]
            discounts = replay_data.discounts if replay_data.discounts is not None else self.gamma
            with th.no_grad():
                noise = replay_data.actions.clone().data.normal_(0, self.target_policy_noise)
                noise = noise.clamp(-self.target_noise_clip, self.target_noise_clip)
                next_actions = (self.actor_target(replay_data.next_observations) + noise).clamp(-1, 1)
                next_q_values = th.cat(self.critic_target(replay_data.next_observations, next_actions), dim=1)
                next_q_values, _ = th.min(next_q_values, dim=1, keepdim=True)
                target_q_values = replay_data.rewards + (1 - replay_data.dones) * discounts * next_q_values
            current_q_values = self.critic(replay_data.observations, replay_data.actions)
            critic_loss = sum(F.mse_loss(current_q, target_q_values) for current_q in current_q_values)
            assert isinstance(critic_loss, th.Tensor)
            critic_losses.append(critic_loss.item())
            self.critic.optimizer.zero_grad()
            critic_loss.backward()
            self.critic.optimizer.step()

            if self._n_updates % self.policy_delay == 0:
                actions = self.actor(replay_data.observations)
                q = self.critic.q1_forward(replay_data.observations, actions)
                prior_actions = None
                if self.prior_actor is not None:
                    with th.no_grad():
                        prior_actions = self.prior_actor(replay_data.observations)
                loss = actor_loss(q, actions, self.prior_coef, prior_actions)
                actor_losses.append(loss.item())
                deviation = actions.detach() if prior_actions is None else actions.detach() - prior_actions
                prior_terms.append(float(deviation.pow(2).mean()))
                self.actor.optimizer.zero_grad()
                loss.backward()
                self.actor.optimizer.step()
                polyak_update(self.critic.parameters(), self.critic_target.parameters(), self.tau)
                polyak_update(self.actor.parameters(), self.actor_target.parameters(), self.tau)
                polyak_update(self.critic_batch_norm_stats, self.critic_batch_norm_stats_target, 1.0)
                polyak_update(self.actor_batch_norm_stats, self.actor_batch_norm_stats_target, 1.0)

        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        if actor_losses:
            self.logger.record("train/actor_loss", np.mean(actor_losses))
            self.logger.record("train/actor_mean_square_action", np.mean(prior_terms))
        self.logger.record("train/critic_loss", np.mean(critic_losses))
