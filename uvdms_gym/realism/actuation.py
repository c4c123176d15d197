"""Actuation realism: the vehicle's eight thrusters and the arm drives' speed limit.

Thrusters (:class:`Thrusters`), per physics substep, on the body wrench ``w`` (6; body frame FRD, about the body
origin) the environment wants:

1. allocation (:meth:`Thrusters.allocate`): ``f = B^+ w`` with ``B`` (6, n) the thrust configuration matrix,
   column ``i`` = ``[d_i; r_i x d_i]`` (:func:`allocation_matrix`), ``B^+`` its pseudo-inverse (least-norm thrusts);
   if a thruster leaves ``[-max_reverse, max_forward]`` the whole ``f`` is scaled by the largest ``s <= 1`` that
   fits, so the produced wrench ``s w`` keeps ``w``'s direction (``s < 1`` flags saturation);
2. dead zone, then first-order rotor dynamics (:meth:`Thrusters.step`): a command with normalised value
   ``|u| < dead_zone`` gives no thrust, any other command is the target unchanged; ``f += (1 - exp(-dt/T))
   (target - f)`` (``f = target`` for ``T = 0``); the wrench is ``B f``.

The arm drives (:func:`limit_joint_speed`): at or beyond the rated speed no torque toward faster motion.

Default layout (:data:`DEFAULT_LAYOUT`), body frame FRD (x forward, y starboard, z down; origin at the hull's
geometric centre; hull envelope 0.92 x 0.62 x 0.56 m, ``VehicleParams.size``), vectored as on the BlueROV2 Heavy:

==  =========================  ==============================  =========================================
#   position (m)               direction (positive thrust)     role
==  =========================  ==============================  =========================================
0   ( 0.30,  0.24, -0.05)      ( cos 45, -sin 45, 0)           front starboard horizontal
1   ( 0.30, -0.24, -0.05)      ( cos 45,  sin 45, 0)           front port horizontal
2   (-0.30,  0.24, -0.05)      ( cos 45,  sin 45, 0)           rear starboard horizontal
3   (-0.30, -0.24, -0.05)      ( cos 45, -sin 45, 0)           rear port horizontal
4   ( 0.41,  0.22, -0.18)      (0, 0, -1): up                  front starboard vertical
5   ( 0.41, -0.22, -0.18)      (0, 0, -1)                      front port vertical
6   (-0.41,  0.22, -0.18)      (0, 0, -1)                      rear starboard vertical
7   (-0.41, -0.22, -0.18)      (0, 0, -1)                      rear port vertical
==  =========================  ==============================  =========================================

All eight push forward (horizontal) or up (vertical) with a positive, stronger, command: the vehicle with its arms
is 165 N heavy in water and carries the arms' moment nose-up, so the vertical thrusters work mostly forward. Each
gives up to ``max_forward = 250 N`` forward and ``max_reverse = 195 N`` reverse (0.78 of forward, as a T200's
3.5 / 4.5 kgf). Placement: the arm bay is the front bottom of the hull (arm mounts at ``(0.2, +-0.2, 0.1)``, the
frame plates around and below it), so the horizontal thrusters sit 0.15 m above the mounts, the vertical ones in
the top of the hull (0.17 m from the horizontal ones, all within the envelope for a 0.1 m rotor); the
vertical thrusters are as far fore and aft as the hull allows (x = +-0.41 m), since pitch is what loads them most.

Sizing, measured (``benchmarks/task_wrenches.py``: ``campc`` through the velocity loop, the wrench applied at every
physics substep after the 500 N / 150 N m box; CircleTrack-v1 cases 1 and 2, ``case="random"`` with
``hydro_randomization=0.3`` over 12 validation draws, Transport-v1 with the paper's goal and with ``goal="random"``,
``hydro_randomization=0.3``, ``current="random"`` over 12 draws). The thrust fraction a wrench needs is the largest
``|u|`` of ``B^+ w`` (1 = one thruster at its limit); with this layout:

* the transport's whole run: 0.50 with the paper's goal; 0.89 with random goals and currents, on draws whose
  current makes the velocity loop ask beyond the box itself (``Z = -500 N`` with ``M = 150 N m``, the box's
  corner; 3 of 12 draws saturate the box there);
* the circles after their 5 s approach (the scored samples): 0.39 (case 1), 0.37 (case 2), 0.80 (random);
* the circles' approach (first 5 s, not scored; the velocity loop asks up to 664 N there and the box saturates):
  0.74, 0.88, and 1.15 on random circles, where 0.2 % of the approach substeps saturate the thrusters
  (allocation scale >= 0.87, direction kept).

So every scored wrench measured is produced with at least 11 % to spare (a committed fixture of the extremes is
checked in ``tests/uvdms_gym/realism/test_actuation.py``). Applying the tasks' wrenches through this allocation and
saturation (``task_wrenches.py --thrusters``, no lag, no dead zone) changes no draw's outcome but one random circle's
(a failure without it, a success with it: position RMSE 0.031 -> 0.027 m) and no position RMSE by more than 0.1 mm
but that circle's and one transport draw's that fails either way (0.093 -> 0.104 m).

The producible set is larger than the 500 N / 150 N m box: along each axis the allocation reaches X +707 / -552 N,
Y +-552 N, Z +780 (down) / -1000 (up) N, K +-172 N m, M +-320 N m, N +-298 N m. Inside the box is not possible
here: the transport's measured corner (Z = -500 N with M = 150 N m, within the box) needs 216 N on each front
vertical thruster (four verticals carry both), so their up-heave is at least 864 N; and one rating serves all eight
(:class:`~uvdms_gym.realism.config.ThrusterLayout` has one ``max_forward``), so the horizontal ones are as strong.
The simulator saturates the generalized force it is given at ``VehicleActuation.tau_max``: if the environment
passes the thrusters' wrench through ``UVDMSSim.step`` as it passes ``tau`` today, the effective set is the
thrusters' within the box, and with thrusters on the vehicle never has more authority than at level 0.
A 0.1 dead zone is 25 N forward (19.5 N reverse) per thruster.

Cost (``benchmarks/bench_actuation.py``, median per call, 2-core AMD EPYC shared with other jobs): ``allocate`` +
``step`` 3.5 us at load average 1.8 (5.3 us at 2.3), ``limit_joint_speed`` on 12 joints 3.0 us (4.6 us at 2.3).
"""

