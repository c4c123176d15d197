"""The PyBullet plant (uvdms_gym.physics.sim) against independent computations: Pinocchio, ODEs, hydrostatics."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pybullet as pb
import pytest
from scipy.integrate import solve_ivp

from uvdms_gym.physics import frames, hydro, model
from uvdms_gym.physics.hydro import HydroScale
from uvdms_gym.physics.params import GRAVITY, JOINT_NAMES, UVDMSParams
from uvdms_gym.physics.sim import NU_LIMIT, PhysicsError, SimState, StepInfo, UVDMSSim

P = UVDMSParams()
# Bare vehicle with buoyancy equal to weight: no net heave force, so 1-DOF responses can be isolated.
P_NEUTRAL = dataclasses.replace(P, vehicle=dataclasses.replace(P.vehicle, buoyancy=P.vehicle.mass * GRAVITY))


@pytest.fixture
def sim():
    s = UVDMSSim(P)
    yield s
    s.close()


@pytest.fixture
def sim_nc():
    """No self-collision: the random states of the dynamics checks may put links inside each other."""
    s = UVDMSSim(P, self_collision=False)
    yield s
    s.close()


@pytest.fixture
def bare():
    s = UVDMSSim(P, arms=False)
    yield s
    s.close()


def random_state(rng: np.random.Generator, n_joints: int = 12, scale: float = 1.0):
    eta = np.r_[rng.uniform(-5, 5, 3), rng.uniform(-1.2, 1.2, 2), rng.uniform(-3.0, 3.0)]
    nu = rng.normal(size=6) * 0.5 * scale
    q = rng.uniform(-1.5, 1.5, n_joints)
    qdot = rng.normal(size=n_joints) * 0.5 * scale
    return eta, nu, q, qdot


def pin_config(eta: np.ndarray, q: np.ndarray) -> np.ndarray:
    return np.r_[eta[:3], pin.Quaternion(frames.euler_to_rot(eta[3:])).coeffs(), q]


def mass_matrix(pm, pd, qp):
    m = pin.crba(pm, pd, qp)
    return np.triu(m) + np.triu(m, 1).T


# ---------------------------------------------------------------------------------------------- frames/API
@pytest.mark.parametrize("arms", [True, False])
def test_reset_state_round_trip(arms):
    rng = np.random.default_rng(0)
    with UVDMSSim(P, arms=arms) as s:
        for _ in range(20):
            eta, nu, q, qdot = random_state(rng, s.n_joints)
            st = s.reset(eta, nu, q, qdot)
            for got, want in ((st.eta, eta), (st.nu, nu), (st.q, q), (st.qdot, qdot)):
                np.testing.assert_allclose(got, want, atol=1e-9, rtol=0)
            assert st.t == 0.0
            np.testing.assert_allclose(st.zeta, np.r_[nu, qdot])


def test_link_index_and_joint_order(sim):
    c = sim.client
    assert sim.link_index["vehicle"] == -1
    assert sim.n_joints == 12 and len(sim.joint_indices) == 12
    names = [c.getJointInfo(sim.body_id, j)[1].decode() for j in sim.joint_indices]
    assert names == list(JOINT_NAMES)
    for name in ("added_mass", "left_grasp", "right_grasp", "right_link3", "plate_front"):
        j = sim.link_index[name]
        assert c.getJointInfo(sim.body_id, j)[12].decode() == name
    with pytest.raises(TypeError):
        sim.link_index["x"] = 3  # read-only mapping


def test_pybullet_damping_is_disabled(sim):
    # Free flight without gravity and without hydrodynamics: a pure translation keeps its velocity exactly.
    sim.client.setGravity(0, 0, 0)
    nu = np.array([0.5, -0.3, 0.2, 0.0, 0.0, 0.0])
    sim.reset(np.r_[0, 0, 5, 0.2, -0.1, 0.4], nu)
    for _ in range(200):
        sim.bare_step()
    np.testing.assert_allclose(sim.state().nu, nu, atol=1e-12)  # PyBullet's default 0.04 would lose ~8 %


def _reference_acceleration(s: UVDMSSim, pm, pd, st: SimState, tau: np.ndarray, nudot_est: np.ndarray):
    """Pinocchio ABA with the reference hydrodynamics of uvdms_gym.physics.hydro applied at the documented points."""
    h, params = s.hydro, s.params
    r_nb = frames.euler_to_rot(st.eta[3:])
    qp, v = pin_config(st.eta, st.q), st.zeta
    pin.forwardKinematics(pm, pd, qp, v)
    pin.updateFramePlacements(pm, pd)
    pin.computeJointJacobians(pm, pd, qp)
    f = tau.astype(float).copy()
    f[6:] -= params.arm.joint_friction * st.qdot  # gear friction (PyBullet jointDamping)
    f[:6] += hydro.vehicle_wrench(st.nu, nudot_est, h)
    f_up = h.up_force * (r_nb.T @ np.array([0.0, 0.0, -1.0]))  # NED up in body coordinates
    f[:3] += f_up
    f[3:6] += np.cross(h.up_centroid, f_up)
    k = 0
    for side in ("left", "right"):
        for i in range(1, 7):
            fid = pm.getFrameId(f"{side}_link{i}")
            a, b = model.link_segment(params, i)
            o_m_f = pd.oMf[fid]
            mid = o_m_f.act(0.5 * (a + b))
            jac = pin.getFrameJacobian(pm, pd, fid, pin.LOCAL_WORLD_ALIGNED)
            jp = jac[:3] - pin.skew(mid - o_m_f.translation) @ jac[3:]
            axis = o_m_f.rotation @ model.link_axis(params, i)
            force = hydro.link_force(jp @ v, axis, h.link_buoyancy[k], h.link_kn[k], h.link_kt[k], up=(0, 0, -1.0))
            f += jp.T @ np.array(force)
            k += 1
    return pin.aba(pm, pd, qp, v, f)


def _com_velocity_world(st: SimState) -> np.ndarray:
    r_wb = frames.body_rot_ned_to_world(frames.euler_to_rot(st.eta[3:]))
    r_g = r_wb @ np.array(P.vehicle.r_g)
    w = r_wb @ st.nu[3:]
    return r_wb @ st.nu[:3] + np.cross(w, r_g)


def _com_acceleration_world(st: SimState, acc: np.ndarray) -> np.ndarray:
    """Classical acceleration of the base COM (PyBullet integrates this velocity in the world frame)."""
    nu, w, r_g = st.nu, st.nu[3:], np.array(P.vehicle.r_g)
    a_o = acc[:3] + np.cross(w, nu[:3])
    a_c = a_o + np.cross(acc[3:6], r_g) + np.cross(w, np.cross(w, r_g))
    return frames.body_rot_ned_to_world(frames.euler_to_rot(st.eta[3:])) @ a_c


def test_one_step_dynamics_match_pinocchio_with_reference_hydrodynamics(sim_nc):
    sim = sim_nc
    # The simulator evaluates the hydrodynamics inline for speed: one explicit step from random states must
    # equal Pinocchio's ABA with the reference functions of uvdms_gym.physics.hydro (forces at the documented points,
    # vehicle wrench at the origin, lagged residual added mass), to round-off.
    pm = model.pinocchio_model(P)
    pd = pm.createData()
    rng = np.random.default_rng(3)
    dt = sim.physics_dt
    for _ in range(4):
        eta, nu, q, qdot = random_state(rng)
        tau = rng.uniform(-1, 1, 18) * P.tau_max * np.r_[np.full(6, 0.3), np.full(12, 0.01)]
        s0 = sim.reset(eta, nu, q, qdot)
        nudot_est = np.zeros(3)  # right after a reset the lag estimate is zero
        for _step in range(2):
            info = sim.step(tau)
            s1 = sim.state()
            ref = _reference_acceleration(sim, pm, pd, s0, info.tau, nudot_est)
            np.testing.assert_allclose((s1.qdot - s0.qdot) / dt, ref[6:], rtol=1e-7, atol=1e-7)
            np.testing.assert_allclose((s1.nu[3:] - s0.nu[3:]) / dt, ref[3:6], rtol=1e-7, atol=1e-7)
            np.testing.assert_allclose(
                (_com_velocity_world(s1) - _com_velocity_world(s0)) / dt,
                _com_acceleration_world(s0, ref),
                rtol=1e-7,
                atol=1e-7,
            )
            nudot_est = (s1.nu[:3] - s0.nu[:3]) / dt  # the lag estimate of the next step
            s0 = s1


# ---------------------------------------------------------------------------------------------- hydrostatics
@pytest.mark.parametrize("scale", [1.0, 2.0])
def test_bare_vehicle_initial_heave_acceleration(scale):
    # 18.1 N net buoyancy accelerates the hull and its added mass Z_wdot (the virtual link, whose own weight is
    # cancelled); scaling the added mass must change the virtual link's mass via changeDynamics.
    with UVDMSSim(P, arms=False, hydro_scale=HydroScale(added_mass=scale)) as s:
        s.reset(np.r_[0, 0, 10, 0, 0, 0])
        s.step(np.zeros(6))
        wdot = s.state().nu[2] / s.physics_dt
    v = P.vehicle
    expected = -(v.buoyancy - v.weight) / (v.mass + scale * v.added_mass[2])
    assert wdot == pytest.approx(expected, rel=1e-3)  # rel: the four frame plates weigh 4e-4 kg
    assert expected == pytest.approx(-18.1 / (106 + scale * 31.3), rel=5e-3)


def test_roll_is_righted_with_the_metacentric_moment(bare):
    v = P.vehicle
    phi0 = math.radians(10.0)
    bare.reset(np.r_[0, 0, 10, phi0, 0, 0])
    s0 = bare.state()
    bare.step(np.zeros(6))
    s1 = bare.state()
    acc = (s1.nu - s0.nu) / bare.physics_dt
    # roll row of (M_RB + M_A) nudot about the origin (Fossen, r_G = (0, 0, z_g)): -m z_g vdot + I_o pdot
    z_g = v.r_g[2]
    i_o = v.inertia[0] + v.mass * z_g**2
    k_measured = -v.mass * z_g * acc[1] + (i_o + v.added_mass[3]) * acc[3]
    k_expected = -(z_g * v.weight - v.r_b[2] * v.buoyancy) * math.sin(phi0)  # -(z_g W - z_b B) sin(phi)
    assert k_expected == pytest.approx(-36.4, abs=0.1)
    assert k_measured == pytest.approx(k_expected, rel=1e-3)
    # and the roll decays (damped oscillation about 0)
    phis = []
    for _ in range(500):
        bare.step(np.zeros(6))
        phis.append(bare.state().eta[3])
    phis = np.abs(np.array(phis))
    assert phis[-100:].max() < 0.05 * phi0
    assert phis[:100].max() <= phi0 * 1.0001


def test_full_system_hydrostatic_force_and_moment(sim_nc):
    sim = sim_nc
    # From rest, one step: the momentum and angular momentum of all links (PyBullet's own masses and inertias)
    # change by dt times the net external force and moment: gravity at every COM, buoyancy of each link at its
    # centre of volume (= COM), hull buoyancy at r_B, the virtual link's weight cancelled at the origin.
    rng = np.random.default_rng(5)
    c, b = sim.client, sim.body_id
    links = list(range(-1, c.getNumJoints(b)))
    for _ in range(3):
        eta = np.r_[0, 0, 10, rng.uniform(-0.4, 0.4, 3)]
        sim.reset(eta, q=rng.uniform(-1.5, 1.5, 12))

        def link_states():
            out = []
            for j in links:
                if j < 0:
                    p, orn = c.getBasePositionAndOrientation(b)
                    v, w = c.getBaseVelocity(b)
                else:
                    ls = c.getLinkState(b, j, computeLinkVelocity=1, computeForwardKinematics=1)
                    p, orn, v, w = ls[0], ls[1], ls[6], ls[7]
                out.append((np.array(p), frames.quat_xyzw_to_rot(np.array(orn)), np.array(v), np.array(w)))
            return out

        before = link_states()
        r_wb = frames.body_rot_ned_to_world(frames.euler_to_rot(eta[3:]))
        origin = frames.ned_to_world(eta[:3])
        up = np.array([0.0, 0.0, 1.0])
        force, moment = np.zeros(3), np.zeros(3)
        for j, (p, _, _, _) in zip(links, before):
            m = c.getDynamicsInfo(b, j)[0]
            f = -m * GRAVITY * up
            name = "vehicle" if j < 0 else c.getJointInfo(b, j)[12].decode()
            if "_link" in name:  # arm link: buoyancy of its own volume at its COM (the capsule midpoint)
                f = f + P.water_density * GRAVITY * P.arm.link_volume(int(name[-1])) * up
            if name == "added_mass":
                f = f + m * GRAVITY * up
            force += f
            moment += np.cross(p, f)
        p_b = origin + r_wb @ np.array(P.vehicle.r_b)
        force += P.vehicle.buoyancy * up
        moment += np.cross(p_b, P.vehicle.buoyancy * up)
        # params' net force ignores the 1e-4 kg frame-only links (plates, tool and grasp frames): 8 mN
        assert force[2] == pytest.approx(P.net_vertical_force(), rel=1e-4)

        base_pose = c.getBasePositionAndOrientation(b)
        q0 = [c.getJointState(b, j)[0] for j in sim.joint_indices]
        sim.step(np.zeros(18))
        # Evaluate the new velocities at the initial configuration: then sum(m v) / dt and the angular momentum
        # are exactly dt times the net force and moment (the configuration change would add O(dt^2) terms,
        # large for the low-inertia roll joints).
        v_base, w_base = c.getBaseVelocity(b)
        qd1 = [c.getJointState(b, j)[1] for j in sim.joint_indices]
        c.resetBasePositionAndOrientation(b, *base_pose)
        c.resetBaseVelocity(b, v_base, w_base)
        for j, qj, qdj in zip(sim.joint_indices, q0, qd1):
            c.resetJointState(b, j, qj, qdj)
        after = link_states()
        momentum, ang_momentum = np.zeros(3), np.zeros(3)
        for j, (p, rot, v, w) in zip(links, after):
            info = c.getDynamicsInfo(b, j)
            inertia_w = rot @ np.diag(info[2]) @ rot.T
            momentum += info[0] * v
            ang_momentum += info[0] * np.cross(p, v) + inertia_w @ w
        dt = sim.physics_dt
        np.testing.assert_allclose(momentum / dt, force, atol=1e-9 * abs(force[2]))
        np.testing.assert_allclose(ang_momentum / dt, moment, atol=1e-9 * np.abs(moment).max())


# ---------------------------------------------------------------------------------------------- 1-DOF ODEs
@pytest.mark.parametrize(
    ("dof", "load", "mass", "d_lin", "d_quad"),
    [
        (0, 200.0, 106.0 + 63.0, 110.0, 90.0),  # surge
        (2, 200.0, 106.0 + 31.3, 140.0, 110.0),  # heave
        (5, 30.0, 12.0 + 3.4, 17.0, 12.0),  # yaw
    ],
)
def test_one_dof_step_response_matches_ode(dof, load, mass, d_lin, d_quad):
    t_end = 20.0
    with UVDMSSim(P_NEUTRAL, arms=False) as s:
        s.reset(np.r_[0, 0, 10, 0, 0, 0])
        tau = np.zeros(6)
        tau[dof] = load
        ts, xs = [0.0], [0.0]
        while s.t < t_end - 1e-9:
            s.step(tau)
            st = s.state()
            ts.append(st.t)
            xs.append(st.nu[dof])
    sol = solve_ivp(
        lambda _t, x: [(load - (d_lin + d_quad * abs(x[0])) * x[0]) / mass],
        (0.0, ts[-1]),
        [0.0],
        t_eval=ts,
        rtol=1e-10,
        atol=1e-12,
    )
    ode = sol.y[0]
    err = np.abs(np.array(xs) - ode).max() / np.abs(ode).max()
    assert err < 0.02, f"max deviation {100 * err:.2f} % of the response"
    assert xs[-1] == pytest.approx(ode[-1], rel=1e-3)  # the same steady state


# ---------------------------------------------------------------------------------------------- stability
def _random_wrench_run(params: UVDMSParams, t_end: float, seed: int = 0):
    """Random piecewise-constant vehicle wrenches (|tau_v| <= tau_max / 2, switched every 0.1 s) with the arms
    held near q = 0 by a computed-torque PD (Pinocchio) plus random accelerations. Returns nu and the
    kinetic energy 0.5 zeta^T M zeta per step, and the PhysicsError if one was raised."""
    pm = model.pinocchio_model(params)
    pd = pm.createData()
    rng = np.random.default_rng(seed)
    nus, energy, error = [], [], None
    with UVDMSSim(params) as s:
        s.reset(np.r_[0, 0, 10, 0, 0, 0])
        try:
            for _ in range(round(t_end / 0.1)):
                wrench = rng.uniform(-1, 1, 6) * params.tau_max[:6] * 0.5
                a_noise = rng.uniform(-1, 1, 12)
                for _ in range(round(0.1 / s.physics_dt)):
                    st = s.state()
                    qp = pin_config(st.eta, st.q)
                    mm = mass_matrix(pm, pd, qp)
                    h = pin.nonLinearEffects(pm, pd, qp, st.zeta)
                    tau_q = mm[6:, 6:] @ (a_noise - 25.0 * st.q - 10.0 * st.qdot) + h[6:]
                    s.step(np.r_[wrench, tau_q])
                    nus.append(st.nu)
                    energy.append(0.5 * st.zeta @ mm @ st.zeta)
        except PhysicsError as exc:
            error = exc
    return np.array(nus), np.array(energy), error


def _high_frequency_ratio(nus: np.ndarray) -> np.ndarray:
    """RMS of the period-2 (Nyquist) component nu_k - (nu_{k-1} + nu_{k+1}) / 2 relative to RMS(nu), per DOF,
    leaving out the three samples after each input switch (an input step is a legitimate kink)."""
    e = nus[1:-1] - 0.5 * (nus[:-2] + nus[2:])
    keep = (np.arange(1, len(nus) - 1) % 10) >= 3
    return np.sqrt((e[keep] ** 2).mean(0)) / np.sqrt((nus**2).mean(0))


def test_added_mass_scheme_is_stable_for_60_s():
    nus, energy, error = _random_wrench_run(P, 60.0)
    assert error is None, error
    # Bounded energy: with |tau_i| <= tau_max/2 plus the hydrostatic loads, each DOF's speed is bounded by its
    # terminal speed d_lin v + d_quad v^2 = load (heave also carries the 165 N net weight; moments get the
    # arms' static moments, at most about 2 x 11 kg x 9.81 m/s^2 x 0.9 m).
    v = P.vehicle
    loads = np.array(P.tau_max[:6]) * 0.5 + np.array([0, 0, 170.0, 200.0, 200.0, 0.0])
    dl, dq = np.array(v.linear_damping), np.array(v.quadratic_damping)
    v_term = (-dl + np.sqrt(dl**2 + 4 * dq * loads)) / (2 * dq)
    assert (np.abs(nus).max(0) < 1.5 * v_term).all(), (np.abs(nus).max(0), v_term)
    n = len(energy)
    assert energy[2 * n // 3 :].max() < 2.0 * energy[: n // 3].max()  # no growth
    # no parasitic oscillation at the step frequency (the lag's mode): measured < 0.2 %
    assert (_high_frequency_ratio(nus) < 0.01).all(), _high_frequency_ratio(nus)


def test_stability_check_detects_an_unstable_lag():
    # Negative control: X_udot = 300 kg leaves a 269 kg lagged residual, above the ~130 kg effective surge mass,
    # so the lag recursion diverges. The checks of the test above must flag it.
    bad = dataclasses.replace(P, vehicle=dataclasses.replace(P.vehicle, added_mass=(300.0, 32.2, 31.3, 5.6, 3.7, 3.4)))
    nus, _energy, error = _random_wrench_run(bad, 5.0)
    assert error is not None or (_high_frequency_ratio(nus) > 0.01).any()


# ---------------------------------------------------------------------------------------------- object / grasp
def _grasp_errors(s: UVDMSSim) -> tuple[float, float]:
    p_o, r_o = s.object_pose()[0], s.object_rotation()
    worst_p, worst_a = 0.0, 0.0
    for side in ("left", "right"):
        p, r = s.link_pose(f"{side}_grasp")
        worst_p = max(worst_p, float(np.linalg.norm(p - p_o)))
        worst_a = max(worst_a, float(np.linalg.norm(frames.rot_error(r, r_o))))
    return worst_p, worst_a


def test_closed_chain_holds_the_object(sim):
    # 10 s of disturbed motion: random vehicle wrenches and random joint torques (random accelerations through a
    # computed-torque PD about q = 0); the object must stay on both grasp frames.
    pm = model.pinocchio_model(P)
    pd = pm.createData()
    rng = np.random.default_rng(1)
    sim.reset(np.r_[2, 1, 30, 0, 0, 0], with_object=True)
    worst_p, worst_a, max_qdot = 0.0, 0.0, 0.0
    for _ in range(100):
        a_noise = rng.uniform(-3, 3, 18)
        wrench = rng.uniform(-1, 1, 6) * P.tau_max[:6] * 0.3 + np.r_[0, 0, -170.0, 0, 0, 0]
        for _ in range(10):
            st = sim.state()
            qp = pin_config(st.eta, st.q)
            mm = mass_matrix(pm, pd, qp)
            h = pin.nonLinearEffects(pm, pd, qp, st.zeta)
            tau_q = mm[6:, 6:] @ (a_noise[6:] - 25.0 * st.q - 10.0 * st.qdot) + h[6:] + P.arm.joint_friction * st.qdot
            sim.step(np.r_[wrench, tau_q])
            ep, ea = _grasp_errors(sim)
            worst_p, worst_a = max(worst_p, ep), max(worst_a, ea)
            max_qdot = max(max_qdot, np.abs(st.qdot).max())
    assert max_qdot > 1.0  # the arms really moved
    assert worst_p < 1e-3, f"{worst_p * 1e3:.3f} mm"
    assert worst_a < math.radians(0.5), f"{math.degrees(worst_a):.3f} deg"


def test_object_is_created_on_the_grasp_frames_and_moves_with_them(sim):
    rng = np.random.default_rng(2)
    eta, nu, _, _ = random_state(rng)
    # pitch-only arm motions keep the two grasp frames coincident (the grasp is defined at q = 0)
    q_arm = rng.uniform(-0.5, 0.5, 6) * np.array([0, 1, 0, 1, 0, 1])
    qd_arm = rng.normal(size=6) * 0.3 * np.array([0, 1, 0, 1, 0, 1])
    sim.reset(eta, nu, np.r_[q_arm, q_arm], np.r_[qd_arm, qd_arm], with_object=True)
    assert sim.object_id is not None
    ep, ea = _grasp_errors(sim)
    assert ep < 1e-9 and ea < 1e-7
    p_r, r_r = sim.link_pose("right_grasp")
    pos, rpy = sim.object_pose()
    np.testing.assert_allclose(pos, p_r, atol=1e-12)
    np.testing.assert_allclose(frames.euler_to_rot(rpy), r_r, atol=1e-9)
    np.testing.assert_allclose(sim.object_rotation(), r_r, atol=1e-9)
    ls = sim.client.getLinkState(sim.body_id, sim.link_index["right_grasp"], computeLinkVelocity=1)
    np.testing.assert_allclose(sim.object_velocity(), np.r_[frames.world_to_ned(ls[6]), frames.world_to_ned(ls[7])])


def test_grasp_forces_balance_the_object_momentum(sim):
    # Sum of both end-effector wrenches on the object = (object + added mass) acceleration minus the external
    # loads (gravity on the body mass, buoyancy and weight cancellation of the added mass), from rest.
    sim.reset(np.r_[2, 1, 30, 0.2, 0.1, 0.5], with_object=True)
    c, obj = sim.client, sim.object_id
    mass, _, inertia = c.getDynamicsInfo(obj, -1)[:3]
    assert mass == pytest.approx(P.obj.mass + sim.hydro.obj_added_mass)
    tau = np.zeros(18)
    tau[[0, 8, 14]] = [50.0, 3.0, -2.0]
    v0 = sim.object_velocity()
    sim.step(tau)
    acc = (sim.object_velocity() - v0) / sim.physics_dt
    r = sim.object_rotation()
    f_e = sim.grasp_forces()
    assert f_e.shape == (2, 6)
    external = np.array([0.0, 0.0, P.obj.mass * GRAVITY - sim.hydro.obj_buoyancy])  # NED, down positive
    np.testing.assert_allclose(f_e[:, :3].sum(0), mass * acc[:3] - external, rtol=1e-3, atol=1e-3)
    np.testing.assert_allclose(f_e[:, 3:].sum(0), r @ np.diag(inertia) @ r.T @ acc[3:], rtol=0.05, atol=1e-3)
    assert np.abs(f_e[:, :3]).max() > 1.0  # both arms carry real load


def test_object_requires_coincident_grasps_and_is_removed_on_reset(sim):
    c = sim.client
    with pytest.raises(ValueError, match="grasp frames differ"):
        sim.reset(np.zeros(6), q=np.r_[np.zeros(6), 0.3, np.zeros(5)], with_object=True)
    sim.reset(np.zeros(6), with_object=True)
    assert c.getNumBodies() == 2 and c.getNumConstraints() == 2
    sim.reset(np.zeros(6))
    assert sim.object_id is None
    assert c.getNumBodies() == 1 and c.getNumConstraints() == 0
    np.testing.assert_array_equal(sim.grasp_forces(), np.zeros((2, 6)))
    with pytest.raises(RuntimeError, match="no object"):
        sim.object_pose()
    with UVDMSSim(P, arms=False) as s, pytest.raises(ValueError, match="arms"):
        s.reset(np.zeros(6), with_object=True)


def test_hydro_scale_updates_the_object(sim):
    sim.reset(np.zeros(6), with_object=True)
    sim.set_hydro_scale(HydroScale(added_mass=0.5))
    mass = sim.client.getDynamicsInfo(sim.object_id, -1)[0]
    assert mass == pytest.approx(P.obj.mass + 0.5 * P.obj.added_mass_coefficient * P.water_density * P.obj.volume)
    with pytest.raises(TypeError):
        sim.set_hydro_scale(2.0)  # type: ignore[arg-type]


# ---------------------------------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    ("tau", "message"),
    [
        (np.r_[np.nan, np.zeros(17)], "NaN"),
        (np.r_[np.zeros(17), np.inf], "inf"),
        (np.zeros(17), "shape"),
        (np.zeros((2, 18)), "shape"),
        (["a"] * 18, "numeric"),
    ],
)
def test_invalid_tau_raises_value_error(sim, tau, message):
    with pytest.raises(ValueError, match=message):
        sim.step(tau)


def test_saturation_is_reported_and_input_untouched(sim):
    tau = np.zeros(18)
    tau[0] = 1e4
    tau[7] = -1e3
    tau_in = tau.copy()
    info = sim.step(tau)
    assert isinstance(info, StepInfo)
    np.testing.assert_array_equal(tau, tau_in)
    assert info.any_saturated
    assert np.flatnonzero(info.saturated).tolist() == [0, 7]
    assert info.tau[0] == P.tau_max[0] and info.tau[7] == -P.tau_max[7]
    assert not sim.step(np.zeros(18)).any_saturated
    with pytest.raises(ValueError, match="n_substeps"):
        sim.step(np.zeros(18), n_substeps=0)


def test_time_and_substeps(sim):
    sim.reset(np.zeros(6))
    info = sim.step(np.zeros(18), n_substeps=5)
    assert info.n_substeps == 5
    assert info.t == pytest.approx(5 * sim.physics_dt) and sim.t == info.t
    assert sim.reset(np.zeros(6)).t == 0.0


def test_blow_up_raises_physics_error_not_nan():
    with UVDMSSim(P) as s:
        s.reset(np.zeros(6), nu=np.r_[5.0 * NU_LIMIT, 0, 0, 0, 0, 0])  # explicit damping overshoots
        with pytest.raises(PhysicsError, match="blew up"):
            s.step(np.zeros(18))
    # a huge time step makes the explicit damping diverge: an exception, never a NaN state
    with UVDMSSim(P, physics_dt=5.0) as s:
        s.reset(np.zeros(6), nu=np.r_[1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
        with pytest.raises(PhysicsError):
            for _ in range(200):
                s.step(np.zeros(18))
                st = s.state()
                assert np.isfinite(np.r_[st.eta, st.zeta]).all()
    assert issubclass(PhysicsError, RuntimeError)


def test_close_is_idempotent_and_disconnects():
    s = UVDMSSim(P)
    cid = s.client._client
    assert pb.getConnectionInfo(physicsClientId=cid)["isConnected"] == 1
    s.close()
    s.close()
    assert s.closed
    assert pb.getConnectionInfo(physicsClientId=cid)["isConnected"] == 0
    for call in (s.state, lambda: s.step(np.zeros(18)), lambda: s.reset(np.zeros(6))):
        with pytest.raises(RuntimeError, match="closed"):
            call()
    with UVDMSSim(P) as s2:
        cid2 = s2.client._client
    assert s2.closed and pb.getConnectionInfo(physicsClientId=cid2)["isConnected"] == 0


# ---------------------------------------------------------------------------------------------- helpers
def test_zeta_matches_state(sim):
    rng = np.random.default_rng(7)
    for _ in range(5):
        st = sim.reset(*random_state(rng))
        np.testing.assert_allclose(sim.zeta(), st.zeta, atol=1e-12)


def test_count_contacts(sim):
    from uvdms_gym.physics.params import CIRCLE_Q0_LEFT_DEG, CIRCLE_Q0_RIGHT_DEG

    sim.reset(np.zeros(6))
    assert sim.count_contacts() == 0
    sim.reset(np.r_[2, 0, 3, 0, 0, 0], q=np.radians(np.array(CIRCLE_Q0_LEFT_DEG + CIRCLE_Q0_RIGHT_DEG)))
    assert sim.count_contacts() == 0
    # right arm rolled towards the left one and pitched down across it / pitched through the frame
    for q in (np.r_[np.zeros(6), 1.57, 1.0, 0, 0, 0, 0], np.tile([0, 0.6, 0, 0, 0, 0], 2)):
        sim.reset(np.zeros(6), q=q)
        n = sim.count_contacts()
        assert n > 0
        # the same pairs from one whole-body query (another PyBullet code path)
        li = sim.link_index
        arm = {li[f"{s}_link{i}"]: s for s in ("left", "right") for i in range(7)}
        plates = {li[f"plate_{p.name}"] for p in P.plates}
        pairs = set()
        for cp in sim.client.getClosestPoints(sim.body_id, sim.body_id, 0.0):
            a, b = cp[3], cp[4]
            cross = a in arm and b in arm and arm[a] != arm[b]
            plate = (a in plates and b in arm and b not in (li["left_link0"], li["right_link0"])) or (
                b in plates and a in arm and a not in (li["left_link0"], li["right_link0"])
            )
            if cross or plate:
                pairs.add(frozenset((a, b)))
        assert n == len(pairs)


def test_render_rgb(sim):
    img = sim.render_rgb(64, 48)
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8
    assert img.std() > 0  # not a blank frame


def test_count_contacts_agrees_with_simulated_self_collision():
    # the same penetrating configurations, reported by closest-point queries (default) and by the contact
    # manifold of a simulator that simulates self-collision
    qs = (np.r_[np.zeros(6), 1.57, 1.0, 0, 0, 0, 0], np.tile([0, 0.6, 0, 0, 0, 0], 2), np.zeros(12))
    with UVDMSSim(P) as a, UVDMSSim(P, self_collision=True) as b:
        for q in qs:
            a.reset(np.zeros(6), q=q)
            b.reset(np.zeros(6), q=q)
            assert a.count_contacts() == b.count_contacts()
        assert a.count_contacts([("right_link1", "left_link1")]) == 0
        with pytest.raises(ValueError, match="unknown link"):
            a.count_contacts([("right_link9", "left_link1")])


def _state_from_pybullet(s: UVDMSSim) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """eta, nu, q, qdot straight from PyBullet's queries and the frames helpers (no simulator code)."""
    c, b = s.client, s.body_id
    p_com, quat = c.getBasePositionAndOrientation(b)
    v_com, w_w = c.getBaseVelocity(b)
    r_wb = frames.quat_xyzw_to_rot(np.array(quat))
    r_g_w = r_wb @ np.array(P.vehicle.r_g)
    eta = np.r_[frames.world_to_ned(np.array(p_com) - r_g_w), frames.rot_to_euler(frames.body_rot_world_to_ned(r_wb))]
    v_o = np.array(v_com) - np.cross(np.array(w_w), r_g_w)
    nu = np.r_[r_wb.T @ v_o, r_wb.T @ np.array(w_w)]
    js = c.getJointStates(b, list(s.joint_indices))
    return eta, nu, np.array([j[0] for j in js]), np.array([j[1] for j in js])


