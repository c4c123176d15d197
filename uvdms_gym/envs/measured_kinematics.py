"""The frames and the observation of a measured (or estimated) state, compiled: what ``observe_estimate`` runs.

:class:`MeasuredKinematics` places the frames the observation reads in one forward-kinematics pass (Pinocchio's
tree transcribed, no Jacobians) and :func:`assemble_observation` assembles the 80 values in one call, equal to
:meth:`uvdms_gym.envs.base.UVDMSEnv._assemble`. At ``realism > 0`` the environment observes the measured state every
step (:mod:`uvdms_gym.envs.realism_layer`); at ``realism=0`` nothing here runs.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from uvdms_gym.distances import kernels as distance_kernels
from uvdms_gym.distances.exact import N_ROWS
from uvdms_gym.envs.tracking import CLEARANCE_CLIP, OBS_CLIP
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.params import ARM_SIDES, D1, D2, N_JOINTS
from uvdms_gym.utils.jit import jit
from uvdms_gym.utils.validation import finite_vector

FREE_FLYER = "JointModelFreeFlyer"
"""Pinocchio's name of the root joint :class:`MeasuredKinematics` expects."""
REVOLUTE_Z = "JointModelRZ"
"""Pinocchio's name of the joints :class:`MeasuredKinematics` expects after the root (revolute about z)."""
PLACEMENT_ROWS = 4
"""Rows of a placement in :class:`MeasuredKinematics`' tables: the rotation (3 rows), then the translation."""


