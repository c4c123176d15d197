"""The environments at ``realism > 0``: measurements in, truth aside, the action path, errors naming the knob."""

from __future__ import annotations

import copy
import math
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import uvdms_gym  # noqa: F401  (registers the ids)
from uvdms_gym.distances import compute_distances
from uvdms_gym.envs.measured_kinematics import MeasuredKinematics, assemble_observation
from uvdms_gym.envs.realism_layer import _vehicle_table, vehicle_row
from uvdms_gym.evaluation import run_episode
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.realism.config import LEVELS, to_substeps
from uvdms_gym.seeds import split_seeds
from uvdms_gym.utils.kwargs import parse_kv

CIRCLE = "uvdms/CircleTrack-v1"
KW = {"case": "random", "hydro_randomization": 0.3}
SEED = split_seeds("validation", 12)[11]  # a validation draw
V1_IDS = ("uvdms/CircleTrack-v1", "uvdms/Transport-v1", "uvdms/TransportObstacles-v1")


def _smooth_actions(n: int, dim: int = 18, amplitude: float = 0.3, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out, a = np.zeros((n, dim)), np.zeros(dim)
    for k in range(n):
        a = 0.9 * a + 0.1 * rng.uniform(-1.0, 1.0, dim)
        out[k] = amplitude * a
    return out.astype(np.float32)


def _rollout(env, seed: int, actions: np.ndarray) -> list[tuple[np.ndarray, float, dict]]:
    obs, info = env.reset(seed=seed)
    rows = [(obs, 0.0, info)]
    for a in actions:
        obs, reward, term, trunc, info = env.step(a)
        rows.append((obs, reward, info))
        if term or trunc:
            break
    return rows


@pytest.mark.parametrize("level", [1, 2, 3])
def test_same_seed_same_noise_and_trajectory(level):
    actions = _smooth_actions(40)
    runs = []
    for _ in range(2):
        env = gym.make(CIRCLE, realism=level, **KW)
        runs.append(_rollout(env, SEED, actions))
        env.close()
    for (o1, r1, i1), (o2, r2, i2) in zip(*runs, strict=True):
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2
        for key in ("eta", "nu", "q", "qdot"):
            np.testing.assert_array_equal(i1[key], i2[key])


def test_a_seed_draws_the_same_task_at_every_level():
    refs, hydro = [], []
    for level in (0, 1, 2, 3):
        env = gym.make(CIRCLE, realism=level, **KW)
        env.reset(seed=SEED)
        refs.append(env.unwrapped.reference(np.linspace(0.0, 20.0, 11)))
        hydro.append(env.unwrapped._sim.hydro_scale)
        env.close()
    for r, h in zip(refs[1:], hydro[1:], strict=True):
        np.testing.assert_array_equal(r, refs[0])
        assert h == hydro[0]


@pytest.mark.parametrize("level", [1, 3])
def test_observation_and_state_keys_come_from_measurements(level):
    env = gym.make(CIRCLE, realism=level, **KW)
    obs, info = env.reset(seed=SEED)
    for a in _smooth_actions(30):
        obs, _, _, _, info = env.step(a)
    u = env.unwrapped
    truth = u.true_state()
    assert "current" not in info and "current" in truth
    assert not np.array_equal(info["eta"], truth["eta"])  # measured, not true
    assert np.max(np.abs(info["eta"][:3] - truth["eta"][:3])) < 0.5  # ... but a measurement of it
    expected, keys = u.observe_estimate(info["eta"], info["nu"], info["q"], info["qdot"])
    np.testing.assert_array_equal(obs, expected)
    np.testing.assert_array_equal(info["distances"], keys["distances"])
    # metrics are judged on the truth
    y_ref = u.reference(u.t)
    assert info["tracking_error"] == pytest.approx(
        0.5 * (np.linalg.norm(truth["y"][:3] - y_ref[:3]) + np.linalg.norm(truth["y"][3:] - y_ref[3:])), abs=1e-12
    )
    assert info["min_distance"] == min(info["distances"])
    env.close()


class _Recorder:
    """A controller that holds still and keeps every ``info`` it is handed."""

    def __init__(self) -> None:
        self.infos: list[dict] = []

    def reset(self, seed=None) -> None:
        self.infos.clear()

    def predict(self, obs, info):
        self.infos.append(info)
        return np.zeros(18, dtype=np.float32)


def test_run_episode_hands_controllers_no_truth_and_judges_on_it():
    env = gym.make(CIRCLE, realism=2, max_episode_steps=40, **KW)
    controller = _Recorder()
    ep = run_episode(env, controller, SEED, save_trajectory=True)
    u = env.unwrapped
    last = controller.infos[-1]
    assert "current" not in last
    # the last info the controller saw is the measurement of the state before the last step; the trajectory's
    # samples are the truth, which no info handed over equals
    traj_eta = np.array(ep["trajectory"]["eta"])
    seen_eta = np.array([i["eta"] for i in controller.infos])
    assert len(seen_eta) == len(traj_eta) - 1
    assert not np.any(np.all(seen_eta == traj_eta[:-1], axis=1))
    np.testing.assert_array_equal(traj_eta[-1], u.true_state()["eta"])
    env.close()


def test_action_delay_is_exact_in_substeps():
    """A joint torque issued at step 0 first acts ``d`` substeps later: the mean commanded torque shows it."""
    dt, n = 0.01, 4
    for delay in (0.04, 0.06):
        env = gym.make(
            CIRCLE,
            action_mode="torque",
            realism={"level": 1, "action_delay": delay, "thrusters": False, "joint_speed_limit": None},
            **KW,
        )
        env.reset(seed=SEED)
        a = np.zeros(18, dtype=np.float32)
        a[7] = 0.1
        d = to_substeps(delay, dt)
        means = [env.step(a)[4]["tau_cmd"][7] for _ in range(3)]
        tau = float(a[7]) * env.unwrapped.tau_max[7]
        expected = [tau * min(max((k + 1) * n - d, 0), n) / n for k in range(3)]
        np.testing.assert_allclose(means, expected, rtol=1e-12, atol=1e-12)
        env.close()


def test_sensor_rates_and_latencies_are_exact_in_the_environment():
    level = LEVELS[2]
    env = gym.make(CIRCLE, realism=2, **KW)
    env.reset(seed=SEED)
    dt, u = 0.01, env.unwrapped
    period = {name: to_substeps(level.sensor(name).period, dt, minimum=1) for name in ("dvl", "fix", "depth")}
    latency = {name: to_substeps(level.sensor(name).latency, dt) for name in ("dvl", "fix", "depth")}
    released: dict[str, list[tuple[float, float]]] = {name: [] for name in period}
    for _ in range(60):
        info = env.step(np.zeros(18, dtype=np.float32))[4]
        for name in period:
            released[name] += [(t, u.t) for t, _ in info["measurements"][name]]
    for name in period:
        assert released[name], name
        for t_sample, t_release in released[name]:
            s = round(t_sample / dt)
            assert math.isclose(s * dt, t_sample, abs_tol=1e-9) and s % period[name] == 0, (name, t_sample)
            # released at the first control-step end at or after t + latency
            assert t_sample + latency[name] * dt <= t_release + 1e-9 < t_sample + latency[name] * dt + 0.04 + 1e-9
    env.close()


@pytest.mark.parametrize("env_id", V1_IDS)
@pytest.mark.parametrize("level", [1, 2, 3])
def test_check_env_at_every_level(env_id, level):
    env = gym.make(env_id, realism=level)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_check_env_in_thrusters_mode():
    env = gym.make(CIRCLE, action_mode="thrusters")
    assert env.action_space.shape == (20,)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("level", [1, 2, 3])
def test_a_pickled_copy_continues_the_episode_bit_for_bit(level):
    env = gym.make("uvdms/TransportObstacles-v1", realism=level, current="random")
    env.reset(seed=SEED)
    actions = _smooth_actions(20)
    for a in actions[:10]:
        env.step(a)
    copies = [pickle.loads(pickle.dumps(env.unwrapped)), copy.deepcopy(env.unwrapped)]
    for a in actions[10:]:
        o, r, *_ = env.unwrapped.step(a)
        for c in copies:
            oc, rc, *_ = c.step(a)
            np.testing.assert_array_equal(oc, o)
            assert rc == r
    for c in (*copies, env):
        c.close()


def test_thrusters_mode_commands_the_thrusters():
    """Equal upward commands on the four vertical thrusters lift the vehicle against its weight."""
    env = gym.make(CIRCLE, action_mode="thrusters", **KW)
    env.reset(seed=SEED)
    u = env.unwrapped
    layout = u._layer.thrusters.layout
    up = [i for i, d in enumerate(layout.directions) if d[2] < -0.5]
    assert len(up) == 4
    a = np.zeros(20, dtype=np.float32)
    a[up] = 1.0
    z0 = u.true_state()["eta"][2]
    for _ in range(25):
        info = env.step(a)[4]
    assert u.true_state()["eta"][2] < z0 - 0.05  # NED: up is -z
    np.testing.assert_allclose(info["thrust"][up], layout.max_forward, rtol=1e-6)
    env.close()


@pytest.mark.parametrize(
    ("realism", "knob"),
    [
        ({"level": 2, "dvl_sigma": float("nan")}, "dvl_sigma"),
        ({"level": 1, "fix_sigma": -0.1}, "fix_sigma"),
        ({"level": 1, "action_delay": 60.0}, "action_delay"),
        ({"level": 1, "sonar_latency": 25.0}, "sonar_latency"),
        ({"level": 1, "warp_drive": 1}, "warp_drive"),
        ({"level": 7}, "level"),
        (
            {
                "layout": {
                    "positions": [[0.3, 0.2, 0.0]] * 8,
                    "directions": [[1.0, 0.0, 0.0]] * 8,
                    "max_forward": 100.0,
                    "max_reverse": 80.0,
                }
            },
            "layout",
        ),
    ],
)
def test_bad_knobs_name_the_knob_through_make_and_env_kwargs(realism, knob):
    with pytest.raises(ValueError, match=knob) as exc:
        gym.make(CIRCLE, realism=realism)
    assert "\n" not in str(exc.value)
    if "layout" not in realism and not any(isinstance(v, float) and math.isnan(v) for v in realism.values()):
        text = "{" + ", ".join(f"{k}: {v}" for k, v in realism.items()) + "}"
        kwargs = parse_kv([f"realism={text}"])
        with pytest.raises(ValueError, match=knob):
            gym.make(CIRCLE, **kwargs)


def test_measured_kinematics_places_frames_as_pinocchio():
    model = KinematicModel()
    fast = MeasuredKinematics(model)
    rng = np.random.default_rng(3)
    for _ in range(50):
        eta = np.r_[rng.uniform(-5.0, 5.0, 3), rng.uniform(-math.pi, math.pi, 3)]
        q = rng.uniform(-math.pi, math.pi, 12)
        model.set_state(eta, q)
        fast.set_state(eta, q)
        for name in ("vehicle", "left_ee", "right_ee", "left_grasp", "right_grasp", "left_link3", "right_link6"):
            for a, b in zip(model.frame_placement(name), fast.frame_placement(name), strict=True):
                np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
        np.testing.assert_allclose(fast.link_segments(), model.link_segments(), rtol=0, atol=1e-12)
        np.testing.assert_allclose(fast.ee_positions(), model.ee_positions(), rtol=0, atol=1e-12)
        np.testing.assert_allclose(fast.clearances(), compute_distances(model, "exact").d, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="eta must be finite"):
        fast.set_state(np.full(6, np.nan), np.zeros(12))


def test_compiled_assembly_equals_assemble():
    u = gym.make(CIRCLE, realism=3).unwrapped
    rng = np.random.default_rng(5)
    for _ in range(2000):
        scale = rng.choice([0.1, 1.0, 30.0])
        parts = [rng.normal(size=n) * scale for n in (18, 6, 6, 12, 12)] + [rng.uniform(-0.1, 0.5, 18)]
        fast = assemble_observation(*parts, u._nu_scale, u._qdot_scale)
        np.testing.assert_array_equal(fast, u._assemble(*parts))
    u.close()


@pytest.mark.parametrize("env_id", V1_IDS)
def test_observe_estimate_equals_its_pinocchio_path(env_id, monkeypatch):
    """The compiled placements and assembly give the observation of a KinematicModel and ``_assemble``."""
    env = gym.make(env_id, realism=3)
    env.reset(seed=SEED)
    for a in _smooth_actions(10):
        env.step(a)
    u = env.unwrapped
    truth = u.true_state()
    state = (truth["eta"], truth["nu"], truth["q"], truth["qdot"], truth.get("obstacles"))
    fast, fast_keys = u.observe_estimate(*state)
    assert type(u._measured_kin) is MeasuredKinematics
    monkeypatch.setattr(MeasuredKinematics, "supports", staticmethod(lambda kin: False))
    u._measured_kin = KinematicModel(u.params)
    slow, slow_keys = u.observe_estimate(*state)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-6)
    for key in ("y", "distances"):
        np.testing.assert_allclose(fast_keys[key], slow_keys[key], rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast_keys["distances"], truth["distances"], rtol=0, atol=1e-12)
    if env_id == CIRCLE:  # the tracked output is kinematic: the truth's observation itself
        np.testing.assert_allclose(fast, u._observe()[0], rtol=0, atol=1e-6)
    env.close()


def test_compiled_probe_rows_equal_vehicle_row():
    rng = np.random.default_rng(6)
    quats = rng.normal(size=(200, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    probes = [tuple(rng.normal(size=3)) + tuple(qt) + tuple(rng.normal(size=6)) for qt in quats.tolist()]
    eta, nu = rng.normal(size=6), rng.normal(size=6)
    table = np.empty((len(probes) + 1, 12))
    _vehicle_table(np.array(probes), eta, nu, table)
    expected = [vehicle_row(p[:3], p[3:7], p[7:]) for p in probes] + [[*eta, *nu]]
    np.testing.assert_array_equal(table, expected)
