"""What the friction grasp adds to a transport environment: two grip commands, the grasp's readings, its costs.

With ``grasp="friction"`` (:mod:`uvdms_gym.physics.grip`) a transport environment's action gains two values, the
grip force command of each hand, ``F = (a + 1) / 2 * grip_max`` (so ``-1`` opens the gripper and ``1`` squeezes at
its limit); the observation gains :data:`GRASP_OBS_DIM` values, what each gripper measures: its grip force over
``grip_max`` and the axial force its wrist transmits to the object over :data:`AXIAL_FORCE_SCALE` (a wrist
force-torque sensor; slip itself is not measured). :class:`GripChannel` does that bookkeeping and fills ``info``:

* ``grip`` (2, N), ``hand_forces`` (2, 6: each hand's wrench on the object, NED, about its centre);
* ``slip`` (2, 2: axial slip m, turn rad), ``slip_distance`` (2, m: how far each contact moved over the surface),
  ``slip_max`` (the largest ``slip_distance`` of either hand so far in the episode);
* ``internal_force`` (N): the squeeze (< 0) or stretch (> 0) along the object, half the difference of the hands'
  axial forces (the component of their wrenches that moves nothing: Erhart & Hirche 2015);
* ``load_share`` (2): each hand's part of the load it carries, ``|g_k| / (|g_left| + |g_right|)`` with ``g_k`` the
  hand's force less its internal part (``f_int`` along the axis, pulling the hands apart: ``g_left = F_left + f_int
  a``, ``g_right = F_right - f_int a``; 0.5 each when neither carries anything). The two ``g`` add up to the net force
  the hands exert and share its axial component equally: the split of an axial load between two sticking hands is
  statically indeterminate, and the internal force holds what differs.
* ``dropped`` (a hand's axial slip reached ``drop_slip``), ``crushed`` (a grip force above ``crush_force``): either
  ends the episode as a failure;
* the costs ``cost_slip`` (1 while a contact moves more than :data:`SLIP_STEP_TOLERANCE` in a step),
  ``cost_drop`` and ``cost_crush`` (1 at the step that dropped or crushed the object), added to ``info["cost"]``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from uvdms_gym.envs.tracking import OBS_CLIP
from uvdms_gym.physics.friction_grasp import FrictionGrasp
from uvdms_gym.physics.grip import FrictionGraspConfig

GRIP_ACTION_DIM = 2
"""Action values the friction grasp adds: the grip command of the left, then the right hand."""
GRASP_OBS_DIM = 4
"""Observation values it adds: grip force left, right (over ``grip_max``); axial wrist force left, right."""
AXIAL_FORCE_SCALE = 20.0
"""Scale of the observed axial wrist forces, N (the clip of the observation, 10, is then 200 N)."""
SLIP_STEP_TOLERANCE = 1.0e-4
"""Movement of a contact over the object's surface in one control step that counts as slipping, m."""


class GripChannel:
    """The friction grasp's action split, observation block and ``info`` keys for one environment.

    Args:
        config: the grasp's knobs.
    """

    def __init__(self, config: FrictionGraspConfig) -> None:
        self.config = config
        self._slip_prev = (0.0, 0.0)
        self._slip_max = 0.0

    def reset(self) -> None:
        """Start an episode (the grasp was attached with ``grip_initial``)."""
        self._slip_prev = (0.0, 0.0)
        self._slip_max = 0.0

    def grip_command(self, a: np.ndarray) -> tuple[float, float]:
        """The grip forces (N) of the last :data:`GRIP_ACTION_DIM` action values (in ``[-1, 1]``)."""
        g = self.config.grip_max
        return 0.5 * (float(a[-2]) + 1.0) * g, 0.5 * (float(a[-1]) + 1.0) * g

    def observe(self, grasp: FrictionGrasp, rot_object: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Fill ``info`` with the grasp's readings and costs (module docstring); return the observation block."""
        cfg = self.config
        forces = grasp.forces()
        axis = rot_object[:, 1].tolist()  # the object's axis (its y) in NED
        f = forces[:, :3].tolist()
        axial = [sum(a * b for a, b in zip(row, axis, strict=True)) for row in f]
        f_int = 0.5 * (axial[1] - axial[0])
        carried_l = math.dist([f[0][i] + f_int * axis[i] for i in range(3)], (0.0, 0.0, 0.0))  # internal part removed
        carried_r = math.dist([f[1][i] - f_int * axis[i] for i in range(3)], (0.0, 0.0, 0.0))
        carried = carried_l + carried_r
        share_left = carried_l / carried if carried > 1e-12 else 0.5
        slip = grasp.slip()
        (xl, tl), (xr, tr) = slip.tolist()
        rl, rr = cfg.torsion_radius
        dl, dr = math.hypot(xl, rl * tl), math.hypot(xr, rr * tr)
        moved = max(abs(dl - self._slip_prev[0]), abs(dr - self._slip_prev[1]))
        self._slip_prev = (dl, dr)
        self._slip_max = max(self._slip_max, dl, dr)
        gl, gr = grasp.grip
        dropped = max(abs(xl), abs(xr)) >= cfg.drop_slip
        crushed = max(gl, gr) > cfg.crush_force
        costs = {
            "cost_slip": 1.0 if moved > SLIP_STEP_TOLERANCE else 0.0,
            "cost_drop": 1.0 if dropped else 0.0,
            "cost_crush": 1.0 if crushed else 0.0,
        }
        info.update(
            grip=np.array([gl, gr]),
            hand_forces=forces,
            slip=slip,
            slip_distance=np.array([dl, dr]),
            slip_max=self._slip_max,
            internal_force=f_int,
            load_share=np.array([share_left, 1.0 - share_left]),
            dropped=dropped,
            crushed=crushed,
            **costs,
        )
        info["cost"] = info["cost"] + costs["cost_slip"] + costs["cost_drop"] + costs["cost_crush"]
        if dropped or crushed:
            info["is_success"] = False
        lim = OBS_CLIP
        return np.array(
            [
                gl / cfg.grip_max,
                gr / cfg.grip_max,
                min(max(axial[0] / AXIAL_FORCE_SCALE, -lim), lim),
                min(max(axial[1] / AXIAL_FORCE_SCALE, -lim), lim),
            ],
            np.float32,
        )
