"""Dynamic inversion with RBF compensation (baselines.inner_loop.di): Lyapunov matrix, signs, adaptation, bounds."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from baselines.inner_loop.di import DIConfig, DynamicInversionController, UVDMSNominalModel, lyapunov_matrix
from uvdms_gym.physics.frames import quat_xyzw_to_rot, rot_to_euler
from uvdms_gym.physics.nominal import NominalScale
from uvdms_gym.physics.params import CIRCLE_Q0_LEFT_DEG, CIRCLE_Q0_RIGHT_DEG, UVDMSParams

# A decoupled 18-DOF test plant with UVDMS-like inertias (vehicle, then two arms) and linear damping.
MASS = np.r_[[170.0, 140.0, 140.0, 15.0, 14.0, 15.0], np.tile([2.0, 1.0, 1.0, 0.5, 0.3, 0.1], 2)]
DAMP = np.r_[[110.0, 90.0, 140.0, 20.0, 13.0, 17.0], np.ones(12)]
BIG_TAU = np.full(18, 1e4)


class DiagonalModel:
    """Nominal model ``diag(MASS) zetadot + DAMP zeta = tau``."""

    def evaluate(self, eta, q, zeta):
        return np.diag(MASS), DAMP * zeta


def simulate(ctl, delta, t_end, cmd, substeps=5, log_h=False):
    """Truth ``zetadot = Mbar^-1 (tau - bbar) + Delta``: exactly ``a + Delta`` under the control law."""
    dt = ctl.config.dt
    zeta, q, eta = np.zeros(18), np.zeros(12), np.zeros(6)
    errs, wn, hs_bound = [], [], []
    for k in range(round(t_end / dt)):
        t = k * dt
        if log_h:
            h = ctl.net.features(ctl.network_input(zeta, q, eta[3:]))
        out = ctl.step(cmd(t), eta, q, zeta)
        if log_h:
            s = ctl.P[18:] @ out.e
            hs_bound.append(np.linalg.norm(h) * np.linalg.norm(s))
        for _ in range(substeps):
            zdot = (out.tau - DAMP * zeta) / MASS + delta(t, zeta, q, ctl)
            zeta = zeta + dt / substeps * zdot
            q = q + dt / substeps * zeta[6:]
        errs.append(out.e)
        wn.append(out.weight_norm)
    return np.array(errs), np.array(wn), np.array(hs_bound)


def sine_cmd(t):
    return 0.3 * np.sin(0.5 * t + np.arange(18))


def make(use_nn=True, **kw):
    cfg = DIConfig(use_nn=use_nn, saturate=False, **kw)
    return DynamicInversionController(cfg, DiagonalModel(), tau_max=BIG_TAU)


def test_lyapunov_matrix_solves_the_equation():
    rng = np.random.default_rng(0)
    kp, ki = rng.uniform(2, 20, 18), rng.uniform(5, 50, 18)
    lam, p = lyapunov_matrix(kp, ki, q_lyap=2.0)
    assert np.allclose(lam.T @ p + p @ lam, -2.0 * np.eye(36), atol=1e-10)
    assert np.allclose(p, p.T)
    assert np.linalg.eigvalsh(p).min() > 0.0
    assert np.all(np.linalg.eigvals(lam).real < 0.0)
    assert np.allclose(lam[18:, :18], -np.diag(ki)) and np.allclose(lam[:18, 18:], np.eye(18))
    ctl = make()
    assert np.allclose(ctl.lam.T @ ctl.P + ctl.P @ ctl.lam, -ctl.Q, atol=1e-10)


def test_error_dynamics_sign_convention():
    """One step of the closed loop follows e2dot = -K_i e1 - K_p e2 + Deltahat - Delta (docs/MODEL.md section 7)."""
    ctl = make(dt=1e-4, kappa=0.0)
    rng = np.random.default_rng(1)
    ctl.net.weights[:] = rng.normal(size=ctl.net.weights.shape) * 0.1
    ctl.e1[:] = rng.normal(size=18) * 0.01
    zeta = rng.normal(size=18) * 0.1
    eta, q = np.zeros(6), np.zeros(12)
    ctl.step(zeta, eta, q, zeta)  # initialises zeta_rm = zeta
    ctl.zeta_rm = zeta + rng.normal(size=18) * 0.01
    zeta_rm = ctl.zeta_rm.copy()
    cmd = rng.normal(size=18) * 0.1
    delta = rng.normal(size=18)
    out = ctl.step(cmd, eta, q, zeta)
    zdot = (out.tau - DAMP * zeta) / MASS + delta
    assert np.allclose(zdot, out.a + delta)  # the inversion is exact for the nominal plant
    e1, e2 = out.e[:18], out.e[18:]
    assert np.allclose(e2, zeta_rm - zeta)
    e2dot = ctl.k_rm * (cmd - zeta_rm) - zdot  # zeta_rm_dot - zetadot
    assert np.allclose(e2dot, -ctl.k_i * e1 - ctl.k_p * e2 + out.delta_hat - delta, atol=1e-9)


def test_network_beats_plain_inversion_on_state_dependent_error():
    def delta(t, z, q, ctl):
        return 0.5 + 0.5 * np.sin(3.0 * z) - 0.8 * z * np.abs(z) + 0.3 * np.sin(0.7 * t)

    e_no, _, _ = simulate(make(use_nn=False), delta, 20.0, sine_cmd)
    e_nn, w, _ = simulate(make(use_nn=True), delta, 20.0, sine_cmd)
    half = len(e_no) // 2
    rms = lambda e: float(np.sqrt(np.mean(np.sum(e[half:] ** 2, axis=1))))  # noqa: E731
    rms_v = lambda e: float(np.sqrt(np.mean(e[half:, 18:] ** 2)))  # noqa: E731
    assert rms(e_nn) < 0.4 * rms(e_no)
    assert rms_v(e_nn) < 0.4 * rms_v(e_no)
    assert np.all(np.isfinite(w))


def test_ideal_case_reaches_the_theorem_bound():
    """Delta = W*^T h(x) + eps(t), |eps| <= eps_max: |e| ends below 2 lambda_max(P) eps_max / lambda_min(Q)."""
    rng = np.random.default_rng(2)
    w_star = rng.normal(size=(80, 18)) * 0.05
    u = rng.normal(size=18)
    u /= np.linalg.norm(u)
    eps_max = 0.02

    def delta(t, z, q, ctl):
        h = ctl.net.features(ctl.network_input(z, q, np.zeros(3)))
        return w_star.T @ h + eps_max * np.sin(2.0 * t) * u

    ctl = make(dt=0.005, kappa=50.0, sigma=0.0)
    e, _, _ = simulate(ctl, delta, 40.0, sine_cmd, substeps=2)
    norms = np.linalg.norm(e, axis=1)
    bound = ctl.ultimate_bound(eps_max)
    assert np.isclose(bound, 2.0 * np.linalg.eigvalsh(ctl.P).max() * eps_max)
    n = len(norms)
    assert norms[3 * n // 4 :].max() < bound
    assert norms[3 * n // 4 :].max() < 0.1 * norms[: n // 2].max()  # the transient decays


def test_sigma_modification_keeps_weights_bounded():
    """Discrete law W+ = (1 - dt kappa sigma) W - dt kappa h s^T: |W| <= max |h||s| / sigma from W = 0."""
    rng = np.random.default_rng(3)
    noise = rng.normal(size=(100000, 18))

    def delta(t, z, q, ctl):  # not representable: fast noise plus a drifting bias
        return 2.0 * noise[int(t * 1000) % len(noise)] + 0.5 * np.sign(np.sin(0.2 * t))

    sigma = 0.05
    ctl = make(kappa=50.0, sigma=sigma)
    _, w, hs = simulate(ctl, delta, 30.0, sine_cmd, substeps=1, log_h=True)
    assert np.all(w <= hs.max() / sigma + 1e-9)
    half = len(w) // 2
    assert w[half:].max() <= 1.5 * w[:half].max()  # no drift


@pytest.fixture(scope="module")
def uvdms_runs():
    """The 18-DOF UVDMS nominal model as the truth, the controller with perturbed hydrodynamics."""

    def run(use_nn: bool, t_end: float = 6.0):
        truth = UVDMSNominalModel()
        model = UVDMSNominalModel(scale=NominalScale(added_mass=0.7, damping=0.5, buoyancy=0.9))
        ctl = DynamicInversionController(DIConfig(use_nn=use_nn), model)
        eta = np.array([2.0, 0.0, 3.0, 0.0, 0.0, 0.0])
        q = np.radians(np.r_[CIRCLE_Q0_LEFT_DEG, CIRCLE_Q0_RIGHT_DEG])
        zeta = np.zeros(18)
        config = truth.kin.configuration(eta, q)
        errs, sat = [], 0
        h = ctl.config.dt / 5
        for k in range(int(t_end / ctl.config.dt)):
            t = k * ctl.config.dt
            cmd = np.zeros(18)
            cmd[:3] = 0.1 * np.sin(0.5 * t)
            cmd[5] = 0.1 * np.sin(0.3 * t)
            cmd[6:] = 0.3 * np.sin(0.8 * t + np.arange(12))
            out = ctl.step(cmd, eta, q, zeta)
            sat += int(out.saturated.any())
            for _ in range(5):
                m, b = truth.evaluate(eta, q, zeta)
                zeta = zeta + h * np.linalg.solve(m, out.tau - b)
                config = pin.integrate(truth.kin.model, config, zeta * h)
                eta = np.r_[config[:3], rot_to_euler(quat_xyzw_to_rot(config[3:7]))]
                q = config[7:].copy()
            errs.append(out.e[18:])
        e = np.array(errs)
        return float(np.sqrt(np.mean(e[len(e) // 2 :] ** 2))), sat

    return run(False), run(True)


def test_uvdms_ablation_network_beats_perturbed_model(uvdms_runs):
    (rms_no, sat_no), (rms_nn, sat_nn) = uvdms_runs
    assert sat_no == 0 and sat_nn == 0
    assert rms_nn < 0.5 * rms_no


def test_payload_adds_object_mass_and_net_weight():
    p = UVDMSParams()
    bare, loaded = UVDMSNominalModel(p), UVDMSNominalModel(p, payload=True)
    eta, q, zeta = np.array([2.0, 1.0, 30.0, 0, 0, 0]), np.zeros(12), np.zeros(18)
    m0, b0 = bare.evaluate(eta, q, zeta)
    m1, b1 = loaded.evaluate(eta, q, zeta)
    dm = m1 - m0
    assert np.allclose(dm, dm.T) and np.linalg.eigvalsh(dm).min() > -1e-9
    assert np.isclose(dm[0, 0], p.obj.mass)  # surge carries the whole object
    net = (p.obj.mass - p.water_density * p.obj.volume) * 9.81
    assert np.isclose(b1[2] - b0[2], -net)  # holding force: push up (-z NED) by the net weight


def test_saturation_and_reset():
    ctl = DynamicInversionController(DIConfig(), DiagonalModel(), tau_max=np.full(18, 1.0))
    out = ctl.step(np.ones(18), np.zeros(6), np.zeros(12), np.zeros(18))
    out = ctl.step(np.ones(18), np.zeros(6), np.zeros(12), np.zeros(18))
    assert np.all(np.abs(out.tau) <= 1.0) and out.saturated.any()
    assert np.all(ctl.e1[out.saturated] == 0.0)  # conditional integration
    ctl.reset()
    assert not ctl.net.weights.any() and not ctl.e1.any()


def test_cascade_campc_nndi_avoids_collision_on_the_nominal_plant():
    """CAMPC (every T_c) + NN-DI (every dt) on the 18-DOF nominal dynamics with perturbed hydrodynamics."""
    from baselines.inner_loop.cascade import CascadeController
    from baselines.mpc.campc import make_mpc_controller
    from uvdms_gym import distances
    from uvdms_gym.envs.references import make_circle_task

    task = make_circle_task(1)
    truth = UVDMSNominalModel()
    model = UVDMSNominalModel(scale=NominalScale(added_mass=0.7, damping=0.5, buoyancy=0.9))
    di = DynamicInversionController(DIConfig(dt=0.01, k_rm=5.0, kappa=50.0), model)  # a 100 Hz inner loop
    casc = CascadeController(make_mpc_controller("circle"), di)
    assert casc.ratio == 4
    eta, q, zeta = np.array(task.vehicle_start, dtype=float), task.q0.copy(), np.zeros(18)
    config = truth.kin.configuration(eta, q)
    casc.reset(truth.evaluate(eta, q, zeta)[1])
    dt = casc.di.config.dt
    d_min, errs, n_mpc = np.inf, [], 0
    for k in range(round(12.0 / dt)):
        t = k * dt
        y_ref = task.reference(casc.mpc.reference_times(t)) if casc.mpc_due() else None
        out = casc.step(eta, q, zeta, y_ref)
        if out.mpc is not None:
            n_mpc += 1
            d_min = min(d_min, distances.compute_distances(casc.mpc.kin).d.min())
            errs.append(np.linalg.norm(casc.mpc.kin.ee_positions().ravel() - task.reference(t)))
        for _ in range(5):
            m, b = truth.evaluate(eta, q, zeta)
            zeta = zeta + dt / 5 * np.linalg.solve(m, out.tau - b)
            config = pin.integrate(truth.kin.model, config, zeta * dt / 5)
            eta = np.r_[config[:3], rot_to_euler(quat_xyzw_to_rot(config[3:7]))]
            q = config[7:].copy()
    assert n_mpc == round(12.0 / casc.mpc.config.t_c)
    assert d_min >= 0.05 - 2e-3
    assert np.sqrt(np.mean(np.square(errs[round(5.0 / casc.mpc.config.t_c) :]))) < 5e-3  # after the 5 s transient
