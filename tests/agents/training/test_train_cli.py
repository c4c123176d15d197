"""``uvdms train`` exactly as the Training page of the docs shows it, and what a failed or short run leaves behind.

The first test runs the ``uvdms train`` lines of ``docs/training/index.md``'s first ``bash`` block with the
``uvdms`` console script of the suite's environment (the one next to ``sys.executable``), progress bar on, from a
temporary working directory, with ``--total-timesteps`` lowered to a few hundred steps (the only change to the
lines). The other tests call
:func:`agents.training.train.train` in-process.
"""

from __future__ import annotations

import json
import math
import os
import re
import shlex
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from agents.algos import ALGOS
from agents.training.train import (
    grow_replay_buffer,
    latest_checkpoint,
    replay_buffer_size,
    run_dir_for,
    train,
    zip_num_timesteps,
)

REPO = Path(__file__).resolve().parents[3]
UVDMS = Path(sys.executable).with_name("uvdms")
STEPS = 300
RESUME_STEPS = 200


def readme_train_lines() -> list[str]:
    """The ``uvdms train`` command lines of the first code block of the docs' Training page (comments removed)."""
    text = (REPO / "docs" / "training" / "index.md").read_text(encoding="utf-8")
    block = text.split("```bash", 1)[1].split("```", 1)[0]
    return [line.split("#", 1)[0].strip() for line in block.splitlines() if line.startswith("uvdms train ")]


def with_steps(line: str, steps: int) -> list[str]:
    """The command line with ``--total-timesteps steps`` (replacing the documented value or appended)."""
    argv = shlex.split(line)
    if "--total-timesteps" in argv:
        argv[argv.index("--total-timesteps") + 1] = str(steps)
    else:
        argv += ["--total-timesteps", str(steps)]
    return argv


