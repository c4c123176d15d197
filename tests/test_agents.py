"""Tests of the agents package: configs, training runs, resume, loading and weights-only export.

The environments under test are listed in TEST_ENVS: two Gymnasium classics and the uvdms ids with short
episodes (``max_episode_steps`` is passed to ``gymnasium.make``), so every algorithm trains for a few
hundred steps on every env id.
"""

from __future__ import annotations

import json
import pickle
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from agents.algos import ALGOS
from agents.config import ConfigError, load_config, parse_entry, validate_config_file
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
    EnvironmentNotFoundError,
    RunDirError,
    ScaledAction,
    eval_env_seed,
    latest_checkpoint,
    main,
    parse_key_values,
    run_dir_for,
    train,
    train_env_seed,
    zip_num_timesteps,
)

REPO = Path(__file__).resolve().parents[1]

# (env id, gymnasium.make kwargs).
TEST_ENVS: list[tuple[str, dict]] = [
    ("Pendulum-v1", {"max_episode_steps": 100}),
    ("MountainCarContinuous-v0", {"max_episode_steps": 100}),
    ("uvdms/CircleTrack-v0", {"case": 1, "max_episode_steps": 60}),
    ("uvdms/Transport-v0", {"goal": "paper", "max_episode_steps": 60}),
]
ALGO_NAMES = sorted(ALGOS)
UVDMS_IDS = ("uvdms/CircleTrack-v0", "uvdms/Transport-v0")
COST_ALGOS = ("ppo_lagrangian",)  # need info["cost"]: trained on the uvdms ids only
TEACHER_ALGOS = ("dagger",)  # need a residual base and a teacher (uvdms train): tests/test_dagger.py
RUNS = [
    (a, e)
    for a in ALGO_NAMES
    for e, _ in TEST_ENVS
    if a not in TEACHER_ALGOS and (a not in COST_ALGOS or e in UVDMS_IDS)
]
"""The (algo, env id) pairs of the shared training runs."""

# A tiny config per algorithm (tests override n_timesteps; small nets, buffers and batches).
_COMMON = {"n_timesteps": 300, "n_envs": 2, "eval_freq": 200, "n_eval_episodes": 1, "checkpoint_freq": 200}
TINY = {
    "dagger": {
        **_COMMON,
        "buffer_size": 1000,
        "batch_size": 32,
        "noise_type": "normal",
        "noise_std": 0.1,
        "teacher": "campc",
        "policy_kwargs": {"net_arch": [16]},
    },
    "ppo": {
        **_COMMON,
        "normalize": True,
        "n_steps": 64,
        "batch_size": 64,
        "n_epochs": 2,
        "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}, "log_std_init": -1.0},
    },
    "ppo_lagrangian": {
        **_COMMON,
        "normalize": True,
        "n_steps": 64,
        "batch_size": 64,
        "n_epochs": 2,
        "cost_limit": 1.0,
        "lagrangian_init": 0.5,
        "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}, "log_std_init": -1.0},
    },
    "sac": {
        **_COMMON,
        "normalize": {"norm_obs": True, "norm_reward": False},
        "buffer_size": 1000,
        "batch_size": 32,
        "learning_starts": 50,
        "policy_kwargs": {"net_arch": [16]},
    },
    "td3": {
        **_COMMON,
        "buffer_size": 1000,
        "batch_size": 32,
        "learning_starts": 50,
        "noise_type": "normal",
        "noise_std": 0.2,
        "policy_kwargs": {"net_arch": [16]},
    },
    "td3_prior": {
        **_COMMON,
        "buffer_size": 1000,
        "batch_size": 32,
        "learning_starts": 50,
        "noise_type": "normal",
        "noise_std": 0.2,
        "prior_coef": 0.4,
        "actor_warmup_steps": 100,
        "policy_kwargs": {"net_arch": [16]},
    },
    "tqc": {
        **_COMMON,
        "normalize": True,
        "buffer_size": 1000,
        "batch_size": 32,
        "learning_starts": 50,
        "policy_kwargs": {"net_arch": [16], "n_quantiles": 5},
    },
}


