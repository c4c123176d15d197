"""Task definitions: references for circle tracking and object transport (docs/MODEL.md section 5), NED/SI.

A task is pure data plus a reference function ``reference(t) -> y_ref`` evaluated on any time grid, so
that controllers can preview the future reference without touching the simulator.

Circle tracking (paper Section 4.1). Both end effectors track circles in the vertical plane normal to the
vehicle's initial x axis (the NED y-z plane for zero initial yaw), mirror-symmetrically: the right end
effector is at ``c_r + rho [0, cos(phase), sin(phase)]`` and the left at ``c_l + rho [0, -cos(phase),
sin(phase)]`` with ``phase = phase0 + 2 pi t / period``, so both move inward (toward the vehicle's
centre line) together. The tracked output is ``y = [p_left (3); p_right (3)]``. [D] ``period = 10 s``,
``phase0 = 0`` (start at the outermost point, where Case 1 drives the right arm toward the right frame).

Object transport (paper Section 4.2). The object pose ``y = [x y z phi theta psi]`` moves from the start
pose to the goal pose through a mid waypoint (the average of the two poses) along a C2 cubic spline with
zero velocity at both ends (the paper's "polynomial trajectory through waypoints"), then holds.
[D] ``move_time = 20 s``; the episode covers the move plus a hold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from uvdms_gym.physics.params import CIRCLE_Q0_LEFT_DEG, CIRCLE_Q0_RIGHT_DEG
from uvdms_gym.utils.jit import jit

CIRCLE_CASES: dict[int, dict[str, tuple[float, ...] | float]] = {
    1: {"left_center": (2.4, -0.25, 3.08), "right_center": (2.4, 0.25, 3.08), "radius": 0.18},
    2: {"left_center": (2.5, -0.2, 3.1), "right_center": (2.5, 0.2, 3.1), "radius": 0.14},
}
"""The paper's two collision cases (Section 4.1), NED metres."""

CIRCLE_VEHICLE_START: tuple[float, ...] = (2.0, 0.0, 3.0, 0.0, 0.0, 0.0)
"""Initial vehicle pose of the circle tasks, NED m / rad [S4]."""

TRANSPORT_START_DEG: tuple[float, ...] = (2.0, 1.0, 30.0, 0.0, 0.0, 0.0)
TRANSPORT_GOAL_DEG: tuple[float, ...] = (3.0, 0.5, 28.0, 0.0, 0.0, 90.0)
"""Object start and goal poses of the transport task, NED m and ZYX Euler degrees [S4]."""

CIRCLE_REACH = 1.2
"""[D] Feasibility envelope: every circle point must lie within this distance (m) of its arm's base at the
initial vehicle pose (arm reach 0.944 m plus what the vehicle can move early in the run)."""
CIRCLE_MIN_GAP = 0.05
"""[D] Two circles must stay at least two link radii apart (m), or the end effectors would collide."""
MAX_RADIUS = 0.3
"""[D] Largest accepted circle radius, m."""

RANDOM_CIRCLE_ENVELOPE: dict[str, tuple[float, float]] = {
    "x_ahead": (0.35, 0.55),  # centre ahead of the vehicle origin, m
    "half_gap": (0.18, 0.3),  # |y| of each centre from the vehicle centre line, m
    "z_below": (0.0, 0.15),  # centre below the vehicle origin, m
    "radius": (0.1, 0.18),
}
"""[D] Envelope of ``case="random"`` circles (relative to the initial vehicle pose), sampled uniformly."""

MIXED_CASES: tuple[int | str, ...] = (1, 2, "random")
"""[D] The cases ``case="mix"`` draws from, with equal probability."""

RANDOM_GOAL_ENVELOPE: dict[str, tuple[float, float]] = {
    "dx": (-1.5, 1.5),
    "dy": (-1.5, 1.5),
    "dz": (-2.0, 2.0),
    "dyaw_deg": (-90.0, 90.0),
}
"""[D] Envelope of ``goal="random"`` transport goals, relative to the start pose, sampled uniformly."""


@dataclass(frozen=True)
class CircleTask:
    """Circle pair tracked by the two end effectors (see module docstring)."""

    left_center: np.ndarray
    right_center: np.ndarray
    radius: float
    period: float = 10.0
    phase0: float = 0.0
    vehicle_start: np.ndarray = field(default_factory=lambda: np.array(CIRCLE_VEHICLE_START))
    q0: np.ndarray = field(default_factory=lambda: np.radians(np.array(CIRCLE_Q0_LEFT_DEG + CIRCLE_Q0_RIGHT_DEG)))

    def reference(self, t: np.ndarray | float) -> np.ndarray:
        """End-effector reference ``[p_left; p_right]`` (6) at time ``t``, or ``(N, 6)`` on a grid."""
        t_arr = np.atleast_1d(np.asarray(t, dtype=float))
        phase = self.phase0 + 2.0 * math.pi * t_arr / self.period
        rc, rs = self.radius * np.cos(phase), self.radius * np.sin(phase)
        (lx, ly, lz), (rx, ry, rz) = self.left_center.tolist(), self.right_center.tolist()
        out = np.empty((t_arr.size, 6))
        out[:, 0] = lx + self.radius * 0.0  # the x offsets are zero (the circles lie in y-z planes)
        out[:, 1] = ly - rc
        out[:, 2] = lz + rs
        out[:, 3] = rx + self.radius * 0.0
        out[:, 4] = ry + rc
        out[:, 5] = rz + rs
        return out[0] if np.ndim(t) == 0 else out


