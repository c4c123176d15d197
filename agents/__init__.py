"""Reinforcement-learning agents for the uvdms-gym environments (Stable-Baselines3).

Modules (imported on demand, so ``import agents`` stays light):

* :mod:`agents.algos`: the algorithm table ``ALGOS`` (PPO, PPO-Lagrangian, SAC, TD3, TQC).
* :mod:`agents.algos.ppo_lagrangian`: PPO-Lagrangian (a cost critic and a Lagrange multiplier on ``info["cost"]``).
* :mod:`agents.config.typecheck`: generic checking of YAML data against type annotations (strict keys, no eval).
* :mod:`agents.config.schema`: ``train_configs/<algo>.yml`` loading and validation (the ``TrainConfig`` schema).
* :mod:`agents.config.zoo`: RL Baselines3 Zoo's config keys (``env_wrapper``, ``callback``, ``train_options``).
* :mod:`agents.common.wrappers`: the training-side wrappers ``AliveBonus`` and ``ScaledAction``.
* :mod:`agents.common.envs`: env-id lookup, the picklable ``EnvFactory``, vector envs, the env seed scheme.
* :mod:`agents.training.callbacks`: checkpoint, seeded evaluation, best-model and initial-action-scale callbacks.
* :mod:`agents.training.models`: replay-buffer capacity, planned steps, action-layer scaling of a model.
* :mod:`agents.training.rundir`: run directories, checkpoints found for ``--resume``, meta records.
* :mod:`agents.training.train`: ``train(...)`` and the ``python -m agents.train`` command line.
* :mod:`agents.export`: ``load_agent`` / ``AgentController`` / ``check_agent`` for evaluation and the
  trust-gated ``load_sb3_zip``.
* :mod:`agents.export.weights`: the weights-only ``export_agent`` / ``load_weights_only`` (also importable from
  :mod:`agents.export`).
* :mod:`agents.distributed.sweep` / :mod:`agents.distributed.worker` / :mod:`agents.distributed.report`: ``uvdms
  sweep`` (seeds x grid,
  locally or as Ray tasks; its summary).
* :mod:`agents.distributed.tune` / :mod:`agents.distributed.search_space`: ``uvdms tune`` (Ray Tune + Optuna TPE over
  RL-Zoo-style spaces).
"""
