"""The one place where NED/FRD (public API, Pinocchio) meets PyBullet's z-up world.

Conventions (docs/MODEL.md section 1):

* Inertial frame NED: x north, y east, z down. Body frame FRD: x forward, y starboard, z down, origin at
  the vehicle's geometric centre. Pinocchio works in NED directly (gravity ``+z``).
* PyBullet's world W is z-up: ``p_W = S p_NED`` with ``S = diag(1, -1, -1)``, a rotation by pi about x.
  The URDF is authored in body FRD coordinates, so a body orientation maps as ``R_WB = S R_NB`` and a
  frame whose own axes are also flipped (NED-like axes, e.g. a reference pose) as ``S R S``.
* Euler angles are ZYX (roll phi, pitch theta, yaw psi): ``R_NB = Rz(psi) Ry(theta) Rx(phi)``.
"""

from __future__ import annotations

import numpy as np

S = np.diag([1.0, -1.0, -1.0])
"""NED <-> PyBullet world axis flip (its own inverse)."""


def ned_to_world(p_ned: np.ndarray) -> np.ndarray:
    """Position (or any vector, ``(..., 3)``) from NED to PyBullet world coordinates."""
    return np.asarray(p_ned, dtype=float) * np.array([1.0, -1.0, -1.0])


def world_to_ned(p_w: np.ndarray) -> np.ndarray:
    """Position (or any vector, ``(..., 3)``) from PyBullet world to NED coordinates."""
    return np.asarray(p_w, dtype=float) * np.array([1.0, -1.0, -1.0])


def body_rot_ned_to_world(r_nb: np.ndarray) -> np.ndarray:
    """Orientation of an FRD-authored body: ``R_NB`` (NED) -> ``R_WB`` (PyBullet world)."""
    return S @ r_nb


def body_rot_world_to_ned(r_wb: np.ndarray) -> np.ndarray:
    """Orientation of an FRD-authored body: ``R_WB`` (PyBullet world) -> ``R_NB`` (NED)."""
    return S @ r_wb


def rot_ned_to_world(r_ned: np.ndarray) -> np.ndarray:
    """Similarity transform of a rotation whose both sides are flipped: ``S R S``."""
    return S @ r_ned @ S


def rot_world_to_ned(r_w: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rot_ned_to_world` (the same map)."""
    return S @ r_w @ S


def euler_to_rot(rpy: np.ndarray) -> np.ndarray:
    """ZYX Euler angles ``[phi, theta, psi]`` -> rotation matrix ``Rz(psi) Ry(theta) Rx(phi)``."""
    phi, theta, psi = (float(a) for a in rpy)
    cf, sf = np.cos(phi), np.sin(phi)
    ct, st = np.cos(theta), np.sin(theta)
    cp, sp = np.cos(psi), np.sin(psi)
    return np.array(
        [
            [cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st],
            [sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf],
            [-st, ct * sf, ct * cf],
        ]
    )


def rot_to_euler(r: np.ndarray) -> np.ndarray:
    """Rotation matrix -> ZYX Euler angles ``[phi, theta, psi]`` (theta in [-pi/2, pi/2])."""
    theta = -np.arcsin(np.clip(r[2, 0], -1.0, 1.0))
    phi = np.arctan2(r[2, 1], r[2, 2])
    psi = np.arctan2(r[1, 0], r[0, 0])
    return np.array([phi, theta, psi])


def euler_rate_matrix(rpy: np.ndarray) -> np.ndarray:
    """``T(eta2)`` with ``eta2dot = T nu2`` (Fossen). Singular at theta = +-pi/2."""
    phi, theta, _ = (float(a) for a in rpy)
    cf, sf = np.cos(phi), np.sin(phi)
    ct, tt = np.cos(theta), np.tan(theta)
    return np.array([[1.0, sf * tt, cf * tt], [0.0, cf, -sf], [0.0, sf / ct, cf / ct]])


def quat_xyzw_to_rot(q: np.ndarray) -> np.ndarray:
    """Unit quaternion ``[x, y, z, w]`` (PyBullet and Pinocchio order) -> rotation matrix."""
    x, y, z, w = (float(v) for v in q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def rot_to_quat_xyzw(r: np.ndarray) -> np.ndarray:
    """Rotation matrix -> unit quaternion ``[x, y, z, w]`` with ``w >= 0``."""
    m = np.asarray(r, dtype=float)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0.0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = np.array([(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s])
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = np.array([0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s])
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = np.array([(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s])
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = np.array([(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s])
    q /= np.linalg.norm(q)
    return q if q[3] >= 0.0 else -q


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Wrap angle(s) to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def rot_error(r_des: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Orientation error vector (axis * angle, inertial frame) taking ``r`` to ``r_des``."""
    re = r_des @ r.T
    cos_a = np.clip((np.trace(re) - 1.0) / 2.0, -1.0, 1.0)
    angle = np.arccos(cos_a)
    v = np.array([re[2, 1] - re[1, 2], re[0, 2] - re[2, 0], re[1, 0] - re[0, 1]])
    s = np.sin(angle)
    if s < 1e-9:
        if angle < 1e-6:
            return 0.5 * v
        # angle ~ pi: axis from the symmetric part
        axis = np.sqrt(np.maximum((np.diag(re) + 1.0) / 2.0, 0.0))
        i = int(np.argmax(axis))
        axis[np.arange(3) != i] = (re[i, np.arange(3) != i] + re[np.arange(3) != i, i]) / (4.0 * axis[i])
        return angle * axis / np.linalg.norm(axis)
    return angle * v / (2.0 * s)


def euler_to_rot_batch(rpy: np.ndarray) -> np.ndarray:
    """Vectorised :func:`euler_to_rot`: ``(N, 3)`` Euler angles -> ``(N, 3, 3)`` rotations."""
    rpy = np.asarray(rpy, dtype=float)
    cf, sf = np.cos(rpy[:, 0]), np.sin(rpy[:, 0])
    ct, st = np.cos(rpy[:, 1]), np.sin(rpy[:, 1])
    cp, sp = np.cos(rpy[:, 2]), np.sin(rpy[:, 2])
    out = np.empty((rpy.shape[0], 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf
    out[:, 2, 0], out[:, 2, 1], out[:, 2, 2] = -st, ct * sf, ct * cf
    return out


def rot_error_batch(r_des: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Vectorised :func:`rot_error` for ``(N, 3, 3)`` desired rotations and one current rotation ``r``."""
    re = r_des @ r.T
    cos_a = np.clip((np.trace(re, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    angle = np.arccos(cos_a)
    v = np.stack([re[:, 2, 1] - re[:, 1, 2], re[:, 0, 2] - re[:, 2, 0], re[:, 1, 0] - re[:, 0, 1]], axis=1)
    s = np.sin(angle)
    out = np.empty_like(v)
    regular = s >= 1e-9
    out[regular] = (angle[regular] / (2.0 * s[regular]))[:, None] * v[regular]
    for i in np.flatnonzero(~regular):  # identity or a half turn: the scalar version handles both
        out[i] = rot_error(r_des[i], r)
    return out
