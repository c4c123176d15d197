"""``uvdms sweep``: grid parsing, the summary, local vs Ray runs, a two-node cluster, a worker killed mid-run.

Runs are tiny (PPO, 1 env, rollouts of 64 steps, an evaluation and a checkpoint every 100 steps, 40-step
episodes of ``uvdms/CircleTrack-v0``). Every Ray test starts its own Ray (a local instance or a
``ray.cluster_utils.Cluster`` on this machine), shuts it down, and checks that no process it started outlives
it (the ``ray_processes`` fixture of ``tests/support/ray_cluster.py``).
"""

from __future__ import annotations

import io
import json
import os
import signal
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from agents.config import ConfigError, load_config
from agents.config.zoo import zoo_entry
from agents.distributed.report import evaluation_summary
from agents.distributed.sweep import (
    STORE_NAMESPACE,
    STORE_PREFIX,
    check_seeds,
    grid_points,
    parse_grid,
    run_cpus,
    sweep,
)
from agents.distributed.worker import pack_run_dir, unpack_run_dir
from tests.support.ray_cluster import in_background
from uvdms_cli.main import main

REPO = Path(__file__).resolve().parents[3]
ENV = "uvdms/CircleTrack-v0"
TINY_PPO = {
    "n_timesteps": 400,
    "n_envs": 1,
    "normalize": True,
    "n_steps": 64,
    "batch_size": 64,
    "n_epochs": 2,
    "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}},
    "eval_freq": 100,
    "n_eval_episodes": 1,
    "checkpoint_freq": 100,
    "max_episode_steps": 40,
}


@pytest.fixture
def tiny_config(tmp_path) -> Path:
    path = tmp_path / "tiny_ppo.yml"
    path.write_text(yaml.safe_dump({"default": TINY_PPO}), encoding="utf-8")
    return path


def sweep_argv(config: Path, out: Path, *extra: str, seeds=("0", "1")) -> list[str]:
    return ["sweep", "--algo", "ppo", "--env", ENV, "--env-kwargs", "case=1", "--config", str(config),
            "--seeds", *seeds, "--out", str(out), *extra]  # fmt: skip


# ------------------------------------------------------------------------------------------------------
# Without Ray: grid, seeds, summary, archives, config round trip
# ------------------------------------------------------------------------------------------------------
def test_parse_grid_and_points():
    axes = parse_grid(["learning_rate=1.0e-3,3.0e-4", "batch_size=64,256", "n_epochs=5", "net_arch=[[64], [8, 8]]"])
    assert axes == {"learning_rate": [1e-3, 3e-4], "batch_size": [64, 256], "n_epochs": [5], "net_arch": [[64], [8, 8]]}
    points = grid_points({"a": [1, 2], "b": ["x", "y", "z"]})
    assert len(points) == 6 and points[0] == {"a": 1, "b": "x"} and points[1] == {"a": 1, "b": "y"}
    assert grid_points({}) == [{}]


@pytest.mark.parametrize(
    ("items", "message"),
    [
        (["learning_rate"], "expected key=value"),
        (["learning_rate="], "needs at least one value"),
        (["learning_rate=[]"], "needs at least one value"),
        (["batch_size=64,64"], "twice"),
        (["batch_size=64", "batch_size=128"], "given twice"),
        (["batch_size=[64,"], "not a YAML literal"),
    ],
)
def test_parse_grid_rejects(items, message):
    with pytest.raises(ValueError, match=message):
        parse_grid(items)


def test_check_seeds_and_cpus():
    assert check_seeds([3, 1]) == [3, 1]
    for bad, message in (([], "at least one"), ([1, 2, 1], "twice"), ([-1], "no split"), ([3_000_000_000], "test")):
        with pytest.raises(ValueError, match=message):
            check_seeds(bad)
    assert (run_cpus(4, "dummy"), run_cpus(4, "subproc"), run_cpus(3, "hybrid")) == (1, 4, 3)