def test_state_and_object_queries_follow_every_step_and_reset(sim):
    """state() and the object queries reuse one PyBullet read per physics state: it must never be stale."""
    rng = np.random.default_rng(11)
    q0 = np.zeros(12)
    sim.reset(np.array([2.0, 0.0, 3.0, 0.1, -0.1, 0.3]), q=q0, with_object=True)
    loop_tau = rng.uniform(-20.0, 20.0, 18)
    for k in range(12):
        if k == 6:  # a reset between steps, after the previous state has been read
            sim.state()
            sim.reset(*random_state(rng, scale=0.3))
        else:
            sim.step(loop_tau, n_substeps=1 + k % 3, feedback=(lambda z: 0.5 * loop_tau) if k % 2 else None)
        st = sim.state()
        for got, expected in zip((st.eta, st.nu, st.q, st.qdot), _state_from_pybullet(sim)):
            np.testing.assert_allclose(got, expected, rtol=0.0, atol=1e-12)
        if sim.object_id is not None:
            p, quat = sim.client.getBasePositionAndOrientation(sim.object_id)
            v, w = sim.client.getBaseVelocity(sim.object_id)
            r = frames.body_rot_world_to_ned(frames.quat_xyzw_to_rot(np.array(quat)))
            pos, rpy, rot = sim.object_pose_rotation()
            np.testing.assert_allclose(pos, frames.world_to_ned(np.array(p)), atol=1e-12)
            np.testing.assert_allclose(rot, r, atol=1e-12)
            np.testing.assert_allclose(rpy, frames.rot_to_euler(r), atol=1e-12)
            np.testing.assert_allclose(sim.object_pose()[1], rpy, atol=0.0)
            np.testing.assert_allclose(
                sim.object_velocity(),
                np.r_[frames.world_to_ned(np.array(v)), frames.world_to_ned(np.array(w))],
                atol=1e-12,
            )
