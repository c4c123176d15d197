"""``uvdms/CircleTrack-v0``: collision-risk circle tracking with both end effectors (paper Section 4.1)."""

from __future__ import annotations

from typing import Any

import numpy as np

from uvdms_gym.envs.base import UVDMSEnv
from uvdms_gym.envs.bounded_reward import BoundedReward
from uvdms_gym.envs.references import CircleTask, make_circle_task
from uvdms_gym.envs.tracking import errors_positions
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.render import FRONT_CAMERA_YAW_OFFSET_DEG, ReferenceScene

TRACKING_TRANSIENT = 5.0
"""Tracking metrics exclude the first seconds of a run (the end effectors start ~0.6 m from their circles,
docs/MODEL.md section 5); collision metrics cover the whole run."""
CIRCLE_MARKER_SAMPLES = 96
"""Points per period of a drawn reference circle (``rgb_array`` frames; the drawing resamples them by arc length)."""


class CircleTrackEnv(UVDMSEnv):
    """Both end effectors of the UVDMS track circles while the arms risk hitting each other and the frame.

    ## Description
    An underwater vehicle (18 DOF: 6 vehicle + 2 x 6 joints, PyBullet with added mass, damping and
    buoyancy on the hull and every link) starts at the paper's pose ``[2, 0, 3, 0, 0, 0]`` (NED) with its
    arms folded. Each end effector must track a circle in the vertical plane normal to the vehicle's x axis,
    mirror-symmetrically (both move inward together); the paper's Case 1 pushes the right arm's link 3 toward
    the right frame plate, Case 2 brings the right arm's link 5 close to the left arm's link 3.

    ## Action Space
    ``Box(-1, 1, (18,), float32)``. ``action_mode="velocity"`` (default): ``zeta_cmd = action * zeta_max``
    (body velocity of the vehicle, then left and right joint rates), tracked by the environment's built-in
    velocity loop (:mod:`uvdms_gym.envs.lowlevel`). ``action_mode="torque"``: ``tau = action * tau_max``
    (body wrench at the vehicle origin, then 12 joint torques). Entries outside [-1, 1] are clipped and
    flagged with ``info["action_clipped"]``; NaN/inf or a wrong shape raise ``ValueError``.

    ## Observation Space
    ``Box(-10, 10, (80,), float32)``, see :mod:`uvdms_gym.envs.base` (reference preview, attitude,
    velocities, joint sin/cos and rates, the 18 clearances).

    ## Rewards
    ``reward = reward_track + reward_orientation + reward_effort + reward_proximity + reward_contact`` with
    ``reward_track = -track_weight * mean end-effector position error (m)``, ``reward_orientation = 0``,
    ``reward_effort = -effort_weight * |action|^2 / 18``,
    ``reward_proximity = -proximity_weight * sum_i (1 - S(d_i))`` (velocity-damper shape, 0 beyond 0.12 m,
    1 per distance inside 0.05 m) and ``reward_contact = -contact_weight`` on a step with physical contact.
    Every term is <= 0, so with ``terminate_on_contact=True`` a policy that crashes early collects a shorter
    negative sum than one that keeps tracking: RL training adds a per-step constant (``alive_bonus`` of
    ``agents.config.schema.TrainConfig``), and the leaderboard ranks by contacts and tracking error, not by return.

    ## Costs
    Safety-Gymnasium convention: ``info["cost_contact"]`` = 1 if PyBullet reports a contact between robot
    parts during the step, ``info["cost_zone"]`` = 1 if any of the 18 distances is below ``d1 = 0.05 m``,
    ``info["cost"]`` their sum.

    ## Starting State
    Vehicle at ``[2, 0, 3, 0, 0, 0]``, at rest; joints at the paper's initial angles with the project's signs
    (``params.CIRCLE_Q0_*``), at rest. Deterministic; ``case="random"`` (and ``"mix"``) draws the circles.

    ## Episode End
    Terminated on physical contact (``terminate_on_contact=True``), when the mean tracking error exceeds
    ``max_tracking_error`` (2 m), or when the physics blows up (``info["physics_error"]``). Truncated by
    ``max_episode_steps`` (500 steps of 0.04 s = 20 s: the transient plus 1.5 circle periods).

    ## Arguments
    ``case`` (1, 2, ``"random"``, or ``"mix"``: each episode draws Case 1, Case 2 or a random circle with equal
    probability), ``left_center``/``right_center`` (NED m), ``radius`` (m), ``period``
    (s, default 10) override the case; an infeasible request raises ``ValueError``. Common arguments:
    ``action_mode``, ``control_dt`` (0.04 s), ``physics_dt`` (0.01 s), ``hydro_randomization`` (s in [0, 1):
    added mass, damping, buoyancy and link drag scaled per episode by factors in [1 - s, 1 + s]),
    ``current`` (``None``: still water; a NED vector of 3 floats, m/s, at most 2 m/s: a constant ocean current;
    ``"random"``: a per-episode current of at most 0.2 m/s varying slowly within the episode; every hydrodynamic
    load then acts on the velocity relative to the water, :mod:`uvdms_gym.physics.current`; ``info["current"]``
    reports it), ``terminate_on_contact``, ``track_weight``, ``orientation_weight``, ``effort_weight``,
    ``proximity_weight``, ``contact_weight``, ``max_tracking_error``, ``render_mode``
    (``"rgb_array"``/``"human"``), ``render_width``, ``render_height``.

    ## Version History
    * v0: initial release.
    """

    with_object = False
    episode_steps = 500
    tracking_transient = TRACKING_TRANSIENT
    camera_yaw_deg = FRONT_CAMERA_YAW_OFFSET_DEG  # the circles face forward

    def __init__(
        self,
        *,
        case: int | str = 1,
        left_center: tuple[float, float, float] | None = None,
        right_center: tuple[float, float, float] | None = None,
        radius: float | None = None,
        period: float = 10.0,
        **kwargs: Any,
    ) -> None:
        super().__init__(**kwargs)
        self.case = case
        self._task_kwargs = {
            "left_center": left_center,
            "right_center": right_center,
            "radius": radius,
            "period": period,
            "arm_bases_body": (np.array(self.params.arm_base_left), np.array(self.params.arm_base_right)),
        }
        try:  # validate now (an infeasible request fails at construction, not at reset)
            make_circle_task(case, np.random.default_rng(0), **self._task_kwargs)
        except ValueError:
            self.close()
            raise

    def _build_task(self, rng: np.random.Generator) -> CircleTask:
        return make_circle_task(self.case, rng, **self._task_kwargs)

    def _initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array(self.task.vehicle_start, dtype=float), np.array(self.task.q0, dtype=float)

    def _output(self) -> np.ndarray:
        return self._kin.ee_positions().reshape(6)

    def _output_at(self, kin: KinematicModel) -> tuple[np.ndarray, None]:
        return kin.ee_positions().reshape(6), None

    def _errors(self, y: np.ndarray, refs: np.ndarray, r_nb: np.ndarray) -> tuple[np.ndarray, float, float]:
        return errors_positions(y, refs, r_nb)

    def _reference_scene(self) -> ReferenceScene:
        """Both reference circles (closed polylines over one period) and the current reference points."""
        grid = np.linspace(0.0, self.task.period, CIRCLE_MARKER_SAMPLES + 1)  # the last point closes the circle
        ref = self.task.reference(grid)
        return ReferenceScene(paths=(ref[:, :3], ref[:, 3:]), points=self.task.reference(self.t).reshape(2, 3))


