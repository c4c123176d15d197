"""A regular (non-editable) install carries the training configs and the shipped agents.

The wheel is built once (``pip wheel --no-deps --no-build-isolation``, a few seconds), its file list is
checked against the checkout, and the unpacked wheel is imported in a subprocess from another working
directory to check that the package-data paths resolve inside it (what ``uvdms train`` and ``uvdms
leaderboard`` use). The full check is manual (minutes): ``python3 -m venv /tmp/v && /tmp/v/bin/pip install
-c constraints.txt .`` (a plain venv, not ``--system-site-packages``), then ``/tmp/v/bin/uvdms train ...`` and
``/tmp/v/bin/uvdms leaderboard --quick`` from a directory outside the checkout.

The wheel is built from a copy of the checkout, so the build leaves no ``build/`` or ``*.egg-info`` in it.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # builds the wheel

REPO = Path(__file__).resolve().parents[2]
SOURCE_PACKAGES = ("uvdms_gym", "baselines", "agents", "leaderboard", "uvdms_cli")
MAX_MODEL_BYTES = 5 * 2**20
SHIPPED_FILES = ("model.zip", "vecnormalize.pkl", "config.yml", "meta.json", "evaluation.json", "README.md")


def shipped_folders() -> list[Path]:
    return sorted(p for p in (REPO / "trained_agents").iterdir() if (p / "model.zip").is_file())


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("wheel")
    source = tmp_path_factory.mktemp("source") / "uvdms-gym"
    ignore = shutil.ignore_patterns(".*", "build", "*.egg-info", "__pycache__", "runs", "docs", "tests", "*_out")
    shutil.copytree(REPO, source, ignore=ignore)
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-v", "-w", str(out), str(source)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    (path,) = out.glob("uvdms_gym-*.whl")
    return path, build.stdout + build.stderr


def test_build_has_no_setuptools_warnings(wheel):
    _, log = wheel
    for marker in ("SetuptoolsDeprecationWarning", "_Warning:", "is absent from the `packages`", "License classifiers"):
        assert marker not in log, marker


def _wheel_names(wheel) -> tuple[set[str], str]:
    path, _ = wheel
    with zipfile.ZipFile(path) as archive:
        names = set(archive.namelist())
        metadata = next(archive.read(n).decode() for n in names if n.endswith(".dist-info/METADATA"))
    return names, metadata


def test_wheel_holds_the_code_and_the_configs(wheel):
    names, metadata = _wheel_names(wheel)
    for package in SOURCE_PACKAGES:
        for source in (REPO / package).rglob("*.py"):
            assert source.relative_to(REPO).as_posix() in names, f"{source} missing: list its package in pyproject"
    for config in (REPO / "train_configs").glob("*.yml"):
        assert f"agents/train_configs/{config.name}" in names
    spaces = list((REPO / "train_configs" / "search_spaces").glob("*.yml"))
    assert spaces
    for space in spaces:  # uvdms tune's search spaces
        assert f"agents/train_configs/search_spaces/{space.name}" in names
    assert not [n for n in names if n.startswith("scripts/")]  # maintainer tools stay in the checkout
    assert "License-Expression: MIT" in metadata
    assert any(line.startswith("Requires-Dist: rich") for line in metadata.splitlines())


def test_wheel_holds_the_shipped_agents(wheel):
    names, _ = _wheel_names(wheel)
    folders = shipped_folders()
    assert folders
    for folder in folders:
        for name in SHIPPED_FILES:
            if (folder / name).is_file() or name in ("model.zip", "config.yml", "meta.json", "README.md"):
                assert f"agents/trained_agents/{folder.name}/{name}" in names, f"{folder.name}/{name}"
        assert (folder / "model.zip").stat().st_size < MAX_MODEL_BYTES
    export_files = ("agent.json", "policy.pt", "normalization.npz", "learning_curve.json", "meta.json")
    for seed_folder in sorted((REPO / "trained_agents").glob("*/seed_*")):  # multi-seed entries' exports
        entry = seed_folder.parent.name
        for name in export_files:
            if (seed_folder / name).is_file():
                assert f"agents/trained_agents/{entry}/{seed_folder.name}/{name}" in names, f"{seed_folder}/{name}"
        assert sum(f.stat().st_size for f in seed_folder.iterdir() if f.is_file()) < MAX_MODEL_BYTES
    assert not [n for n in names if "training_logs" in n or n.endswith(".png")]  # logs and plots stay in git


def test_unpacked_wheel_finds_configs_and_agents_from_any_directory(wheel, tmp_path):
    path, _ = wheel
    site = tmp_path / "site"
    with zipfile.ZipFile(path) as archive:
        archive.extractall(site)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    code = """
import json, agents, uvdms_gym
from agents.config import default_config_path, load_config
from agents.export import TRUSTED_DIR, load_agent
from agents.distributed.search_space import default_search_space_path, load_search_space
from leaderboard.suite.entries import find_agent_folders, resolve_entries
cfg = load_config(default_config_path("ppo"), "ppo", "uvdms/CircleTrack-v0")
space = load_search_space(default_search_space_path("ppo"))
folders = find_agent_folders(TRUSTED_DIR)
agent = load_agent(next(f for f in folders if not any(f.glob("seed_*"))))  # a single agent (not a seed folder)
entries = resolve_entries(["agents"])
print(json.dumps({
    "agents": agents.__file__, "uvdms_gym": uvdms_gym.__file__, "config": str(default_config_path("ppo")),
    "trusted": str(TRUSTED_DIR), "folders": [f.name for f in folders], "n_timesteps": cfg.n_timesteps,
    "agent_env": agent.env_id, "entries": [e.name for e in entries],
    "space": str(default_search_space_path("ppo")), "space_params": len(space.params),
}))
"""
    env = {**os.environ, "PYTHONPATH": str(site)}
    run = subprocess.run(
        [sys.executable, "-c", code], cwd=elsewhere, env=env, capture_output=True, text=True, timeout=300, check=False
    )
    assert run.returncode == 0, run.stderr[-3000:]
    found = json.loads(run.stdout.strip().splitlines()[-1])
    for key in ("agents", "uvdms_gym", "config", "trusted", "space"):
        assert Path(found[key]).is_relative_to(site), (key, found[key])
    assert found["n_timesteps"] > 0 and found["agent_env"].startswith("uvdms/") and found["space_params"] > 0
    multi_seed = {p.parent.name for p in (REPO / "trained_agents").glob("*/seed_*")}
    expected = sorted([p.name for p in shipped_folders()] + sorted(multi_seed))
    assert found["folders"] == expected and sorted(found["entries"]) == expected