from __future__ import annotations

import math

import numpy as np

from uvdms_gym.realism.config import ThrusterLayout
from uvdms_gym.utils.jit import jit

WRENCH_DIM = 6
"""Components of a body wrench ``[X, Y, Z, K, M, N]`` (N, N m; body frame FRD, about the body origin)."""
UNIT_TOLERANCE = 1e-6
"""Largest ``| |d| - 1 |`` accepted for a thrust direction (a unit vector typed with six or more digits)."""

_SQRT_HALF = math.sqrt(0.5)
"""``cos 45 deg = sin 45 deg``."""

HORIZONTAL_X = 0.30
"""Horizontal thrusters' distance ahead of / behind the body origin, m (module docstring)."""
HORIZONTAL_Y = 0.24
"""Horizontal thrusters' distance to starboard / port, m."""
HORIZONTAL_Z = -0.05
"""Horizontal thrusters' height: 0.05 m above the origin (z down), 0.15 m above the arm mounts."""
VERTICAL_X = 0.41
"""Vertical thrusters' distance ahead of / behind the origin, m: as far as the 0.92 m hull allows a 0.1 m rotor."""
VERTICAL_Y = 0.22
"""Vertical thrusters' distance to starboard / port, m."""
VERTICAL_Z = -0.18
"""Vertical thrusters' height: 0.18 m above the origin, in the top of the 0.56 m hull."""
MAX_FORWARD = 250.0
"""Largest thrust of one thruster, forward, N (module docstring: the sizing)."""
REVERSE_RATIO = 0.78
"""Reverse over forward thrust of a propeller, as a T200's 3.5 kgf reverse / 4.5 kgf forward."""
MAX_REVERSE = REVERSE_RATIO * MAX_FORWARD
"""Largest thrust of one thruster, reverse, N (195 N)."""
_UP = (0.0, 0.0, -1.0)

