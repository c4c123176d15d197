"""The figures of ``uvdms reproduce`` (:mod:`baselines.paper.reproduce`), numbered like the paper's.

``fig07``/``fig08`` end effectors against their circles, ``fig09`` the minimum distances, ``fig11``-``fig16`` the
transport run (object and vehicle pose, joint angles, velocities, torques, the RBF network's output) and the
ablation; :func:`make_figures` writes them all from the results of :func:`baselines.paper.reproduce.run_experiments`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from uvdms_gym.physics.params import D1, D2

ROW_RIGHT_LINK3_FRAME = 8
"""Distance row of right link 3 vs the nearest frame plate (rows 6-11: right links 1..6 vs plates)."""
ROW_RIGHT_LINK5_LEFT_ARM = 4
"""Distance row of right link 5 vs the left arm (rows 0-5: right links 1..6 vs the left arm)."""
ABLATION_SEEDS = (0, 1, 2, 3, 4)
"""Seeds of the ablation (``campc-di`` vs ``campc-nndi`` under hydrodynamic randomisation)."""


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
