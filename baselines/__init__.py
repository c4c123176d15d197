"""Reference controllers of the UVDMS benchmark (the paper's method and its ablations), grouped by family.

* :mod:`baselines.mpc` — the kinematic MPC / CAMPC: the QP core (:class:`KinematicMPC` in
  :mod:`baselines.mpc.kinematic`, :class:`MPCConfig` in :mod:`baselines.mpc.config`), the damper rows, the ProxSuite
  build, and the model-based front end (:class:`MPCController`, :func:`make_mpc_controller` in
  :mod:`baselines.mpc.campc`);
* :mod:`baselines.inner_loop` — dynamic inversion with RBF compensation (:class:`DynamicInversionController` in
  :mod:`baselines.inner_loop.di`) and the MPC outer loop + DI inner loop (:class:`CascadeController` in
  :mod:`baselines.inner_loop.cascade`);
* :mod:`baselines.safety` — the safety filter (:mod:`baselines.safety.filter`);
* :mod:`baselines.controllers` — the controller interface shared with agents and the named baselines ``mpc``,
  ``campc``, ``campc-di``, ``campc-nndi``, ``campc-inner``, ``hold`` (:func:`~baselines.controllers.make_baseline`);
* :mod:`baselines.paper` — the paper's experiments, figures and acceptance checks (``uvdms reproduce``);
* :mod:`baselines.bench` — timings (:func:`~baselines.bench.benchmark_all`: ``uvdms bench mpc``) and the OSQP replay;
* :mod:`baselines.cli` — registers ``uvdms reproduce``.

The names below are re-exported here (``from baselines import KinematicMPC``). The module paths before the grouping
(``baselines.campc``, ...) fail in one line naming their new home (:mod:`baselines.legacy`).
"""

from baselines.inner_loop.cascade import CascadeController, CascadeOutput
from baselines.inner_loop.di import DIConfig, DIOutput, DynamicInversionController, UVDMSNominalModel
from baselines.legacy import REGROUPED as _REGROUPED
from baselines.mpc.campc import MPCController, make_mpc_controller, task_config
from baselines.mpc.config import MPCConfig, MPCProblem, MPCStepRecord, QPMatrices
from baselines.mpc.kinematic import KinematicMPC
from uvdms_gym.utils.legacy import install_moved_finder, regrouped_message

install_moved_finder(_REGROUPED, regrouped_message)

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
