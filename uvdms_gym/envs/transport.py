"""``uvdms/Transport-v0``: transport of a gripped cylinder along a reference (paper Section 4.2)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from uvdms_gym.envs.base import UVDMSEnv
from uvdms_gym.envs.bounded_reward import BoundedReward
from uvdms_gym.envs.grip_channel import GRASP_OBS_DIM, GRIP_ACTION_DIM, GripChannel
from uvdms_gym.envs.references import TransportTask, make_transport_task
from uvdms_gym.envs.tracking import errors_pose
from uvdms_gym.physics.frames import euler_to_rot, rot_to_euler
from uvdms_gym.physics.grip import parse_grasp
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.render import ReferenceScene
from uvdms_gym.physics.sim import UVDMSSim

SUCCESS_POSITION = 0.02
"""Success: object position error below this (m) ..."""
SUCCESS_ORIENTATION = np.radians(2.0)
"""... and orientation error below this (rad), once the reference holds (t >= move_time)."""
TRACKING_TRANSIENT = 0.0
"""The transport run starts on its reference: no transient is excluded from its tracking metrics."""
PATH_MARKER_SAMPLES = 96
"""Points of the drawn object path over the move (``rgb_array`` frames; the drawing resamples them by arc length)."""


def vehicle_pose_for_object(kin: KinematicModel, object_pose: np.ndarray) -> np.ndarray:
    """Vehicle pose ``eta`` that puts the gripped object at ``object_pose`` with all joints at zero.

    At ``q = 0`` the object frame is aligned with the body frame at a fixed body offset ``p0`` (model.py),
    so ``R_NB = R_NO`` and ``p_B = p_O - R_NO p0``.
    """
    kin.set_state(np.zeros(6), np.zeros(12))
    p0 = kin.object_pose("right")[0]
    r = euler_to_rot(object_pose[3:])
    return np.concatenate([object_pose[:3] - r @ p0, object_pose[3:]])


class TransportEnv(UVDMSEnv):
    """Both arms hold a cylinder (closed kinematic chain) and carry it along a reference to a goal pose.

    ## Description
    The UVDMS grips a solid cylinder (0.6 m x 0.05 m, 1100 kg/m^3) with both end effectors (two fixed
    constraints in PyBullet). The object pose ``[x y z phi theta psi]`` (NED, ZYX Euler) must follow a C2
    spline from the start pose through a mid waypoint to the goal (:mod:`uvdms_gym.envs.references`) and hold it.

    ## Action Space
    As in :class:`~uvdms_gym.envs.circle.CircleTrackEnv`: ``Box(-1, 1, (18,), float32)``, velocity mode
    (``zeta_cmd = action * zeta_max``, built-in velocity loop) or torque mode (``tau = action * tau_max``).

    ## Observation Space
    ``Box(-10, 10, (80,), float32)``, see :mod:`uvdms_gym.envs.base`; the preview blocks hold the object's
    position error and orientation error (rotation vector), body frame.

    ## Rewards
    ``reward_track = -track_weight * |p_ref - p| (m)``,
    ``reward_orientation = -orientation_weight * |rotation error| (rad)``, and the effort, proximity and
    contact terms of the circle task; the reward is their sum (every term <= 0: see the circle task's note
    on early termination).

    ## Costs
    ``info["cost_contact"]``, ``info["cost_zone"]``, ``info["cost"]`` as in the circle task.

    ## Starting State
    Object at ``start_pose`` (paper: ``[2, 1, 30, 0, 0, 0]``), all joints zero, vehicle placed accordingly,
    everything at rest.

    ## Episode End
    Terminated on contact (``terminate_on_contact``), tracking error above ``max_tracking_error`` or a physics
    blow-up. ``info["is_success"]`` is true while, after the reference stops, the object is within 2 cm and
    2 degrees of the goal. Truncated by ``max_episode_steps`` (600 steps of 0.04 s = 20 s move + 4 s hold).

    ## Arguments
    ``goal`` (``"paper"`` or ``"random"``: a goal drawn from ``tasks.RANDOM_GOAL_ENVELOPE``), ``start_pose`` /
    ``goal_pose`` (NED m + ZYX Euler **degrees**), ``move_time`` (s, default 20), ``grasp`` (``"rigid"``, the
    default: the object welded to both hands; ``"friction"`` or a mapping of knobs: held by friction, with two grip
    commands in the action, four gripper readings in the observation, slip, drop and crush in ``info`` and the
    episode's end: :mod:`uvdms_gym.envs.grip_channel`), and the common arguments of the circle task.

    ## Version History
    * v0: initial release.
    """

    with_object = True
    episode_steps = 600
    tracking_transient = TRACKING_TRANSIENT

    def __init__(
        self,
        *,
        goal: str = "paper",
        start_pose: tuple[float, ...] | None = None,
        goal_pose: tuple[float, ...] | None = None,
        move_time: float = 20.0,
        grasp: str | Mapping[str, Any] = "rigid",
        **kwargs: Any,
    ) -> None:
        self.grasp_config = parse_grasp(grasp)  # before the simulator is built; ValueError naming the knob
        """The friction grasp's knobs (:mod:`uvdms_gym.physics.grip`), or ``None`` for the rigid grasp."""
        self._grip = None if self.grasp_config is None else GripChannel(self.grasp_config)
        super().__init__(**kwargs)
        if self._grip is not None:
            self.action_dim += GRIP_ACTION_DIM
            self.action_space = gym.spaces.Box(-1.0, 1.0, (self.action_dim,), np.float32)
            self._grow_observation(GRASP_OBS_DIM)
        self.goal = goal
        self._task_kwargs = {"start_pose": start_pose, "goal_pose": goal_pose, "move_time": move_time}
        try:
            task = make_transport_task(goal, np.random.default_rng(0), **self._task_kwargs)
        except ValueError:
            self.close()
            raise
        # compile (or load from numba's disk cache) the step's kernels now, not in the first step
        errors_pose(task.start[:3], np.eye(3), task.reference(np.zeros(1)), np.eye(3))

    def _grow_observation(self, extra: int) -> None:
        """Add ``extra`` values to the observation space (same bounds)."""
        box = self.observation_space
        self.observation_space = gym.spaces.Box(box.low.flat[0], box.high.flat[0], (box.shape[0] + extra,), np.float32)

    def _make_sim(self) -> UVDMSSim:
        return UVDMSSim(self.params, physics_dt=self.physics_dt, gui=self.render_mode == "human", **self._sim_options())

    def _sim_options(self) -> dict[str, Any]:
        """The simulator's keywords beyond the common ones (the grasp; the obstacle task adds its collisions)."""
        return {} if self.grasp_config is None else {"grasp": self.grasp_config}

    # ----------------------------------------------------------------- the friction grasp
    def _start_episode(self, noise_key: tuple[int, int] = (0, 0)) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = super()._start_episode(noise_key)
        if self._grip is None:
            return obs, info
        self._grip.reset()
        return np.concatenate([obs, self._grip.observe(self._sim.grasp, self._obj_rot, info)]), info

    def _apply(self, a: np.ndarray) -> tuple[np.ndarray, bool]:
        if self._grip is None:
            return super()._apply(a)
        self._sim.grasp.set_grip(*self._grip.grip_command(a))
        return super()._apply(a[:-GRIP_ACTION_DIM])

    def step(self, action):
        """As :meth:`UVDMSEnv.step`; with the friction grasp, the grasp's block, ``info`` keys and episode end."""
        obs, reward, terminated, truncated, info = super().step(action)
        if self._grip is None:
            return obs, reward, terminated, truncated, info
        if info.get("physics_error") is not None:
            return np.concatenate([obs, np.zeros(GRASP_OBS_DIM, np.float32)]), reward, terminated, truncated, info
        block = self._grip.observe(self._sim.grasp, self._obj_rot, info)
        terminated = terminated or info["dropped"] or info["crushed"]
        return np.concatenate([obs, block]), reward, terminated, truncated, info

    def _build_task(self, rng: np.random.Generator) -> TransportTask:
        return make_transport_task(self.goal, rng, **self._task_kwargs)

    def _initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return vehicle_pose_for_object(self._kin, self.task.start), np.zeros(12)

    def _output(self) -> np.ndarray:
        pos, rpy, self._obj_rot = self._sim.object_pose_rotation()  # the matrix is kept for _errors
        return np.concatenate([pos, rpy])

    def _errors(self, y: np.ndarray, refs: np.ndarray, r_nb: np.ndarray) -> tuple[np.ndarray, float, float]:
        return errors_pose(y[:3], self._obj_rot, refs, r_nb)

    def _output_at(self, kin: KinematicModel) -> tuple[np.ndarray, np.ndarray]:
        """The object's pose from the grasp frame of a kinematic state (the weld holds it there)."""
        pos, rot = kin.object_pose()
        return np.concatenate([pos, rot_to_euler(rot)]), rot

    def _errors_at(
        self, y: np.ndarray, rot: np.ndarray | None, refs: np.ndarray, r_nb: np.ndarray
    ) -> tuple[np.ndarray, float, float]:
        return errors_pose(y[:3], rot, refs, r_nb)

    def _success(self, pos_err: float, ori_err: float) -> bool:
        return self.t >= self.task.move_time and pos_err < SUCCESS_POSITION and ori_err < SUCCESS_ORIENTATION

    def _reference_scene(self) -> ReferenceScene:
        """The object's reference path (its centre over the move), the current reference centre and the goal."""
        task = self.task
        path = task.reference(np.linspace(0.0, task.move_time, PATH_MARKER_SAMPLES))[:, :3]
        goal = (task.goal[:3], euler_to_rot(task.goal[3:]))
        return ReferenceScene(paths=(path,), points=task.reference(self.t)[None, :3], goal=goal)


class TransportV1Env(BoundedReward, TransportEnv):
    """``uvdms/Transport-v1``: :class:`~uvdms_gym.envs.transport.TransportEnv` with the bounded v1 reward.

    ## Rewards
    As :class:`~uvdms_gym.envs.circle.CircleTrackV1Env`, with ``e`` the object's position error and
    ``reward_orientation = orientation_weight * exp(-e_o / orientation_scale)`` (``e_o``: the object's
    orientation error, rad; ``orientation_scale`` default 5 degrees).

    Everything else (dynamics, task, observation, costs, episode end, ``max_episode_steps = 600``) is v0's.

    ## Version History
    * v1: bounded non-negative per-step reward and a contact penalty (v0: every term <= 0). Release 0.3.0 adds
      the optional keywords ``precision_weight`` and ``precision_scale`` (a narrow tracking term, off by
      default: the default reward is unchanged).
    * v0: initial release.
    """
