"""The training-side wrappers under the names the RL Zoo configurations use (``agents.wrappers.AliveBonus``).

``train_configs/<algo>.yml`` name them in ``env_wrapper`` lists, which RL Zoo imports by this dotted path; the
implementation lives in :mod:`agents.common.wrappers`.
"""

from agents.common.wrappers import KEPT_ARRAYS, AliveBonus, ScalarInfo, ScaledAction, is_unit_scale

__all__ = ["KEPT_ARRAYS", "AliveBonus", "ScalarInfo", "ScaledAction", "is_unit_scale"]
