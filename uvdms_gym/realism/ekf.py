"""The navigation filter's compiled kernels: the EKF's prediction, updates, clones and the joint filters.

:class:`uvdms_gym.realism.navigation.NavigationFilter` owns the state and the tables; these kernels do its
arithmetic (numba, :mod:`uvdms_gym.utils.jit`), one call per control step (``_prepare``, ``_advance``) and one per
measurement at reset (``_apply``). The model, the state layout and the measurements are documented in
:mod:`uvdms_gym.realism.navigation`.
"""

from __future__ import annotations

import math

import numpy as np

from uvdms_gym.utils.jit import jit

N_CORE = 20
"""States with dynamics (``eta``, ``nu``, ``d``); the rest (biases, clones) are constant between updates."""
MAX_DIM = 4
"""Largest number of components of a fused sensor (the fix)."""


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
