"""Distances from the robot to outer obstacles, their closest points and ``J_dis`` with the obstacle's velocity.

Rows, obstacle-major: for obstacle ``k`` (:mod:`uvdms_gym.physics.obstacles`) the robot parts of
:func:`part_names`: left links 1..6, right links 1..6 (capsules of the link radius about their axis segments),
the gripped object when present (a capsule of the object's radius whose total length is the cylinder's), and the
vehicle hull (a box of ``params.vehicle.size`` centred at the body origin). Row ``k * n_parts + i`` is
part ``i`` against obstacle ``k``.

Unlike the 18 internal rows (axis to core), these rows report **gaps between surfaces**: the core distance minus
both radii (a box has none), so that ``d = 0`` is contact whatever the obstacle's size. A negative gap is an
overlap; for the hull, once the obstacle's core is inside the box the row reports ``-radius`` (the depth is not
resolved: the episode has ended on the contact long before). ``p`` is the closest point
of the part's core (or the box), ``e`` of the obstacle's core, ``n = (e - p) / |e - p|``.

Rate: the obstacle translates with ``v_obs`` (no rotation), so
``d_dot = n^T v_obs - n^T J_P zeta = -(J_dis zeta - n^T v_obs)``: :func:`outer_distance_jacobian` returns
``J_dis`` (rows ``n^T J_P`` of the part's material point at ``p``, the same column formula as the internal rows'
:func:`uvdms_gym.distances.distance_jacobian`) and the obstacle term ``n^T v_obs``.

The segment-segment rows use Ericson's clamped closed form (degenerate segments included: a sphere's core is
a point); the box rows minimise the convex point-box distance along the obstacle's core by golden-section
search to 1e-12 of the core's length, then take the exact closest point of the box. Everything runs in one
compiled kernel (:func:`outer_rows`); :func:`compute_outer_distances_reference` is a slower, independent numpy
evaluation kept for the tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from uvdms_gym.distances import kernels as _distkernels
from uvdms_gym.distances.geometry import segment_segment
from uvdms_gym.physics.obstacles import RADIUS, STATE_COLS, VEL, core_segments
from uvdms_gym.utils.jit import jit

_GOLDEN = 0.5 * (math.sqrt(5.0) - 1.0)
_GOLDEN_ITERS = 60  # 0.618^60 ~ 3e-13 of the core's length


def part_names(with_object: bool) -> tuple[str, ...]:
    """Robot parts of the rows of one obstacle: left links 1..6, right links 1..6, ``"object"``, ``"vehicle"``."""
    links = [f"{side}_link{k}" for side in ("left", "right") for k in range(1, 7)]
    return tuple(links + (["object"] if with_object else []) + ["vehicle"])


def part_frames(with_object: bool) -> tuple[str, ...]:
    """Model frame carrying each part (the object rides on the right gripper, ``right_grasp``)."""
    return tuple("right_grasp" if n == "object" else n for n in part_names(with_object))


@dataclass(frozen=True)
class OuterDistances:
    """Gaps between the robot's parts and the obstacles, with closest points (NED).

    Attributes:
        d: surface gaps ``(K * n_parts,)``, obstacle-major (negative: penetration).
        p: closest points on the parts' cores or the hull box ``(K * n_parts, 3)``.
        e: closest points on the obstacles' cores ``(K * n_parts, 3)``.
        parts: part name of each row.
        obstacle_index: obstacle of each row.
        n_parts: parts per obstacle.
    """

    d: np.ndarray
    p: np.ndarray
    e: np.ndarray
    parts: tuple[str, ...]
    obstacle_index: np.ndarray
    n_parts: int

    @property
    def normals(self) -> np.ndarray:
        """Unit vectors ``(e - p) / |e - p|`` per row (zero where ``e = p``)."""
        diff = self.e - self.p
        nrm = np.sqrt(np.einsum("ij,ij->i", diff, diff))[:, None]
        return diff / np.where(nrm > 0.0, nrm, np.inf)

    def per_obstacle(self) -> np.ndarray:
        """The gaps as ``(K, n_parts)``."""
        return self.d.reshape(-1, self.n_parts)


def robot_parts(kin, with_object: bool) -> tuple[np.ndarray, np.ndarray]:
    """Core segments ``(n_parts - 1, 2, 3)`` of the capsule parts and their radii, at ``kin``'s state."""
    seg = kin.link_segments()  # (2, 7, 2, 3): side 0 left
    cores = [seg[0, 1:], seg[1, 1:]]
    radii = [np.full(12, kin.params.arm.link_radius)]  # (the reference path's own constants)
    if with_object:
        o = kin.params.obj
        p, r = kin.object_pose("right")
        half = (0.5 * o.length - o.radius) * r[:, 1]  # the object's axis is its y
        cores.append(np.stack([p - half, p + half])[None])
        radii.append(np.array([o.radius]))
    return np.ascontiguousarray(np.concatenate(cores)), np.concatenate(radii)


