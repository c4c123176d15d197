"""Fixtures of the uvdms_gym tests (every subdirectory): the plant with arms, without self-collision, bare."""

import pytest

from uvdms_gym.physics.params import UVDMSParams
from uvdms_gym.physics.sim import UVDMSSim

P = UVDMSParams()


@pytest.fixture
def sim():
    s = UVDMSSim(P)
    yield s
    s.close()


@pytest.fixture
def sim_nc():
    """No self-collision: the random states of the dynamics checks may put links inside each other."""
    s = UVDMSSim(P, self_collision=False)
    yield s
    s.close()


@pytest.fixture
def bare():
    s = UVDMSSim(P, arms=False)
    yield s
    s.close()


@pytest.fixture(scope="module")
def kin():
    """A kinematic model of the default parameters (its state is set by each test)."""
    from uvdms_gym.physics.kinematics import KinematicModel

    return KinematicModel(P)
