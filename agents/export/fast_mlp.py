"""A deterministic MLP actor evaluated with NumPy: the same action as SB3's ``policy.predict``, without its overhead.

SB3's ``predict`` on one observation converts it to a tensor, checks its shape, runs the network under
``torch.no_grad`` and converts back: for the 256x256 actors here that is ~100-200 us, several times the
arithmetic (three small matrix-vector products, ~10-20 us in NumPy). A distilled controller's whole point is its
speed (``docs/LEARNED_CONTROLLERS.md``), so :class:`AgentController` evaluates the actors this module can read
with :class:`NumpyActor`: the weights copied to float32 arrays, the same layers in the same order, and SB3's
output mapping (``unscale_action`` for squashed outputs, then the clip to the action box). Results equal
``policy.predict``'s to float32 rounding (the tests compare them); other policies keep ``policy.predict``.

Readable: deterministic actors whose output layer ends in ``tanh`` (TD3 and the algorithms built on it:
DAgger, TD3-prior), a ``FlattenExtractor`` on a one-dimensional ``Box`` observation, ``Linear`` layers with
``ReLU`` or ``Tanh`` activations.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from torch import nn

_ACTIVATIONS = {nn.ReLU: "relu", nn.Tanh: "tanh"}


class NumpyActor:
    """A TD3-family actor (``policy.actor.mu``) as float32 NumPy layers (see the module).

    Attributes:
        layers: ``(weight, bias, activation)`` per ``Linear`` layer; activation ``"relu"``, ``"tanh"`` or ``None``.
        low: Lower bound of the action box (float32).
        high: Upper bound of the action box (float32).
    """

    def __init__(self, layers: list[tuple[np.ndarray, np.ndarray, str | None]], low: np.ndarray, high: np.ndarray):
        self.layers = layers
        self.low = low
        self.high = high

    @classmethod
    def from_policy(cls, policy: Any) -> NumpyActor | None:
        """The actor of ``policy`` if this module can read it (see the module), else ``None``."""
        actor = getattr(policy, "actor", None)
        mu = getattr(actor, "mu", None)
        if not isinstance(mu, nn.Sequential) or not getattr(policy, "squash_output", False):
            return None
        if type(getattr(actor, "features_extractor", None)).__name__ != "FlattenExtractor":
            return None
        space = policy.action_space
        if not isinstance(space, spaces.Box) or len(policy.observation_space.shape) != 1:
            return None
        layers = _layers(list(mu))
        if layers is None or layers[-1][2] != "tanh":
            return None
        return cls(layers, space.low.astype(np.float32), space.high.astype(np.float32))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The action for one observation (or a batch): the network's, mapped as SB3's ``predict`` maps it."""
        x = np.asarray(obs, dtype=np.float32)
        for weight, bias, activation in self.layers:
            x = x @ weight + bias
            if activation == "relu":
                x = np.maximum(x, 0.0)
            elif activation == "tanh":
                x = np.tanh(x)
        action = self.low + 0.5 * (x + 1.0) * (self.high - self.low)  # SB3's unscale_action
        return np.clip(action, self.low, self.high)


def _layers(modules: list[nn.Module]) -> list[tuple[np.ndarray, np.ndarray, str | None]] | None:
    """``Linear`` layers each followed by at most one known activation; ``None`` for anything else."""
    layers: list[tuple[np.ndarray, np.ndarray, str | None]] = []
    for module in modules:
        if isinstance(module, nn.Linear):
            weight = module.weight.detach().cpu().numpy().astype(np.float32).T.copy()
            bias = module.bias.detach().cpu().numpy().astype(np.float32).copy()
            layers.append((weight, bias, None))
        elif type(module) in _ACTIVATIONS and layers and layers[-1][2] is None:
            weight, bias, _ = layers[-1]
            layers[-1] = (weight, bias, _ACTIVATIONS[type(module)])
        else:
            return None
    return layers or None