class CircleTrackV1Env(BoundedReward, CircleTrackEnv):
    """``uvdms/CircleTrack-v1``: :class:`~uvdms_gym.envs.circle.CircleTrackEnv` with the bounded v1 reward.

    ## Rewards
    ``reward = reward_track + reward_orientation + reward_effort + reward_proximity + reward_contact`` with
    ``reward_track = track_weight * exp(-e / track_scale)`` (``e``: mean end-effector position error, m),
    ``reward_orientation = 0``, ``reward_effort = effort_weight * (1 - |action|^2 / 18)``,
    ``reward_proximity = proximity_weight * mean_i S(d_i)`` (velocity-damper shape: 1 beyond 0.12 m, 0 inside
    0.05 m) and ``reward_contact = -contact_weight`` on a step with physical contact (which ends the episode).
    Every term but the contact penalty lies in ``[0, weight]``, so at equal tracking running to the time limit
    always beats ending the episode early. Defaults: :data:`~uvdms_gym.envs.bounded_reward.V1_WEIGHTS`,
    ``track_scale = 0.05 m``. The optional ``reward_precision = precision_weight * exp(-e / precision_scale)``
    (default weight 0, scale 0.01 m) is a narrow second tracking term for training with a wide ``track_scale``.

    Everything else (dynamics, task, observation, costs, episode end, ``max_episode_steps = 500``) is v0's.

    ## Version History
    * v1: bounded non-negative per-step reward and a contact penalty (v0: every term <= 0). Release 0.3.0 adds
      the optional keywords ``precision_weight`` and ``precision_scale`` (a narrow tracking term, off by
      default: the default reward is unchanged).
    * v0: initial release.
    """

    rewards_orientation = False
