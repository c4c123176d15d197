"""Hydrodynamic model (uvdms_gym.physics.hydro) against independent matrix formulas and the parameters."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from uvdms_gym.physics import hydro, model
from uvdms_gym.physics.params import GRAVITY, UVDMSParams

P = UVDMSParams()


def skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def fossen_c_a(m_a: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Fossen's added-mass Coriolis matrix for a diagonal M_A (6x6)."""
    a11, a22 = m_a[:3, :3], m_a[3:, 3:]
    s1, s2 = skew(a11 @ nu[:3]), skew(a22 @ nu[3:])
    return np.block([[np.zeros((3, 3)), -s1], [-s1, -s2]])


def fossen_c_rb(mass: float, inertia: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Fossen's rigid-body Coriolis matrix of a body with its centre of gravity at the origin."""
    return np.block([[mass * skew(nu[3:]), np.zeros((3, 3))], [np.zeros((3, 3)), -skew(np.diag(inertia) * nu[3:])]])


def test_vehicle_wrench_matches_fossen_matrices():
    c = hydro.hydro_coefficients(P)
    rng = np.random.default_rng(0)
    m_res = np.diag([*c.a_res, 0.0, 0.0, 0.0])
    for _ in range(20):
        nu = rng.normal(size=6)
        nudot = rng.normal(size=6)
        d = np.diag(np.array(P.vehicle.linear_damping) + np.array(P.vehicle.quadratic_damping) * np.abs(nu))
        expected = -d @ nu - m_res @ nudot - fossen_c_a(m_res, nu) @ nu
        np.testing.assert_allclose(hydro.vehicle_wrench(nu, nudot, c), expected, rtol=1e-12, atol=1e-12)


def test_residual_plus_virtual_rigid_body_equals_full_added_mass():
    # The documented split: Fossen's M_A nudot + C_A(nu) nu for the full diagonal M_A equals the rigid-body
    # dynamics of the virtual link (point mass m_a with inertia diag(K, M, N) at the origin) plus the residual.
    v = P.vehicle
    m_a_full = np.diag(v.added_mass)
    m_res = np.diag(v.residual_added_mass)
    ma = v.rigid_added_mass
    inertia = np.array(v.added_mass[3:])
    m_rigid = np.diag([ma, ma, ma, *inertia])
    np.testing.assert_allclose(m_rigid + m_res, m_a_full)
    rng = np.random.default_rng(1)
    for _ in range(10):
        nu = rng.normal(size=6)
        full = fossen_c_a(m_a_full, nu) @ nu
        split = fossen_c_rb(ma, np.diag(inertia), nu) @ nu + fossen_c_a(m_res, nu) @ nu
        np.testing.assert_allclose(split, full, rtol=1e-12, atol=1e-12)
    assert v.residual_added_mass == pytest.approx((31.7, 0.9, 0.0, 0.0, 0.0, 0.0))


def test_lagged_residual_is_stable_against_the_smallest_effective_mass():
    # The lag recursion a_k = -(A / M_eff) a_{k-1} is stable iff A < M_eff. The smallest effective surge mass
    # at the origin is the bare vehicle's: rigid body (mass at r_G) plus the virtual link, with pitch coupling.
    import pinocchio as pin

    m = model.pinocchio_model(P)
    bare_text = model.build_urdf(P, shapes=False, arms=False)
    bare = pin.buildModelFromXML(bare_text, pin.JointModelFreeFlyer())
    for mdl in (bare, m):
        data = mdl.createData()
        mm = pin.crba(mdl, data, pin.neutral(mdl))
        mm = np.triu(mm) + np.triu(mm, 1).T
        m_eff = 1.0 / np.diag(np.linalg.inv(mm))[:3]
        ratio = np.array(P.vehicle.residual_added_mass[:3]) / m_eff
        assert ratio.max() < 0.3, ratio


def test_morison_force_decomposition():
    kn, kt = 7.0, 0.3
    e = np.array([0.0, 0.6, 0.8])
    # pure cross-flow and pure axial flow
    v_n = np.array([1.5, 0.0, 0.0])
    np.testing.assert_allclose(hydro.morison_force(v_n, e, kn, kt), -kn * 1.5 * v_n)
    v_t = -2.0 * e
    np.testing.assert_allclose(hydro.morison_force(v_t, e, kn, kt), -kt * 2.0 * v_t, atol=1e-14)
    # mixed flow: components add; the force is even in the axis direction
    v = v_n + v_t
    f = np.array(hydro.morison_force(v, e, kn, kt))
    np.testing.assert_allclose(f, -kn * 1.5 * v_n - kt * 2.0 * v_t, atol=1e-14)
    np.testing.assert_allclose(hydro.morison_force(v, -e, kn, kt), f, atol=1e-14)
    assert np.dot(f, v) < 0.0  # always dissipative


def test_link_coefficients_from_parameters():
    c = hydro.hydro_coefficients(P)
    arm, rho, r = P.arm, P.water_density, P.arm.link_radius
    assert len(c.link_buoyancy) == 12
    for k in range(12):
        i = k % 6 + 1
        assert c.link_buoyancy[k] == pytest.approx(rho * GRAVITY * math.pi * r**2 * arm.link_length[i])
        assert c.link_kn[k] == pytest.approx(0.5 * rho * arm.drag_coefficient * 2 * r * arm.link_length[i])
        assert c.link_kt[k] == pytest.approx(0.5 * rho * arm.axial_drag_coefficient * math.pi * r**2)
        np.testing.assert_allclose(c.link_axis[k], model.link_axis(P, i))
    bare = hydro.hydro_coefficients(P, arms=False)
    assert bare.link_buoyancy == ()


def test_hydrostatic_totals_match_params_net_force():
    # up_force lumps hull buoyancy, both base shells and the virtual link's weight cancellation; with the
    # moving links' buoyancy and all weights the net must equal params.net_vertical_force().
    c = hydro.hydro_coefficients(P)
    weights = P.vehicle.weight + 2 * P.arm_mass() * GRAVITY
    net = c.up_force - c.rigid_added_mass * GRAVITY + sum(c.link_buoyancy) - weights
    assert net == pytest.approx(P.net_vertical_force(), rel=1e-12)
    assert net == pytest.approx(-165.0, abs=5.0)
    bare = hydro.hydro_coefficients(P, arms=False)
    assert bare.up_force - bare.rigid_added_mass * GRAVITY - P.vehicle.weight == pytest.approx(18.1, abs=0.05)
    # the centroid is the force-weighted mean: hull at r_B, shells at their midpoints, virtual weight at 0
    shells = hydro.base_shell_midpoints(P)
    shell_b = P.water_density * GRAVITY * P.arm.link_volume(0)
    moment = P.vehicle.buoyancy * np.array(P.vehicle.r_b) + shell_b * (shells[0] + shells[1])
    np.testing.assert_allclose(np.array(c.up_centroid) * c.up_force, moment, atol=1e-12)


def test_hydro_scale_scales_each_group():
    base = hydro.hydro_coefficients(P)
    s = hydro.HydroScale(added_mass=2.0, damping=0.5, buoyancy=1.1, link_drag=3.0)
    c = hydro.hydro_coefficients(P, s)
    np.testing.assert_allclose(c.d_lin, np.array(base.d_lin) * 0.5)
    np.testing.assert_allclose(c.d_quad, np.array(base.d_quad) * 0.5)
    np.testing.assert_allclose(c.a_res, np.array(base.a_res) * 2.0)
    assert c.rigid_added_mass == pytest.approx(2.0 * base.rigid_added_mass)
    np.testing.assert_allclose(c.rigid_added_inertia, np.array(base.rigid_added_inertia) * 2.0)
    np.testing.assert_allclose(c.link_buoyancy, np.array(base.link_buoyancy) * 1.1)
    np.testing.assert_allclose(c.link_kn, np.array(base.link_kn) * 3.0)
    assert c.hull_buoyancy == pytest.approx(1.1 * base.hull_buoyancy)
    assert c.obj_buoyancy == pytest.approx(1.1 * base.obj_buoyancy)
    assert c.obj_added_mass == pytest.approx(2.0 * base.obj_added_mass)
    assert c.obj_kn == pytest.approx(3.0 * base.obj_kn)
    # weights are never scaled: the virtual weight cancellation follows the (scaled) virtual mass
    ups = c.hull_buoyancy + 2 * P.water_density * GRAVITY * P.arm.link_volume(0) * 1.1
    assert c.up_force == pytest.approx(ups + c.rigid_added_mass * GRAVITY)


@pytest.mark.parametrize("field", ["added_mass", "damping", "buoyancy", "link_drag"])
@pytest.mark.parametrize("value", [-0.1, float("nan"), float("inf")])
def test_hydro_scale_rejects_bad_values(field, value):
    with pytest.raises(ValueError, match=field):
        hydro.HydroScale(**{field: value})


def test_object_coefficients_and_wrench():
    o = P.obj
    c = hydro.hydro_coefficients(P)
    assert c.obj_added_mass == pytest.approx(o.added_mass_coefficient * P.water_density * o.volume)
    assert c.obj_added_mass == pytest.approx(4.712, abs=1e-3)
    assert c.obj_added_inertia == pytest.approx(c.obj_added_mass * o.length**2 / 12)
    assert c.obj_buoyancy == pytest.approx(46.2, abs=0.05)
    e = np.array([0.0, 1.0, 0.0])
    # at rest: buoyancy plus the cancellation of the added mass's weight, straight up; no moment
    f, m = hydro.object_wrench(np.zeros(3), e, np.zeros(3), c)
    np.testing.assert_allclose(f, [0.0, 0.0, c.obj_buoyancy + c.obj_added_mass * GRAVITY])
    np.testing.assert_allclose(m, 0.0)
    # moving: Morison drag, axial-momentum correction passed through, Munk moment m_a (v.e)(v x e)
    v = np.array([0.3, -0.4, 0.2])
    rate = np.array([0.1, 0.2, 0.3])
    f, m = hydro.object_wrench(v, e, rate, c, up=(0.0, 0.0, -1.0))
    drag = hydro.morison_force(v, e, c.obj_kn, c.obj_kt)
    lift = c.obj_buoyancy + c.obj_added_mass * GRAVITY
    np.testing.assert_allclose(f, np.array(drag) + rate + [0.0, 0.0, -lift])
    p_added = c.obj_added_mass * (v - np.dot(v, e) * e)  # transverse added momentum
    np.testing.assert_allclose(m, -np.cross(v, p_added), atol=1e-14)  # Kirchhoff: M = -v x P


def test_hydro_is_pure():
    c = hydro.hydro_coefficients(P)
    nu = np.array([0.3, -0.1, 0.2, 0.05, -0.02, 0.1])
    nu_copy = nu.copy()
    a = hydro.vehicle_wrench(nu, np.zeros(3), c)
    b = hydro.vehicle_wrench(nu, np.zeros(3), c)
    assert a == b
    np.testing.assert_array_equal(nu, nu_copy)
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.up_force = 0.0  # type: ignore[misc]


def test_compiled_link_forces_match_link_force_with_rotated_axes():
    """link_forces_world = link_force(v, R(q) e, ...) per link, R from frames (an independent rotation)."""
    from uvdms_gym.physics.frames import quat_xyzw_to_rot

    c = hydro.hydro_coefficients(P, hydro.HydroScale(link_drag=1.3, buoyancy=0.9))
    table = hydro.link_table(c)
    rng = np.random.default_rng(5)
    n = table.shape[0]
    quats = rng.normal(size=(n, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    vels = rng.normal(scale=0.8, size=(n, 3))
    vels[0] = 0.0  # a link at rest: buoyancy only
    out = np.empty((n, 3))
    hydro.link_forces_world(np.concatenate([quats, vels], axis=1).reshape(-1), table, out)
    for k in range(n):
        axis = quat_xyzw_to_rot(quats[k]) @ np.array(c.link_axis[k])
        expected = hydro.link_force(vels[k], axis, c.link_buoyancy[k], c.link_kn[k], c.link_kt[k])
        np.testing.assert_allclose(out[k], expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out[0], [0.0, 0.0, c.link_buoyancy[0]], atol=1e-15)
