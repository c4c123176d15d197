"""Compiled (numba) kernels of the exact UVDMS distances and ``J_dis``.

These are scalar-loop transcriptions of the numpy reference in :mod:`uvdms_gym.distances`
(``_link_link_exact``, ``_link_plate_exact``, ``distance_jacobian_reference``): the same formulas, the same
candidate order and the same first-minimum tie rule, so they agree with it to rounding (tested to 1e-12 in
``tests/uvdms_gym/distances/test_distances.py``). The numpy version spends its time in per-call overhead on arrays
of a few dozen elements; these loops do the 90 pairs (42 link-link, 48 link-plate) in about 4 µs.

Compilation is lazy (first call) and cached on disk (``cache=True``: ``NUMBA_CACHE_DIR`` if set, else
``__pycache__`` beside this file, else numba's user-wide cache directory). If that location is not
writable, the kernels compile without a disk cache (a ``logging`` warning says so) instead of failing.
"""

from __future__ import annotations

import math

import numpy as np

from uvdms_gym.utils.jit import jit

_TINY = 1e-300  # the reference's floor for denominators (never 0/0)
PLATE_COLS = 14  # per plate: u, v, n (body rows), basis . centre (3), hx, hy


def plate_table(plates) -> np.ndarray:
    """Body-frame constants of the plates as one ``(n_plates, PLATE_COLS)`` array for :func:`exact_rows`.

    Columns: ``u`` (3), ``v`` (3), ``n = u x v`` (3), ``[u.c, v.c, n.c]`` (3), ``hx``, ``hy``.

    Args:
        plates: ``params.plates`` (objects with ``center``, ``u``, ``v``, ``half_extents``).
    """
    out = np.empty((len(plates), PLATE_COLS))
    for k, pl in enumerate(plates):
        u = np.asarray(pl.u, dtype=float)
        v = np.asarray(pl.v, dtype=float)
        c = np.asarray(pl.center, dtype=float)
        basis = np.stack([u, v, np.cross(u, v)])
        out[k, :9] = basis.ravel()
        out[k, 9:12] = basis @ c
        out[k, 12:14] = pl.half_extents
    return out


