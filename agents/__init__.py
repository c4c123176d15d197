"""Reinforcement-learning agents for the uvdms-gym environments (Stable-Baselines3).

Modules (imported on demand, so ``import agents`` stays light):

* :mod:`agents.algos`: the algorithm table ``ALGOS`` (PPO, SAC, TD3, TQC).
* :mod:`agents.config`: ``train_configs/<algo>.yml`` loading and validation (``TrainConfig``).
* :mod:`agents.train`: ``train(...)`` and the ``python -m agents.train`` command line.
* :mod:`agents.policy`: ``load_agent`` / ``AgentController`` / ``check_agent`` for evaluation and the
  trust-gated ``load_sb3_zip``.
* :mod:`agents.export`: the weights-only ``export_agent`` / ``load_weights_only`` (also importable from
  :mod:`agents.policy`).
"""