class MeasuredKinematics:
    """The frame placements of a measured (or estimated) state, in one compiled forward-kinematics pass.

    What the observation of a state reads of a :class:`~uvdms_gym.physics.kinematics.KinematicModel` (the vehicle
    frame, the tool tips, the grasp frames and the links' capsule axes), with the same read API
    (:meth:`frame_placement`, :meth:`link_segments`, :meth:`ee_positions`, :meth:`object_pose`) and no Jacobians:
    the environment's :meth:`~uvdms_gym.envs.base.UVDMSEnv.observe_estimate` runs it every step at ``realism > 0``,
    where Pinocchio's own pass costs little but reading its frames from Python costs several times more. The joint
    and frame placements come from the model's Pinocchio tree (a free-flyer root, revolute-z joints); the
    placements equal Pinocchio's to rounding (``tests/uvdms_gym/realism/test_realism_env.py``).

    Args:
        kin: the kinematic model whose tree is transcribed (:meth:`supports` must hold).
    """

    def __init__(self, kin: KinematicModel) -> None:
        if not self.supports(kin):
            raise ValueError("MeasuredKinematics needs a free-flyer root and revolute-z joints")
        m = kin.model
        self.params = kin.params
        joints = range(m.njoints)
        self._joints = np.array([[m.parents[j], m.idx_qs[j] - 7] for j in joints], dtype=np.int64)
        self._joint_table = np.array([_placement_rows(m.jointPlacements[j]) for j in joints])
        names = ["vehicle", *(f"{s}_ee" for s in ARM_SIDES), *(f"{s}_grasp" for s in ARM_SIDES)]
        n_links = kin.params.arm.n_links
        names += [f"{s}_link{i}" for s in ARM_SIDES for i in range(n_links)]
        fid = {f.name: i for i, f in enumerate(m.frames)}
        self._row = {name: k for k, name in enumerate(names)}
        self._frame_joint = np.array([m.frames[fid[n]].parentJoint for n in names], dtype=np.int64)
        self._frame_table = np.array([_placement_rows(m.frames[fid[n]].placement) for n in names])
        self._first_link = len(names) - 2 * n_links
        self._seg_local = np.ascontiguousarray(kin._seg_local_h[:, :, :3])  # (2 n_links, 2, 3), link frames
        self._frames = np.zeros((len(names), PLACEMENT_ROWS, 3))
        self._seg = np.zeros((2, n_links, 2, 3))
        self._plates = distance_kernels.plate_table(kin.params.plates)
        self._scratch = (np.empty((N_ROWS, 3)), np.empty((N_ROWS, 3)), np.empty(N_ROWS, dtype=np.int64))
        """The distance kernel's closest points and obstacle indices (not handed out: reused)."""
        self.set_state(np.zeros(6), np.zeros(N_JOINTS))  # compiles (or loads) the kernel now, not in a step

    @staticmethod
    def supports(kin: KinematicModel) -> bool:
        """Whether the model is a free-flyer root with revolute-z joints (what the compiled pass transcribes)."""
        m = kin.model
        kinds = [m.joints[j].shortname() for j in range(1, m.njoints)]
        return kinds[:1] == [FREE_FLYER] and all(k == REVOLUTE_Z for k in kinds[1:])

    def set_state(self, eta: np.ndarray, q: np.ndarray, zeta: np.ndarray | None = None) -> None:
        """Place every frame at the state ``(eta, q)`` (``zeta`` is accepted and unused: no dynamics here).

        Raises:
            ValueError: ``eta`` or ``q`` has the wrong shape or non-finite entries (the message names it).
        """
        e, qq = np.asarray(eta, dtype=float), np.asarray(q, dtype=float)
        if e.shape != (6,) or qq.shape != (N_JOINTS,):
            e, qq = finite_vector(eta, 6, "eta"), finite_vector(q, N_JOINTS, "q")  # raises the detailed error
        seg = np.empty(self._seg.shape)  # a new array per state: link_segments() hands it out
        frames = self._frames  # never handed out (frame_placement copies): reused
        ok = _placements(
            e,
            qq,
            self._joints,
            self._joint_table,
            self._frame_joint,
            self._frame_table,
            self._first_link,
            self._seg_local,
            frames,
            seg.reshape(-1, 2, 3),
        )
        if not ok:
            finite_vector(eta, 6, "eta")
            finite_vector(q, N_JOINTS, "q")
        seg.flags.writeable = False
        self._seg = seg

    def frame_placement(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (3) and rotation (3x3, frame -> NED) of a tabulated frame: the vehicle, tool tips, grasps, links."""
        f = self._frames[self._row[name]]
        return f[3].copy(), f[:3].copy()

    def link_segments(self) -> np.ndarray:
        """Capsule axes of all links in NED, ``(2, n_links, 2, 3)`` (read only), as ``KinematicModel``'s."""
        return self._seg

    def clearances(self) -> np.ndarray:
        """The 18 distances of :func:`~uvdms_gym.distances.compute_distances` (``"exact"``: the same kernel), new."""
        vehicle = self._frames[self._row["vehicle"]]
        d = np.empty(N_ROWS)
        distance_kernels.exact_rows(self._seg, vehicle[:3], vehicle[3], self._plates, d, *self._scratch)
        return d

    def ee_positions(self) -> np.ndarray:
        """Tool-tip positions (2, 3): row 0 left, row 1 right, NED."""
        return self._frames[1:3, 3].copy()

    def object_pose(self, side: str = "right") -> tuple[np.ndarray, np.ndarray]:
        """Pose of the gripped object's frame as carried by one arm: centre in NED and rotation object -> NED."""
        return self.frame_placement(f"{side}_grasp")


def _placement_rows(placement: Any) -> np.ndarray:
    """A Pinocchio ``SE3`` as ``PLACEMENT_ROWS x 3``: the rotation, then the translation."""
    return np.vstack([np.asarray(placement.rotation, dtype=float), np.asarray(placement.translation, dtype=float)])


@jit
def _placements(eta, q, joints, jtab, fjoint, ftab, first_link, seg_local, frames, seg):  # pragma: no cover - compiled
    """Forward kinematics of :class:`MeasuredKinematics`; False (outputs incomplete) for a non-finite state.

    Joint 0 is the universe, joint 1 the free flyer (``R_NB`` from the ZYX Euler angles ``eta[3:6]``, position
    ``eta[:3]``), every later joint revolute about its z axis at ``q[idx]``: ``oMi = oMi[parent] * placement *
    Rz(q)`` (``joints[j]``: parent and index in ``q``; ``jtab[j]``: placement). Frames: ``oMf = oMi[fjoint[f]]
    * ftab[f]``; link ``l``'s capsule end ``a``: ``R_f s_la + p_f``.
    """
    if not (np.isfinite(eta).all() and np.isfinite(q).all()):
        return False
    nj = joints.shape[0]
    om = np.zeros((nj, PLACEMENT_ROWS, 3))
    for r in range(3):
        om[0, r, r] = 1.0
    local = np.empty((PLACEMENT_ROWS, 3))
    _free_flyer(eta, local)
    tmp = np.empty((PLACEMENT_ROWS, 3))
    _compose(jtab[1], local, tmp)  # the root's placement: the identity in practice
    _compose(om[joints[1, 0]], tmp, om[1])
    for j in range(2, nj):
        _revolute_z(jtab[j], q[joints[j, 1]], local)
        _compose(om[joints[j, 0]], local, om[j])
    for f in range(fjoint.shape[0]):
        _compose(om[fjoint[f]], ftab[f], frames[f])
    for lk in range(seg_local.shape[0]):
        fr = frames[first_link + lk]
        for a in range(2):
            for r in range(3):
                x = fr[r, 0] * seg_local[lk, a, 0] + fr[r, 1] * seg_local[lk, a, 1] + fr[r, 2] * seg_local[lk, a, 2]
                seg[lk, a, r] = x + fr[3, r]
    return True


@jit
def _free_flyer(eta, out):  # pragma: no cover - compiled
    """The free flyer's motion: ``R_NB`` of the ZYX Euler angles ``eta[3:6]`` (``frames.euler_to_rot``), ``eta[:3]``."""
    cf, sf = math.cos(eta[3]), math.sin(eta[3])
    ct, st = math.cos(eta[4]), math.sin(eta[4])
    cp, sp = math.cos(eta[5]), math.sin(eta[5])
    out[0, 0], out[0, 1], out[0, 2] = cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st
    out[1, 0], out[1, 1], out[1, 2] = sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf
    out[2, 0], out[2, 1], out[2, 2] = -st, ct * sf, ct * cf
    out[3, 0], out[3, 1], out[3, 2] = eta[0], eta[1], eta[2]


@jit
def _revolute_z(placement, angle, out):  # pragma: no cover - compiled
    """``placement * Rz(angle)``: a revolute-z joint's placement in its parent and its motion."""
    c, s = math.cos(angle), math.sin(angle)
    for r in range(3):
        out[r, 0] = c * placement[r, 0] + s * placement[r, 1]
        out[r, 1] = -s * placement[r, 0] + c * placement[r, 1]
        out[r, 2] = placement[r, 2]
        out[3, r] = placement[3, r]


@jit
def _compose(a, b, out):  # pragma: no cover - compiled
    """``out = a * b`` of two placements (``PLACEMENT_ROWS x 3``): ``R = R_a R_b``, ``p = R_a p_b + p_a``."""
    for r in range(3):
        for c in range(3):
            out[r, c] = a[r, 0] * b[0, c] + a[r, 1] * b[1, c] + a[r, 2] * b[2, c]
        out[3, r] = (a[r, 0] * b[3, 0] + a[r, 1] * b[3, 1] + a[r, 2] * b[3, 2]) + a[3, r]


def assemble_observation(
    blocks: np.ndarray,
    eta: np.ndarray,
    nu: np.ndarray,
    q: np.ndarray,
    qdot: np.ndarray,
    d: np.ndarray,
    nu_scale: np.ndarray,
    qdot_scale: np.ndarray,
) -> np.ndarray:
    """:meth:`UVDMSEnv._assemble <uvdms_gym.envs.base.UVDMSEnv._assemble>` in one compiled call (float32).

    The same values in the same operation order (``sin`` and ``cos`` from the C library, as numpy's where it
    does not vectorize them; ``tests/uvdms_gym/realism/test_realism_env.py`` compares the two).
    """
    out = np.empty(blocks.size + 2 + nu.size + 2 * q.size + qdot.size + d.size, dtype=np.float32)
    _assemble(blocks, eta, nu, q, qdot, d, nu_scale, qdot_scale, D2 - D1, out)
    return out


@jit
def _assemble(blocks, eta, nu, q, qdot, d, nu_scale, qdot_scale, band, out):  # pragma: no cover - compiled
    """:func:`assemble_observation` into ``out``: each value, then clipped to ``[-OBS_CLIP, OBS_CLIP]``."""
    k = 0
    for i in range(blocks.shape[0]):
        out[k] = _clip(blocks[i])
        k += 1
    for i in range(3, 5):
        out[k] = _clip(eta[i])
        k += 1
    for i in range(nu.shape[0]):
        out[k] = _clip(nu[i] / nu_scale[i])
        k += 1
    for i in range(q.shape[0]):
        out[k] = _clip(math.sin(q[i]))
        k += 1
    for i in range(q.shape[0]):
        out[k] = _clip(math.cos(q[i]))
        k += 1
    for i in range(qdot.shape[0]):
        out[k] = _clip(qdot[i] / qdot_scale[i])
        k += 1
    for i in range(d.shape[0]):
        v = d[i]
        if v < 0.0:  # np.maximum then np.minimum: NaN passes through
            v = 0.0
        if v > CLEARANCE_CLIP:
            v = CLEARANCE_CLIP
        out[k] = _clip((v - D1) / band)
        k += 1


@jit
def _clip(v):  # pragma: no cover - compiled
    """``v`` clipped to ``[-OBS_CLIP, OBS_CLIP]`` (NaN passes through, as through ``np.maximum`` and ``np.minimum``)."""
    if v < -OBS_CLIP:
        v = -OBS_CLIP
    if v > OBS_CLIP:
        v = OBS_CLIP
    return v
