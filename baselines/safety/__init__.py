"""Safety filters for any controller of the velocity track.

* :mod:`~baselines.safety.filter`: :class:`~baselines.safety.filter.SafetyFilter`, the minimal-change projection of a
  velocity command onto CAMPC's collision rows.
"""
