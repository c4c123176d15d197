"""Hydrodynamic and hydrostatic loads of the UVDMS as pure functions of state and parameters.

Everything here is frame-agnostic plain arithmetic on floats (no PyBullet, no global state), so the
simulator (:mod:`uvdms_gym.physics.sim`) can call it on every physics step and tests can check it against
independent matrix formulas. The simulator evaluates the same equations (inlined for speed, see
``UVDMSSim._substep``); :func:`vehicle_wrench`, :func:`morison_force` and :func:`object_wrench` are the
reference implementations.

Model (docs/MODEL.md section 3; coefficients from :mod:`uvdms_gym.physics.params`, all scaled by :class:`HydroScale`):

Vehicle (body frame FRD, wrench about the body origin)
    * damping ``-D(nu) nu``, ``D = diag(d_lin + d_quad |nu|)`` (Fossen; no off-diagonal terms).
    * added mass ``M_A = diag(X_udot, Y_vdot, Z_wdot, K_pdot, M_qdot, N_rdot)`` split in two [D]:

      - the isotropic translational part ``m_a = min(X_udot, Y_vdot, Z_wdot)`` and the whole rotational
        added inertia are the rigid virtual link ``added_mass`` of the URDF (a point mass at the origin
        with inertia ``diag(K_pdot, M_qdot, N_rdot)``). Its rigid-body dynamics *are* Fossen's
        ``M_A nudot + C_A(nu) nu`` for that part (Kirchhoff's equations of a diagonal added-mass matrix with
        isotropic translational block equal those of a rigid body), integrated implicitly by the physics
        engine: no acceleration feedback, no added-mass instability. Its weight ``m_a g`` is cancelled by
        an equal upward force at the origin.
      - only the anisotropic residual ``A = diag(X_udot - m_a, Y_vdot - m_a, Z_wdot - m_a) =
        diag(31.7, 0.9, 0)`` is an external force with a one-step-lagged acceleration estimate
        ``nudot_est = (nu_k - nu_{k-1}) / dt``: force ``-A nudot_est + (A nu1) x nu2`` and Munk moment
        ``(A nu1) x nu1`` (``-C_A(nu) nu`` of Fossen's ``C_A`` for a diagonal ``M_A``:
        ``[[0, -S(A11 nu1)], [-S(A11 nu1), -S(A22 nu2)]]`` with ``A22 = 0``).

      Stability of the lag: the explicit term turns ``M a_k = F - A a_{k-1}`` into the recursion
      ``a_k = -(A / M_eff) a_{k-1} + ...``, stable iff ``A < M_eff``. The smallest effective mass of the
      base under a force at the origin is the bare vehicle's, about 130 kg in surge (rigid 106 kg at
      ``r_G`` plus the 31.3 kg virtual mass, reduced by the pitch coupling of the low centre of gravity),
      so the ratio is at most ``31.7 / 130 = 0.24``: a parasitic alternating mode that decays by a factor
      4 per step, independent of ``dt`` (tested in ``tests/uvdms_gym/physics/test_sim.py``).
    * hydrostatics: hull buoyancy ``B`` up at ``r_B``; gravity is applied by the physics engine at ``r_G``.
      The buoyancy of the two fixed arm base shells (``link0``) and the weight cancellation of the virtual
      link are also upward forces at body-fixed points: all are lumped into one upward force at their
      centroid (:attr:`HydroCoefficients.up_force`, :attr:`HydroCoefficients.up_centroid`).

Arm links 1..6 (per link, any frame with an ``up`` direction)
    * buoyancy ``rho g V_i`` (``V_i`` = :meth:`ArmParams.link_volume`) up at the centre of volume, the
      midpoint of the capsule axis (which is also the link's centre of mass in the URDF).
    * Morison quadratic drag on the velocity ``v`` of the midpoint, split along the axis unit vector ``e``:
      cross-flow ``-0.5 rho Cd (2 r L) |v_n| v_n`` and axial ``-0.5 rho Cd_ax (pi r^2) |v_t| v_t e``.
      [D] Drag from the link's own angular velocity about its midpoint is neglected: for a link of length
      ``L`` swinging about one end the midpoint approximation gives 3/4 of the strip-theory drag moment,
      and a link spinning about its midpoint (the only motion it misses) has a drag moment
      ``rho Cd r w^2 L^4 / 32`` below 0.01 N m at 1 rad/s. No added mass on the links (``rho V`` is under
      0.4 kg per link, small against the link masses and the vehicle's added mass).
    * the fixed base shells ``link0`` lie inside the hull envelope: their drag is part of the hull's
      ``D(nu)``; their buoyancy is kept (lumped into the vehicle's upward force, see above).

Object (gripped cylinder of radius ``r``, length ``L``, axis ``e`` = object ``y``)
    * buoyancy ``rho g V`` at its centre; Morison drag as for a link (cross-flow and axial).
    * added mass: potential-flow cross-flow ``m_a = C_a rho V`` on the two transverse axes, zero along the
      axis; strip-theory transverse added inertia ``m_a L^2 / 12``. [D] As for the vehicle, the added
      mass is made as rigid as possible: the object's body mass becomes ``m + m_a`` and its transverse
      inertia ``+ m_a L^2 / 12`` (set by the simulator, weight of ``m_a`` cancelled by an upward force),
      and only the *axial* excess is removed by a lagged force ``+ dP_ax/dt`` with the axial added momentum
      ``P_ax = m_a (v . e) e`` (finite difference over one step). The Kirchhoff force
      ``-d/dt [m_a (v - (v.e) e)]`` is then reproduced exactly up to the one-step lag, with lag ratio
      ``m_a / (m + m_a) = 4.7 / 9.9 = 0.48`` for the free object, instead of ``m_a / m = 0.91`` for the
      plain lagged cross-flow force (a slowly decaying ringing of the grasp forces). While gripped the
      effective mass is the whole robot's and the ratio is far smaller. Munk moment
      ``-v x P = m_a (v . e) (v x e)`` explicit; the transverse rotational drag is neglected (as for links).

Current (Fossen's relative-velocity form; :meth:`uvdms_gym.physics.sim.UVDMSSim.set_current`)
    A uniform, irrotational ocean current ``v_c`` (NED, constant or slowly varying) enters every hydrodynamic
    term through the velocity relative to the water; hydrostatics are unchanged. With ``v_c = 0`` everything
    above holds as written (and the simulator runs the code path without a current, bit for bit).

    * vehicle: ``nu_r = nu - [R_NB^T v_c; 0, 0, 0]`` (:func:`relative_body_velocity`; the angular part is
      unchanged). Damping ``-D(nu_r) nu_r``, residual added mass ``-A (nu_r,k - nu_r,k-1) / dt`` and the
      Coriolis/Munk terms ``(A nu_r1) x nu2``, ``(A nu_r1) x nu_r1``: :func:`vehicle_wrench` of ``nu_r``.
    * rigid virtual added-mass links (vehicle and object): unchanged. Their momentum is ``m_a v``, and with
      ``v_c`` constant in NED ``d/dt (m_a v_r) = m_a dv/dt``, so the rigid body already has Fossen's
      ``M_A nu_r_dot`` for the isotropic part. For a slowly varying current the term ``m_a dv_c/dt`` is
      neglected (as Fossen does for slowly varying currents); the lagged residuals neglect it too (the
      simulator re-expresses their stored previous value when the current changes).
    * arm links and object: Morison drag on ``v - v_c`` (:func:`morison_force` with ``current``); the object's
      axial added momentum ``P_ax = m_a (v_r . e) e`` and Munk moment ``m_a (v_r . e) (v_r x e)`` with
      ``v_r = v - v_c`` (:func:`object_wrench` with ``current``).

    The current's value per control step comes from :mod:`uvdms_gym.physics.current` (the environments'
    ``current`` keyword).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from uvdms_gym.physics.model import link_axis, link_segment, mount_rotation
from uvdms_gym.physics.params import ARM_SIDES, GRAVITY, UVDMSParams
from uvdms_gym.utils.jit import jit


@dataclass(frozen=True)
class HydroScale:
    """Multiplicative factors on the hydrodynamic model, for model-mismatch randomisation (default 1).

    Attributes:
        added_mass: every added mass and added inertia (vehicle rigid and residual parts, object).
        damping: the vehicle's damping matrix ``D(nu)`` (linear and quadratic).
        buoyancy: every buoyancy force (hull, arm links, object). Weights are never scaled.
        link_drag: the Morison drag of the arm links and of the object.
    """

    added_mass: float = 1.0
    damping: float = 1.0
    buoyancy: float = 1.0
    link_drag: float = 1.0

    def __post_init__(self) -> None:
        for name in ("added_mass", "damping", "buoyancy", "link_drag"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"HydroScale.{name} must be finite and >= 0, got {value!r}")


@dataclass(frozen=True)
class HydroCoefficients:
    """Every constant of the hydrodynamic model, precomputed from parameters and a :class:`HydroScale`.

    Arm-link tuples are ordered like ``q``: left links 1..6, then right links 1..6 (empty without arms).
    """

    d_lin: tuple[float, ...]
    """Vehicle linear damping (6), scaled."""
    d_quad: tuple[float, ...]
    """Vehicle quadratic damping (6), scaled."""
    a_res: tuple[float, float, float]
    """Residual translational added mass ``diag(X_udot, Y_vdot, Z_wdot) - m_a`` (3), kg, scaled."""
    rigid_added_mass: float
    """Mass of the virtual ``added_mass`` link, kg, scaled."""
    rigid_added_inertia: tuple[float, float, float]
    """Inertia of the virtual ``added_mass`` link ``(K_pdot, M_qdot, N_rdot)``, kg m^2, scaled."""
    hull_buoyancy: float
    """Hull buoyancy ``B``, N, scaled."""
    up_force: float
    """Total upward force on the vehicle body, N: hull buoyancy, base-shell buoyancy, virtual weight cancel."""
    up_centroid: tuple[float, float, float]
    """Body-frame point where :attr:`up_force` acts (centroid of its parts), m."""
    link_buoyancy: tuple[float, ...]
    """Buoyancy of each moving arm link, N, scaled."""
    link_kn: tuple[float, ...]
    """Cross-flow drag constant ``0.5 rho Cd 2 r L`` of each moving link, kg/m, scaled."""
    link_kt: tuple[float, ...]
    """Axial drag constant ``0.5 rho Cd_ax pi r^2`` of each moving link, kg/m, scaled."""
    link_axis: tuple[tuple[float, float, float], ...]
    """Unit axis of each moving link in its own link frame."""
    obj_buoyancy: float
    """Object buoyancy ``rho g V``, N, scaled."""
    obj_kn: float
    """Object cross-flow drag constant ``0.5 rho Cd 2 r L``, kg/m, scaled."""
    obj_kt: float
    """Object axial drag constant ``0.5 rho Cd_ax pi r^2``, kg/m, scaled."""
    obj_added_mass: float
    """Object transverse added mass ``C_a rho V``, kg, scaled."""
    obj_added_inertia: float
    """Object transverse added inertia ``C_a rho V L^2 / 12``, kg m^2, scaled."""
    obj_axis: tuple[float, float, float]
    """Object axis in the object frame (its ``y``)."""


def base_shell_midpoints(params: UVDMSParams) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame midpoints of the two fixed arm base shells (``left_link0``, ``right_link0``)."""
    a, b = link_segment(params, 0)
    mid = 0.5 * (a + b)
    rot = mount_rotation(params)
    out = []
    for side in ARM_SIDES:
        base = np.array(params.arm_base_left if side == "left" else params.arm_base_right)
        out.append(base + rot @ mid)
    return out[0], out[1]


