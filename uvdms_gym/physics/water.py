"""The water around the robot, as the simulator's physics step reads it (:class:`Water`).

The hydrodynamic coefficients under the model-mismatch factors (:class:`~uvdms_gym.physics.hydro.HydroScale`), the
vehicle's constants as one flat tuple and the links' table of the compiled load kernel, the ocean current (NED and
z-up world), and the lag state of the vehicle's residual added mass (the previous physics step's velocity relative
to the water). :class:`uvdms_gym.physics.sim.UVDMSSim` holds one and reads its attributes in its physics step.
"""

from __future__ import annotations

import numpy as np
from pybullet_utils.bullet_client import BulletClient

from uvdms_gym.physics import frames, model
from uvdms_gym.physics.hydro import HydroCoefficients, HydroScale, hydro_coefficients, link_table
from uvdms_gym.physics.params import GRAVITY, UVDMSParams

MIN_VIRTUAL_MASS = model.TINY_MASS
"""Floor on the virtual added-mass link's mass and inertia when :attr:`HydroScale.added_mass` is 0."""


class Water:
    """Hydrodynamic coefficients, current and lag state of one simulator.

    Args:
        client: the simulator's ``BulletClient``.
        body: PyBullet id of the UVDMS multibody.
        added_mass_link: link index of its virtual ``added_mass`` link.
        params: the physical parameters.
        arms: whether the body has arms.

    Attributes:
        scale: the model-mismatch factors in use.
        hydro: the coefficients in use.
        vehicle_consts: ``(*d_lin, *d_quad, *a_res, up_force, *up_centroid)``, unpacked once per physics step.
        link_table: the links' rows of :func:`uvdms_gym.physics.hydro.link_forces_world`.
        link_forces: its output buffer ``(n_links, 3)``.
        n_link_state: ``7 * n_links``, the length of the links' ``[orientation xyzw, velocity]`` state.
        has_current: whether a current is set (without one the physics step runs exactly the still-water formulas).
        current_ned: the current ``v_c`` (NED, m/s).
        current_world: the same in PyBullet's z-up world.
        nu_prev: the previous physics step's (relative) body velocity ``(u, v, w)``, for the lagged added mass.
    """

    def __init__(
        self, client: BulletClient, body: int, added_mass_link: int, params: UVDMSParams, *, arms: bool
    ) -> None:
        self._client = client
        self._body = body
        self._am_link = added_mass_link
        self._params = params
        self._arms = arms
        self.scale = HydroScale()
        self.hydro: HydroCoefficients = hydro_coefficients(params, self.scale, arms=arms)
        self.has_current = False
        self.current_ned = (0.0, 0.0, 0.0)
        self.current_world = (0.0, 0.0, 0.0)
        self.nu_prev = (0.0, 0.0, 0.0)

    @property
    def current(self) -> tuple[float, float, float] | None:
        """The current in the z-up world, or ``None`` without one."""
        return self.current_world if self.has_current else None

    def set_scale(self, scale: HydroScale) -> None:
        """Recompute every coefficient for ``scale`` and give the virtual added-mass link its mass and inertia."""
        self.scale = scale
        self.hydro = h = hydro_coefficients(self._params, scale, arms=self._arms)
        self._client.changeDynamics(
            self._body,
            self._am_link,
            mass=max(h.rigid_added_mass, MIN_VIRTUAL_MASS),
            localInertiaDiagonal=[max(i, MIN_VIRTUAL_MASS) for i in h.rigid_added_inertia],
        )
        # the weight cancellation follows the mass actually set (floored), its centroid shift is negligible
        up_force = h.up_force + (max(h.rigid_added_mass, MIN_VIRTUAL_MASS) - h.rigid_added_mass) * GRAVITY
        # the vehicle's constants as one flat tuple (one unpacking per physics step instead of attribute lookups)
        self.vehicle_consts = (*h.d_lin, *h.d_quad, *h.a_res, up_force, *h.up_centroid)
        self.link_table = link_table(h)
        self.link_forces = np.empty((self.link_table.shape[0], 3))
        self.n_link_state = 7 * self.link_table.shape[0]  # [orientation xyzw, velocity] per link

    def set_current(self, v_ned: tuple[float, float, float]) -> np.ndarray | None:
        """Set the current; returns its change in the z-up world (``None`` if unchanged)."""
        if v_ned == self.current_ned:
            return None
        old_world = np.array(self.current_world)
        self.current_ned = v_ned
        self.current_world = tuple(frames.ned_to_world(np.array(v_ned)).tolist())
        self.has_current = v_ned != (0.0, 0.0, 0.0)
        return np.array(self.current_world) - old_world

    def shift_lag(self, dv_world: np.ndarray, quat: tuple[float, ...]) -> None:
        """Re-express the lagged body velocity relative to a current changed by ``dv_world`` (body at ``quat``)."""
        dv_body = frames.quat_xyzw_to_rot(np.array(quat)).T @ dv_world  # R_WB^T dv_W = R_NB^T dv_NED
        self.nu_prev = tuple((np.array(self.nu_prev) - dv_body).tolist())

    def reset_lag(self, nu: np.ndarray, r_wb: np.ndarray) -> None:
        """The lag state of a reset to body velocity ``nu`` (``R_WB``: the body's orientation): ``nu_r``."""
        self.nu_prev = (float(nu[0]), float(nu[1]), float(nu[2]))
        if self.has_current:  # the lag state is the relative velocity nu_r = nu - R_NB^T v_c
            r_nb = frames.body_rot_world_to_ned(r_wb)
            self.nu_prev = tuple((nu[:3] - r_nb.T @ np.array(self.current_ned)).tolist())
