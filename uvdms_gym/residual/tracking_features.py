"""The tracking features a policy observes with ``tracking_features=True``: its current error, magnified.

The observation's first preview row is the tracking error now, in the body frame: a position error divided by
:data:`~uvdms_gym.envs.tracking.POS_SCALE` (0.5 m) and, on the transport, the orientation error in radians. The
transport succeeds within 2 cm and 2 degrees, which the observation gives as 0.04 and 0.035: a network fitted by
least squares resolves its command to a few hundredths of the action range, about what such an error asks of it.
:class:`TrackingFeatures` hands it the same error at the scale of success::

    tanh(e_p / TRACKING_POSITION)          (3)   (transport: the object; circles: the left end effector)
    tanh(e_o / TRACKING_ORIENTATION)       (3)   (transport: the object's orientation error, rad)
    tanh(e_p,right / TRACKING_POSITION)    (3)   (circles: the right end effector, in place of the orientation)

So an error at the success threshold observes as tanh(1) = 0.76, the gain is 1 / (2 cm) near zero, and an error
of a few threshold widths saturates. Nothing is added that the observation does not hold: the features are its
first six values rescaled (the :class:`~uvdms_gym.residual.ObstacleFeatures` convention of computing features from
the observation alone, so the same function serves training and evaluation).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

from uvdms_gym.residual.obstacle_features import with_features

POS_SCALE = 0.5
"""The observation's position scale, m (``uvdms_gym.envs.tracking.POS_SCALE``; a test checks)."""
TRACKING_POSITION = 0.02
"""Position error (m) that observes as ``tanh(1)`` among the tracking features: the transport's success radius."""
TRACKING_ORIENTATION = math.radians(2.0)
"""Orientation error (rad) that observes as ``tanh(1)``: the transport's success angle."""
TRACKING_SIZE = 6
"""Values of the tracking features (the first preview row)."""


class TrackingFeatures:
    """The features of the module docstring, from one observation of a UVDMS environment.

    Args:
        orientation: The first preview row holds a position then an orientation error (the transports); without it,
            two position errors (the circles' end effectors).
    """

    option = "tracking_features=True"
    size = TRACKING_SIZE

    def __init__(self, orientation: bool) -> None:
        if not isinstance(orientation, bool):
            raise ValueError(f"orientation must be true or false, got {orientation!r}")
        self.orientation = orientation
        second = 1.0 / TRACKING_ORIENTATION if orientation else POS_SCALE / TRACKING_POSITION
        self._gain = np.array([POS_SCALE / TRACKING_POSITION] * 3 + [second] * 3)

    @classmethod
    def for_env(cls, env: Any) -> TrackingFeatures:
        """The features of a UVDMS environment (through wrappers): with the orientation where it holds the object.

        Raises:
            ValueError: ``env`` is not a UVDMS tracking environment (it has no ``tracking_transient``).
        """
        base = getattr(env, "unwrapped", env)
        if not hasattr(base, "tracking_transient") or not hasattr(base, "with_object"):
            name = env.spec.id if getattr(env, "spec", None) is not None else type(base).__name__
            raise ValueError(f"{cls.option} needs a UVDMS circle or transport environment, not {name}")
        return cls(orientation=bool(base.with_object))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The features (``size``, float64) of one observation (or of one with features appended after it)."""
        return np.tanh(self._gain * np.asarray(obs, dtype=np.float64)[:TRACKING_SIZE])


def tracking_feature_space(space: gym.spaces.Box) -> gym.spaces.Box:
    """``space`` extended by the tracking features (bounds ``+-1``), in its dtype."""
    low = np.concatenate([space.low, -np.ones(TRACKING_SIZE)])
    high = np.concatenate([space.high, np.ones(TRACKING_SIZE)])
    return gym.spaces.Box(low.astype(space.dtype), high.astype(space.dtype), dtype=space.dtype)


class TrackingFeatureObservation(gym.ObservationWrapper):
    """Training wrapper: the observation followed by its :class:`TrackingFeatures`.

    Outside :class:`~uvdms_gym.residual.ObstacleFeatureObservation` when both are on, so the obstacle features'
    columns (that wrapper's ``opening_index``) stay where it put them.

    Attributes:
        features: The features it appends.
        featured_dim: The size of this wrapper's observation (found before the obstacle wrapper's: the size of the
            policy's observation with every feature).

    Raises:
        ValueError: ``env`` is not a UVDMS tracking environment (:meth:`TrackingFeatures.for_env`).
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.features = TrackingFeatures.for_env(env)
        self.observation_space = tracking_feature_space(env.observation_space)  # type: ignore[arg-type]
        self.featured_dim = int(self.observation_space.shape[0])

    def observation(self, observation: np.ndarray) -> np.ndarray:
        """``[obs; features(obs)]``."""
        return with_features(observation, self.features)