# hot path: a line-by-line transcription of the numpy reference, one kernel so that numba compiles it whole
@jit
def exact_rows(seg, rot, pos, plates, d, p, e, idx):  # noqa: C901  # pragma: no cover - compiled kernel (below)
    """Fill the 18 exact rows ``d (18,)``, ``p (18, 3)``, ``e (18, 3)``, ``idx (18,)`` (int64) in place.

    Args:
        seg: link axes ``(2, 7, 2, 3)`` (``KinematicModel.link_segments``).
        rot: vehicle rotation ``R_NB`` (3, 3).
        pos: vehicle position (3,), NED.
        plates: :func:`plate_table` of the plates.
        d: output distances.
        p: output closest points on the monitored links.
        e: output closest points on the obstacles.
        idx: output obstacle indices (left link 0..6 for rows 0-5, plate for rows 6-17).
    """
    # ---- rows 0-5: right link i+1 vs left links 0..6 (Ericson's clamped solution, no parallel threshold)
    for i in range(6):
        a00, a01, a02 = seg[1, i + 1, 0, 0], seg[1, i + 1, 0, 1], seg[1, i + 1, 0, 2]
        d10 = seg[1, i + 1, 1, 0] - a00
        d11 = seg[1, i + 1, 1, 1] - a01
        d12 = seg[1, i + 1, 1, 2] - a02
        a = max(d10 * d10 + d11 * d11 + d12 * d12, _TINY)
        d1a0 = d10 * a00 + d11 * a01 + d12 * a02
        best = np.inf
        bs = 0.0
        bt = 0.0
        bj = 0
        for j in range(7):
            b00, b01, b02 = seg[0, j, 0, 0], seg[0, j, 0, 1], seg[0, j, 0, 2]
            d20 = seg[0, j, 1, 0] - b00
            d21 = seg[0, j, 1, 1] - b01
            d22 = seg[0, j, 1, 2] - b02
            ee = max(d20 * d20 + d21 * d21 + d22 * d22, _TINY)
            b = d10 * d20 + d11 * d21 + d12 * d22
            # as the reference's Gram matrix: d1 . a0 - d1 . b0 and d2 . a0 - d2 . b0
            c = d1a0 - (d10 * b00 + d11 * b01 + d12 * b02)
            f = (d20 * a00 + d21 * a01 + d22 * a02) - (d20 * b00 + d21 * b01 + d22 * b02)
            den = max(a * ee - b * b, _TINY)
            s = min(max((b * f - c * ee) / den, 0.0), 1.0)
            t = (b * s + f) / ee
            if t < 0.0:
                s = min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                s = min(max((b - c) / a, 0.0), 1.0)
            t = min(max(t, 0.0), 1.0)
            x0 = a00 + s * d10 - (b00 + t * d20)
            x1 = a01 + s * d11 - (b01 + t * d21)
            x2 = a02 + s * d12 - (b02 + t * d22)
            dd = x0 * x0 + x1 * x1 + x2 * x2
            if dd < best:  # the first minimum, as argmin
                best = dd
                bs = s
                bt = t
                bj = j
        d[i] = math.sqrt(best)
        p[i, 0] = a00 + bs * d10
        p[i, 1] = a01 + bs * d11
        p[i, 2] = a02 + bs * d12
        for k in range(3):
            b0k = seg[0, bj, 0, k]
            e[i, k] = b0k + bt * (seg[0, bj, 1, k] - b0k)
        idx[i] = bj
    # ---- rows 6-17: right links 1..6 then left links 1..6 vs the nearest plate (9 piece minimisers each)
    n_pl = plates.shape[0]
    bw = np.empty((n_pl, 3, 4))  # per plate: rows u, v, n in NED, then the offset u.pos + u.c (etc.)
    for q in range(n_pl):
        for r in range(3):
            for jj in range(3):
                c3 = 3 * r
                bw[q, r, jj] = (
                    plates[q, c3] * rot[jj, 0] + plates[q, c3 + 1] * rot[jj, 1] + (plates[q, c3 + 2] * rot[jj, 2])
                )
            bw[q, r, 3] = bw[q, r, 0] * pos[0] + bw[q, r, 1] * pos[1] + bw[q, r, 2] * pos[2] + plates[q, 9 + r]
    for mi in range(12):
        side = 1 if mi < 6 else 0
        kl = mi % 6 + 1
        m00, m01, m02 = seg[side, kl, 0, 0], seg[side, kl, 0, 1], seg[side, kl, 0, 2]
        m10, m11, m12 = seg[side, kl, 1, 0], seg[side, kl, 1, 1], seg[side, kl, 1, 2]
        best = np.inf
        blam = 0.0
        bq = 0
        for q in range(n_pl):
            hx = plates[q, 12]
            hy = plates[q, 13]
            # segment end points in plate coordinates (s, t, w): X0 and X1 - X0
            s0 = bw[q, 0, 0] * m00 + bw[q, 0, 1] * m01 + bw[q, 0, 2] * m02 - bw[q, 0, 3]
            t0 = bw[q, 1, 0] * m00 + bw[q, 1, 1] * m01 + bw[q, 1, 2] * m02 - bw[q, 1, 3]
            w0 = bw[q, 2, 0] * m00 + bw[q, 2, 1] * m01 + bw[q, 2, 2] * m02 - bw[q, 2, 3]
            ds = bw[q, 0, 0] * m10 + bw[q, 0, 1] * m11 + bw[q, 0, 2] * m12 - bw[q, 0, 3] - s0
            dt = bw[q, 1, 0] * m10 + bw[q, 1, 1] * m11 + bw[q, 1, 2] * m12 - bw[q, 1, 3] - t0
            dw = bw[q, 2, 0] * m10 + bw[q, 2, 1] * m11 + bw[q, 2, 2] * m12 - bw[q, 2, 3] - w0
            f0 = ds * s0
            f1 = dt * t0
            f2 = dw * w0
            f3 = ds * hx
            f4 = dt * hy
            f5 = ds * ds
            f6 = dt * dt
            f7 = dw * dw
            for si in range(3):  # (a_s, sig) = (1, 1), (1, -1), (0, 0): the reference's candidate order
                a_s = 1.0 if si < 2 else 0.0
                sig = 1.0 if si == 0 else (-1.0 if si == 1 else 0.0)
                for ti in range(3):
                    a_t = 1.0 if ti < 2 else 0.0
                    tau = 1.0 if ti == 0 else (-1.0 if ti == 1 else 0.0)
                    num = -a_s * f0 - a_t * f1 - f2 + a_s * sig * f3 + a_t * tau * f4
                    lam = num / (a_s * f5 + a_t * f6 + f7 + _TINY)  # flat piece: 0 / tiny = 0
                    lam = min(max(lam, 0.0), 1.0)
                    es = max(abs(s0 + lam * ds) - hx, 0.0)
                    et = max(abs(t0 + lam * dt) - hy, 0.0)
                    xw = w0 + lam * dw
                    g = es * es + et * et + xw * xw
                    if g < best:  # the first minimum over (plate, candidate), as argmin
                        best = g
                        blam = lam
                        bq = q
        row = 6 + mi
        # the winning candidate's plate coordinates, then P and E in NED
        hx = plates[bq, 12]
        hy = plates[bq, 13]
        s0 = bw[bq, 0, 0] * m00 + bw[bq, 0, 1] * m01 + bw[bq, 0, 2] * m02 - bw[bq, 0, 3]
        t0 = bw[bq, 1, 0] * m00 + bw[bq, 1, 1] * m01 + bw[bq, 1, 2] * m02 - bw[bq, 1, 3]
        w0 = bw[bq, 2, 0] * m00 + bw[bq, 2, 1] * m01 + bw[bq, 2, 2] * m02 - bw[bq, 2, 3]
        ds = bw[bq, 0, 0] * m10 + bw[bq, 0, 1] * m11 + bw[bq, 0, 2] * m12 - bw[bq, 0, 3] - s0
        dt = bw[bq, 1, 0] * m10 + bw[bq, 1, 1] * m11 + bw[bq, 1, 2] * m12 - bw[bq, 1, 3] - t0
        dw = bw[bq, 2, 0] * m10 + bw[bq, 2, 1] * m11 + bw[bq, 2, 2] * m12 - bw[bq, 2, 3] - w0
        xs = s0 + blam * ds
        xt = t0 + blam * dt
        ex_s = xs - min(max(xs, -hx), hx)  # P - E in plate coordinates
        ex_t = xt - min(max(xt, -hy), hy)
        ex_w = w0 + blam * dw
        p0 = m00 + blam * (m10 - m00)
        p1 = m01 + blam * (m11 - m01)
        p2 = m02 + blam * (m12 - m02)
        p[row, 0] = p0
        p[row, 1] = p1
        p[row, 2] = p2
        e[row, 0] = p0 - (ex_s * bw[bq, 0, 0] + ex_t * bw[bq, 1, 0] + ex_w * bw[bq, 2, 0])
        e[row, 1] = p1 - (ex_s * bw[bq, 0, 1] + ex_t * bw[bq, 1, 1] + ex_w * bw[bq, 2, 1])
        e[row, 2] = p2 - (ex_s * bw[bq, 0, 2] + ex_t * bw[bq, 1, 2] + ex_w * bw[bq, 2, 2])
        d[row] = math.sqrt(best)
        idx[row] = bq


