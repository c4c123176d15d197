"""Pure geometry of the distance computation: points, segments and rectangles, and the paper's Algorithm 1.

Every helper broadcasts over leading dimensions (points and vectors are ``(..., 3)``). :mod:`uvdms_gym.distances`
builds the 18 UVDMS distances from them (and re-exports the public names).
"""

from __future__ import annotations

import numpy as np

_TINY = 1e-300
_PARALLEL_EPS = 1e-12


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a, b = np.broadcast_arrays(a, b)
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def point_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance from point(s) ``p`` to segment(s) ``[a, b]`` (a degenerate segment ``a = b`` is a point).

    Args:
        p: points ``(..., 3)``.
        a: segment start points ``(..., 3)`` (broadcast with ``p``).
        b: segment end points ``(..., 3)``.

    Returns:
        ``(dist, q)``: distances ``(...)`` and the closest points ``q`` on the segments ``(..., 3)``.
    """
    p, a, b = (np.asarray(x, dtype=float) for x in (p, a, b))
    ab = b - a
    den = _dot(ab, ab)
    t = np.clip(_dot(p - a, ab) / np.maximum(den, _TINY), 0.0, 1.0)
    t = np.where(den > 0.0, t, 0.0)
    q = a + t[..., None] * ab
    return np.linalg.norm(p - q, axis=-1), q


def segment_segment(
    a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact distance between segments ``[a0, a1]`` and ``[b0, b1]``, broadcasting over leading dims.

    Minimises ``|a0 + s (a1 - a0) - b0 - t (b1 - b0)|`` over ``(s, t)`` in the unit square. Candidates:
    Ericson's clamped solution (*Real-Time Collision Detection*, 5.1.9: the unconstrained ``s`` clamped,
    ``t`` optimal for it, ``s`` re-optimised if ``t`` had to be clamped) and the four end-point-to-segment
    projections; the smallest actual distance wins. Ericson's solution is the global minimum (convexity)
    whenever ``s`` is computed accurately; for (nearly) parallel segments ``s`` is ill-conditioned, but
    then the minimum lies on the square's boundary or the distance is nearly constant along the overlap,
    and an end-point projection is exact (to ``~1e-16`` m). Degenerate segments (points) are handled.

    Returns:
        ``(dist, p_on_a, p_on_b)`` with shapes ``(...)``, ``(..., 3)``, ``(..., 3)``.
    """
    a0, a1, b0, b1 = (np.asarray(x, dtype=float) for x in (a0, a1, b0, b1))
    d1 = a1 - a0
    d2 = b1 - b0
    r = a0 - b0
    a = _dot(d1, d1)
    e = _dot(d2, d2)
    b = _dot(d1, d2)
    c = _dot(d1, r)
    f = _dot(d2, r)
    a_ok = a > 0.0
    e_ok = e > 0.0
    inv_a = np.where(a_ok, 1.0 / np.where(a_ok, a, 1.0), 0.0)  # a point: any s, take 0
    inv_e = np.where(e_ok, 1.0 / np.where(e_ok, e, 1.0), 0.0)
    den = a * e - b * b
    gen = den > _PARALLEL_EPS * a * e
    s = np.where(gen, np.clip((b * f - c * e) / np.where(gen, den, 1.0), 0.0, 1.0), 0.0)
    s = np.where(e_ok, s, np.clip(-c * inv_a, 0.0, 1.0))  # B is a point: project it onto A
    t = (b * s + f) * inv_e
    s_lo = np.clip(-c * inv_a, 0.0, 1.0)  # b0 projected onto A
    s_hi = np.clip((b - c) * inv_a, 0.0, 1.0)  # b1 projected onto A
    s = np.where(t < 0.0, s_lo, np.where(t > 1.0, s_hi, s))
    t = np.clip(t, 0.0, 1.0)
    # candidates (..., 5): Ericson, a0 -> B, a1 -> B, b0 -> A, b1 -> A
    one = np.ones_like(s)
    s_all = np.stack([s, 0.0 * one, one, s_lo, s_hi], axis=-1)
    t_all = np.stack([t, np.clip(f * inv_e, 0.0, 1.0), np.clip((f + b) * inv_e, 0.0, 1.0), 0.0 * one, one], axis=-1)
    pa = a0[..., None, :] + s_all[..., None] * d1[..., None, :]
    pb = b0[..., None, :] + t_all[..., None] * d2[..., None, :]
    dist = np.linalg.norm(pa - pb, axis=-1)
    k = np.argmin(dist, axis=-1)[..., None]
    pa = np.take_along_axis(pa, k[..., None], axis=-2)[..., 0, :]
    pb = np.take_along_axis(pb, k[..., None], axis=-2)[..., 0, :]
    return np.take_along_axis(dist, k, axis=-1)[..., 0], pa, pb


