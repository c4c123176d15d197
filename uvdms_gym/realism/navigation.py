"""The vehicle's navigation filter: an EKF of pose, body velocity and sensor biases, plus joint-state filters.

State of the EKF (27 values, then the clones of delayed samples):

======  ====  =============================================================================================
slice   size  content
======  ====  =============================================================================================
0:6     6     ``eta``: NED position ``x, y, z`` and ZYX Euler angles ``phi, theta, psi``
6:12    6     ``nu``: body velocity ``u, v, w, p, q, r``
12:18   6     ``d``: an unknown body acceleration (random walk): the rest of the model's error (added mass off
              by up to 30 %, the arms' drag, the thrusters' dead zone within a step)
18      1     ``beta``: the buoyancy's relative error (every buoyancy force is ``(1 + beta)`` times the nominal)
19      1     ``delta``: the vehicle damping's relative error (``D(nu)`` is ``(1 + delta)`` times the nominal)
20:23   3     the gyro's bias (random walk of the gyro's ``bias_walk``)
23:26   3     the DVL's bias (constant)
26      1     the depth sensor's bias (constant)
======  ====  =============================================================================================

Prediction, every physics substep: ``eta' = J(eta) nu`` and
``nu' = [M_n^-1 (tau - b_n(q, zeta))]_v + beta g_b - (1 + delta) [M_n^-1]_vv D(nu) nu + d`` with the nominal model
(:mod:`uvdms_gym.physics.nominal`: Pinocchio rigid body with added mass, hydrostatics, Coriolis, joint friction)
evaluated once per control step at the estimate, ``g_b = -[M_n^-1 g_buoyancy]_v`` (one unit of buoyancy error),
and the vehicle damping ``D(nu) nu`` at every substep. The arms enter through the full 18-DOF model (their weight,
buoyancy and reaction). The vehicle's wrench ``tau_v`` is the thrusters' at each substep: the step's mean commanded
wrench ``tau_cmd`` is allocated to thrust commands (``B^+``), the dead zone zeroes the small ones, the first-order
rotor lag (the filter keeps each rotor's thrust) makes the thrust of every substep, and the simulator's wrench box
bounds ``B f`` (:mod:`uvdms_gym.realism.actuation`); without thrusters ``tau_cmd`` is applied within the box.
White process noise on ``nu'`` and random walks on ``d``, ``beta``, ``delta`` stand for what the model does not
know.

Measurements are linear in the state (a state plus a bias): AHRS angles, gyro rates plus bias, DVL velocity plus
bias, depth plus bias, the position fix (``x, y, z, psi``), with the angle innovations wrapped. Each is applied at
its sample time. A sample released late (the DVL, the fix) is handled exactly by stochastic cloning: at each of the
sensor's sample times the states it measures are copied into extra state slots (with their covariance), the slots
are carried unchanged while the filter moves on, and the late sample updates its clone, the correlations carrying
the correction to the present. A slot whose sample does not come by its release time (a dropout) is freed.

Joints: one Kalman filter per joint of ``(q, qdot)``, driven by the nominal model's joint acceleration and corrected
by the encoders each control step.

The filter knows its sensors' specifications (the :class:`~uvdms_gym.realism.config.RealismConfig`): rates,
latencies, noise and bias magnitudes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
import pinocchio as pin

from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.nominal import NominalDynamics
from uvdms_gym.physics.params import N_JOINTS, UVDMSParams
from uvdms_gym.realism.actuation import DEFAULT_LAYOUT, Thrusters
from uvdms_gym.realism.config import RealismConfig, to_substeps
from uvdms_gym.utils.jit import jit

N_CORE = 20
"""States with dynamics (``eta``, ``nu``, ``d``); the rest (biases, clones) are constant between updates."""
N_BASE = 27
"""States without the clones."""
FILTERED_SENSORS: tuple[str, ...] = ("ahrs", "gyro", "dvl", "depth", "fix")
"""The sensors the EKF fuses, in the order of its tables (the encoders feed the joint filters)."""
MEASURED_STATES: dict[str, tuple[int, ...]] = {
    "ahrs": (3, 4, 5),
    "gyro": (9, 10, 11),
    "dvl": (6, 7, 8),
    "depth": (2,),
    "fix": (0, 1, 2, 5),
}
"""State measured by each component of each sensor."""
BIAS_STATES: dict[str, tuple[int, ...]] = {"gyro": (20, 21, 22), "dvl": (23, 24, 25), "depth": (26,)}
"""Bias state added to each component (sensors not listed have no bias)."""
ANGLE_MEASUREMENTS: dict[str, tuple[int, ...]] = {"ahrs": (0, 1, 2), "fix": (3,)}
"""Components whose innovation is an angle (wrapped to ``[-pi, pi)``)."""
MAX_DIM = 4
"""Largest number of components of a fused sensor (the fix)."""

POSITION_PRIOR_SIGMA = 10.0
"""Standard deviation of the initial position before the first fix, m (the first fix sets it)."""
ANGLE_PRIOR_SIGMA = 1.0
"""Standard deviation of the initial attitude before the first AHRS sample, rad."""
VELOCITY_PRIOR_SIGMA = (0.05, 0.05, 0.05, 0.05, 0.05, 0.05)
"""Standard deviation of the initial body velocity, m/s and rad/s (the vehicle starts at rest, unknown drift)."""
DISTURBANCE_PRIOR_SIGMA = (0.2, 0.2, 0.3, 0.2, 0.2, 0.2)
"""Standard deviation of the initial unknown acceleration ``d``, m/s^2 and rad/s^2: heave carries the buoyancy's
30 % (about 190 N standard deviation on some 160 kg of heave inertia)."""
ACCEL_NOISE_DENSITY = (0.002, 0.003, 0.002, 0.01, 0.03, 0.03)
"""White acceleration noise on ``nu'``, m/s^2/sqrt(Hz) and rad/s^2/sqrt(Hz): the fast part of the model's error.
Tuned on the consistency harness (``scripts/filter_consistency.py``, validation seeds) once the thrusters,
buoyancy and damping errors were modelled: what is left is small."""
DISTURBANCE_WALK = (0.008, 0.01, 0.006, 0.05, 0.15, 0.15)
"""Random-walk density of ``d``, m/s^2/sqrt(s) and rad/s^2/sqrt(s): its slow part (tuned as the above)."""
BUOYANCY_PRIOR_SIGMA = 0.2
"""Standard deviation of the buoyancy's relative error ``beta`` (``hydro_randomization=0.3`` draws it uniformly
in ``[-0.3, 0.3]``: 0.17 standard deviation)."""
DAMPING_PRIOR_SIGMA = 0.2
"""Standard deviation of the damping's relative error ``delta`` (as ``beta``)."""
BUOYANCY_WALK = 1.0e-3
"""Random-walk density of ``beta``, 1/sqrt(s) (a constant per episode; a little noise keeps the linearisation
honest)."""
DAMPING_WALK = 1.0e-3
"""Random-walk density of ``delta``, 1/sqrt(s)."""
POSITION_NOISE_DENSITY = 1.0e-4
"""White noise on the position's rate, m/sqrt(s) (the Euler integration's error)."""
ANGLE_NOISE_DENSITY = 6.0e-4
"""White noise on the Euler angles' rates, rad/sqrt(s) (the Euler integration's error over a substep of changing
body rates)."""
JOINT_PRIOR_RATE_SIGMA = 0.05
"""Standard deviation of the initial joint rates, rad/s (the arms start at rest)."""
JOINT_ACCEL_NOISE_DENSITY = 2.0
"""White noise on each joint's acceleration, rad/s^2/sqrt(Hz) (the joints' model is rougher: gear friction)."""
MIN_VARIANCE = 1.0e-12
"""Floor of a measurement's variance (a noiseless sensor would make the update singular)."""
_PADS = tuple([0.0] * k for k in range(MAX_DIM + 1))