def hydro_coefficients(params: UVDMSParams, scale: HydroScale | None = None, *, arms: bool = True) -> HydroCoefficients:
    """Precompute every hydrodynamic constant (see the module docstring for the equations).

    Args:
        params: the physical parameters.
        scale: model-mismatch factors (default: all 1).
        arms: the model has both arms (``False``: bare vehicle, no arm links and no base shells).
    """
    s = scale or HydroScale()
    veh, arm, obj = params.vehicle, params.arm, params.obj
    rho = params.water_density
    ma = veh.rigid_added_mass * s.added_mass
    # Upward forces at body-fixed points, lumped: hull buoyancy, base shells, virtual-link weight cancel.
    ups: list[tuple[float, np.ndarray]] = [(veh.buoyancy * s.buoyancy, np.array(veh.r_b, dtype=float))]
    if arms:
        shell_b = rho * GRAVITY * arm.link_volume(0) * s.buoyancy
        ups += [(shell_b, m) for m in base_shell_midpoints(params)]
    ups.append((ma * GRAVITY, np.zeros(3)))
    up_force = sum(f for f, _ in ups)
    up_centroid = sum(f * r for f, r in ups) / up_force if up_force > 0.0 else np.zeros(3)
    moving = range(1, arm.n_links) if arms else range(0)
    r = arm.link_radius
    link_b, link_kn, link_kt, axes = [], [], [], []
    for _side in ARM_SIDES if arms else ():
        for i in moving:
            link_b.append(rho * GRAVITY * arm.link_volume(i) * s.buoyancy)
            link_kn.append(0.5 * rho * arm.drag_coefficient * 2.0 * r * arm.link_length[i] * s.link_drag)
            link_kt.append(0.5 * rho * arm.axial_drag_coefficient * math.pi * r**2 * s.link_drag)
            axes.append(tuple(float(x) for x in link_axis(params, i)))
    m_a_obj = obj.added_mass_coefficient * rho * obj.volume * s.added_mass
    return HydroCoefficients(
        d_lin=tuple(d * s.damping for d in veh.linear_damping),
        d_quad=tuple(d * s.damping for d in veh.quadratic_damping),
        a_res=tuple(a * s.added_mass for a in veh.residual_added_mass[:3]),  # type: ignore[arg-type]
        rigid_added_mass=ma,
        rigid_added_inertia=tuple(i * s.added_mass for i in veh.added_mass[3:]),  # type: ignore[arg-type]
        hull_buoyancy=veh.buoyancy * s.buoyancy,
        up_force=float(up_force),
        up_centroid=tuple(float(x) for x in up_centroid),  # type: ignore[arg-type]
        link_buoyancy=tuple(link_b),
        link_kn=tuple(link_kn),
        link_kt=tuple(link_kt),
        link_axis=tuple(axes),  # type: ignore[arg-type]
        obj_buoyancy=rho * GRAVITY * obj.volume * s.buoyancy,
        obj_kn=0.5 * rho * obj.drag_coefficient * 2.0 * obj.radius * obj.length * s.link_drag,
        obj_kt=0.5 * rho * obj.axial_drag_coefficient * math.pi * obj.radius**2 * s.link_drag,
        obj_added_mass=m_a_obj,
        obj_added_inertia=m_a_obj * obj.length**2 / 12.0,
        obj_axis=(0.0, 1.0, 0.0),
    )


