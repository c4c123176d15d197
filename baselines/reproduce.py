"""``uvdms reproduce``: the paper's experiments on the simulator, as figures, a summary and acceptance checks.

Experiments (all with :func:`uvdms_gym.evaluation.run_episode`, seed 0 unless stated):

* Case 1 and Case 2 circle tracking (``uvdms/CircleTrack-v0``, ``case=1|2``, velocity mode,
  ``terminate_on_contact=False`` so that plain MPC runs on through its collisions), ``mpc`` vs ``campc``;
* object transport (``uvdms/Transport-v0``, torque mode) with ``campc-nndi``, the paper's full stack;
* ablation: ``campc-di`` vs ``campc-nndi`` with ``hydro_randomization=0.3`` over seeds 0-4, on Case 1 (the checked
  one), Case 2 and transport (the last two skipped with ``quick``).

Figures (PNG, numbered like the paper's): ``fig07_case1_end_effectors.png``, ``fig08_case2_end_effectors.png``,
``fig09_min_distances.png``, ``fig11_object_pose.png``, ``fig12_vehicle_pose.png``, ``fig13_joint_angles.png``,
``fig14_velocities.png``, ``fig15_joint_velocities_torques.png``, ``fig16_vehicle_torques_nn.png``,
``ablation.png``; ``summary.md`` holds the numbers and the acceptance checks, ``results.json`` the per-episode
metrics (without trajectories).

Acceptance checks (:func:`acceptance`): see ``docs/REPRODUCTION.md``.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from uvdms_gym.evaluation import run_episode
from uvdms_gym.physics.frames import wrap_angle
from uvdms_gym.physics.params import D1, D2
from uvdms_gym.utils.io import write_json_atomic

ROW_RIGHT_LINK3_FRAME = 8
"""Distance row of right link 3 vs the nearest frame plate (rows 6-11: right links 1..6 vs plates)."""
ROW_RIGHT_LINK5_LEFT_ARM = 4
"""Distance row of right link 5 vs the left arm (rows 0-5: right links 1..6 vs the left arm)."""
ABLATION_SEEDS = (0, 1, 2, 3, 4)
CIRCLE = "uvdms/CircleTrack-v0"
TRANSPORT = "uvdms/Transport-v0"


def _episode(spec: str, env_id: str, env_kwargs: dict, seed: int = 0, save: bool = True) -> dict:
    import gymnasium as gym

    import uvdms_gym  # noqa: F401
    from baselines.controllers import BASELINES, make_controller

    kwargs = {"action_mode": BASELINES[spec]["action_mode"], **env_kwargs}
    env = gym.make(env_id, **kwargs)
    try:
        return run_episode(env, make_controller(spec, env), seed, save_trajectory=save)
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
    return checks


# ---------------------------------------------------------------------------------------------------- figures
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"font.size": 8, "axes.grid": True, "grid.alpha": 0.3, "lines.linewidth": 1.1})
    return plt


def _save(fig, path: Path, dpi: int) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path


def _arr(ep: dict, key: str) -> np.ndarray:
    return np.array(ep["trajectory"][key], dtype=float)


def fig_end_effectors(res: dict, case: int, path: Path, dpi: int) -> Path:
    """Paper Fig. 7/8: left (a) and right (b) end-effector positions x, y, z: reference, MPC and CAMPC."""
    plt = _plt()
    mpc, campc = res[f"case{case}_mpc"], res[f"case{case}_campc"]
    fig, axes = plt.subplots(3, 2, figsize=(9.0, 5.2), sharex=True)
    for side in range(2):
        for i, axis in enumerate("xyz"):
            ax = axes[i, side]
            col = 3 * side + i
            ax.plot(_arr(campc, "t"), _arr(campc, "y_ref")[:, col], color="k", ls=":", lw=1.2, label="reference")
            ax.plot(_arr(mpc, "t"), _arr(mpc, "y")[:, col], color="tab:blue", ls="--", lw=0.9, label="MPC")
            ax.plot(_arr(campc, "t"), _arr(campc, "y")[:, col], color="tab:orange", lw=0.9, label="CAMPC")
            ax.axvline(5.0, color="grey", lw=0.6, ls="-.")
            ax.set_ylabel(f"{axis} (m)")
        axes[0, side].set_title(f"({'ab'[side]}) {('left', 'right')[side]} end effector, Case {case} (NED)")
        axes[2, side].set_xlabel("t (s)")
    axes[0, 1].legend(fontsize=7, loc="upper right")
    return _save(fig, path, dpi)


def fig_min_distances(res: dict, path: Path, dpi: int) -> Path:
    """Paper Fig. 9: (a) right link 5 to the left arm (Case 2); (b) right link 3 to the frame (Case 1)."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.2))
    panels = (
        (2, ROW_RIGHT_LINK5_LEFT_ARM, "(a) right link 5 to the left arm, Case 2"),
        (1, ROW_RIGHT_LINK3_FRAME, "(b) right link 3 to the frame, Case 1"),
    )
    for ax, (case, row, title) in zip(axes, panels):
        for spec, style in (("mpc", "--"), ("campc", "-")):
            ep = res[f"case{case}_{spec}"]
            ax.plot(_arr(ep, "t"), _arr(ep, "distances")[:, row], ls=style, label=spec.upper())
        ax.axhline(D1, color="tab:red", lw=0.8, label="d1 = 0.05 m")
        ax.axhline(D2, color="tab:orange", lw=0.8, label="d2 = 0.12 m")
        if row == ROW_RIGHT_LINK3_FRAME:
            ax.axhline(0.027, color="k", lw=0.6, ls=":", label="contact (0.027 m)")
        else:
            ax.axhline(0.05, color="k", lw=0.6, ls=":", label="contact (0.05 m)")
        ax.set_ylim(0.0, 0.3)
        ax.set_title(title)
        ax.set_xlabel("t (s)")
        ax.set_ylabel("minimum distance (m)")
        ax.legend(fontsize=7)
    return _save(fig, path, dpi)


