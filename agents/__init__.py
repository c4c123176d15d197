"""Reinforcement-learning agents for the uvdms-gym environments (Stable-Baselines3).

Subpackages (imported on demand, so ``import agents`` stays light; ``docs/ARCHITECTURE.md`` has the module tables):

* :mod:`agents.common`: the env factory and vector envs, ``RolloutPPO``'s parallel rollouts, the training-side
  wrappers, the learning-curve record, threads, shared names, where the configs and shipped agents live.
* :mod:`agents.algos`: the algorithm table ``ALGOS``; PPO-Lagrangian, TD3-prior, DAgger.
* :mod:`agents.config`: ``train_configs/<algo>.yml`` read into the ``TrainConfig`` schema (strict keys, no eval;
  RL Zoo's vocabulary).
* :mod:`agents.training`: ``train(...)`` and ``--resume``, the ``RunSpec`` of a run, one training segment in
  named steps, callbacks, run directories, ``uvdms bench train``.
* :mod:`agents.export`: ``load_agent`` (any folder format), ``AgentController``, the weights-only
  ``export_agent`` / ``load_weights_only``, the trust-gated SB3 zips.
* :mod:`agents.distributed`: ``uvdms sweep`` (seeds x grid, locally or as Ray tasks) and ``uvdms tune`` (Ray Tune +
  Optuna TPE over RL-Zoo-style spaces).

The paths that were re-exports or aliases in 0.3.0 (``agents.train``, ``agents.policy``, ``agents.wrappers``,
``agents.callbacks``, ``agents.ppo_lagrangian``) fail on import in one line naming their new home
(:mod:`agents.common.legacy`); :mod:`agents.cli` registers ``uvdms train`` and ``uvdms export-agent``.
"""

from agents.common.legacy import MOVED as _MOVED
from uvdms_gym.utils.legacy import install_moved_finder

install_moved_finder(_MOVED)
