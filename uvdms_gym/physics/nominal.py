"""Nominal (controller-side) dynamics of the UVDMS in ``zeta`` coordinates.

``M_n zetadot + b_n(q, zeta) = tau`` with

* ``M_n`` = Pinocchio's rigid-body mass matrix (which already holds the isotropic added mass and the
  rotational added inertia as the virtual ``added_mass`` body, see :mod:`uvdms_gym.physics.params`) plus the
  residual anisotropic added mass on the vehicle block;
* ``b_n`` = rigid-body Coriolis and gravity + residual added-mass Coriolis ``C_A,res(nu) nu``
  + vehicle damping ``D(nu) nu`` + joint gear friction ``b qdot`` + hydrostatics (buoyancy of the hull
  at ``r_b`` and of every link at its centre of volume).

Hydrostatics are computed with a second Pinocchio model whose bodies carry their *displaced* mass at their
centre of volume under an upward gravity: its generalized gravity is exactly the generalized force that
holds the buoyancy, ``-sum_i J_i^T F_b,i``, for the cost of one ``computeGeneralizedGravity`` call.

This is the model an environment's built-in low-level controller and the reference controller may use. It
omits link drag and the object's hydrodynamics and can be perturbed with scale factors, so it is
deliberately not the simulator's exact plant.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.model import link_segment
from uvdms_gym.physics.params import ARM_SIDES, GRAVITY


@dataclass(frozen=True)
class NominalScale:
    """Multiplicative factors on the nominal hydrodynamic coefficients (1.0 = the parameter values)."""

    added_mass: float = 1.0
    damping: float = 1.0
    buoyancy: float = 1.0


def _buoyancy_model(kin: KinematicModel, buoyancy_scale: float) -> pin.Model:
    """Copy of the kinematic model whose inertias are displaced water masses at the centres of volume."""
    params = kin.params
    model = pin.Model(kin.model)
    rho = params.water_density
    for jid in range(1, model.njoints):
        model.inertias[jid] = pin.Inertia.Zero()
    veh = params.vehicle
    root = pin.Inertia.FromSphere(veh.buoyancy / GRAVITY * buoyancy_scale, 0.0)
    root.lever = np.array(veh.r_b)
    model.inertias[1] = root
    for side in ARM_SIDES:
        for i in range(params.arm.n_links):
            frame = model.frames[model.getFrameId(f"{side}_link{i}")]
            a, b = link_segment(params, i)
            centre = frame.placement.act(0.5 * (a + b))  # in the parent joint's frame
            piece = pin.Inertia.FromSphere(rho * params.arm.link_volume(i) * buoyancy_scale, 0.0)
            piece.lever = centre
            model.inertias[frame.parentJoint] = model.inertias[frame.parentJoint] + piece
    model.gravity.linear = np.array([0.0, 0.0, -GRAVITY])  # buoyancy pushes up (-z in NED)
    return model


class NominalDynamics:
    """Nominal model evaluated at the state last given to its :class:`KinematicModel`.

    Args:
        kin: the kinematic model (its ``set_state`` must have been called with ``zeta`` for :meth:`bias`).
        scale: factors on added mass, damping and buoyancy (model mismatch on purpose).
    """

    def __init__(self, kin: KinematicModel, scale: NominalScale | None = None) -> None:
        self.kin = kin
        self.scale = scale or NominalScale()
        veh = kin.params.vehicle
        self._residual_ma = np.array(veh.residual_added_mass) * self.scale.added_mass
        extra = (self.scale.added_mass - 1.0) * np.array(
            [veh.rigid_added_mass] * 3 + list(veh.added_mass[3:])
        )  # perturbation of the part the rigid virtual body carries
        self._base_added = self._residual_ma + extra
        self._joint_friction = kin.params.arm.joint_friction
        self._lin = np.array(veh.linear_damping) * self.scale.damping
        self._quad = np.array(veh.quadratic_damping) * self.scale.damping
        self._bmodel = _buoyancy_model(kin, self.scale.buoyancy)
        self._bdata = self._bmodel.createData()

    def mass_matrix(self) -> np.ndarray:
        """``M_n`` (18, 18): rigid body (with the virtual added-mass body) + residual/perturbed added mass."""
        m = self.kin.mass_matrix()
        step = m.shape[0] + 1
        m.reshape(-1)[: 6 * step : step] += self._base_added  # the first 6 diagonal entries (a view of m)
        return m

    def hydrostatics(self) -> np.ndarray:
        """Generalized force (18) holding buoyancy (hull and links): add it to gravity for ``g_n``."""
        return pin.computeGeneralizedGravity(self._bmodel, self._bdata, self.kin.config).copy()

    def static_force(self) -> np.ndarray:
        """``g_n(q, eta2)`` (18): rigid gravity + hydrostatics, the force that holds the system at rest."""
        return self.kin.gravity() + self.hydrostatics()

    def damping(self, nu: np.ndarray) -> np.ndarray:
        """Vehicle damping ``D(nu) nu`` (6, body frame)."""
        return (self._lin + self._quad * np.abs(nu)) * nu

    def joint_friction(self, qdot: np.ndarray) -> np.ndarray:
        """Gear-train viscous friction torque ``b qdot`` (12)."""
        return self._joint_friction * np.asarray(qdot)

    def added_mass_coriolis(self, nu: np.ndarray) -> np.ndarray:
        """Residual/perturbed added-mass Coriolis ``C_A(nu) nu`` (6) for the diagonal part in ``_base_added``."""
        # [w x a1; v x a1 + w x a2] with a1 = m_lin v, a2 = m_ang w, written out on floats: the same products and
        # differences as np.cross (bit for bit), without its per-call overhead (np.cross: ~15 us per call)
        m0, m1, m2, m3, m4, m5 = self._base_added.tolist()
        u, v, w, p, q, r = np.asarray(nu, dtype=float)[:6].tolist()
        ax, ay, az = m0 * u, m1 * v, m2 * w
        bx, by, bz = m3 * p, m4 * q, m5 * r
        return np.array(
            [
                q * az - r * ay,
                r * ax - p * az,
                p * ay - q * ax,
                (v * az - w * ay) + (q * bz - r * by),
                (w * ax - u * az) + (r * bx - p * bz),
                (u * ay - v * ax) + (p * by - q * bx),
            ]
        )

    def bias(self) -> np.ndarray:
        """``b_n(q, zeta)`` (18) at the kinematic model's state (needs ``zeta``)."""
        zeta = self.kin.zeta
        if zeta is None:
            raise RuntimeError("bias() needs zeta: call kin.set_state(eta, q, zeta)")
        b = self.kin.nonlinear_effects() + self.hydrostatics()
        nu = zeta[:6]
        b[:6] += self.damping(nu) + self.added_mass_coriolis(nu)
        b[6:] += self.joint_friction(zeta[6:])
        return b
