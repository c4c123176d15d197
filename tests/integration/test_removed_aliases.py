"""The compatibility layer of 0.3.0 is gone (0.4.0): each old module path fails in one line naming its new home.

``uvdms_gym.utils.legacy.MOVED`` (the 14 paths of ``uvdms_gym`` before its subpackages) and
``agents.common.legacy.MOVED`` (the re-export modules ``agents.train``, ``agents.policy``, ``agents.wrappers``,
``agents.callbacks`` and the alias ``agents.ppo_lagrangian``) list them; SB3 zips pickled under
``agents.ppo_lagrangian`` still load, through ``agents.common.legacy.old_pickles``.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import subprocess
import sys
import zipfile
from collections.abc import Iterator
from pathlib import Path

import gymnasium as gym
import pytest
import yaml
from stable_baselines3.common.vec_env import DummyVecEnv

import agents  # noqa: F401  (installs the finder of agents' old paths)
from agents.common import legacy as agents_legacy
from uvdms_gym.utils import legacy

REPO = Path(__file__).resolve().parents[2]
TABLE = {**legacy.MOVED, **agents_legacy.MOVED}


def test_the_tables_name_the_paths_of_0_3_0():
    assert len(legacy.MOVED) == 14 and len(agents_legacy.MOVED) == 5
    assert {"uvdms_gym.sim", "agents.train", "agents.policy", "agents.wrappers", "agents.callbacks"} <= set(TABLE)


@pytest.mark.parametrize("old", sorted(TABLE))
def test_an_old_path_fails_in_one_line_naming_the_new_home_which_imports(old):
    new = TABLE[old]
    with pytest.raises(ModuleNotFoundError) as excinfo:
        importlib.import_module(old)
    message = str(excinfo.value)
    assert message == f"{old} was moved to {new} in 0.3.0 and the alias removed in 0.4.0; import {new}"
    assert "\n" not in message and excinfo.value.name == old
    assert old not in sys.modules
    assert importlib.import_module(new).__name__ == new


def test_from_import_and_python_m_fail_in_one_line():
    code = "from uvdms_gym.params import UVDMSParams"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines()[-1] == (
        "ModuleNotFoundError: uvdms_gym.params was moved to uvdms_gym.physics.params in 0.3.0 and the alias removed "
        "in 0.4.0; import uvdms_gym.physics.params"
    )
    proc = subprocess.run(
        [sys.executable, "-m", "agents.train", "--help"], capture_output=True, text=True, timeout=120, cwd=REPO
    )
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1 and len(lines) == 1, proc.stderr
    assert "agents.train was moved to agents.training.train in 0.3.0" in lines[0]


def test_the_layer_is_gone():
    for path in ("uvdms_gym/_moved.py", "agents/train.py", "agents/policy.py", "agents/wrappers.py"):
        assert not (REPO / path).exists(), path
    assert not (REPO / "agents" / "callbacks.py").exists()
    with pytest.raises(ModuleNotFoundError, match=r"No module named 'uvdms_gym\._moved'"):
        importlib.import_module("uvdms_gym._moved")
    source = (REPO / "agents" / "algos" / "ppo_lagrangian.py").read_text(encoding="utf-8")
    assert "sys.modules" not in source


def test_an_existing_module_is_not_shadowed():
    finder = legacy.MovedModuleFinder({"json": "somewhere.else"})
    sys.meta_path.append(finder)
    try:
        assert importlib.import_module("json") is json
        assert finder.find_spec("not.in.the.table") is None
    finally:
        sys.meta_path.remove(finder)
    legacy.install_moved_finder(legacy.MOVED)  # installed already: not twice
    assert sum(isinstance(f, legacy.MovedModuleFinder) and f.table == legacy.MOVED for f in sys.meta_path) == 1


@contextlib.contextmanager
def _pickled_under_the_old_path() -> Iterator[None]:
    """Within the block, SB3 pickles the PPO-Lagrangian policy class as 0.2 did: ``agents.ppo_lagrangian.*``."""
    import agents.algos.ppo_lagrangian as module

    cls = module.CostActorCriticPolicy
    sys.modules["agents.ppo_lagrangian"] = module
    cls.__module__ = "agents.ppo_lagrangian"
    try:
        yield
    finally:
        cls.__module__ = module.__name__
        del sys.modules["agents.ppo_lagrangian"]


def _pickled_module(path: Path) -> str:
    with zipfile.ZipFile(path) as archive:
        return json.loads(archive.read("data"))["policy_class"]["__module__"]


def _old_ppo_lagrangian_zip(path: Path) -> Path:
    """A PPO-Lagrangian zip as 0.2 wrote it."""
    from agents.algos.ppo_lagrangian import PPOLagrangian

    venv = DummyVecEnv([lambda: gym.make("Pendulum-v1")])
    model = PPOLagrangian("MlpPolicy", venv, n_steps=8, batch_size=8, policy_kwargs={"net_arch": [4]}, seed=0)
    with _pickled_under_the_old_path():
        model.save(path)
    venv.close()
    return path


def test_a_zip_pickled_under_the_old_module_path_loads(tmp_path):
    from agents.algos.ppo_lagrangian import CostActorCriticPolicy, PPOLagrangian
    from agents.export import load_sb3_zip, zip_algo

    path = _old_ppo_lagrangian_zip(tmp_path / "old.zip")
    assert _pickled_module(path) == "agents.ppo_lagrangian"
    with pytest.raises(ModuleNotFoundError, match=r"agents\.ppo_lagrangian was moved to agents\.algos\.ppo_lagrangian"):
        PPOLagrangian.load(path)  # without the legacy route: the one line
    assert zip_algo(path) == "ppo_lagrangian"
    model = load_sb3_zip(path, trust=True)
    assert type(model) is PPOLagrangian and type(model.policy) is CostActorCriticPolicy
    assert "agents.ppo_lagrangian" not in sys.modules  # the alias lived for the load only


def test_a_run_whose_checkpoints_were_pickled_under_the_old_module_path_resumes(tmp_path):
    from agents.algos.ppo_lagrangian import PPOLagrangian
    from agents.training.train import latest_checkpoint, train

    entry = {"n_timesteps": 128, "n_envs": 1, "n_steps": 64, "batch_size": 64, "n_epochs": 1, "eval_freq": 0}
    entry |= {"checkpoint_freq": 64, "policy_kwargs": {"net_arch": {"pi": [8], "vf": [8]}}}
    config = tmp_path / "ppo_lagrangian.yml"
    config.write_text(yaml.safe_dump({"default": entry}), encoding="utf-8")
    run_dir = train("ppo_lagrangian", "uvdms/CircleTrack-v1", None, config, seed=0, out_dir=tmp_path, progress=False)
    zips = sorted(run_dir.rglob("*.zip"))
    assert zips
    for path in zips:  # rewritten as 0.2 wrote them
        model = PPOLagrangian.load(path)
        with _pickled_under_the_old_path():
            model.save(path)
        assert _pickled_module(path) == "agents.ppo_lagrangian"
    assert train(resume_dir=run_dir, total_timesteps=64, progress=False) == run_dir
    assert latest_checkpoint(run_dir).num_timesteps == 192
    assert _pickled_module(run_dir / "final_model.zip") == "agents.algos.ppo_lagrangian"


def regrouped_tables() -> dict[str, str]:
    """The module paths 0.4.0 moved without an alias, of every package that keeps such a table."""
    import baselines.legacy
    import leaderboard.legacy

    return {**legacy.REGROUPED, **baselines.legacy.REGROUPED, **leaderboard.legacy.REGROUPED}


@pytest.mark.parametrize("old", sorted(regrouped_tables()))
def test_a_path_the_regrouping_moved_fails_in_one_line_naming_where_its_names_live(old):
    import baselines  # noqa: F401  (installs its finder)
    import leaderboard  # noqa: F401  (installs its finder)

    new = regrouped_tables()[old]
    with pytest.raises(ModuleNotFoundError) as excinfo:
        importlib.import_module(old)
    assert str(excinfo.value) == f"{old} was moved in 0.4.0: import from {new}" and excinfo.value.name == old
    homes = [word.strip(",()") for word in new.split() if "." in word and word.strip("(")[0].isalpha()]
    for home in homes:  # every module the message names exists
        assert importlib.util.find_spec(home) is not None, home


def moved_name_tables() -> list[tuple[str, str, str]]:
    """(package, former name, its module now) of every package whose root or former module lost names in 0.4.0."""
    import baselines.legacy
    import leaderboard.legacy

    tables = {**legacy.MOVED_NAMES, **baselines.legacy.MOVED_NAMES, **leaderboard.legacy.MOVED_NAMES}
    return [(package, name, home) for package, table in tables.items() for name, home in sorted(table.items())]


@pytest.mark.parametrize(("package", "name", "home"), moved_name_tables())
def test_a_name_the_regrouping_moved_fails_in_one_line_naming_its_module(package, name, home):
    module = importlib.import_module(package)
    with pytest.raises(ImportError) as excinfo:
        exec(f"from {package} import {name}", {})
    assert str(excinfo.value) == f"{package}.{name} was moved in 0.4.0: import it from {home}"
    if name != "PACKAGE_VERSION":  # removed: the version is uvdms_gym.__version__
        assert hasattr(importlib.import_module(home), name), (home, name)
    with pytest.raises(AttributeError):
        module.no_such_name  # noqa: B018  (any other missing name is missing as usual)