def relative_body_velocity(nu: Sequence[float], r_nb: np.ndarray, v_c: Sequence[float] | None) -> np.ndarray:
    """Body velocity relative to the water, ``nu_r = nu - [R_NB^T v_c; 0, 0, 0]`` (irrotational current).

    Args:
        nu: body velocity ``[u v w p q r]`` (FRD).
        r_nb: body orientation ``R_NB``.
        v_c: current, NED, m/s (``None``: no current, ``nu`` is returned as an array).

    Returns:
        ``nu_r`` (6).
    """
    out = np.array(nu, dtype=float)
    if v_c is not None:
        out[:3] -= np.asarray(r_nb, dtype=float).T @ np.asarray(v_c, dtype=float)
    return out


def vehicle_wrench(nu: Sequence[float], nudot_est: Sequence[float], c: HydroCoefficients) -> tuple[float, ...]:
    """Damping and residual added-mass wrench on the vehicle, body frame, about the body origin.

    ``tau = -D(nu) nu - A nudot_est - C_A,res(nu) nu`` with ``A = diag(a_res)`` (translational only):
    force ``-d(nu1) nu1 - A nudot1 + (A nu1) x nu2``, moment ``-d(nu2) nu2 + (A nu1) x nu1``. In a current
    pass the relative velocity ``nu_r`` (:func:`relative_body_velocity`) and its lagged derivative estimate.

    Args:
        nu: body velocity ``[u v w p q r]`` relative to the water (the body velocity without a current).
        nudot_est: estimate of ``nudot`` (of ``nu_r`` in a current; only its first three entries are used).
        c: coefficients from :func:`hydro_coefficients`.

    Returns:
        ``(X, Y, Z, K, M, N)``.
    """
    u, v, w, p, q, r = (float(x) for x in nu)
    dl, dq = c.d_lin, c.d_quad
    a1, a2, a3 = c.a_res
    p1, p2, p3 = a1 * u, a2 * v, a3 * w  # residual added momentum A nu1
    return (
        -(dl[0] + dq[0] * abs(u)) * u - a1 * float(nudot_est[0]) + (p2 * r - p3 * q),
        -(dl[1] + dq[1] * abs(v)) * v - a2 * float(nudot_est[1]) + (p3 * p - p1 * r),
        -(dl[2] + dq[2] * abs(w)) * w - a3 * float(nudot_est[2]) + (p1 * q - p2 * p),
        -(dl[3] + dq[3] * abs(p)) * p + (p2 * w - p3 * v),
        -(dl[4] + dq[4] * abs(q)) * q + (p3 * u - p1 * w),
        -(dl[5] + dq[5] * abs(r)) * r + (p1 * v - p2 * u),
    )


