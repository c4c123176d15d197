"""The Lagrangian pieces of PPO-Lagrangian (:mod:`agents.algos.ppo_lagrangian`), each tested on its own.

Dual ascent on the multiplier, GAE for the cost, the combined advantages, the per-step costs read from ``info``,
the argument checks, one rollout's :class:`DualUpdate`, and the ``lagrangian.csv`` history
(:class:`LagrangianHistory`, :func:`read_history`).
"""

import csv
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

COST_KEY = "cost"
"""The ``info`` entry holding the per-step safety cost (Safety-Gymnasium convention)."""
ADVANTAGE_EPS = 1e-8
"""Added to the standard deviation when standardising the reward advantages (SB3's and OmniSafe's value)."""
HISTORY_FILE = "lagrangian.csv"
"""Per-rollout record of the multiplier in a run directory (:class:`LagrangianHistory`)."""
HISTORY_FIELDS = ("segment", "update", "num_timesteps", "n_episodes", "episode_cost", "cost_limit", "lambda")
"""Columns of :data:`HISTORY_FILE` (``episode_cost`` is empty when no episode ended in the rollout)."""


# ------------------------------------------------------------------------------------------------------
# Pure pieces (tested on their own)
# ------------------------------------------------------------------------------------------------------
def dual_ascent(multiplier: float, episode_cost: float, cost_limit: float, lr: float) -> float:
    """One projected gradient-ascent step of the Lagrange multiplier.

    Args:
        multiplier: Current ``lambda >= 0``.
        episode_cost: Mean per-episode cost ``J_c`` of the rollout's finished episodes.
        cost_limit: The per-episode budget ``d``.
        lr: Step size ``lagrangian_lr``.

    Returns:
        ``max(0, multiplier + lr * (episode_cost - cost_limit))``.
    """
    return max(0.0, multiplier + lr * (episode_cost - cost_limit))


