"""The navigation filter: its linearisation, its thruster model, late samples, its consistency (NEES) per level."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from scripts.filter_consistency import FIRST_SEED, make_env, nees, random_commands, run_episode
from uvdms_gym.physics.params import UVDMSParams
from uvdms_gym.realism.actuation import DEFAULT_LAYOUT, allocation_matrix
from uvdms_gym.realism.config import LEVELS
from uvdms_gym.realism.ekf import N_CORE, _derivative, _thruster_wrench
from uvdms_gym.realism.navigation import NavigationFilter

EPISODES, STEPS = 20, 250
"""The consistency test's episodes (validation seeds from :data:`FIRST_SEED`) and control steps per episode."""


def test_derivative_jacobian_matches_finite_differences():
    rng = np.random.default_rng(0)
    x = np.r_[rng.normal(0, 1, 3), rng.uniform(-0.6, 0.6, 3), rng.normal(0, 0.3, 6), rng.normal(0, 0.1, 6), 0.2, -0.1]
    accel, gb = rng.normal(0, 0.1, 6), rng.normal(0, 0.5, 6)
    wvv = np.diag(rng.uniform(0.005, 0.1, 6)) + 1e-3
    lin, quad = np.array(UVDMSParams().vehicle.linear_damping), np.array(UVDMSParams().vehicle.quadratic_damping)
    a = np.zeros((12, N_CORE))
    _derivative(x, accel, gb, wvv, lin, quad, a)
    eps = 1e-6
    for k in range(N_CORE):
        dx = np.zeros(N_CORE)
        dx[k] = eps
        fd = (
            _derivative(x + dx, accel, gb, wvv, lin, quad, np.zeros((12, N_CORE)))
            - _derivative(x - dx, accel, gb, wvv, lin, quad, np.zeros((12, N_CORE)))
        ) / (2 * eps)
        np.testing.assert_allclose(a[:, k], fd[:12], atol=1e-6, err_msg=f"column {k}")


def test_thruster_wrench_follows_the_definition():
    # dead zone on the allocated commands, then f += (1 - exp(-dt/T)) (target - f) per substep; the wrench B f
    b = allocation_matrix(DEFAULT_LAYOUT)
    pinv = np.linalg.pinv(b)
    fmax, rmax, tc, dt = DEFAULT_LAYOUT.max_forward, DEFAULT_LAYOUT.max_reverse, 0.035, 0.01
    alpha = 1.0 - math.exp(-dt / tc)
    box = np.full(6, 1e6)
    f0 = np.linspace(-50.0, 50.0, b.shape[1])
    tau_v = np.array([60.0, -20.0, 150.0, 3.0, -10.0, 1.0])
    cmd = pinv @ tau_v
    u = np.abs(np.where(cmd >= 0, cmd / fmax, cmd / rmax))
    dz = float(np.sort(u)[2]) + 1e-3  # three thrusters in the dead zone, the others outside
    expected_target = np.where(u < dz, 0.0, cmd)
    assert 0 < np.count_nonzero(expected_target) < b.shape[1]
    thrust = f0.copy()
    out = _thruster_wrench(tau_v, pinv, b, thrust, fmax, rmax, dz, alpha, box, 4)
    f = f0.copy()
    for s in range(4):
        f = f + alpha * (expected_target - f)
        np.testing.assert_allclose(out[s], b @ f, atol=1e-9)
    np.testing.assert_allclose(thrust, f, atol=1e-9)
    small = _thruster_wrench(tau_v, pinv, b, f0.copy(), fmax, rmax, dz, alpha, np.full(6, 5.0), 2)
    assert np.all(np.abs(small) <= 5.0 + 1e-12)  # the simulator's box


def test_late_fix_equals_the_same_fix_on_time():
    # the same episode (open-loop commands, the same noise streams) with the fix 0.3 s late or on time: the late
    # sample, handled by cloning, must give (nearly) the estimate of the same sample fused at its sample time
    knobs = {"level": 3, "fix_dropout_prob": 0.0}
    out = []
    for cfg in (knobs, {**knobs, "fix_latency": 0.0}):
        env = make_env(cfg)
        base = env.unwrapped
        _, info = env.reset(seed=FIRST_SEED)
        commands = random_commands(FIRST_SEED, 190, base.control_dt).astype(np.float32)
        nav = NavigationFilter(base.realism, base.params, control_dt=base.control_dt, physics_dt=base.physics_dt)
        nav.reset(info["t"], info["measurements"])
        for k in range(190):  # t = 7.6 s: the late filter has had the fix of t = 7 s since 7.3 s
            _, _, _, _, info = env.step(commands[k])
            nav.update(info["t"], info["measurements"], info["tau_cmd"])
        env.close()
        out.append((nav.x[:12].copy(), nav.covariance()))
    (xa, pa), (xb, pb) = out
    sd = np.sqrt(np.diag(pb))
    # the linearisation points differ for 0.3 s (bilinear buoyancy and damping terms): a small fraction of sd
    assert np.all(np.abs(xa - xb) < 0.25 * sd), (xa - xb) / sd
    # the covariance depends on the linearisation point through those terms too (with beta and delta held inert the
    # two variances agree to 2 %): within 8 %
    np.testing.assert_allclose(np.diag(pa), np.diag(pb), rtol=0.08)


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
def test_nees_within_chi_square_bounds(level):
    # the filter in the environment (thrusters, delay, the sensor pipeline), judged on true_state(): the NEES of
    # (eta, nu) averaged over 20 episodes step by step lies in the two-sided 95 % chi-square bounds (12 dof x 20)
    runs = [run_episode(level, FIRST_SEED + i, STEPS) for i in range(EPISODES)]
    assert all(e.shape[0] == STEPS + 1 for e, _ in runs)
    avg = np.mean([nees(e, c) for e, c in runs], axis=0)[1:]
    lo, hi = stats.chi2.ppf([0.025, 0.975], 12 * EPISODES) / EPISODES
    inside = np.mean((avg >= lo) & (avg <= hi))
    assert inside >= 0.9, (level, inside, avg.mean())
