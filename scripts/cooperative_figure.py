"""Draw the friction grasp over the paper transport: the cooperative CAMPC against today's CAMPC with a constant grip.

    python -m scripts.cooperative_figure [--out docs/figures] [--json PATH]

Runs ``campc-coop`` and ``campc`` (the ablation: a constant grip of ``grip_initial``) on
``uvdms/CooperativeTransport-v1`` with the paper's goal (deterministic: one episode each) and writes
``cooperative_transport.png``: per controller over time, each hand's slip (mm), the internal force along the object
(N, positive: stretch), the left hand's load share and the grip forces (N). Prints a markdown summary table
(``docs/cooperative.md`` quotes it) and, with ``--json``, writes the series.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import uvdms_gym  # noqa: F401  (registers the environments)
from baselines.controllers import make_baseline
from uvdms_gym.utils.io import write_json_atomic

LOG = logging.getLogger("cooperative_figure")
ENV_ID = "uvdms/CooperativeTransport-v1"
CONTROLLERS: tuple[str, ...] = ("campc-coop", "campc")
"""The cooperative CAMPC and the ablation (today's CAMPC with a constant grip)."""
SERIES: tuple[str, ...] = ("t", "slip_left", "slip_right", "internal_force", "share_left", "grip_left", "grip_right")


def run(name: str) -> dict[str, Any]:
    """One paper-transport episode of baseline ``name``: the series of :data:`SERIES` and the episode's outcome."""
    env = gym.make(ENV_ID, goal="paper")
    try:
        controller = make_baseline(name, env)
        obs, info = env.reset(seed=0)
        controller.reset(0)
        rows = [_row(info)]
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(controller.predict(obs, info))
            rows.append(_row(info))
            done = terminated or truncated
        series = {key: [r[k] for r in rows] for k, key in enumerate(SERIES)}
        outcome = {
            "success": bool(info["is_success"] and not terminated),
            "dropped": bool(info["dropped"]),
            "crushed": bool(info["crushed"]),
            "slip_max_mm": 1e3 * float(info["slip_max"]),
            "internal_force_max": float(np.max(np.abs(series["internal_force"]))),
            "final_error_mm": 1e3 * float(info["tracking_error"]),
            "steps": len(rows) - 1,
        }
        return {"series": series, "outcome": outcome}
    finally:
        env.close()


def _row(info: dict[str, Any]) -> tuple[float, ...]:
    s = 1e3 * np.asarray(info["slip_distance"])
    return (
        float(info["t"]),
        float(s[0]),
        float(s[1]),
        float(info["internal_force"]),
        float(info["load_share"][0]),
        float(info["grip"][0]),
        float(info["grip"][1]),
    )


def draw(results: dict[str, dict[str, Any]], path: Path) -> None:
    """The four panels of the module docstring, one line style per controller."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(4, 1, figsize=(7.5, 8.5), sharex=True)
    styles = {"campc-coop": "-", "campc": "--"}
    for name, res in results.items():
        s, ls = res["series"], styles.get(name, ":")
        axes[0].plot(s["t"], s["slip_left"], ls, color="tab:blue", label=f"{name}, left")
        axes[0].plot(s["t"], s["slip_right"], ls, color="tab:orange", label=f"{name}, right")
        axes[1].plot(s["t"], s["internal_force"], ls, color="tab:red", label=name)
        axes[2].plot(s["t"], s["share_left"], ls, color="tab:green", label=name)
        axes[3].plot(s["t"], s["grip_left"], ls, color="tab:blue", label=f"{name}, left")
        axes[3].plot(s["t"], s["grip_right"], ls, color="tab:orange", label=f"{name}, right")
    labels = ("slip (mm)", "internal force (N)\n+ stretch", "left hand's\nload share", "grip force (N)")
    for ax, label in zip(axes, labels, strict=True):
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    axes[-1].set_xlabel("t (s)")
    title = "Paper transport, friction grasp: campc-coop (solid), campc with a constant grip (dashed)"
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def table(results: dict[str, dict[str, Any]]) -> str:
    """The outcomes as a markdown table."""
    head = "| controller | success | dropped | crushed | max slip (mm) | max internal force (N) | final error (mm) |"
    lines = [head, "|---|---|---|---|--:|--:|--:|"]
    for name, res in results.items():
        o = res["outcome"]
        lines.append(
            f"| {name} | {o['success']} | {o['dropped']} | {o['crushed']} | {o['slip_max_mm']:.2f} | "
            f"{o['internal_force_max']:.1f} | {o['final_error_mm']:.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Command line: see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/figures"), help="folder of the figure")
    parser.add_argument("--json", type=Path, default=None, help="also write the series and outcomes here")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    results = {name: run(name) for name in CONTROLLERS}
    draw(results, args.out / "cooperative_transport.png")
    if args.json is not None:
        write_json_atomic(args.json, results)
    print(table(results))  # the command's output


if __name__ == "__main__":
    main()
