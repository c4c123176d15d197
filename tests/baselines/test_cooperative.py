"""The cooperative CAMPC (``campc-coop``), its grip law and internal-force loop, and the constant-grip ablation."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import uvdms_gym  # noqa: F401  (registers the environments)
from baselines import cooperative as coop
from baselines.controllers import make_baseline
from uvdms_gym.physics.grip import FrictionGraspConfig
from uvdms_gym.physics.params import GRAVITY, UVDMSParams


@pytest.fixture(scope="module")
def coop_env():
    env = gym.make("uvdms/CooperativeTransport-v1", goal="paper")
    yield env
    env.close()


def test_axial_load_matches_a_hand_computation() -> None:
    params = UVDMSParams()
    obj = params.obj
    axis = np.array([0.0, 0.6, 0.8])  # tilted: the axis has a vertical (NED z) component
    accel = np.array([0.0, 0.5, 0.0])
    load = coop.axial_load(params, axis, accel, np.zeros(3))
    expected = (obj.density - params.water_density) * obj.volume * GRAVITY * 0.8 + obj.mass * 0.5 * 0.6
    assert load == pytest.approx(expected, rel=1e-12)


def test_grip_law_against_the_friction_ellipse() -> None:
    cfg = FrictionGraspConfig()
    f_axial, m_axial = np.array([30.0, -5.0]), np.array([0.0, 0.5])
    grip = coop.grip_law(f_axial, m_axial, load=4.0, f_int=10.0, config=cfg)
    mu, r_t = cfg.mu[0], cfg.torsion_radius[0]
    left = coop.GRIP_SAFETY * 30.0 / mu  # its measured force exceeds its model share 4/2 + 10
    right = coop.GRIP_SAFETY * np.hypot(12.0 / mu, 0.5 / (mu * r_t))
    assert grip == pytest.approx([min(left, 160.0), right])


@pytest.mark.parametrize("force", [0.0, 5.0, 1.0e3, 1.0e6])
def test_grip_stays_between_the_floor_and_the_crush_margin(force: float) -> None:
    cfg = FrictionGraspConfig()
    grip = coop.grip_law(np.array([force, -force]), np.array([force, 0.0]), load=force, f_int=force, config=cfg)
    assert np.all(grip >= coop.GRIP_FLOOR)
    assert np.all(grip <= coop.CRUSH_MARGIN * cfg.crush_force)
    assert coop.CRUSH_MARGIN * cfg.crush_force < cfg.crush_force


def test_internal_wrench_sign_matches_the_environment() -> None:
    axis = np.array([0.0, 1.0, 0.0])
    hf = np.zeros((2, 6))
    hf[0, 1], hf[1, 1] = -8.0, 8.0  # the left hand pulls along -y, the right along +y: a stretch
    hf[0, 4], hf[1, 4] = -0.2, 0.2
    f_int, m_int, f_axial, _ = coop.internal_wrench(hf, axis)
    assert f_int == pytest.approx(8.0) and m_int == pytest.approx(0.2)
    assert f_axial == pytest.approx([-8.0, 8.0])


def test_a_stretch_gets_a_relative_velocity_that_closes_the_hands(monkeypatch) -> None:
    monkeypatch.setattr(coop, "K_FORCE", 1.0e-3)
    monkeypatch.setattr(coop, "K_MOMENT", 0.05)
    axis = np.array([0.0, 1.0, 0.0])
    twist = coop.relative_twist(8.0, 0.2, axis)
    # rows J_o,left - J_o,right: the left hand (at object y = -0.2 m) moves along +y relative to the right one
    assert twist[1] > 0.0 and twist[4] > 0.0
    assert np.allclose(twist[[0, 2, 3, 5]], 0.0)
    squeeze = coop.relative_twist(-1.0e4, 0.0, axis)
    assert squeeze[1] == pytest.approx(-coop.V_REL_MAX)


def test_a_measured_relative_motion_is_driven_back(coop_env) -> None:
    ctrl = make_baseline("campc-coop", coop_env)
    obs, info = coop_env.reset(seed=0)
    ctrl.reset(0)
    ctrl.predict(obs, info)  # a problem with its closed-chain matrix
    axis = np.array([0.0, 1.0, 0.0])
    j_eq = np.zeros((6, 18))
    j_eq[1, 6] = 1.0  # joint 0's velocity moves the left hand along +y relative to the right one
    j_eq[4, 7] = 1.0  # joint 1's turns it about +y
    ctrl.mpc.last_problem.j_eq = j_eq
    zeta = np.zeros(18)
    zeta[6], zeta[7] = 0.01, 0.1
    rhs = ctrl._relative_correction(zeta, axis)
    # the hands moved apart along +y and turned: the command moves them back, in proportion
    assert rhs[1] == pytest.approx(-coop.K_REL * 0.01 * ctrl.control_dt)
    assert rhs[4] == pytest.approx(-coop.K_REL_TWIST * 0.1 * ctrl.control_dt)
    assert np.allclose(rhs[[0, 2, 3, 5]], 0.0)
    ctrl.reset(0)
    assert np.allclose(ctrl._rel, 0.0)


def test_make_baseline_campc_on_a_friction_env_appends_the_constant_grip(coop_env) -> None:
    ctrl = make_baseline("campc", coop_env)
    assert isinstance(ctrl, coop.ConstantGrip)
    obs, info = coop_env.reset(seed=0)
    ctrl.reset(0)
    a = ctrl.predict(obs, info)
    assert a.shape == (20,) and coop_env.action_space.contains(a)
    cfg = coop_env.unwrapped.grasp_config
    assert 0.5 * (a[-2:] + 1.0) * cfg.grip_max == pytest.approx([cfg.grip_initial] * 2, rel=1e-6)
    hold = make_baseline("hold", coop_env).predict(obs, info)
    assert hold.shape == (20,) and np.allclose(hold[:18], 0.0) and np.allclose(hold[-2:], a[-2:])


def test_campc_coop_refuses_a_rigid_grasp() -> None:
    env = gym.make("uvdms/Transport-v1")
    try:
        with pytest.raises(ValueError, match="friction grasp") as err:
            make_baseline("campc-coop", env)
        assert "\n" not in str(err.value)
    finally:
        env.close()


def test_campc_coop_keeps_slip_small_on_the_paper_transport(coop_env) -> None:
    ctrl = make_baseline("campc-coop", coop_env)
    obs, info = coop_env.reset(seed=0)
    ctrl.reset(0)
    cfg = coop_env.unwrapped.grasp_config
    for _ in range(60):
        a = ctrl.predict(obs, info)
        assert a.shape == (20,) and np.all(np.abs(a) <= 1.0)
        grip = 0.5 * (a[-2:] + 1.0) * cfg.grip_max
        assert np.all(grip <= coop.CRUSH_MARGIN * cfg.crush_force + 1e-3)  # float32 action
        obs, _, terminated, _, info = coop_env.step(a)
        assert not terminated
    assert info["slip_max"] < 2.0e-3
    assert not info["dropped"] and not info["crushed"]
