"""A run's configuration.

The ``TrainConfig`` schema of ``train_configs/<algo>.yml`` (``schema``), reading and checking the files
(``files``), the generic YAML-to-dataclass checker (``typecheck``), RL Zoo's keys (``zoo``) and the whitelisted
``policy_kwargs`` classes (``policy_kwargs``). The public names are re-exported here (``from agents.config import
TrainConfig, load_config``).
"""

from agents.common.wrappers import is_unit_scale
from agents.config.files import default_config_path, load_config, parse_entry, read_config_file, validate_config_file
from agents.config.schema import DEFAULT_ENTRY, NOISE_TYPES, LinearSchedule, TrainConfig
from agents.config.typecheck import ConfigError

__all__ = [
    "DEFAULT_ENTRY",
    "NOISE_TYPES",
    "ConfigError",
    "LinearSchedule",
    "TrainConfig",
    "default_config_path",
    "is_unit_scale",
    "load_config",
    "parse_entry",
    "read_config_file",
    "validate_config_file",
]
