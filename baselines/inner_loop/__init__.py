"""The inner loop of the torque baselines: dynamic inversion under the MPC.

* :mod:`~baselines.inner_loop.di`: dynamic inversion with RBF-network compensation
  (:class:`~baselines.inner_loop.di.DynamicInversionController`);
* :mod:`~baselines.inner_loop.cascade`: the MPC outer loop feeding it
  (:class:`~baselines.inner_loop.cascade.CascadeController`).
"""
