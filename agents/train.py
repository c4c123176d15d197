"""``python -m agents.train`` and the training names documented at this path (moved to :mod:`agents.training`).

The implementation lives in :mod:`agents.training.train` (the loop and ``--resume``), :mod:`agents.training.spec`
(the run specification) and :mod:`agents.training.segment` (one training segment); this module re-exports the
names users and RL Zoo configurations import from ``agents.train`` and runs the command line.
"""

import sys

from agents.training.train import (
    CHECKPOINT_PREFIX,
    EVAL_SEED_OFFSET,
    SEGMENT_SEED_STRIDE,
    ActionComponents,
    AliveBonus,
    Checkpoint,
    EnvFactory,
    EnvironmentNotFoundError,
    RunDirError,
    ScaledAction,
    check_env_id,
    composition_factories,
    eval_env_seed,
    git_info,
    grow_replay_buffer,
    import_gym_packages,
    latest_checkpoint,
    main,
    package_versions,
    parse_key_values,
    replay_buffer_size,
    resolve_config,
    run_dir_for,
    scale_action_layer,
    train,
    train_env_seed,
    zip_num_timesteps,
)

__all__ = [
    "CHECKPOINT_PREFIX",
    "EVAL_SEED_OFFSET",
    "SEGMENT_SEED_STRIDE",
    "ActionComponents",
    "AliveBonus",
    "Checkpoint",
    "EnvFactory",
    "EnvironmentNotFoundError",
    "RunDirError",
    "ScaledAction",
    "check_env_id",
    "composition_factories",
    "eval_env_seed",
    "git_info",
    "grow_replay_buffer",
    "import_gym_packages",
    "latest_checkpoint",
    "main",
    "package_versions",
    "parse_key_values",
    "replay_buffer_size",
    "resolve_config",
    "run_dir_for",
    "scale_action_layer",
    "train",
    "train_env_seed",
    "zip_num_timesteps",
]

if __name__ == "__main__":
    sys.exit(main())