def _write_config(folder: Path, algo: str, **extra) -> Path:
    path = folder / f"{algo}.yml"
    path.write_text(yaml.safe_dump({"default": {**TINY[algo], **extra}}), encoding="utf-8")
    return path


def _observations(env_id: str, env_kwargs: dict, n: int = 12) -> list[np.ndarray]:
    env = gym.make(env_id, **env_kwargs)
    obs_list = []
    obs, _ = env.reset(seed=123)
    env.action_space.seed(123)
    for _ in range(n):
        obs_list.append(obs)
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            obs, _ = env.reset()
    env.close()
    return obs_list


@pytest.fixture(scope="module")
def config_dir(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("configs")
    for algo in ALGO_NAMES:
        _write_config(folder, algo)
    return folder


class _Runs:
    """One short training run per (algo, env) pair of :data:`RUNS`, trained when a test first asks for it."""

    def __init__(self, out: Path, config_dir: Path) -> None:
        self.out, self.config_dir = out, config_dir
        self._done: dict[tuple[str, str], Path] = {}

    def __getitem__(self, key: tuple[str, str]) -> Path:
        if key not in self._done:
            algo, env_id = key
            self._done[key] = train(
                algo,
                env_id,
                dict(TEST_ENVS)[env_id],
                self.config_dir / f"{algo}.yml",
                seed=7,
                total_timesteps=None,
                n_envs=None,
                out_dir=self.out,
                resume_dir=None,
                progress=False,
                gym_packages=["uvdms_gym"],
            )
        return self._done[key]


@pytest.fixture(scope="module")
def runs(tmp_path_factory, config_dir) -> _Runs:
    """The shared training runs (:class:`_Runs`), shared by several tests."""
    return _Runs(tmp_path_factory.mktemp("runs"), config_dir)


# ------------------------------------------------------------------------------------------------------
# Configs
# ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("path", sorted((REPO / "train_configs").glob("*.yml")), ids=lambda p: p.name)
def test_every_train_config_validates(path):
    configs = validate_config_file(path)
    assert path.stem in ALGOS
    assert "default" in configs
    for env_id in UVDMS_IDS:
        cfg = configs[env_id]
        assert cfg.n_timesteps >= 100_000
        assert cfg.algo == path.stem
    for cfg in configs.values():
        assert parse_entry(cfg.to_entry(), cfg.algo) == cfg  # the resolved form round-trips
        cfg.sb3_policy_kwargs()
        cfg.sb3_hyperparams()


def test_all_algos_have_a_config():
    assert sorted(p.stem for p in (REPO / "train_configs").glob("*.yml")) == ALGO_NAMES


@pytest.mark.parametrize(
    ("entry", "key"),
    [
        ({"n_timesteps": 10, "learning_rat": 1.0e-3}, "learning_rat"),
        ({"n_timesteps": 10, "policy_kwargs": {"net_arc": [8]}}, "policy_kwargs.net_arc"),
        ({"n_timesteps": 10, "normalize": {"clip": 5.0}}, "normalize.clip"),
        ({"n_timesteps": 10, "seed": 3}, "seed"),
        ({"n_timesteps": 10, "action_noise": "normal"}, "action_noise"),
    ],
)
def test_unknown_key_is_rejected_with_its_name(tmp_path, entry, key):
    path = tmp_path / "sac.yml"
    path.write_text(yaml.safe_dump({"default": entry}), encoding="utf-8")
    with pytest.raises(ConfigError, match=re.escape(f"'{key}'")) as info:
        load_config(path, "sac", "Pendulum-v1")
    assert str(path) in str(info.value)


@pytest.mark.parametrize(
    ("entry", "key"),
    [
        ({"n_timesteps": "many"}, "n_timesteps"),
        ({"n_timesteps": 10, "n_envs": 1.5}, "n_envs"),
        ({"n_timesteps": 10, "batch_size": "32x"}, "batch_size"),
        ({"n_timesteps": 10, "gamma": [0.9]}, "gamma"),
        ({"n_timesteps": 10, "normalize": "yes"}, "normalize"),
        ({"n_timesteps": 10, "learning_rate": "fast"}, "learning_rate"),
        ({"n_timesteps": 10, "policy_kwargs": {"activation_fn": "sigmoid"}}, "policy_kwargs.activation_fn"),
        ({"n_timesteps": 10, "policy_kwargs": {"net_arch": "big"}}, "policy_kwargs.net_arch"),
        ({"n_timesteps": 10, "use_sde": 1}, "use_sde"),
        ({"n_timesteps": 10, "env_kwargs": ["case", 1]}, "env_kwargs"),
    ],
)
def test_wrong_type_is_rejected_with_key_and_file(tmp_path, entry, key):
    path = tmp_path / "sac.yml"
    path.write_text(yaml.safe_dump({"default": entry, "Pendulum-v1": {}}), encoding="utf-8")
    with pytest.raises(ConfigError, match=re.escape(f"'{key}'")) as info:
        load_config(path, "sac", "Pendulum-v1")
    assert str(path) in str(info.value)


def test_error_in_another_entry_is_reported(tmp_path):
    path = tmp_path / "ppo.yml"
    path.write_text("default: {n_timesteps: 10}\nOther-v0: {n_stepz: 3}\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"n_stepz.*did you mean 'n_steps'"):
        load_config(path, "ppo", "Pendulum-v1")


def test_anchors_default_merge_and_conversions(tmp_path):
    path = tmp_path / "ppo.yml"
    path.write_text(
        "base: &base\n"
        "  n_timesteps: 1000\n"
        "  learning_rate: 3e-4\n"  # YAML 1.1 reads this as a string; accepted as a float
        "  policy_kwargs: {net_arch: {pi: [32], vf: [64]}, activation_fn: elu}\n"
        "default:\n  <<: *base\n  n_envs: 4\n"
        "My-v0:\n  <<: *base\n  clip_range: lin_0.2\n  env_kwargs: {case: 2}\n",
        encoding="utf-8",
    )
    cfg = load_config(path, "ppo", "My-v0")
    assert cfg.n_envs == 4  # from default
    assert cfg.hyperparams["learning_rate"] == pytest.approx(3e-4)
    assert cfg.env_kwargs == {"case": 2}
    kwargs = cfg.sb3_policy_kwargs()
    assert kwargs["activation_fn"] is torch.nn.ELU
    schedule = cfg.sb3_hyperparams()["clip_range"]
    assert schedule(1.0) == pytest.approx(0.2) and schedule(0.5) == pytest.approx(0.1)
    assert load_config(path, "ppo", "Unlisted-v0").n_envs == 4


def test_missing_entry_and_bad_files(tmp_path):
    path = tmp_path / "sac.yml"
    path.write_text("Other-v0: {n_timesteps: 10}\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="no entry for env 'Pendulum-v1'"):
        load_config(path, "sac", "Pendulum-v1")
    path.write_text("- 1\n- 2\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="top level must be a mapping"):
        load_config(path, "sac", "Pendulum-v1")
    path.write_text("default: !!python/object/apply:os.system ['true']\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="invalid YAML"):
        load_config(path, "sac", "Pendulum-v1")
    with pytest.raises(ConfigError, match="unknown algorithm"):
        load_config(path, "dqn", "Pendulum-v1")


def test_parse_key_values():
    assert parse_key_values(["case=1", "goal=paper", "hydro_randomization=true", "scale=1.5e-2", "goals=[1, 2]"]) == {
        "case": 1,
        "goal": "paper",
        "hydro_randomization": True,
        "scale": 0.015,
        "goals": [1, 2],
    }
    with pytest.raises(ConfigError, match="key=value"):
        parse_key_values(["novalue"])


# ------------------------------------------------------------------------------------------------------
# Training runs
# ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("algo", "env_id"), RUNS)
def test_training_writes_complete_run_dir(runs, algo, env_id):
    run_dir = runs[algo, env_id]
    assert run_dir == run_dir_for(run_dir.parents[1], env_id, algo, 7)
    assert "/" not in run_dir.parent.name
    for name in (
        "config.yml",
        "command.txt",
        "meta.json",
        "final_model.zip",
        "best_model.zip",
        "best_model.json",
        "logs/seg0/progress.csv",
        "logs/seg0/evaluations.npz",
        "monitor/seg0_train_0.monitor.csv",
        "monitor/seg0_train_1.monitor.csv",
        "monitor/seg0_eval_0.monitor.csv",
    ):
        assert (run_dir / name).is_file(), name
    assert list((run_dir / "logs" / "seg0").glob("events.out.tfevents.*"))
    assert list((run_dir / "checkpoints").glob("rl_model_*_steps.zip"))
    normalized = TINY[algo].get("normalize", False) is not False
    assert (run_dir / "vecnormalize.pkl").is_file() == normalized
    assert (run_dir / "best_vecnormalize.pkl").is_file() == normalized
    assert (run_dir / "lagrangian.csv").is_file() == (algo in COST_ALGOS)

    resolved = yaml.safe_load((run_dir / "config.yml").read_text())
    assert resolved["algo"] == algo and resolved["env_id"] == env_id and resolved["seed"] == 7
    assert resolved["config"]["env_kwargs"] == dict(TEST_ENVS)[env_id]
    assert parse_entry(resolved["config"], algo).n_envs == 2

    meta = json.loads((run_dir / "meta.json").read_text())
    for package in ("python", "numpy", "torch", "stable_baselines3", "sb3_contrib", "gymnasium"):
        assert meta["versions"][package]
    assert re.fullmatch(r"[0-9a-f]{40}", meta["git"]["revision"])
    assert isinstance(meta["git"]["dirty"], bool)
    (segment,) = meta["segments"]
    assert segment["status"] == "completed"
    assert segment["end_num_timesteps"] >= 300
    assert segment["train_env_seeds"] == [train_env_seed(7, 0, 0), train_env_seed(7, 0, 1)] == [7, 8]
    assert segment["eval_env_seeds"] == [eval_env_seed(7, 0)]
    assert not set(segment["train_env_seeds"]) & set(segment["eval_env_seeds"])
    assert zip_num_timesteps(run_dir / "final_model.zip") == segment["end_num_timesteps"]
    command = (run_dir / "command.txt").read_text().splitlines()
    assert len(command) == 1 and f"--algo {algo}" in command[0]


@pytest.mark.parametrize(("algo", "env_id"), RUNS)
def test_round_trip_gives_identical_actions(runs, tmp_path, algo, env_id):
    run_dir = runs[algo, env_id]
    env_kwargs = dict(TEST_ENVS)[env_id]
    observations = _observations(env_id, env_kwargs)

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


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_resume_continues_step_count(tmp_path, config_dir, algo):
    env_id, env_kwargs = TEST_ENVS[0]
    config = _write_config(tmp_path, algo, save_replay_buffer=True) if algo == "sac" else (config_dir / f"{algo}.yml")
    run_dir = train(
        algo, env_id, env_kwargs, config, seed=1, out_dir=tmp_path / "runs", progress=False, total_timesteps=200
    )
    before = zip_num_timesteps(run_dir / "final_model.zip")
    assert latest_checkpoint(run_dir).model == run_dir / "final_model.zip"
    with pytest.raises(RunDirError, match="--resume"):
        train(algo, env_id, env_kwargs, config, seed=1, out_dir=tmp_path / "runs", progress=False)

    assert train(resume_dir=run_dir, total_timesteps=200, progress=False) == run_dir
    model = ALGOS[algo].load(run_dir / "final_model.zip")
    assert model.num_timesteps > before
    assert model.num_timesteps >= before + 200
    for segment in ("seg0", "seg1"):
        assert (run_dir / "logs" / segment / "progress.csv").is_file()
        assert (run_dir / "monitor" / f"{segment}_train_0.monitor.csv").is_file()
    progress = (run_dir / "logs" / "seg1" / "progress.csv").read_text().splitlines()
    header = progress[0].split(",")
    steps = [
        int(float(row.split(",")[header.index("time/total_timesteps")]))
        for row in progress[1:]
        if row.split(",")[header.index("time/total_timesteps")]
    ]
    assert steps and min(steps) > before  # the step axis continues
    meta = json.loads((run_dir / "meta.json").read_text())
    assert [s["status"] for s in meta["segments"]] == ["completed", "completed"]
    first, second = meta["segments"]
    assert second["start_num_timesteps"] == first["end_num_timesteps"] == before
    assert second["resumed_from"] == "final_model.zip"
    assert not set(first["train_env_seeds"]) & set(second["train_env_seeds"])
    assert len((run_dir / "command.txt").read_text().splitlines()) == 2
    if algo == "sac":
        assert (run_dir / "replay_buffer.pkl").is_file()
    # A finished run needs --total-timesteps to continue.
    with pytest.raises(ConfigError, match="--total-timesteps"):
        train(resume_dir=run_dir, progress=False, total_timesteps=None)
    with pytest.raises(ConfigError, match="differs"):
        train(algo="td3", resume_dir=run_dir, total_timesteps=10, progress=False)


def test_same_seed_gives_identical_weights(tmp_path, config_dir):
    env_id, env_kwargs = TEST_ENVS[0]
    weights = []
    for out in ("a", "b"):
        run_dir = train(
            "sac",
            env_id,
            env_kwargs,
            config_dir / "sac.yml",
            seed=5,
            out_dir=tmp_path / out,
            progress=False,
            total_timesteps=150,
        )
        model = ALGOS["sac"].load(run_dir / "final_model.zip")
        weights.append(torch.cat([p.flatten() for p in model.policy.parameters()]))
    torch.testing.assert_close(weights[0], weights[1], rtol=0, atol=0)


def test_cli(tmp_path, config_dir, capsys):
    env_id = TEST_ENVS[0][0]
    argv = [
        "--algo",
        "td3",
        "--env",
        env_id,
        "--config",
        str(config_dir / "td3.yml"),
        "--seed",
        "2",
        "--total-timesteps",
        "120",
        "--n-envs",
        "1",
        "--out",
        str(tmp_path),
        "--no-progress",
        "--env-kwargs",
        "max_episode_steps=50",
        "--hyperparams",
        "learning_rate=1.0e-3",
        "eval_freq=0",
        "checkpoint_freq=0",
    ]
    assert main(argv) == 0
    run_dir = run_dir_for(tmp_path, env_id, "td3", 2)
    assert capsys.readouterr().out.strip() == str(run_dir)
    resolved = yaml.safe_load((run_dir / "config.yml").read_text())["config"]
    assert resolved["env_kwargs"] == {"max_episode_steps": 50}
    assert resolved["n_envs"] == 1 and resolved["learning_rate"] == 1.0e-3
    assert not (run_dir / "best_model.zip").exists() and not (run_dir / "checkpoints").exists()
    assert "--env-kwargs max_episode_steps=50" in (run_dir / "command.txt").read_text()

    assert main(argv) == 2  # exists
    assert "--resume" in capsys.readouterr().err
    assert main(["--algo", "sac", "--env", "uvdms/NoSuchEnv-v0", "--out", str(tmp_path), "--no-progress"]) == 2
    assert "not registered" in capsys.readouterr().err
    assert main(["--algo", "sac", "--env", env_id, "--out", str(tmp_path), "--hyperparams", "gama=0.9"]) == 2
    assert "'gama'" in capsys.readouterr().err


def test_missing_env_package_is_reported(tmp_path, config_dir):
    with pytest.raises(EnvironmentNotFoundError, match=r"no_such_gym_pkg.*ModuleNotFoundError"):
        train(
            "sac",
            "NoSuch-v0",
            None,
            config_dir / "sac.yml",
            out_dir=tmp_path,
            progress=False,
            gym_packages=["no_such_gym_pkg"],
        )


def test_subproc_vec_env(tmp_path, config_dir):
    env_id, env_kwargs = TEST_ENVS[0]
    run_dir = train(
        "sac",
        env_id,
        env_kwargs,
        config_dir / "sac.yml",
        out_dir=tmp_path,
        progress=False,
        total_timesteps=100,
        vec_env="subproc",
        hyperparams={"eval_freq": 0, "checkpoint_freq": 0},
    )
    meta = json.loads((run_dir / "meta.json").read_text())
    assert meta["segments"][0]["vec_env"] == "subproc"
    assert meta["segments"][0]["status"] == "completed"
    assert (run_dir / "monitor" / "seg0_train_1.monitor.csv").is_file()


# ------------------------------------------------------------------------------------------------------
# Training-side options, the uvdms subcommands, shipped agent folders
# ------------------------------------------------------------------------------------------------------
def test_algo_names_of_the_light_parser_match_algos():
    from agents.training.args import ALGO_NAMES as PARSER_ALGOS

    assert list(PARSER_ALGOS) == ALGO_NAMES


def test_residual_observation_choices_of_the_light_parser_match_the_composition():
    from agents.training.args import RESIDUAL_OBSERVATION_NAMES
    from uvdms_gym.residual import RESIDUAL_OBSERVATIONS

    assert RESIDUAL_OBSERVATION_NAMES == RESIDUAL_OBSERVATIONS


def test_max_episode_steps_and_alive_bonus(tmp_path, config_dir):
    """Both fields reach the training/evaluation envs; Monitor logs hold the shaped return."""
    env_id = "Pendulum-v1"
    run_dir = train(
        "ppo",
        env_id,
        None,
        config_dir / "ppo.yml",
        out_dir=tmp_path,
        progress=False,
        total_timesteps=128,
        hyperparams={"max_episode_steps": 16, "alive_bonus": 20.0, "checkpoint_freq": 0, "eval_freq": 64},
    )
    resolved = yaml.safe_load((run_dir / "config.yml").read_text())["config"]
    assert resolved["max_episode_steps"] == 16 and resolved["alive_bonus"] == 20.0
    assert parse_entry(resolved, "ppo").alive_bonus == 20.0
    from scripts.ship_agent import read_monitor_episodes

    episodes = read_monitor_episodes(run_dir)
    assert len(episodes["l"]) >= 4 and set(episodes["l"]) == {16}
    # Pendulum rewards are in [-16.3, 0]: with +20 per step every shaped return is positive.
    assert np.all(episodes["r"] > 0) and np.all(episodes["r"] - 20.0 * episodes["l"] <= 0)
    assert read_monitor_episodes(run_dir, "eval")["l"].tolist()[0] == 16
    with pytest.raises(ConfigError, match="'max_episode_steps'"):
        parse_entry({"n_timesteps": 10, "max_episode_steps": 0}, "ppo")
    with pytest.raises(ConfigError, match="'alive_bonus'"):
        parse_entry({"n_timesteps": 10, "alive_bonus": "lots"}, "ppo")


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
    obs = _observations("uvdms/CircleTrack-v0", {"case": 2}, n=3)
    for o in obs:
        np.testing.assert_array_equal(exported.predict(o), best.predict(o))


def test_shipped_agent_folder(runs, tmp_path, monkeypatch):
    """scripts.ship_agent packages a run; load_agent loads the folder (trusted inside trained_agents/)."""
    from scripts.ship_agent import package_run

    env_id, env_kwargs = TEST_ENVS[2]
    run_dir = runs["sac", env_id]
    trusted = tmp_path / "trained_agents"
    folder = package_run(run_dir, trusted / "sac-circle-case1-v0", which="best")
    names = {p.name for p in folder.iterdir()}
    assert {"model.zip", "vecnormalize.pkl", "config.yml", "meta.json", "training_curve.png", "training_logs"} <= names
    assert (folder / "model.zip").stat().st_size < 5 * 2**20
    meta = json.loads((folder / "meta.json").read_text())
    shipped = meta["shipped"]
    assert shipped["which"] == "best" and shipped["seed"] == 7 and shipped["budget_timesteps"] == 300
    assert shipped["wall_time_s"] > 0 and shipped["env_kwargs"] == env_kwargs
    assert re.fullmatch(r"[0-9a-f]{40}", shipped["packaged_with"]["git"]["revision"])
    with pytest.raises(FileExistsError):
        package_run(run_dir, folder)

    with pytest.raises(UntrustedFileError):
        load_agent(folder)
    monkeypatch.setattr(agent_sb3, "TRUSTED_DIR", trusted)
    agent = load_agent(folder)
    reference = load_agent(run_dir, which="best", trust=True)
    assert agent.env_id == env_id and agent.env_kwargs == env_kwargs and agent.normalizer is not None
    for obs in _observations(env_id, env_kwargs, n=5):
        np.testing.assert_array_equal(agent.predict(obs), reference.predict(obs))


def test_shipped_agents_load_and_act():
    """Every folder of trained_agents/ loads without trust=True and acts on its own environment."""
    folders = sorted(p for p in (REPO / "trained_agents").glob("*") if (p / "model.zip").is_file())
    if not folders:
        pytest.skip("no shipped agents")
    for folder in folders:
        assert (folder / "model.zip").stat().st_size < 5 * 2**20
        for name in ("config.yml", "meta.json", "training_curve.png"):
            assert (folder / name).is_file(), f"{folder.name}/{name}"
        agent = load_agent(folder)
        env = gym.make(agent.env_id, **agent.env_kwargs)
        obs, info = env.reset(seed=1000)
        agent.reset(seed=1000)
        action = agent.predict(obs, info)
        assert env.action_space.contains(action.astype(np.float32))
        env.close()


def _action_layer(model) -> torch.nn.Linear:
    layer = model.policy.action_net if hasattr(model.policy, "action_net") else model.policy.actor.mu
    if isinstance(layer, torch.nn.Sequential):
        layer = [m for m in layer if isinstance(m, torch.nn.Linear)][-1]
    return layer


@pytest.mark.parametrize("algo", ["sac", "td3", "tqc"])
def test_action_init_scale_scales_the_last_action_layer(tmp_path, config_dir, algo):
    """Same seed, no gradient step yet: the scaled run's action layer is exactly scale x the unscaled one."""
    layers = []
    for scale in (None, 0.01):
        run_dir = train(
            algo,
            "Pendulum-v1",
            {"max_episode_steps": 50},
            config_dir / f"{algo}.yml",
            seed=4,
            out_dir=tmp_path / str(scale),
            progress=False,
            total_timesteps=64,
            hyperparams={"eval_freq": 0, "checkpoint_freq": 0, "learning_starts": 10_000, "action_init_scale": scale},
        )
        layers.append(_action_layer(ALGOS[algo].load(run_dir / "final_model.zip")))
    torch.testing.assert_close(layers[1].weight, 0.01 * layers[0].weight)
    torch.testing.assert_close(layers[1].bias, 0.01 * layers[0].bias)
    with pytest.raises(ConfigError, match="'action_init_scale'"):
        parse_entry({"n_timesteps": 10, "action_init_scale": 0.0}, algo)


def test_scale_action_layer_on_ppo_and_td3_target():
    from agents.training.train import scale_action_layer

    ppo = ALGOS["ppo"]("MlpPolicy", "Pendulum-v1", seed=0)
    before = _action_layer(ppo).weight.clone()
    scale_action_layer(ppo, 0.5)
    torch.testing.assert_close(_action_layer(ppo).weight, 0.5 * before)
    td3 = ALGOS["td3"]("MlpPolicy", "Pendulum-v1", seed=0)
    scale_action_layer(td3, 0.1)
    for p, q in zip(td3.policy.actor.parameters(), td3.policy.actor_target.parameters()):
        torch.testing.assert_close(p, q)


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
    for obs in _observations("Pendulum-v1", {}):
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
    from leaderboard.registry import evaluate

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
