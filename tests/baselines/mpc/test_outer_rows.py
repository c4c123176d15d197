"""CAMPC's outer-obstacle rows (baselines.mpc.kinematic, .campc) and the obstacle experiment of uvdms reproduce."""

import gymnasium as gym
import numpy as np
import pytest

import uvdms_gym  # noqa: F401
from baselines.controllers import make_baseline
from baselines.mpc.campc import make_mpc_controller
from baselines.mpc_baselines import OUTER_ROWS
from baselines.paper.obstacle_figure import obstacle_checks, run_obstacle_experiment
from uvdms_gym.distances.outer import compute_outer_distances, outer_distance_jacobian
from uvdms_gym.envs.references import make_transport_task
from uvdms_gym.envs.transport import vehicle_pose_for_object
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.obstacles import Obstacle, obstacle_states


@pytest.fixture(scope="module")
def start():
    task = make_transport_task("paper", np.random.default_rng(0))
    kin = KinematicModel()
    eta = vehicle_pose_for_object(kin, task.start)
    y_ref = task.reference(0.04 * np.arange(1, 11))
    return eta, np.zeros(12), y_ref


def _approaching_sphere(eta, gap: float, speed: float = 0.15):
    """A sphere ``gap`` above the object (NED: smaller z), falling onto it at ``speed``."""
    kin = KinematicModel()
    kin.set_state(eta, np.zeros(12))
    p, _ = kin.object_pose("right")
    r = 0.08
    centre = np.add(p, [0.05, 0.1, -(0.05 + r + gap)])  # object radius 0.05
    return [Obstacle("sphere", r, tuple(centre), (0.0, 0.0, speed))]


def _bound(cfg, d, rate):
    x = np.clip((d - cfg.outer_d1) / (cfg.outer_d2 - cfg.outer_d1), 0.0, 1.0)
    s = np.sin(0.5 * np.pi * x) ** 2
    return s * cfg.outer_vbar + (1 - s) * rate - cfg.k_escape * np.maximum(0.0, cfg.outer_d1 - d)


def test_outer_rows_bound_the_command(start):
    eta, q, y_ref = start
    ctrl = make_mpc_controller("transport", collision=True, outer_rows=8)
    plain = make_mpc_controller("transport", collision=True)
    obstacles = obstacle_states(_approaching_sphere(eta, gap=0.04), 0.0)
    rec = ctrl.step(eta, q, y_ref, obstacles=obstacles)
    ref = plain.step(eta, q, y_ref)
    assert rec.solved and rec.max_slack < 1e-6
    # the rows, rebuilt independently of the controller: gaps, J_dis, obstacle term, the damper's bound
    kin = KinematicModel()
    kin.set_state(eta, q)
    res = compute_outer_distances(kin, obstacles, True)
    jac, rate = outer_distance_jacobian(kin, res, obstacles)
    bound = _bound(ctrl.config, res.d, rate)
    approach = jac @ rec.zeta_cmd
    nearest = np.argsort(res.d)[:8]
    assert np.all(approach[nearest] <= bound[nearest] + 1e-6)
    # and they bind: the controller without them drives the object into the falling sphere faster than allowed
    assert np.any(jac[nearest] @ ref.zeta_cmd > bound[nearest] + 1e-3)


def test_inactive_outer_rows_change_nothing(start):
    eta, q, y_ref = start
    with_rows = make_mpc_controller("transport", collision=True, outer_rows=8)
    without = make_mpc_controller("transport", collision=True)
    a = with_rows.step(eta, q, y_ref, obstacles=None).zeta_cmd
    b = without.step(eta, q, y_ref).zeta_cmd
    np.testing.assert_allclose(a, b, atol=1e-6)


def test_escape_bias_leads_out_of_the_obstacles_path(start):
    eta, q, y_ref = start
    ctrl = make_mpc_controller("transport", collision=True, outer_rows=8, outer_escape=0.1)
    obstacles = obstacle_states(_approaching_sphere(eta, gap=0.04), 0.0)
    ctrl.step(eta, q, y_ref, obstacles=obstacles)
    bias = ctrl._escape(ctrl.last_outer, obstacles)
    v = obstacles[0, 3:6]
    assert np.linalg.norm(bias) > 0.05
    assert abs(bias @ v) < 1e-9  # across the obstacle's motion
    i = int(np.argmin(ctrl.last_outer.d))
    assert bias @ (ctrl.last_outer.p[i] - ctrl.last_outer.e[i]) > 0  # away from the obstacle


def test_baselines_get_outer_rows_only_where_there_are_obstacles():
    env = gym.make("uvdms/TransportObstacles-v1")
    assert make_baseline("campc", env).mpc.config.n_outer == OUTER_ROWS
    assert make_baseline("campc-inner", env).mpc.config.n_outer == 0
    assert make_baseline("mpc", env).mpc.config.n_outer == 0
    env.close()
    plain = gym.make("uvdms/Transport-v1")
    cfg = make_baseline("campc", plain).mpc.config
    assert cfg.n_outer == 0 and cfg.max_position_error is None and cfg.outer_escape == 0.0  # unchanged there
    plain.close()


def test_the_scripted_obstacle_scenario_needs_the_outer_rows():
    runs = run_obstacle_experiment()
    for name, ok, measured in obstacle_checks(runs):
        assert ok, f"{name}: {measured}"
