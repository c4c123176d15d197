"""Outer obstacles: specifications, scripted motion, PyBullet bodies and contacts, TransportObstacles-v1."""

import gymnasium as gym
import numpy as np
import pytest

import uvdms_gym  # noqa: F401  (registers the environments)
from uvdms_gym.envs.obstacle_scenarios import START_CLEARANCE
from uvdms_gym.physics.obstacles import Obstacle, obstacle_states, parse_obstacles

ENV_ID = "uvdms/TransportObstacles-v1"
SCRIPT = [
    {"shape": "sphere", "radius": 0.08, "position": [3.5, 1.5, 29.0], "velocity": [-0.05, 0.02, 0.01]},
    {
        "shape": "capsule",
        "radius": 0.04,
        "length": 0.3,
        "axis": [0.0, 0.0, 1.0],
        "position": [1.0, 2.5, 30.0],
        "waypoints": [[0.4, 1.1, 2.4, 30.1], [1.0, 1.2, 2.4, 30.0]],
    },
]


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ({"shape": "sphere", "radius": -0.1, "position": [0, 0, 0]}, "radius must be > 0"),
        ({"shape": "sphere", "radius": 0.1, "position": [0, float("nan"), 0]}, "position must be finite"),
        ({"shape": "sphere", "radius": 0.1, "position": [0, 0, 0], "colour": "red"}, "unknown key(s) ['colour']"),
        ({"shape": "cube", "radius": 0.1, "position": [0, 0, 0]}, "shape must be one of"),
        ({"shape": "capsule", "radius": 0.1, "position": [0, 0, 0]}, "needs length > 0"),
        ({"shape": "sphere", "radius": 0.1, "position": [0, 0]}, "position must be 3 numbers"),
        ({"shape": "sphere", "radius": 0.1, "position": [0, 0, 0], "velocity": [3, 0, 0]}, "exceeds 2.0 m/s"),
        (
            {"shape": "sphere", "radius": 0.1, "position": [0, 0, 0], "waypoints": [[1, 0, 0, 0], [0.5, 1, 1, 1]]},
            "strictly",
        ),
        ({"radius": 0.1, "position": [0, 0, 0]}, "missing key 'shape'"),
    ],
)
def test_bad_obstacle_specifications_name_the_problem(spec, message):
    with pytest.raises(ValueError, match="obstacles\\[0\\]") as err:
        parse_obstacles([spec])
    assert message in str(err.value)
    with pytest.raises(ValueError) as err_env:  # the same message through gym.make, before any client exists
        gym.make(ENV_ID, obstacles=[spec])
    assert message in str(err_env.value)


def test_obstacles_keyword_rejects_other_values():
    for bad in ("many", {"shape": "sphere"}, 3):
        with pytest.raises(ValueError, match="obstacles must be"):
            gym.make(ENV_ID, obstacles=bad)


def test_a_start_inside_the_vehicle_is_refused():
    env = gym.make(ENV_ID, obstacles=[])
    eta = env.unwrapped._initial_state()[0]
    inside = {"shape": "sphere", "radius": 0.1, "position": eta[:3].tolist()}
    with pytest.raises(ValueError, match="obstacles\\[0\\] starts in contact with the robot's vehicle"):
        gym.make(ENV_ID, obstacles=[inside])
    env.close()


def test_waypoint_and_constant_velocity_scripts():
    ob = Obstacle("sphere", 0.1, (1.0, 2.0, 3.0), waypoints=((2.0, 3.0, 2.0, 3.0), (4.0, 3.0, 2.0, 5.0)))
    np.testing.assert_allclose(ob.position_at(1.0), [2.0, 2.0, 3.0])  # halfway to the first waypoint
    np.testing.assert_allclose(ob.position_at(3.0), [3.0, 2.0, 4.0])
    np.testing.assert_allclose(ob.position_at(10.0), [3.0, 2.0, 5.0])  # held after the last
    np.testing.assert_allclose(ob.velocity_at(1.0), [1.0, 0.0, 0.0])
    np.testing.assert_allclose(ob.velocity_at(3.0), [0.0, 0.0, 1.0])
    np.testing.assert_allclose(ob.velocity_at(5.0), [0.0, 0.0, 0.0])
    lin = Obstacle("capsule", 0.05, (0.0, 0.0, 0.0), (0.1, -0.2, 0.3), length=0.4, axis=(0.0, 0.0, 2.0))
    np.testing.assert_allclose(lin.position_at(np.array([0.0, 2.0])), [[0, 0, 0], [0.2, -0.4, 0.6]])
    assert lin.axis == (0.0, 0.0, 1.0)  # normalised
    assert parse_obstacles([lin.as_dict()])[0] == lin


