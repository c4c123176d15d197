"""The paper's two-level controller: kinematic (CA)MPC every ``T_c``, dynamic inversion every ``dt``.

:class:`CascadeController` calls the MPC on every ``round(T_c / dt)``-th tick and holds its command
``zeta_cmd`` in between; the dynamic inversion (with or without the RBF network) turns the held command into
the generalized force ``tau`` at every tick. The measured velocity goes to the MPC too (collision lookahead), and
with a closed chain (transport) the MPC's constraint matrix ``J_o,left - J_o,right`` goes to the inversion, which
then commands no internal force (:meth:`~baselines.inner_loop.di.DynamicInversionController.step`). The environments'
torque baselines run both loops at the same rate (``ratio = 1``, :mod:`baselines.controllers`). This is the
``campc-di`` / ``campc-nndi`` baseline; plain ``mpc`` / ``campc`` in the environment's velocity action mode
use :class:`~baselines.mpc.campc.MPCController` alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baselines.inner_loop.di import DIOutput, DynamicInversionController
from baselines.mpc.campc import MPCController
from baselines.mpc.config import MPCStepRecord


@dataclass
class CascadeOutput:
    """One tick of the cascade.

    Attributes:
        tau: generalized force (18).
        zeta_cmd: the (held) MPC command (18).
        mpc: the MPC record if the MPC ran on this tick, else ``None``.
        di: the dynamic-inversion output.
    """

    tau: np.ndarray
    zeta_cmd: np.ndarray
    mpc: MPCStepRecord | None
    di: DIOutput


class CascadeController:
    """(CA)MPC outer loop + dynamic inversion inner loop."""

    def __init__(self, mpc: MPCController, di: DynamicInversionController) -> None:
        """Compose the two loops.

        Args:
            mpc: the kinematic MPC (its ``config.t_c`` is the outer period).
            di: the dynamic inversion (its ``config.dt`` is the tick; ``t_c`` must be a multiple of it).

        Raises:
            ValueError: ``t_c`` is not an integer multiple of ``dt``.
        """
        ratio = mpc.config.t_c / di.config.dt
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"t_c = {mpc.config.t_c} must be a multiple of dt = {di.config.dt}")
        self.mpc = mpc
        self.di = di
        self.ratio = round(ratio)
        self.tick = 0
        self.zeta_cmd = np.zeros(18)
        self.a_eq: np.ndarray | None = None

    def reset(self, tau0: np.ndarray | None = None) -> None:
        """Start an episode (both loops reset; the MPC runs on the next tick).

        Args:
            tau0: initial ``tau_prev`` of the network input (e.g. the static holding force).
        """
        self.mpc.reset()
        self.di.reset(tau0)
        self.tick = 0
        self.zeta_cmd = np.zeros(18)
        self.a_eq = None

    def mpc_due(self) -> bool:
        """Whether the next :meth:`step` runs the MPC (then it needs the reference window)."""
        return self.tick % self.ratio == 0

    def step(self, eta: np.ndarray, q: np.ndarray, zeta: np.ndarray, y_ref: np.ndarray | None) -> CascadeOutput:
        """One inner tick.

        Args:
            eta: vehicle pose (6).
            q: joint angles (12).
            zeta: measured velocity (18).
            y_ref: reference window at ``t + j T_c``, ``j = 1..N_p`` (required when :meth:`mpc_due`).

        Returns:
            The torque and logs.
        """
        rec = None
        if self.mpc_due():
            if y_ref is None:
                raise ValueError("the MPC runs on this tick: y_ref is required")
            rec = self.mpc.step(eta, q, y_ref, zeta)
            self.zeta_cmd = rec.zeta_cmd
            problem = self.mpc.last_problem
            self.a_eq = None if problem is None else problem.j_eq
        out = self.di.step(self.zeta_cmd, eta, q, zeta, self.a_eq)
        self.tick += 1
        return CascadeOutput(tau=out.tau, zeta_cmd=self.zeta_cmd.copy(), mpc=rec, di=out)
