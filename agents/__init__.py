"""Reinforcement-learning agents for the uvdms-gym environments (Stable-Baselines3).

Modules (imported on demand, so ``import agents`` stays light):

* :mod:`agents.algos`: the algorithm table ``ALGOS`` (PPO, PPO-Lagrangian, SAC, TD3, TQC).
* :mod:`agents.ppo_lagrangian`: PPO-Lagrangian (a cost critic and a Lagrange multiplier on ``info["cost"]``).
* :mod:`agents.typecheck`: generic checking of YAML data against type annotations (strict keys, no eval).
* :mod:`agents.config`: ``train_configs/<algo>.yml`` loading and validation (the ``TrainConfig`` schema).
* :mod:`agents.zoo`: RL Baselines3 Zoo's config keys (``env_wrapper``, ``callback``, ``train_options``).
* :mod:`agents.wrappers`: the training-side wrappers ``AliveBonus`` and ``ScaledAction``.
* :mod:`agents.envs`: env-id lookup, the picklable ``EnvFactory``, vector envs, the env seed scheme.
* :mod:`agents.callbacks`: checkpoint, seeded evaluation, best-model and initial-action-scale callbacks.
* :mod:`agents.models`: replay-buffer capacity, planned steps, action-layer scaling of a model.
* :mod:`agents.rundir`: run directories, checkpoints found for ``--resume``, meta records.
* :mod:`agents.train`: ``train(...)`` and the ``python -m agents.train`` command line.
* :mod:`agents.policy`: ``load_agent`` / ``AgentController`` / ``check_agent`` for evaluation and the
  trust-gated ``load_sb3_zip``.
* :mod:`agents.export`: the weights-only ``export_agent`` / ``load_weights_only`` (also importable from
  :mod:`agents.policy`).
* :mod:`agents.sweep` / :mod:`agents.sweep_worker` / :mod:`agents.sweep_report`: ``uvdms sweep`` (seeds x grid,
  locally or as Ray tasks; its summary).
* :mod:`agents.tune` / :mod:`agents.search_space`: ``uvdms tune`` (Ray Tune + Optuna TPE over RL-Zoo-style spaces).
"""
