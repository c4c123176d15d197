"""Loading and the weights-only export: identical actions, trust, no pickles, the commands (agents.export)."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from agents.algos import ALGOS
from agents.config import ConfigError, parse_entry
from agents.export import (
    UntrustedFileError,
    export_agent,
    load_agent,
    load_sb3_zip,
    load_weights_only,
)
from agents.export import sb3 as agent_sb3
from agents.export import weights as agent_weights
from agents.training.train import (
    ScaledAction,
    run_dir_for,
    train,
    zip_num_timesteps,
)
from tests.support.agent_runs import REPO, RUNS, TEST_ENVS, sample_observations


@pytest.mark.parametrize(("algo", "env_id"), RUNS)
def test_round_trip_gives_identical_actions(runs, tmp_path, algo, env_id):
    run_dir = runs[algo, env_id]
    env_kwargs = dict(TEST_ENVS)[env_id]
    observations = sample_observations(env_id, env_kwargs)

    # Reference: the SB3 model and VecNormalize exactly as SB3 loads them.
    model = ALGOS[algo].load(run_dir / "final_model.zip", device="cpu")
    vec_normalize = None
    if (run_dir / "vecnormalize.pkl").is_file():
        vec_normalize = VecNormalize.load(
            str(run_dir / "vecnormalize.pkl"), DummyVecEnv([lambda: gym.make(env_id, **env_kwargs)])
        )
    expected = []
    for obs in observations:
        net_obs = vec_normalize.normalize_obs(obs) if vec_normalize is not None else obs
        expected.append(model.predict(net_obs, deterministic=True)[0])

    agent = load_agent(run_dir, trust=True)
    exported = load_weights_only(export_agent(run_dir, tmp_path / "export", trust=True))
    for controller in (agent, exported):
        assert controller.algo == algo and controller.env_id == env_id
        assert (controller.normalizer is not None) == (vec_normalize is not None)
        controller.reset(seed=0)
        for obs, action in zip(observations, expected):
            np.testing.assert_array_equal(controller.predict(obs, {}), action)
            assert controller.action_space.contains(controller.predict(obs, {}).astype(np.float32))
    assert exported.num_timesteps == agent.num_timesteps == model.num_timesteps
    assert exported.env_kwargs == env_kwargs
    if vec_normalize is not None:
        # The statistics are really applied: the network input differs from the raw observation.
        obs = observations[0]
        np.testing.assert_array_equal(agent.normalize(obs), vec_normalize.normalize_obs(obs))
        np.testing.assert_array_equal(exported.normalize(obs), vec_normalize.normalize_obs(obs))
        assert not np.allclose(agent.normalize(obs), obs)

    best = load_agent(run_dir, which="best", trust=True)
    best_model = ALGOS[algo].load(run_dir / "best_model.zip", device="cpu")
    obs = observations[0]
    net_obs = obs
    if (run_dir / "best_vecnormalize.pkl").is_file():
        net_obs = VecNormalize.load(
            str(run_dir / "best_vecnormalize.pkl"), DummyVecEnv([lambda: gym.make(env_id, **env_kwargs)])
        ).normalize_obs(obs)
    np.testing.assert_array_equal(best.predict(obs, {}), best_model.predict(net_obs, deterministic=True)[0])


def test_loading_pickles_requires_trust(runs, monkeypatch):
    run_dir = runs["sac", TEST_ENVS[0][0]]
    with pytest.raises(UntrustedFileError, match="trust=True"):
        load_agent(run_dir)
    with pytest.raises(UntrustedFileError):
        load_sb3_zip(run_dir / "final_model.zip", trust=False)
    with pytest.raises(UntrustedFileError):
        export_agent(run_dir, run_dir.parent / "export_untrusted")
    assert load_sb3_zip(run_dir / "final_model.zip", trust=True).num_timesteps > 0
    # Files inside the repository's trained_agents/ folder are trusted without the flag.
    monkeypatch.setattr(agent_sb3, "TRUSTED_DIR", run_dir.parent)
    assert load_agent(run_dir).algo == "sac"


def test_weights_only_export_contains_no_pickle(runs, tmp_path):
    run_dir = runs["ppo", TEST_ENVS[0][0]]
    export = export_agent(run_dir, tmp_path / "export", trust=True)
    # the policy's three files, and the run's record (plain JSON, not read to rebuild the policy)
    assert sorted(p.name for p in export.iterdir()) == ["agent.json", "meta.json", "normalization.npz", "policy.pt"]
    assert json.loads((export / "meta.json").read_text()) == json.loads((run_dir / "meta.json").read_text())

    def _no_constants(name):
        raise ValueError(name)

    doc = json.loads((export / "agent.json").read_text(), parse_constant=_no_constants)  # strict JSON
    assert doc["algo"] == "ppo" and doc["policy"] == "MlpPolicy"
    assert doc["policy_kwargs"]["activation_fn"] == "tanh"
    assert doc["policy_kwargs"]["net_arch"] == {"pi": [16], "vf": [16]}
    assert doc["observation_space"]["shape"] == list(gym.make(TEST_ENVS[0][0]).observation_space.shape)
    state = torch.load(export / "policy.pt", weights_only=True)
    assert all(isinstance(v, torch.Tensor) for v in state.values())
    with np.load(export / "normalization.npz", allow_pickle=False) as stats:
        assert set(stats.files) == {"obs_mean", "obs_var"}
    with pytest.raises(FileExistsError):
        export_agent(run_dir, export, trust=True)

    # Tampered weights: a pickled object that would create a file when unpickled.
    marker = tmp_path / "pwned"
    torch.save({**state, "payload": _Payload(str(marker))}, export / "policy.pt")
    with pytest.raises(agent_weights.ExportFormatError, match="SHA-256"):
        load_weights_only(export)
    doc["files"]["policy.pt"] = agent_weights._sha256(export / "policy.pt")  # an attacker fixes the hash
    (export / "agent.json").write_text(json.dumps(doc))
    with pytest.raises(pickle.UnpicklingError):
        load_weights_only(export)
    assert not marker.exists()

    # Unknown class names in the JSON are refused too.
    torch.save(state, export / "policy.pt")
    doc["files"]["policy.pt"] = agent_weights._sha256(export / "policy.pt")
    doc["policy_kwargs"]["activation_fn"] = "os.system"
    (export / "agent.json").write_text(json.dumps(doc))
    with pytest.raises(agent_weights.ExportFormatError, match="activation_fn"):
        load_weights_only(export)


class _Payload:
    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):
        return (Path.touch, (Path(self.path),))


def test_uvdms_train_and_export_agent_commands(tmp_path, config_dir, capsys):
    from uvdms_cli.main import main as uvdms_main

    with pytest.raises(SystemExit) as info:
        uvdms_main(["train", "--help"])
    assert info.value.code == 0
    assert "--total-timesteps" in capsys.readouterr().out
    argv = ["train", "--algo", "ppo", "--env", "uvdms/CircleTrack-v0", "--env-kwargs", "case=2"]
    argv += ["max_episode_steps=40", "--config", str(config_dir / "ppo.yml"), "--seed", "3"]
    argv += ["--total-timesteps", "128", "--out", str(tmp_path / "runs"), "--no-progress"]
    assert uvdms_main(argv) == 0
    run_dir = run_dir_for(tmp_path / "runs", "uvdms/CircleTrack-v0", "ppo", 3)
    assert capsys.readouterr().out.strip() == str(run_dir)
    assert yaml.safe_load((run_dir / "config.yml").read_text())["config"]["env_kwargs"] == {
        "case": 2,
        "max_episode_steps": 40,
    }
    before = zip_num_timesteps(run_dir / "final_model.zip")
    assert uvdms_main(["train", "--resume", str(run_dir), "--total-timesteps", "128", "--no-progress"]) == 0
    assert zip_num_timesteps(run_dir / "final_model.zip") >= before + 128
    capsys.readouterr()
    with pytest.raises(SystemExit):
        uvdms_main(["train", "--env", "uvdms/CircleTrack-v0"])  # --algo missing
    capsys.readouterr()

    assert uvdms_main(["export-agent", str(run_dir), str(tmp_path / "exp")]) == 2  # untrusted pickles
    assert "trust" in capsys.readouterr().err
    assert uvdms_main(["export-agent", str(run_dir), str(tmp_path / "exp"), "--which", "final", "--trust"]) == 0
    exported = load_weights_only(tmp_path / "exp")
    best = load_agent(run_dir, which="final", trust=True)
    obs = sample_observations("uvdms/CircleTrack-v0", {"case": 2}, n=3)
    for o in obs:
        np.testing.assert_array_equal(exported.predict(o), best.predict(o))


class _RecordActions(gym.Wrapper):
    """Records the actions that reach the wrapped environment."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.seen: list[np.ndarray] = []

    def step(self, action):
        self.seen.append(np.array(action))
        return self.env.step(action)


