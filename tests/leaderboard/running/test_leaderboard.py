"""Leaderboard: cache and resume, bootstrap CIs, ranking and ties, seed disjointness, safe submissions."""

from __future__ import annotations

import json
import logging
import math
import zipfile
from collections import Counter
from pathlib import Path

import pytest

import leaderboard as lb
import leaderboard.running.cache
import leaderboard.running.runner
from leaderboard.running.cache import cache_key, cache_material
from leaderboard.running.jobs import DEFAULT_BACKEND, Backend
from leaderboard.suite.agent_files import training_seeds
from leaderboard.suite.entries import agent_entry, check_seed_disjointness
from tests.support.leaderboard_fakes import (
    BASELINE_ENTRIES,
    CALLS,
    CIRCLE,
    FAKE,
    TINY_TASKS,
    _run,
    planned_episodes,
)
from uvdms_cli.main import main as uvdms_main
from uvdms_gym.seeds import PROTOCOL, TEST, TEST2, VALIDATION, split_of, split_seeds
from uvdms_gym.utils.io import _umask, mirror_file, write_json_atomic


def _cache_files(tmp_path) -> list[Path]:
    return sorted((tmp_path / "out" / "cache").rglob("*.json"))


# ------------------------------------------------------------------------------------------------------
# Cache and resume
# ------------------------------------------------------------------------------------------------------
def test_second_run_computes_nothing_and_outputs_are_written(tmp_path):
    first = _run(tmp_path, plots=True)
    pairs = [(e, t) for e in BASELINE_ENTRIES for t in TINY_TASKS if e.runs_on(t)]
    assert len(pairs) == 2 * len(BASELINE_ENTRIES) == 8  # campc-inner (the obstacle task only) is not among them
    # per baseline: the one draw of the deterministic case1, 3 test and 3 test2 draws of circle-random
    n = len(BASELINE_ENTRIES) * (1 + 3 + 3)
    assert n == planned_episodes(BASELINE_ENTRIES)
    assert first.computed == n and first.cached == 0 and len(CALLS) == n
    assert first.split == "test" and first.seeds == split_seeds("test", 3)
    assert first.check_seeds == split_seeds("test2", 3)
    assert sorted(seed for _name, seed in CALLS) == sorted(
        [TEST.start] * 4 + split_seeds("test", 3) * 4 + split_seeds("test2", 3) * 4
    )
    assert len(_cache_files(tmp_path)) == n
    out = tmp_path / "out"
    for name in ("leaderboard.md", "leaderboard.csv"):
        assert (out / name).is_file()
    assert {p.stem for p in (out / "entries").glob("*.json")} == {e.name for e, _ in pairs}
    pngs = {p.name for p in (out / "plots").glob("*.png")}
    assert {"velocity_contact_free_success.png", "torque_rmse_pos.png", "min_distance_case1.png"} <= pngs
    doc = json.loads((out / "entries" / "campc.json").read_text())
    assert set(doc["tasks"]) == {"case1", "circle-random"}
    case1, randomised = doc["tasks"]["case1"], doc["tasks"]["circle-random"]
    assert [ep["seed"] for ep in case1["episodes"]] == [TEST.start] and "check" not in case1
    assert [ep["seed"] for ep in randomised["episodes"]] == split_seeds("test", 3)
    assert [ep["seed"] for ep in randomised["check"]["episodes"]] == split_seeds("test2", 3)
    assert case1["seed_protocol"] == randomised["seed_protocol"] == {"protocol": PROTOCOL, "split": "test"}
    assert randomised["check"]["seed_protocol"] == {"protocol": PROTOCOL, "split": "test2"}
    markdown = (out / "leaderboard.md").read_text()

    second = _run(tmp_path)
    assert second.computed == 0 and second.cached == n and CALLS == []
    assert lb.markdown_tables(second) == lb.markdown_tables(first)
    assert "## Plots" in markdown and "plots/min_distance_case1.png" in markdown