DEFAULT_LAYOUT = ThrusterLayout(
    positions=(
        (HORIZONTAL_X, HORIZONTAL_Y, HORIZONTAL_Z),  # 0: front starboard
        (HORIZONTAL_X, -HORIZONTAL_Y, HORIZONTAL_Z),  # 1: front port
        (-HORIZONTAL_X, HORIZONTAL_Y, HORIZONTAL_Z),  # 2: rear starboard
        (-HORIZONTAL_X, -HORIZONTAL_Y, HORIZONTAL_Z),  # 3: rear port
        (VERTICAL_X, VERTICAL_Y, VERTICAL_Z),  # 4: front starboard, up
        (VERTICAL_X, -VERTICAL_Y, VERTICAL_Z),  # 5: front port, up
        (-VERTICAL_X, VERTICAL_Y, VERTICAL_Z),  # 6: rear starboard, up
        (-VERTICAL_X, -VERTICAL_Y, VERTICAL_Z),  # 7: rear port, up
    ),
    directions=(
        (_SQRT_HALF, -_SQRT_HALF, 0.0),
        (_SQRT_HALF, _SQRT_HALF, 0.0),
        (_SQRT_HALF, _SQRT_HALF, 0.0),
        (_SQRT_HALF, -_SQRT_HALF, 0.0),
        _UP,
        _UP,
        _UP,
        _UP,
    ),
    max_forward=MAX_FORWARD,
    max_reverse=MAX_REVERSE,
)
"""The paper's vehicle with eight thrusters vectored as on the BlueROV2 Heavy (module docstring)."""


def allocation_matrix(layout: ThrusterLayout) -> np.ndarray:
    """The thrust configuration matrix ``B`` (6, n): column ``i`` is ``[d_i; r_i x d_i]``.

    ``B f`` is the body wrench (force; moment about the body origin) of thrusts ``f`` (N, along each ``d_i``).
    """
    r = np.asarray(layout.positions, dtype=float).reshape(-1, 3)
    d = np.asarray(layout.directions, dtype=float).reshape(-1, 3)
    return np.vstack([d.T, np.cross(r, d).T])


def check_layout(layout: ThrusterLayout) -> np.ndarray:
    """Validate ``layout``; its allocation matrix.

    Raises:
        ValueError: ``"realism: layout ..."``, one line naming the problem: positions and directions of
            different counts or not ``(x, y, z)`` triples, a non-finite value, a zero or non-unit direction,
            a limit that is not a finite number ``> 0``, or a rank below 6 (some wrench cannot be produced).
    """
    try:
        r = np.asarray(layout.positions, dtype=float)
        d = np.asarray(layout.directions, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"realism: layout positions and directions must be (x, y, z) triples ({exc})") from None
    if r.ndim != 2 or r.shape[1] != 3 or d.ndim != 2 or d.shape[1] != 3:
        raise ValueError(
            f"realism: layout positions and directions must be (x, y, z) triples, got shapes {r.shape}, {d.shape}"
        )
    if r.shape[0] != d.shape[0]:
        raise ValueError(f"realism: layout has {r.shape[0]} positions but {d.shape[0]} directions")
    if not (np.isfinite(r).all() and np.isfinite(d).all()):
        raise ValueError("realism: layout positions and directions must be finite")
    norms = np.linalg.norm(d, axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > UNIT_TOLERANCE)
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"realism: layout direction {i} must be a unit vector, got {d[i].tolist()} (norm {norms[i]})")
    for name in ("max_forward", "max_reverse"):
        v = getattr(layout, name)
        ok = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and math.isfinite(v)
        if not ok or v <= 0:
            raise ValueError(f"realism: layout {name} must be a finite number > 0, got {v!r}")
    b = allocation_matrix(layout)
    rank = int(np.linalg.matrix_rank(b))
    if rank < WRENCH_DIM:
        raise ValueError(
            f"realism: layout has rank {rank} < 6 (some body wrench cannot be produced by its {r.shape[0]} thrusters)"
        )
    return b