def test_action_scale_in_training_evaluation_and_export(tmp_path, config_dir):
    """``action_scale`` scales what the env sees in training, at evaluation and after a weights-only export."""
    recorder = _RecordActions(gym.make("Pendulum-v1"))
    wrapped = ScaledAction(recorder, 0.25)
    wrapped.reset(seed=0)
    wrapped.step(np.array([2.0], np.float32))
    assert recorder.seen[0] == pytest.approx([0.5]) and wrapped.action_space == recorder.action_space

    run_dir = train(
        "sac",
        "Pendulum-v1",
        {"max_episode_steps": 50},
        config_dir / "sac.yml",
        seed=2,
        out_dir=tmp_path,
        progress=False,
        total_timesteps=64,
        hyperparams={"eval_freq": 0, "checkpoint_freq": 0, "learning_starts": 10, "action_scale": 0.25},
    )
    assert yaml.safe_load((run_dir / "config.yml").read_text())["config"]["action_scale"] == 0.25
    model = ALGOS["sac"].load(run_dir / "final_model.zip")
    agent = load_agent(run_dir, trust=True)
    exported = load_weights_only(export_agent(run_dir, tmp_path / "export", trust=True))
    for obs in sample_observations("Pendulum-v1", {}):
        raw, _ = model.predict(agent.normalize(obs), deterministic=True)
        assert np.abs(raw).max() > 0
        np.testing.assert_allclose(agent.predict(obs), 0.25 * raw, rtol=1e-6)
        np.testing.assert_allclose(exported.predict(obs), 0.25 * raw, rtol=1e-6)
    doc_path = tmp_path / "export" / "agent.json"
    doc = json.loads(doc_path.read_text())
    doc_path.write_text(json.dumps({**doc, "action_scale": 2.0}))
    with pytest.raises(agent_weights.ExportFormatError, match="action_scale"):
        load_weights_only(tmp_path / "export")
    for bad in (0.0, 1.5):
        with pytest.raises(ConfigError, match="'action_scale'"):
            parse_entry({"n_timesteps": 10, "action_scale": bad}, "sac")


def test_agent_on_another_env_id_warns():
    """An agent evaluated on an env id other than its training env's gets a warning naming both ids."""
    import warnings

    from agents.export import EnvMismatchWarning, check_agent
    from leaderboard.running.evaluate import evaluate

    folder = REPO / "trained_agents" / "ppo-circle-case1-v0"
    agent = load_agent(folder)
    assert agent.env_id == "uvdms/CircleTrack-v0"
    message = r"trained on uvdms/CircleTrack-v0 but runs on uvdms/Transport-v0"
    env = gym.make("uvdms/Transport-v0")
    with pytest.warns(EnvMismatchWarning, match=message):
        check_agent(agent, env, "ppo-circle-case1-v0")
    env.close()
    env = gym.make("uvdms/CircleTrack-v0", case=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error", EnvMismatchWarning)
        check_agent(agent, env, "ppo-circle-case1-v0")  # same id, another task: fine
    env.close()
    with pytest.warns(EnvMismatchWarning, match=message):  # what `uvdms evaluate` runs
        evaluate(str(folder), "uvdms/Transport-v0", {"max_episode_steps": 3}, episodes=1, progress=False)
