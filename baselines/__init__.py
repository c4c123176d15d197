"""Reference controllers of the UVDMS benchmark (the paper's method and its ablations).

* :mod:`baselines.mpc` — the kinematic MPC / CAMPC QP core (:class:`KinematicMPC`, :class:`MPCConfig`);
* :mod:`baselines.campc` — its model-based front end (:class:`MPCController`, :func:`make_mpc_controller`);
* :mod:`baselines.di` — dynamic inversion with RBF compensation (:class:`DynamicInversionController`);
* :mod:`baselines.cascade` — MPC outer loop + DI inner loop (:class:`CascadeController`);
* :mod:`baselines.controllers` — the controller interface shared with agents and the named baselines ``mpc``,
  ``campc``, ``campc-di``, ``campc-nndi`` (:func:`make_controller`);
* :mod:`baselines.evaluate` — deprecated aliases (0.2) of :mod:`uvdms_gym.evaluation` (episodes -> JSON metrics);
* :mod:`baselines.reproduce` — the paper's experiments, figures and acceptance checks (``uvdms reproduce``);
* :mod:`baselines.bench` — timings (:func:`benchmark_all`: ``uvdms bench mpc``) and the OSQP replay.
"""

from baselines.campc import MPCController, make_mpc_controller, task_config
from baselines.cascade import CascadeController, CascadeOutput
from baselines.di import DIConfig, DIOutput, DynamicInversionController, UVDMSNominalModel
from baselines.mpc import KinematicMPC, MPCConfig, MPCProblem, MPCStepRecord, QPMatrices

__all__ = [
    "CascadeController",
    "CascadeOutput",
    "DIConfig",
    "DIOutput",
    "DynamicInversionController",
    "KinematicMPC",
    "MPCConfig",
    "MPCController",
    "MPCProblem",
    "MPCStepRecord",
    "QPMatrices",
    "UVDMSNominalModel",
    "make_mpc_controller",
    "task_config",
]