def _finite_number(name: str, value: float, *, positive: bool) -> float:
    """``value`` as a float; ``ValueError`` naming ``name`` unless finite and ``> 0`` (``>= 0`` if not positive)."""
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not ok or not math.isfinite(value) or value < 0 or (positive and value == 0):
        need = "a finite number > 0" if positive else "a finite number >= 0"
        raise ValueError(f"realism: {name} must be {need}, got {value!r}")
    return float(value)


class Thrusters:
    """The vehicle's thrusters: allocation with direction-keeping saturation, dead zone, rotor dynamics.

    The allocation matrix ``B`` (:func:`allocation_matrix`) and its Moore-Penrose pseudo-inverse ``B^+`` are built
    once. Per physics substep the environment calls :meth:`allocate` on the wrench it wants and :meth:`step` on the
    thrust commands that returns; both run one compiled kernel on preallocated arrays (module docstring: the
    measured cost).

    Args:
        layout: the thrusters (``None``: :data:`DEFAULT_LAYOUT`).
        rotor_time_constant: first-order lag ``T`` of every thruster's thrust, s (``0``: no lag).
        dead_zone: normalised commands with ``|u| < dead_zone`` produce no thrust (``0 <= dead_zone < 1``).
        physics_dt: the physics substep, s.

    Raises:
        ValueError: ``"realism: ..."`` naming the bad argument (:func:`check_layout` for the layout).
    """

    def __init__(
        self,
        layout: ThrusterLayout | None = None,
        *,
        rotor_time_constant: float = 0.0,
        dead_zone: float = 0.0,
        physics_dt: float,
    ) -> None:
        layout = DEFAULT_LAYOUT if layout is None else layout
        b = check_layout(layout)
        tc = _finite_number("rotor_time_constant", rotor_time_constant, positive=False)
        dz = _finite_number("dead_zone", dead_zone, positive=False)
        if dz >= 1.0:
            raise ValueError(f"realism: dead_zone must be below 1 (a fraction of full thrust), got {dead_zone!r}")
        dt = _finite_number("physics_dt", physics_dt, positive=True)
        self.layout = layout
        self.matrix: np.ndarray = np.ascontiguousarray(b)
        """``B`` (6, n)."""
        self.pinv: np.ndarray = np.ascontiguousarray(np.linalg.pinv(b))
        """``B^+`` (n, 6): ``B B^+ = I`` (full row rank)."""
        self.n = b.shape[1]
        self.max_forward = float(layout.max_forward)
        self.max_reverse = float(layout.max_reverse)
        self.rotor_time_constant = tc
        self.dead_zone = dz
        self.physics_dt = dt
        self.alpha = 1.0 if tc == 0.0 else -math.expm1(-dt / tc)
        """Fraction of the gap to the command closed per substep, ``1 - exp(-dt / T)`` (``1`` for ``T = 0``)."""
        self._thrust = np.zeros(self.n)
        _warm_up()

    @property
    def thrust(self) -> np.ndarray:
        """The thrusters' actual thrusts, N (n; a copy)."""
        return self._thrust.copy()

    def reset(self) -> None:
        """Stop the rotors: every actual thrust to zero."""
        self._thrust[:] = 0.0

    def allocate(self, wrench: np.ndarray) -> tuple[np.ndarray, float]:
        """The thrust commands of a body wrench, scaled down as a whole when a thruster saturates.

        ``f = B^+ w`` (the least-norm thrusts that produce ``w``); if some ``f_i`` lies outside
        ``[-max_reverse, max_forward]``, ``f`` is multiplied by the largest ``s <= 1`` that brings every thruster
        inside, so ``B f = s w`` keeps the wrench's direction and at least one thruster is exactly at its limit.

        Args:
            wrench: ``[X, Y, Z, K, M, N]`` (6), body frame FRD, about the body origin.

        Returns:
            ``(thrust_cmd (n,), scale)``: ``scale < 1`` flags saturation (the fraction of the wrench produced).

        Raises:
            ValueError: ``wrench`` is not 6 finite numbers.
        """
        w = np.asarray(wrench, dtype=float)
        if w.shape != (WRENCH_DIM,):
            raise ValueError(f"realism: wrench must have shape (6,), got {w.shape}")
        out = np.empty(self.n)
        scale = _allocate(self.pinv, w, self.max_forward, self.max_reverse, out)
        if scale < 0.0:
            raise ValueError(f"realism: wrench must be finite, got {w.tolist()}")
        return out, scale

    def step(self, thrust_cmd: np.ndarray) -> np.ndarray:
        """One physics substep of the thrusters; the body wrench ``B f`` of their actual thrusts ``f``.

        Per thruster: the command is clamped to ``[-max_reverse, max_forward]``; if its normalised value
        (:meth:`to_normalized`) has ``|u| < dead_zone`` the target thrust is ``0``, otherwise the command itself
        (no re-scaling outside the dead zone: the thrust jumps from ``0`` to ``dead_zone`` of full thrust at its
        edge); then ``f += (1 - exp(-dt / T)) (target - f)`` (``f = target`` for ``T = 0``), the exact
        discretisation of ``T df/dt = target - f`` for a target held over the substep.

        Args:
            thrust_cmd: the commanded thrusts, N (n).

        Returns:
            The wrench (6) of the thrusts after the substep (:attr:`thrust`).

        Raises:
            ValueError: ``thrust_cmd`` is not n finite numbers.
        """
        cmd = np.asarray(thrust_cmd, dtype=float)
        if cmd.shape != (self.n,):
            raise ValueError(f"realism: thrust_cmd must have shape ({self.n},), got {cmd.shape}")
        wrench = np.empty(WRENCH_DIM)
        ok = _step(
            self.matrix, cmd, self._thrust, self.max_forward, self.max_reverse, self.dead_zone, self.alpha, wrench
        )
        if not ok:
            raise ValueError(f"realism: thrust_cmd must be finite, got {cmd.tolist()}")
        return wrench

    def to_normalized(self, thrust: np.ndarray) -> np.ndarray:
        """Thrusts as normalised commands: ``u = f / max_forward`` for ``f >= 0``, ``f / max_reverse`` for ``f < 0``."""
        f = np.asarray(thrust, dtype=float)
        return np.where(f >= 0.0, f / self.max_forward, f / self.max_reverse)

    def from_normalized(self, u: np.ndarray) -> np.ndarray:
        """Normalised commands ``u`` in ``[-1, 1]`` as thrusts, N (the inverse of :meth:`to_normalized`).

        Raises:
            ValueError: some ``u`` is outside ``[-1, 1]`` or not finite.
        """
        v = np.asarray(u, dtype=float)
        if not (np.abs(v) <= 1.0).all():
            raise ValueError(f"realism: normalised thruster commands must be in [-1, 1], got {v.tolist()}")
        return np.where(v >= 0.0, v * self.max_forward, v * self.max_reverse)