def make_circle_task(
    case: int | str,
    rng: np.random.Generator | None = None,
    *,
    left_center: tuple[float, float, float] | None = None,
    right_center: tuple[float, float, float] | None = None,
    radius: float | None = None,
    period: float = 10.0,
    arm_bases_body: tuple[np.ndarray, np.ndarray] | None = None,
) -> CircleTask:
    """Build a circle task from a paper case (1, 2), ``"random"`` (needs ``rng``) and explicit overrides.

    ``"mix"`` (needs ``rng``) draws one of Case 1, Case 2 and ``"random"`` with equal probability (one
    ``rng.integers`` draw, then the drawn case as given): a training distribution with the paper's two cases as
    often as random circles, which rarely come as close to a collision as the paper's cases do.

    Raises:
        ValueError: unknown case, non-positive or too large radius or period, a centre that is not a finite
            3-vector, circles out of reach of the arms or too close to each other.
    """
    lc, rc, rad = _case_circles(case, rng)
    if left_center is not None:
        lc = _vec3(left_center, "left_center")
    if right_center is not None:
        rc = _vec3(right_center, "right_center")
    if radius is not None:
        rad = float(radius)
    if not math.isfinite(rad) or rad <= 0.0 or rad > MAX_RADIUS:
        raise ValueError(f"radius must be in (0, {MAX_RADIUS}] m, got {rad}")
    if not math.isfinite(period) or period <= 0.0:
        raise ValueError(f"period must be a positive number of seconds, got {period}")
    task = CircleTask(lc, rc, rad, float(period))
    _check_circle_feasible(task, arm_bases_body)
    return task


def _case_circles(case: int | str, rng: np.random.Generator | None) -> tuple[np.ndarray, np.ndarray, float]:
    """``(left centre, right centre, radius)`` of a paper case, a random draw, or a ``"mix"`` draw of either."""
    if case == "mix":
        if rng is None:
            raise ValueError("case='mix' needs the environment's seeded generator")
        case = MIXED_CASES[int(rng.integers(len(MIXED_CASES)))]
    if case in CIRCLE_CASES:
        spec = CIRCLE_CASES[int(case)]
        return np.array(spec["left_center"]), np.array(spec["right_center"]), float(spec["radius"])
    elif case == "random":
        if rng is None:
            raise ValueError("case='random' needs the environment's seeded generator")
        env = RANDOM_CIRCLE_ENVELOPE
        v = np.array(CIRCLE_VEHICLE_START[:3])
        x = v[0] + rng.uniform(*env["x_ahead"])
        half = rng.uniform(*env["half_gap"])
        z = v[2] + rng.uniform(*env["z_below"])
        lc, rc = np.array([x, v[1] - half, z]), np.array([x, v[1] + half, z])
        rad = float(rng.uniform(*env["radius"]))
        return lc, rc, min(rad, 0.5 * (2.0 * half - CIRCLE_MIN_GAP) - 1e-3)
    else:
        raise ValueError(f"unknown circle case {case!r}: expected 1, 2, 'random' or 'mix'")


def _vec3(v, name: str) -> np.ndarray:
    arr = np.asarray(v, dtype=float)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite 3-vector (NED metres), got {v!r}")
    return arr


def _check_circle_feasible(task: CircleTask, arm_bases_body: tuple[np.ndarray, np.ndarray] | None) -> None:
    gap = float(np.linalg.norm(task.right_center - task.left_center)) - 2.0 * task.radius
    if gap < CIRCLE_MIN_GAP:
        raise ValueError(f"infeasible circles: they come within {gap:.3f} m of each other (need >= {CIRCLE_MIN_GAP} m)")
    if task.right_center[1] <= task.left_center[1]:
        raise ValueError("infeasible circles: the left (port) circle must lie at smaller NED y than the right")
    if arm_bases_body is None:
        return
    v = task.vehicle_start
    from uvdms_gym.physics.frames import euler_to_rot

    r_nb = euler_to_rot(v[3:])
    grid = task.reference(np.linspace(0.0, task.period, 64, endpoint=False))
    for k, side in enumerate(("left", "right")):
        base = v[:3] + r_nb @ np.asarray(arm_bases_body[k])
        dist = np.linalg.norm(grid[:, 3 * k : 3 * k + 3] - base, axis=1).max()
        if dist > CIRCLE_REACH:
            raise ValueError(
                f"infeasible circle: the {side} circle reaches {dist:.2f} m from the {side} arm base at the "
                f"initial vehicle pose (reach envelope {CIRCLE_REACH} m)"
            )


