import hashlib
import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import uvdms_gym

IDS = uvdms_gym.ENV_IDS
MODES = ("velocity", "torque")


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("mode", MODES)
def test_env_checkers_pass(env_id, mode):
    env = gym.make(env_id, action_mode=mode)
    try:
        gym_check_env(env.unwrapped, skip_render_check=True)
        sb3_check_env(env, warn=True)
    finally:
        env.close()


def _rollout_digest(env_id: str, seed: int, n: int = 300, **kwargs) -> str:
    env = gym.make(env_id, terminate_on_contact=False, **kwargs)
    rng = np.random.default_rng(seed)
    h = hashlib.sha256()
    obs, info = env.reset(seed=seed)
    h.update(obs.tobytes())
    for _ in range(n):
        a = rng.uniform(-0.5, 0.5, env.action_space.shape).astype(np.float32)
        obs, r, term, trunc, info = env.step(a)
        h.update(obs.tobytes())
        h.update(np.float64(r).tobytes())
        for key in sorted(info):
            v = info[key]
            if isinstance(v, (np.ndarray, float, int, bool, np.floating)):
                h.update(key.encode())
                h.update(np.asarray(v, dtype=float).tobytes())
        if term or trunc:
            obs, info = env.reset()
    env.close()
    return h.hexdigest()


@pytest.mark.slow
@pytest.mark.portability
@pytest.mark.parametrize("env_id", IDS)
def test_same_seed_same_trajectory_in_process_and_across_processes(env_id):
    kwargs = {"case": "random", "hydro_randomization": 0.3} if "Circle" in env_id else {"goal": "random"}
    a = _rollout_digest(env_id, 3, **kwargs)
    b = _rollout_digest(env_id, 3, **kwargs)
    assert a == b
    code = (
        f"import sys; sys.path.insert(0, {os.getcwd()!r}); from tests.uvdms_gym.envs.test_envs import _rollout_digest; "
        f"print(_rollout_digest({env_id!r}, 3, **{kwargs!r}))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=os.getcwd())
    assert out.stdout.strip().splitlines()[-1] == a
    assert _rollout_digest(env_id, 4, n=30, **kwargs) != _rollout_digest(env_id, 3, n=30, **kwargs)


@pytest.mark.parametrize("env_id", IDS)
def test_reward_is_sum_of_terms_and_cost_is_sum_of_costs(env_id):
    env = gym.make(env_id, terminate_on_contact=False)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(60):
        _, r, term, trunc, info = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        terms = {k: v for k, v in info.items() if k.startswith("reward_")}
        assert set(terms) >= {"reward_track", "reward_effort", "reward_proximity", "reward_contact"}
        assert r == pytest.approx(sum(terms.values()), abs=1e-12)
        assert info["cost"] == sum(v for k, v in info.items() if k.startswith("cost_"))
        assert {"cost_contact", "cost_zone"} <= set(info)
        assert info["min_distance"] == pytest.approx(info["distances"].min())
        assert info["y"].shape == (6,) and info["y_ref"].shape == (6,)
        assert np.allclose(info["y_ref"], env.unwrapped.reference(info["t"]))
        if term or trunc:
            break
    env.close()


def test_driving_a_link_into_the_bottom_frame_costs_and_terminates():
    env = gym.make("uvdms/CircleTrack-v0", terminate_on_contact=True)
    env.reset(seed=0)
    a = np.zeros(18, np.float32)
    a[6 + 6 + 1] = 1.0  # right shoulder pitch at full speed: swings the right arm down into the bottom plate
    saw_contact = False
    for _ in range(200):
        _, _, term, _, info = env.step(a)
        if info["cost_contact"] > 0:
            saw_contact = True
            assert term
            break
        assert not term
    env.close()
    assert saw_contact


@pytest.mark.parametrize("env_id", IDS)
def test_bad_actions_and_kwargs_raise_named_errors(env_id):
    env = gym.make(env_id)
    env.reset(seed=0)
    dim = env.action_space.shape[0]
    a = np.zeros(dim, np.float32)
    a[4] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        env.step(a)
    a[4] = np.inf
    with pytest.raises(ValueError, match="inf"):
        env.step(a)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(dim - 1, np.float32))
    _, _, _, _, info = env.step(np.full(dim, 2.0, np.float32))
    assert info["action_clipped"] is True
    env.close()
    with pytest.raises(TypeError, match="bogus_kwarg"):
        gym.make(env_id, bogus_kwarg=1)
    with pytest.raises(ValueError, match="action_mode"):
        gym.make(env_id, action_mode="jets")


def test_infeasible_circle_raises_at_construction():
    with pytest.raises(ValueError, match="radius"):
        gym.make("uvdms/CircleTrack-v0", radius=0.0)
    with pytest.raises(ValueError, match="reach"):
        gym.make("uvdms/CircleTrack-v0", right_center=(9.0, 0.3, 3.0))