def test_scripted_scenario_runs_exactly_as_given():
    env = gym.make(ENV_ID, obstacles=SCRIPT)
    u = env.unwrapped
    _, info = env.reset(seed=0)
    obstacles = parse_obstacles(SCRIPT)
    for _ in range(40):
        expected = obstacle_states(obstacles, info["t"])
        np.testing.assert_allclose(info["obstacles"], expected, rtol=0, atol=1e-12)
        np.testing.assert_allclose(u._sim.obstacle_positions(), expected[:, :3], rtol=0, atol=1e-9)
        _, _, term, _, info = env.step(np.zeros(18, np.float32))
        assert not term
    env.close()


def _rollout(seed: int, steps: int = 25, env=None):
    env = env or gym.make(ENV_ID, current="random")
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = [obs, info["obstacles"], info["current"]]
    for _ in range(steps):
        obs, reward, _, _, info = env.step(rng.uniform(-0.3, 0.3, 18).astype(np.float32))
        out += [obs, reward, info["obstacles"], info["obstacle_distances"], info["current"], info["eta"]]
    return env, out


def test_same_seed_repeats_the_episode_bit_for_bit():
    env, first = _rollout(7)
    _, other = _rollout(8, env=env)  # another episode in between: the simulator's body order must not matter
    _, again = _rollout(7, env=env)
    env2, fresh = _rollout(7)
    for a, b, c in zip(first, again, fresh):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)
    assert not np.array_equal(first[1], other[1])
    env.close()
    env2.close()


def test_random_scenarios_cross_the_transport_and_start_clear():
    env = gym.make(ENV_ID)
    u = env.unwrapped
    counts = set()
    for seed in range(6):
        _, info = env.reset(seed=seed)
        counts.add(len(u.obstacles))
        assert 1 <= len(u.obstacles) <= 3
        assert info["obstacle_distances"].min() >= START_CLEARANCE  # never starting in contact (or near it)
        for ob in u.obstacles:
            _, gaps = u._nominal_gaps(ob)
            assert gaps.min() < 0.0  # a robot tracking its reference and ignoring it would touch it
    assert len(counts) > 1
    env.close()


def test_observation_slots_against_an_independent_computation():
    env = gym.make(ENV_ID, obstacles=SCRIPT, n_observed_obstacles=3)
    obs, info = env.reset(seed=0)
    assert obs.shape == (80 + 3 * 13,) and env.observation_space.contains(obs)
    eta, nu = info["eta"], info["nu"]
    from uvdms_gym.physics.frames import euler_to_rot

    r = euler_to_rot(eta[3:])
    order = np.argsort(info["obstacle_distances"].min(axis=1))
    for slot, k in enumerate(order):
        s = obs[80 + 13 * slot : 80 + 13 * (slot + 1)]
        st = info["obstacles"][k]
        np.testing.assert_allclose(s[0:3], r.T @ (st[:3] - eta[:3]) / 2.0, atol=1e-6)
        np.testing.assert_allclose(s[3:6], r.T @ (st[3:6] - r @ nu[:3]) / 0.5, atol=1e-6)
        np.testing.assert_allclose(s[6:9], r.T @ st[8:11], atol=1e-6)
        assert s[9] == pytest.approx(st[6] / 0.5) and s[10] == pytest.approx(st[7] / 0.5)
        assert s[12] == 1.0
    np.testing.assert_array_equal(obs[80 + 13 * 2 :], 0.0)  # the third slot is padding
    env.close()


def test_an_obstacle_driven_into_the_object_is_a_contact_and_ends_the_episode():
    env = gym.make(ENV_ID, obstacles=[])
    u = env.unwrapped
    env.reset(seed=0)
    p = u._sim.object_position()
    ram = [
        {"shape": "sphere", "radius": 0.06, "position": np.add(p, [0.0, 0.0, -0.4]).tolist(), "velocity": [0, 0, 0.5]}
    ]
    env = gym.make(ENV_ID, obstacles=ram)
    _, info = env.reset(seed=0)
    z0 = info["eta"][2]
    for _ in range(50):
        _, _, term, _, info = env.step(np.zeros(18, np.float32))
        if term:
            break
    assert term and info["obstacle_contacts"] >= 1 and info["cost_contact"] == 1.0
    assert info["reward_contact"] < 0.0
    assert info["min_obstacle_distance"] < 0.01
    env.close()
    # kinematic: the obstacle keeps its script and pushes the robot (without termination it carries the object
    # down, the arms giving way)
    env = gym.make(ENV_ID, obstacles=ram, terminate_on_contact=False)
    _, info = env.reset(seed=0)
    for _ in range(40):
        _, _, _, _, info = env.step(np.zeros(18, np.float32))
    np.testing.assert_allclose(info["obstacles"][0, :3], np.add(ram[0]["position"], [0, 0, 0.5 * info["t"]]))
    np.testing.assert_allclose(env.unwrapped._sim.obstacle_positions()[0], info["obstacles"][0, :3], atol=1e-9)
    assert env.unwrapped._sim.object_position()[2] - p[2] > 0.2
    assert info["eta"][2] - z0 < 0.05
    env.close()