def _pose_figure(t, y, y_ref, title_pos, title_ang, path, dpi, ref_label="reference"):
    plt = _plt()
    fig, axes = plt.subplots(3, 2, figsize=(9.0, 5.2), sharex=True)
    for i, (axis, ang) in enumerate(zip("xyz", ("roll", "pitch", "yaw"))):
        axes[i, 0].plot(t, y[:, i], color="tab:blue", label="actual")
        axes[i, 1].plot(t, np.degrees(np.unwrap(y[:, 3 + i])), color="tab:blue", label="actual")
        if y_ref is not None:
            axes[i, 0].plot(t, y_ref[:, i], color="k", ls=":", lw=1.2, label=ref_label)
            axes[i, 1].plot(t, np.degrees(np.unwrap(y_ref[:, 3 + i])), color="k", ls=":", lw=1.2, label=ref_label)
        axes[i, 0].set_ylabel(f"{axis} (m)")
        axes[i, 1].set_ylabel(f"{ang} (deg)")
    axes[0, 0].set_title(title_pos)
    axes[0, 1].set_title(title_ang)
    axes[2, 0].set_xlabel("t (s)")
    axes[2, 1].set_xlabel("t (s)")
    if y_ref is not None:
        axes[0, 1].legend(fontsize=7)
    return _save(fig, path, dpi)


