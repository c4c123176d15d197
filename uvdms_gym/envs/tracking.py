"""Tracking errors of the observation's preview blocks: end-effector positions (circles) and object pose (transport).

Moved out of :mod:`uvdms_gym.envs.base`, which re-exports both functions.
"""

from __future__ import annotations

import math

import numpy as np

from uvdms_gym.physics.frames import euler_to_rot, rot_error
from uvdms_gym.utils.jit import jit

POS_SCALE = 0.5
"""Position errors in the observation are divided by this, m."""
OBS_CLIP = 10.0
"""Every observation value is clipped to ``[-OBS_CLIP, OBS_CLIP]``."""
CLEARANCE_CLIP = 0.3
"""Clearances are clipped to ``[0, CLEARANCE_CLIP]`` m before scaling (``uvdms_gym.envs.base``'s observation)."""


def errors_positions(y: np.ndarray, refs: np.ndarray, r_nb: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Circle tracking: both end-effector position errors in the body frame; mean error norm (now)."""
    e = (refs - y).reshape(-1, 3)  # (2 P, 3): left, right for each preview time
    blk = (e @ r_nb).reshape(-1) / POS_SCALE  # rows r_nb^T e
    return blk, float(0.5 * (np.linalg.norm(e[0]) + np.linalg.norm(e[1]))), 0.0


def errors_pose(p: np.ndarray, r: np.ndarray, refs: np.ndarray, r_nb: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Object transport: position error and orientation error (rotation vector), both in the body frame.

    The orientation errors are :func:`uvdms_gym.physics.frames.rot_error` of ``euler_to_rot(ref)`` and ``r``, written
    out in one compiled kernel for the few preview rows (numpy's per-call cost on 3x3 arrays was most of the
    work); near-identity and half-turn errors, where the kernel's axis formula loses accuracy, go to
    :func:`~uvdms_gym.physics.frames.rot_error` itself.

    Returns:
        The observation block (per preview row: ``r_nb^T e_p / POS_SCALE``, ``r_nb^T e_o``), ``|e_p|`` and
        ``|e_o|`` of the first row.
    """
    refs = np.ascontiguousarray(refs, dtype=float)
    n = refs.shape[0]
    blk = np.empty(6 * n)
    e_o = np.empty((n, 3))
    p = np.ascontiguousarray(p, dtype=float)
    r = np.ascontiguousarray(r, dtype=float)
    r_nb = np.ascontiguousarray(r_nb, dtype=float)
    if not _pose_errors(p, r, refs, r_nb, POS_SCALE, e_o, blk):
        e_o = np.array([rot_error(euler_to_rot(ref), r) for ref in refs[:, 3:]])
        e_p = refs[:, :3] - p
        blk = np.concatenate([e_p @ r_nb / POS_SCALE, e_o @ r_nb], axis=1).reshape(-1)
    e_p0 = refs[0, :3] - p
    return blk, math.sqrt(float(e_p0 @ e_p0)), math.sqrt(float(e_o[0] @ e_o[0]))


@jit
def _pose_errors(p, r, refs, r_nb, pos_scale, e_o, blk):  # pragma: no cover - compiled
    """The rows of :func:`errors_pose`; False (outputs incomplete) if a row's rotation angle has ``sin < 1e-9``.

    ``R_des = frames.euler_to_rot(ref[3:])`` (ZYX), the angle of ``R_des r^T`` from its trace and the axis from
    its skew part; then both errors rotated into the body frame (``e @ r_nb``).
    """
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = (
        r[0, 0],
        r[0, 1],
        r[0, 2],
        r[1, 0],
        r[1, 1],
        r[1, 2],
        r[2, 0],
        r[2, 1],
        r[2, 2],
    )
    for i in range(refs.shape[0]):
        phi, theta, psi = refs[i, 3], refs[i, 4], refs[i, 5]
        cf, sf, ct, st, cp, sp = np.cos(phi), np.sin(phi), np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
        d00, d01, d02 = cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st
        d10, d11, d12 = sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf
        d20, d21, d22 = -st, ct * sf, ct * cf
        e00 = d00 * r00 + d01 * r01 + d02 * r02
        e11 = d10 * r10 + d11 * r11 + d12 * r12
        e22 = d20 * r20 + d21 * r21 + d22 * r22
        angle = np.arccos(min(max((e00 + e11 + e22 - 1.0) / 2.0, -1.0), 1.0))
        s = np.sin(angle)
        if s < 1e-9:
            return False
        k = angle / (2.0 * s)
        e_o[i, 0] = k * ((d20 * r10 + d21 * r11 + d22 * r12) - (d10 * r20 + d11 * r21 + d12 * r22))
        e_o[i, 1] = k * ((d00 * r20 + d01 * r21 + d02 * r22) - (d20 * r00 + d21 * r01 + d22 * r02))
        e_o[i, 2] = k * ((d10 * r00 + d11 * r01 + d12 * r02) - (d00 * r10 + d01 * r11 + d02 * r12))
        ex, ey, ez = refs[i, 0] - p[0], refs[i, 1] - p[1], refs[i, 2] - p[2]
        for j in range(3):
            blk[6 * i + j] = (ex * r_nb[0, j] + ey * r_nb[1, j] + ez * r_nb[2, j]) / pos_scale
            blk[6 * i + 3 + j] = e_o[i, 0] * r_nb[0, j] + e_o[i, 1] * r_nb[1, j] + e_o[i, 2] * r_nb[2, j]
    return True
