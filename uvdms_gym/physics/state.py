"""The simulator's state: :class:`SimState`, :class:`StepInfo`, :class:`PhysicsError` and the sanity bounds.

Also the conversions between the NED/FRD state of docs/MODEL.md section 1 and PyBullet's base (COM) pose and
velocity in its z-up world (:func:`base_state`, :func:`state_from_raw`), the check of a state against the sanity
bounds :data:`NU_LIMIT`, :data:`QDOT_LIMIT`, :data:`POSITION_LIMIT` (:func:`check_bounds`), and the saturation of
a generalized force at ``tau_max`` (:func:`saturate`). :class:`uvdms_gym.physics.sim.UVDMSSim` uses them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uvdms_gym.physics import frames

NU_LIMIT = 50.0
"""Sanity bound on every component of ``nu`` (m/s, rad/s); beyond it the state is a blow-up."""
QDOT_LIMIT = 100.0
"""Sanity bound on every joint rate, rad/s."""
POSITION_LIMIT = 1.0e4
"""Sanity bound on the vehicle's and the object's NED position, m."""

_arctan2 = np.arctan2
_arcsin = np.arcsin


class PhysicsError(RuntimeError):
    """The simulation blew up: a state became non-finite or left the documented sanity bounds.

    Raised by :meth:`uvdms_gym.physics.sim.UVDMSSim.step` instead of ever returning NaN; the simulator must be reset.
    """


@dataclass(frozen=True)
class SimState:
    """State of the system in NED/FRD (docs/MODEL.md section 1).

    Attributes:
        eta: vehicle pose ``[x y z phi theta psi]`` (NED position of the body origin, ZYX Euler).
        nu: body velocity ``[u v w p q r]`` at the body origin (FRD).
        q: joint angles ``[q_l; q_r]`` (12; empty for a bare vehicle).
        qdot: joint rates, same order.
        t: simulated time since the last reset, s.
    """

    eta: np.ndarray
    nu: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    t: float

    @property
    def zeta(self) -> np.ndarray:
        """System velocity ``[nu; qdot]`` (18)."""
        return np.concatenate([self.nu, self.qdot])


@dataclass(frozen=True)
class StepInfo:
    """What :meth:`uvdms_gym.physics.sim.UVDMSSim.step` applied.

    Attributes:
        tau: the generalized force actually applied (after saturation), ``[tau_v (6); tau_q (12)]``.
        saturated: boolean mask, ``True`` where the requested component exceeded ``params.tau_max``.
        t: simulated time after the step, s.
        n_substeps: number of physics steps taken.
    """

    tau: np.ndarray
    saturated: np.ndarray
    t: float
    n_substeps: int

    @property
    def any_saturated(self) -> bool:
        """Whether any component was saturated."""
        return True in self.saturated.tolist()  # (a list scan: ndarray.any() costs several times more)


def blew_up(t: float, message: str) -> PhysicsError:
    """The :class:`PhysicsError` of a blow-up at simulated time ``t``."""
    return PhysicsError(f"simulation blew up at t = {t:.4f} s: {message}; reset() required")


def base_state(
    eta: np.ndarray, nu: np.ndarray, r_g: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """PyBullet's base state of the NED pose ``eta`` and body velocity ``nu`` (centre of gravity ``r_g``, body).

    Returns:
        ``(p_com, quat_xyzw, v_com, w_w, r_wb)`` in the z-up world, with ``R_WB`` of the body.
    """
    r_wb = frames.body_rot_ned_to_world(frames.euler_to_rot(eta[3:]))
    r_g_w = r_wb @ r_g
    p_com = frames.ned_to_world(eta[:3]) + r_g_w
    w_w = r_wb @ nu[3:]
    v_com = r_wb @ nu[:3] + np.cross(w_w, r_g_w)
    return p_com, frames.rot_to_quat_xyzw(r_wb), v_com, w_w, r_wb


def state_from_raw(raw: tuple, r_g: np.ndarray, t: float) -> SimState:
    """The NED/FRD state of PyBullet's raw read ``(p_com, quat, v_com, w, joint_states)`` (double precision).

    The conversion is written in scalars around the few numpy calls whose rounding it must keep (the
    3x3 matrix products and the inverse trigonometric functions give the same bits as
    :mod:`uvdms_gym.physics.frames`; plain Python products and ``math.atan2`` would differ in the last bit).
    """
    (px, py, pz), (x, y, z, w), (vx, vy, vz), (wx, wy, wz), js = raw
    # R_WB, the expressions of frames.quat_xyzw_to_rot
    r_wb = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    rx, ry, rz = (r_wb @ r_g).tolist()  # r_G in world axes
    # Euler angles of R_NB = S R_WB (frames.rot_to_euler); the +0.0 keeps the signed zeros of the product
    (r00, _, _), (r10, _, _), (r20, r21, r22) = r_wb.tolist()
    phi, psi = _arctan2(np.array([0.0 - r21, 0.0 - r10]), np.array([0.0 - r22, r00 + 0.0])).tolist()
    theta = -float(_arcsin(min(max(0.0 - r20, -1.0), 1.0)))
    eta = np.array([px - rx, -(py - ry), -(pz - rz), phi, theta, psi])
    # v_origin = v_com - w x r_g
    v = np.array([vx - (wy * rz - wz * ry), vy - (wz * rx - wx * rz), vz - (wx * ry - wy * rx)])
    r_bw = r_wb.T
    nu = np.concatenate([r_bw @ v, r_bw @ np.array([wx, wy, wz])])
    if js:
        q = np.array([s[0] for s in js])
        qdot = np.array([s[1] for s in js])
    else:
        q = qdot = np.zeros(0)
    return SimState(eta=eta, nu=nu, q=q, qdot=qdot, t=t)


def check_bounds(raw: tuple, r_g: np.ndarray, t: float, raw_object: tuple | None) -> None:
    """Raise :class:`PhysicsError` if a raw state (and the object's) is non-finite or beyond the sanity bounds."""
    pos, _, vel, ang, js = raw
    # cheap conservative pre-check on PyBullet's COM velocity (components below NU_LIMIT / 2 imply
    # |nu_i| <= sqrt(3) NU_LIMIT / 2 + |w| |r_G| < NU_LIMIT); the exact check only if it fails
    if not (max(map(abs, (*vel, *ang))) < 0.5 * NU_LIMIT and max(map(abs, pos)) < 0.5 * POSITION_LIMIT):
        st = state_from_raw(raw, r_g, t)
        if not (np.isfinite(st.eta).all() and np.isfinite(st.nu).all()):
            raise blew_up(t, f"non-finite state: eta = {st.eta}, nu = {st.nu}")
        if np.abs(st.nu).max() > NU_LIMIT:
            raise blew_up(t, f"|nu| > {NU_LIMIT}: nu = {st.nu}")
        if np.abs(st.eta[:3]).max() > POSITION_LIMIT:
            raise blew_up(t, f"|position| > {POSITION_LIMIT}: eta = {st.eta}")
    if js:
        qdot = [s[1] for s in js]
        if not max(map(abs, qdot)) <= QDOT_LIMIT:
            raise blew_up(t, f"|qdot| > {QDOT_LIMIT} or non-finite: qdot = {qdot}")
    if raw_object is not None:
        p, _, v, w = raw_object
        if not (max(map(abs, (*v, *w))) < NU_LIMIT + QDOT_LIMIT and max(map(abs, p)) < POSITION_LIMIT):
            raise blew_up(t, f"object state out of bounds or non-finite: position {p}, velocity {v}, {w}")


def saturate(tau: np.ndarray, tau_max: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(clip(tau, -tau_max, tau_max), saturated mask)``, or ``None`` if ``tau`` has NaN or inf.

    ``tau`` is returned itself (no copy) when no component exceeds ``tau_max``.
    """
    within = np.abs(tau) <= tau_max  # False for NaN/inf and for saturated components
    if False in within.tolist():  # (a list scan: ndarray.all() costs several times more on 18 entries)
        if not np.isfinite(tau).all():
            return None
        tau = np.clip(tau, -tau_max, tau_max)
    return tau, ~within
