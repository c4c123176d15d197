"""uvdms-gym: a Gymnasium benchmark for an underwater vehicle-dual-manipulator system (UVDMS)."""

from uvdms_gym.params import UVDMSParams

__version__ = "0.1.0"
__all__ = ["UVDMSParams", "__version__"]
