"""Dynamic inversion with RBF-network compensation (docs/MODEL.md section 7, paper Section 3.2).

Velocity-tracking control of ``zeta`` towards the MPC command ``zeta_cmd``:

* nominal model ``Mbar zetadot + bbar(q, zeta) = tau`` (``bbar = Hbar zeta + gbar``), by default
  :class:`UVDMSNominalModel` (Pinocchio rigid body + nominal vehicle added mass, damping and hydrostatics from
  :mod:`uvdms_gym.physics.nominal`, optionally perturbed by scale factors and with the gripped object as a payload);
* control law ``tau = Mbar a + bbar``;
* reference model ``a_rm = K_rm (zeta_cmd - zeta_rm)``, ``zeta_rm`` starts at the measured ``zeta``;
* errors ``e1 = int (zeta_rm - zeta) dt``, ``e2 = zeta_rm - zeta``, ``e = [e1; e2]`` (36);
* virtual control ``a = a_rm + K_p e2 + K_i e1 - Deltahat`` with ``Deltahat = What^T h(x)`` (docs/MODEL.md's sign: the
  network estimates the model error ``Delta`` in ``zetadot = a + Delta`` and is subtracted; the paper's
  ``a_nn`` is ``-Deltahat``);
* error dynamics ``edot = Lambda e + B (Deltahat - Delta)``, ``Lambda = [[0, I], [-K_i, -K_p]]``, ``B = [0; I]``;
* adaptive law ``Whatdot = -kappa (h(x) (B^T P e)^T + sigma What)`` with ``P`` solving
  ``Lambda^T P + P Lambda = -Q`` (``sigma = 0`` is the paper's law; ``sigma > 0`` the sigma-modification);
  with ``V = e^T P e / 2 + tr(Wtilde^T Wtilde) / (2 kappa)``, ``Vdot = -e^T Q e / 2 - e^T P B eps`` (``sigma = 0``).

Discrete time (control period ``dt``): the reference model is integrated exactly
(``zeta_rm += (1 - exp(-K_rm dt)) (zeta_cmd - zeta_rm)``), ``e1`` and ``What`` by forward Euler after the torque
is computed. The adaptation acts on ``e2`` like an extra integral gain ``kappa |h|^2 P_22`` (about
``20 * 50 * 0.052 = 52 1/s^2`` for the defaults near the operating point, ``P_22 = 0.052 I``); it must stay
well below ``1/dt^2`` (625 at the default 25 Hz). Measured on the simulator at 25 Hz: ``kappa = 50`` made the
transport run drift (the two arms' joint angles parted by up to 20 degrees), ``kappa = 20`` is stable; at 100 Hz
``kappa = 1000`` destabilised the loop.

RBF network: 80 Gaussian units ``h_i = exp(-|x - c_i|^2 / (2 b^2))`` on the normalised input
``x = [tau_prev / tau_max, zeta / zeta_max, q / q_max, eta2 / pi]`` (18 + 18 + 12 + 3 = 51; joint limits are
symmetric so ``q / q_max`` lies in ``[-1, 1]``; ``eta2 = [phi, theta, psi]`` wrapped to ``[-pi, pi)``, so the
input jumps when the yaw crosses ``+-pi``). Centres are drawn once, uniformly in ``[-0.5, 0.5]^51`` (a seeded
generator), width ``b = 3``: an input near the origin lies about ``sqrt(51/12) ~ 2`` from a centre, so every
unit stays active (``h_i`` in 0.7-0.85 at ``x = 0``, ``|h|^2 ~ 50``; 0.2-0.75 at the corners of the box) and the
network acts as a smooth, state-dependent adaptive compensator.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import scipy.linalg

from uvdms_gym.physics.frames import wrap_angle
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.nominal import NominalDynamics, NominalScale
from uvdms_gym.physics.params import UVDMSParams

N_DOF = 18


class NominalModel(Protocol):
    """What the dynamic inversion needs from a model: ``Mbar`` and ``bbar`` at a state."""

    def evaluate(self, eta: np.ndarray, q: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(Mbar (18, 18), bbar (18))`` with ``Mbar zetadot + bbar = tau``."""
        ...


