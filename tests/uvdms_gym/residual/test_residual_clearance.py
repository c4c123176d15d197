"""The clearance features of ``residual_observation="clearance"`` (uvdms_gym.residual.ClearanceFeatures).

* The 36 features equal an independent computation from the numpy reference distances and ``J_dis``; the rates
  equal central finite differences of the clearances along the base's command (pin.integrate); the direction
  satisfies its defining identity (its weighted, normalised clearance rates sum to its squared norm) and is zero
  when every clearance is beyond ``d2``.
* On the same episode the training wrapper and the evaluation controller give the policy the same observation,
  bit for bit; the observation lies in the declared space.
* ``uvdms train --residual-observation clearance`` records the option in the run and the export, evaluation
  composes the same observation from the export alone, ``--resume`` refuses to change it, and bad values are
  refused with clear errors.
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pinocchio as pin
import pytest
import yaml

from agents.training.train import run_dir_for
from baselines.controllers import make_baseline
from leaderboard.suite.registry import BaselineFactory, make_controller
from uvdms_cli.main import main as uvdms
from uvdms_gym import distances as D
from uvdms_gym.evaluation import run_episode
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.params import D1, D2
from uvdms_gym.residual import (
    CLEARANCE_RATE_SCALE,
    FEATURE_CLIP,
    ActionComposition,
    ClearanceFeatures,
    ResidualAction,
    ResidualController,
    residual_observation_space,
)

CIRCLE = "uvdms/CircleTrack-v0"
OBS_DIM = 80
ACTION_DIM = 18
N_FEATURES = 36
SCALE = 0.2
SEED = 7


def _mpc_states(steps: int, case: int = 1) -> list[tuple[np.ndarray, dict]]:
    """``(a_base, info)`` along a plain-mpc episode (Case 1 drives the arms towards each other)."""
    env = gym.make(CIRCLE, case=case, max_episode_steps=steps)
    try:
        mpc = make_baseline("mpc", env)
        obs, info = env.reset(seed=SEED)
        mpc.reset(SEED)
        states = []
        for _ in range(steps):
            a = np.asarray(mpc.predict(obs, info))
            states.append((a, info))
            obs, _, terminated, truncated, info = env.step(a)
            if terminated or truncated:
                break
        return states
    finally:
        env.close()


@pytest.fixture(scope="module")
def states() -> list[tuple[np.ndarray, dict]]:
    return _mpc_states(90)


@pytest.fixture(scope="module")
def features() -> ClearanceFeatures:
    env = gym.make(CIRCLE)
    try:
        return ClearanceFeatures.for_env(env)
    finally:
        env.close()


def _reference(kin: KinematicModel, zeta_max: np.ndarray, info: dict, a: np.ndarray) -> np.ndarray:
    """The features by the formula of the docstring, from the numpy reference distances and J_dis."""
    kin.set_state(info["eta"], info["q"])
    res = D.compute_distances_reference(kin)
    jdis = D.distance_jacobian_reference(kin, res)
    g = np.stack([-jdis[i] * zeta_max for i in range(18)])  # d_dot_i per unit of normalised action
    direction = np.zeros(18)
    for i in range(18):
        s = np.sin(0.5 * np.pi * (res.d[i] - D1) / (D2 - D1)) ** 2 if D1 < res.d[i] < D2 else float(res.d[i] >= D2)
        if np.linalg.norm(g[i]) > 0:
            direction += (1.0 - s) * g[i] / np.linalg.norm(g[i])
    rate = np.array([g[i] @ a for i in range(18)]) / CLEARANCE_RATE_SCALE
    return np.clip(np.concatenate([direction, rate]), -FEATURE_CLIP, FEATURE_CLIP)


def test_features_equal_an_independent_computation(states, features):
    kin = KinematicModel()
    close = 0
    for a, info in states[::6]:
        got = features(info, a)
        assert got.shape == (N_FEATURES,) and got.dtype == np.float64
        np.testing.assert_allclose(got, _reference(kin, features.zeta_max, info, a), rtol=1e-9, atol=1e-9)
        close += bool(np.any(got[:18] != 0.0))
    assert close >= 2, "no state had a clearance below d2: the direction was not exercised"


def test_rates_are_finite_differences_of_the_clearances_along_the_base_command(states, features):
    kin = KinematicModel()
    eps = 1e-6
    checked = 0
    for a, info in states[::10]:
        rate = features(info, a)[18:] * CLEARANCE_RATE_SCALE
        zeta = a * features.zeta_max  # the commanded velocity [nu; qdot] (pinocchio's tangent order)
        kin.set_state(info["eta"], info["q"])
        config = kin.config.copy()
        d0 = D.compute_distances(kin).d
        kin.set_configuration(pin.integrate(kin.model, config, eps * zeta))
        d_plus = D.compute_distances(kin).d
        kin.set_configuration(pin.integrate(kin.model, config, -eps * zeta))
        d_minus = D.compute_distances(kin).d
        smooth = np.abs(d_plus - 2 * d0 + d_minus) < 1e-10  # rows whose closest-point pair does not switch
        fd = (d_plus - d_minus) / (2 * eps)
        np.testing.assert_allclose(rate[smooth], fd[smooth], atol=2e-6, rtol=1e-5)
        checked += int(smooth.sum())
    assert checked > 0.5 * 18 * len(states[::10])


def test_the_direction_is_defined_by_its_weighted_rates_and_vanishes_far_from_obstacles(states, features):
    for a, info in states[::6]:
        direction = features(info, a)[:18]
        if np.any(np.abs(direction) >= FEATURE_CLIP):
            continue  # (clipped: the identity holds before the clip only)
        features.kin.set_state(info["eta"], info["q"])
        res = D.compute_distances(features.kin)
        g = -D.distance_jacobian(features.kin, res) * features.zeta_max
        w = 1.0 - D.velocity_damper(res.d, D1, D2)
        norms = np.linalg.norm(g, axis=1)
        unit = np.where(norms[:, None] > 0, g / np.maximum(norms, 1e-300)[:, None], 0.0)
        # sum_i w_i (g_i / |g_i|) . direction = |direction|^2: moving along it opens the close clearances on average
        assert (w * (unit @ direction)).sum() == pytest.approx(direction @ direction, rel=1e-9, abs=1e-12)
    far = dict(states[0][1])  # the start of Case 1: every clearance is beyond d2
    assert min(far["distances"]) > D2
    np.testing.assert_array_equal(features(far, states[0][0])[:18], np.zeros(18))


class LinearPolicy:
    """A deterministic stand-in for a trained residual policy on ``[obs; a_base; features]``."""

    def __init__(self, seed: int = 0, n_inputs: int = OBS_DIM + ACTION_DIM + N_FEATURES) -> None:
        rng = np.random.default_rng(seed)
        self.w = rng.normal(0.0, 0.3, (ACTION_DIM, n_inputs)).astype(np.float32)
        self.seen: list[np.ndarray] = []

    def reset(self, seed: int | None = None) -> None:
        self.seen = []

    def predict(self, obs: np.ndarray, info: dict | None = None) -> np.ndarray:
        self.seen.append(obs.copy())
        return np.tanh(self.w @ obs).astype(np.float32)


def test_training_and_evaluation_give_the_policy_the_same_observation():
    steps = 90
    train_env = ResidualAction(
        gym.make(CIRCLE, case=1, max_episode_steps=steps), BaselineFactory("mpc"), SCALE, observation="clearance"
    )
    policy = LinearPolicy()
    assert train_env.observation_space.shape == (OBS_DIM + ACTION_DIM + N_FEATURES,)
    obs, _ = train_env.reset(seed=SEED)
    while True:
        assert train_env.observation_space.contains(obs)
        obs, _, terminated, truncated, _ = train_env.step(policy.predict(obs))
        if terminated or truncated:
            break
    train_seen = policy.seen
    train_env.close()

    eval_env = gym.make(CIRCLE, case=1, max_episode_steps=steps)
    controller = ResidualController(make_baseline("mpc", eval_env), policy, SCALE, ClearanceFeatures.for_env(eval_env))
    run_episode(eval_env, controller, SEED)
    eval_env.close()
    assert len(train_seen) == len(policy.seen) > 60
    for k, (o_train, o_eval) in enumerate(zip(train_seen, policy.seen, strict=True)):
        np.testing.assert_array_equal(o_train, o_eval, err_msg=f"step {k}")
    assert any(np.any(o[OBS_DIM + ACTION_DIM : OBS_DIM + ACTION_DIM + 18] != 0) for o in train_seen)


def test_composition_records_the_observation_and_old_records_read_as_base():
    composition = ActionComposition("mpc", SCALE, residual_observation="clearance")
    assert ActionComposition.from_record(composition.to_record()) == composition
    assert ActionComposition.from_record({"residual_base": "mpc", "residual_scale": SCALE}).residual_observation == (
        "base"
    )
    with pytest.raises(ValueError, match="residual_observation must be one of"):
        ActionComposition("mpc", SCALE, residual_observation="lidar")
    with pytest.raises(ValueError, match="no residual_base"):
        ActionComposition(residual_observation="clearance")
    obs_space = gym.spaces.Box(-1.0, 1.0, (OBS_DIM,), np.float32)
    act_space = gym.spaces.Box(-1.0, 1.0, (ACTION_DIM,), np.float32)
    space = residual_observation_space(obs_space, act_space, "clearance")
    assert space.shape == (OBS_DIM + ACTION_DIM + N_FEATURES,)
    assert np.all(space.high[-N_FEATURES:] == FEATURE_CLIP)
    with pytest.raises(ValueError, match="needs a UVDMS environment"):
        ClearanceFeatures.for_env(gym.make("Pendulum-v1"))


TINY = [
    "learning_starts=30",
    "batch_size=16",
    "eval_freq=0",
    "checkpoint_freq=0",
    "save_replay_buffer=false",
    "policy_kwargs={net_arch: [16]}",
]


def test_uvdms_train_records_it_and_evaluation_composes_it_from_the_export(tmp_path, capsys):
    argv = ["train", "--algo", "sac", "--env", CIRCLE, "--env-kwargs", "case=1", "max_episode_steps=20"]
    argv += ["--residual", "mpc", "--residual-scale", str(SCALE), "--residual-observation", "clearance"]
    argv += ["--total-timesteps", "60", "--hyperparams", *TINY, "--n-envs", "1", "--out", str(tmp_path / "runs")]
    assert uvdms([*argv, "--no-progress"]) == 0, capsys.readouterr().err
    run_dir = run_dir_for(tmp_path / "runs", CIRCLE, "sac", 0)
    config = yaml.safe_load((run_dir / "config.yml").read_text())["config"]
    assert config["residual_observation"] == "clearance"
    assert (
        "--residual-observation clearance" in json.loads((run_dir / "meta.json").read_text())["segments"][0]["command"]
    )
    export = tmp_path / "export"
    assert uvdms(["export-agent", str(run_dir), str(export), "--trust"]) == 0
    doc = json.loads((export / "agent.json").read_text())
    assert doc["residual_observation"] == "clearance"
    assert doc["observation_space"]["shape"] == [OBS_DIM + ACTION_DIM + N_FEATURES]
    env = gym.make(CIRCLE, case=1, max_episode_steps=5)
    try:
        controller = make_controller(str(export), env)
        assert isinstance(controller, ResidualController) and isinstance(controller.features, ClearanceFeatures)
        result = run_episode(env, controller, SEED)
        assert result["steps"] == 5
    finally:
        env.close()
    capsys.readouterr()
    changed = ["train", "--resume", str(run_dir), "--residual-observation", "base", "--total-timesteps", "10"]
    assert uvdms([*changed, "--no-progress"]) == 2
    assert "residual_observation cannot change" in capsys.readouterr().err
    bad = ["train", "--algo", "sac", "--env", CIRCLE, "--residual", "mpc", "--residual-scale", str(SCALE)]
    with pytest.raises(SystemExit):  # argparse names the choices
        uvdms([*bad, "--residual-observation", "lidar"])
    assert "invalid choice: 'lidar'" in capsys.readouterr().err
