"""Package a training run as a shipped agent folder (``trained_agents/<name>/``) and plot its training curve.

Shipped agent folder::

    model.zip               the SB3 model (``best_model.zip`` or ``final_model.zip`` of the run)
    vecnormalize.pkl        its VecNormalize statistics (only when the run normalised observations)
    config.yml              the run's resolved configuration (algo, env id, env kwargs, seed, hyperparameters)
    meta.json               the run's meta.json plus a ``shipped`` record: which model, its steps, the budget,
                            the training wall time, the seeds, versions and git revision
    training_curve.png      environment return (alive bonus removed) vs timesteps, training episodes and the
                            evaluation callback's episodes
    learning_curve.json     the benchmark's metrics of the evaluation callback's episodes vs timesteps (when the
                            run recorded them, :mod:`agents.common.learning_curve`)
    training_logs/          the run's Monitor CSVs, progress.csv and evaluations.npz (small text/npz files)
    evaluation.json         written afterwards by ``uvdms evaluate --controller trained_agents/<name> ...``
    README.md               what the agent is, its evaluation, and how to run it with this project or with
                            plain Stable-Baselines3 (:func:`write_readme`; the ``action_scale`` wrapper and the
                            VecNormalize statistics that ``<ALGO>.load`` alone does not apply)

:func:`agents.export.load_agent` loads such a folder (``model.zip`` + ``vecnormalize.pkl``); pickles inside
the repository's ``trained_agents/`` are trusted (they are reviewed and committed).

Command line: ``python -m scripts.ship_agent RUN_DIR OUT_DIR [--which best|final]``; ``python -m scripts.ship_agent
--readme
FOLDER ...`` rewrites the README of packaged folders (after ``scripts.evaluate_shipped`` wrote their evaluation).
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.common.learning_curve import copy_learning_curve
from agents.export import SHIPPED_MODEL, SHIPPED_STATS
from agents.training.rundir import zip_num_timesteps
from uvdms_gym.utils.provenance import git_info, package_versions

MAX_MODEL_BYTES = 5 * 1024 * 1024


def read_monitor_episodes(run_dir: str | Path, kind: str = "train") -> dict[str, np.ndarray]:
    """Episodes of a run's Monitor CSVs, in completion order across envs and segments.

    Args:
        run_dir: The run directory.
        kind: ``train`` or ``eval`` monitor files.

    Returns:
        Arrays ``r`` (logged return), ``l`` (length), ``t`` (wall time since the segment start) and
        ``timesteps`` (cumulative environment steps of this kind of env at the episode end; for ``train``
        this is the training step count, resumed segments continue it).
    """
    rows: list[tuple[int, float, float, int]] = []
    for path in sorted(Path(run_dir, "monitor").glob(f"seg*_{kind}_*.monitor.csv")):
        segment = int(path.name[3 : path.name.index("_")])
        with path.open(encoding="utf-8") as f:
            lines = [line for line in f if not line.startswith("#")]
        for row in csv.DictReader(lines):
            rows.append((segment, float(row["t"]), float(row["r"]), int(row["l"])))
    rows.sort()
    r = np.array([x[2] for x in rows], dtype=float)
    length = np.array([x[3] for x in rows], dtype=int)
    return {"r": r, "l": length, "t": np.array([x[1] for x in rows]), "timesteps": np.cumsum(length)}


def plot_training_curve(run_dir: str | Path, out_png: str | Path, title: str | None = None) -> Path:
    """Plot environment return vs timesteps of a run (training episodes and evaluation-callback means).

    The alive bonus of the configuration is removed, so the curve shows the environment's own return.

    Args:
        run_dir: The run directory.
        out_png: Output PNG.
        title: Figure title (default: the run directory name).

    Returns:
        The PNG path.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    resolved = yaml.safe_load((run_dir / "config.yml").read_text(encoding="utf-8"))
    bonus = float(resolved["config"].get("alive_bonus", 0.0))
    train = read_monitor_episodes(run_dir, "train")
    fig, (ax_r, ax_l) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    if len(train["r"]):
        env_return = train["r"] - bonus * train["l"]
        ax_r.plot(train["timesteps"], env_return, ".", ms=2, alpha=0.35, color="tab:blue", label="training episode")
        window = max(1, min(20, len(env_return) // 5))
        smooth = np.convolve(env_return, np.ones(window) / window, mode="valid")
        ax_r.plot(train["timesteps"][window - 1 :], smooth, color="tab:blue", label=f"training, mean of {window}")
        ax_l.plot(train["timesteps"], train["l"], ".", ms=2, alpha=0.35, color="tab:blue")
    evals = sorted(run_dir.glob("logs/seg*/evaluations.npz"))
    for k, path in enumerate(evals):
        data = np.load(path, allow_pickle=False)
        steps, results, lengths = data["timesteps"], data["results"], data["ep_lengths"]
        env_return = (results - bonus * lengths).mean(axis=1)
        ax_r.plot(
            steps, env_return, "o-", color="tab:red", label="evaluation callback (deterministic)" if k == 0 else None
        )
        ax_l.plot(steps, lengths.mean(axis=1), "o-", color="tab:red")
    ax_r.set_ylabel("environment return")
    ax_l.set_ylabel("episode length (steps)")
    ax_l.set_xlabel("timesteps")
    ax_r.legend(loc="lower right", fontsize=8)
    note = f" (alive bonus {bonus:g} removed)" if bonus else ""
    fig.suptitle((title or run_dir.name) + note, fontsize=10)
    for ax in (ax_r, ax_l):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    out_png = Path(out_png)
    fig.savefig(out_png, dpi=100)
    plt.close(fig)
    return out_png


def package_run(run_dir: str | Path, out_dir: str | Path, *, which: str = "best", overwrite: bool = False) -> Path:
    """Copy a run into a shipped agent folder (see the module docstring).

    Args:
        run_dir: The run directory (``runs/.../<algo>_<seed>``).
        out_dir: The agent folder to write (``trained_agents/<name>``).
        which: ``best`` (the evaluation callback's best model; falls back to ``final`` if the run has none)
            or ``final``.
        overwrite: Replace an existing folder's files.

    Returns:
        The agent folder.

    Raises:
        FileExistsError: ``out_dir`` exists and is not empty and ``overwrite`` is false.
        FileNotFoundError: The run has no such model.
        ValueError: The model is larger than 5 MB.
    """
    run_dir, out_dir = Path(run_dir), Path(out_dir)
    which, model, stats = _chosen_model(run_dir, out_dir, which, overwrite)
    out_dir.mkdir(parents=True, exist_ok=True)
    shutil.copy2(model, out_dir / SHIPPED_MODEL)
    if stats.is_file():
        shutil.copy2(stats, out_dir / SHIPPED_STATS)
    elif (out_dir / SHIPPED_STATS).exists():
        (out_dir / SHIPPED_STATS).unlink()
    shutil.copy2(run_dir / "config.yml", out_dir / "config.yml")
    copy_learning_curve(run_dir, out_dir)

    _copy_training_logs(run_dir, out_dir)
    meta, resolved = _meta_with_shipped_record(run_dir, model, which)
    (out_dir / "meta.json").write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
    plot_training_curve(run_dir, out_dir / "training_curve.png", title=f"{out_dir.name}: {resolved['env_id']}")
    write_readme(out_dir)
    return out_dir


def _chosen_model(run_dir: Path, out_dir: Path, which: str, overwrite: bool) -> tuple[str, Path, Path]:
    """``(which, model zip, VecNormalize file)`` to ship (``best`` falls back to ``final``), checked."""
    if which not in ("best", "final"):
        raise ValueError(f"which must be 'best' or 'final', got {which!r}")
    if out_dir.exists() and any(out_dir.iterdir()) and not overwrite:
        raise FileExistsError(f"{out_dir} is not empty (overwrite=True to replace)")
    if which == "best" and not (run_dir / "best_model.zip").is_file():
        which = "final"
    model = run_dir / f"{which}_model.zip"
    stats = run_dir / ("best_vecnormalize.pkl" if which == "best" else "vecnormalize.pkl")
    if not model.is_file():
        raise FileNotFoundError(model)
    if model.stat().st_size > MAX_MODEL_BYTES:
        raise ValueError(f"{model} is {model.stat().st_size / 2**20:.1f} MB (> 5 MB)")
    return which, model, stats


def _copy_training_logs(run_dir: Path, out_dir: Path) -> None:
    """The run's monitor files, ``progress.csv`` and ``evaluations.npz`` into ``<out_dir>/training_logs``."""
    logs = out_dir / "training_logs"
    if logs.exists():
        shutil.rmtree(logs)
    logs.mkdir()
    for path in sorted((run_dir / "monitor").glob("*.monitor.csv")):
        shutil.copy2(path, logs / path.name)
    for path in sorted((run_dir / "logs").glob("seg*/*")):
        if path.name in ("progress.csv", "evaluations.npz"):
            shutil.copy2(path, logs / f"{path.parent.name}_{path.name}")


def _meta_with_shipped_record(run_dir: Path, model: Path, which: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """The run's ``meta.json`` with a ``shipped`` record (model, budget, seeds, env, versions); and its config."""
    meta = json.loads((run_dir / "meta.json").read_text(encoding="utf-8"))
    resolved = yaml.safe_load((run_dir / "config.yml").read_text(encoding="utf-8"))
    segments = meta.get("segments", [])
    shipped: dict[str, Any] = {
        "which": which,
        "source_run": str(run_dir),
        "model_num_timesteps": zip_num_timesteps(model),
        "budget_timesteps": int(sum(s.get("requested_timesteps", 0) for s in segments)),
        "trained_timesteps": int(segments[-1].get("end_num_timesteps") or 0) if segments else 0,
        "wall_time_s": round(float(sum(s.get("wall_time_s", 0.0) for s in segments)), 1),
        "seed": resolved["seed"],
        "training_env_seeds": [seed for s in segments for seed in s.get("train_env_seeds", [])],
        "eval_callback_seeds": segments[0].get("eval_env_seeds", []) if segments else [],
        "env_id": resolved["env_id"],
        "env_kwargs": resolved["config"].get("env_kwargs", {}),
        "alive_bonus": resolved["config"].get("alive_bonus", 0.0),
        "action_scale": resolved["config"].get("action_scale", 1.0),
        "packaged_with": {"versions": package_versions(), "git": git_info()},
    }
    if which == "best" and (run_dir / "best_model.json").is_file():
        shipped["best_model"] = json.loads((run_dir / "best_model.json").read_text(encoding="utf-8"))
    meta["shipped"] = shipped
    return meta, resolved


TASK_KEYS = ("case", "goal", "action_mode")
"""``env_kwargs`` keys that define an agent's evaluation task (training-only keys such as ``effort_weight`` are
left out: evaluation uses the environment's defaults)."""
README_SNIPPET_HEADING = "## With plain Stable-Baselines3"
"""Heading of the README section whose ``python`` block runs the agent without this project's loader."""


def plain_sb3_snippet(folder: str | Path, repo_relative: str | None = None) -> str:
    """Python code running a shipped agent with plain Stable-Baselines3 and Gymnasium (one episode).

    It applies what ``<ALGO>.load`` alone does not: the ``action_scale`` of the configuration (one
    ``gymnasium.wrappers.TransformAction``) and, when the run normalised observations, the statistics of
    ``vecnormalize.pkl`` (``VecNormalize.normalize_obs``). ``tests/docs/test_shipped_readmes.py`` runs this code
    from every README and checks that its actions equal :class:`agents.export.AgentController`'s.

    Args:
        folder: The agent folder (``model.zip``, ``config.yml``, optional ``vecnormalize.pkl``).
        repo_relative: The folder path written into the code (default ``trained_agents/<name>``).

    Returns:
        The code (no trailing fence).
    """
    folder = Path(folder)
    resolved = yaml.safe_load((folder / "config.yml").read_text(encoding="utf-8"))
    algo_cls = resolved["algo"].upper()
    env_id = resolved["env_id"]
    config = resolved["config"]
    env_kwargs = config.get("env_kwargs", {})
    task = ", ".join(f"{k}={json.dumps(v)}" for k, v in env_kwargs.items() if k in TASK_KEYS)
    scale = float(config.get("action_scale", 1.0))
    stats = (folder / SHIPPED_STATS).is_file()
    module = "sb3_contrib" if resolved["algo"] == "tqc" else "stable_baselines3"
    lines = ["import gymnasium as gym", f"from {module} import {algo_cls}"]
    if stats:
        lines.append("from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize")
    lines += [
        "",
        "import uvdms_gym  # noqa: F401  (registers the environment ids)",
        "",
        f'folder = "{repo_relative or f"trained_agents/{folder.name}"}"',
        f'model = {algo_cls}.load(f"{{folder}}/model.zip", device="cpu")',
        f'env = gym.make("{env_id}", {task})',
    ]
    if scale != 1.0:
        lines.append(
            f"env = gym.wrappers.TransformAction(env, lambda a: {scale!r} * a, env.action_space)  "
            f"# action_scale {scale!r} (config.yml)"
        )
    if stats:
        lines.append(
            'stats = VecNormalize.load(f"{folder}/vecnormalize.pkl", DummyVecEnv([lambda: env]))  '
            "# observation statistics"
        )
    observation = "stats.normalize_obs(obs)" if stats else "obs"
    lines += [
        "obs, info = env.reset(seed=1000)",
        "episode_return, done = 0.0, False",
        "while not done:",
        f"    action, _ = model.predict({observation}, deterministic=True)",
        "    obs, reward, terminated, truncated, info = env.step(action)",
        "    episode_return += reward",
        "    done = terminated or truncated",
        'print(f"return {episode_return:.1f}")',
    ]
    return "\n".join(lines)


def write_readme(folder: str | Path) -> Path:
    """Write ``README.md`` of a shipped agent folder from its ``config.yml``, ``meta.json`` and ``evaluation.json``.

    Args:
        folder: The agent folder.

    Returns:
        The README path.
    """
    folder = Path(folder)
    resolved = yaml.safe_load((folder / "config.yml").read_text(encoding="utf-8"))
    meta = json.loads((folder / "meta.json").read_text(encoding="utf-8"))
    shipped = meta.get("shipped", {})
    algo, env_id, config = resolved["algo"], resolved["env_id"], resolved["config"]
    env_kwargs = config.get("env_kwargs", {})
    task = {k: v for k, v in env_kwargs.items() if k in TASK_KEYS}
    task_kv = " ".join(f"{k}={v}" for k, v in task.items())
    scale = float(config.get("action_scale", 1.0))
    stats = (folder / SHIPPED_STATS).is_file()
    name = folder.name
    which = "the evaluation callback's best model" if shipped.get("which") == "best" else "the final model"
    text = [
        f"# {name}: {algo.upper()} on `{env_id}` ({task_kv})",
        "",
        f"A Stable-Baselines3 {algo.upper()} agent for `{env_id}` with `{task_kv}`, trained by `uvdms train` "
        f"(seed {resolved['seed']}, budget {shipped.get('budget_timesteps', '?')} environment steps, "
        f"{shipped.get('wall_time_s', 0) / 60:.0f} min of training; `meta.json` has the seeds, package versions and "
        f"git revision, `config.yml` the full configuration). `model.zip` is {which} "
        f"({shipped.get('model_num_timesteps', '?')} steps)"
        + (", `vecnormalize.pkl` its observation normalisation." if stats else "."),
        "",
        "## Evaluation",
        "",
    ]
    evaluation = folder / "evaluation.json"
    if evaluation.is_file():
        data = json.loads(evaluation.read_text(encoding="utf-8"))
        summary, seeds = data["summary"], data["meta"]["seeds"]
        text.append(
            f"`evaluation.json` (`uvdms evaluate`, {len(seeds)} episodes, seeds {seeds[0]}-{seeds[-1]}, env kwargs "
            f"`{data['meta']['env_kwargs']}`): return {summary['return']:.1f}, position RMSE "
            f"{summary['rmse_pos']:.3f} m, {summary['contacts']:.2f} contact steps per episode, "
            f"{summary['steps']:.0f} steps per episode, success rate {summary['success_rate']:.0%}."
        )
    else:
        text.append("Not evaluated yet (`python -m scripts.evaluate_shipped` writes `evaluation.json`).")
    text += [
        "",
        "## With this project",
        "",
        f"`uvdms evaluate --controller trained_agents/{name} --env {env_id} --env-kwargs {task_kv} --episodes 10 "
        "--seed 1000` reproduces `evaluation.json`; in Python, "
        f'`agents.export.load_agent("trained_agents/{name}")` returns a controller whose `predict(obs)` applies '
        "the observation normalisation and the action scale.",
        "",
        README_SNIPPET_HEADING,
        "",
    ]
    needs = []
    if scale != 1.0:
        needs.append(
            f"**The action is scaled**: the agent was trained with `action_scale: {scale!r}` (`config.yml`), so the "
            f"environment must receive `{scale!r} * action`. `{algo.upper()}.load` does not know this; add the one "
            f"wrapper `gym.wrappers.TransformAction(env, lambda a: {scale!r} * a, env.action_space)` below (without "
            f"it every command is {1 / scale:.1f} times too large and the agent tracks worse)."
        )
    else:
        needs.append("No action scaling (`action_scale: 1.0`): the environment receives `model.predict`'s action.")
    if stats:
        needs.append(
            "Observations are normalised with the statistics of `vecnormalize.pkl` (`VecNormalize.normalize_obs`; "
            "loading it unpickles the file, as `model.zip` does: load only files you trust)."
        )
    text += [" ".join(needs), "", "From the repository root:", "", "```python", plain_sb3_snippet(folder), "```", ""]
    text.append(
        "The printed return is that of seed 1000; the task is deterministic, so it equals the mean return above."
    )
    path = folder / "README.md"
    path.write_text("\n".join(text) + "\n", encoding="utf-8")
    return path


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m scripts.ship_agent RUN_DIR OUT_DIR [--which best|final] [--overwrite]``."""
    parser = argparse.ArgumentParser(prog="python -m scripts.ship_agent", description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", type=Path, nargs="?")
    parser.add_argument("out_dir", type=Path, nargs="?")
    parser.add_argument("--which", choices=("best", "final"), default="best")
    parser.add_argument("--overwrite", action="store_true")
    parser.add_argument("--readme", type=Path, nargs="+", metavar="FOLDER", help="only rewrite these folders' README")
    args = parser.parse_args(argv)
    if args.readme:
        for folder in args.readme:
            print(write_readme(folder))
        return 0
    if args.run_dir is None or args.out_dir is None:
        parser.error("RUN_DIR and OUT_DIR are required unless --readme is given")
    try:
        out = package_run(args.run_dir, args.out_dir, which=args.which, overwrite=args.overwrite)
    except (FileExistsError, FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