# ----------------------------------------------------------------------------------------------- numba kernels
@jit
def _kinematics(eta: np.ndarray, nu: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``eta' = J(eta) nu`` and its Jacobian: fills ``a[0:6, 3:12]`` (d eta' / d (angles, nu)); returns ``eta'``."""
    c1, s1 = math.cos(eta[3]), math.sin(eta[3])
    c2, s2 = math.cos(eta[4]), math.sin(eta[4])
    c3, s3 = math.cos(eta[5]), math.sin(eta[5])
    r = np.empty((3, 3))
    r[0, 0], r[0, 1], r[0, 2] = c3 * c2, c3 * s2 * s1 - s3 * c1, c3 * s2 * c1 + s3 * s1
    r[1, 0], r[1, 1], r[1, 2] = s3 * c2, s3 * s2 * s1 + c3 * c1, s3 * s2 * c1 - c3 * s1
    r[2, 0], r[2, 1], r[2, 2] = -s2, c2 * s1, c2 * c1
    u, v, w, p, q, rr = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    # d(R v)/d phi, theta, psi
    a[0, 3] = (c3 * s2 * c1 + s3 * s1) * v + (-c3 * s2 * s1 + s3 * c1) * w
    a[1, 3] = (s3 * s2 * c1 - c3 * s1) * v + (-s3 * s2 * s1 - c3 * c1) * w
    a[2, 3] = c2 * c1 * v - c2 * s1 * w
    a[0, 4] = -c3 * s2 * u + c3 * c2 * s1 * v + c3 * c2 * c1 * w
    a[1, 4] = -s3 * s2 * u + s3 * c2 * s1 * v + s3 * c2 * c1 * w
    a[2, 4] = -c2 * u - s2 * s1 * v - s2 * c1 * w
    a[0, 5] = -s3 * c2 * u + (-s3 * s2 * s1 - c3 * c1) * v + (-s3 * s2 * c1 + c3 * s1) * w
    a[1, 5] = c3 * c2 * u + (c3 * s2 * s1 - s3 * c1) * v + (c3 * s2 * c1 + s3 * s1) * w
    a[2, 5] = 0.0
    t2 = s2 / c2
    out = np.empty(6)
    for i in range(3):
        out[i] = r[i, 0] * u + r[i, 1] * v + r[i, 2] * w
        for j in range(3):
            a[i, 6 + j] = r[i, j]
    out[3] = p + s1 * t2 * q + c1 * t2 * rr
    out[4] = c1 * q - s1 * rr
    out[5] = (s1 * q + c1 * rr) / c2
    a[3, 3], a[3, 4], a[3, 5] = c1 * t2 * q - s1 * t2 * rr, (s1 * q + c1 * rr) / (c2 * c2), 0.0
    a[4, 3], a[4, 4], a[4, 5] = -s1 * q - c1 * rr, 0.0, 0.0
    a[5, 3], a[5, 4], a[5, 5] = (c1 * q - s1 * rr) / c2, (s1 * q + c1 * rr) * s2 / (c2 * c2), 0.0
    a[3, 9], a[3, 10], a[3, 11] = 1.0, s1 * t2, c1 * t2
    a[4, 9], a[4, 10], a[4, 11] = 0.0, c1, -s1
    a[5, 9], a[5, 10], a[5, 11] = 0.0, s1 / c2, c1 / c2
    return out


