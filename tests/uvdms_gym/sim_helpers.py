"""Helpers of the simulator tests: random states, Pinocchio configurations, the mass matrix."""

import numpy as np
import pinocchio as pin

from uvdms_gym.physics import frames


def random_state(rng: np.random.Generator, n_joints: int = 12, scale: float = 1.0):
    eta = np.r_[rng.uniform(-5, 5, 3), rng.uniform(-1.2, 1.2, 2), rng.uniform(-3.0, 3.0)]
    nu = rng.normal(size=6) * 0.5 * scale
    q = rng.uniform(-1.5, 1.5, n_joints)
    qdot = rng.normal(size=n_joints) * 0.5 * scale
    return eta, nu, q, qdot


def pin_config(eta: np.ndarray, q: np.ndarray) -> np.ndarray:
    return np.r_[eta[:3], pin.Quaternion(frames.euler_to_rot(eta[3:])).coeffs(), q]


def mass_matrix(pm, pd, qp):
    m = pin.crba(pm, pd, qp)
    return np.triu(m) + np.triu(m, 1).T
