"""The navigation filter: its linearisation, its handling of late samples, and its consistency (NEES) per level."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats

from scripts.filter_consistency import SENSORS, _sensor_values, nees, run_filter, simulate
from uvdms_gym.physics.params import UVDMSParams
from uvdms_gym.realism.config import LEVELS
from uvdms_gym.realism.navigation import N_CORE, NavigationFilter, _derivative
from uvdms_gym.realism.sensors import SensorBank

EPISODES, STEPS = 20, 250


@pytest.fixture(scope="module")
def truths():
    return [simulate(seed, STEPS) for seed in range(EPISODES)]


def test_derivative_jacobian_matches_finite_differences():
    rng = np.random.default_rng(0)
    x = np.r_[rng.normal(0, 1, 3), rng.uniform(-0.6, 0.6, 3), rng.normal(0, 0.3, 6), rng.normal(0, 0.1, 6)]
    accel, wvv = rng.normal(0, 0.1, 6), np.diag(rng.uniform(0.005, 0.1, 6)) + 1e-3
    lin, quad = np.array(UVDMSParams().vehicle.linear_damping), np.array(UVDMSParams().vehicle.quadratic_damping)
    a = np.zeros((12, N_CORE))
    _derivative(x, accel, wvv, lin, quad, a)
    eps = 1e-6
    for k in range(N_CORE):
        dx = np.zeros(N_CORE)
        dx[k] = eps
        fd = (
            _derivative(x + dx, accel, wvv, lin, quad, np.zeros((12, N_CORE)))
            - _derivative(x - dx, accel, wvv, lin, quad, np.zeros((12, N_CORE)))
        ) / (2 * eps)
        np.testing.assert_allclose(a[:, k], fd[:12], atol=1e-6, err_msg=f"column {k}")


def _feed(nav: NavigationFilter, truth, bank: SensorBank, steps: int, delay_to_zero: bool = False):
    n_sub, dt = truth.n_substeps, truth.physics_dt
    for k in range(steps):
        for s in range(k * n_sub + 1, (k + 1) * n_sub + 1):
            values = _sensor_values(truth, s)
            bank.sample(s, {n: values[n] for n in bank.due(s)})
        s_now = (k + 1) * n_sub
        nav.update(s_now * dt, bank.release(s_now), truth.tau[k])


def test_late_fix_equals_the_same_fix_on_time(truths):
    # a fix sample released 0.3 s late, handled by cloning, must give (nearly) the estimate of the same sample
    # fused at its sample time: the information is the same, only the linearisation points differ
    truth = truths[0]
    base = dataclasses.replace(LEVELS[3], fix=dataclasses.replace(LEVELS[3].fix, dropout_prob=0.0))
    late = base
    on_time = dataclasses.replace(base, fix=dataclasses.replace(base.fix, latency=0.0))
    out = []
    for cfg in (late, on_time):
        bank = SensorBank(cfg, physics_dt=truth.physics_dt, control_substeps=truth.n_substeps, names=SENSORS)
        nav = NavigationFilter(cfg, UVDMSParams(), control_dt=truth.control_dt, physics_dt=truth.physics_dt)
        bank.reset(truth.seed, 0, _sensor_values(truth, 0))
        nav.reset(0.0, bank.initial())
        _feed(nav, truth, bank, 190)  # t = 7.6 s: the late filter has had the fix of t = 7 s since 7.3 s
        out.append((nav.x[:12].copy(), nav.covariance()))
    (xa, pa), (xb, pb) = out
    sd = np.sqrt(np.diag(pb))
    assert np.all(np.abs(xa - xb) < 0.05 * sd), (xa - xb) / sd
    np.testing.assert_allclose(np.diag(pa), np.diag(pb), rtol=0.02)


def test_state_shapes_and_bad_inputs():
    nav = NavigationFilter(LEVELS[1], UVDMSParams(), control_dt=0.04, physics_dt=0.01)
    with pytest.raises(ValueError, match="encoder"):
        nav.reset(0.0, {"ahrs": [(0.0, np.zeros(3))]})
    nav.reset(0.0, {"encoders": [(0.0, np.full(12, 0.2))], "ahrs": [(0.0, np.array([0.1, -0.1, 3.0]))]})
    eta, nu, q, qdot = nav.state()
    assert eta.shape == nu.shape == (6,) and q.shape == qdot.shape == (12,)
    assert nav.covariance().shape == (12, 12)
    np.testing.assert_allclose(eta[3:], [0.1, -0.1, 3.0], atol=1e-3)  # the AHRS sets the attitude
    np.testing.assert_allclose(q, 0.2)
    with pytest.raises(ValueError, match="tau_cmd"):
        nav.update(0.04, {}, np.zeros(17))
    with pytest.raises(ValueError, match="control_dt"):
        NavigationFilter(LEVELS[1], UVDMSParams(), control_dt=0.045, physics_dt=0.01)


@pytest.mark.slow
@pytest.mark.parametrize("level", [1, 2, 3])
def test_nees_within_chi_square_bounds(truths, level):
    runs = [run_filter(truth, level) for truth in truths]
    avg = np.mean([nees(e, c) for e, c in runs], axis=0)[1:]
    lo, hi = stats.chi2.ppf([0.025, 0.975], 12 * EPISODES) / EPISODES
    inside = np.mean((avg >= lo) & (avg <= hi))
    assert inside >= 0.9, (level, inside, avg.mean())