@jit
def _derivative(x, accel, gb, wvv, lin, quad, a):
    """``x'`` of the core states (:data:`N_CORE`) and its Jacobian ``a`` (12 x N_CORE, rows ``eta, nu``).

    ``nu' = accel + d + beta gb - (1 + delta) [M^-1]_vv D(nu) nu`` (``gb``: the acceleration of one unit of
    buoyancy error); ``d``, ``beta``, ``delta`` are random walks (their rate is noise only).
    """
    a[:, :] = 0.0
    f = np.zeros(N_CORE)
    f[:6] = _kinematics(x[:6], x[6:12], a)
    nu = x[6:12]
    damp = (lin + quad * np.abs(nu)) * nu
    ddamp = lin + 2.0 * quad * np.abs(nu)
    beta, kd = x[18], 1.0 + x[19]
    for i in range(6):
        dterm = 0.0
        for j in range(6):
            dterm += wvv[i, j] * damp[j]
            a[6 + i, 6 + j] = -kd * wvv[i, j] * ddamp[j]
        f[6 + i] = accel[i] + x[12 + i] + beta * gb[i] - kd * dterm
        a[6 + i, 12 + i] = 1.0
        a[6 + i, 18] = gb[i]
        a[6 + i, 19] = -dterm
    return f


@jit
def _thruster_wrench(tau_v, pinv, b, thrust, fmax, rmax, dead_zone, alpha, box, n_sub):
    """The body wrench of each of ``n_sub`` substeps (rows) from the step's mean commanded wrench ``tau_v``.

    The thrust commands ``B^+ tau_v`` (``tau_v`` is the allocation's output, already inside the limits), the dead
    zone on them, the rotor lag ``f += alpha (target - f)`` per substep on ``thrust`` (in place), and the
    simulator's box ``|w| <= box`` on ``B f``.
    """
    n = thrust.shape[0]
    target = np.empty(n)
    for i in range(n):
        c = 0.0
        for j in range(6):
            c += pinv[i, j] * tau_v[j]
        c = min(max(c, -rmax), fmax)
        u = c / fmax if c >= 0.0 else -c / rmax
        target[i] = 0.0 if u < dead_zone else c
    out = np.empty((n_sub, 6))
    for s in range(n_sub):
        for i in range(n):
            thrust[i] += alpha * (target[i] - thrust[i])
        for j in range(6):
            acc = 0.0
            for i in range(n):
                acc += b[j, i] * thrust[i]
            out[s, j] = min(max(acc, -box[j]), box[j])
    return out


@jit
def _wrap(a: float) -> float:
    """An angle wrapped to ``[-pi, pi)``."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@jit
def _predict(x, p, dt, accel, gb, wvv, lin, quad, qdiag, a):  # noqa: C901  (loops over A's nonzeros)
    """One Euler step of the core states and ``P <- F P F' + Q dt`` with ``F = I + A dt`` (A nonzero in rows 0:12)."""
    n = x.shape[0]
    f = _derivative(x, accel, gb, wvv, lin, quad, a)
    g = np.zeros((12, n))  # A P, over A's nonzeros (about 75 of 216)
    for i in range(12):
        for k in range(N_CORE):
            aik = a[i, k]
            if aik != 0.0:
                for j in range(n):
                    g[i, j] += aik * p[k, j]
    h = np.zeros((12, 12))  # A P A'
    for i in range(12):
        for k in range(N_CORE):
            for j in range(12):
                h[i, j] += g[i, k] * a[j, k]
    for i in range(12):
        for j in range(n):
            p[i, j] += dt * g[i, j]
    for i in range(n):
        for j in range(12):
            p[i, j] += dt * g[j, i]
    for i in range(12):
        for j in range(12):
            p[i, j] += dt * dt * h[i, j]
    for i in range(qdiag.shape[0]):
        p[i, i] += qdiag[i] * dt
    for i in range(N_CORE):
        x[i] += dt * f[i]
    for i in range(3, 6):
        x[i] = _wrap(x[i])


@jit
def _update_scalar(x, p, i, j, z, r, angle, angle_states):
    """Kalman update with one scalar ``z = x[i] + x[j] + noise(r)`` (``j < 0``: no bias term)."""
    n = x.shape[0]
    ph = p[:, i].copy()
    hx = x[i]
    if j >= 0:
        ph += p[:, j]
        hx += x[j]
    s = ph[i] + (ph[j] if j >= 0 else 0.0) + r
    innov = _wrap(z - hx) if angle else z - hx
    for a in range(n):
        x[a] += ph[a] / s * innov
        for b in range(n):
            p[a, b] -= ph[a] * ph[b] / s
    for k in range(angle_states.shape[0]):
        x[angle_states[k]] = _wrap(x[angle_states[k]])