def test_string_entry_point_works():
    env = gym.make("uvdms_gym:uvdms/Transport-v0")
    env.close()


def test_rgb_array_render():
    env = gym.make("uvdms/CircleTrack-v0", render_mode="rgb_array", render_width=160, render_height=120)
    env.reset(seed=0)
    img = env.render()
    env.close()
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8
    assert img.std() > 5  # not a blank frame


def test_helpers_for_model_based_controllers():
    env = gym.make("uvdms/CircleTrack-v0")
    _, info = env.reset(seed=0)
    u = env.unwrapped
    grid = info["t"] + u.control_dt * np.arange(10)
    assert u.reference(grid).shape == (10, 6)
    kin = u.kinematic_model
    kin.set_state(info["eta"], info["q"])
    assert np.allclose(kin.ee_positions().reshape(6), info["y"], atol=1e-9)
    from uvdms_gym.distances import compute_distances

    assert np.allclose(compute_distances(kin, "exact").d, info["distances"])
    env.close()


def _rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS"):
                return int(line.split()[1]) / 1024.0
    raise RuntimeError("no VmRSS")


@pytest.mark.slow
def test_make_step_close_cycles_do_not_leak():
    ids = []
    for k in range(20):  # warm-up (caches, allocator)
        env = gym.make(IDS[k % 2])
        env.reset(seed=k)
        env.step(env.action_space.sample())
        env.close()
    before = _rss_mb()
    for k in range(300):
        env = gym.make(IDS[k % 2])
        env.reset(seed=k)
        env.step(np.zeros(18, np.float32))
        ids.append(env.unwrapped._sim.client._client)
        env.close()
        env.close()  # idempotent
    assert _rss_mb() - before < 50.0
    assert not any(p.isConnected(physicsClientId=c) for c in set(ids))


def test_velocity_loop_inverse_diagonal_matches_numpy_inverse():
    """The loop's compiled diag(M^-1) equals np.linalg.inv's diagonal to rounding; non-SPD input is refused."""
    from uvdms_gym.envs.lowlevel import _inverse_diagonal

    rng = np.random.default_rng(11)
    env = gym.make("uvdms/CircleTrack-v0")
    env.reset(seed=0)
    mats = [env.unwrapped._nominal.mass_matrix()]
    env.close()
    for n in (1, 5, 18):
        a = rng.normal(size=(n, n))
        mats.append(a @ a.T + 1e-2 * np.eye(n))
    for m in mats:
        out = np.empty(m.shape[0])
        assert _inverse_diagonal(m, out)
        np.testing.assert_allclose(out, np.linalg.inv(m).diagonal(), rtol=1e-11, atol=0.0)
    indefinite = np.diag([1.0, -1.0, 2.0])
    assert not _inverse_diagonal(indefinite, np.empty(3))
    assert not _inverse_diagonal(np.full((2, 2), np.nan), np.empty(2))


def test_transport_orientation_errors_match_frames_rot_error():
    """errors_pose's float-arithmetic rotation errors equal frames.rot_error of the Euler references."""
    from uvdms_gym.envs.tracking import POS_SCALE, errors_pose
    from uvdms_gym.physics.frames import euler_to_rot, rot_error

    rng = np.random.default_rng(3)
    for k in range(200):
        r = euler_to_rot(rng.uniform(-1.5, 1.5, 3))
        r_nb = euler_to_rot(rng.uniform(-1.5, 1.5, 3))
        refs = np.c_[rng.normal(size=(3, 3)), rng.uniform(-1.5, 1.5, (3, 3))]
        if k % 4 == 1:  # a reference equal to the current orientation (zero error: the delegated branch)
            refs[0, 3:] = [np.arctan2(r[2, 1], r[2, 2]), -np.arcsin(r[2, 0]), np.arctan2(r[1, 0], r[0, 0])]
        p = rng.normal(size=3)
        blk, pos_err, ori_err = errors_pose(p, r, refs, r_nb)
        e_o = np.array([rot_error(euler_to_rot(ref[3:]), r) for ref in refs])
        e_p = refs[:, :3] - p
        expected = np.concatenate([e_p @ r_nb / POS_SCALE, e_o @ r_nb], axis=1).reshape(-1)
        # at zero error the angle is acos of a trace ~1: rounding of order 1e-16 there moves it by ~1e-8 in
        # either implementation (sqrt conditioning), elsewhere the two agree to rounding
        tol = 1e-7 if k % 4 == 1 else 1e-12
        np.testing.assert_allclose(blk, expected, rtol=0.0, atol=tol)
        assert pos_err == pytest.approx(np.linalg.norm(e_p[0]), abs=1e-14)
        assert ori_err == pytest.approx(np.linalg.norm(e_o[0]), abs=tol)
