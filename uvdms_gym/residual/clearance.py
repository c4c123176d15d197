"""The 36 clearance features a residual policy observes with ``residual_observation="clearance"``.

Computed from ``info`` with the environment's explicit kinematic model, the same way in training and at evaluation
(package docstring: :mod:`uvdms_gym.residual`). :class:`KinematicHelper` is what they share with the null-space
projection (:mod:`uvdms_gym.residual.nullspace`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np

from uvdms_gym.distances import compute_distances, distance_jacobian, velocity_damper
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.params import D1, D2
from uvdms_gym.residual.composition import ActionComposition

CLEARANCE_RATE_SCALE = 0.1
"""Scale (m/s) of the clearance rates among the :class:`ClearanceFeatures` (a rate of 0.1 m/s observes as 1)."""
FEATURE_CLIP = 10.0
"""The clearance features are clipped to ``[-FEATURE_CLIP, FEATURE_CLIP]`` (the environments' observation clip)."""


_Helper = TypeVar("_Helper", bound="KinematicHelper")


class KinematicHelper:
    """What :class:`ClearanceFeatures` and :class:`NullspaceProjection` share: a kinematic model and ``zeta_max``.

    Args:
        kin: A kinematic model of the environment's vehicle (its state is overwritten on every call).
        zeta_max: The velocity-mode action scale (18).
    """

    option = ""
    """The composition option that needs the helper (for the error of :meth:`for_env`)."""

    def __init__(self, kin: Any, zeta_max: np.ndarray) -> None:
        self.kin = kin
        self.zeta_max = np.asarray(zeta_max, dtype=np.float64).copy()
        if self.zeta_max.shape != (18,):
            raise ValueError(f"zeta_max must have 18 entries, got shape {self.zeta_max.shape}")

    @classmethod
    def for_env(cls: type[_Helper], env: Any) -> _Helper:
        """The helper for a UVDMS environment (through wrappers).

        It uses a kinematic model of its own, built from the environment's ``params`` (not shared with the
        base controller), and the environment's ``zeta_max``.

        Raises:
            ValueError: ``env`` is not a UVDMS environment.
        """
        base = getattr(env, "unwrapped", env)
        if not hasattr(base, "params") or not hasattr(base, "zeta_max"):
            raise ValueError(f"{cls.option} needs a UVDMS environment (params, zeta_max), got {base!r}")
        return cls(KinematicModel(base.params), base.zeta_max)


class ClearanceFeatures(KinematicHelper):
    """The 36 clearance features of ``residual_observation="clearance"``, from ``info`` and a kinematic model.

    With ``d`` the 18 clearances (m), ``G = -J_dis diag(zeta_max)`` (18 x 18: the rate of each clearance per unit
    of normalised action, since ``d_dot = -J_dis zeta`` and ``zeta = a * zeta_max``) and ``w = 1 - S(d)`` (0
    beyond ``d2``, 1 inside ``d1``)::

        direction = sum_i w_i G_i / |G_i|                 (18): opens the clearances closer than d2
        rate      = G a_base / CLEARANCE_RATE_SCALE        (18): each clearance's rate under the base's command

    both clipped to ``[-FEATURE_CLIP, FEATURE_CLIP]``. The direction is zero when every clearance is beyond
    ``d2``. The features are a function of ``info``'s configuration (``eta``, ``q``) and of ``a_base`` only,
    evaluated on a kinematic model built from the environment's parameters, so training and evaluation compute
    the same values for the same inputs.

    Args:
        kin: A kinematic model of the environment's vehicle (its state is overwritten on every call).
        zeta_max: The velocity-mode action scale (18).
    """

    size = 36
    """Number of features."""
    option = "residual_observation='clearance'"

    def __call__(self, info: Mapping[str, Any], base_action: np.ndarray) -> np.ndarray:
        """``[direction; rate]`` (36, float64) at the configuration of ``info``."""
        self.kin.set_state(np.asarray(info["eta"], dtype=np.float64), np.asarray(info["q"], dtype=np.float64))
        res = compute_distances(self.kin, "exact")
        gain = -distance_jacobian(self.kin, res) * self.zeta_max
        weight = 1.0 - velocity_damper(res.d, D1, D2)
        norms = np.sqrt(np.einsum("ij,ij->i", gain, gain))
        direction = (weight / np.maximum(norms, 1e-12)) @ gain
        rate = gain @ np.asarray(base_action, dtype=np.float64) / CLEARANCE_RATE_SCALE
        return np.clip(np.concatenate([direction, rate]), -FEATURE_CLIP, FEATURE_CLIP)


def residual_features(composition: ActionComposition, env: Any) -> ClearanceFeatures | None:
    """The extra features a composition's residual policy observes on ``env`` (``None``: only the base's action)."""
    if composition.residual_observation == "clearance":
        return ClearanceFeatures.for_env(env)
    return None
