"""Fixtures of the agents tests: the tiny configurations and the shared training runs (session-wide)."""

from pathlib import Path

import pytest

from tests.support.agent_runs import ALGO_NAMES, Runs, write_config


@pytest.fixture(scope="session")
def config_dir(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("configs")
    for algo in ALGO_NAMES:
        write_config(folder, algo)
    return folder


@pytest.fixture(scope="session")
def runs(tmp_path_factory, config_dir) -> Runs:
    """The shared training runs (:class:`Runs`), shared by several tests."""
    return Runs(tmp_path_factory.mktemp("runs"), config_dir)