def fig_transport(res: dict, out: Path, dpi: int) -> list[Path]:
    """Paper Fig. 11-16 from the transport run."""
    ep = res["transport"]
    t = _arr(ep, "t")
    paths = [
        _pose_figure(
            t,
            _arr(ep, "y"),
            _arr(ep, "y_ref"),
            "(a) object position (NED)",
            "(b) object Euler angles (ZYX)",
            out / "fig11_object_pose.png",
            dpi,
        ),
        _pose_figure(
            t,
            _arr(ep, "eta"),
            None,
            "(a) vehicle position (NED)",
            "(b) vehicle Euler angles (ZYX)",
            out / "fig12_vehicle_pose.png",
            dpi,
        ),
    ]
    paths.append(_fig_joint_angles(ep, t, out, dpi))
    paths.append(_fig_velocities(ep, t, out, dpi))
    paths.append(_fig_joint_velocities_torques(ep, t, out, dpi))
    paths.append(_fig_vehicle_torques_nn(ep, t, out, dpi))
    return paths


def _fig_joint_angles(ep: dict, t: np.ndarray, out: Path, dpi: int) -> Path:
    """Paper Fig. 13: the joint angles of both arms."""
    plt = _plt()
    q = np.degrees(_arr(ep, "q"))
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.2), sharey=True)
    for side, ax in enumerate(axes):
        for j in range(6):
            ax.plot(t, q[:, 6 * side + j], label=f"q{j + 1}")
        ax.set_title(f"({'ab'[side]}) joints of the {('left', 'right')[side]} arm")
        ax.set_xlabel("t (s)")
    axes[0].set_ylabel("deg")
    axes[1].legend(fontsize=7, ncol=2)
    return _save(fig, out / "fig13_joint_angles.png", dpi)



def _fig_velocities(ep: dict, t: np.ndarray, out: Path, dpi: int) -> Path:
    """Paper Fig. 14: the object's NED rates and the vehicle's body velocity."""
    plt = _plt()
    y = _arr(ep, "y")
    y_u = np.concatenate([y[:, :3], np.unwrap(y[:, 3:], axis=0)], axis=1)
    v_obj = np.gradient(y_u, t, axis=0)
    nu = _arr(ep, "nu")
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.2))
    for i, name in enumerate(("dx/dt", "dy/dt", "dz/dt")):
        axes[0].plot(t, v_obj[:, i], label=f"{name} (m/s)")
    for i, name in enumerate(("droll/dt", "dpitch/dt", "dyaw/dt")):
        axes[0].plot(t, v_obj[:, 3 + i], ls="--", label=f"{name} (rad/s)")
    for i, name in enumerate(("u", "v", "w")):
        axes[1].plot(t, nu[:, i], label=f"{name} (m/s)")
    for i, name in enumerate(("p", "q", "r")):
        axes[1].plot(t, nu[:, 3 + i], ls="--", label=f"{name} (rad/s)")
    axes[0].set_title("(a) object velocity (NED rates)")
    axes[1].set_title("(b) vehicle body velocity")
    for ax in axes:
        ax.set_xlabel("t (s)")
        ax.legend(fontsize=6, ncol=2)
    return _save(fig, out / "fig14_velocities.png", dpi)



def _fig_joint_velocities_torques(ep: dict, t: np.ndarray, out: Path, dpi: int) -> Path:
    """Paper Fig. 15: joint velocities and torques (solid left, dashed right)."""
    plt = _plt()
    qd = _arr(ep, "qdot")
    tau = _arr(ep, "tau")
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.2))
    for j in range(6):
        axes[0].plot(t, qd[:, j], label=f"left q{j + 1}")
        axes[0].plot(t, qd[:, 6 + j], ls="--", color=axes[0].lines[-1].get_color(), label=f"right q{j + 1}")
        axes[1].plot(t[1:], tau[1:, 6 + j], label=f"left {j + 1}")
        axes[1].plot(t[1:], tau[1:, 12 + j], ls="--", color=axes[1].lines[-1].get_color(), label=f"right {j + 1}")
    axes[0].set_title("(a) joint velocities (solid left, dashed right)")
    axes[0].set_ylabel("rad/s")
    axes[1].set_title("(b) joint torques (solid left, dashed right)")
    axes[1].set_ylabel("N m")
    for ax in axes:
        ax.set_xlabel("t (s)")
        ax.legend(fontsize=6, ncol=3)
    return _save(fig, out / "fig15_joint_velocities_torques.png", dpi)



