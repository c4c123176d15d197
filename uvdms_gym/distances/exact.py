"""The 18 collision distances of the UVDMS (docs/MODEL.md section 4), their closest points, ``J_dis`` and ``S(d)``.

Row layout (``docs/ARCHITECTURE.md``):

* rows 0-5: right links 1..6 vs the left arm (left links 0..6, the minimum over them);
* rows 6-11: right links 1..6 vs the nearest frame plate;
* rows 12-17: left links 1..6 vs the nearest frame plate.

``d`` is the distance between the monitored link's **axis segment** and the obstacle's core (the other
link's axis segment, or the plate's mid-surface rectangle); it is not reduced by any radius. ``P`` is the
closest point on the monitored link, ``E`` on the obstacle, ``n = (E - P)/|E - P|``.

Three interchangeable methods:

* ``"exact"``: analytic segment-segment and segment-rectangle distances, computed by the compiled kernels
  of :mod:`uvdms_gym.distances.kernels` (numba); :func:`compute_distances_reference` is the vectorized numpy
  form of the same computation, kept as the reference the kernels are tested against;
* ``"sampled"``: the paper's Algorithm 1 (point samples on the monitored link, ``d' = d - r``);
* :func:`uvdms_gym.distances.pybullet_queries.pybullet_distances`: PyBullet closest-point queries on the loaded
  multibody, converted to the same axis/core convention.

All geometry helpers broadcast over leading dimensions (points and vectors are ``(..., 3)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from uvdms_gym.distances import kernels as _distkernels
from uvdms_gym.distances.geometry import (  # and the helpers imported "as" themselves below are re-exported
    _TINY,
    _cross,
    algorithm1_rectangle,
    algorithm1_segment,
    point_rectangle,
    point_segment,
)
from uvdms_gym.distances.geometry import (
    rectangle_edges as rectangle_edges,
)
from uvdms_gym.distances.geometry import (
    sample_segment as sample_segment,
)
from uvdms_gym.distances.geometry import (
    segment_rectangle as segment_rectangle,
)
from uvdms_gym.distances.geometry import (
    segment_segment as segment_segment,
)
from uvdms_gym.physics.params import D1, D2, UVDMSParams

if TYPE_CHECKING:
    from uvdms_gym.physics.kinematics import KinematicModel

N_ROWS = 18
SIDES = ("left", "right")


# --------------------------------------------------------------------------------------------------------
# Velocity damper
# --------------------------------------------------------------------------------------------------------
def velocity_damper(d: np.ndarray | float, d1: float = D1, d2: float = D2) -> np.ndarray:
    """Velocity damper ``S(d)`` (docs/MODEL.md section 4): 0 for ``d <= d1``, 1 for ``d >= d2``, ``sin^2`` between.

    ``S(d) = sin^2((pi/2) (d - d1)/(d2 - d1))`` on ``d1 < d < d2``; continuous and non-decreasing.
    """
    x = np.clip((np.asarray(d, dtype=float) - d1) / (d2 - d1), 0.0, 1.0)
    return np.sin(0.5 * np.pi * x) ** 2


# --------------------------------------------------------------------------------------------------------
# The 18 UVDMS distances
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DistanceResult:
    """The 18 distances with their closest points (NED), in the row order of the module docstring.

    Attributes:
        d: distances (18,), axis segment to obstacle core (not reduced by radii). For the ``"sampled"``
            method these are Algorithm 1's conservative ``d' = d - r`` (then ``|e - p| = d' + r``).
        p: closest point on the monitored link (18, 3).
        e: closest point on the obstacle (18, 3).
        link_frame: frame name carrying ``P`` per row (``"right_link{k}"`` / ``"left_link{k}"``).
        obstacle_frame: frame name carrying ``E`` per row (``"left_link{j}"``, or ``"vehicle"`` for plates).
        obstacle_index: left link ``j`` (0..6) for rows 0-5, plate index (``params.plates``) for rows 6-17.
        method: ``"exact"``, ``"sampled"`` or ``"pybullet"``.
    """

    d: np.ndarray
    p: np.ndarray
    e: np.ndarray
    obstacle_frame: tuple[str, ...]
    link_frame: tuple[str, ...]
    obstacle_index: np.ndarray
    method: str = "exact"

    @property
    def normals(self) -> np.ndarray:
        """Unit vectors ``n = (E - P)/|E - P|`` (18, 3); zero rows where ``E = P``."""
        diff = self.e - self.p
        nrm = np.sqrt(np.einsum("ij,ij->i", diff, diff))[:, None]
        return diff / np.where(nrm > 0.0, nrm, np.inf)


LINK_FRAMES: tuple[str, ...] = tuple(
    [f"right_link{k}" for k in range(1, 7)] * 2 + [f"left_link{k}" for k in range(1, 7)]
)
"""Frame carrying the monitored link of each row (``P``)."""

ROW_NAMES: tuple[str, ...] = tuple(
    [f"right_link{k}-left_arm" for k in range(1, 7)]
    + [f"right_link{k}-plate" for k in range(1, 7)]
    + [f"left_link{k}-plate" for k in range(1, 7)]
)
"""Human-readable name of each row."""

_LEFT_FRAMES = tuple(f"left_link{j}" for j in range(7))
_PLATE_ROWS_FRAMES = ("vehicle",) * 12


def contact_thresholds(params: UVDMSParams, obstacle_index: np.ndarray | None = None) -> np.ndarray:
    """Distance ``d`` (18,) at which the physical surfaces touch, per row.

    ``2 r`` for link-link rows, ``r + t/2`` for link-plate rows (``t`` the thickness of the row's plate,
    given by ``obstacle_index``; the thinnest plate if ``None``).

    Args:
        params: :class:`uvdms_gym.physics.params.UVDMSParams`.
        obstacle_index: :attr:`DistanceResult.obstacle_index`, or ``None``.
    """
    r = params.arm.link_radius
    t = np.array([pl.thickness for pl in params.plates], dtype=float)
    out = np.empty(N_ROWS)
    out[:6] = 2.0 * r
    out[6:] = r + 0.5 * (t.min() if obstacle_index is None else t[np.asarray(obstacle_index)[6:]])
    return out


def _plate_arrays(plates) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    c = np.array([pl[0] for pl in plates], dtype=float)
    u = np.array([pl[1] for pl in plates], dtype=float)
    v = np.array([pl[2] for pl in plates], dtype=float)
    h = np.array([pl[3] for pl in plates], dtype=float)
    return c, u, v, h


def _monitored(seg: np.ndarray) -> np.ndarray:
    """Monitored links of the plate rows 6-17: right links 1..6 then left links 1..6, (12, 2, 3)."""
    return seg[::-1, 1:].reshape(12, 2, 3)


def _link_link_exact(seg: np.ndarray):
    """Rows 0-5: right links 1..6 vs left links 0..6, all 42 pairs at once.

    Ericson's clamped solution (see :func:`segment_segment`) with the dot products from one Gram matrix;
    links have positive length. No parallel threshold: for (nearly) parallel pairs ``s`` is computed from
    the rounded ``den`` (floored at 1e-300, never 0/0) and clamped, ``t`` is optimal for it and ``s`` is
    re-optimised if ``t`` had to be clamped. Forcing ``s = 0`` below a threshold instead picks the wrong
    end of nearly parallel segments (errors ~1e-7 m, measured); this form matches the candidate search of
    :func:`segment_segment` to 1e-16 m on nearly parallel and exactly parallel pairs (tested).
    """
    ra = seg[1, 1:]  # (6, 2, 3)
    lb = seg[0]  # (7, 2, 3)
    a0 = ra[:, 0]
    d1 = ra[:, 1] - a0
    b0 = lb[:, 0]
    d2 = lb[:, 1] - b0
    z = np.concatenate([a0, d1, b0, d2])  # (26, 3)
    gram = z @ z.T
    a = np.maximum(np.diagonal(gram[6:12, 6:12]), _TINY)[:, None]  # (6, 1); links have positive length
    e = np.maximum(np.diagonal(gram[19:, 19:]), _TINY)  # (7,)
    b = gram[6:12, 19:]  # d1 . d2, (6, 7)
    c = np.diagonal(gram[6:12, :6])[:, None] - gram[6:12, 12:19]  # d1 . (a0 - b0)
    f = gram[:6, 19:] - np.diagonal(gram[12:19, 19:])  # d2 . (a0 - b0)
    den = np.maximum(a * e - b * b, _TINY)
    s = np.minimum(np.maximum((b * f - c * e) / den, 0.0), 1.0)
    t = (b * s + f) / e
    s_lo = np.minimum(np.maximum(-c / a, 0.0), 1.0)
    s_hi = np.minimum(np.maximum((b - c) / a, 0.0), 1.0)
    s = np.where(t < 0.0, s_lo, np.where(t > 1.0, s_hi, s))
    t = np.minimum(np.maximum(t, 0.0), 1.0)
    pa = a0[:, None, :] + s[..., None] * d1[:, None, :]  # (6, 7, 3)
    pb = b0[None] + t[..., None] * d2[None]
    diff = pa - pb
    dd = (diff * diff).sum(-1)  # (6, 7)
    j = np.argmin(dd, axis=1)
    rows = np.arange(6)
    return np.sqrt(dd[rows, j]), pa[rows, j], pb[rows, j], j


def _candidate_matrix() -> np.ndarray:
    """Linear map from per-pair features to the numerators and denominators of the 9 piece minimisers.

    Plate coordinates ``(s, t, w)`` (along ``u``, ``v``, normal), segment ``X0 + lam (ds, dt, dw)`` with
    ``X0 = (s0, t0, w0)``. Piece ``(sig, tau)``: the excess along ``u`` is ``s - hx`` (``sig = 1``),
    ``s + hx`` (``sig = -1``) or absent (inside, ``a_s = 0``), the same along ``v``; its quadratic
    ``a_s (s - sig hx)^2 + a_t (t - tau hy)^2 + w^2`` is stationary at
    ``lam = -(a_s ds (s0 - sig hx) + a_t dt (t0 - tau hy) + dw w0) / (a_s ds^2 + a_t dt^2 + dw^2)``.

    Returns:
        ``(18, 8)`` matrix ``C``: ``C @ [ds s0, dt t0, dw w0, ds hx, dt hy, ds^2, dt^2, dw^2]`` gives the 9
        numerators (with the minus sign) then the 9 denominators.
    """
    cmat = np.zeros((18, 8))
    k = 0
    for a_s, sig in ((1.0, 1.0), (1.0, -1.0), (0.0, 0.0)):
        for a_t, tau in ((1.0, 1.0), (1.0, -1.0), (0.0, 0.0)):
            cmat[k, :5] = -a_s, -a_t, -1.0, a_s * sig, a_t * tau
            cmat[9 + k, 5:] = a_s, a_t, 1.0
            k += 1
    return cmat


_CAND = _candidate_matrix()
_N_CAND = 9  # the 9 piece minimisers


@dataclass(frozen=True)
class _PlateData:
    """Constant (body-frame) plate geometry, prepared once per parameter set (pairs are link-major)."""

    basis: np.ndarray  # (n_pl * 3, 3): rows u, v, n of each plate (body)
    basis_c: np.ndarray  # (n_pl * 3,): basis rows dotted with the plate centre
    n_plates: int
    h2: np.ndarray  # (2, m * n_pl): [hx; hy] per link-plate pair
    h3: np.ndarray  # (3, m * n_pl): [hx; hy; 0]

    @classmethod
    def build(cls, plates, m: int = 12) -> _PlateData:
        u = np.array([pl.u for pl in plates], dtype=float)
        v = np.array([pl.v for pl in plates], dtype=float)
        c = np.array([pl.center for pl in plates], dtype=float)
        h = np.array([pl.half_extents for pl in plates], dtype=float)
        basis = np.stack([u, v, np.cross(u, v)], axis=1)  # (n_pl, 3, 3)
        h2 = np.tile(h, (m, 1)).T.copy()  # (2, m * n_pl)
        h3 = np.concatenate([h2, np.zeros((1, h2.shape[1]))])
        return cls(
            basis.reshape(-1, 3),
            np.einsum("pij,pj->pi", basis, c).ravel(),
            len(plates),
            h2,
            h3,
        )


_PLATE_CACHE: dict = {}


def _plate_data(params: UVDMSParams) -> _PlateData:
    key = params.plates
    pd = _PLATE_CACHE.get(key)
    if pd is None:
        pd = _PLATE_CACHE[key] = _PlateData.build(key)
    return pd


def _link_plate_exact(mon: np.ndarray, rot: np.ndarray, pos: np.ndarray, pd: _PlateData):
    """Monitored links ``mon`` (m, 2, 3) vs plates: nearest plate per link, exact.

    In plate coordinates ``(s, t, w)`` the squared distance of the segment point ``X(lam)`` to the rectangle
    is ``g(lam) = max(|s|-hx, 0)^2 + max(|t|-hy, 0)^2 + w^2``: convex, continuously differentiable and
    piecewise quadratic in ``lam`` (9 pieces, :func:`_candidate_matrix`). Let ``lam*`` minimise ``g`` on
    ``[0, 1]`` and ``q`` be the quadratic of a piece containing it. If ``q`` is strictly convex, ``lam*`` is
    ``q``'s minimiser clamped to ``[0, 1]`` (``g' = q'`` there, as ``g`` is C1: zero inside, of the right
    sign at an end). If ``q`` is flat, ``g`` keeps its minimum value over the whole piece, up to a
    breakpoint where ``s`` or ``t`` crosses ``+-h`` (so the neighbouring piece is strictly convex and
    stationary there, ``g' = 0``) or up to ``lam = 0`` (the flat piece's own candidate, ``0/0 -> 0``).
    Evaluating ``g`` at the 9 clamped piece minimisers therefore gives the exact minimum. Arrays are laid
    out coordinates first, pairs last (contiguous inner loops).

    Args:
        mon: monitored link segments in NED.
        rot: vehicle rotation ``R_NB``.
        pos: vehicle position (NED).
        pd: body-frame plate data.
    """
    m = mon.shape[0]
    n_pl = pd.n_plates
    n = m * n_pl
    bw = pd.basis @ rot.T  # (3 n_pl, 3) plate axes in NED
    off = bw @ pos + pd.basis_c
    x = bw @ mon.reshape(-1, 3).T - off[:, None]  # (3 n_pl, 2 m): rows (plate, coord), columns (link, end)
    x = x.reshape(n_pl, 3, m, 2).transpose(1, 3, 2, 0).reshape(3, 2, n)  # (coord, end, pair)
    p0 = x[:, 0]
    dl = x[:, 1] - p0
    feat = np.concatenate([dl * p0, dl[:2] * pd.h2, dl * dl])  # (8, n)
    nd = _CAND @ feat  # (18, n)
    lam = np.divide(nd[:9], nd[9:] + _TINY)  # (9, n); a zero denominator (flat piece) has a zero numerator
    np.clip(lam, 0.0, 1.0, out=lam)
    xx = p0[:, None, :] + lam * dl[:, None, :]  # (3, 9, n) plate coordinates of the candidates
    ex = np.abs(xx[:2])
    ex -= pd.h2[:, None, :]
    np.maximum(ex, 0.0, out=ex)
    g = (ex * ex).sum(0) + xx[2] * xx[2]  # (9, n)
    g = g.reshape(_N_CAND, m, n_pl).transpose(1, 2, 0).reshape(m, n_pl * _N_CAND)
    k = np.argmin(g, axis=1)
    rows = np.arange(m)
    pl = k // _N_CAND
    cand = k - pl * _N_CAND
    pair = rows * n_pl + pl
    xb = xx[:, cand, pair]  # (3, m)
    h3 = pd.h3[:, pair]
    excess = xb - np.minimum(np.maximum(xb, -h3), h3)  # P - E in plate coordinates
    p = mon[:, 0] + lam[cand, pair][:, None] * (mon[:, 1] - mon[:, 0])
    e = p - np.einsum("im,mij->mj", excess, bw.reshape(n_pl, 3, 3)[pl])
    return np.sqrt(g[rows, k]), p, e, pl


def _exact_reference(seg: np.ndarray, rot: np.ndarray, pos: np.ndarray, pd: _PlateData):
    d = np.empty(N_ROWS)
    p = np.empty((N_ROWS, 3))
    e = np.empty((N_ROWS, 3))
    idx = np.empty(N_ROWS, dtype=int)
    d[:6], p[:6], e[:6], idx[:6] = _link_link_exact(seg)
    d[6:], p[6:], e[6:], idx[6:] = _link_plate_exact(_monitored(seg), rot, pos, pd)
    return d, p, e, idx


def _sampled(seg: np.ndarray, plates, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    c, u, v, h = _plate_arrays(plates)
    n_pl = c.shape[0]
    d = np.empty(N_ROWS)
    p = np.empty((N_ROWS, 3))
    e = np.empty((N_ROWS, 3))
    idx = np.empty(N_ROWS, dtype=int)
    ra = seg[1, 1:]
    lb = seg[0]
    d[:6], p[:6], e[:6] = algorithm1_segment(ra[:, 0], ra[:, 1], lb[None, :, 0], lb[None, :, 1], n)
    mon = _monitored(seg)
    shp = (12, n_pl)
    d[6:], p[6:], e[6:] = algorithm1_rectangle(
        mon[:, 0],
        mon[:, 1],
        np.broadcast_to(c, (*shp, 3)),
        np.broadcast_to(u, (*shp, 3)),
        np.broadcast_to(v, (*shp, 3)),
        np.broadcast_to(h, (*shp, 2)),
        n,
    )
    # which obstacle: recover from the closest point (the obstacle nearest to E)
    dl, _ = point_segment(e[:6, None], lb[None, :, 0], lb[None, :, 1])
    idx[:6] = np.argmin(dl, axis=1)
    dp, _ = point_rectangle(e[6:, None], c, u, v, h)
    idx[6:] = np.argmin(dp, axis=1)
    return d, p, e, idx


_SEG_SHAPE = (2, 7, 2, 3)
_PLATE_TABLE_CACHE: dict = {}
_OBSTACLE_FRAMES_CACHE: dict[bytes, tuple[str, ...]] = {}


def _plate_table(params: UVDMSParams) -> np.ndarray:
    """:func:`uvdms_gym.distances.kernels.plate_table` of ``params.plates``, cached per plates object.

    Keyed by identity (hashing the frozen plate dataclasses costs ~2 µs per call); the cached entry keeps
    the plates object alive, so its id cannot be reused by another object.
    """
    plates = params.plates
    hit = _PLATE_TABLE_CACHE.get(id(plates))
    if hit is None or hit[0] is not plates:
        hit = _PLATE_TABLE_CACHE[id(plates)] = (plates, _distkernels.plate_table(plates))
    return hit[1]


def _obstacle_frames(idx: np.ndarray) -> tuple[str, ...]:
    """``obstacle_frame`` of a result from its ``obstacle_index`` (cached per link-link index pattern)."""
    key = idx[:6].tobytes()
    out = _OBSTACLE_FRAMES_CACHE.get(key)
    if out is None:
        out = _OBSTACLE_FRAMES_CACHE[key] = tuple(_LEFT_FRAMES[j] for j in idx[:6]) + _PLATE_ROWS_FRAMES
    return out


def compute_distances(kin: KinematicModel, method: str = "exact", n: int = 20) -> DistanceResult:
    """The 18 distances of the current state of ``kin`` (a :class:`uvdms_gym.physics.kinematics.KinematicModel`).

    The link axes come from ``kin.link_segments()``. The plates are ``kin.params.plates`` placed with the
    vehicle pose ``kin.frame_placement("vehicle")`` (the same rectangles as ``kin.plates()``, whose
    body-frame constants are prepared once); ``"sampled"`` reads ``kin.plates()``. ``"exact"`` runs the
    compiled kernel :func:`uvdms_gym.distances.kernels.exact_rows`, which agrees with
    :func:`compute_distances_reference` (numpy) to rounding.

    Args:
        kin: kinematic model after ``set_state``.
        method: ``"exact"`` (analytic) or ``"sampled"`` (Algorithm 1 with ``n`` intervals per link).
        n: number of sampling intervals for ``"sampled"`` (``n + 1`` points including both ends).

    Returns:
        The :class:`DistanceResult`.
    """
    if method == "exact":
        pos, rot = kin.frame_placement("vehicle")
        seg = np.ascontiguousarray(kin.link_segments(), dtype=float)  # no copy for KinematicModel's array
        if seg.shape != _SEG_SHAPE:  # the kernel indexes without bounds checks
            raise ValueError(f"link_segments() must have shape {_SEG_SHAPE}, got {seg.shape}")
        d = np.empty(N_ROWS)
        p = np.empty((N_ROWS, 3))
        e = np.empty((N_ROWS, 3))
        idx = np.empty(N_ROWS, dtype=np.int64)
        _distkernels.exact_rows(seg, rot, pos, _plate_table(kin.params), d, p, e, idx)
        return DistanceResult(d, p, e, _obstacle_frames(idx), LINK_FRAMES, idx, method)
    if method == "sampled":
        d, p, e, idx = _sampled(kin.link_segments(), kin.plates(), n)
    else:
        raise ValueError(f"method must be 'exact' or 'sampled', got {method!r}")
    return DistanceResult(d, p, e, _obstacle_frames(idx), LINK_FRAMES, idx, method)


def compute_distances_reference(kin: KinematicModel) -> DistanceResult:
    """``compute_distances(kin, "exact")`` by the vectorized numpy implementation (the reference).

    The same analytic method as the default ``"exact"`` path (see :func:`_link_link_exact` and
    :func:`_link_plate_exact`), written with numpy array operations; about ten times slower than the
    compiled path (numpy's per-call overhead dominates on arrays of a few dozen elements; ``uvdms bench sim``
    prints the ratio). Kept so that the kernel is tested against it (``tests/uvdms_gym/distances/test_distances.py``).

    Args:
        kin: kinematic model after ``set_state`` (or any object with ``link_segments``,
            ``frame_placement("vehicle")`` and ``params``).
    """
    pos, rot = kin.frame_placement("vehicle")
    d, p, e, idx = _exact_reference(kin.link_segments(), rot, pos, _plate_data(kin.params))
    return DistanceResult(d, p, e, _obstacle_frames(idx), LINK_FRAMES, idx, "exact")


# --------------------------------------------------------------------------------------------------------
# Distance Jacobian
# --------------------------------------------------------------------------------------------------------
_MASK_CACHE: dict[int, tuple] = {}


def _row_masks(model, res: DistanceResult) -> np.ndarray:
    """``mask(link_frame[i]) - mask(obstacle_frame[i])`` per row (18, nv): +1 moves P only, -1 E only.

    ``mask(frame)`` flags the velocity columns of the joints supporting the frame's body (Pinocchio's
    ``model.supports``); cached per model and per row layout.
    """
    hit = _MASK_CACHE.get(id(model))
    if hit is None or hit[0] is not model:
        masks = {}
        for f in model.frames:
            mask = np.zeros(model.nv)
            for j in model.supports[f.parentJoint]:
                if j > 0:
                    mask[model.idx_vs[j] : model.idx_vs[j] + model.nvs[j]] = 1.0
            masks[f.name] = mask
        hit = _MASK_CACHE[id(model)] = (model, masks, {})
    _, masks, rows = hit
    key = (res.link_frame, res.obstacle_frame)
    out = rows.get(key)
    if out is None:
        out = rows[key] = np.array([masks[f] for f in res.link_frame]) - np.array(
            [masks[f] for f in res.obstacle_frame]
        )
    return out


def distance_jacobian(kin: KinematicModel, res: DistanceResult) -> np.ndarray:
    """``J_dis`` (18, 18): row ``i`` is ``n_i^T (J_P,i - J_E,i)``, so ``v_dis = J_dis zeta`` and ``d_dot = -v_dis``.

    ``J_P,i`` (``J_E,i``) is the Jacobian of the material point at ``P_i`` (``E_i``) rigidly attached to the
    body carrying ``link_frame[i]`` (``obstacle_frame[i]``). With Pinocchio's world-frame joint Jacobian
    columns ``[v_k; w_k]`` (``kin.data.J``, filled by ``kin.set_state``) the point velocity column is
    ``v_k + w_k x P`` for every joint ``k`` supporting the body, so
    ``n^T J_P[:, k] = n . v_k + (P x n) . w_k``, and ``E x n = P x n`` (``E - P`` is parallel to ``n``):
    a column supporting both bodies cancels exactly. The base columns therefore vanish identically (both
    points ride on the vehicle); ``tests/uvdms_gym/distances/test_distances.py`` checks this against the full point
    Jacobians of ``KinematicModel.point_jacobian`` and against finite differences of ``d``.
    Rows with ``E = P`` (``d = 0``, axes intersecting) have no direction and are zero. Computed by the
    compiled kernel :func:`uvdms_gym.distances.kernels.jdis_rows` (reference: :func:`distance_jacobian_reference`).

    Args:
        kin: the :class:`uvdms_gym.physics.kinematics.KinematicModel` at the state of ``res``.
        res: distances from :func:`compute_distances` or
            :func:`uvdms_gym.distances.pybullet_queries.pybullet_distances` at that state.

    Returns:
        ``J_dis`` (18, 18), columns acting on ``zeta = [nu; qdot_l; qdot_r]``.
    """
    if res.p.shape != (N_ROWS, 3) or res.e.shape != (N_ROWS, 3):  # the kernel indexes without bounds checks
        raise ValueError(f"res.p and res.e must have shape ({N_ROWS}, 3), got {res.p.shape} and {res.e.shape}")
    return _distkernels.jdis_rows(_row_masks(kin.model, res), kin.data.J, res.p, res.e)


def distance_jacobian_reference(kin: KinematicModel, res: DistanceResult) -> np.ndarray:
    """:func:`distance_jacobian` in numpy (the reference the compiled kernel is tested against).

    Args:
        kin: the :class:`uvdms_gym.physics.kinematics.KinematicModel` at the state of ``res``.
        res: distances at that state.
    """
    sel = _row_masks(kin.model, res)
    jac = kin.data.J  # (6, nv) [v_k; w_k] at the NED origin
    nrm = res.normals
    # E x n = P x n because E - P is parallel to n: columns supporting both bodies cancel exactly.
    return sel * (nrm @ jac[:3] + _cross(res.p, nrm) @ jac[3:])