class UVDMSNominalModel:
    """The UVDMS nominal model of :mod:`uvdms_gym.physics.nominal`, optionally with the gripped object as payload.

    The payload (transport) adds the object's rigid-body mass ``J_o^T M_o J_o`` and its net weight (weight minus
    buoyancy) at its centre, split evenly between the two grasp Jacobians (which agree on a closed chain);
    the object's hydrodynamics are omitted (part of the deliberate model error).
    """

    def __init__(
        self, params: UVDMSParams | None = None, scale: NominalScale | None = None, payload: bool = False
    ) -> None:
        """Build the model.

        Args:
            params: physical parameters; defaults to :class:`UVDMSParams`.
            scale: multiplicative errors on added mass, damping and buoyancy (1 = the parameter values).
            payload: include the gripped object (transport task).
        """
        self.params = params or UVDMSParams()
        self.kin = KinematicModel(self.params)
        self.dyn = NominalDynamics(self.kin, scale)
        self.payload = payload
        o = self.params.obj
        m = o.mass
        i_ax = 0.5 * m * o.radius**2
        i_tr = m * (3.0 * o.radius**2 + o.length**2) / 12.0
        self._m_obj = m
        self._i_obj = np.diag([i_tr, i_ax, i_tr])  # object axis along its own y (see uvdms_gym.physics.model)
        self._net_weight = (m - self.params.water_density * o.volume) * 9.81  # N, down (+z NED)
        self._f_obj = np.array([0.0, 0.0, self._net_weight])

    def evaluate(self, eta: np.ndarray, q: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(Mbar, bbar)`` at the state.

        Args:
            eta: vehicle pose (6).
            q: joint angles (12).
            zeta: system velocity (18).

        Returns:
            Mass matrix (18, 18) and bias (18).
        """
        self.kin.set_state(eta, q, zeta)
        mbar = self.dyn.mass_matrix()
        bbar = self.dyn.bias()
        if self.payload:
            _, r = self.kin.object_pose("right")
            mo = np.zeros((6, 6))
            mo[:3, :3] = self._m_obj * np.eye(3)
            mo[3:, 3:] = r @ self._i_obj @ r.T
            f = self._f_obj
            for side in ("left", "right"):
                jo = self.kin.object_jacobian(side)
                mbar += 0.5 * jo.T @ mo @ jo
                bbar -= 0.5 * jo[:3].T @ f  # tau must hold the net weight: bbar = -J^T f_ext
        return mbar, bbar


@dataclass(frozen=True)
class DIConfig:
    """Gains and network settings of the dynamic inversion (scalars apply to all 18 DOF).

    Attributes:
        dt: control period of the inner loop, s [D] 0.04 (25 Hz): the environments' ``control_dt``; the torque
            baselines run the MPC and the inversion once per environment step (:mod:`baselines.controllers`).
        k_rm: reference-model bandwidth ``K_rm``, 1/s [D] 10 (the paper's first-order reference model; 5 let the
            kinematic loop lag the transport reference by centimetres).
        k_p: ``K_p`` of the PI error dynamics, 1/s [D] 10 (with ``K_i`` 25: critically damped, 5 rad/s).
        k_i: ``K_i``, 1/s^2 [D] 25.
        use_nn: add the RBF compensation (``False``: plain DI, the ``campc-di`` baseline).
        n_hidden: hidden Gaussian units [paper: 80].
        rbf_width: Gaussian width ``b`` on the normalised input [D] 3.
        center_range: centres uniform in ``[-center_range, center_range]^51`` [D] 0.5.
        kappa: adaptation gain ``kappa``, scalar or one per DOF (output column of the network) [D] 20 at 25 Hz
            (module docstring: 50 destabilised the transport run).
        sigma: sigma-modification ``sigma`` (0 = the paper's law) [D] 0.01.
        q_lyap: ``Q = q_lyap I`` (36x36) of the Lyapunov equation [D] 1.
        seed: seed of the centre generator (fixed: the network is part of the controller, not the episode).
        saturate: clip ``tau`` to ``tau_max`` and freeze ``e1`` and the adaptation of saturated DOFs
            (conditional integration, anti-windup).
    """

    dt: float = 0.04
    k_rm: float | tuple[float, ...] = 10.0
    k_p: float | tuple[float, ...] = 10.0
    k_i: float | tuple[float, ...] = 25.0
    use_nn: bool = True
    n_hidden: int = 80
    rbf_width: float = 3.0
    center_range: float = 0.5
    kappa: float | tuple[float, ...] = 20.0
    sigma: float = 0.01
    q_lyap: float = 1.0
    seed: int = 0
    saturate: bool = True


@dataclass
class DIOutput:
    """One step of the dynamic inversion.

    Attributes:
        tau: generalized force (18), saturated if configured.
        delta_hat: network estimate ``Deltahat`` of the model error (18), subtracted from ``a``; zeros without
            the network.
        a: virtual control (commanded acceleration) (18).
        e: tracking error ``[e1; e2]`` (36) used in this step.
        zeta_rm: reference-model velocity (18).
        weight_norm: Frobenius norm of ``What`` after the update.
        saturated: which DOFs hit ``tau_max``.
    """

    tau: np.ndarray
    delta_hat: np.ndarray
    a: np.ndarray
    e: np.ndarray
    zeta_rm: np.ndarray
    weight_norm: float
    saturated: np.ndarray


def _diag18(x: float | tuple[float, ...]) -> np.ndarray:
    return np.broadcast_to(np.asarray(x, dtype=float), (N_DOF,)).copy()


def lyapunov_matrix(k_p: np.ndarray, k_i: np.ndarray, q_lyap: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``Lambda`` and ``P`` with ``Lambda^T P + P Lambda = -Q``, ``Q = q_lyap I`` (36x36).

    Args:
        k_p: diagonal of ``K_p`` (18).
        k_i: diagonal of ``K_i`` (18).
        q_lyap: scale of ``Q``.

    Returns:
        ``(Lambda, P)``.
    """
    n = len(k_p)
    lam = np.zeros((2 * n, 2 * n))
    lam[:n, n:] = np.eye(n)
    lam[n:, :n] = -np.diag(k_i)
    lam[n:, n:] = -np.diag(k_p)
    p = scipy.linalg.solve_continuous_lyapunov(lam.T, -q_lyap * np.eye(2 * n))
    return lam, 0.5 * (p + p.T)


class RBFNetwork:
    """Gaussian RBF network ``Deltahat = W^T h(x)`` with a normalised input (see module docstring)."""

    def __init__(self, n_in: int, n_out: int, n_hidden: int, width: float, center_range: float, seed: int) -> None:
        """Draw the centres and zero the weights.

        Args:
            n_in: input dimension.
            n_out: output dimension.
            n_hidden: number of Gaussian units.
            width: Gaussian width ``b``.
            center_range: centres uniform in ``[-center_range, center_range]^n_in``.
            seed: generator seed for the centres.
        """
        rng = np.random.default_rng(seed)
        self.centers = rng.uniform(-center_range, center_range, size=(n_hidden, n_in))
        self.width = float(width)
        self.weights = np.zeros((n_hidden, n_out))
        self._c2 = np.einsum("ij,ij->i", self.centers, self.centers)
        self._two_centers = 2.0 * self.centers  # exact doubling, kept instead of recomputed per call

    def features(self, x: np.ndarray) -> np.ndarray:
        """Hidden-layer output ``h(x)`` (n_hidden)."""
        d2 = self._c2 - self._two_centers @ x + x @ x
        return np.exp(-np.maximum(d2, 0.0) / (2.0 * self.width**2))

    def output(self, h: np.ndarray) -> np.ndarray:
        """``W^T h``."""
        return self.weights.T @ h


class DynamicInversionController:
    """Dynamic inversion velocity tracker with optional RBF compensation (docs/MODEL.md section 7)."""

    def __init__(
        self,
        config: DIConfig | None = None,
        model: NominalModel | None = None,
        params: UVDMSParams | None = None,
        tau_max: np.ndarray | None = None,
        zeta_max: np.ndarray | None = None,
        q_max: np.ndarray | None = None,
    ) -> None:
        """Build the controller.

        Args:
            config: gains and network settings; defaults to :class:`DIConfig`.
            model: nominal model; defaults to :class:`UVDMSNominalModel` of ``params`` (no perturbation).
            params: physical parameters (default limits and model); defaults to :class:`UVDMSParams`.
            tau_max: torque limits (18) for saturation and input normalisation; defaults to ``params.tau_max``.
            zeta_max: velocity normalisation (18); defaults to ``params.zeta_max``.
            q_max: joint-angle normalisation (12); defaults to ``params.q_max``.
        """
        self.config = cfg = config or DIConfig()
        self.params = params = params or UVDMSParams()
        self.model: NominalModel = model if model is not None else UVDMSNominalModel(params)
        self.tau_max = np.asarray(params.tau_max if tau_max is None else tau_max, dtype=float)
        self.zeta_max = np.asarray(params.zeta_max if zeta_max is None else zeta_max, dtype=float)
        self.q_max = np.abs(np.asarray(params.q_max if q_max is None else q_max, dtype=float))
        self.k_rm = _diag18(cfg.k_rm)
        self.k_p = _diag18(cfg.k_p)
        self.k_i = _diag18(cfg.k_i)
        self.kappa = _diag18(cfg.kappa)
        self.lam, self.P = lyapunov_matrix(self.k_p, self.k_i, cfg.q_lyap)
        self.Q = cfg.q_lyap * np.eye(2 * N_DOF)
        self._bt_p = self.P[N_DOF:, :].copy()  # B^T P (18 x 36)
        self._eye = np.eye(N_DOF)
        self._rm_gain = 1.0 - np.exp(-self.k_rm * cfg.dt)
        self.net = RBFNetwork(2 * N_DOF + 12 + 3, N_DOF, cfg.n_hidden, cfg.rbf_width, cfg.center_range, cfg.seed)
        self._inv_scale = np.concatenate(
            [1.0 / self.tau_max, 1.0 / self.zeta_max, 1.0 / self.q_max, np.full(3, 1 / np.pi)]
        )
        self.zeta_rm = np.zeros(N_DOF)
        self.e1 = np.zeros(N_DOF)
        self.tau_prev = np.zeros(N_DOF)
        self._started = False

    def reset(self, tau0: np.ndarray | None = None) -> None:
        """Start an episode: weights to zero, integrator to zero, reference model re-initialised at the next step.

        Args:
            tau0: previous torque for the network input (e.g. the static holding force); zeros if ``None``.
        """
        self.net.weights[:] = 0.0
        self.e1[:] = 0.0
        self.tau_prev = np.zeros(N_DOF) if tau0 is None else np.asarray(tau0, dtype=float).copy()
        self._started = False

    def network_input(self, zeta: np.ndarray, q: np.ndarray, eta2: np.ndarray) -> np.ndarray:
        """Normalised network input ``x`` (51) from ``tau_prev`` and the state."""
        eta2w = wrap_angle(np.asarray(eta2, dtype=float))
        return np.concatenate([self.tau_prev, zeta, q, eta2w]) * self._inv_scale

    def _chain_projection(self, mbar: np.ndarray, a_eq: np.ndarray) -> np.ndarray:
        """``I - M^-1 A^T (A M^-1 A^T)^-1 A``: the closed chain's projection of the velocity error.

        On a singular chain (an arm stretched out, seen under realism) the inverse is a least-squares one.
        """
        m_inv_at = np.linalg.solve(mbar, a_eq.T)
        gram = a_eq @ m_inv_at
        try:
            return self._eye - m_inv_at @ np.linalg.solve(gram, a_eq)
        except np.linalg.LinAlgError:
            return self._eye - m_inv_at @ np.linalg.pinv(gram) @ a_eq

    def step(
        self,
        zeta_cmd: np.ndarray,
        eta: np.ndarray,
        q: np.ndarray,
        zeta: np.ndarray,
        a_eq: np.ndarray | None = None,
    ) -> DIOutput:
        """One control period: torque for the measured state, then the error/weight/reference-model updates.

        Closed kinematic chain (transport): with the constraint ``a_eq zeta = 0`` (``a_eq = J_o,left - J_o,right``)
        the plant only realises accelerations in the constraint's null space; the rest of ``Mbar a`` becomes an
        internal (squeezing) force between the arms. Given ``a_eq``, the virtual control and the velocity error
        are projected onto the consistent subspace with the ``Mbar``-weighted projector
        ``P = I - Mbar^-1 A^T (A Mbar^-1 A^T)^-1 A`` before they are used: no internal force is commanded, and
        the integrator and the network never wind up on errors the plant cannot remove.

        Args:
            zeta_cmd: commanded velocity (18), e.g. the MPC's ``zeta_0`` (held between MPC steps).
            eta: vehicle pose (6).
            q: joint angles (12).
            zeta: measured velocity (18).
            a_eq: closed-chain constraint matrix (m, 18), or ``None`` (no closed chain).

        Returns:
            The torque and the quantities to log.
        """
        cfg = self.config
        zeta_cmd = np.asarray(zeta_cmd, dtype=float)
        zeta = np.asarray(zeta, dtype=float)
        if not self._started:
            self.zeta_rm = zeta.copy()
            self._started = True
        mbar, bbar = self.model.evaluate(eta, q, zeta)
        proj = None if a_eq is None else self._chain_projection(mbar, np.asarray(a_eq, dtype=float))
        e2 = self.zeta_rm - zeta
        if proj is not None:
            e2 = proj @ e2
        e = np.concatenate([self.e1, e2])
        a_rm = self.k_rm * (zeta_cmd - self.zeta_rm)
        if cfg.use_nn:
            h = self.net.features(self.network_input(zeta, q, np.asarray(eta)[3:6]))
            delta_hat = self.net.output(h)
        else:
            h = None
            delta_hat = np.zeros(N_DOF)
        a = a_rm + self.k_p * e2 + self.k_i * self.e1 - delta_hat
        if proj is not None:
            a = proj @ a
        tau = mbar @ a + bbar
        saturated = np.zeros(N_DOF, dtype=bool)
        if cfg.saturate:
            saturated = np.abs(tau) > self.tau_max
            tau = np.minimum(np.maximum(tau, -self.tau_max), self.tau_max)  # np.clip's values, cheaper
        # updates (forward Euler over dt); saturated DOFs neither integrate nor adapt (anti-windup)
        active = ~saturated
        if h is not None:
            s = self._bt_p @ e
            s[saturated] = 0.0
            w = self.net.weights
            w -= cfg.dt * self.kappa * (np.multiply.outer(h, s) + cfg.sigma * w)
        self.e1 += cfg.dt * e2 * active
        self.zeta_rm += self._rm_gain * (zeta_cmd - self.zeta_rm)
        self.tau_prev = tau.copy()
        return DIOutput(
            tau=tau,
            delta_hat=delta_hat,
            a=a,
            e=e,
            zeta_rm=self.zeta_rm.copy(),
            weight_norm=float(np.linalg.norm(self.net.weights)),
            saturated=saturated,
        )

    def ultimate_bound(self, eps_max: float) -> float:
        """The paper's ultimate bound on ``|e|``: ``2 lambda_max(P) eps_max / lambda_min(Q)`` (Section 3.3)."""
        return 2.0 * float(np.linalg.eigvalsh(self.P).max()) * eps_max / float(np.linalg.eigvalsh(self.Q).min())