@jit
def jdis_rows(sel, jac, p, e):  # pragma: no cover - compiled; run through distances.distance_jacobian
    """``J_dis`` rows ``sel_i * (n_i . v_k + (P_i x n_i) . w_k)`` for every column ``k``.

    Args:
        sel: row masks (n, nv) of ``distances._row_masks``.
        jac: Pinocchio's world-frame joint Jacobian columns ``[v_k; w_k]`` (6, nv).
        p: closest points on the monitored links (n, 3).
        e: closest points on the obstacles (n, 3).
    """
    n_rows, nv = sel.shape
    out = np.empty((n_rows, nv))
    for i in range(n_rows):
        x0 = e[i, 0] - p[i, 0]
        x1 = e[i, 1] - p[i, 1]
        x2 = e[i, 2] - p[i, 2]
        nrm = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if not nrm > 0.0:
            nrm = np.inf  # E = P: zero row (NaN rows stay NaN), as the reference's normals
        n0 = x0 / nrm
        n1 = x1 / nrm
        n2 = x2 / nrm
        c0 = p[i, 1] * n2 - p[i, 2] * n1
        c1 = p[i, 2] * n0 - p[i, 0] * n2
        c2 = p[i, 0] * n1 - p[i, 1] * n0
        for k in range(nv):
            val = n0 * jac[0, k] + n1 * jac[1, k] + n2 * jac[2, k]
            val += c0 * jac[3, k] + c1 * jac[4, k] + c2 * jac[5, k]
            out[i, k] = sel[i, k] * val
    return out
