"""Delay compensation: predict the state at the time the next command will first act.

With an action delay of ``D`` (``realism > 0``: a whole number ``d`` of physics substeps of ``dt``), the command a
controller issues at ``t`` acts from ``t + D``; until then the commands it issued during ``[t - D, t)`` act, each
from its own issue time plus ``D``. A controller that plans from the state at ``t`` plans as if its first move
acted at once, and a single 40 ms delay turned CAMPC's 3 mm circle tracking into a 0.1 m oscillation. So the CAMPC
baselines plan from the state at ``t + D`` predicted by :class:`DelayPredictor`:

* the commands issued in the last ``D`` act in turn (the substep at which each starts follows from its issue
  substep plus ``d``; before the first, the zero command the environment holds);
* the velocity ``zeta`` follows the command in effect as a first-order lag per component, at the bandwidths of the
  environment's velocity loop (:class:`uvdms_gym.envs.lowlevel.VelocityLoopGains`):
  ``zeta += (1 - exp(-omega dt)) (zeta_cmd - zeta)``;
* the pose integrates it: ``p += R(eta2) nu1 dt``, ``eta2 += T(eta2) nu2 dt``, ``q += qdot dt`` (explicit Euler
  at the substep).

Nothing else is modelled (hydrodynamics, saturation, the thrusters): the prediction spans at most a few control
steps. With ``D = 0`` the state passes through unchanged.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from uvdms_gym.envs.lowlevel import VelocityLoopGains
from uvdms_gym.physics.frames import euler_rate_matrix, euler_to_rot


class DelayPredictor:
    """The state at ``t + D`` from the state at ``t`` and the commands still to act (module docstring).

    Args:
        delay_substeps: ``d``, the action delay in physics substeps.
        physics_dt: the physics step, s.
        n_substeps: physics substeps per control step.
        gains: the velocity loop's bandwidths (default: the environment's defaults).
    """

    def __init__(
        self, delay_substeps: int, physics_dt: float, n_substeps: int, gains: VelocityLoopGains | None = None
    ) -> None:
        self.d = int(delay_substeps)
        self.dt = float(physics_dt)
        self.n = int(n_substeps)
        g = gains or VelocityLoopGains()
        omega = np.r_[np.full(3, g.vehicle_translation), np.full(3, g.vehicle_rotation), np.full(12, g.joints)]
        self._alpha = 1.0 - np.exp(-omega * self.dt)
        self._issued: deque[np.ndarray] = deque(maxlen=max(1, math.ceil(self.d / self.n) + 1))
        self.reset()

    @property
    def delay(self) -> float:
        """``D``, s."""
        return self.d * self.dt

    def reset(self) -> None:
        """Start an episode: no command issued yet (the environment holds the zero command)."""
        self._issued.clear()

    def record(self, zeta_cmd: np.ndarray) -> None:
        """Remember the velocity command just issued (call once per control step, after predicting)."""
        self._issued.append(np.asarray(zeta_cmd, dtype=float).copy())

    def _command_at(self, i: int) -> np.ndarray:
        """The command in effect ``i`` substeps after now (``0 <= i < d``): issued ``k`` control steps ago."""
        k = math.ceil((self.d - i) / self.n)  # issued at -k n, acts from -k n + d <= i
        issued = self._issued
        return issued[-k] if k <= len(issued) else np.zeros(18)

    def predict(self, eta: np.ndarray, q: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(eta, q, zeta)`` at ``t + D`` (copies; unchanged for ``D = 0``)."""
        eta, q, zeta = (np.array(v, dtype=float) for v in (eta, q, zeta))
        dt, alpha = self.dt, self._alpha
        for i in range(self.d):
            zeta += alpha * (self._command_at(i) - zeta)
            eta[:3] += euler_to_rot(eta[3:]) @ zeta[:3] * dt
            eta[3:] += euler_rate_matrix(eta[3:]) @ zeta[3:6] * dt
            q += zeta[6:] * dt
        return eta, q, zeta
