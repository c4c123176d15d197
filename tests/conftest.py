"""Fixtures shared across test files (each defined in its own module, registered here)."""

import os

import pytest

from tests.support.ray_cluster import ray_processes  # noqa: F401  (the fixture is registered by being imported here)


@pytest.fixture(scope="session", autouse=True)
def sb3_logs_under_pytest_tmp(tmp_path_factory):
    """SB3 models learning without a configured logger make an empty ``SB3-<date>`` folder: under pytest's tmp.

    Tests write only under their ``tmp_path`` (tests/integration/test_temp_hygiene.py checks the library's own paths
    leave
    the system temp directory alone).
    """
    previous = os.environ.get("SB3_LOGDIR")
    os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3_logs"))
    yield
    if previous is None:
        os.environ.pop("SB3_LOGDIR", None)
    else:
        os.environ["SB3_LOGDIR"] = previous
