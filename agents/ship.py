"""Package a training run as a shipped agent folder (``trained_agents/<name>/``) and plot its training curve.

Shipped agent folder::

    model.zip               the SB3 model (``best_model.zip`` or ``final_model.zip`` of the run)
    vecnormalize.pkl        its VecNormalize statistics (only when the run normalised observations)
    config.yml              the run's resolved configuration (algo, env id, env kwargs, seed, hyperparameters)
    meta.json               the run's meta.json plus a ``shipped`` record: which model, its steps, the budget,
                            the training wall time, the seeds, versions and git revision
    training_curve.png      environment return (alive bonus removed) vs timesteps, training episodes and the
                            evaluation callback's episodes
    training_logs/          the run's Monitor CSVs, progress.csv and evaluations.npz (small text/npz files)
    evaluation.json         written afterwards by ``uvdms evaluate --controller trained_agents/<name> ...``

:func:`agents.policy.load_agent` loads such a folder (``model.zip`` + ``vecnormalize.pkl``); pickles inside
the repository's ``trained_agents/`` are trusted (they are reviewed and committed).

Command line: ``python -m agents.ship RUN_DIR OUT_DIR [--which best|final]``.
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

from agents.policy import SHIPPED_MODEL, SHIPPED_STATS
from agents.train import git_info, package_versions, zip_num_timesteps

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
    out_dir.mkdir(parents=True, exist_ok=True)
    shutil.copy2(model, out_dir / SHIPPED_MODEL)
    if stats.is_file():
        shutil.copy2(stats, out_dir / SHIPPED_STATS)
    elif (out_dir / SHIPPED_STATS).exists():
        (out_dir / SHIPPED_STATS).unlink()
    shutil.copy2(run_dir / "config.yml", out_dir / "config.yml")

    logs = out_dir / "training_logs"
    if logs.exists():
        shutil.rmtree(logs)
    logs.mkdir()
    for path in sorted((run_dir / "monitor").glob("*.monitor.csv")):
        shutil.copy2(path, logs / path.name)
    for path in sorted((run_dir / "logs").glob("seg*/*")):
        if path.name in ("progress.csv", "evaluations.npz"):
            shutil.copy2(path, logs / f"{path.parent.name}_{path.name}")

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
    (out_dir / "meta.json").write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
    plot_training_curve(run_dir, out_dir / "training_curve.png", title=f"{out_dir.name}: {resolved['env_id']}")
    return out_dir


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m agents.ship RUN_DIR OUT_DIR [--which best|final] [--overwrite]``."""
    parser = argparse.ArgumentParser(prog="python -m agents.ship", description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--which", choices=("best", "final"), default="best")
    parser.add_argument("--overwrite", action="store_true")
    args = parser.parse_args(argv)
    try:
        out = package_run(args.run_dir, args.out_dir, which=args.which, overwrite=args.overwrite)
    except (FileExistsError, FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
