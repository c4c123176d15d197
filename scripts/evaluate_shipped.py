"""Evaluate the shipped agents, ``campc`` and a uniform random policy on the shipped agents' tasks.

For every folder ``trained_agents/<name>/`` this runs ``uvdms evaluate --controller trained_agents/<name>
--env <its env> --env-kwargs <its task> --episodes 10 --seed 1000 --out trained_agents/<name>/evaluation.json``
(as a subprocess, so the command line itself is exercised), then evaluates the references once per task
into ``trained_agents/reference/<task>_{campc,random}.json`` (``campc`` through the same command; the random
policy through :func:`uvdms_gym.evaluation.run_episode`, as it is not a named controller), rewrites each agent
folder's ``README.md`` with its numbers (:func:`scripts.ship_agent.write_readme`) and prints the markdown table of the
README.

Seeds: the agents were trained on environment seeds 0 and 1 (and evaluated during training on 1000000+);
the evaluation uses seeds 1000-1009, disjoint from both. CircleTrack case 1/2 and Transport goal=paper are
deterministic tasks (no hydrodynamic randomisation), so the seeds only matter for the random policy.

Command line: ``python -m scripts.evaluate_shipped [--episodes 10] [--seed 1000] [--skip-existing]``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from uvdms_gym.utils.provenance import REPO_ROOT

SHIPPED_DIR = REPO_ROOT / "trained_agents"
REFERENCE_DIR = SHIPPED_DIR / "reference"
EVAL_SEED = 1000
EVAL_EPISODES = 10
_TASK_KEYS = ("case", "goal")


class RandomController:
    """Uniform random actions in ``[-1, 1]^18``, reseeded by ``reset(seed)`` (a reference, not a controller)."""

    def __init__(self, action_dim: int = 18) -> None:
        self.action_dim = action_dim
        self.rng = np.random.default_rng()

    def reset(self, seed: int | None = None) -> None:
        """Reseed the generator."""
        self.rng = np.random.default_rng(seed)

    def predict(self, obs: np.ndarray, info: Mapping[str, Any] | None = None) -> np.ndarray:
        """A uniform random action."""
        return self.rng.uniform(-1.0, 1.0, self.action_dim)


class ZeroController(RandomController):
    """Action 0 (velocity mode: hold still), a reference for "does the agent track at all"."""

    def predict(self, obs: np.ndarray, info: Mapping[str, Any] | None = None) -> np.ndarray:
        """The zero action."""
        return np.zeros(self.action_dim)


def agent_task(folder: Path) -> tuple[str, dict[str, Any]]:
    """Env id and task kwargs (``case``/``goal``/``action_mode``) of a shipped agent, from its config.yml."""
    resolved = yaml.safe_load((folder / "config.yml").read_text(encoding="utf-8"))
    env_kwargs = resolved["config"].get("env_kwargs", {})
    task = {k: env_kwargs[k] for k in (*_TASK_KEYS, "action_mode") if k in env_kwargs}
    return resolved["env_id"], task


def task_name(env_id: str, task: Mapping[str, Any]) -> str:
    """``circle_case1``, ``transport_paper``, ... (file-name friendly)."""
    base = "circle" if "Circle" in env_id else "transport"
    if "case" in task:
        return f"{base}_case{task['case']}"
    return f"{base}_{task.get('goal', 'default')}"


def _kv(task: Mapping[str, Any]) -> list[str]:
    return [f"{k}={v}" for k, v in task.items()]


def run_uvdms_evaluate(
    controller: str, env_id: str, task: Mapping[str, Any], out: Path, episodes: int, seed: int
) -> dict[str, Any]:
    """``uvdms evaluate`` as a subprocess (nice 10); returns the JSON it wrote."""
    uvdms = Path(sys.executable).with_name("uvdms")
    cmd = ["nice", "-n", "10", str(uvdms), "evaluate", "--controller", controller, "--env", env_id]
    cmd += ["--env-kwargs", *_kv(task), "--episodes", str(episodes), "--seed", str(seed), "--out", str(out)]
    cmd.append("--no-progress")
    subprocess.run(cmd, check=True, cwd=REPO_ROOT, stdout=subprocess.DEVNULL)
    return json.loads(out.read_text(encoding="utf-8"))


def evaluate_random(
    env_id: str, task: Mapping[str, Any], out: Path, episodes: int, seed: int, *, zero: bool = False
) -> dict[str, Any]:
    """The uniform random (or zero) policy through :func:`uvdms_gym.evaluation.run_episode`; same JSON shape."""
    import gymnasium as gym

    import uvdms_gym  # noqa: F401
    from uvdms_gym.evaluation import run_episode, summarize
    from uvdms_gym.utils.io import write_json_atomic

    env = gym.make(env_id, **task)
    try:
        controller = ZeroController() if zero else RandomController()
        results = [run_episode(env, controller, seed + i) for i in range(episodes)]
    finally:
        env.close()
    data = {
        "episodes": results,
        "summary": summarize(results),
        "meta": {
            "controller": "zero action (hold still)"
            if zero
            else "uniform random actions in [-1, 1]^18 (scripts.evaluate_shipped.RandomController)",
            "env_id": env_id,
            "env_kwargs": dict(task),
            "episodes": episodes,
            "seeds": [seed + i for i in range(episodes)],
        },
    }
    write_json_atomic(out, data)
    return data


def summary_row(label: str, data: Mapping[str, Any]) -> dict[str, Any]:
    """The table columns of one evaluation JSON."""
    s = data["summary"]
    eps = data["episodes"]
    return {
        "controller": label,
        "return": s["return"],
        "rmse_pos": s["rmse_pos"],
        "contacts": s["contacts"],
        "episodes_with_contact": sum(ep["contacts"] > 0 for ep in eps) / len(eps),
        "steps": s["steps"],
        "success": s["success_rate"],
    }


def markdown_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """The README table: one row per (task, controller)."""
    head = (
        "| task | controller | budget (steps) | wall time | return | rmse_pos (m) | contacts/episode "
        "| episodes with contact | steps | success |\n"
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n"
    )
    lines = []
    for r in rows:
        rmse = "n/a" if r["rmse_pos"] is None or not np.isfinite(r["rmse_pos"]) else f"{r['rmse_pos']:.3f}"
        lines.append(
            f"| {r['task']} | {r['controller']} | {r.get('budget', '')} | {r.get('wall', '')} "
            f"| {r['return']:.1f} | {rmse} | {r['contacts']:.2f} | {r['episodes_with_contact']:.0%} "
            f"| {r['steps']:.0f} | {r['success']:.0%} |"
        )
    return head + "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    """Evaluate everything and print the markdown table."""
    parser = argparse.ArgumentParser(prog="python -m scripts.evaluate_shipped", description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=EVAL_EPISODES)
    parser.add_argument("--seed", type=int, default=EVAL_SEED)
    parser.add_argument("--skip-existing", action="store_true", help="reuse JSON files that already exist")
    parser.add_argument(
        "--only",
        nargs="*",
        default=None,
        help="(re)evaluate only these agent folders (names or paths); reuse the other JSON files",
    )
    args = parser.parse_args(argv)

    folders = sorted(p for p in SHIPPED_DIR.iterdir() if (p / "model.zip").is_file())
    REFERENCE_DIR.mkdir(parents=True, exist_ok=True)
    tasks: dict[str, tuple[str, dict[str, Any]]] = {}
    agent_rows: dict[str, list[dict[str, Any]]] = {}
    for folder in folders:
        env_id, task = agent_task(folder)
        name = task_name(env_id, task)
        tasks[name] = (env_id, task)
        out = folder / "evaluation.json"
        forced = args.only is not None and folder.name in {Path(o).name for o in args.only}
        skip = args.skip_existing or (args.only is not None and not forced)
        if out.is_file() and skip and not forced:
            data = json.loads(out.read_text(encoding="utf-8"))
        else:
            data = run_uvdms_evaluate(f"trained_agents/{folder.name}", env_id, task, out, args.episodes, args.seed)
        from scripts.ship_agent import write_readme

        write_readme(folder)  # its numbers come from evaluation.json
        meta = json.loads((folder / "meta.json").read_text(encoding="utf-8"))
        shipped = meta["shipped"]
        row = summary_row(f"{meta['algo'].upper()} (`{folder.name}`)", data)
        row["budget"] = f"{shipped['budget_timesteps'] // 1000}k"
        row["wall"] = f"{shipped['wall_time_s'] / 60:.0f} min"
        agent_rows.setdefault(name, []).append(row)

    rows = []
    for name, (env_id, task) in sorted(tasks.items()):
        ref_task = {**task, "action_mode": "velocity"}
        campc_out = REFERENCE_DIR / f"{name}_campc.json"
        random_out = REFERENCE_DIR / f"{name}_random.json"
        campc = (
            json.loads(campc_out.read_text(encoding="utf-8"))
            if campc_out.is_file() and (args.skip_existing or args.only is not None)
            else run_uvdms_evaluate("campc", env_id, ref_task, campc_out, args.episodes, args.seed)
        )
        rand = (
            json.loads(random_out.read_text(encoding="utf-8"))
            if random_out.is_file() and (args.skip_existing or args.only is not None)
            else evaluate_random(env_id, ref_task, random_out, args.episodes, args.seed)
        )
        zero_out = REFERENCE_DIR / f"{name}_zero.json"
        zero = (
            json.loads(zero_out.read_text(encoding="utf-8"))
            if zero_out.is_file() and (args.skip_existing or args.only is not None)
            else evaluate_random(env_id, ref_task, zero_out, args.episodes, args.seed, zero=True)
        )
        for row in agent_rows[name]:
            rows.append({"task": name, **row})
        rows.append({"task": name, **summary_row("campc", campc)})
        rows.append({"task": name, **summary_row("zero action (hold still)", zero)})
        rows.append({"task": name, **summary_row("uniform random", rand)})
    table = markdown_table(rows)
    (REFERENCE_DIR / "table.md").write_text(table, encoding="utf-8")
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