@dataclass(frozen=True)
class TransportTask:
    """Object transport along a smooth reference through waypoints (see module docstring)."""

    start: np.ndarray
    goal: np.ndarray
    move_time: float = 20.0
    _spline: CubicSpline = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        mid = 0.5 * (self.start + self.goal)
        knots = np.array([0.0, 0.5 * self.move_time, self.move_time])
        spline = CubicSpline(knots, np.stack([self.start, mid, self.goal]), bc_type="clamped", axis=0)
        object.__setattr__(self, "_spline", spline)

    def reference(self, t: np.ndarray | float) -> np.ndarray:
        """Object pose reference ``[x y z phi theta psi]`` (6) at ``t`` (held after ``move_time``).

        A 0-d or 1-d ``t`` (every caller's case) is evaluated by a compiled transcription of the spline's
        piecewise-polynomial evaluation, which gives the same bits as calling the spline (tested) at a tenth
        of scipy's per-call cost; other shapes go to the spline itself.
        """
        t_arr = np.asarray(t, dtype=float)
        if t_arr.ndim > 1:
            return self._spline(np.clip(t_arr, 0.0, self.move_time))
        t_1d = t_arr.reshape(-1)
        spline = self._spline
        out = np.empty((t_1d.shape[0], spline.c.shape[2]))
        _ppoly_eval_clipped(spline.x, spline.c, t_1d, self.move_time, out)
        return out[0] if t_arr.ndim == 0 else out


@jit
def _ppoly_eval_clipped(x, c, t, t_max, out):  # noqa: C901  # pragma: no cover - compiled kernel (module docstring)
    """``PPoly(c, x)(clip(t, 0, t_max))`` in scipy's operation order (``scipy.interpolate._ppoly.evaluate``).

    The interval is the last breakpoint ``x[i] <= t`` (the last interval at and beyond ``x[-1]``, the first
    before ``x[0]``); the local polynomial is summed from the constant term up, ``res += c[k-1-m] s**m`` with
    the power built by repeated multiplication, as scipy's ``evaluate_poly1`` does. NaN passes through.
    """
    nx = x.shape[0]
    k = c.shape[0]
    for ip in range(t.shape[0]):
        v = t[ip]
        if v < 0.0:  # np.clip: np.minimum(np.maximum(t, 0), t_max), NaN kept
            v = 0.0
        if v > t_max:
            v = t_max
        if not v < x[nx - 1]:  # at or beyond the last breakpoint, or NaN
            i = nx - 2
        elif v < x[0]:
            i = 0
        else:
            lo, hi = 0, nx - 1  # x[lo] <= v < x[hi]
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if v < x[mid]:
                    hi = mid
                else:
                    lo = mid
            i = lo
        s = v - x[i]
        for jp in range(c.shape[2]):
            res = 0.0
            z = 1.0
            for m in range(k):
                res = res + c[k - m - 1, i, jp] * z
                if m < k - 1:
                    z *= s
            out[ip, jp] = res


def _pose_deg(v, name: str) -> np.ndarray:
    arr = np.asarray(v, dtype=float)
    if arr.shape != (6,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite 6-vector [x y z (m), roll pitch yaw (deg)], got {v!r}")
    if abs(arr[3]) >= 90.0 or abs(arr[4]) >= 90.0:
        raise ValueError(f"{name}: roll and pitch must be within (-90, 90) degrees, got {arr[3:5]}")
    return np.concatenate([arr[:3], np.radians(arr[3:])])


def make_transport_task(
    goal: str = "paper",
    rng: np.random.Generator | None = None,
    *,
    start_pose: tuple[float, ...] | None = None,
    goal_pose: tuple[float, ...] | None = None,
    move_time: float = 20.0,
) -> TransportTask:
    """Build a transport task. Poses in kwargs are NED metres + ZYX Euler **degrees**.

    Raises:
        ValueError: unknown goal mode, malformed poses, non-positive move time.
    """
    start = _pose_deg(start_pose if start_pose is not None else TRANSPORT_START_DEG, "start_pose")
    if goal_pose is not None:
        end = _pose_deg(goal_pose, "goal_pose")
    elif goal == "paper":
        end = _pose_deg(TRANSPORT_GOAL_DEG, "goal_pose")
    elif goal == "random":
        if rng is None:
            raise ValueError("goal='random' needs the environment's seeded generator")
        env = RANDOM_GOAL_ENVELOPE
        d = np.array([rng.uniform(*env["dx"]), rng.uniform(*env["dy"]), rng.uniform(*env["dz"])])
        end = start.copy()
        end[:3] += d
        end[5] += math.radians(rng.uniform(*env["dyaw_deg"]))
    else:
        raise ValueError(f"unknown goal {goal!r}: expected 'paper' or 'random'")
    if not math.isfinite(move_time) or move_time <= 0.0:
        raise ValueError(f"move_time must be positive seconds, got {move_time}")
    return TransportTask(start, end, float(move_time))