def test_deleting_one_cached_file_recomputes_only_that_one(tmp_path):
    _run(tmp_path)
    files = _cache_files(tmp_path)
    victim = files[len(files) // 2]
    victim.unlink()
    again = _run(tmp_path)
    assert again.computed == 1 and len(CALLS) == 1
    assert victim.is_file()
    entry_slug, _task, seed_part = victim.relative_to(tmp_path / "out" / "cache").parts
    assert CALLS[0][0] == entry_slug and f"seed{CALLS[0][1]}-" in seed_part


def test_truncated_cached_file_is_reported_and_recomputed(tmp_path, caplog):
    first = _run(tmp_path)
    victim = _cache_files(tmp_path)[0]
    text = victim.read_text()
    victim.write_text(text[: len(text) // 2])
    with caplog.at_level(logging.WARNING, logger="uvdms.leaderboard"):
        again = _run(tmp_path)
    assert again.computed == 1 and again.corrupt == [victim]
    assert any(str(victim) in rec.getMessage() for rec in caplog.records if rec.levelno == logging.WARNING)
    assert json.loads(victim.read_text())["result"]["seed"] == CALLS[0][1]
    assert lb.markdown_tables(again) == lb.markdown_tables(first)


def test_cached_file_with_wrong_content_is_not_used(tmp_path, caplog):
    _run(tmp_path)
    victim = _cache_files(tmp_path)[0]
    doc = json.loads(victim.read_text())
    doc["key"] = "0" * 64
    victim.write_text(json.dumps(doc))
    with caplog.at_level(logging.WARNING, logger="uvdms.leaderboard"):
        again = _run(tmp_path)
    assert again.computed == 1 and victim.name in caplog.text


def test_force_recomputes_everything(tmp_path):
    first = _run(tmp_path)
    again = _run(tmp_path, force=True)
    assert again.computed == first.computed and len(CALLS) == first.computed


def test_atomic_write_leaves_no_temporary_files(tmp_path):
    write_json_atomic(tmp_path / "a" / "x.json", {"v": 1})
    assert [p.name for p in (tmp_path / "a").iterdir()] == ["x.json"]
    assert (tmp_path / "a" / "x.json").stat().st_mode & 0o777 == 0o666 & ~_umask()
    with pytest.raises(ValueError):
        write_json_atomic(tmp_path / "a" / "x.json", {"v": math.nan})
    assert [p.name for p in (tmp_path / "a").iterdir()] == ["x.json"]
    assert json.loads((tmp_path / "a" / "x.json").read_text()) == {"v": 1}


def test_mirror_file_copies_keeps_itself_and_removes_a_stale_copy(tmp_path):
    source, target = tmp_path / "meta.json", tmp_path / "out" / "meta.json"
    target.parent.mkdir()
    source.write_text('{"seed": 3}')
    assert mirror_file(source, target) == target and target.read_text() == '{"seed": 3}'
    assert mirror_file(target, target) == target and target.read_text() == '{"seed": 3}'  # itself: kept as is
    source.unlink()
    assert mirror_file(source, target) is None and not target.exists()  # the source has none: stale copy gone
    assert mirror_file(None, target) is None and not target.exists()


def test_cache_key_depends_on_entry_task_seed_and_format_not_on_the_version(monkeypatch, release):
    entry, task = BASELINE_ENTRIES[0], TINY_TASKS[0]
    seed = TEST.start + 1
    base = cache_key(cache_material(entry, task, seed, False))
    assert base == cache_key(cache_material(entry, task, seed, False))
    assert base != cache_key(cache_material(entry, task, seed + 1, False))
    assert base != cache_key(cache_material(entry, TINY_TASKS[1], seed, False))
    assert base != cache_key(cache_material(BASELINE_ENTRIES[1], task, seed, False))
    assert cache_material(entry, task, seed, False)["seed_protocol"] == {"protocol": PROTOCOL, "split": "test"}
    assert cache_material(entry, task, TEST2.start, False)["seed_protocol"]["split"] == "test2"
    assert cache_material(entry, task, VALIDATION.start, False)["seed_protocol"]["split"] == "validation"
    release("9.9.9")
    assert base == cache_key(cache_material(entry, task, seed, False))
    monkeypatch.setattr(leaderboard.running.cache, "PROTOCOL", "uvdms-seeds-2")  # another seed protocol
    assert base != cache_key(cache_material(entry, task, seed, False))
    monkeypatch.setattr(leaderboard.running.cache, "PROTOCOL", PROTOCOL)
    monkeypatch.setattr(leaderboard.running.cache, "CACHE_FORMAT", leaderboard.running.cache.CACHE_FORMAT + 1)
    assert base != cache_key(cache_material(entry, task, seed, False))


def test_earlier_cache_keys_are_the_keys_of_formats_3_and_2(release):
    """Written out independently: the material of format 3 (no seed protocol) and of format 2 (the version too)."""
    entry, task = BASELINE_ENTRIES[0], TINY_TASKS[1]
    material = cache_material(entry, task, VALIDATION.start + 4, True)
    assert material["format"] == leaderboard.running.cache.CACHE_FORMAT == 4
    format3 = {
        "format": 3,
        "entry": entry.identity(),
        "task": entry.task_spec(task),
        "seed": VALIDATION.start + 4,
        "trajectory": True,
        "qp_solver": leaderboard.running.cache.PROXSUITE_BUILD,
    }
    format2 = {**format3, "format": 2, "package_version": "0.1.0"}
    earlier = leaderboard.running.cache.earlier_cache_keys(material, "0.1.0")
    assert earlier == {cache_key(format3), cache_key(format2)}
    assert leaderboard.running.cache.earlier_cache_keys(material, None) == {cache_key(format3)}
    assert cache_key(material) not in earlier


def test_a_version_bump_recomputes_no_cached_episode(tmp_path, release):
    first = _run(tmp_path)
    assert first.computed == len(CALLS) == planned_episodes(BASELINE_ENTRIES)
    release("0.4.0")
    second = _run(tmp_path)
    assert (second.computed, second.cached, CALLS) == (0, first.computed, [])
    assert lb.markdown_tables(second) == lb.markdown_tables(first)
    document = json.loads((tmp_path / "out" / "entries" / "mpc.json").read_text())
    assert document["package_version"] == "0.4.0"  # the documents still say which release wrote them


def test_baseline_cache_key_depends_on_the_proxsuite_build(monkeypatch):
    entry, task = BASELINE_ENTRIES[0], TINY_TASKS[0]
    assert entry.kind == "baseline"
    base = cache_key(cache_material(entry, task, TEST.start, False))
    monkeypatch.setattr(leaderboard.running.cache, "PROXSUITE_BUILD", "proxsuite_pywrap_avx512")
    assert base != cache_key(cache_material(entry, task, TEST.start, False))


# ------------------------------------------------------------------------------------------------------
# Seeds
# ------------------------------------------------------------------------------------------------------
def _agent_folder(root: Path, name: str, seed: int, env_kwargs=None) -> Path:
    folder = root / name
    folder.mkdir(parents=True)
    with zipfile.ZipFile(folder / "final_model.zip", "w") as archive:  # a valid archive, never loaded here
        archive.writestr("data", "{}")
    (folder / "config.yml").write_text(
        json.dumps({"algo": "sac", "env_id": CIRCLE, "seed": seed, "config": {"env_kwargs": env_kwargs or {}}})
    )
    meta = {
        "seed": seed,
        "segments": [
            {"model_seed": seed, "train_env_seeds": [seed, seed + 1], "eval_env_seeds": [seed + 1_000_000]},
            {"model_seed": seed + 1000, "train_env_seeds": [seed + 1000, seed + 1001], "eval_env_seeds": []},
        ],
    }
    (folder / "meta.json").write_text(json.dumps(meta))
    return folder


def test_training_seeds_are_read_and_evaluation_seeds_are_disjoint(tmp_path):
    folder = _agent_folder(tmp_path, "sac_case1", seed=7)
    assert training_seeds(folder) == {7, 8, 1007, 1008, 1_000_007}
    entry = agent_entry(folder, trust=True)
    assert entry.env_id == CIRCLE and entry.track == "velocity"
    assert entry.training_seeds == {7, 8, 1007, 1008, 1_000_007}
    seeds = split_seeds("test", 10) + split_seeds("test2", 10) + split_seeds("validation", 10)
    assert min(seeds) >= VALIDATION.start
    check_seed_disjointness(seeds, [entry])
    # the agents.training.train scheme (seed + 1000 k + i, eval seed + 1_000_000 + i) never reaches the validation
    # and test ranges for training seeds < 1e9
    assert 999_999_999 + 1_000_000 + 1000 < VALIDATION.start < TEST.start


def test_clashing_seed_is_refused(tmp_path):
    folder = _agent_folder(tmp_path, "sac_clash", seed=TEST.start + 1)
    entry = agent_entry(folder, trust=True)
    with pytest.raises(ValueError, match="disjoint"):
        check_seed_disjointness(split_seeds("test", 5), [entry])
    with pytest.raises(ValueError, match="disjoint"):
        _run(tmp_path, entries=[entry], episodes=3)
    assert CALLS == []  # refused before any episode


def test_a_training_seed_in_the_second_test_set_clashes_only_with_the_generalisation_check(tmp_path):
    entry = agent_entry(_agent_folder(tmp_path, "sac_test2", seed=TEST2.start + 1), trust=True)
    with pytest.raises(ValueError, match="disjoint"):
        _run(tmp_path, entries=[entry], episodes=3)
    assert CALLS == []
    result = _run(tmp_path, entries=[entry], episodes=3, generalization=False)  # no test2 draw is evaluated
    assert result.check_seeds == [] and all(row.check is None for row in result.rows)
    assert len(CALLS) == planned_episodes([entry], check=False) == 1 + 3


def test_agent_track_and_tasks_follow_its_config(tmp_path):
    torque = agent_entry(_agent_folder(tmp_path, "ppo_torque", 1, {"action_mode": "torque"}), trust=True)
    assert torque.track == "torque"
    assert torque.runs_on(TINY_TASKS[0])
    assert not torque.runs_on(lb.Task("transport", "T", "uvdms/Transport-v0"))
    circle_tasks = [t.name for t in lb.TASKS if torque.runs_on(t)]
    assert circle_tasks == [
        "case1",
        "case2",
        "circle-random",
        "circle-random-r1",
        "circle-random-r2",
        "circle-random-r3",
    ]


def test_quick_selects_the_paper_tasks():
    assert [t.name for t in lb.select_tasks(quick=True)] == ["case1", "case2", "transport"]
    rigid = [t for t in lb.TASKS if t.grasp == "rigid"]
    randomised = [t for t in rigid if not t.paper and t.env_id != "uvdms/TransportObstacles-v1"]
    assert {t.env_kwargs.get("hydro_randomization") for t in randomised} == {0.3}
    obstacles = [t for t in lb.TASKS if t.env_id == "uvdms/TransportObstacles-v1"]
    assert [dict(t.env_kwargs) for t in obstacles] == [
        {"obstacles": "random", "current": "random", **({"realism": level} if level else {})} for level in (0, 1, 2, 3)
    ]
    assert [t.realism for t in rigid if not t.check] == [1, 1, 1, 2, 2, 2, 3, 3, 3]


def test_the_cooperative_group_holds_the_object_by_friction_with_its_draws():
    from leaderboard.suite.tasks import COOP_OBSTACLE_DRAWS, DEFAULT_EPISODES, friction_tasks

    coop = friction_tasks(lb.TASKS)
    assert [t.name for t in coop] == ["coop", "coop-random", "coop-obstacles"]
    ids = ["uvdms/CooperativeTransport-v1"] * 2 + ["uvdms/CooperativeTransportObstacles-v1"]
    assert [t.env_id for t in coop] == ids
    assert [dict(t.env_kwargs) for t in coop] == [
        {"goal": "paper"},
        {"goal": "random", "hydro_randomization": 0.3},
        {"obstacles": "random", "current": "random"},
    ]
    assert coop[0].deterministic and not any(t.paper or t.realism for t in coop)
    assert [len(t.draws("test", DEFAULT_EPISODES)) for t in coop] == [1, DEFAULT_EPISODES, COOP_OBSTACLE_DRAWS]
    assert not any(t.check for t in coop[1:])  # no generalisation check: it would double their cost
    assert lb.select_tasks(quick=True) == tuple(t for t in lb.TASKS if t.paper)


def test_a_baseline_restricted_to_the_friction_grasp_runs_only_on_the_cooperative_tasks(monkeypatch):
    from leaderboard.suite import entries as entries_module
    from leaderboard.suite.entries import Entry
    from leaderboard.suite.registry import GRASP_KEY

    assert GRASP_KEY == "grasp"
    coop = Entry("coop-mpc", "baseline", "coop-mpc", "velocity", grasp="friction")
    assert [t.name for t in lb.TASKS if coop.runs_on(t)] == ["coop", "coop-random", "coop-obstacles"]
    plain = lb.resolve_entries(["campc", "campc-inner"])
    assert [t.name for t in lb.TASKS if plain[0].runs_on(t)][-3:] == ["coop", "coop-random", "coop-obstacles"]
    assert not any(plain[1].runs_on(t) for t in lb.TASKS if t.grasp == "friction")  # TransportObstacles only
    # a BASELINES spec with the key: named by the coop token, not by the baselines token, and restricted
    monkeypatch.setattr(entries_module, "BASELINES", {**entries_module.BASELINES, "coop-mpc": "velocity"})
    monkeypatch.setattr(entries_module, "BASELINE_ENV", {**entries_module.BASELINE_ENV, "coop-mpc": None})
    monkeypatch.setattr(entries_module, "GRASP_OF", {**entries_module.GRASP_OF, "coop-mpc": "friction"})
    monkeypatch.setattr(entries_module, "GRASP_ONLY", frozenset({"coop-mpc"}))
    (entry,) = lb.resolve_entries(["coop"])
    assert entry == coop
    assert "coop-mpc" not in [e.name for e in lb.resolve_entries(["baselines"])]
    with pytest.raises(ValueError, match="unknown task"):
        lb.select_tasks(["nope"])


# ------------------------------------------------------------------------------------------------------
# Safe submissions (real environment, real loading, 3-step episodes)
# ------------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def tiny_policy_model():
    import gymnasium as gym
    from stable_baselines3 import PPO

    import uvdms_gym  # noqa: F401  (registers the environments)

    env = gym.make(CIRCLE, case=1)
    model = PPO("MlpPolicy", env, policy_kwargs={"net_arch": [8]}, n_steps=8, batch_size=8, seed=0, device="cpu")
    env.close()
    return model


def _export_submission(model, folder: Path) -> Path:
    from agents.export import AgentController, export_controller

    agent = AgentController(model.policy, algo="ppo", env_id=CIRCLE, env_kwargs={"case": 1}, source="tiny")
    return export_controller(agent, folder)


def test_weights_only_submission_evaluates_and_ranks_without_trust(tmp_path, tiny_policy_model, monkeypatch):
    import agents.export

    submission = _export_submission(tiny_policy_model, tmp_path / "submission")

    def no_unpickling(*args, **kwargs):
        raise AssertionError("a weights-only submission must not be unpickled")

    monkeypatch.setattr(agents.export, "load_sb3_zip", no_unpickling)
    monkeypatch.setattr(agents.export, "load_vecnormalize_stats", no_unpickling)
    entries = lb.resolve_entries(["campc", str(submission)], trust=False)
    assert entries[1].weights_only and entries[1].track == "velocity" and entries[1].env_id == CIRCLE
    result = lb.run_leaderboard(
        entries,
        out_dir=tmp_path / "out",
        tasks=TINY_TASKS[:1],
        episodes=2,
        progress=False,
        plots=False,
        backend=DEFAULT_BACKEND,  # the real environment, make_controller and run_episode
        trust=False,
    )
    rows = {r.entry.name: r for r in result.rows}
    assert set(rows) == {"campc", "submission"}
    assert sorted(r.rank for r in rows.values())[0] == 1
    assert all([ep["seed"] for ep in r.episodes] == [TEST.start] for r in rows.values())  # deterministic: one draw
    assert "submission" in lb.markdown_tables(result)


def test_pickle_zip_from_outside_the_repo_is_refused_without_trust(tmp_path, tiny_policy_model, capsys):
    from agents.export import UntrustedFileError

    zip_path = tmp_path / "elsewhere" / "model.zip"
    zip_path.parent.mkdir()
    tiny_policy_model.save(zip_path)
    assert zip_path.is_file()
    with pytest.raises(UntrustedFileError, match="--trust"):
        lb.resolve_entries([str(zip_path)])
    with pytest.raises(UntrustedFileError):
        lb.resolve_entries(["agents"], agents_dir=tmp_path)  # the folder holds a zip outside trained_agents/
    code = uvdms_main(["leaderboard", "--entries", str(zip_path), "--out", str(tmp_path / "out"), "--no-progress"])
    assert code == 2
    err = capsys.readouterr().err
    assert "refusing to load" in err and "--trust" in err and str(zip_path) in err
    assert not (tmp_path / "out").exists()
    entry = lb.resolve_entries([str(zip_path)], trust=True)[0]
    assert entry.kind == "agent" and not entry.weights_only


# ------------------------------------------------------------------------------------------------------
# Command line (fake backend)
# ------------------------------------------------------------------------------------------------------
def test_cli_prints_ranked_tables_and_reuses_the_cache(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(leaderboard.running.runner, "DEFAULT_BACKEND", FAKE)
    argv = ["leaderboard", "--quick", "--entries", "campc", "campc-nndi", "--tasks", "case1", "case2"]
    argv += ["--out", str(tmp_path / "out"), "--no-progress", "--no-plots", "--agents-dir", str(tmp_path)]
    CALLS.clear()
    assert uvdms_main(argv) == 0
    out = capsys.readouterr().out
    assert "### Velocity track" in out and "### Torque track" in out and "(n=1)" in out
    # the paper tasks are deterministic: one episode per entry and task, whatever QUICK_EPISODES
    assert sorted(CALLS) == sorted((name, TEST.start) for name in ("campc", "campc-nndi") for _task in range(2))
    CALLS.clear()
    assert uvdms_main(argv) == 0
    assert CALLS == [] and capsys.readouterr().out == out
    md = (tmp_path / "out" / "leaderboard.md").read_text()
    assert "uvdms leaderboard --quick --entries campc campc-nndi" in md
    assert uvdms_main(["leaderboard", "--entries", "nope", "--out", str(tmp_path / "x")]) == 2
    assert "neither a baseline" in capsys.readouterr().err


def test_agents_of_another_env_version_run_the_tasks_on_their_version():
    from leaderboard.suite.entries import Entry
    from leaderboard.suite.tasks import TASKS, env_family

    by_name = {t.name: t for t in TASKS}
    circle, transport = by_name["case1"], by_name["transport"]
    assert env_family("uvdms/CircleTrack-v1") == env_family("uvdms/CircleTrack-v0") == "uvdms/CircleTrack"
    assert env_family("uvdms_gym:uvdms/Transport-v1") == "uvdms/Transport"
    v1 = Entry("a", "agent", "path/a", "velocity", env_id="uvdms/CircleTrack-v1", checksum="0" * 64)
    v0 = Entry("b", "agent", "path/b", "velocity", env_id="uvdms/CircleTrack-v0", checksum="1" * 64)
    base = Entry("campc", "baseline", "campc", "velocity")
    assert v1.runs_on(circle) and not v1.runs_on(transport)
    assert v1.task_spec(circle) == {**circle.spec("velocity"), "env_id": "uvdms/CircleTrack-v1"}
    # v0 agents and baselines keep the task's own spec (and so their cache keys)
    assert v0.task_spec(circle) == base.task_spec(circle) == circle.spec("velocity")
    assert base.task_spec(transport)["env_id"] == "uvdms/Transport-v0"
    with pytest.raises(ValueError, match="another environment"):
        circle.spec("velocity", "uvdms/Transport-v1")
    material = cache_material(v1, circle, TEST.start, False)
    assert material["task"]["env_id"] == "uvdms/CircleTrack-v1"


def test_a_v1_agent_runs_its_version_and_the_table_says_whose_return_it_is(tmp_path):
    from tests.support.multiseed_fakes import FAKE, TINY_TASKS, _agent_folder, _fake_episode

    seen: list[tuple[str, str]] = []

    def recording_episode(env, controller, seed, save_trajectory):
        seen.append((Path(controller.spec).name, env.spec_["env_id"]))
        return _fake_episode(env, controller, seed, save_trajectory)

    backend = Backend(make_env=FAKE.make_env, make_controller=FAKE.make_controller, run_episode=recording_episode)
    _agent_folder(tmp_path / "agents" / "sac_v1", 5, env_id="uvdms/CircleTrack-v1")
    entries = lb.resolve_entries(["agents", "mpc"], agents_dir=tmp_path / "agents", trust=True)
    result = lb.run_leaderboard(
        entries, out_dir=tmp_path / "out", tasks=TINY_TASKS, episodes=2, progress=False, plots=False, backend=backend
    )
    assert {env_id for name, env_id in seen if name == "sac_v1"} == {"uvdms/CircleTrack-v1"}
    assert {env_id for name, env_id in seen if name == "mpc"} == {"uvdms/CircleTrack-v0"}
    assert "Returns are in the reward of the environment version each entry runs (v0, v1" in lb.markdown_tables(result)
    alone = lb.run_leaderboard(
        entries[1:],
        out_dir=tmp_path / "out",
        tasks=TINY_TASKS,
        episodes=2,
        progress=False,
        plots=False,
        backend=backend,
    )
    assert "Returns are in the reward" not in lb.markdown_tables(alone)  # one version: no note


def test_cli_split_episodes_and_generalisation_check_options(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(leaderboard.running.runner, "DEFAULT_BACKEND", FAKE)
    argv = ["leaderboard", "--entries", "campc", "--tasks", "case1", "circle-random", "--episodes", "3"]
    argv += ["--no-progress", "--no-plots", "--agents-dir", str(tmp_path)]
    runs = {
        "full": ([], {"test": 1 + 3, "test2": 3}),  # --episodes: the draws of the randomised task, on both test sets
        "validation": (["--split", "validation"], {"validation": 1 + 3}),
        "nocheck": (["--no-generalization-check"], {"test": 1 + 3}),
    }
    for name, (extra, expected) in runs.items():
        CALLS.clear()
        assert uvdms_main([*argv, *extra, "--out", str(tmp_path / name)]) == 0
        assert Counter(split_of(seed) for _entry, seed in CALLS) == expected, name
        markdown = (tmp_path / name / "leaderboard.md").read_text()
        assert (" ".join(extra) in markdown.split("\n")[2]) and ("## Generalisation check" in markdown) == (
            name == "full"
        )
    assert "the `validation` split" in (tmp_path / "validation" / "leaderboard.md").read_text()
    capsys.readouterr()
    with pytest.raises(SystemExit):
        uvdms_main([*argv, "--split", "test2", "--out", str(tmp_path / "x")])
    assert "invalid choice: 'test2'" in capsys.readouterr().err and not (tmp_path / "x").exists()
