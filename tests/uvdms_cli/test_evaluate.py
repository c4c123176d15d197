"""``uvdms_gym.evaluation`` and ``uvdms evaluate``: JSON schema, metric definitions, determinism, agents."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import uvdms_gym  # noqa: F401
from leaderboard.running.evaluate import evaluate
from leaderboard.suite.registry import make_controller
from uvdms_gym.evaluation import EPISODE_KEYS, TRAJECTORY_KEYS, run_episode

CIRCLE, TRANSPORT = "uvdms/CircleTrack-v0", "uvdms/Transport-v0"
SHORT = {"max_episode_steps": 40}  # gymnasium.make's own keyword: short episodes for the schema tests


class ZeroVelocity:
    """A dummy controller: command zero velocity (holds the vehicle and arms)."""

    def reset(self, seed=None):
        self.seeds = [*getattr(self, "seeds", []), seed]

    def predict(self, obs, info):
        return np.zeros(18, dtype=np.float32)


def _euler_to_rot(rpy):
    phi, th, psi = rpy
    rx = np.array([[1, 0, 0], [0, np.cos(phi), -np.sin(phi)], [0, np.sin(phi), np.cos(phi)]])
    ry = np.array([[np.cos(th), 0, np.sin(th)], [0, 1, 0], [-np.sin(th), 0, np.cos(th)]])
    rz = np.array([[np.cos(psi), -np.sin(psi), 0], [np.sin(psi), np.cos(psi), 0], [0, 0, 1]])
    return rz @ ry @ rx


@pytest.fixture(scope="module")
def circle_result(tmp_path_factory):
    out = tmp_path_factory.mktemp("eval") / "sub" / "campc.json"
    kwargs = {"case": 1, "terminate_on_contact": False}
    return evaluate(
        "campc", CIRCLE, kwargs, episodes=2, seed=5, out=str(out), save_trajectory=True, progress=False
    ), out


def test_result_schema_and_file(circle_result):
    result, out = circle_result
    on_disk = json.loads(out.read_text())
    assert on_disk == json.loads(json.dumps(result))  # written as returned, plain JSON
    assert not list(out.parent.glob("*.tmp"))  # atomic write leaves no temporary file
    assert set(result) == {"episodes", "summary", "meta"}
    eps = result["episodes"]
    assert [e["seed"] for e in eps] == [5, 6] and result["meta"]["seeds"] == [5, 6]
    for ep in eps:
        assert set(EPISODE_KEYS) <= set(ep)
        assert len(ep["min_distance_by_pair"]) == 18
        assert ep["min_distance"] == pytest.approx(min(ep["min_distance_by_pair"]))
        assert ep["rmse_ori"] is None and ep["final_ori_error"] is None  # circle tracking
        assert ep["steps"] == 500 and ep["truncated"] and not ep["terminated"]
        assert isinstance(ep["success"], bool) and ep["qp_slack_max"] is not None and ep["qp_unsolved"] == 0
        assert ep["controller_ms_median"] > 0
        traj = ep["trajectory"]
        assert set(traj) == set(TRAJECTORY_KEYS) and len(traj["t"]) == ep["steps"] + 1
        assert np.array(traj["distances"]).shape == (501, 18) and np.array(traj["tau"]).shape == (501, 18)
        assert traj["nn_output"] is None  # no dynamic inversion in velocity mode
    meta = result["meta"]
    assert meta["controller"] == "campc" and meta["env_id"] == CIRCLE
    assert meta["env_kwargs"] == {"case": 1, "terminate_on_contact": False, "action_mode": "velocity"}
    assert "numpy" in meta["versions"] and "revision" in meta["git"]
    summ = result["summary"]
    assert summ["episodes"] == 2
    assert summ["rmse_pos"] == pytest.approx(np.mean([e["rmse_pos"] for e in eps]))
    assert summ["success_rate"] == pytest.approx(np.mean([e["success"] for e in eps]))
    assert len(summ["min_distance_by_pair"]) == 18


def test_circle_metrics_recomputed_from_the_trajectory(circle_result):
    ep = circle_result[0]["episodes"][0]
    traj = ep["trajectory"]
    t, y, ref = np.array(traj["t"]), np.array(traj["y"]), np.array(traj["y_ref"])
    keep = t >= 5.0 - 1e-9
    sq = [np.sum((y[k, :3] - ref[k, :3]) ** 2) + np.sum((y[k, 3:] - ref[k, 3:]) ** 2) for k in np.flatnonzero(keep)]
    assert ep["rmse_pos"] == pytest.approx(math.sqrt(np.sum(sq) / (2 * len(sq))), rel=1e-9)
    d = np.array(traj["distances"])
    assert ep["min_distance_by_pair"] == pytest.approx(d.min(axis=0).tolist())
    last = y[-1] - ref[-1]
    assert ep["final_pos_error"] == pytest.approx(0.5 * (np.linalg.norm(last[:3]) + np.linalg.norm(last[3:])))
    assert ep["success"] == (ep["contacts"] == 0 and ep["rmse_pos"] <= 0.03)


def test_transport_metrics_recomputed_from_the_trajectory():
    env = gym.make(TRANSPORT, action_mode="velocity", **SHORT)
    try:
        ep = run_episode(env, make_controller("campc", env), seed=0, save_trajectory=True)
    finally:
        env.close()
    traj = ep["trajectory"]
    y, ref = np.array(traj["y"]), np.array(traj["y_ref"])
    assert ep["steps"] == 40 and len(traj["t"]) == 41
    pos = np.linalg.norm(y[:, :3] - ref[:, :3], axis=1)
    ang = []
    for a, b in zip(y[:, 3:], ref[:, 3:]):
        r = _euler_to_rot(b).T @ _euler_to_rot(a)
        ang.append(math.acos(min(1.0, max(-1.0, (np.trace(r) - 1.0) / 2.0))))
    assert ep["rmse_pos"] == pytest.approx(math.sqrt(np.mean(pos**2)), rel=1e-9)  # transient 0: all samples
    assert ep["rmse_ori"] == pytest.approx(math.sqrt(np.mean(np.square(ang))), rel=1e-6, abs=1e-9)
    assert ep["final_pos_error"] == pytest.approx(pos[-1], rel=1e-6)
    assert ep["final_ori_error"] == pytest.approx(ang[-1], abs=1e-6)
    assert not ep["success"]  # cut short by the time limit before the move ends: is_success is false


def test_same_seed_same_result():
    env = gym.make(CIRCLE, action_mode="torque", case="random", **SHORT)
    try:
        ctl = make_controller("campc-nndi", env)
        a = run_episode(env, ctl, seed=11, save_trajectory=True)
        b = run_episode(env, ctl, seed=11, save_trajectory=True)
        c = run_episode(env, ctl, seed=12)
    finally:
        env.close()
    for key in EPISODE_KEYS:
        if key != "controller_ms_median":
            assert a[key] == b[key], key
    assert a["trajectory"] == b["trajectory"]
    assert np.array(a["trajectory"]["nn_output"][1:]).shape == (40, 18)
    assert c["final_pos_error"] != a["final_pos_error"]  # another seed draws other circles


def test_dummy_controller_without_qp():
    env = gym.make(CIRCLE, **SHORT)
    try:
        ctl = ZeroVelocity()
        ep = run_episode(env, ctl, seed=2)
    finally:
        env.close()
    assert ctl.seeds == [2]
    assert ep["qp_slack_max"] is None and ep["qp_unsolved"] is None
    assert ep["steps"] == 40 and ep["truncated"]
    json.dumps(ep, allow_nan=False)  # JSON-serialisable, no NaN (all 40 samples lie inside the 5 s transient)
    assert ep["rmse_pos"] is None and not ep["success"]


def test_action_mode_mismatch_and_bad_arguments():
    with pytest.raises(ValueError, match="action_mode='torque'"):
        evaluate("campc-nndi", CIRCLE, {"action_mode": "velocity"}, episodes=1, progress=False)
    with pytest.raises(ValueError, match="neither a baseline"):
        evaluate("nope", CIRCLE, episodes=1, progress=False)
    with pytest.raises(ValueError, match="episodes"):
        evaluate("campc", CIRCLE, episodes=0, progress=False)


def test_baseline_mode_is_filled_in():
    result = evaluate("campc-di", TRANSPORT, SHORT, episodes=1, progress=False)
    assert result["meta"]["env_kwargs"]["action_mode"] == "torque"
    assert result["episodes"][0]["steps"] == 40


def test_cli_evaluate(tmp_path):
    out = tmp_path / "r.json"
    cmd = [sys.executable, "-m", "uvdms_cli", "evaluate", "--controller", "campc", "--env", CIRCLE]
    cmd += ["--env-kwargs", "case=2", "max_episode_steps=20", "--episodes", "2", "--seed", "3", "--out", str(out)]
    proc = subprocess.run([*cmd, "--no-progress"], capture_output=True, text=True, timeout=300, check=True)
    summary = json.loads(proc.stdout)
    data = json.loads(out.read_text())
    assert summary == data["summary"] and data["meta"]["seeds"] == [3, 4]
    assert data["meta"]["env_kwargs"]["case"] == 2
    base = [sys.executable, "-m", "uvdms_cli", "evaluate", "--controller", "campc", "--env", CIRCLE]
    bad = subprocess.run(
        [*base, "--env-kwargs", "action_mode=torque", "--no-progress"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert bad.returncode == 2 and "action_mode='velocity'" in bad.stderr


# ---------------------------------------------------------------------------------------------------- agents
TINY_PPO = {
    "n_timesteps": 128,
    "n_envs": 1,
    "eval_freq": 0,
    "checkpoint_freq": 0,
    "normalize": True,
    "n_steps": 64,
    "batch_size": 64,
    "n_epochs": 1,
    "policy_kwargs": {"net_arch": {"pi": [8], "vf": [8]}},
}


@pytest.fixture(scope="module")
def tiny_agent(tmp_path_factory) -> Path:
    from agents.training.train import train

    folder = tmp_path_factory.mktemp("agent")
    config = folder / "ppo.yml"
    config.write_text(yaml.safe_dump({"default": TINY_PPO}), encoding="utf-8")
    return train("ppo", CIRCLE, {"action_mode": "velocity"}, config, seed=0, out_dir=folder / "runs", progress=False)


def test_evaluate_a_trained_agent(tiny_agent, tmp_path):
    from agents.export import UntrustedFileError, export_agent

    with pytest.raises(UntrustedFileError):  # SB3 zips hold pickles: trust required outside trained_agents/
        evaluate(str(tiny_agent), CIRCLE, SHORT, episodes=1, progress=False)
    result = evaluate(str(tiny_agent), CIRCLE, SHORT, episodes=2, progress=False, trust=True)
    for ep in result["episodes"]:
        assert ep["qp_slack_max"] is None and ep["steps"] >= 1
    assert result["meta"]["env_kwargs"]["action_mode"] == "velocity"
    assert result["meta"]["controller_settings"]["algo"] == "ppo"
    export = export_agent(tiny_agent, tmp_path / "export", trust=True)  # weights only: loads without trust
    again = evaluate(str(export), CIRCLE, SHORT, episodes=2, progress=False)
    assert [e["return"] for e in again["episodes"]] == pytest.approx([e["return"] for e in result["episodes"]])
    with pytest.raises(ValueError, match="action_mode='velocity'"):
        evaluate(str(export), CIRCLE, {**SHORT, "action_mode": "torque"}, episodes=1, progress=False)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            "obstacles=[{shape: sphere, radius: -0.1, position: [3, 1, 29]}]",
            "obstacles[0]: obstacle radius must be > 0",
        ),
        ("obstacles=[{shape: sphere, radius: 0.1, position: [3, 1, 29], spin: 1}]", "unknown key(s) ['spin']"),
        ("current=[3, 0, 0]", "above the limit of 2.0 m/s"),
        ("current=[.nan, 0, 0]", "current"),
    ],
)
def test_cli_evaluate_names_bad_obstacles_and_currents_in_one_line(kwargs, message):
    cmd = [sys.executable, "-m", "uvdms_cli", "evaluate", "--controller", "campc", "--env"]
    cmd += ["uvdms/TransportObstacles-v1", "--env-kwargs", kwargs, "--no-progress"]
    bad = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2
    assert message in bad.stderr and len(bad.stderr.strip().splitlines()) == 1, bad.stderr
