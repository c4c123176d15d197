"""A deterministic actor called directly: the same action as SB3's ``policy.predict``, without its overhead.

SB3's ``predict`` on one observation checks and converts it (``obs_to_tensor``, the vectorised-env test, the
reshapes) around the network call, which for the small actors here costs several times the network itself. A
distilled controller's whole point is its speed (``docs/LEARNED_CONTROLLERS.md``), so :class:`AgentController`
evaluates the actors this module can read with :class:`FastActor`: the policy's own actor module (the same torch
operations on the same ``(1, n)`` input, hence the same bits) and SB3's output mapping in NumPy
(``unscale_action`` for a squashed output). The tests compare it with ``policy.predict`` to the bit; other
policies keep ``policy.predict``.

Readable: deterministic actors with a squashed output (``policy.actor``, TD3 and the algorithms built on it:
DAgger, TD3-prior) on a one-dimensional ``Box`` observation and action.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from gymnasium import spaces


class FastActor:
    """A TD3-family actor called directly (see the module).

    Attributes:
        actor: The policy's actor module (evaluation mode).
        low: Lower bound of the action box (float32).
        high: Upper bound of the action box (float32).
    """

    def __init__(self, actor: torch.nn.Module, low: np.ndarray, high: np.ndarray) -> None:
        self.actor = actor
        self.low = low
        self.high = high

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
            action = self.actor(torch.as_tensor(obs[None] if single else obs)).numpy()
        action = self.low + (0.5 * (action + 1.0) * (self.high - self.low))  # SB3's unscale_action
        return action[0] if single else action