@jit
def _allocate(pinv, w, fmax, rmax, out):  # pragma: no cover - compiled
    """``out = B^+ w`` scaled into the limits (:meth:`Thrusters.allocate`); the scale (``-1``: non-finite wrench).

    The binding thruster ``k`` (largest ``|f_k| / limit_k``) sets ``s = limit_k / |f_k|``; every scaled thrust is
    clamped to its limits, which only removes a rounding excess and puts ``f_k`` exactly on its limit.
    """
    n = pinv.shape[0]
    worst = 1.0
    k = -1
    for i in range(n):
        acc = 0.0
        for j in range(w.shape[0]):
            acc += pinv[i, j] * w[j]
        if not math.isfinite(acc):
            return -1.0
        out[i] = acc
        u = acc / fmax if acc >= 0.0 else -acc / rmax
        if u > worst:
            worst = u
            k = i
    if k < 0:
        return 1.0
    s = fmax / out[k] if out[k] > 0.0 else rmax / -out[k]
    for i in range(n):
        v = out[i] * s
        if v > fmax:
            v = fmax
        elif v < -rmax:
            v = -rmax
        out[i] = v
    out[k] = fmax if out[k] > 0.0 else -rmax
    return s


@jit
def _step(b, cmd, thrust, fmax, rmax, dead_zone, alpha, wrench):  # pragma: no cover - compiled
    """One substep of :meth:`Thrusters.step` in place on ``thrust``; ``wrench = B thrust``.

    Returns False, changing nothing, if ``cmd`` is not finite.
    """
    n = thrust.shape[0]
    for i in range(n):
        if not math.isfinite(cmd[i]):
            return False
    for i in range(n):
        c = cmd[i]
        if c > fmax:
            c = fmax
        elif c < -rmax:
            c = -rmax
        u = c / fmax if c >= 0.0 else -c / rmax
        if u < dead_zone:
            c = 0.0
        if alpha == 1.0:
            thrust[i] = c
        else:
            thrust[i] += alpha * (c - thrust[i])
    for j in range(b.shape[0]):
        acc = 0.0
        for i in range(n):
            acc += b[j, i] * thrust[i]
        wrench[j] = acc
    return True


