"""Safety filters for any controller of the velocity track.

* :mod:`~baselines.safety.filter`: :class:`~baselines.safety.filter.SafetyFilter`, the minimal-change projection of a
  velocity command onto CAMPC's collision rows.
"""

from baselines.legacy import MOVED_NAMES as _MOVED_NAMES
from uvdms_gym.utils.legacy import moved_names as _moved_names

__getattr__ = _moved_names(__name__, _MOVED_NAMES[__name__])  # former names: one line naming their module
