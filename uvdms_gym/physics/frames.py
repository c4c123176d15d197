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
    """Vectorised :func:`euler_to_rot`: ZYX Euler angles ``(..., 3)`` -> rotations ``(..., 3, 3)`` (``Rz Ry Rx``).

    Args:
        rpy: roll, pitch, yaw.

    Returns:
        The rotations.
    """
    rpy = np.asarray(rpy, dtype=float)
    c, s = np.cos(rpy), np.sin(rpy)  # one call each (elementwise: the same values as per column)
    cf, ct, cp = c[..., 0], c[..., 1], c[..., 2]
    sf, st, sp = s[..., 0], s[..., 1], s[..., 2]
    r = np.empty((*rpy.shape[:-1], 3, 3))
    r[..., 0, 0] = cp * ct
    r[..., 0, 1] = -sp * cf + cp * st * sf
    r[..., 0, 2] = sp * sf + cp * cf * st
    r[..., 1, 0] = sp * ct
    r[..., 1, 1] = cp * cf + sf * st * sp
    r[..., 1, 2] = -cp * sf + st * sp * cf
    r[..., 2, 0] = -st
    r[..., 2, 1] = ct * sf
    r[..., 2, 2] = ct * cf
    return r


_VEE_PLUS = (np.array([2, 0, 1]), np.array([1, 2, 0]))
_VEE_MINUS = (np.array([1, 2, 0]), np.array([2, 0, 1]))


def rot_error_batch(r_des: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Vectorised :func:`rot_error`: error vectors (axis * angle, inertial frame) taking ``r`` to each ``r_des``.

    The angle is in ``[0, pi]`` (wrapped by construction); to first order the vector changes by
    ``-omega dt`` when the body turns at the inertial angular velocity ``omega``.

    Args:
        r_des: desired rotations (N, 3, 3).
        r: current rotation (3, 3).

    Returns:
        Errors (N, 3).
    """
    re = np.asarray(r_des) @ np.asarray(r).T
    v = re[:, _VEE_PLUS[0], _VEE_PLUS[1]] - re[:, _VEE_MINUS[0], _VEE_MINUS[1]]  # [R32 - R23, R13 - R31, R21 - R12]
    # the trace summed in np.trace's order and clipped with min/max: the same values for less per-call overhead
    cos_a = np.minimum(np.maximum((re[:, 0, 0] + re[:, 1, 1] + re[:, 2, 2] - 1.0) / 2.0, -1.0), 1.0)
    angle = np.arccos(cos_a)
    s = np.sin(angle)
    ok = s > 1e-6
    if ok.all():  # the usual case: no angle near 0 or pi
        return (angle / (2.0 * s))[:, None] * v
    out = np.empty_like(v)
    out[ok] = (angle[ok] / (2.0 * s[ok]))[:, None] * v[ok]
    small = ~ok & (angle < 0.5)
    out[small] = 0.5 * v[small]
    for i in np.flatnonzero(~ok & ~small):  # angle ~ pi: rare, use the careful scalar version
        out[i] = rot_error(r_des[i], r)
    return out
