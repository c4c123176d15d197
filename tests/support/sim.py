"""Helpers of the simulator tests: random states, Pinocchio configurations, the mass matrix, the reference step."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from uvdms_gym.physics import frames, hydro, model
from uvdms_gym.physics.params import UVDMSParams
from uvdms_gym.physics.sim import UVDMSSim
from uvdms_gym.physics.state import SimState

P = UVDMSParams()


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


def reference_acceleration(
    s: UVDMSSim, pm, pd, st: SimState, tau: np.ndarray, nudot_est: np.ndarray, current: np.ndarray | None = None
):
    """Pinocchio ABA with the reference hydrodynamics of uvdms_gym.physics.hydro applied at the documented points.

    ``current`` (NED, m/s): the vehicle wrench of the relative velocity ``nu_r`` (``nudot_est`` is then the lagged
    estimate of ``nu_r``'s derivative) and the links' Morison drag on ``v - v_c`` (Pinocchio's world is NED).
    """
    h, params = s.hydro, s.params
    r_nb = frames.euler_to_rot(st.eta[3:])
    qp, v = pin_config(st.eta, st.q), st.zeta
    pin.forwardKinematics(pm, pd, qp, v)
    pin.updateFramePlacements(pm, pd)
    pin.computeJointJacobians(pm, pd, qp)
    f = tau.astype(float).copy()
    f[6:] -= params.arm.joint_friction * st.qdot  # gear friction (PyBullet jointDamping)
    nu_r = st.nu if current is None else hydro.relative_body_velocity(st.nu, r_nb, current)
    f[:6] += hydro.vehicle_wrench(nu_r, nudot_est, h)
    f_up = h.up_force * (r_nb.T @ np.array([0.0, 0.0, -1.0]))  # NED up in body coordinates
    f[:3] += f_up
    f[3:6] += np.cross(h.up_centroid, f_up)
    k = 0
    for side in ("left", "right"):
        for i in range(1, 7):
            fid = pm.getFrameId(f"{side}_link{i}")
            a, b = model.link_segment(params, i)
            o_m_f = pd.oMf[fid]
            mid = o_m_f.act(0.5 * (a + b))
            jac = pin.getFrameJacobian(pm, pd, fid, pin.LOCAL_WORLD_ALIGNED)
            jp = jac[:3] - pin.skew(mid - o_m_f.translation) @ jac[3:]
            axis = o_m_f.rotation @ model.link_axis(params, i)
            force = hydro.link_force(
                jp @ v, axis, h.link_buoyancy[k], h.link_kn[k], h.link_kt[k], up=(0, 0, -1.0), current=current
            )
            f += jp.T @ np.array(force)
            k += 1
    return pin.aba(pm, pd, qp, v, f)


def com_velocity_world(st: SimState) -> np.ndarray:
    r_wb = frames.body_rot_ned_to_world(frames.euler_to_rot(st.eta[3:]))
    r_g = r_wb @ np.array(P.vehicle.r_g)
    w = r_wb @ st.nu[3:]
    return r_wb @ st.nu[:3] + np.cross(w, r_g)


def com_acceleration_world(st: SimState, acc: np.ndarray) -> np.ndarray:
    """Classical acceleration of the base COM (PyBullet integrates this velocity in the world frame)."""
    nu, w, r_g = st.nu, st.nu[3:], np.array(P.vehicle.r_g)
    a_o = acc[:3] + np.cross(w, nu[:3])
    a_c = a_o + np.cross(acc[3:6], r_g) + np.cross(w, np.cross(w, r_g))
    return frames.body_rot_ned_to_world(frames.euler_to_rot(st.eta[3:])) @ a_c
