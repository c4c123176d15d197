"""Names the command line, the configuration and the env factory share; light (no torch, no SB3).

``uvdms`` builds its subcommand parsers at start-up from these, so this module imports nothing heavy.
"""

from __future__ import annotations

ALGO_NAMES: tuple[str, ...] = ("dagger", "ppo", "ppo_lagrangian", "sac", "td3", "td3_prior", "tqc")
"""Names of :data:`agents.algos.ALGOS` (kept equal to its keys; checked by the tests)."""
DEFAULT_GYM_PACKAGES: tuple[str, ...] = ("uvdms_gym",)
"""Packages imported by default so that the env ids are registered."""
NO_BASE = "none"
"""``--residual none``: no residual base (the policy outputs the whole command), whatever the config file says."""
RESIDUAL_OBSERVATION_NAMES: tuple[str, ...] = ("base", "clearance")
"""Choices of ``--residual-observation``: :data:`uvdms_gym.residual.RESIDUAL_OBSERVATIONS` (checked by the tests)."""
RESIDUAL_SPACE_NAMES: tuple[str, ...] = ("full", "nullspace")
"""Choices of ``--residual-space``: :data:`uvdms_gym.residual.RESIDUAL_SPACES` (checked by the tests)."""
VEC_ENV_TYPES: tuple[str, ...] = ("dummy", "subproc", "hybrid", "rollout")
"""Vectorised environment types of ``--vec-env`` (:func:`agents.common.envs.make_vec_env`)."""