def actuate(
    thrusters: Thrusters, tau: np.ndarray, qdot: np.ndarray, limit: np.ndarray, tau_sum: np.ndarray, out: np.ndarray
) -> float:
    """One physics substep of the whole actuation in one compiled call (the per-substep path of the environment).

    The body wrench ``tau[:6]`` through :meth:`Thrusters.allocate` and :meth:`Thrusters.step`, the joint torques
    ``tau[6:]`` through :func:`limit_joint_speed` (no limit if ``limit`` is empty): the same arithmetic, bit for bit.

    Args:
        thrusters: the thrusters (their actual thrusts advance one substep).
        tau: the generalized force the controller wants (6 + k).
        qdot: the joint rates (k).
        limit: the drives' rated speed: one value, one per joint, or none (empty: no limit).
        tau_sum: the commanded generalized force is added to it (6 + k): ``scale * tau[:6]`` (``B`` times the
            thrust commands: the allocation keeps the direction) and the limited joint torques.
        out: receives the generalized force that acts (6 + k): the thrusters' wrench, the limited joint torques.

    Returns:
        The allocation's scale (``< 1``: the thrusters saturated).

    Raises:
        ValueError: ``tau`` is not finite, or a limit is not finite and ``> 0``.
    """
    scale = _actuate(
        thrusters.pinv,
        thrusters.matrix,
        tau,
        qdot,
        thrusters._thrust,
        thrusters.max_forward,
        thrusters.max_reverse,
        thrusters.dead_zone,
        thrusters.alpha,
        limit,
        tau_sum,
        out,
    )
    if scale < 0.0:
        if scale == _BAD_LIMIT:
            raise ValueError(f"realism: joint_speed_limit must be finite and > 0, got {limit.tolist()}")
        raise ValueError(f"realism: wrench must be finite, got {tau[:WRENCH_DIM].tolist()}")
    return scale


_BAD_LIMIT = -2.0
"""What :func:`_actuate` returns for a joint speed limit that is not finite and ``> 0`` (``-1``: a bad wrench)."""


