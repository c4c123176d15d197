"""Fixtures shared across test files (each defined in its own module, registered here)."""

from ray_support import ray_processes  # noqa: F401  (the fixture is registered by being imported here)