def point_rectangle(
    p: np.ndarray, center: np.ndarray, u: np.ndarray, v: np.ndarray, half_extents: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Distance from point(s) to the filled rectangle ``center + s u + t v``, ``|s| <= h0``, ``|t| <= h1``.

    Args:
        p: points ``(..., 3)``.
        center: rectangle centres ``(..., 3)``.
        u: first in-plane unit axis ``(..., 3)`` (orthogonal to ``v``).
        v: second in-plane unit axis ``(..., 3)``.
        half_extents: half sizes along ``u`` and ``v``, ``(..., 2)``.

    Returns:
        ``(dist, q)``: distances ``(...)`` and closest points on the rectangles ``(..., 3)``.
    """
    p, center, u, v, h = (np.asarray(x, dtype=float) for x in (p, center, u, v, half_extents))
    w = p - center
    s = np.clip(_dot(w, u), -h[..., 0], h[..., 0])
    t = np.clip(_dot(w, v), -h[..., 1], h[..., 1])
    q = center + s[..., None] * u + t[..., None] * v
    return np.linalg.norm(p - q, axis=-1), q


def rectangle_edges(
    center: np.ndarray, u: np.ndarray, v: np.ndarray, half_extents: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The four edges of rectangle(s): start and end points, each ``(..., 4, 3)``."""
    center, u, v, h = (np.asarray(x, dtype=float) for x in (center, u, v, half_extents))
    hu = h[..., 0, None] * u
    hv = h[..., 1, None] * v
    c00 = center - hu - hv
    c10 = center + hu - hv
    c11 = center + hu + hv
    c01 = center - hu + hv
    start = np.stack([c00, c10, c11, c01], axis=-2)
    end = np.stack([c10, c11, c01, c00], axis=-2)
    return start, end


def _segment_plane_crossing(a0, a1, center, u, v, h):
    """Crossing point of segments with filled rectangles: ``(hit (...), x (..., 3))``."""
    n = _cross(u, v)
    da = _dot(a0 - center, n)
    db = _dot(a1 - center, n)
    den = da - db
    cross = (da * db <= 0.0) & (den != 0.0)
    lam = np.where(cross, da / np.where(cross, den, 1.0), 0.0)
    x = a0 + lam[..., None] * (a1 - a0)
    w = x - center
    inside = (np.abs(_dot(w, u)) <= h[..., 0]) & (np.abs(_dot(w, v)) <= h[..., 1])
    return cross & inside, x


def segment_rectangle(
    a0: np.ndarray, a1: np.ndarray, center: np.ndarray, u: np.ndarray, v: np.ndarray, half_extents: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact distance from segment(s) ``[a0, a1]`` to filled rectangle(s), broadcasting over leading dims.

    If the segment crosses the rectangle the distance is 0 (both closest points at the crossing).
    Otherwise the minimum lies at an end point (projected onto the rectangle) or on one of the four edges
    (the distance to the rectangle is convex along the segment; in the open face region it is linear, so
    an interior minimum there is either a crossing or is attained at an end point too).

    Returns:
        ``(dist, p_on_segment, p_on_rectangle)`` with shapes ``(...)``, ``(..., 3)``, ``(..., 3)``.
    """
    a0, a1, center, u, v, h = (np.asarray(x, dtype=float) for x in (a0, a1, center, u, v, half_extents))
    shape = np.broadcast_shapes(a0.shape, a1.shape, center.shape, u.shape, v.shape, (*h.shape[:-1], 3))
    a0, a1, center, u, v = (np.broadcast_to(x, shape) for x in (a0, a1, center, u, v))
    h = np.broadcast_to(h, (*shape[:-1], 2))
    hit, x = _segment_plane_crossing(a0, a1, center, u, v, h)
    ends = np.stack([a0, a1], axis=-2)  # (..., 2, 3)
    d_end, q_end = point_rectangle(ends, center[..., None, :], u[..., None, :], v[..., None, :], h[..., None, :])
    e0, e1 = rectangle_edges(center, u, v, h)
    d_edge, p_edge, q_edge = segment_segment(a0[..., None, :], a1[..., None, :], e0, e1)
    dist = np.concatenate([d_end, d_edge], axis=-1)  # (..., 6)
    p_all = np.concatenate([ends, p_edge], axis=-2)
    q_all = np.concatenate([q_end, q_edge], axis=-2)
    k = np.argmin(dist, axis=-1)
    d = np.take_along_axis(dist, k[..., None], axis=-1)[..., 0]
    p = np.take_along_axis(p_all, k[..., None, None], axis=-2)[..., 0, :]
    q = np.take_along_axis(q_all, k[..., None, None], axis=-2)[..., 0, :]
    d = np.where(hit, 0.0, d)
    p = np.where(hit[..., None], x, p)
    q = np.where(hit[..., None], x, q)
    return d, p, q


def sample_segment(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """Algorithm 1 sample points ``P'(i) = A + (i/n) AB`` for ``i = 0..n`` (both ends): ``(..., n+1, 3)``.

    The paper's loop runs ``i = 1..n`` (it never samples ``A`` itself); this project also samples
    ``i = 0`` so that both end points are included. The sampling interval is ``r = |AB| / n`` either way.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    lam = np.arange(n + 1, dtype=float) / n
    return a[..., None, :] + lam[:, None] * (b - a)[..., None, :]


def algorithm1_segment(
    a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, n: int = 20
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Algorithm 1 for link ``AB`` vs obstacle segment(s) ``CD``: conservative distance ``d' = d - r``.

    ``AB`` is sampled with :func:`sample_segment`; ``d`` is the minimum exact point-to-segment distance of
    the samples to ``CD`` and ``r = |AB|/n``. ``c, d`` may carry one extra axis before the coordinates
    (``(..., m, 3)``, several obstacle segments, e.g. the links of the other arm): the minimum over them is
    taken. Theorem 1: ``d' <= d*`` (the exact segment-segment distance); with samples at both ends the
    error ``d* - d'`` lies in ``[r/2, r]``.

    Returns:
        ``(d_prime, p, e)``: conservative distances ``(...)``, the chosen sample point on ``AB`` and its
        closest point on the obstacle (``|e - p| = d' + r``).
    """
    a, b, c, d = (np.asarray(x, dtype=float) for x in (a, b, c, d))
    many = c.ndim > a.ndim
    pts = sample_segment(a, b, n)  # (..., n+1, 3)
    if many:
        dist, q = point_segment(pts[..., :, None, :], c[..., None, :, :], d[..., None, :, :])  # (..., n+1, m)
    else:
        dist, q = point_segment(pts, c[..., None, :], d[..., None, :])  # (..., n+1)
    return _pick_min_sample(dist, q, pts, a, b, n, many)


def algorithm1_rectangle(
    a: np.ndarray,
    b: np.ndarray,
    center: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    half_extents: np.ndarray,
    n: int = 20,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Algorithm 1 for link ``AB`` vs filled rectangle(s) (point-to-rectangle distances).

    The paper says "point-plane distance"; the frame plates are finite, so the point-to-**rectangle**
    distance is used (the same plate core as the exact method). Rectangle arguments may carry one extra
    axis (``(..., m, 3)`` / ``(..., m, 2)``, several plates): the minimum over them is taken.

    Returns:
        ``(d_prime, p, e)`` as in :func:`algorithm1_segment`.
    """
    a, b, center, u, v, h = (np.asarray(x, dtype=float) for x in (a, b, center, u, v, half_extents))
    many = center.ndim > a.ndim
    pts = sample_segment(a, b, n)
    if many:
        dist, q = point_rectangle(
            pts[..., :, None, :], center[..., None, :, :], u[..., None, :, :], v[..., None, :, :], h[..., None, :, :]
        )
    else:
        dist, q = point_rectangle(pts, center[..., None, :], u[..., None, :], v[..., None, :], h[..., None, :])
    return _pick_min_sample(dist, q, pts, a, b, n, many)


def _pick_min_sample(dist, q, pts, a, b, n, many):
    if many:  # (..., n+1, m) -> (..., (n+1) m)
        m = dist.shape[-1]
        flat = dist.reshape((*dist.shape[:-2], -1))
        k = np.argmin(flat, axis=-1)
        dmin = np.take_along_axis(flat, k[..., None], axis=-1)[..., 0]
        e = np.take_along_axis(q.reshape((*q.shape[:-3], -1, 3)), k[..., None, None], axis=-2)[..., 0, :]
        i = k // m
    else:
        i = np.argmin(dist, axis=-1)
        dmin = np.take_along_axis(dist, i[..., None], axis=-1)[..., 0]
        e = np.take_along_axis(q, i[..., None, None], axis=-2)[..., 0, :]
    p = np.take_along_axis(pts, i[..., None, None], axis=-2)[..., 0, :]
    r = np.linalg.norm(b - a, axis=-1) / n
    return dmin - r, p, e
