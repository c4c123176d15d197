import numpy as np

from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.model import link_segment
from uvdms_gym.physics.nominal import NominalDynamics, NominalScale
from uvdms_gym.physics.params import GRAVITY


def _independent_hydrostatics(kin: KinematicModel, scale: float = 1.0) -> np.ndarray:
    """-sum_i J_i^T F_b,i over the hull and the 14 links (point Jacobians, explicit forces)."""
    p = kin.params
    tot = np.zeros(18)
    pos, rot = kin.frame_placement("vehicle")
    f_hull = np.array([0.0, 0.0, -p.vehicle.buoyancy * scale])
    tot -= kin.point_jacobian("vehicle", pos + rot @ np.array(p.vehicle.r_b)).T @ f_hull
    for side in ("left", "right"):
        for i in range(7):
            pl, rl = kin.frame_placement(f"{side}_link{i}")
            a, b = link_segment(p, i)
            f = np.array([0.0, 0.0, -p.water_density * GRAVITY * p.arm.link_volume(i) * scale])
            tot -= kin.point_jacobian(f"{side}_link{i}", pl + rl @ (0.5 * (a + b))).T @ f
    return tot


def test_hydrostatics_equal_sum_of_point_forces():
    kin = KinematicModel()
    rng = np.random.default_rng(0)
    for scale in (1.0, 0.7):
        nd = NominalDynamics(kin, NominalScale(buoyancy=scale))
        for _ in range(10):
            kin.set_state(np.r_[rng.normal(size=3), rng.uniform(-0.8, 0.8, 3)], rng.uniform(-1.5, 1.5, 12))
            assert np.allclose(nd.hydrostatics(), _independent_hydrostatics(kin, scale), atol=1e-9)


def test_static_force_at_level_pose_is_net_weight():
    kin = KinematicModel()
    nd = NominalDynamics(kin)
    kin.set_state(np.zeros(6), np.zeros(12), np.zeros(18))
    g = nd.static_force()
    # holding force = - (net hydrostatic force); net force up is params.net_vertical_force() (negative: sinks)
    # (0.01 N: the eight frame-only links carry 1e-4 kg each, see model.TINY_MASS)
    assert np.isclose(g[2], kin.params.net_vertical_force(), atol=0.01)
    assert np.allclose(g[[0, 1]], 0.0, atol=1e-9)


def test_bias_adds_damping_and_added_mass_terms():
    kin = KinematicModel()
    nd = NominalDynamics(kin)
    rng = np.random.default_rng(1)
    zeta = rng.normal(size=18) * 0.3
    kin.set_state(np.r_[0, 0, 1, 0.1, -0.2, 0.3], rng.uniform(-1, 1, 12), zeta)
    nu = zeta[:6]
    v = kin.params.vehicle
    d = (np.array(v.linear_damping) + np.array(v.quadratic_damping) * np.abs(nu)) * nu
    b = nd.bias()
    rigid = kin.nonlinear_effects() + nd.hydrostatics()
    assert np.allclose(b[6:], rigid[6:] + kin.params.arm.joint_friction * zeta[6:])
    # residual added mass is diag(31.7, 0.9, 0, 0, 0, 0): C_A nu = [w x a1; v x a1]
    a1 = np.array(v.residual_added_mass[:3]) * nu[:3]
    ca = np.concatenate([np.cross(nu[3:], a1), np.cross(nu[:3], a1)])
    assert np.allclose(b[:6] - rigid[:6], d + ca)
    m = nd.mass_matrix()
    assert np.allclose(m - kin.mass_matrix(), np.diag(np.r_[v.residual_added_mass, np.zeros(12)]))
    assert np.allclose(m, m.T) and np.all(np.linalg.eigvalsh(m) > 0)


def test_added_mass_coriolis_matches_cross_products_with_all_six_coefficients():
    """With a perturbed added mass every diagonal coefficient enters: [w x a1; v x a1 + w x a2] (np.cross)."""
    nd = NominalDynamics(KinematicModel(), NominalScale(added_mass=1.4))
    m = nd._base_added
    assert np.all(m > 0.0)  # all six terms active
    rng = np.random.default_rng(5)
    for _ in range(20):
        nu = rng.normal(size=6)
        v, w = nu[:3], nu[3:]
        a1, a2 = m[:3] * v, m[3:] * w
        expected = np.concatenate([np.cross(w, a1), np.cross(v, a1) + np.cross(w, a2)])
        assert np.allclose(nd.added_mass_coriolis(nu), expected, rtol=1e-14, atol=1e-14)
    # C_A(nu) nu does no work on the vehicle: nu . (C_A nu) = 0
    nu = rng.normal(size=6)
    assert abs(nu @ nd.added_mass_coriolis(nu)) < 1e-10