def compute_outer_distances(
    kin, obstacles: np.ndarray, with_object: bool, segments: np.ndarray | None = None
) -> OuterDistances:
    """The rows of the module docstring at ``kin``'s state for obstacles given as ``obstacle_states`` rows.

    Args:
        kin: :class:`uvdms_gym.physics.kinematics.KinematicModel` after ``set_state``.
        obstacles: ``(K, STATE_COLS)`` (:func:`uvdms_gym.physics.obstacles.obstacle_states`, ``info["obstacles"]``).
        with_object: include the gripped object's rows.
        segments: ``kin.link_segments()`` when the caller has it already (saves recomputing it).
    """
    states = np.ascontiguousarray(obstacles, dtype=float).reshape(-1, STATE_COLS)
    params = kin.params
    consts = _constants(params, with_object)
    radii, half_box, obj_half = consts.radii, consts.half_box, consts.obj_half
    obj_seg = _NO_OBJECT
    if with_object:
        p, r = kin.object_pose("right")
        half_axis = obj_half * r[:, 1]  # the object's axis is its y
        obj_seg = np.stack([p - half_axis, p + half_axis])
    pos, rot = kin.frame_placement("vehicle")
    n_obs = states.shape[0]
    n_parts = radii.shape[0] + 1
    rows = n_obs * n_parts
    d, pts, e = np.empty(rows), np.empty((rows, 3)), np.empty((rows, 3))
    seg = kin.link_segments() if segments is None else segments
    outer_rows(seg, obj_seg, radii, rot, pos, half_box, states, d, pts, e)
    labels = consts.labels.get(n_obs)
    if labels is None:
        index = np.repeat(np.arange(n_obs), n_parts)
        index.flags.writeable = False  # shared by every result with n_obs obstacles
        labels = consts.labels[n_obs] = (part_names(with_object) * n_obs, index)
    return OuterDistances(d, pts, e, labels[0], labels[1], n_parts)


@dataclass
class _Constants:
    """Per-parameter constants of the rows: capsule radii, the hull's half extents, the object's half core."""

    params: object
    radii: np.ndarray
    half_box: np.ndarray
    obj_half: float
    labels: dict[int, tuple[tuple[str, ...], np.ndarray]]


_CONSTANTS: dict[tuple[int, bool], _Constants] = {}


def _constants(params, with_object: bool) -> _Constants:
    hit = _CONSTANTS.get((id(params), with_object))
    if hit is None or hit.params is not params:
        radii = np.full(12, params.arm.link_radius)
        hit = _CONSTANTS[(id(params), with_object)] = _Constants(
            params,
            np.r_[radii, params.obj.radius] if with_object else radii,
            0.5 * np.asarray(params.vehicle.size, dtype=float),
            0.5 * params.obj.length - params.obj.radius,
            {},
        )
    return hit


_NO_OBJECT = np.zeros((2, 3))


@dataclass(frozen=True)
class RobotTrack:
    """The robot's parts at ``T`` instants (for checking obstacle paths against a planned motion).

    Attributes:
        times: the instants, s.
        segs: link axes ``(T, 2, 7, 2, 3)``.
        obj_segs: the object's core ``(T, 2, 3)`` (zeros without an object).
        rots: hull rotations ``R_NB`` ``(T, 3, 3)``.
        poss: hull centres ``(T, 3)``.
        with_object: whether the object's rows are included.
    """

    times: np.ndarray
    segs: np.ndarray
    obj_segs: np.ndarray
    rots: np.ndarray
    poss: np.ndarray
    with_object: bool


def robot_track(kin, times: np.ndarray, etas: np.ndarray, qs: np.ndarray, with_object: bool) -> RobotTrack:
    """A :class:`RobotTrack` from states ``(eta, q)`` at ``times`` (``kin``'s state is overwritten)."""
    n = len(times)
    segs, obj_segs = np.empty((n, 2, 7, 2, 3)), np.zeros((n, 2, 3))
    rots, poss = np.empty((n, 3, 3)), np.empty((n, 3))
    obj_half = _constants(kin.params, with_object).obj_half
    for k in range(n):
        kin.set_state(etas[k], qs[k])
        segs[k] = kin.link_segments()
        poss[k], rots[k] = kin.frame_placement("vehicle")
        if with_object:
            p, r = kin.object_pose("right")
            obj_segs[k] = (p - obj_half * r[:, 1], p + obj_half * r[:, 1])
    return RobotTrack(np.asarray(times, dtype=float), segs, obj_segs, rots, poss, with_object)


