"""A deterministic actor called directly: the same action as SB3's ``policy.predict``, without its overhead.

SB3's ``predict`` on one observation checks and converts it (``obs_to_tensor``, the vectorised-env test, the
reshapes) around the network call, which for the small actors here costs several times the network itself. A
distilled controller's whole point is its speed (``docs/LEARNED_CONTROLLERS.md``), so :class:`AgentController`
evaluates the actors this module can read with :class:`FastActor`: the policy's own actor module (the same torch
operations on the same ``(1, n)`` input, hence the same bits) and SB3's output mapping in NumPy
(``unscale_action`` for a squashed output). When the actor is a plain MLP after a flatten (SB3's default: ``Linear``
layers and ``ReLU`` / ``Tanh`` activations in ``mu``), its layers are applied as the functions their modules call
(``F.linear``, ``torch.relu``, ``torch.tanh``), without ``nn.Module``'s per-call machinery: the same operations.
The tests compare it with ``policy.predict`` to the bit; other policies keep ``policy.predict``.

Readable: deterministic actors with a squashed output (``policy.actor``, TD3 and the algorithms built on it:
DAgger, TD3-prior) on a one-dimensional ``Box`` observation and action.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from gymnasium import spaces
from stable_baselines3.common.torch_layers import FlattenExtractor
from torch import nn
from torch.nn import functional as F

_ACTIVATIONS = {nn.ReLU: torch.relu, nn.Tanh: torch.tanh}
"""The activations a plain actor may use, and the function each module's ``forward`` calls."""


class FastActor:
    """A TD3-family actor called directly (see the module).

    Attributes:
        actor: The policy's actor module (evaluation mode).
        low: Lower bound of the action box (float32).
        high: Upper bound of the action box (float32).
        steps: The plain actor's layers as ``(weight, bias)`` pairs and activation functions (``None``: the actor
            module is called).
    """

    def __init__(self, actor: torch.nn.Module, low: np.ndarray, high: np.ndarray) -> None:
        self.actor = actor
        self.low = low
        self.high = high
        self.steps = _plain_steps(actor)

    @classmethod
    def from_policy(cls, policy: Any) -> FastActor | None:
        """The actor of ``policy`` if this module can call it directly (see the module), else ``None``."""
        actor = getattr(policy, "actor", None)
        if not isinstance(actor, torch.nn.Module) or not getattr(policy, "squash_output", False):
            return None
        if not hasattr(actor, "mu") or hasattr(actor, "action_dist"):  # a deterministic actor (not SAC's)
            return None
        action_space, observation_space = policy.action_space, policy.observation_space
        if not isinstance(action_space, spaces.Box) or not isinstance(observation_space, spaces.Box):
            return None
        if len(action_space.shape) != 1 or len(observation_space.shape) != 1:
            return None
        return cls(actor, action_space.low, action_space.high)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The action for one observation (or a batch), as ``policy.predict(obs, deterministic=True)`` gives it."""
        obs = np.asarray(obs, dtype=np.float32)
        single = obs.ndim == 1
        with torch.no_grad():
            x = torch.as_tensor(obs[None] if single else obs)
            if self.steps is None:
                action = self.actor(x).numpy()
            else:
                for step in self.steps:
                    x = F.linear(x, *step) if isinstance(step, tuple) else step(x)
                action = x.numpy()
        action = self.low + (0.5 * (action + 1.0) * (self.high - self.low))  # SB3's unscale_action
        return action[0] if single else action


def _plain_steps(actor: torch.nn.Module) -> list[Any] | None:
    """``actor.mu`` as layer steps if the actor is a plain MLP after a flatten (see the module), else ``None``."""
    mu = getattr(actor, "mu", None)
    flat = isinstance(getattr(actor, "features_extractor", None), FlattenExtractor)
    if not flat or not isinstance(mu, nn.Sequential):
        return None
    steps: list[Any] = []
    for module in mu:
        if type(module) is nn.Linear:
            steps.append((module.weight, module.bias))
        elif type(module) in _ACTIVATIONS and not getattr(module, "inplace", False):
            steps.append(_ACTIVATIONS[type(module)])
        else:
            return None
    return steps