def run_uvdms(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """Run ``argv`` (starting with ``uvdms``) with the suite's console script, this checkout first on the path."""
    assert argv[0] == "uvdms"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH")) if p)}
    return subprocess.run(
        [str(UVDMS), *argv[1:]], cwd=cwd, env=env, capture_output=True, text=True, timeout=900, check=False
    )


@pytest.mark.slow
def test_readme_train_commands_run_as_written(tmp_path):
    lines = readme_train_lines()
    assert [shlex.split(line)[2] for line in lines] == ["--algo", "--algo", "--resume"], lines
    sac, ppo, resume = lines
    assert UVDMS.is_file(), f"no console script next to {sys.executable}"

    # A start that fails at env creation (bad --env-kwargs) leaves nothing behind ...
    bad = [a if a != "case=1" else "case=7" for a in with_steps(sac, STEPS)]
    failed = run_uvdms(bad, tmp_path)
    assert failed.returncode == 2, failed.stderr
    assert "unknown circle case 7" in failed.stderr and "Traceback" not in failed.stderr
    sac_dir = run_dir_for(tmp_path / "runs", "uvdms/CircleTrack-v0", "sac", 0)
    assert not sac_dir.exists()

    # ... so the documented SAC line with the same seed then runs (progress bar on: rich must be installed).
    done = run_uvdms(with_steps(sac, STEPS), tmp_path)
    assert done.returncode == 0, done.stderr
    assert Path(done.stdout.strip().splitlines()[-1]) == Path("runs/uvdms_CircleTrack-v0/sac_0")
    assert f"{STEPS}/{STEPS}" in done.stdout + done.stderr  # the progress bar's final state
    assert zip_num_timesteps(sac_dir / "final_model.zip") == STEPS
    meta = json.loads((sac_dir / "meta.json").read_text())
    n_envs = yaml.safe_load((sac_dir / "config.yml").read_text())["config"]["n_envs"]
    capacity = n_envs * (math.ceil(STEPS / n_envs) + 1)
    assert meta["segments"][0]["replay_buffer_size"] == capacity
    # the buffer file holds `capacity` transitions of 80 + 80 observation and 18 action floats, not 300,000
    assert (sac_dir / "replay_buffer.pkl").stat().st_size < capacity * (80 + 80 + 18 + 4) * 4 * 1.5

    # PPO rounds the steps up to whole rollouts and says so.
    done = run_uvdms(with_steps(ppo, STEPS), tmp_path)
    assert done.returncode == 0, done.stderr
    ppo_dir = run_dir_for(tmp_path / "runs", "uvdms/Transport-v0", "ppo", 0)
    cfg = yaml.safe_load((ppo_dir / "config.yml").read_text())["config"]
    rollout = cfg["n_steps"] * cfg["n_envs"]
    assert re.search(rf"whole rollouts .* = {rollout} steps: the {STEPS} requested steps run as {rollout}", done.stderr)
    assert zip_num_timesteps(ppo_dir / "final_model.zip") == rollout
    assert json.loads((ppo_dir / "meta.json").read_text())["segments"][0]["planned_timesteps"] == rollout
    assert cfg["learning_rate"] == 1.0e-4 and cfg["env_kwargs"]["goal"] == "paper"

    # The documented resume line continues the SAC run; its replay buffer grows to the new total.
    done = run_uvdms(with_steps(resume, RESUME_STEPS), tmp_path)
    assert done.returncode == 0, done.stderr
    assert zip_num_timesteps(sac_dir / "final_model.zip") == STEPS + RESUME_STEPS
    segment = json.loads((sac_dir / "meta.json").read_text())["segments"][1]
    assert segment["replay_buffer_loaded"] and segment["status"] == "completed"
    assert segment["replay_buffer_size"] == n_envs * (math.ceil((STEPS + RESUME_STEPS) / n_envs) + 1)


# ------------------------------------------------------------------------------------------------------
# In-process checks of the same rules (small configs)
# ------------------------------------------------------------------------------------------------------
_SAC = {
    "n_timesteps": 300,
    "n_envs": 2,
    "eval_freq": 0,
    "checkpoint_freq": 0,
    "buffer_size": 100_000,
    "batch_size": 32,
    "learning_starts": 50,
    "policy_kwargs": {"net_arch": [16]},
}


def _config(tmp_path: Path, algo: str, entry: dict) -> Path:
    path = tmp_path / f"{algo}.yml"
    path.write_text(yaml.safe_dump({"default": entry}), encoding="utf-8")
    return path


def _train(tmp_path: Path, algo: str, entry: dict, out: str = "runs", **kwargs) -> Path:
    return train(
        algo,
        "Pendulum-v1",
        {"max_episode_steps": 50},
        _config(tmp_path, algo, entry),
        seed=3,
        out_dir=tmp_path / out,
        progress=False,
        **kwargs,
    )


def test_failure_before_a_model_removes_the_run_dir_and_an_interrupt_keeps_it(tmp_path, monkeypatch):
    sac = ALGOS["sac"]
    original = sac.learn

    def crash(self, *args, **kwargs):
        raise RuntimeError("diverged")

    monkeypatch.setattr(sac, "learn", crash)
    with pytest.raises(RuntimeError, match="diverged"):
        _train(tmp_path, "sac", _SAC)
    run_dir = run_dir_for(tmp_path / "runs", "Pendulum-v1", "sac", 3)
    assert not run_dir.exists()

    def interrupt(self, *args, **kwargs):
        original(self, total_timesteps=60, progress_bar=False)
        raise KeyboardInterrupt

    monkeypatch.setattr(sac, "learn", interrupt)
    with pytest.raises(KeyboardInterrupt):
        _train(tmp_path, "sac", _SAC)
    checkpoint = latest_checkpoint(run_dir)
    assert checkpoint is not None and checkpoint.model.name == "final_model.zip"  # resumable, so kept

    monkeypatch.setattr(sac, "learn", original)
    assert _train(tmp_path, "sac", _SAC, out="runs2") == run_dir_for(tmp_path / "runs2", "Pendulum-v1", "sac", 3)


def test_capped_replay_buffer_trains_exactly_like_the_configured_one(tmp_path, monkeypatch):
    """The cap never lets the buffer fill, so weights equal those of an uncapped run with the same seed."""
    capped = _train(tmp_path, "sac", _SAC, out="capped")
    meta = json.loads((capped / "meta.json").read_text())
    assert meta["segments"][0]["replay_buffer_size"] == replay_buffer_size(100_000, 2, 300) == 2 * 151
    monkeypatch.setattr("agents.training.segment.replay_buffer_size", lambda configured, n_envs, total: configured)
    full = _train(tmp_path, "sac", _SAC, out="full")
    assert json.loads((full / "meta.json").read_text())["segments"][0]["replay_buffer_size"] == 100_000
    a = ALGOS["sac"].load(capped / "final_model.zip").policy.state_dict()
    b = ALGOS["sac"].load(full / "final_model.zip").policy.state_dict()
    assert a.keys() == b.keys()
    for key in a:
        torch.testing.assert_close(a[key], b[key], rtol=0, atol=0)
    assert replay_buffer_size(1000, 2, 5000) == 1000  # a buffer smaller than the run is left alone


def test_grow_replay_buffer_keeps_the_transitions():
    model = ALGOS["sac"]("MlpPolicy", "Pendulum-v1", buffer_size=100, learning_starts=1000, seed=0)
    model.learn(60)
    buffer = model.replay_buffer
    pos = buffer.pos
    before = {k: v[:pos].copy() for k, v in vars(buffer).items() if isinstance(v, np.ndarray) and v.shape[0] == 100}
    assert set(before) >= {"observations", "next_observations", "actions", "rewards", "dones"}
    assert grow_replay_buffer(model, 500)
    assert buffer.buffer_size == 500 and model.buffer_size == 500 and buffer.pos == pos and not buffer.full
    for key, value in before.items():
        assert getattr(buffer, key).shape[0] == 500
        np.testing.assert_array_equal(getattr(buffer, key)[:pos], value)
    assert not grow_replay_buffer(model, 300)  # never shrinks
    model.learn(400, reset_num_timesteps=False)  # fills past the old size without error
    assert buffer.pos == pos + 400 and not buffer.full


def test_ppo_warns_when_rollouts_round_the_steps_up(tmp_path):
    entry = {
        "n_timesteps": 100,
        "n_envs": 2,
        "eval_freq": 0,
        "checkpoint_freq": 0,
        "n_steps": 64,
        "batch_size": 64,
        "n_epochs": 1,
        "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}},
    }
    with pytest.warns(UserWarning, match=r"64 x 2 = 128 steps: the 100 requested steps run as 128"):
        run_dir = _train(tmp_path, "ppo", entry)
    assert zip_num_timesteps(run_dir / "final_model.zip") == 128
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # (not Gymnasium's DeprecationWarning: v0 is not the newest)
        _train(tmp_path, "ppo", {**entry, "n_timesteps": 256}, out="exact")  # a multiple: no warning