def test_archive_round_trip_keeps_only_the_checkpoint_asked_for(tmp_path):
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "logs" / "seg0").mkdir(parents=True)
    files = {
        "config.yml": b"a: 1\n",
        "logs/seg0/progress.csv": b"x\n1\n",
        "checkpoints/rl_model_100_steps.zip": b"old",
        "checkpoints/rl_model_vecnormalize_100_steps.pkl": b"old-vn",
        "checkpoints/rl_model_200_steps.zip": b"new",
        "checkpoints/rl_model_vecnormalize_200_steps.pkl": b"new-vn",
    }
    for name, data in files.items():
        (run / name).write_bytes(data)
    whole = unpack_run_dir(pack_run_dir(run), tmp_path / "whole")
    assert {p.relative_to(whole).as_posix(): p.read_bytes() for p in whole.rglob("*") if p.is_file()} == files
    latest = unpack_run_dir(pack_run_dir(run, checkpoint=200), tmp_path / "latest")
    assert sorted(p.name for p in (latest / "checkpoints").iterdir()) == [
        "rl_model_200_steps.zip",
        "rl_model_vecnormalize_200_steps.pkl",
    ]


def test_evaluation_summary_reads_every_segment(tmp_path):
    segments = ((0, [[-3.0, -1.0], [-2.0, -2.0]], [[10, 20], [30, 30]]), (1, [[-5.0, -4.0]], [[7, 9]]))
    for seg, results, lengths in segments:
        folder = tmp_path / "logs" / f"seg{seg}"
        folder.mkdir(parents=True)
        np.savez(folder / "evaluations.npz", timesteps=np.arange(len(results)), results=results, ep_lengths=lengths)
    summary = evaluation_summary(tmp_path)
    assert summary == {
        "final_eval_return": -4.5,
        "best_eval_return": -2.0,
        "final_eval_episode_length": 8.0,
        "n_evaluations": 3,
    }


def test_zoo_entry_round_trips_every_shipped_entry(tmp_path):
    from agents.config import validate_config_file

    for algo in ("ppo", "sac", "td3", "tqc"):
        for name, cfg in validate_config_file(REPO / "train_configs" / f"{algo}.yml").items():
            if name == "default":
                continue
            entry, options = zoo_entry(cfg.to_entry())
            path = tmp_path / f"{algo}.yml"
            path.write_text(yaml.safe_dump({name: entry, "train_options": {name: options}}), encoding="utf-8")
            assert load_config(path, algo, name) == cfg, (algo, name)


# ------------------------------------------------------------------------------------------------------
# Bad input: one line, exit status 2, before anything runs
# ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"--algo": "a2c"}, "unknown algorithm 'a2c'"),
        ({"--env": "uvdms/NoSuchEnv-v0"}, "is not registered"),
        ({"--seeds": []}, "--seeds: give at least one seed"),
        ({"--seeds": ["0", "1", "0"]}, "seed 0 is given twice"),
        ({"--seeds": ["x"]}, "'x' is not an integer"),
        ({"--seeds": ["0", "3000000000"]}, "--seeds: training seed 3000000000: seed 3000000000 is in the test split"),
        ({"--seeds": ["999999999"]}, r"training seed 999999999 \(its evaluation env 0: .*\): seed 1000999999"),
        ({"--grid": ["learning_rate"]}, "--grid: expected key=value"),
        ({"--grid": ["learning_rate=1.0e-3,1.0e-3"]}, "lists the value 0.001 twice"),
        ({"--grid": ["learning_rat=1.0e-3,3.0e-4"]}, "grid point 0 .* unknown key 'learning_rat'"),
        ({"--grid": ["n_epochs=2,3"], "--hyperparams": ["n_epochs=4"]}, "both set 'n_epochs'"),
        ({"--env-kwargs": ["cas=1"]}, "takes no keyword argument 'cas'"),
        ({"--address": "auto"}, "--address and --num-cpus are options of --backend ray"),
        ({"--total-timesteps": "0"}, "--total-timesteps must be >= 1"),
    ],
)
def test_bad_input_is_one_line(tiny_config, tmp_path, capsys, change, message):
    import re

    argv = sweep_argv(tiny_config, tmp_path / "out")
    for option, value in change.items():
        if option in argv:
            i = argv.index(option)
            end = i + 1
            while end < len(argv) and not argv[end].startswith("--"):
                end += 1
            argv[i + 1 : end] = value if isinstance(value, list) else [value]
        else:
            argv += [option, *(value if isinstance(value, list) else [value])]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("uvdms: error: ") and "\n" not in err, err
    assert re.search(message, err), err
    assert not (tmp_path / "out").exists()


