"""The null-space projection of ``residual_space="nullspace"``: a residual that, to first order, moves no hand.

The policy's output is projected onto the null space of the two end-effector positions before it is added
(package docstring: :mod:`uvdms_gym.residual`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from uvdms_gym.residual.clearance import KinematicHelper
from uvdms_gym.residual.composition import ACTION_HIGH, ACTION_LOW, ActionComposition


class NullspaceProjection(KinematicHelper):
    """The projection of ``residual_space="nullspace"``: residual commands that leave both hands where they are.

    With ``J`` the (6, 18) Jacobian of the two end-effector positions (world-aligned) per unit of normalised
    action, ``J = J_pos diag(zeta_max)``, at the configuration of ``info``, and ``J^+`` its Moore-Penrose
    pseudo-inverse, ``P = I - J^+ J`` (18 x 18, symmetric, ``J P = 0``); a policy output ``u`` becomes
    ``clip(P u, -1, 1)``. To first order the projected command moves the vehicle and the arms without moving the
    end effectors; the clip (and the base's own command, which is not projected) can break this at large commands.
    Evaluated on a kinematic model built from the environment's parameters, from ``info`` alone, so training and
    evaluation project alike.

    Args:
        kin: A kinematic model of the environment's vehicle (its state is overwritten on every call).
        zeta_max: The velocity-mode action scale (18).
    """

    option = "residual_space='nullspace'"

    def matrix(self, info: Mapping[str, Any]) -> np.ndarray:
        """``P`` (18, 18) at the configuration of ``info``."""
        self.kin.set_state(np.asarray(info["eta"], dtype=np.float64), np.asarray(info["q"], dtype=np.float64))
        jac = self.kin.ee_jacobian()[_EE_POSITION_ROWS] * self.zeta_max
        return np.eye(jac.shape[1]) - np.linalg.pinv(jac) @ jac

    def __call__(self, info: Mapping[str, Any], policy_action: np.ndarray) -> tuple[np.ndarray, bool]:
        """``clip(P u, -1, 1)`` (18, float64) for the policy output ``u`` at ``info``'s configuration, and a flag.

        The flag says whether the clip changed anything (``P`` is a projection, but single entries of ``P u`` can
        exceed 1).
        """
        raw = self.matrix(info) @ np.asarray(policy_action, dtype=np.float64)
        projected = np.clip(raw, ACTION_LOW, ACTION_HIGH)
        return projected, bool(np.any(projected != raw))


_EE_POSITION_ROWS = [0, 1, 2, 6, 7, 8]
"""Rows of :meth:`uvdms_gym.physics.kinematics.KinematicModel.ee_jacobian` that are the two end-effector positions."""


def residual_projection(composition: ActionComposition, env: Any) -> NullspaceProjection | None:
    """The projection a composition's residual goes through on ``env`` (``None``: the full command space)."""
    if composition.residual_space == "nullspace":
        return NullspaceProjection.for_env(env)
    return None