@jit
def _actuate(pinv, b, tau, qdot, thrust, fmax, rmax, dead_zone, alpha, limit, tau_sum, out):  # pragma: no cover
    """:func:`actuate`: ``_allocate``, ``_step`` and ``_limit_speed`` on preallocated arrays; the scale.

    Returns ``-1`` (nothing changed) for a non-finite wrench, ``-2`` for a bad limit (thrusts already advanced).
    """
    nw = pinv.shape[1]
    cmd = np.empty(pinv.shape[0])
    scale = _allocate(pinv, tau[:nw], fmax, rmax, cmd)
    if scale < 0.0:
        return scale
    for j in range(nw):
        tau_sum[j] += scale * tau[j]  # = B f_cmd: the allocation keeps the direction
    _step(b, cmd, thrust, fmax, rmax, dead_zone, alpha, out[:nw])
    nq = tau.shape[0] - nw
    tq = tau[nw:].copy()
    if limit.shape[0] > 0 and not _limit_speed(tq, qdot, limit):
        return _BAD_LIMIT
    for i in range(nq):
        tau_sum[nw + i] += tq[i]
        out[nw + i] = tq[i]
    return scale


def _warm_up() -> None:
    """Compile (or load from numba's cache) the kernels now, when the thrusters are built, not in a step."""
    pinv, b, v, out = np.zeros((1, WRENCH_DIM)), np.zeros((WRENCH_DIM, 1)), np.zeros(WRENCH_DIM), np.zeros(1)
    _allocate(pinv, v, 1.0, 1.0, out)
    _step(b, out, out.copy(), 1.0, 1.0, 0.0, 1.0, v)
    _limit_speed(out.copy(), out, np.ones(1))
    tau, total = np.zeros(WRENCH_DIM + 1), np.zeros(WRENCH_DIM + 1)
    _actuate(pinv, b, tau, out, out.copy(), 1.0, 1.0, 0.0, 1.0, np.ones(1), total, total.copy())


def limit_joint_speed(tau_q: np.ndarray, qdot: np.ndarray, limit: float | np.ndarray) -> np.ndarray:
    """The joint torques a drive with a rated speed delivers: no torque toward faster motion beyond it.

    Law, per joint ``i``: if ``|qdot_i| >= limit_i`` and ``tau_i qdot_i > 0`` (the torque would accelerate the joint
    further in its direction of motion) the torque is ``0``; otherwise it is ``tau_i`` unchanged (a torque
    opposing the motion, or any torque below the rated speed, passes). Beyond the limit the joint then coasts
    against its friction and drag until it is below the limit again.

    Args:
        tau_q: joint torques, N m (k).
        qdot: joint rates, rad/s (k).
        limit: rated speed, rad/s, one value or one per joint (``> 0``).

    Returns:
        The limited torques (a new array).

    Raises:
        ValueError: shapes differ, or ``limit`` is not finite and ``> 0``.
    """
    tau = np.array(tau_q, dtype=float)  # a copy: the caller's torques are never modified
    qd = np.asarray(qdot, dtype=float)
    lim = np.asarray(limit, dtype=float)
    if tau.ndim != 1 or qd.shape != tau.shape or lim.shape not in ((), tau.shape):
        raise ValueError(
            f"realism: limit_joint_speed needs tau_q and qdot (and a per-joint limit) of one shape, got "
            f"{tau.shape}, {qd.shape}, {lim.shape}"
        )
    if not _limit_speed(tau, qd, lim.reshape(-1)):
        raise ValueError(f"realism: joint_speed_limit must be finite and > 0, got {lim.tolist()}")
    return tau


@jit
def _limit_speed(tau, qdot, limit):  # pragma: no cover - compiled
    """:func:`limit_joint_speed` in place on ``tau``; ``limit`` holds one value or one per joint.

    Returns False for a limit that is not finite and ``> 0``.
    """
    one = limit.shape[0] == 1
    for i in range(tau.shape[0]):
        lim = limit[0] if one else limit[i]
        if not (lim > 0.0 and math.isfinite(lim)):
            return False
        if abs(qdot[i]) >= lim and tau[i] * qdot[i] > 0.0:
            tau[i] = 0.0
    return True