def test_existing_sweep_is_not_overwritten(tiny_config, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "sweep.json").write_text("{}", encoding="utf-8")
    assert main(sweep_argv(tiny_config, out)) == 2
    assert "already holds a sweep" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------------------
# Runs
# ------------------------------------------------------------------------------------------------------
def _policy_tensors(model_zip: Path) -> dict[str, torch.Tensor]:
    with zipfile.ZipFile(model_zip) as archive:
        return torch.load(io.BytesIO(archive.read("policy.pth")), weights_only=True)


def _evaluations(run_dir: Path) -> dict[str, np.ndarray]:
    files = sorted(run_dir.glob("logs/seg*/evaluations.npz"))
    loaded = [np.load(f) for f in files]
    return {k: np.concatenate([d[k] for d in loaded]) for k in ("timesteps", "results", "ep_lengths")}


def _check_completed(out: Path, seeds: list[int]) -> dict[int, dict]:
    """Every seed has one completed run whose summary agrees with its own evaluations; returns rows by seed."""
    summary = json.loads((out / "sweep.json").read_text(encoding="utf-8"))
    rows = {row["seed"]: row for row in summary["runs"]}
    assert sorted(rows) == sorted(seeds) and len(summary["runs"]) == len(seeds)
    assert sorted(p.parent.name + "/" + p.name for p in out.glob("*/ppo_*")) == sorted(
        f"uvdms_CircleTrack-v0/ppo_{s}" for s in seeds
    )
    csv_lines = (out / "sweep.csv").read_text(encoding="utf-8").splitlines()
    assert len(csv_lines) == 1 + len(seeds)
    for row in rows.values():
        run_dir = out / row["run"]
        assert row["status"] == "completed", row
        evaluations = _evaluations(run_dir)
        means = evaluations["results"].mean(axis=1)
        assert row["final_eval_return"] == pytest.approx(float(means[-1]))
        assert row["best_eval_return"] == pytest.approx(float(means.max()))
        assert row["final_eval_episode_length"] == pytest.approx(float(evaluations["ep_lengths"][-1].mean()))
        assert row["num_timesteps"] == 448  # 400 steps in whole rollouts of 64
        assert row["wall_time_s"] > 0
        # the records name where the run and its configuration are now, not the worker's temporary directory
        for name in ("command.txt", "meta.json", "config.yml"):
            assert "uvdms-sweep-" not in (run_dir / name).read_text(encoding="utf-8"), name
        config = yaml.safe_load((run_dir / "config.yml").read_text(encoding="utf-8"))
        assert Path(config["config_source"]).is_file()
        assert f"--out {out}" in (run_dir / "command.txt").read_text(encoding="utf-8")
    return rows


