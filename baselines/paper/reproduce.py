"""``uvdms reproduce``: the paper's experiments on the simulator, as figures, a summary and acceptance checks.

Experiments (all with :func:`uvdms_gym.evaluation.run_episode`, seed 0 unless stated):

* Case 1 and Case 2 circle tracking (``uvdms/CircleTrack-v0``, ``case=1|2``, velocity mode,
  ``terminate_on_contact=False`` so that plain MPC runs on through its collisions), ``mpc`` vs ``campc``;
* object transport (``uvdms/Transport-v0``, torque mode) with ``campc-nndi``, the paper's full stack;
* ablation: ``campc-di`` vs ``campc-nndi`` with ``hydro_randomization=0.3`` over seeds 0-4, on Case 1 (the checked
  one), Case 2 and transport (the last two skipped with ``quick``);
* beyond the paper, its stated future work: the transport among moving outer obstacles
  (``uvdms/TransportObstacles-v1``, the scripted scenario of :mod:`baselines.paper.obstacle_figure`), ``campc`` with and
  without its outer-obstacle rows.

Figures (PNG, numbered like the paper's): ``fig07_case1_end_effectors.png``, ``fig08_case2_end_effectors.png``,
``fig09_min_distances.png``, ``fig11_object_pose.png``, ``fig12_vehicle_pose.png``, ``fig13_joint_angles.png``,
``fig14_velocities.png``, ``fig15_joint_velocities_torques.png``, ``fig16_vehicle_torques_nn.png``,
``ablation.png``, ``obstacles.png``; ``summary.md`` holds the numbers and the acceptance checks, ``results.json``
the per-episode metrics (without trajectories).

Acceptance checks (:func:`acceptance`): see ``docs/REPRODUCTION.md``. The figures are drawn by
:mod:`baselines.paper.figures`.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from baselines.paper.figures import ABLATION_SEEDS, ROW_RIGHT_LINK3_FRAME, ROW_RIGHT_LINK5_LEFT_ARM, make_figures
from baselines.paper.obstacle_figure import fig_obstacles, obstacle_checks, run_obstacle_experiment
from uvdms_gym.evaluation import run_episode
from uvdms_gym.physics.frames import wrap_angle
from uvdms_gym.physics.params import D1
from uvdms_gym.utils.io import write_json_atomic

CIRCLE = "uvdms/CircleTrack-v0"
TRANSPORT = "uvdms/Transport-v0"


def _episode(spec: str, env_id: str, env_kwargs: dict, seed: int = 0, save: bool = True) -> dict:
    import gymnasium as gym

    import uvdms_gym  # noqa: F401
    from baselines.controllers import BASELINES, make_baseline

    kwargs = {"action_mode": BASELINES[spec]["action_mode"], **env_kwargs}
    env = gym.make(env_id, **kwargs)
    try:
        return run_episode(env, make_baseline(spec, env), seed, save_trajectory=save)
    finally:
        env.close()


def _nearest_left_link(traj: dict, row: int) -> str | None:
    """Name of the left-arm link closest to the monitored right link at the time ``row`` is smallest."""
    from uvdms_gym import distances
    from uvdms_gym.physics.kinematics import KinematicModel

    d = np.array(traj["distances"])
    k = int(np.argmin(d[:, row]))
    kin = KinematicModel()
    kin.set_state(np.array(traj["eta"][k]), np.array(traj["q"][k]))
    res = distances.compute_distances(kin, "exact")
    return str(res.obstacle_frame[row])


def run_experiments(quick: bool = False, progress: bool = True) -> dict:
    """Run every experiment; return ``{name: episode dict (with trajectory)}`` plus ``ablation`` and timings.

    Args:
        quick: skip the Case 2 and transport ablations.
        progress: print one line per run to stderr.
    """
    import sys

    out: dict[str, Any] = {}
    t_all = time.perf_counter()

    def note(msg: str) -> None:
        if progress:
            sys.stderr.write(f"[reproduce {time.perf_counter() - t_all:6.1f} s] {msg}\n")
            sys.stderr.flush()

    for case in (1, 2):
        for spec in ("mpc", "campc"):
            note(f"case {case} {spec}")
            out[f"case{case}_{spec}"] = _episode(spec, CIRCLE, {"case": case, "terminate_on_contact": False})
    note("transport campc-nndi")
    out["transport"] = _episode("campc-nndi", TRANSPORT, {"terminate_on_contact": False})
    ablation: dict[str, dict[str, list[dict]]] = {}
    tasks = [("case1", CIRCLE, {"case": 1})]
    if not quick:
        tasks += [("case2", CIRCLE, {"case": 2}), ("transport", TRANSPORT, {})]
    for name, env_id, kw in tasks:
        ablation[name] = {}
        for spec in ("campc-di", "campc-nndi"):
            note(f"ablation {name} {spec} seeds {list(ABLATION_SEEDS)}")
            kwargs = {**kw, "hydro_randomization": 0.3, "terminate_on_contact": False}
            ablation[name][spec] = [_episode(spec, env_id, kwargs, s, save=False) for s in ABLATION_SEEDS]
    out["ablation"] = ablation
    note("outer obstacles campc, campc-inner")
    out["obstacles"] = run_obstacle_experiment()
    out["nearest_left_link_case2_mpc"] = _nearest_left_link(out["case2_mpc"]["trajectory"], ROW_RIGHT_LINK5_LEFT_ARM)
    out["wall_s"] = time.perf_counter() - t_all
    return out


# ---------------------------------------------------------------------------------------------------- numbers
def transport_numbers(ep: dict) -> dict:
    """The transport acceptance quantities of an episode with a trajectory."""
    tr = ep["trajectory"]
    t = np.array(tr["t"])
    y, y_ref, eta, q = (np.array(tr[k]) for k in ("y", "y_ref", "eta", "q"))
    return {
        "final_pos_error_m": float(np.linalg.norm(y[-1, :3] - y_ref[-1, :3])),
        "final_yaw_error_deg": float(abs(np.degrees(wrap_angle(y[-1, 5] - y_ref[-1, 5])))),
        "final_ori_error_deg": float(np.degrees(ep["final_ori_error"])),
        "max_roll_pitch_deg": float(np.degrees(np.abs(eta[t >= 0.0, 3:5]).max())),
        "max_joint_difference_deg": float(np.degrees(np.abs(q[:, :6] - q[:, 6:]).max())),
        "contacts": ep["contacts"],
        "rmse_pos_m": ep["rmse_pos"],
        "rmse_ori_deg": float(np.degrees(ep["rmse_ori"])),
        "is_success": ep["success"],
        "qp_unsolved": ep["qp_unsolved"],
        "qp_slack_max": ep["qp_slack_max"],
    }


def acceptance(res: dict) -> list[tuple[str, bool, str]]:
    """The acceptance checks: ``(name, passed, measured)`` for each (see ``docs/REPRODUCTION.md``)."""
    checks: list[tuple[str, bool, str]] = []

    def add(name: str, ok: bool, measured: str) -> None:
        checks.append((name, bool(ok), measured))

    for case, row, what in (
        (1, ROW_RIGHT_LINK3_FRAME, "right link 3 - right frame"),
        (2, ROW_RIGHT_LINK5_LEFT_ARM, "right link 5 - left arm"),
    ):
        mpc, campc = res[f"case{case}_mpc"], res[f"case{case}_campc"]
        d_mpc = mpc["min_distance_by_pair"][row]
        add(f"Case {case}: plain MPC drives {what} below d1 = 0.05 m", d_mpc < D1, f"min {d_mpc:.4f} m")
        add(
            f"Case {case}: CAMPC keeps all 18 distances >= d1 - 2 mm with zero contacts",
            campc["min_distance"] >= D1 - 2e-3 and campc["contacts"] == 0,
            f"min {campc['min_distance']:.4f} m, {campc['contacts']} contact steps",
        )
        add(
            f"Case {case}: CAMPC end-effector RMSE <= 3 cm and <= 2x plain MPC's",
            campc["rmse_pos"] <= 0.03 and campc["rmse_pos"] <= 2.0 * mpc["rmse_pos"],
            f"CAMPC {campc['rmse_pos'] * 1e3:.2f} mm, MPC {mpc['rmse_pos'] * 1e3:.2f} mm",
        )
    tn = transport_numbers(res["transport"])
    add(
        "Transport: final object position error <= 2 cm",
        tn["final_pos_error_m"] <= 0.02,
        f"{tn['final_pos_error_m'] * 100:.3f} cm",
    )
    add("Transport: final yaw error <= 2 deg", tn["final_yaw_error_deg"] <= 2.0, f"{tn['final_yaw_error_deg']:.3f} deg")
    add(
        "Transport: vehicle roll and pitch within 3 deg",
        tn["max_roll_pitch_deg"] <= 3.0,
        f"max {tn['max_roll_pitch_deg']:.2f} deg",
    )
    add("Transport: zero contacts", tn["contacts"] == 0, f"{tn['contacts']} contact steps")
    add(
        "Transport: both arms' joint angles equal within 1 deg",
        tn["max_joint_difference_deg"] <= 1.0,
        f"max {tn['max_joint_difference_deg']:.3f} deg",
    )
    abl = res["ablation"]["case1"]
    m_di = float(np.mean([e["rmse_pos"] for e in abl["campc-di"]]))
    m_nn = float(np.mean([e["rmse_pos"] for e in abl["campc-nndi"]]))
    add(
        "Ablation (Case 1, hydro_randomization 0.3, seeds 0-4): campc-nndi mean RMSE < campc-di's",
        m_nn < m_di,
        f"campc-nndi {m_nn * 1e3:.3f} mm, campc-di {m_di * 1e3:.3f} mm",
    )
    runs = [res[k] for k in ("case1_mpc", "case1_campc", "case2_mpc", "case2_campc", "transport")]
    for task in res["ablation"].values():
        for eps in task.values():
            runs += eps
    unsolved = sum(int(r["qp_unsolved"] or 0) for r in runs)
    slack = max(float(r["qp_slack_max"] or 0.0) for r in runs)
    add(
        "The QP never fails (every step 'solved'; slack reported)",
        unsolved == 0,
        f"{unsolved} unsolved, max slack {slack:.2e} m/s",
    )
    if "obstacles" in res:
        checks += obstacle_checks(res["obstacles"])
    return checks


# ---------------------------------------------------------------------------------------------------- figures
def _fmt_mm(x: float | None) -> str:
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x * 1e3:.2f}"


def summary_markdown(res: dict, checks: list[tuple[str, bool, str]], figures: list[Path]) -> str:
    """The ``summary.md`` text."""
    lines = ["# uvdms reproduce: summary", ""]
    lines += ["## Acceptance checks", "", "| check | result | measured |", "|---|---|---|"]
    lines += [f"| {name} | {'PASS' if ok else 'FAIL'} | {meas} |" for name, ok, meas in checks]
    lines += ["", "## Circle tracking (seed 0, velocity mode, terminate_on_contact=False)", ""]
    lines += [
        "| run | EE RMSE after 5 s (mm) | min distance (m) | right link 3 - frame (m) | right link 5 - left arm (m) "
        "| contact steps | zone steps | max QP slack (m/s) | ctrl ms |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for case in (1, 2):
        for spec in ("mpc", "campc"):
            ep = res[f"case{case}_{spec}"]
            dp = ep["min_distance_by_pair"]
            slack = ep["qp_slack_max"]
            lines.append(
                f"| Case {case} {spec.upper()} | {_fmt_mm(ep['rmse_pos'])} | {ep['min_distance']:.4f} "
                f"| {dp[ROW_RIGHT_LINK3_FRAME]:.4f} | {dp[ROW_RIGHT_LINK5_LEFT_ARM]:.4f} | {ep['contacts']} "
                f"| {ep['zone_steps']} | {0.0 if slack is None else slack:.1e} | {ep['controller_ms_median']:.2f} |"
            )
    nearest = res.get("nearest_left_link_case2_mpc")
    if nearest:
        lines += ["", f"Case 2, plain MPC: at its closest approach right link 5 is nearest to `{nearest}`."]
    tn = transport_numbers(res["transport"])
    lines += ["", "## Transport (campc-nndi, torque mode, seed 0)", "", "| quantity | value |", "|---|---|"]
    lines += [f"| {k} | {v:.4f} |" if isinstance(v, float) else f"| {k} | {v} |" for k, v in tn.items()]
    lines += ["", "## Ablation: campc-di vs campc-nndi, hydro_randomization = 0.3, seeds 0-4", ""]
    lines += [
        "| task | campc-di mean RMSE (mm) | campc-nndi mean RMSE (mm) | per seed di / nndi (mm) |",
        "|---|---|---|---|",
    ]
    for task, runs in res["ablation"].items():
        di = [e["rmse_pos"] for e in runs["campc-di"]]
        nn = [e["rmse_pos"] for e in runs["campc-nndi"]]
        per = ", ".join(f"{a * 1e3:.2f}/{b * 1e3:.2f}" for a, b in zip(di, nn))
        lines.append(f"| {task} | {np.mean(di) * 1e3:.3f} | {np.mean(nn) * 1e3:.3f} | {per} |")
    if "obstacles" in res:
        lines += ["", "## Outer obstacles (TransportObstacles-v1, scripted scenario, seed 0)", ""]
        lines += ["| run | contact steps | min gap (mm) | final error (mm) | success |", "|---|---|---|---|---|"]
        for name, run in res["obstacles"].items():
            lines.append(
                f"| {name} | {run['contacts']} | {run['gaps'].min() * 1e3:.1f} | {run['final_error_m'] * 1e3:.1f} "
                f"| {run['success']} |"
            )
    lines += ["", "## Figures", ""]
    lines += [f"![{p.stem}]({p.name})" for p in figures]
    lines += ["", f"Wall time of the experiments: {res.get('wall_s', float('nan')):.0f} s.", ""]
    return "\n".join(lines)


def _strip(ep: dict) -> dict:
    return {k: v for k, v in ep.items() if k != "trajectory"}


def reproduce(out: str | Path, *, check: bool = False, quick: bool = False, progress: bool = True) -> int:
    """Run the experiments, write figures, ``summary.md`` and ``results.json`` into ``out``.

    Args:
        out: output folder (created).
        check: return 1 (and print the failures) if an acceptance check fails.
        quick: fewer ablation runs (Case 1 only) and smaller figures.
        progress: progress lines on stderr.

    Returns:
        The exit code: 0, or 1 if ``check`` and a check failed.
    """
    import sys

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    res = run_experiments(quick=quick, progress=progress)
    checks = acceptance(res)
    figures = make_figures(res, out, dpi=80 if quick else 110)
    figures.append(fig_obstacles(res["obstacles"], out / "obstacles.png", dpi=80 if quick else 110))
    (out / "summary.md").write_text(summary_markdown(res, checks, figures), encoding="utf-8")
    flat = {
        k: (_strip(v) if isinstance(v, dict) and "trajectory" in v else v)
        for k, v in res.items()
        if k not in ("ablation", "obstacles")
    }
    flat["obstacles"] = {
        name: {k: run[k] for k in ("contacts", "success", "final_error_m")} | {"min_gap_m": float(run["gaps"].min())}
        for name, run in res["obstacles"].items()
    }
    flat["ablation"] = {t: {s: [_strip(e) for e in eps] for s, eps in r.items()} for t, r in res["ablation"].items()}
    flat["checks"] = [{"check": n, "passed": ok, "measured": m} for n, ok, m in checks]
    write_json_atomic(out / "results.json", flat)
    failed = [(n, m) for n, ok, m in checks if not ok]
    for name, ok, meas in checks:
        sys.stdout.write(f"{'PASS' if ok else 'FAIL'}  {name}: {meas}\n")
    sys.stdout.write(f"wrote {len(figures)} figures, summary.md and results.json to {out}\n")
    if check and failed:
        sys.stderr.write("uvdms reproduce --check: acceptance failed:\n")
        for name, meas in failed:
            sys.stderr.write(f"  - {name} (measured: {meas})\n")
        return 1
    return 0