@jit
def _apply(x, p, row, idx, bias, var, angle, angle_states):
    """Apply a measurement row ``(sensor, s, v0..v3)`` with the state indices ``idx`` of its components."""
    sid = int(row[0])
    for k in range(MAX_DIM):
        if idx[k] < 0:
            break
        _update_scalar(x, p, idx[k], bias[sid, k], row[2 + k], var[sid, k], angle[sid, k], angle_states)


@jit
def _clone(x, p, dst, src):
    """Copy states ``src`` into slots ``dst`` with their covariance (rows, then columns)."""
    for k in range(src.shape[0]):
        if src[k] < 0:
            break
        x[dst[k]] = x[src[k]]
        p[dst[k], :] = p[src[k], :]
    for k in range(src.shape[0]):
        if src[k] < 0:
            break
        p[:, dst[k]] = p[:, src[k]]


@jit
def _free(x, p, dst):
    """Free a clone slot: zero its state and correlations, unit variance (decoupled from everything)."""
    for k in range(dst.shape[0]):
        if dst[k] < 0:
            break
        x[dst[k]] = 0.0
        p[dst[k], :] = 0.0
        p[:, dst[k]] = 0.0
        p[dst[k], dst[k]] = 1.0


@jit
def _run(x, p, s_from, s_to, dt, accel0, gb, wrench, wvv, lin, quad, qdiag, meas, tab, slots, a):  # noqa: C901
    """Substeps ``s_from + 1 .. s_to``: predict, clone at delayed sensors' sample times, apply the samples.

    The vehicle's acceleration at substep ``i`` is ``accel0 + [M^-1]_vv wrench[i]`` (``accel0``: without the
    vehicle's wrench). ``tab`` holds the sensor tables ``(idx, bias, var, angle, period, latency, angle_states)``;
    ``slots`` the clone slots ``(sensor, s_sample, state indices (MAX_DIM))`` as rows of an int array.
    """
    idx, bias, var, angle, period, latency, angle_states = tab
    n_meas = meas.shape[0]
    accel = np.empty(6)
    for s in range(s_from + 1, s_to + 1):
        w = wrench[s - s_from - 1]
        for i in range(6):
            acc = accel0[i]
            for j in range(6):
                acc += wvv[i, j] * w[j]
            accel[i] = acc
        _predict(x, p, dt, accel, gb, wvv, lin, quad, qdiag, a)
        for sid in range(period.shape[0]):
            if latency[sid] > 0 and s % period[sid] == 0:  # a delayed sensor samples now: clone into a free slot
                for m in range(slots.shape[0]):
                    if slots[m, 0] == sid and slots[m, 1] < 0:
                        slots[m, 1] = s
                        _clone(x, p, slots[m, 2:], idx[sid])
                        break
        for m in range(n_meas):
            sid = int(meas[m, 0])
            if latency[sid] == 0 and int(meas[m, 1]) == s:
                _apply(x, p, meas[m], idx[sid], bias, var, angle, angle_states)
    for m in range(n_meas):
        sid = int(meas[m, 0])
        if latency[sid] > 0:
            for k in range(slots.shape[0]):
                if slots[k, 0] == sid and slots[k, 1] == int(meas[m, 1]):
                    _apply(x, p, meas[m], slots[k, 2:], bias, var, angle, angle_states)
                    _free(x, p, slots[k, 2:])
                    slots[k, 1] = -1
                    break
    for k in range(slots.shape[0]):
        if slots[k, 1] >= 0 and slots[k, 1] + latency[slots[k, 0]] <= s_to:  # released by now: lost in a dropout
            _free(x, p, slots[k, 2:])
            slots[k, 1] = -1
    for i in range(p.shape[0]):  # keep P symmetric to rounding
        for j in range(i):
            v = 0.5 * (p[i, j] + p[j, i])
            p[i, j] = v
            p[j, i] = v


@jit
def _dynamics(m_upper, nle, buoy, added, added_weight, eta, zeta, tau, friction, lin, quad):
    """Nominal accelerations at the estimate (18-DOF model; the vehicle damping at ``nu``).

    Returns:
        The vehicle's acceleration without its damping, ``[M^-1]_vv`` and the joints' accelerations.
    """
    n = m_upper.shape[0]
    m = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            m[i, j] = m_upper[i, j]
            m[j, i] = m_upper[i, j]
    for i in range(6):
        m[i, i] += added[i]
    rhs = tau - nle - buoy
    c1, s1 = math.cos(eta[3]), math.sin(eta[3])
    c2, s2 = math.cos(eta[4]), math.sin(eta[4])
    rhs[0] -= added_weight * -s2  # the virtual added-mass body is weightless: R_NB^T W e_z, third row of R_NB
    rhs[1] -= added_weight * c2 * s1
    rhs[2] -= added_weight * c2 * c1
    nu = zeta[:6]
    u, v, w, p_, q, r = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    ax, ay, az = added[0] * u, added[1] * v, added[2] * w
    bx, by, bz = added[3] * p_, added[4] * q, added[5] * r
    rhs[0] -= q * az - r * ay
    rhs[1] -= r * ax - p_ * az
    rhs[2] -= p_ * ay - q * ax
    rhs[3] -= (v * az - w * ay) + (q * bz - r * by)
    rhs[4] -= (w * ax - u * az) + (r * bx - p_ * bz)
    rhs[5] -= (u * ay - v * ax) + (p_ * by - q * bx)
    for i in range(6, n):
        rhs[i] -= friction * zeta[i]
    # M X = [rhs, buoy, e_0 .. e_5] by Cholesky (M is symmetric positive definite): X[:, 2:] = [M^-1]_(:, v)
    rhs_all = np.zeros((n, 8))
    for i in range(n):
        rhs_all[i, 0] = rhs[i]
        rhs_all[i, 1] = buoy[i]
    for i in range(6):
        rhs_all[i, 2 + i] = 1.0
    sol = _cholesky_solve(m, rhs_all)
    accel = sol[:6, 0].copy()
    gb = -sol[:6, 1]
    damp = (lin + quad * np.abs(nu)) * nu
    qdd = sol[6:, 0] - sol[6:, 2:] @ damp
    return accel, gb, sol[:6, 2:].copy(), qdd