def track_gaps(track: RobotTrack, params, states: np.ndarray) -> np.ndarray:
    """Gaps ``(T, n_parts)`` of one obstacle (its ``obstacle_states`` row at each instant of the track)."""
    consts = _constants(params, track.with_object)
    out = np.empty((len(track.times), consts.radii.shape[0] + 1))
    gaps_over_time(track.segs, track.obj_segs, consts.radii, track.rots, track.poss, consts.half_box,
                   np.ascontiguousarray(states, dtype=float), out)  # fmt: skip
    return out


def outer_distance_jacobian(kin, res: OuterDistances, obstacles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``J_dis`` ``(rows, 18)`` (``n^T J_P``) and the obstacle term ``n^T v_obs`` (rows,) of :class:`OuterDistances`.

    ``d_dot = -(J_dis zeta - n^T v_obs)``. The part's columns are those of the joints supporting its frame
    (:func:`part_frames`), as in :func:`uvdms_gym.distances.distance_jacobian`.
    """
    states = np.asarray(obstacles, dtype=float).reshape(-1, STATE_COLS)
    masks = part_masks(kin.model, "object" in res.parts[: res.n_parts])
    sel = np.tile(masks, (states.shape[0], 1))
    jac = _distkernels.jdis_rows(sel, kin.data.J, res.p, res.e)
    v_obs = np.repeat(states[:, VEL], res.n_parts, axis=0)
    return jac, np.einsum("ij,ij->i", res.normals, v_obs)


_MASKS: dict[tuple[int, bool], tuple[object, np.ndarray]] = {}


def part_masks(model, with_object: bool) -> np.ndarray:
    """Velocity columns of the joints supporting each part's frame, ``(n_parts, nv)`` (cached per model)."""
    hit = _MASKS.get((id(model), with_object))
    if hit is not None and hit[0] is model:
        return hit[1]
    out = np.zeros((len(part_frames(with_object)), model.nv))
    for i, name in enumerate(part_frames(with_object)):
        f = model.frames[model.getFrameId(name)]
        for j in model.supports[f.parentJoint]:
            if j > 0:
                out[i, model.idx_vs[j] : model.idx_vs[j] + model.nvs[j]] = 1.0
    _MASKS[(id(model), with_object)] = (model, out)
    return out


# ------------------------------------------------------------------------------------------------ kernels
# Scalar code throughout: numba's array temporaries and its BLAS-backed dot products on 3-vectors cost more than
# the arithmetic here.
@jit
def _segment_segment(a0x, a0y, a0z, a1x, a1y, a1z, b0x, b0y, b0z, b1x, b1y, b1z):  # pragma: no cover - compiled
    """Parameters ``(s, t)`` of the closest points of segments ``a0 a1`` and ``b0 b1`` (Ericson 5.1.9)."""
    d1x, d1y, d1z = a1x - a0x, a1y - a0y, a1z - a0z
    d2x, d2y, d2z = b1x - b0x, b1y - b0y, b1z - b0z
    rx, ry, rz = a0x - b0x, a0y - b0y, a0z - b0z
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    if a <= 1e-18 and e <= 1e-18:
        return 0.0, 0.0
    if a <= 1e-18:
        return 0.0, min(max(f / e, 0.0), 1.0)
    c = d1x * rx + d1y * ry + d1z * rz
    if e <= 1e-18:
        return min(max(-c / a, 0.0), 1.0), 0.0
    b = d1x * d2x + d1y * d2y + d1z * d2z
    den = a * e - b * b
    s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 1e-18 else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t, s = 0.0, min(max(-c / a, 0.0), 1.0)
    elif t > 1.0:
        t, s = 1.0, min(max((b - c) / a, 0.0), 1.0)
    return s, t


@jit
def _box_point(rot, pos, half, x, y, z):  # pragma: no cover - compiled
    """Closest point of the box (centre ``pos``, axes the columns of ``rot``, half extents ``half``) to a point."""
    dx, dy, dz = x - pos[0], y - pos[1], z - pos[2]
    ox, oy, oz = pos[0], pos[1], pos[2]
    for k in range(3):
        c = rot[0, k] * dx + rot[1, k] * dy + rot[2, k] * dz
        c = min(max(c, -half[k]), half[k])
        ox += rot[0, k] * c
        oy += rot[1, k] * c
        oz += rot[2, k] * c
    return ox, oy, oz


@jit
def _box_gap2(rot, pos, half, x, y, z):  # pragma: no cover - compiled
    bx, by, bz = _box_point(rot, pos, half, x, y, z)
    return (x - bx) ** 2 + (y - by) ** 2 + (z - bz) ** 2


@jit
def _box_segment(rot, pos, half, b0, b1):  # pragma: no cover - compiled
    """Parameter ``t`` of the segment's point nearest the box: golden-section search of the convex distance."""
    if b0[0] == b1[0] and b0[1] == b1[1] and b0[2] == b1[2]:
        return 0.0
    lo, hi = 0.0, 1.0
    dx, dy, dz = b1[0] - b0[0], b1[1] - b0[1], b1[2] - b0[2]
    for _ in range(_GOLDEN_ITERS):
        m1 = hi - _GOLDEN * (hi - lo)
        m2 = lo + _GOLDEN * (hi - lo)
        g1 = _box_gap2(rot, pos, half, b0[0] + m1 * dx, b0[1] + m1 * dy, b0[2] + m1 * dz)
        g2 = _box_gap2(rot, pos, half, b0[0] + m2 * dx, b0[1] + m2 * dy, b0[2] + m2 * dz)
        if g1 <= g2:
            hi = m2
        else:
            lo = m1
    return 0.5 * (lo + hi)


@jit
def _part_core(seg, obj_seg, i):  # pragma: no cover - compiled
    """End points of part ``i``'s core: left links 1..6, right links 1..6, then the object."""
    if i < 12:
        side, link = i // 6, i % 6 + 1
        return (seg[side, link, 0, 0], seg[side, link, 0, 1], seg[side, link, 0, 2],
                seg[side, link, 1, 0], seg[side, link, 1, 1], seg[side, link, 1, 2])  # fmt: skip
    return obj_seg[0, 0], obj_seg[0, 1], obj_seg[0, 2], obj_seg[1, 0], obj_seg[1, 1], obj_seg[1, 2]


@jit
def _obstacle_rows(seg, obj_seg, radii, rot, pos, half, ob, obs_seg, d, p, e, base):  # pragma: no cover - compiled
    """The rows ``base .. base + n`` (``n = len(radii) + 1``) of one obstacle ``ob`` (an ``obstacle_states`` row).

    ``obs_seg`` is a ``(2, 3)`` scratch array for the obstacle's core.
    """
    n = radii.shape[0]
    r_obs, h = ob[6], ob[7]
    for j in range(3):  # core A, B = centre -+ half length * axis
        obs_seg[0, j] = ob[j] - h * ob[8 + j]
        obs_seg[1, j] = ob[j] + h * ob[8 + j]
    b0x, b0y, b0z = obs_seg[0, 0], obs_seg[0, 1], obs_seg[0, 2]
    b1x, b1y, b1z = obs_seg[1, 0], obs_seg[1, 1], obs_seg[1, 2]
    for i in range(n):
        a0x, a0y, a0z, a1x, a1y, a1z = _part_core(seg, obj_seg, i)
        s, t = _segment_segment(a0x, a0y, a0z, a1x, a1y, a1z, b0x, b0y, b0z, b1x, b1y, b1z)
        row = base + i
        px, py, pz = a0x + s * (a1x - a0x), a0y + s * (a1y - a0y), a0z + s * (a1z - a0z)
        ex, ey, ez = b0x + t * (b1x - b0x), b0y + t * (b1y - b0y), b0z + t * (b1z - b0z)
        p[row, 0], p[row, 1], p[row, 2] = px, py, pz
        e[row, 0], e[row, 1], e[row, 2] = ex, ey, ez
        d[row] = math.sqrt((ex - px) ** 2 + (ey - py) ** 2 + (ez - pz) ** 2) - radii[i] - r_obs
    row = base + n
    t = _box_segment(rot, pos, half, obs_seg[0], obs_seg[1])
    ex, ey, ez = b0x + t * (b1x - b0x), b0y + t * (b1y - b0y), b0z + t * (b1z - b0z)
    px, py, pz = _box_point(rot, pos, half, ex, ey, ez)
    p[row, 0], p[row, 1], p[row, 2] = px, py, pz
    e[row, 0], e[row, 1], e[row, 2] = ex, ey, ez
    d[row] = math.sqrt((ex - px) ** 2 + (ey - py) ** 2 + (ez - pz) ** 2) - r_obs


@jit
def outer_rows(seg, obj_seg, radii, rot, pos, half, obstacles, d, p, e):  # pragma: no cover - compiled
    """Fill the gaps ``d``, part points ``p`` and obstacle points ``e`` of every (obstacle, part) row in place.

    Args:
        seg: link axes ``(2, 7, 2, 3)`` (``KinematicModel.link_segments``; links 1..6 are parts).
        obj_seg: the object's core segment ``(2, 3)`` (read only when ``radii`` has 13 entries).
        radii: the capsule parts' radii: 12 links, then the object if present.
        rot: the hull box's rotation ``R_NB`` (the hull is the last part of each obstacle).
        pos: the hull box's centre (the body origin), NED.
        half: the hull box's half extents.
        obstacles: ``(K, STATE_COLS)`` rows of :func:`uvdms_gym.physics.obstacles.obstacle_states`.
        d: output gaps ``(K (n + 1),)`` with ``n = len(radii)``.
        p: output points on the parts ``(K (n + 1), 3)``.
        e: output points on the obstacles ``(K (n + 1), 3)``.
    """
    n = radii.shape[0] + 1
    obs_seg = np.empty((2, 3))
    for k in range(obstacles.shape[0]):
        _obstacle_rows(seg, obj_seg, radii, rot, pos, half, obstacles[k], obs_seg, d, p, e, k * n)


@jit
def gaps_over_time(segs, obj_segs, radii, rots, poss, half, states, out):  # pragma: no cover - compiled
    """The gaps of one obstacle to a robot given at ``T`` instants: ``out[t] = d`` of :func:`outer_rows`.

    Args:
        segs: link axes per instant ``(T, 2, 7, 2, 3)``.
        obj_segs: object cores ``(T, 2, 3)``.
        radii: capsule parts' radii (as :func:`outer_rows`).
        rots: hull rotations ``(T, 3, 3)``.
        poss: hull centres ``(T, 3)``.
        half: hull half extents.
        states: the obstacle's ``obstacle_states`` row at each instant ``(T, STATE_COLS)``.
        out: output gaps ``(T, len(radii) + 1)``.
    """
    n = radii.shape[0] + 1
    obs_seg = np.empty((2, 3))
    p = np.empty((n, 3))
    e = np.empty((n, 3))
    for t in range(states.shape[0]):
        _obstacle_rows(segs[t], obj_segs[t], radii, rots[t], poss[t], half, states[t], obs_seg, out[t], p, e, 0)


# ------------------------------------------------------------------------------------------------ reference
def compute_outer_distances_reference(kin, obstacles: np.ndarray, with_object: bool) -> np.ndarray:
    """The gaps of :func:`compute_outer_distances` by independent means (for tests), ``(K * n_parts,)``.

    Capsule parts: the project's numpy ``segment_segment``. The hull: a dense sampling of the obstacle's core
    refined by a bounded scalar minimisation (scipy) of the exact point-box distance.
    """
    from scipy.optimize import minimize_scalar

    states = np.asarray(obstacles, dtype=float).reshape(-1, STATE_COLS)
    cores, radii = robot_parts(kin, with_object)
    pos, rot = kin.frame_placement("vehicle")
    half = 0.5 * np.asarray(kin.params.vehicle.size, dtype=float)

    def box_dist(x: np.ndarray) -> float:
        local = rot.T @ (x - pos)
        return float(np.linalg.norm(local - np.clip(local, -half, half)))

    out = []
    for seg, r_obs in zip(core_segments(states), states[:, RADIUS]):
        for core, r in zip(cores, radii):
            dist, _, _ = segment_segment(core[0], core[1], seg[0], seg[1])
            out.append(float(dist) - r - r_obs)
        a, b = seg[0], seg[1]

        def along(t: float, a: np.ndarray = a, b: np.ndarray = b) -> float:
            return box_dist(a + t * (b - a))

        ts = np.linspace(0.0, 1.0, 201)
        t0 = ts[int(np.argmin([along(t) for t in ts]))]
        lo, hi = max(0.0, t0 - 0.005), min(1.0, t0 + 0.005)
        best = minimize_scalar(along, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12})
        out.append(min(best.fun, along(0.0), along(1.0)) - r_obs)
    return np.array(out)
