"""Setting up the SB3 model of a training run: replay-buffer capacity, planned steps, action-layer scaling."""

from __future__ import annotations

import inspect
import math
import warnings

import numpy as np
import torch
from stable_baselines3.common.base_class import BaseAlgorithm

from agents.algos import ALGOS, is_off_policy
from agents.config import ConfigError, TrainConfig


def configured_buffer_size(cfg: TrainConfig) -> int:
    """``buffer_size`` of the configuration, or the algorithm's default."""
    if "buffer_size" in cfg.hyperparams:
        return int(cfg.hyperparams["buffer_size"])
    return int(inspect.signature(ALGOS[cfg.algo].__init__).parameters["buffer_size"].default)


def replay_buffer_size(configured: int, n_envs: int, total_timesteps: int) -> int:
    """Replay-buffer capacity (transitions) for a run that ends at ``total_timesteps``.

    SB3 preallocates the whole buffer (and ``save_replay_buffer`` pickles all of it), so a 300-step run with
    ``buffer_size: 300000`` would hold and write ~200 MB. The capacity is capped at the transitions the run
    can store, ``n_envs * (ceil(total_timesteps / n_envs) + 1)``: the buffer never fills, so sampling and
    training are exactly those of the configured size. A resumed run grows it (:func:`grow_replay_buffer`).

    Args:
        configured: ``buffer_size`` of the configuration.
        n_envs: Number of training environments.
        total_timesteps: ``num_timesteps`` at the end of the segment.

    Returns:
        ``min(configured, cap)``.
    """
    return min(int(configured), n_envs * (math.ceil(total_timesteps / n_envs) + 1))


def grow_replay_buffer(model: BaseAlgorithm, size: int) -> bool:
    """Enlarge an off-policy model's replay buffer to ``size`` transitions, keeping its content.

    A buffer that has wrapped around (``full``) or is already large enough is left alone (a full buffer was
    allocated at the configured size, see :func:`replay_buffer_size`).

    Args:
        model: An off-policy SB3 model.
        size: The capacity wanted, in transitions over all envs.

    Returns:
        Whether the buffer was enlarged.
    """
    buffer = model.replay_buffer
    old = buffer.buffer_size
    new = max(size // buffer.n_envs, 1)
    if buffer.full or new <= old:
        return False
    for name, value in list(vars(buffer).items()):
        if isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == old:
            setattr(buffer, name, _grown(value, new, buffer.pos))
        elif isinstance(value, dict) and all(isinstance(v, np.ndarray) for v in value.values()):
            setattr(buffer, name, {k: _grown(v, new, buffer.pos) if v.shape[0] == old else v for k, v in value.items()})
    buffer.buffer_size = new
    model.buffer_size = new * buffer.n_envs
    return True


def _grown(array: np.ndarray, length: int, filled: int) -> np.ndarray:
    out = np.zeros((length, *array.shape[1:]), dtype=array.dtype)
    out[:filled] = array[:filled]
    return out


def planned_timesteps(model: BaseAlgorithm, cfg: TrainConfig, timesteps: int) -> int:
    """Steps the segment will run: on-policy algorithms collect whole rollouts of ``n_steps x n_envs``.

    Warns when that exceeds the requested steps (PPO with ``--total-timesteps 300`` and ``n_steps: 1024`` on
    2 envs runs 2048 steps).
    """
    if is_off_policy(cfg.algo):
        return timesteps
    rollout = int(model.n_steps) * cfg.n_envs
    planned = math.ceil(timesteps / rollout) * rollout
    if planned != timesteps:
        warnings.warn(
            f"{cfg.algo.upper()} trains in whole rollouts of n_steps x n_envs = {model.n_steps} x {cfg.n_envs} = "
            f"{rollout} steps: the {timesteps} requested steps run as {planned} (pass --hyperparams n_steps=N "
            "for shorter rollouts)",
            stacklevel=3,
        )
    return planned


def scale_action_layer(model: BaseAlgorithm, scale: float) -> torch.nn.Linear:
    """Multiply the last action layer of a fresh model's policy by ``scale`` (``TrainConfig.action_init_scale``).

    Args:
        model: A freshly built SB3 model (PPO: ``policy.action_net``; SAC/TQC: ``actor.mu``; TD3: the last
            ``Linear`` of ``actor.mu``, copied to ``actor_target``).
        scale: The factor.

    Returns:
        The scaled layer.

    Raises:
        ConfigError: If the policy has no recognised action layer.
    """
    policy = model.policy
    actor = getattr(policy, "actor", None)
    if hasattr(policy, "action_net"):
        layer = policy.action_net
    elif actor is not None and isinstance(getattr(actor, "mu", None), torch.nn.Linear):
        layer = actor.mu
    elif actor is not None and isinstance(getattr(actor, "mu", None), torch.nn.Sequential):
        layer = [m for m in actor.mu if isinstance(m, torch.nn.Linear)][-1]
    else:
        raise ConfigError(f"action_init_scale: no action layer found in {type(policy).__name__}")
    with torch.no_grad():
        layer.weight.mul_(scale)
        if layer.bias is not None:
            layer.bias.mul_(scale)
    if getattr(policy, "actor_target", None) is not None:
        policy.actor_target.load_state_dict(actor.state_dict())
    return layer
