"""The reward of ``uvdms/CircleTrack-v1`` and ``uvdms/Transport-v1`` (:class:`BoundedReward`): v0's tasks, not gamed.

Same dynamics, tasks, observations, costs, episode ends and time limits as v0; only the reward differs.

Why: every v0 reward term is <= 0, so a policy that ends the episode early (a contact terminates it) collects a
shorter negative sum than one that keeps going, and ending early is the return-maximising policy unless
training adds an alive bonus. Under the v1 reward every step's reward is >= 0 and bounded, and a contact costs a
penalty on top of ending the episode, so at equal tracking running to the time limit always scores more than
ending early (``tests/uvdms_gym/envs/test_envs_v1.py`` checks it on a policy that drives an arm into the frame).

v1 reward, the sum of the terms reported in ``info`` (``e_p``: position tracking error in m, ``e_o``: orientation
error in rad, ``a``: the clipped action, ``S``: the velocity-damper shape of the 18 clearances, 1 beyond
``d2 = 0.12 m`` and 0 inside ``d1 = 0.05 m``)::

    reward_track       = track_weight       * exp(-e_p / track_scale)            in [0, track_weight]
    reward_orientation = orientation_weight * exp(-e_o / orientation_scale)      (transport; 0 on the circles)
    reward_effort      = effort_weight      * (1 - |a|^2 / 18)                   in [0, effort_weight]
    reward_proximity   = proximity_weight   * mean_i S(d_i)                      in [0, proximity_weight]
    reward_contact     = -contact_weight    on a step with physical contact      (the episode then ends)
    reward_precision   = precision_weight   * exp(-e_p / precision_scale)        in [0, precision_weight]

``reward_precision`` is off by default (``precision_weight = 0``). It is a training-side option: a second,
narrow tracking term for learners that train with a wide ``track_scale`` (whose term is nearly linear, and so
nearly flat in the last centimetres) and must still be rewarded for millimetres.

A step on which the physics blows up keeps v0's ``PHYSICS_ERROR_REWARD``.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from uvdms_gym.distances import velocity_damper
from uvdms_gym.envs.base import UVDMSEnv
from uvdms_gym.physics.params import D1, D2

V1_WEIGHTS: dict[str, float] = {
    "track_weight": 1.0,
    "orientation_weight": 0.5,
    "effort_weight": 0.1,
    "proximity_weight": 0.2,
    "contact_weight": 50.0,
}
"""Default weights of the v1 reward (keyword arguments of the v1 environments)."""
TRACK_SCALE = 0.05
"""Default ``track_scale`` (m): the tracking term is 1/e of its maximum at a 5 cm error."""
ORIENTATION_SCALE = math.radians(5.0)
"""Default ``orientation_scale`` (rad)."""
PRECISION_SCALE = 0.01
"""Default ``precision_scale`` (m) of the optional narrow tracking term (off unless ``precision_weight > 0``)."""


class BoundedReward(UVDMSEnv):
    """The v1 reward over any v0 task (a mixin placed before the task class)."""

    rewards_orientation = True
    default_weights: ClassVar[dict[str, float]] = V1_WEIGHTS
    """The reward weights' defaults, overriding :class:`~uvdms_gym.envs.base.UVDMSEnv`'s."""

    def __init__(
        self,
        *,
        track_scale: float = TRACK_SCALE,
        orientation_scale: float = ORIENTATION_SCALE,
        precision_weight: float = 0.0,
        precision_scale: float = PRECISION_SCALE,
        **kwargs: Any,
    ) -> None:
        for name, value in (
            ("track_scale", track_scale),
            ("orientation_scale", orientation_scale),
            ("precision_scale", precision_scale),
        ):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite positive number, got {value}")
        if not (math.isfinite(precision_weight) and precision_weight >= 0.0):
            raise ValueError(f"precision_weight must be a finite non-negative number, got {precision_weight}")
        super().__init__(**{**self.default_weights, **kwargs})
        self.track_scale = float(track_scale)
        self.orientation_scale = float(orientation_scale)
        self.precision_scale = float(precision_scale)
        self.weights["precision"] = float(precision_weight)
        self._reward_keys = {k: f"reward_{k}" for k in self.weights}

    def _reward_terms(self, a: np.ndarray, info: dict[str, Any]) -> dict[str, float]:
        w = self.weights
        if info["min_distance"] < D2:  # S = 1 exactly for every distance beyond d2 (see UVDMSEnv)
            clear = float(np.add.reduce(velocity_damper(info["distances"], D1, D2))) / len(info["distances"])
        else:
            clear = 1.0
        orientation = math.exp(-info["orientation_error"] / self.orientation_scale) if self.rewards_orientation else 0.0
        return {
            "track": w["track"] * math.exp(-info["tracking_error"] / self.track_scale),
            "orientation": w["orientation"] * orientation,
            "effort": w["effort"] * (1.0 - float(a @ a) / self.action_dim),
            "proximity": w["proximity"] * clear,
            "contact": -w["contact"] * info["cost_contact"],
            "precision": (
                w["precision"] * math.exp(-info["tracking_error"] / self.precision_scale) if w["precision"] else 0.0
            ),
        }