@jit
def _cholesky_solve(m, b):
    """``M^-1 B`` for a symmetric positive definite ``M`` (overwritten by its Cholesky factor ``L``)."""
    n = m.shape[0]
    for j in range(n):
        d = m[j, j]
        for k in range(j):
            d -= m[j, k] * m[j, k]
        d = math.sqrt(d)
        m[j, j] = d
        for i in range(j + 1, n):
            v = m[i, j]
            for k in range(j):
                v -= m[i, k] * m[j, k]
            m[i, j] = v / d
    x = b.copy()
    for c in range(x.shape[1]):
        for i in range(n):  # L y = b
            v = x[i, c]
            for k in range(i):
                v -= m[i, k] * x[k, c]
            x[i, c] = v / m[i, i]
        for i in range(n - 1, -1, -1):  # L' x = y
            v = x[i, c]
            for k in range(i + 1, n):
                v -= m[k, i] * x[k, c]
            x[i, c] = v / m[i, i]
    return x


@jit
def _prepare(x, q, qd, tau, pinv, b, thrust, fmax, rmax, dead_zone, alpha, box, n_sub, config, zeta, tau_eff):
    """Before the nominal model: its configuration and velocity at the estimate, the substeps' vehicle wrench.

    Fills ``config`` (Pinocchio's ``[x y z, quaternion xyzw, q]``), ``zeta`` (``[nu, qdot]``) and ``tau_eff``
    (``tau`` with the substeps' mean vehicle wrench); returns the wrench of each substep (:func:`_thruster_wrench`).
    """
    for i in range(3):
        config[i] = x[i]
    hr, hp, hy = 0.5 * x[3], 0.5 * x[4], 0.5 * x[5]
    cr, sr = math.cos(hr), math.sin(hr)
    cp, sp = math.cos(hp), math.sin(hp)
    cy, sy = math.cos(hy), math.sin(hy)
    qw = cr * cp * cy + sr * sp * sy
    sign = 1.0 if qw >= 0.0 else -1.0
    config[3] = sign * (sr * cp * cy - cr * sp * sy)
    config[4] = sign * (cr * sp * cy + sr * cp * sy)
    config[5] = sign * (cr * cp * sy - sr * sp * cy)
    config[6] = sign * qw
    for i in range(q.shape[0]):
        config[7 + i] = q[i]
        zeta[6 + i] = qd[i]
    for i in range(6):
        zeta[i] = x[6 + i]
    wrench = _thruster_wrench(tau[:6], pinv, b, thrust, fmax, rmax, dead_zone, alpha, box, n_sub)
    for i in range(tau.shape[0]):
        tau_eff[i] = tau[i]
    if n_sub > 0:
        for j in range(6):
            acc = 0.0
            for k in range(n_sub):
                acc += wrench[k, j]
            tau_eff[j] = acc / n_sub
    return wrench


@jit
def _advance(x, p, s_from, s_to, dt, model, zeta, tau_eff, wrench, qdiag, meas, tab, slots, a, joints, z):
    """One control step: the nominal model's accelerations, the EKF's substeps (:func:`_run`), the joint filters.

    ``model`` is ``(M upper, nle, buoyancy, added, added_weight, friction, lin, quad)``; ``joints`` is
    ``(q, qdot, p11, p12, p22, qvar, encoder variances)``.
    """
    m_upper, nle, buoy, added, added_weight, friction, lin, quad = model
    accel, gb, wvv, qdd = _dynamics(m_upper, nle, buoy, added, added_weight, x[:6], zeta, tau_eff, friction, lin, quad)
    accel0 = np.empty(6)
    for i in range(6):
        acc = accel[i]
        for j in range(6):
            acc -= wvv[i, j] * tau_eff[j]
        accel0[i] = acc
    _run(x, p, s_from, s_to, dt, accel0, gb, wrench, wvv, lin, quad, qdiag, meas, tab, slots, a)
    q, qd, p11, p12, p22, qvar, r = joints
    _joints(q, qd, p11, p12, p22, qdd, (s_to - s_from) * dt, qvar, z, r)


@jit
def _joints(q, qd, p11, p12, p22, qdd, dt, qvar, z, r):
    """One control step of the joint filters: predict with ``qdd`` and white acceleration noise, then the encoders."""
    for i in range(q.shape[0]):
        q[i] += dt * qd[i] + 0.5 * dt * dt * qdd[i]
        qd[i] += dt * qdd[i]
        a11 = p11[i] + 2.0 * dt * p12[i] + dt * dt * p22[i] + qvar * dt**3 / 3.0
        a12 = p12[i] + dt * p22[i] + qvar * dt**2 / 2.0
        a22 = p22[i] + qvar * dt
        if z.shape[0] > 0:
            s = a11 + r[i]
            k1, k2 = a11 / s, a12 / s
            innov = z[i] - q[i]
            q[i] += k1 * innov
            qd[i] += k2 * innov
            a22 -= k2 * a12
            a12 -= k1 * a12
            a11 -= k1 * a11
        p11[i], p12[i], p22[i] = a11, a12, a22