def gae(
    rewards: np.ndarray,
    values: np.ndarray,
    episode_starts: np.ndarray,
    last_values: np.ndarray,
    last_dones: np.ndarray,
    gamma: float,
    gae_lambda: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Generalised advantage estimates and TD(lambda) returns, SB3's ``RolloutBuffer`` formula.

    Args:
        rewards: ``(n_steps, n_envs)`` per-step signal (here the cost, truncations already bootstrapped).
        values: ``(n_steps, n_envs)`` value estimates of the visited states.
        episode_starts: ``(n_steps, n_envs)`` 1 where a step starts an episode.
        last_values: ``(n_envs,)`` value of the observation after the last step.
        last_dones: ``(n_envs,)`` whether the last step ended an episode.
        gamma: Discount factor.
        gae_lambda: GAE's bias-variance factor.

    Returns:
        ``(advantages, returns)``, both ``(n_steps, n_envs)`` float32.
    """
    n_steps = rewards.shape[0]
    advantages = np.zeros_like(rewards, dtype=np.float32)
    last_gae = np.zeros(rewards.shape[1], dtype=np.float32)
    for step in reversed(range(n_steps)):
        if step == n_steps - 1:
            next_non_terminal = 1.0 - last_dones.astype(np.float32)
            next_values = last_values
        else:
            next_non_terminal = 1.0 - episode_starts[step + 1]
            next_values = values[step + 1]
        delta = rewards[step] + gamma * next_values * next_non_terminal - values[step]
        last_gae = delta + gamma * gae_lambda * next_non_terminal * last_gae
        advantages[step] = last_gae
    return advantages, (advantages + values).astype(np.float32)


def lagrangian_advantages(reward_adv: np.ndarray, cost_adv: np.ndarray, multiplier: float) -> np.ndarray:
    """``(A_r - lambda A_c) / (1 + lambda)`` with ``A_r`` standardised and ``A_c`` centred over the rollout.

    Args:
        reward_adv: Reward advantages of the rollout.
        cost_adv: Cost advantages of the rollout (same shape).
        multiplier: ``lambda >= 0``.

    Returns:
        The advantages PPO's surrogate uses (float32, same shape).
    """
    a_r = (reward_adv - reward_adv.mean()) / (reward_adv.std() + ADVANTAGE_EPS)
    a_c = cost_adv - cost_adv.mean()
    return ((a_r - multiplier * a_c) / (1.0 + multiplier)).astype(np.float32)


def step_costs(infos: list[dict[str, Any]]) -> np.ndarray:
    """The per-env costs ``info["cost"]`` of one vector-env step.

    Raises:
        ValueError: An ``info`` without a finite numeric ``cost``.
    """
    costs = np.empty(len(infos), dtype=np.float64)
    for i, info in enumerate(infos):
        if COST_KEY not in info:
            raise ValueError(
                f"ppo_lagrangian reads the per-step safety cost from info[{COST_KEY!r}] (Safety-Gymnasium "
                f"convention), but env {i}'s step info has no {COST_KEY!r} (keys: {sorted(info)})"
            )
        try:
            cost = float(info[COST_KEY])
        except (TypeError, ValueError):
            raise ValueError(f"env {i}: info[{COST_KEY!r}] must be a number, got {info[COST_KEY]!r}") from None
        if not math.isfinite(cost):
            raise ValueError(f"env {i}: info[{COST_KEY!r}] must be finite, got {cost}")
        costs[i] = cost
    return costs


def check_lagrangian_args(values: Mapping[str, Any]) -> None:
    """Range checks of the Lagrangian keys present in ``values`` (shared by the class and the config loader).

    Raises:
        ValueError: Naming the key: ``cost_limit`` and ``lagrangian_init`` must be finite and >= 0,
            ``lagrangian_lr`` finite and > 0.
    """
    for key, positive in (("cost_limit", False), ("lagrangian_lr", True), ("lagrangian_init", False)):
        if key not in values:
            continue
        value = values[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ValueError(f"key {key!r} must be a finite number, got {value!r}")
        if value < 0 or (positive and value == 0):
            raise ValueError(f"key {key!r} must be {'> 0' if positive else '>= 0'}, got {value}")


@dataclass(frozen=True)
class DualUpdate:
    """One rollout's multiplier update (a row of :data:`HISTORY_FILE` without the segment).

    Attributes:
        update: Rollouts since training started (over all segments; 1 for the first).
        num_timesteps: The model's step count after the rollout.
        n_episodes: Episodes that ended in the rollout.
        episode_cost: Their mean summed cost ``J_c`` (``None`` without episodes: ``lambda`` unchanged).
        cost_limit: The budget.
        multiplier: ``lambda`` after the update (the one the following policy update uses).
    """

    update: int
    num_timesteps: int
    n_episodes: int
    episode_cost: float | None
    cost_limit: float
    multiplier: float


# ------------------------------------------------------------------------------------------------------
# The history file
# ------------------------------------------------------------------------------------------------------
class LagrangianHistory(BaseCallback):
    """Appends each rollout's :class:`DualUpdate` of a :class:`PPOLagrangian` to a CSV file.

    The update happens after a rollout; the row is written when the next rollout starts or training ends.
    The file is appended to across training segments (``segment`` column); :data:`HISTORY_FIELDS` are the columns.
    ``update`` continues the resumed model's count, so after resuming from a checkpoint older than the last row
    (a crash between checkpoints) an update number appears twice, with different segments.

    Args:
        path: The CSV file (``<run dir>/lagrangian.csv``).
        segment: Training segment written in every row.
    """

    def __init__(self, path: str | Path, segment: int = 0) -> None:
        super().__init__()
        self.path = Path(path)
        self.segment = segment
        self._written = 0

    def _init_callback(self) -> None:
        if not hasattr(self.model, "last_dual_update"):  # a PPOLagrangian (agents.algos.ppo_lagrangian)
            raise TypeError(f"LagrangianHistory needs a PPOLagrangian model, got {type(self.model).__name__}")
        self._written = self.model.n_dual_updates

    def _on_step(self) -> bool:
        return True

    def _on_rollout_start(self) -> None:
        self._write_pending()

    def _on_training_end(self) -> None:
        self._write_pending()

    def _write_pending(self) -> None:
        update = self.model.last_dual_update
        if update is None or update.update <= self._written:
            return
        new_file = not self.path.is_file()
        row = asdict(update)
        row["lambda"] = row.pop("multiplier")
        row["episode_cost"] = "" if row["episode_cost"] is None else row["episode_cost"]
        with self.path.open("a", encoding="utf-8", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=HISTORY_FIELDS)
            if new_file:
                writer.writeheader()
            writer.writerow({"segment": self.segment, **row})
        self._written = update.update


def read_history(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a :data:`HISTORY_FILE` with numbers parsed (``episode_cost`` ``None`` when empty)."""
    with Path(path).open(encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    ints = ("segment", "update", "num_timesteps", "n_episodes")
    return [
        {
            **{key: int(row[key]) for key in ints},
            "episode_cost": float(row["episode_cost"]) if row["episode_cost"] else None,
            "cost_limit": float(row["cost_limit"]),
            "lambda": float(row["lambda"]),
        }
        for row in rows
    ]
