"""``uvdms demo``: drop the vehicle in the water with the arms holding a pose and print a state trace.

The vehicle gets no thrust, so the whole system (about 165 N heavier than the water it displaces) sinks
toward its terminal heave speed while the restoring moment keeps it level; the arms hold the circle task's
initial joint angles with a joint-space PD plus gravity/buoyancy compensation from the nominal model.
"""

from __future__ import annotations

import logging
import math
import sys
import time
from pathlib import Path

import numpy as np

from uvdms_gym.envs.references import CIRCLE_VEHICLE_START
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.nominal import NominalDynamics
from uvdms_gym.physics.params import CIRCLE_Q0_LEFT_DEG, CIRCLE_Q0_RIGHT_DEG, UVDMSParams
from uvdms_gym.physics.sim import UVDMSSim

log = logging.getLogger(__name__)

HOLD_STIFFNESS = 200.0
"""Joint PD stiffness, N m / rad."""
HOLD_DAMPING = 20.0
"""Joint PD damping, N m s / rad."""


def run_demo(seconds: float = 5.0, gui: bool = False, png: str | None = None, trace_every: float = 0.5) -> list[dict]:
    """Simulate the drop and write a trace table to stdout; return the trace rows.

    Args:
        seconds: simulated time.
        gui: open the PyBullet GUI (real-time pacing).
        png: save a rendered frame at the end to this path.
        trace_every: trace period, s.

    Raises:
        ValueError: ``seconds`` or ``trace_every`` not a finite positive number.
        FileNotFoundError: the folder of ``png`` does not exist (checked before simulating).
        DisplayUnavailableError: ``gui`` without a display (:mod:`uvdms_gym.utils.display`).
    """
    for name, value in (("seconds", seconds), ("trace_every", trace_every)):
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f"{name} must be a finite duration > 0 s, got {value}")
    if png is not None:
        folder = Path(png).resolve().parent
        if not folder.is_dir():
            raise FileNotFoundError(f"cannot save the frame to {png}: folder {folder} does not exist")
    params = UVDMSParams()
    q_hold = np.radians(np.array(CIRCLE_Q0_LEFT_DEG + CIRCLE_Q0_RIGHT_DEG))
    kin = KinematicModel(params)
    nominal = NominalDynamics(kin)
    rows: list[dict] = []
    with UVDMSSim(params, gui=gui) as sim:
        sim.reset(np.array(CIRCLE_VEHICLE_START), q=q_hold)
        dt = sim.physics_dt
        n = round(seconds / dt)
        every = max(1, round(trace_every / dt))
        sys.stdout.write(
            f"{'t [s]':>6} {'depth z [m]':>11} {'roll [deg]':>10} {'pitch [deg]':>11} {'w [m/s]':>8} "
            f"{'max |q-q0| [deg]':>16}\n"
        )
        for k in range(n + 1):
            st = sim.state()
            if k % every == 0:
                row = {
                    "t": round(st.t, 3),
                    "z": float(st.eta[2]),
                    "roll_deg": float(np.degrees(st.eta[3])),
                    "pitch_deg": float(np.degrees(st.eta[4])),
                    "w": float(st.nu[2]),
                    "max_joint_dev_deg": float(np.degrees(np.abs(st.q - q_hold).max())),
                }
                rows.append(row)
                sys.stdout.write(
                    f"{row['t']:6.2f} {row['z']:11.4f} {row['roll_deg']:10.3f} {row['pitch_deg']:11.3f} "
                    f"{row['w']:8.4f} {row['max_joint_dev_deg']:16.3f}\n"
                )
            if k == n:
                break
            kin.set_state(st.eta, st.q)
            tau = np.zeros(18)
            tau[6:] = nominal.static_force()[6:] + HOLD_STIFFNESS * (q_hold - st.q) - HOLD_DAMPING * st.qdot
            sim.step(tau)
            if gui:
                time.sleep(dt)
        if png:
            from PIL import Image

            Image.fromarray(sim.render_rgb(640, 480)).save(png)
            log.info("saved a frame to %s", png)
    return rows
