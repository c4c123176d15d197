"""The outer-obstacle experiment of ``uvdms reproduce``: a scripted scenario, CAMPC with and without its outer rows.

The paper names moving outer obstacles as future work; ``uvdms/TransportObstacles-v1`` adds them.
:data:`OBSTACLE_SCENARIO` is one scripted scenario (two drifting pipes and a piece of debris crossing the paper's
transport, drawn once by the random generator and rounded), run with ``campc`` (its outer rows on, the default in
an environment with obstacles) and ``campc-inner`` (the same controller without them), ``terminate_on_contact=False``
so that both runs last the whole episode. :func:`fig_obstacles` draws the object's path against the obstacles' and
the smallest gap to each obstacle over time.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

OBSTACLE_ENV = "uvdms/TransportObstacles-v1"
OBSTACLE_SCENARIO: tuple[dict[str, Any], ...] = (
    {
        "shape": "capsule",
        "radius": 0.055,
        "length": 0.296,
        "axis": [0.443, 0.897, 0.0],
        "position": [0.764, 1.283, 27.384],
        "velocity": [0.154, -0.076, 0.096],
    },
    {
        "shape": "capsule",
        "radius": 0.032,
        "length": 0.276,
        "axis": [0.895, 0.447, 0.0],
        "position": [2.409, -0.026, 29.663],
        "velocity": [-0.039, 0.078, -0.039],
    },
    {"shape": "sphere", "radius": 0.07, "position": [3.214, 1.375, 29.902], "velocity": [-0.142, -0.067, -0.054]},
)
"""The scripted scenario (``obstacles=`` keyword list; NED m, m/s)."""
OBSTACLE_RUNS = ("campc", "campc-inner")


def run_obstacle_experiment() -> dict[str, dict[str, Any]]:
    """Run :data:`OBSTACLE_SCENARIO` with each of :data:`OBSTACLE_RUNS` (seed 0); return their time series.

    Per run: ``t``, the object's position ``y`` and reference ``y_ref`` (first 3 columns), the obstacles'
    centres ``obstacles`` (T, K, 3), the smallest gap to each obstacle ``gaps`` (T, K), and the counts ``contacts``
    (steps with a contact), ``success`` and the final position error ``final_error_m``.
    """
    import gymnasium as gym

    import uvdms_gym  # noqa: F401
    from baselines.controllers import make_baseline

    out = {}
    for name in OBSTACLE_RUNS:
        env = gym.make(OBSTACLE_ENV, obstacles=list(OBSTACLE_SCENARIO), terminate_on_contact=False)
        ctrl = make_baseline(name, env)
        obs, info = env.reset(seed=0)
        ctrl.reset(0)
        series: dict[str, list] = {"t": [], "y": [], "y_ref": [], "obstacles": [], "gaps": []}
        contacts = 0
        while True:
            obs, _, term, trunc, info = env.step(ctrl.predict(obs, info))
            series["t"].append(info["t"])
            series["y"].append(info["y"][:3])
            series["y_ref"].append(info["y_ref"][:3])
            series["obstacles"].append(info["obstacles"][:, :3])
            series["gaps"].append(info["obstacle_distances"].min(axis=1))
            contacts += int(info["obstacle_contacts"] > 0)
            if term or trunc:
                break
        env.close()
        run = {k: np.array(v) for k, v in series.items()}
        run.update(contacts=contacts, success=bool(info["is_success"]), final_error_m=float(info["tracking_error"]))
        out[name] = run
    return out


def obstacle_checks(runs: dict[str, dict[str, Any]]) -> list[tuple[str, bool, str]]:
    """Acceptance of the experiment: CAMPC with outer rows clears every obstacle; without them it touches one."""
    outer, inner = runs["campc"], runs["campc-inner"]
    return [
        (
            "Obstacles (scripted): CAMPC with outer rows, zero contacts and success",
            outer["contacts"] == 0 and outer["success"],
            f"min gap {outer['gaps'].min() * 1e3:.1f} mm, final error {outer['final_error_m'] * 1e3:.1f} mm",
        ),
        (
            "Obstacles (scripted): CAMPC without outer rows touches an obstacle",
            inner["contacts"] > 0,
            f"{inner['contacts']} contact steps, min gap {inner['gaps'].min() * 1e3:.1f} mm",
        ),
    ]


def fig_obstacles(runs: dict[str, dict[str, Any]], path: Path, dpi: int) -> Path:
    """Object paths and obstacle paths (top and side views), and the smallest gap to each obstacle over time."""
    from baselines.paper.figures import _plt, _save

    plt = _plt()
    fig, axes = plt.subplots(1, 3, figsize=(11.0, 3.4))
    styles = {"campc": ("tab:orange", "-", "CAMPC, outer rows"), "campc-inner": ("tab:blue", "--", "without")}
    ref = runs["campc"]
    for ax, (i, j, xl, yl) in zip(axes[:2], ((1, 0, "y (m)", "x (m)"), (0, 2, "x (m)", "z (m, down)"))):
        ax.plot(ref["y_ref"][:, i], ref["y_ref"][:, j], color="k", ls=":", lw=1.0, label="reference")
        for name, run in runs.items():
            color, ls, label = styles[name]
            ax.plot(run["y"][:, i], run["y"][:, j], color=color, ls=ls, lw=1.0, label=label)
        for k in range(ref["obstacles"].shape[1]):
            ax.plot(ref["obstacles"][:, k, i], ref["obstacles"][:, k, j], color="tab:red", lw=0.8, alpha=0.7)
            ax.plot(*ref["obstacles"][0, k, [i, j]], "o", color="tab:red", ms=3)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.set_aspect("equal", adjustable="datalim")
    axes[1].invert_yaxis()
    axes[0].set_title("object and obstacles (red), top view")
    axes[1].set_title("side view")
    axes[0].legend(fontsize=7)
    ax = axes[2]
    for name, run in runs.items():
        color, ls, label = styles[name]
        for k in range(run["gaps"].shape[1]):
            ax.plot(run["t"], run["gaps"][:, k], color=color, ls=ls, lw=0.9, label=label if k == 0 else None)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_ylim(-0.02, 0.6)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("smallest gap to each obstacle (m)")
    ax.set_title("gaps (contact at 0)")
    ax.legend(fontsize=7)
    return _save(fig, path, dpi)
