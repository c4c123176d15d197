"""The training callbacks under the names the RL Zoo configurations use (``agents.callbacks.ScaleInitialActions``).

``train_configs/<algo>.yml`` name them in ``callback`` lists, which RL Zoo imports by this dotted path; the
implementation lives in :mod:`agents.training.callbacks`.
"""

from agents.training.callbacks import (
    DelayActorUpdates,
    LatestBufferCheckpointCallback,
    SaveBestExtras,
    ScaleInitialActions,
    SeededEvalCallback,
)

__all__ = [
    "DelayActorUpdates",
    "LatestBufferCheckpointCallback",
    "SaveBestExtras",
    "ScaleInitialActions",
    "SeededEvalCallback",
]
