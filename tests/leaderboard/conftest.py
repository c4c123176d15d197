"""Fixtures of the leaderboard's tests."""

import sys

import pytest

import uvdms_gym


@pytest.fixture
def release(monkeypatch):
    """``release(version)``: the code as a release of ``version`` sees it (until the test ends).

    Sets ``uvdms_gym.__version__`` and every copy of it a leaderboard module holds as ``PACKAGE_VERSION`` (the
    cache module held one up to 0.3), as a new install of that version would.
    """

    def bump(version: str) -> None:
        monkeypatch.setattr(uvdms_gym, "__version__", version)
        for name, module in list(sys.modules.items()):
            if name.split(".")[0] == "leaderboard" and "PACKAGE_VERSION" in vars(module):
                monkeypatch.setattr(module, "PACKAGE_VERSION", version)

    return bump
