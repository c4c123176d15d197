"""Robot-obstacle distances (uvdms_gym.distances.outer): exact reference, PyBullet, and J_dis along a moving path."""

import numpy as np
import pinocchio as pin
import pytest

from uvdms_gym.distances.outer import (
    compute_outer_distances,
    compute_outer_distances_reference,
    outer_distance_jacobian,
    part_names,
    robot_track,
    track_gaps,
)
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.obstacles import Obstacle, obstacle_states
from uvdms_gym.physics.params import UVDMSParams
from uvdms_gym.physics.sim import UVDMSSim

P = UVDMSParams()
TOLERANCE = {"vehicle": 1e-3, "object": 1e-5}
"""PyBullet's accuracy (m) against the exact rows: capsule pairs are solved in closed form by Bullet too (links to
1e-12); the object's pose comes from its own body (1e-7 here); box pairs go through GJK with a collision margin
(up to 7e-4 m measured)."""


def _random_scene(rng):
    eta = np.r_[np.add(rng.uniform(-1, 1, 3), [0, 0, 10]), rng.uniform(-0.3, 0.3, 3)]
    q = rng.uniform(-0.6, 0.6, 12)
    centre = eta[:3] + rng.normal(size=3) * 0.6
    obstacles = [
        Obstacle("sphere", float(rng.uniform(0.03, 0.15)), tuple(centre), tuple(rng.normal(size=3) * 0.1)),
        Obstacle(
            "capsule",
            float(rng.uniform(0.02, 0.08)),
            tuple(eta[:3] + rng.normal(size=3) * 0.6),
            tuple(rng.normal(size=3) * 0.1),
            length=float(rng.uniform(0.1, 0.8)),
            axis=tuple(rng.normal(size=3)),
        ),
    ]
    return eta, q, obstacles


def test_rows_match_the_independent_reference():
    kin = KinematicModel(P)
    rng = np.random.default_rng(3)
    for it in range(40):
        eta, q, obstacles = _random_scene(rng)
        kin.set_state(eta, q)
        states = obstacle_states(obstacles, 0.0)
        with_object = bool(it % 2)
        res = compute_outer_distances(kin, states, with_object)
        ref = compute_outer_distances_reference(kin, states, with_object)
        np.testing.assert_allclose(res.d, ref, atol=1e-9)
        assert res.parts[: res.n_parts] == part_names(with_object)
        # the closest points realise the gaps: |e - p| minus the radii
        radii = [P.arm.link_radius] * 12 + ([P.obj.radius] if with_object else []) + [0.0]
        for k, ob in enumerate(obstacles):
            rows = slice(k * res.n_parts, (k + 1) * res.n_parts)
            sep = np.linalg.norm(res.e[rows] - res.p[rows], axis=1)
            np.testing.assert_allclose(sep - radii - ob.radius, res.d[rows], atol=1e-12)


def test_rows_match_pybullet_closest_points():
    rng = np.random.default_rng(5)
    kin = KinematicModel(P)
    with UVDMSSim(P, outer_collisions=True) as sim:
        c = sim.client
        checked = 0
        for it in range(10):
            eta, q, obstacles = _random_scene(rng)
            with_object = it % 2 == 0
            if with_object:
                q = np.zeros(12)  # the grippers hold the object together only at matching poses
            sim.reset(eta, q=q, with_object=with_object)
            sim.set_obstacles(obstacles)
            st = sim.state()
            kin.set_state(st.eta, st.q)
            res = compute_outer_distances(kin, obstacle_states(obstacles, 0.0), with_object)
            for row, part in enumerate(res.parts):
                k = int(res.obstacle_index[row])
                body, link = (sim.object_id, -1) if part == "object" else (sim.body_id, sim.link_index[part])
                gap = min(p[8] for p in c.getClosestPoints(body, sim.obstacle_ids[k], 10.0, link, -1))
                if part == "vehicle" and res.d[row] < 0.0:
                    continue  # the core inside the hull box: the row reports -radius, not the depth (module docs)
                assert gap == pytest.approx(res.d[row], abs=TOLERANCE.get(part, 1e-9)), (part, k)
                checked += 1
        assert checked > 200


def test_jdis_with_obstacle_velocity_matches_finite_differences():
    """d_dot = -(J_dis zeta - n^T v_obs) along a path where the robot and the obstacles move at once."""
    kin = KinematicModel(P)
    rng = np.random.default_rng(11)
    worst = 0.0
    for _ in range(30):
        eta, q, obstacles = _random_scene(rng)
        zeta = rng.normal(size=18) * 0.3
        config = KinematicModel.configuration(eta, q)
        kin.set_configuration(config)
        states = obstacle_states(obstacles, 0.0)
        res = compute_outer_distances(kin, states, True)
        jac, rate = outer_distance_jacobian(kin, res, states)
        predicted = -(jac @ zeta - rate)

        def gaps_at(t, config=config, zeta=zeta, obstacles=obstacles):
            kin.set_configuration(pin.integrate(kin.model, config, zeta * t))
            return compute_outer_distances(kin, obstacle_states(obstacles, t), True).d

        h = 1e-6
        fd = (gaps_at(h) - gaps_at(-h)) / (2 * h)
        unique = res.d > 1e-3  # separated rows (overlapping ones have no unique closest points)
        err = np.abs(fd - predicted)[unique]
        worst = max(worst, float(err.max()))
    assert worst < 1e-6


def test_gaps_over_a_track_equal_the_per_instant_rows():
    kin = KinematicModel(P)
    rng = np.random.default_rng(2)
    eta, q, obstacles = _random_scene(rng)
    times = np.linspace(0.0, 3.0, 7)
    etas = np.array([np.add(eta, [0.1 * t, 0, 0, 0, 0, 0.05 * t]) for t in times])
    qs = np.tile(q, (times.size, 1))
    track = robot_track(kin, times, etas, qs, True)
    ob = obstacles[1]
    states = np.array([obstacle_states([ob], t)[0] for t in times])
    gaps = track_gaps(track, P, states)
    for k in range(times.size):
        kin.set_state(etas[k], qs[k])
        np.testing.assert_allclose(gaps[k], compute_outer_distances(kin, states[k : k + 1], True).d, atol=1e-12)