def morison_force(
    vel: Sequence[float],
    axis: Sequence[float],
    kn: float,
    kt: float,
    current: Sequence[float] | None = None,
) -> tuple[float, float, float]:
    """Quadratic (Morison) drag on a slender body moving with ``vel``; ``axis`` is a unit vector.

    ``F = -kn |v_n| v_n - kt |v_t| v_t e`` with ``v_t = v . e``, ``v_n = v - v_t e``, where ``v = vel - current``
    is the velocity relative to the water (``current`` in the frame of ``vel``; ``None``: still water).
    """
    vx, vy, vz = (float(x) for x in _relative(vel, current))
    ex, ey, ez = (float(x) for x in axis)
    vt = vx * ex + vy * ey + vz * ez
    nx, ny, nz = vx - vt * ex, vy - vt * ey, vz - vt * ez
    kvn = kn * math.sqrt(nx * nx + ny * ny + nz * nz)
    kvt = kt * abs(vt) * vt
    return (-kvn * nx - kvt * ex, -kvn * ny - kvt * ey, -kvn * nz - kvt * ez)


def link_force(
    vel: Sequence[float],
    axis: Sequence[float],
    buoyancy: float,
    kn: float,
    kt: float,
    up: Sequence[float] = (0.0, 0.0, 1.0),
    current: Sequence[float] | None = None,
) -> tuple[float, float, float]:
    """Total hydrodynamic force on an arm link at its midpoint: Morison drag plus buoyancy along ``up``.

    The drag acts on ``vel - current`` (:func:`morison_force`); the buoyancy does not depend on the current.
    """
    fx, fy, fz = morison_force(vel, axis, kn, kt, current)
    return (fx + buoyancy * up[0], fy + buoyancy * up[1], fz + buoyancy * up[2])