@pytest.mark.slow
@pytest.mark.portability
def test_ray_sweep_matches_local_and_runs_load(tiny_config, tmp_path, capsys, ray_processes):
    ray_out, local_out = tmp_path / "ray", tmp_path / "local"
    assert main(sweep_argv(tiny_config, ray_out, "--backend", "ray", "--num-cpus", "2")) == 0
    assert "uvdms_CircleTrack-v0/ppo_1" in capsys.readouterr().out
    import ray

    assert not ray.is_initialized()  # the sweep's own local instance is shut down
    assert main(sweep_argv(tiny_config, local_out, "--backend", "local")) == 0
    ray_rows, local_rows = _check_completed(ray_out, [0, 1]), _check_completed(local_out, [0, 1])
    assert {r["node"] for r in local_rows.values()} == {"local"}
    assert all(r["retries"] == 0 for r in [*ray_rows.values(), *local_rows.values()])
    for seed in (0, 1):
        a, b = ray_out / ray_rows[seed]["run"], local_out / local_rows[seed]["run"]
        for key, value in _evaluations(a).items():  # same seed, same training: identical evaluations and weights
            np.testing.assert_array_equal(value, _evaluations(b)[key])
        ta, tb = _policy_tensors(a / "final_model.zip"), _policy_tensors(b / "final_model.zip")
        assert ta.keys() == tb.keys() and all(torch.equal(ta[k], tb[k]) for k in ta)
    seeds = [_evaluations(ray_out / ray_rows[s]["run"])["results"] for s in (0, 1)]
    assert not np.array_equal(*seeds)  # different seeds differ (the comparison above can fail)

    report = tmp_path / "eval.json"
    argv = ["evaluate", "--controller", str(ray_out / ray_rows[0]["run"]), "--env", ENV, "--env-kwargs", "case=1",
            "max_episode_steps=20", "--episodes", "1", "--trust", "--no-progress", "--out", str(report)]  # fmt: skip
    assert main(argv) == 0
    assert len(json.loads(report.read_text(encoding="utf-8"))["episodes"]) == 1


def test_grid_sweep_locally(tiny_config, tmp_path):
    result = sweep(
        "ppo",
        ENV,
        [3],
        env_kwargs={"case": 1},
        config_path=tiny_config,
        grid=parse_grid(["n_epochs=1,2"]),
        total_timesteps=128,
        out_dir=tmp_path / "out",
    )
    assert [(r["grid"], r["grid_point"], r["status"]) for r in result.rows] == [
        (0, {"n_epochs": 1}, "completed"),
        (1, {"n_epochs": 2}, "completed"),
    ]
    for row in result.rows:
        resolved = yaml.safe_load((tmp_path / "out" / row["run"] / "config.yml").read_text(encoding="utf-8"))
        assert row["run"].startswith(f"grid_{row['grid']}/")
        assert resolved["config"]["n_epochs"] == row["grid_point"]["n_epochs"]
        assert resolved["config"]["n_timesteps"] == 128


@pytest.mark.slow
def test_two_node_cluster(tiny_config, tmp_path, ray_processes):
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    try:
        cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        out = tmp_path / "out"
        assert main(sweep_argv(tiny_config, out, "--backend", "ray", "--address", cluster.address)) == 0
        rows = _check_completed(out, [0, 1])
        # one CPU per node and one CPU per run: the two runs trained side by side, one on each node
        assert len({row["node"] for row in rows.values()}) == 2
    finally:
        cluster.shutdown()