# ----------------------------------------------------------------------------------------------- the filter
def _vector(values: Any, n: int) -> np.ndarray:
    return np.asarray(values, dtype=float) * np.ones(n)


class NavigationFilter:
    """EKF of ``(eta, nu)`` with biases and an unknown acceleration, joint filters (module docstring).

    Args:
        cfg: the realism level (the sensors' specifications the vehicle's software knows).
        params: the nominal physical parameters.
        control_dt: the control step, s (:meth:`update` is called once per control step).
        physics_dt: the physics substep, s (the sensors' clock; samples are taken at its multiples).
    """

    def __init__(self, cfg: RealismConfig, params: UVDMSParams, *, control_dt: float, physics_dt: float) -> None:
        if not (math.isfinite(physics_dt) and physics_dt > 0):
            raise ValueError(f"physics_dt must be a finite number > 0, got {physics_dt!r}")
        n_sub = round(control_dt / physics_dt)
        if n_sub < 1 or abs(n_sub * physics_dt - control_dt) > 1e-9:
            raise ValueError(f"control_dt ({control_dt}) must be a whole multiple of physics_dt ({physics_dt})")
        self.cfg, self.params = cfg, params
        self.control_dt, self.physics_dt, self.n_substeps = float(control_dt), float(physics_dt), n_sub
        self._kin = KinematicModel(params)
        self._nominal = NominalDynamics(self._kin)
        self._model, self._data = self._kin.model, self._kin.model.createData()
        self._bmodel = self._nominal._bmodel
        self._bdata = self._bmodel.createData()
        veh = params.vehicle
        self._added = self._nominal._base_added.copy()
        self._added_weight = float(self._kin._added_weight)
        self._friction = float(params.arm.joint_friction)
        self._lin, self._quad = np.array(veh.linear_damping), np.array(veh.quadratic_damping)
        self._build_tables(cfg)
        self._qdiag = np.r_[
            np.full(3, POSITION_NOISE_DENSITY**2),
            np.full(3, ANGLE_NOISE_DENSITY**2),
            _vector(ACCEL_NOISE_DENSITY, 6) ** 2,
            _vector(DISTURBANCE_WALK, 6) ** 2,
            np.full(1, BUOYANCY_WALK**2),
            np.full(1, DAMPING_WALK**2),
            np.full(3, cfg.gyro.bias_walk**2),
        ]
        enc = cfg.encoders.sigma_vector(N_JOINTS)
        self._enc_var = np.maximum(enc**2, MIN_VARIANCE)
        self._box = np.asarray(params.tau_max[:6], dtype=float)
        self._thr = (
            Thrusters(
                cfg.layout or DEFAULT_LAYOUT,
                rotor_time_constant=cfg.rotor_time_constant,
                dead_zone=cfg.dead_zone,
                physics_dt=physics_dt,
            )
            if cfg.thrusters
            else None
        )
        if self._thr is None:  # no thrusters: the identity "allocation" without limits, lag or dead zone
            eye = np.eye(6)
            self._thr_args = (eye, eye, np.zeros(6), math.inf, math.inf, 0.0, 1.0)
        else:
            t_ = self._thr
            self._thr_args = (
                t_.pinv,
                t_.matrix,
                np.zeros(t_.n),
                t_.max_forward,
                t_.max_reverse,
                t_.dead_zone,
                t_.alpha,
            )
        self._thrust = self._thr_args[2]
        self._config, self._zeta, self._tau_eff = np.zeros(7 + N_JOINTS), np.zeros(18), np.zeros(18)
        self._model_consts = (self._added, self._added_weight, self._friction, self._lin, self._quad)
        self._qvar = JOINT_ACCEL_NOISE_DENSITY**2
        self._no_encoders = np.zeros(0)
        self._a = np.zeros((12, N_CORE))
        self._t = 0.0
        self._s = 0
        self.restarts = 0
        """Restarts after a divergence (:meth:`_restart_if_diverged`)."""
        self._latest: dict[str, tuple[float, np.ndarray]] = {}
        self.x = np.zeros(self._n)
        self.P = np.eye(self._n)
        self._q, self._qd = np.zeros(N_JOINTS), np.zeros(N_JOINTS)
        self._pj = [np.zeros(N_JOINTS), np.zeros(N_JOINTS), np.zeros(N_JOINTS)]

    def _build_tables(self, cfg: RealismConfig) -> None:
        """Per fused sensor: measured states, bias states, variances, angle flags, period, latency; clone slots."""
        k = len(FILTERED_SENSORS)
        idx, bias = np.full((k, MAX_DIM), -1, np.int64), np.full((k, MAX_DIM), -1, np.int64)
        var, angle = np.ones((k, MAX_DIM)), np.zeros((k, MAX_DIM), np.bool_)
        period, latency = np.zeros(k, np.int64), np.zeros(k, np.int64)
        slots: list[list[int]] = []
        n = N_BASE
        for j, name in enumerate(FILTERED_SENSORS):
            spec, states = cfg.sensor(name), MEASURED_STATES[name]
            dim = len(states)
            idx[j, :dim] = states
            bias[j, : len(BIAS_STATES.get(name, ()))] = BIAS_STATES.get(name, ())
            var[j, :dim] = np.maximum(spec.sigma_vector(dim) ** 2, MIN_VARIANCE)
            angle[j, list(ANGLE_MEASUREMENTS.get(name, ()))] = True
            period[j] = to_substeps(spec.period, self.physics_dt, minimum=1)
            latency[j] = to_substeps(spec.latency, self.physics_dt)
            if latency[j] > 0:
                for _ in range((latency[j] + self.n_substeps) // period[j] + 1):
                    slots.append([j, -1, *range(n, n + dim), *([-1] * (MAX_DIM - dim))])
                    n += dim
        self._n = n
        clone_angles = [row[2 + c] for row in slots for c in range(MAX_DIM) if angle[row[0], c]]
        angle_states = np.array([3, 4, 5, *clone_angles], np.int64)
        self._tab = (idx, bias, var, angle, period, latency, angle_states)
        self._slots_template = np.array(slots, np.int64).reshape(-1, 2 + MAX_DIM)
        self._slots = self._slots_template.copy()
        self._prior = np.r_[
            np.full(3, POSITION_PRIOR_SIGMA),
            np.full(3, ANGLE_PRIOR_SIGMA),
            _vector(VELOCITY_PRIOR_SIGMA, 6),
            _vector(DISTURBANCE_PRIOR_SIGMA, 6),
            np.full(1, BUOYANCY_PRIOR_SIGMA),
            np.full(1, DAMPING_PRIOR_SIGMA),
            np.full(3, cfg.gyro.bias_sigma),
            np.full(3, cfg.dvl.bias_sigma),
            np.full(1, cfg.depth.bias_sigma),
            np.ones(n - N_BASE),
        ]

    # ----------------------------------------------------------------------------------------- public API
    def reset(self, t: float, measurements: Mapping[str, list[tuple[float, np.ndarray]]]) -> None:
        """Start from the prior and the initial samples (taken at ``t``, released at once)."""
        self._t, self._s = float(t), round(t / self.physics_dt)
        self.x = np.zeros(self._n)
        self.P = np.diag(np.maximum(self._prior, math.sqrt(MIN_VARIANCE)) ** 2)
        self._slots = self._slots_template.copy()
        self._thrust[:] = 0.0
        enc = measurements.get("encoders") or []
        if not enc:
            raise ValueError("reset needs the initial encoder sample in measurements['encoders']")
        self._q = np.array(enc[-1][1], dtype=float)
        self._qd = np.zeros(N_JOINTS)
        self._pj = [self._enc_var.copy(), np.zeros(N_JOINTS), np.full(N_JOINTS, JOINT_PRIOR_RATE_SIGMA**2)]
        tab = self._tab
        self._keep_latest(measurements)
        for row in self._pack(measurements):
            _apply(self.x, self.P, row, tab[0][int(row[0])], tab[1], tab[2], tab[3], tab[6])

    def _keep_latest(self, measurements: Mapping[str, list[tuple[float, np.ndarray]]]) -> None:
        """Remember each sensor's newest sample (what a restart after a divergence starts from)."""
        latest = self._latest
        for name, samples in measurements.items():
            if samples:
                latest[name] = samples[-1]

    def _restart_if_diverged(self, t: float) -> None:
        """Start again from each sensor's newest sample if the estimate or its variances became non-finite.

        A controller far outside the model's validity (a torque cascade tumbling the vehicle) can drive the EKF's
        linearisation to overflow; the vehicle's software then re-initialises its navigation, as a real one would,
        rather than handing out NaN. :attr:`restarts` counts it.
        """
        core = N_CORE
        if np.isfinite(self.x[:core]).all() and np.isfinite(np.diagonal(self.P)[:core]).all():
            return
        self.restarts += 1
        self.reset(t, {name: [(t, value)] for name, (_, value) in self._latest.items()})

    def update(self, t: float, measurements: Mapping[str, list[tuple[float, np.ndarray]]], tau_cmd: np.ndarray) -> None:
        """Advance to ``t`` with the commanded force of the step just ended and fuse the samples released in it.

        Args:
            t: the time at the end of the control step, s.
            measurements: sensor name -> the samples released during the step, ``(t_sample, value)``.
            tau_cmd: the 18 commanded generalized forces of the step, mean over its substeps.
        """
        tau = np.asarray(tau_cmd, dtype=float)
        if tau.shape != (18,) or not np.isfinite(tau).all():
            raise ValueError(f"tau_cmd must be 18 finite values, got {tau_cmd!r}")
        s_to = round(t / self.physics_dt)
        if s_to < self._s:
            raise ValueError(f"t ({t}) is before the filter's time ({self._t})")
        wrench = _prepare(
            self.x,
            self._q,
            self._qd,
            tau,
            *self._thr_args,
            self._box,
            s_to - self._s,
            self._config,
            self._zeta,
            self._tau_eff,
        )
        config, zeta = self._config, self._zeta
        pin.crba(self._model, self._data, config)
        nle = pin.nonLinearEffects(self._model, self._data, config, zeta)
        buoy = pin.computeGeneralizedGravity(self._bmodel, self._bdata, config)
        model = (self._data.M, nle, buoy, *self._model_consts)
        enc = measurements.get("encoders")
        z = enc[-1][1] if enc else self._no_encoders
        meas = self._pack(measurements)
        _advance(
            self.x,
            self.P,
            self._s,
            s_to,
            self.physics_dt,
            model,
            zeta,
            self._tau_eff,
            wrench,
            self._qdiag,
            meas,
            self._tab,
            self._slots,
            self._a,
            (self._q, self._qd, *self._pj, self._qvar, self._enc_var),
            z,
        )
        self._t, self._s = float(t), s_to
        self._keep_latest(measurements)
        self._restart_if_diverged(t)

    def _pack(self, measurements: Mapping[str, list[tuple[float, np.ndarray]]]) -> np.ndarray:
        """The fused samples as rows ``(sensor index, substep, v0..v3)``."""
        flat: list[float] = []
        extend, inv_dt, n = flat.extend, 1.0 / self.physics_dt, 0
        for j, name in enumerate(FILTERED_SENSORS):
            samples = measurements.get(name)
            if samples:
                pad = _PADS[MAX_DIM - len(samples[0][1])]
                for t, v in samples:
                    flat.append(j)
                    flat.append(round(t * inv_dt))
                    extend(v.tolist())
                    extend(pad)
                n += len(samples)
        return np.array(flat, dtype=float).reshape(n, 2 + MAX_DIM)

    def state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The estimates ``eta, nu, q, qdot`` at the filter's time."""
        return self.x[:6].copy(), self.x[6:12].copy(), self._q.copy(), self._qd.copy()

    def covariance(self) -> np.ndarray:
        """The 12 x 12 covariance of the ``(eta, nu)`` estimate (angle errors are wrapped)."""
        return self.P[:12, :12].copy()

    @property
    def t(self) -> float:
        """The filter's time, s."""
        return self._t


class NavigationFilterWrapper(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Puts the navigation filter's estimate where the oracle state was (observation and ``info`` state keys).

    The environment (at a realism level) reports ``info["measurements"]`` (the samples released during the step,
    and at reset the initial samples) and ``info["tau_cmd"]`` (the step's mean commanded force); the wrapper runs
    the filter on them and asks the environment to observe the estimate (``observe_estimate``).

    Args:
        env: a UVDMS environment built with a realism level.
        cfg: that level (default: the environment's ``realism`` attribute).
    """

    def __init__(self, env: gym.Env, cfg: RealismConfig | None = None) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, cfg=cfg)  # the spec can rebuild it (check_env)
        gym.Wrapper.__init__(self, env)
        base = env.unwrapped
        cfg = cfg if cfg is not None else base.realism
        if cfg is None:
            raise ValueError("NavigationFilterWrapper needs a realism level > 0 (the environment's realism is None)")
        self.filter = NavigationFilter(cfg, base.params, control_dt=base.control_dt, physics_dt=base.physics_dt)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the environment and start the filter from its initial samples."""
        _, info = self.env.reset(**kwargs)
        self.filter.reset(info.get("t", 0.0), info["measurements"])
        return self._observe(info)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Step the environment, update the filter, observe the estimate."""
        _, reward, terminated, truncated, info = self.env.step(action)
        self.filter.update(info["t"], info["measurements"], info["tau_cmd"])
        obs, info = self._observe(info)
        return obs, reward, terminated, truncated, info

    def _observe(self, info: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
        # the obstacles as measured (the sonar's track in info), never the true rows
        obs, state_keys = self.env.unwrapped.observe_estimate(*self.filter.state(), info.get("obstacles"))
        info.update(state_keys)
        return obs, info


class FilteredController:
    """A controller fed the navigation filter's estimate where the oracle state was: the wrapper's job, per controller.

    For a controller evaluated on an unwrapped environment (the leaderboard's, ``uvdms evaluate``'s): at each
    ``predict`` the filter takes ``info["measurements"]`` and ``info["tau_cmd"]``, and the controller receives the
    observation and ``info`` state keys of the estimate (``env.unwrapped.observe_estimate``, with the obstacles as
    measured). At ``realism=0`` it passes ``obs`` and ``info`` through unchanged.

    Args:
        controller: anything with ``reset(seed)`` and ``predict(obs, info)``.
        env: the environment the controller drives (wrapped or not).
    """

    def __init__(self, controller: Any, env: gym.Env) -> None:
        self.controller = controller
        self._env = env.unwrapped
        cfg = self._env.realism
        self.filter = (
            None
            if cfg is None
            else NavigationFilter(
                cfg, self._env.params, control_dt=self._env.control_dt, physics_dt=self._env.physics_dt
            )
        )
        self._started = False

    def __getattr__(self, name: str) -> Any:
        """The wrapped controller's attributes (``last_record``, ``last_di``, ``action_mode``, ...)."""
        if name == "controller":  # not set yet (unpickling): no recursion
            raise AttributeError(name)
        return getattr(self.controller, name)

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: the filter starts at the next ``predict``'s initial samples."""
        self._started = False
        self.controller.reset(seed)

    def predict(self, obs: Any, info: dict[str, Any]) -> Any:
        """The controller's action for the estimated state's observation and ``info``."""
        if self.filter is None:
            return self.controller.predict(obs, info)
        if self._started:
            self.filter.update(float(info["t"]), info["measurements"], info["tau_cmd"])
        else:
            self.filter.reset(float(info["t"]), info["measurements"])
            self._started = True
        obs_hat, keys = self._env.observe_estimate(*self.filter.state(), info.get("obstacles"))
        return self.controller.predict(obs_hat, {**info, **keys})