LINK_TABLE_COLS = 6
"""Columns of :func:`link_table`: buoyancy, ``kn``, ``kt``, axis (3) in the link frame."""


def link_table(c: HydroCoefficients) -> np.ndarray:
    """The moving links' constants as one ``(n, LINK_TABLE_COLS)`` array for :func:`link_forces_world`."""
    out = np.empty((len(c.link_buoyancy), LINK_TABLE_COLS))
    for k in range(out.shape[0]):
        out[k] = (c.link_buoyancy[k], c.link_kn[k], c.link_kt[k], *c.link_axis[k])
    return out


@jit
def link_forces_world(states: np.ndarray, table: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`link_force` of ``n`` links in a z-up world frame, compiled (the simulator's per-step loop).

    Args:
        states: flat ``[qx qy qz qw vx vy vz]`` per link (7 n): orientation of the link frame (xyzw) and
            velocity of its midpoint relative to the water (the simulator subtracts the current), world frame.
        table: :func:`link_table`.
        out: ``(n, 3)``, filled with the world force on each link's midpoint.

    The axis ``e`` is rotated to the world as ``e + 2 w (q x e) + 2 q x (q x e)`` and the drag is
    :func:`morison_force`; the operation order is that of the former inline Python loop, and numba compiles
    without fastmath, so the forces are the same bits.
    """
    for i in range(table.shape[0]):
        j = 7 * i
        qx, qy, qz, qw = states[j], states[j + 1], states[j + 2], states[j + 3]
        vx, vy, vz = states[j + 4], states[j + 5], states[j + 6]
        fb, kn, kt, ex, ey, ez = table[i, 0], table[i, 1], table[i, 2], table[i, 3], table[i, 4], table[i, 5]
        tx = 2.0 * (qy * ez - qz * ey)
        ty = 2.0 * (qz * ex - qx * ez)
        tz = 2.0 * (qx * ey - qy * ex)
        ax = ex + qw * tx + qy * tz - qz * ty
        ay = ey + qw * ty + qz * tx - qx * tz
        az = ez + qw * tz + qx * ty - qy * tx
        vt = vx * ax + vy * ay + vz * az
        nx, ny, nz = vx - vt * ax, vy - vt * ay, vz - vt * az
        kvn = kn * math.sqrt(nx * nx + ny * ny + nz * nz)
        kvt = kt * abs(vt) * vt
        out[i, 0] = -kvn * nx - kvt * ax
        out[i, 1] = -kvn * ny - kvt * ay
        out[i, 2] = fb - kvn * nz - kvt * az


def object_wrench(
    vel: Sequence[float],
    axis: Sequence[float],
    axial_momentum_rate: Sequence[float],
    c: HydroCoefficients,
    up: Sequence[float] = (0.0, 0.0, 1.0),
    current: Sequence[float] | None = None,
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """External hydrodynamic wrench on the object about its centre (any frame with an ``up`` direction).

    The object's body mass and inertia already include the rigid part of its added mass (see the module
    docstring), so this returns: buoyancy plus the cancellation of the added mass's weight, Morison drag,
    the axial added-mass correction ``+dP_ax/dt`` and the Munk moment ``m_a (v_r . e) (v_r x e)``, all with the
    velocity relative to the water ``v_r = vel - current``.

    Args:
        vel: velocity of the object's centre.
        axis: unit axis ``e`` of the cylinder.
        axial_momentum_rate: estimate of ``d/dt [m_a (v_r . e) e]`` (lagged finite difference).
        c: coefficients from :func:`hydro_coefficients`.
        up: unit vector opposite to gravity.
        current: the current in the frame of ``vel`` (``None``: still water).

    Returns:
        ``(force, moment)``.
    """
    vel = _relative(vel, current)
    fx, fy, fz = morison_force(vel, axis, c.obj_kn, c.obj_kt)
    lift = c.obj_buoyancy + c.obj_added_mass * GRAVITY
    vx, vy, vz = (float(x) for x in vel)
    ex, ey, ez = (float(x) for x in axis)
    k = c.obj_added_mass * (vx * ex + vy * ey + vz * ez)
    force = (
        fx + lift * up[0] + float(axial_momentum_rate[0]),
        fy + lift * up[1] + float(axial_momentum_rate[1]),
        fz + lift * up[2] + float(axial_momentum_rate[2]),
    )
    moment = (k * (vy * ez - vz * ey), k * (vz * ex - vx * ez), k * (vx * ey - vy * ex))
    return force, moment


def _relative(vel: Sequence[float], current: Sequence[float] | None) -> Sequence[float]:
    """``vel - current`` (``vel`` itself without a current)."""
    if current is None:
        return vel
    return tuple(float(a) - float(b) for a, b in zip(vel, current))