def _fig_vehicle_torques_nn(ep: dict, t: np.ndarray, out: Path, dpi: int) -> Path:
    """Paper Fig. 16: the vehicle's generalized force and the RBF network's compensation."""
    plt = _plt()
    tau = _arr(ep, "tau")
    nn = ep["trajectory"]["nn_output"]
    nn_arr = np.array([np.zeros(18) if v is None else v for v in nn], dtype=float) if nn is not None else None
    fig, axes = plt.subplots(1, 3, figsize=(12.0, 3.2))
    for i, name in enumerate(("X", "Y", "Z", "K", "M", "N")):
        axes[0].plot(t[1:], tau[1:, i], ls="-" if i < 3 else "--", label=f"{name} ({'N' if i < 3 else 'N m'})")
        if nn_arr is not None:
            axes[1].plot(t[1:], nn_arr[1:, i], ls="-" if i < 3 else "--", label=("u", "v", "w", "p", "q", "r")[i])
    if nn_arr is not None:
        for j in range(12):
            axes[2].plot(t[1:], nn_arr[1:, 6 + j], lw=0.8, ls="-" if j < 6 else "--")
    axes[0].set_title("(a) vehicle generalized force")
    axes[1].set_title("(b) NN compensation, vehicle DOFs")
    axes[2].set_title("(c) NN compensation, joints (solid left, dashed right)")
    axes[1].set_ylabel("m/s^2, rad/s^2")
    axes[2].set_ylabel("rad/s^2")
    for ax in axes:
        ax.set_xlabel("t (s)")
    axes[0].legend(fontsize=6, ncol=2)
    axes[1].legend(fontsize=6, ncol=2)
    return _save(fig, out / "fig16_vehicle_torques_nn.png", dpi)


def fig_ablation(res: dict, path: Path, dpi: int) -> Path:
    """Per-seed tracking RMSE of campc-di vs campc-nndi under hydrodynamic randomisation."""
    plt = _plt()
    abl = res["ablation"]
    fig, axes = plt.subplots(1, len(abl), figsize=(3.6 * len(abl), 3.0), squeeze=False)
    for ax, (task, runs) in zip(axes[0], abl.items()):
        x = np.arange(len(ABLATION_SEEDS))
        for k, (spec, color) in enumerate((("campc-di", "tab:gray"), ("campc-nndi", "tab:blue"))):
            vals = [e["rmse_pos"] * 1e3 for e in runs[spec]]
            ax.bar(x + (k - 0.5) * 0.38, vals, 0.38, color=color, label=f"{spec} (mean {np.mean(vals):.2f})")
        ax.set_xticks(x, [str(s) for s in ABLATION_SEEDS])
        ax.set_xlabel("seed")
        ax.set_ylabel("tracking RMSE (mm)")
        ax.set_title(f"{task}, hydro randomisation 0.3")
        ax.legend(fontsize=7)
    return _save(fig, path, dpi)


def make_figures(res: dict, out: Path, dpi: int = 110) -> list[Path]:
    """Write every figure into ``out``; return the paths."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [
        fig_end_effectors(res, 1, out / "fig07_case1_end_effectors.png", dpi),
        fig_end_effectors(res, 2, out / "fig08_case2_end_effectors.png", dpi),
        fig_min_distances(res, out / "fig09_min_distances.png", dpi),
    ]
    paths += fig_transport(res, out, dpi)
    paths.append(fig_ablation(res, out / "ablation.png", dpi))
    return paths


# ---------------------------------------------------------------------------------------------------- summary
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
    (out / "summary.md").write_text(summary_markdown(res, checks, figures), encoding="utf-8")
    flat = {
        k: (_strip(v) if isinstance(v, dict) and "trajectory" in v else v) for k, v in res.items() if k != "ablation"
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
