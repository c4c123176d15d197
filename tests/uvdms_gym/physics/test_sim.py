"""The PyBullet plant (uvdms_gym.physics.sim) against independent computations: Pinocchio, ODEs, hydrostatics."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

from tests.support.sim import (
    com_acceleration_world,
    com_velocity_world,
    mass_matrix,
    pin_config,
    random_state,
    reference_acceleration,
)
from uvdms_gym.physics import frames, model
from uvdms_gym.physics.hydro import HydroScale
from uvdms_gym.physics.params import GRAVITY, JOINT_NAMES, UVDMSParams
from uvdms_gym.physics.sim import UVDMSSim
from uvdms_gym.physics.state import PhysicsError

P = UVDMSParams()
# Bare vehicle with buoyancy equal to weight: no net heave force, so 1-DOF responses can be isolated.
P_NEUTRAL = dataclasses.replace(P, vehicle=dataclasses.replace(P.vehicle, buoyancy=P.vehicle.mass * GRAVITY))


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
            ref = reference_acceleration(sim, pm, pd, s0, info.tau, nudot_est)
            np.testing.assert_allclose((s1.qdot - s0.qdot) / dt, ref[6:], rtol=1e-7, atol=1e-7)
            np.testing.assert_allclose((s1.nu[3:] - s0.nu[3:]) / dt, ref[3:6], rtol=1e-7, atol=1e-7)
            np.testing.assert_allclose(
                (com_velocity_world(s1) - com_velocity_world(s0)) / dt,
                com_acceleration_world(s0, ref),
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
