"""The reinforcement-learning algorithms available to the training scripts.

SB3's PPO (as :class:`agents.common.rollouts.RolloutPPO`: SB3's PPO, which also collects parallel rollouts on
``--vec-env rollout``), SAC, TD3, sb3-contrib's TQC, and the project's PPO-Lagrangian
(:mod:`agents.algos.ppo_lagrangian`: PPO under a per-episode budget on ``info["cost"]``) and TD3-prior
(:mod:`agents.algos.td3_prior`: TD3 whose actor is held near the zero action, TD3+BC's loss; for residual agents) and
DAgger (:mod:`agents.algos.dagger`: a residual policy fitted to a teacher's labels on the states it visits).
"""

from sb3_contrib import TQC
from stable_baselines3 import SAC, TD3
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

from agents.algos.dagger import DAgger
from agents.algos.ppo_lagrangian import PPOLagrangian
from agents.algos.td3_prior import TD3Prior
from agents.common.rollouts import RolloutPPO

ALGOS: dict[str, type[BaseAlgorithm]] = {
    "dagger": DAgger,
    "ppo": RolloutPPO,
    "ppo_lagrangian": PPOLagrangian,
    "sac": SAC,
    "td3": TD3,
    "td3_prior": TD3Prior,
    "tqc": TQC,
}
"""Algorithm name (as used in ``--algo`` and in ``train_configs/<algo>.yml``) -> SB3 class."""


def get_algo(name: str) -> type[BaseAlgorithm]:
    """Return the algorithm class for ``name``.

    Args:
        name: One of the keys of :data:`ALGOS`.

    Returns:
        The Stable-Baselines3 algorithm class.

    Raises:
        ValueError: If the name is unknown.
    """
    try:
        return ALGOS[name]
    except KeyError:
        raise ValueError(f"unknown algorithm {name!r}; choose one of {sorted(ALGOS)}") from None


def is_off_policy(name: str) -> bool:
    """Whether the algorithm ``name`` uses a replay buffer (SAC, TD3, TQC)."""
    return issubclass(get_algo(name), OffPolicyAlgorithm)