@pytest.mark.slow
def test_killed_worker_resumes_from_its_checkpoint(tiny_config, tmp_path, ray_processes):
    import ray

    ray.init(num_cpus=2, include_dashboard=False, logging_level="WARNING")
    out = tmp_path / "out"
    # a run that needs more CPUs than any node has would wait forever: an error before anything is written
    with pytest.raises(ConfigError, match=r"a run needs 3 CPUs .* the largest Ray node has 2"):
        sweep("ppo", ENV, [0], config_path=tiny_config, n_envs=3, vec_env="subproc", backend="ray", out_dir=out)
    assert not out.exists() and ray.is_initialized()  # the caller's session is reused and left connected
    thread, outcome = in_background(
        lambda: sweep(
            "ppo",
            ENV,
            [0, 1],
            env_kwargs={"case": 1},
            config_path=tiny_config,
            total_timesteps=1000,
            backend="ray",
            out_dir=out,
        )
    )
    killed = None
    deadline = time.monotonic() + 120
    while killed is None and thread.is_alive() and time.monotonic() < deadline:
        actors = ray.util.list_named_actors(all_namespaces=True)
        names = [a["name"] for a in actors if a["name"].startswith(STORE_PREFIX)]
        if names:
            status = ray.get(ray.get_actor(names[0], namespace=STORE_NAMESPACE).status.remote())
            record = status.get("uvdms_CircleTrack-v0/ppo_0", {})
            if record.get("checkpoint_timesteps"):
                os.kill(record["pid"], signal.SIGKILL)
                killed, dead_root = record["checkpoint_timesteps"], Path(record["worker_root"])
                assert dead_root.is_dir()
        time.sleep(0.02)
    thread.join(timeout=300)
    assert "error" not in outcome, outcome.get("error")
    assert killed is not None, "the run ended before its first checkpoint could be seen"

    rows = {row["seed"]: row for row in outcome["result"].rows}
    assert [rows[0]["retries"], rows[1]["retries"]] == [1, 0]
    assert all(row["status"] == "completed" for row in rows.values())
    assert sorted(p.name for p in out.glob("*/ppo_*")) == ["ppo_0", "ppo_1"]
    meta = json.loads((out / rows[0]["run"] / "meta.json").read_text(encoding="utf-8"))
    first, second = meta["segments"]
    assert first["status"] == "worker_lost" and first["start_num_timesteps"] == 0
    assert second["status"] == "completed"
    assert second["start_num_timesteps"] >= killed > 0  # resumed from a checkpoint, not from step 0
    assert second["resumed_from"] == f"checkpoints/rl_model_{second['start_num_timesteps']}_steps.zip"
    # PPO trains whole rollouts of 64 steps: 1000 from 0, and the missing 1000 - start from the checkpoint
    start = second["start_num_timesteps"]
    assert rows[1]["num_timesteps"] == 1024
    assert rows[0]["num_timesteps"] == start + -(-(1000 - start) // 64) * 64
    # every evaluation time once: the resumed segment continued where the checkpoint left off
    resumed, clean = _evaluations(out / rows[0]["run"])["timesteps"], _evaluations(out / rows[1]["run"])["timesteps"]
    np.testing.assert_array_equal(resumed, clean)
    assert rows[0]["n_evaluations"] == len(clean) == 10
    assert not dead_root.exists()  # the retry (on this node) removed the dead worker's temporary directory
    ray.shutdown()


def test_config_error_in_one_grid_point_is_reported_before_any_run(tiny_config, tmp_path):
    with pytest.raises(ConfigError, match=r"grid point 1 .*n_epochs"):
        sweep("ppo", ENV, [0], config_path=tiny_config, grid={"n_epochs": [2, "many"]}, out_dir=tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_failing_run_is_recorded_and_the_exit_status_is_1(tiny_config, tmp_path, capsys):
    out = tmp_path / "out"
    argv = sweep_argv(tiny_config, out, seeds=("5",))
    argv[argv.index("case=1")] = "case=7"  # accepted key, value the environment rejects when the run starts
    assert main(argv) == 1
    (row,) = json.loads((out / "sweep.json").read_text(encoding="utf-8"))["runs"]
    assert row["status"] == "failed" and "unknown circle case 7" in row["error"]
    assert "failed" in capsys.readouterr().err
    assert not list(out.glob("*/ppo_*"))


def test_residual_sweep_trains_the_composition_and_needs_the_components(tiny_config, tmp_path, capsys):
    residual = ["--hyperparams", "residual_base=mpc", "residual_scale=0.5", "--total-timesteps", "128"]
    assert main(sweep_argv(tiny_config, tmp_path / "out", *residual, seeds=("4",))) == 0
    row = json.loads((tmp_path / "out" / "sweep.json").read_text(encoding="utf-8"))["runs"][0]
    assert row["status"] == "completed"
    run = tmp_path / "out" / row["run"]
    resolved = yaml.safe_load((run / "config.yml").read_text(encoding="utf-8"))
    assert (resolved["config"]["residual_base"], resolved["config"]["residual_scale"]) == ("mpc", 0.5)
    meta = json.loads((run / "meta.json").read_text(encoding="utf-8"))
    assert meta["segments"][0]["action_composition"]["residual_base"] == "mpc"
    # the agents package alone (no composition layer) refuses it before any run starts
    with pytest.raises(ConfigError, match="uvdms train"):
        sweep("ppo", ENV, [5], env_kwargs={"case": 1}, config_path=tiny_config,
              hyperparams={"residual_base": "mpc", "residual_scale": 0.5}, out_dir=tmp_path / "bare")  # fmt: skip
    assert not (tmp_path / "bare").exists()
