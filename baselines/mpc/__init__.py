"""The kinematic MPC and CAMPC (docs/MODEL.md section 6, paper Section 3.1).

* :mod:`~baselines.mpc.solver`: the ProxSuite build the QPs are solved with (the portable one, checked at import);
* :mod:`~baselines.mpc.config`: the settings :class:`~baselines.mpc.config.MPCConfig` and one step's data
  (:class:`~baselines.mpc.config.MPCProblem`, :class:`~baselines.mpc.config.QPMatrices`,
  :class:`~baselines.mpc.config.MPCStepRecord`);
* :mod:`~baselines.mpc.damper`: the velocity damper of the collision rows (shared with the safety filter);
* :mod:`~baselines.mpc.kinematic`: :class:`~baselines.mpc.kinematic.KinematicMPC`, the QP and its warm-started solve;
* :mod:`~baselines.mpc.campc`: its model-based front end :class:`~baselines.mpc.campc.MPCController` and the task
  settings (:func:`~baselines.mpc.campc.task_config`).
"""

from baselines.legacy import MOVED_NAMES as _MOVED_NAMES
from uvdms_gym.utils.legacy import moved_names as _moved_names

__getattr__ = _moved_names(__name__, _MOVED_NAMES[__name__])  # former names: one line naming their module
