"""Sensing and actuation realism: levels of noisy, late sensors, thrusters and drive limits, and a navigation filter.

* :mod:`uvdms_gym.realism.config`: the typed knobs, the four levels and their validation;
* :mod:`uvdms_gym.realism.sensors`: the sensor models (rate, latency, noise, bias, dropouts);
* :mod:`uvdms_gym.realism.actuation`: thrusters (allocation, saturation, rotor dynamics, dead zone), drive limits;
* :mod:`uvdms_gym.realism.navigation`: the vehicle's navigation filter and the wrapper that puts its estimate where
  the oracle state was.

``docs/realism.md`` documents the levels, their sources and the filter.
"""
