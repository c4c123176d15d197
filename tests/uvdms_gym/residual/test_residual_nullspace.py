"""The null-space residual of ``residual_space="nullspace"`` (uvdms_gym.residual.NullspaceProjection).

* The projection is ``I - J^+ J`` of the end-effector position Jacobian per unit of normalised action: checked
  against an independent Jacobian (central finite differences of the hand positions along each action axis,
  pin.integrate) and against the defining properties (symmetric, idempotent, ``J P = 0``), and a projected command
  moves the hands by second order only: after a small step along it, the hands move far less than along the
  unprojected command.
* On the same episode the training wrapper and the evaluation controller send the same actions, bit for bit.
* ``uvdms train --residual-space nullspace`` records the option in the run and the export, evaluation composes the
  same projection from the export alone, ``--resume`` refuses to change it, old records read as ``"full"``, and bad
  values are refused with clear errors.
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pinocchio as pin
import pytest
import yaml
from test_residual_clearance import ACTION_DIM, CIRCLE, OBS_DIM, SCALE, SEED, TINY, LinearPolicy, _mpc_states

from agents.training.train import run_dir_for
from baselines.controllers import make_baseline
from leaderboard.suite.registry import BaselineFactory, make_controller
from uvdms_cli.main import main as uvdms
from uvdms_gym.evaluation import run_episode
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.residual import (
    RESIDUAL_SPACES,
    ActionComposition,
    NullspaceProjection,
    ResidualAction,
    ResidualController,
)


@pytest.fixture(scope="module")
def states() -> list[tuple[np.ndarray, dict]]:
    return _mpc_states(60)


@pytest.fixture(scope="module")
def projection() -> NullspaceProjection:
    env = gym.make(CIRCLE)
    try:
        return NullspaceProjection.for_env(env)
    finally:
        env.close()


def _hands(kin: KinematicModel, config: np.ndarray) -> np.ndarray:
    kin.set_configuration(config)
    return np.concatenate(kin.ee_positions())


def _position_jacobian_fd(kin: KinematicModel, info: dict, zeta_max: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """d(hand positions)/d(normalised action) (6, 18) by central differences along each action axis."""
    q0 = KinematicModel.configuration(np.asarray(info["eta"]), np.asarray(info["q"]))
    cols = []
    for j in range(18):
        v = np.zeros(18)
        v[j] = zeta_max[j] * h
        plus = _hands(kin, pin.integrate(kin.model, q0, v))
        minus = _hands(kin, pin.integrate(kin.model, q0, -v))
        cols.append((plus - minus) / (2 * h))
    return np.stack(cols, axis=1)


def test_projection_is_the_null_space_of_an_independent_hand_jacobian(states, projection):
    kin = KinematicModel()
    for _, info in states[::15]:
        p = projection.matrix(info)
        jac = _position_jacobian_fd(kin, info, projection.zeta_max)
        np.testing.assert_allclose(jac @ p, 0.0, atol=1e-6)
        np.testing.assert_allclose(p, p.T, atol=1e-12)
        np.testing.assert_allclose(p @ p, p, atol=1e-12)
        assert np.linalg.matrix_rank(p, tol=1e-9) == 18 - 6  # both hands: 6 constrained directions
        reference = np.eye(18) - np.linalg.pinv(jac) @ jac
        np.testing.assert_allclose(p, reference, atol=1e-6)


def test_a_projected_command_leaves_the_hands_in_place_to_first_order(states, projection):
    kin = KinematicModel()
    rng = np.random.default_rng(0)
    for _, info in states[::20]:
        q0 = KinematicModel.configuration(np.asarray(info["eta"]), np.asarray(info["q"]))
        start = _hands(kin, q0)
        u = rng.uniform(-0.5, 0.5, 18)
        dt = 0.04
        moved = _hands(kin, pin.integrate(kin.model, q0, u * projection.zeta_max * dt)) - start
        projected, clipped = projection(info, u)
        assert not clipped  # entries of P u stay within [-1, 1] for this small u
        kept = _hands(kin, pin.integrate(kin.model, q0, projected * projection.zeta_max * dt)) - start
        assert np.linalg.norm(kept) < 0.05 * np.linalg.norm(moved)


def test_a_clipped_projection_is_reported(states, projection, monkeypatch):
    info = states[0][1]
    monkeypatch.setattr(projection, "matrix", lambda _info: 2.0 * np.eye(18))
    out, clipped = projection(info, np.full(18, 0.75))
    assert clipped and np.all(out == 1.0)
    out, clipped = projection(info, np.full(18, 0.25))
    assert not clipped and np.all(out == 0.5)


def test_training_and_evaluation_send_the_same_projected_actions():
    steps = 60
    train_env = ResidualAction(
        gym.make(CIRCLE, case=1, max_episode_steps=steps), BaselineFactory("mpc"), SCALE, space="nullspace"
    )
    policy = LinearPolicy(n_inputs=OBS_DIM + ACTION_DIM)
    sent_train = []
    obs, _ = train_env.reset(seed=SEED)
    while True:
        obs, _, terminated, truncated, info = train_env.step(policy.predict(obs))
        sent_train.append(info["residual_action"])
        base = info["residual_base_action"]
        if terminated or truncated:
            break
    train_env.close()
    eval_env = gym.make(CIRCLE, case=1, max_episode_steps=steps)
    controller = ResidualController(
        make_baseline("mpc", eval_env), policy, SCALE, projection=NullspaceProjection.for_env(eval_env)
    )
    sent_eval = []
    obs, info = eval_env.reset(seed=SEED)
    controller.reset(SEED)
    for _ in range(len(sent_train)):
        action = controller.predict(obs, info)
        sent_eval.append(action)
        obs, _, terminated, truncated, info = eval_env.step(action)
        if terminated or truncated:
            break
    eval_env.close()
    assert len(sent_eval) == len(sent_train) > 30
    for k, (a_train, a_eval) in enumerate(zip(sent_train, sent_eval, strict=True)):
        np.testing.assert_array_equal(a_train, a_eval, err_msg=f"step {k}")
    assert np.any(np.abs(sent_train[-1] - base) > 0)  # the residual did act


def test_composition_records_the_space_and_old_records_read_as_full():
    composition = ActionComposition("mpc", SCALE, residual_space="nullspace")
    assert ActionComposition.from_record(composition.to_record()) == composition
    assert ActionComposition.from_record({"residual_base": "mpc", "residual_scale": SCALE}).residual_space == "full"
    with pytest.raises(ValueError, match="residual_space must be one of"):
        ActionComposition("mpc", SCALE, residual_space="task")
    with pytest.raises(ValueError, match="no residual_base"):
        ActionComposition(residual_space="nullspace")
    with pytest.raises(ValueError, match="needs a UVDMS environment"):
        NullspaceProjection.for_env(gym.make("Pendulum-v1"))
    with pytest.raises(ValueError, match="residual_space must be one of"):
        ResidualAction(gym.make(CIRCLE), BaselineFactory("mpc"), SCALE, space="task")


def test_space_choices_of_the_light_parser_match_the_composition():
    from agents.training.args import RESIDUAL_SPACE_NAMES

    assert RESIDUAL_SPACE_NAMES == RESIDUAL_SPACES


def test_uvdms_train_records_it_and_evaluation_composes_it_from_the_export(tmp_path, capsys):
    argv = ["train", "--algo", "sac", "--env", CIRCLE, "--env-kwargs", "case=1", "max_episode_steps=20"]
    argv += ["--residual", "mpc", "--residual-scale", str(SCALE), "--residual-space", "nullspace"]
    argv += ["--total-timesteps", "60", "--hyperparams", *TINY, "--n-envs", "1", "--out", str(tmp_path / "runs")]
    assert uvdms([*argv, "--no-progress"]) == 0, capsys.readouterr().err
    run_dir = run_dir_for(tmp_path / "runs", CIRCLE, "sac", 0)
    assert yaml.safe_load((run_dir / "config.yml").read_text())["config"]["residual_space"] == "nullspace"
    assert "--residual-space nullspace" in json.loads((run_dir / "meta.json").read_text())["segments"][0]["command"]
    export = tmp_path / "export"
    assert uvdms(["export-agent", str(run_dir), str(export), "--trust"]) == 0
    assert json.loads((export / "agent.json").read_text())["residual_space"] == "nullspace"
    env = gym.make(CIRCLE, case=1, max_episode_steps=5)
    try:
        controller = make_controller(str(export), env)
        assert isinstance(controller, ResidualController) and isinstance(controller.projection, NullspaceProjection)
        assert run_episode(env, controller, SEED)["steps"] == 5
    finally:
        env.close()
    capsys.readouterr()
    changed = ["train", "--resume", str(run_dir), "--residual-space", "full", "--total-timesteps", "10"]
    assert uvdms([*changed, "--no-progress"]) == 2
    assert "residual_space cannot change" in capsys.readouterr().err
    bad = ["train", "--algo", "sac", "--env", CIRCLE, "--residual", "mpc", "--residual-scale", str(SCALE)]
    with pytest.raises(SystemExit):  # argparse names the choices
        uvdms([*bad, "--residual-space", "task"])
    assert "invalid choice: 'task'" in capsys.readouterr().err
