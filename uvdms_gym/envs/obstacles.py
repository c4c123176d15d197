"""``uvdms/TransportObstacles-v1``: the v1 transport among moving outer obstacles.

The paper's stated future work ("outer obstacles, especially the non-static ones"): debris (spheres) and drifting
pipes (capsules) cross the object's path while the UVDMS carries it. See :class:`TransportObstaclesV1Env`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from uvdms_gym.distances.outer import RobotTrack, compute_outer_distances, part_names, robot_track, track_gaps
from uvdms_gym.envs.base import CLEARANCE_CLIP, CONTACT_MARGIN, OBS_CLIP
from uvdms_gym.envs.obstacle_scenarios import random_obstacles
from uvdms_gym.envs.transport import TransportV1Env, vehicle_pose_for_object
from uvdms_gym.physics.obstacles import (
    POS,
    STATE_COLS,
    VEL,
    Obstacle,
    obstacle_states,
    parse_obstacles,
)
from uvdms_gym.physics.params import D1, D2
from uvdms_gym.utils.jit import jit

NOMINAL_GRID_DT = 0.2
"""Time step of the nominal-robot check of random obstacles, s."""
OBSTACLE_SLOT = 13
"""Observation values per observed obstacle (see :class:`TransportObstaclesV1Env`)."""
OBSTACLE_POS_SCALE = 2.0
"""Obstacle positions in the observation are divided by this, m."""
OBSTACLE_VEL_SCALE = 0.5
"""Obstacle velocities in the observation are divided by this, m/s."""
OBSTACLE_SIZE_SCALE = 0.5
"""Obstacle radii and half lengths in the observation are divided by this, m."""


class TransportObstaclesV1Env(TransportV1Env):
    """The v1 transport task with moving kinematic obstacles in the workspace.

    ## Description
    As ``uvdms/Transport-v1`` (:class:`~uvdms_gym.envs.transport.TransportV1Env`), while 1-3 obstacles move through the
    workspace. Obstacles are kinematic spheres and capsules (:mod:`uvdms_gym.physics.obstacles`): they follow their
    script exactly, push the robot on contact and are never pushed; they collide with the arm links, the object
    and the vehicle's hull. ``obstacles="random"`` (default) draws a scenario per seed whose obstacles cross the
    object's or an arm's path during the move (:mod:`uvdms_gym.envs.obstacle_scenarios`); a list of obstacle
    specifications (dicts with ``shape``, ``radius``, ``position``, ``velocity`` or ``waypoints``, and for a
    capsule ``length`` and ``axis``) gives a scripted scenario.

    ## Observation Space
    ``Box(-10, 10, (80 + 13 K,), float32)`` with ``K = n_observed_obstacles`` (default 3): the 80 values of
    ``uvdms/Transport-v1``, then one slot of 13 per obstacle, nearest first (smallest gap to any robot part):
    centre relative to the body origin in the body frame / 2 m (3), velocity relative to the body origin's in the
    body frame / 0.5 m/s (3), core axis in the body frame (3), radius / 0.5 m, half length / 0.5 m, the gap
    scaled as the clearances (``(clip(d, 0, 0.3) - d1) / (d2 - d1)``), and a mask (1 for an obstacle, 0 for
    padding; padded slots are all zero).

    ## Rewards
    Those of ``uvdms/Transport-v1``; a contact with an obstacle is a contact (``reward_contact``).

    ## Costs
    ``info["cost_contact"]`` counts obstacle contacts with the robot's own (and the episode ends on either).

    ## Info
    Beyond Transport-v1's: ``obstacles`` (``(K, 11)``: centre, velocity, radius, half length, axis; NED),
    ``obstacle_distances`` (``(K, 14)`` surface gaps; parts: left links 1-6, right links 1-6, object, hull),
    ``min_obstacle_distance`` and ``obstacle_contacts``.

    ## Arguments
    ``obstacles`` (``"random"`` or a list), ``n_observed_obstacles`` (observation slots, default 3), and every
    argument of ``uvdms/Transport-v1`` (``current`` included).

    ## Version History
    * v1: initial release (with the v1 reward).
    """

    def __init__(
        self,
        *,
        obstacles: str | Sequence[Obstacle | Mapping[str, Any]] = "random",
        n_observed_obstacles: int = 3,
        **kwargs: Any,
    ) -> None:
        if isinstance(obstacles, str):
            if obstacles != "random":
                raise ValueError(f"obstacles must be 'random' or a list of obstacle specifications, got {obstacles!r}")
            self._scripted: tuple[Obstacle, ...] | None = None
        else:
            self._scripted = parse_obstacles(obstacles)
        if (
            isinstance(n_observed_obstacles, bool)
            or not isinstance(n_observed_obstacles, int)
            or n_observed_obstacles < 0
        ):
            raise ValueError(f"n_observed_obstacles must be an integer >= 0, got {n_observed_obstacles!r}")
        self.obstacle_spec = obstacles
        self.n_observed_obstacles = n_observed_obstacles
        super().__init__(**kwargs)
        self.obstacles: tuple[Obstacle, ...] = ()
        self._states0 = np.zeros((0, STATE_COLS))
        self._scripted_rows: list[int] = []
        self._nominal_track: RobotTrack | None = None
        self._parts = part_names(True)
        dim = self.observation_space.shape[0] + OBSTACLE_SLOT * n_observed_obstacles  # OBS_DIM (+ the grasp's)
        self.observation_space = type(self.observation_space)(-OBS_CLIP, OBS_CLIP, (dim,), np.float32)
        if self._scripted is not None:
            try:
                self._check_start(self._scripted, self._initial_state())
            except ValueError:
                self.close()
                raise

    has_outer_obstacles = True

    def _sim_options(self) -> dict[str, Any]:
        return {**super()._sim_options(), "outer_collisions": True}

    # ----------------------------------------------------------------- scenario
    def _initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        if self.task is None:  # called by the constructor's start check
            from uvdms_gym.envs.references import make_transport_task

            task = make_transport_task(self.goal, np.random.default_rng(0), **self._task_kwargs)
            return vehicle_pose_for_object(self._kin, task.start), np.zeros(12)
        return super()._initial_state()

    def _gaps_at(self, eta: np.ndarray, q: np.ndarray, states: np.ndarray) -> np.ndarray:
        self._kin.set_state(eta, q)
        return compute_outer_distances(self._kin, states, True).per_obstacle()

    def _check_start(self, obstacles: Sequence[Obstacle], state: tuple[np.ndarray, np.ndarray]) -> None:
        """Refuse a scripted obstacle that starts in contact with (or inside) the robot."""
        gaps = self._gaps_at(*state, obstacle_states(obstacles, 0.0))
        for k, row in enumerate(gaps):
            i = int(np.argmin(row))
            if row[i] <= 0.0:
                raise ValueError(
                    f"obstacles[{k}] starts in contact with the robot's {self._parts[i]} "
                    f"(gap {row[i]:.3f} m at t = 0); move its start position"
                )

    def _nominal_gaps(self, obstacle: Obstacle) -> tuple[np.ndarray, np.ndarray]:
        """Gaps ``(T, 14)`` of one obstacle to the nominal robot (object on its reference, ``q = 0``), whole episode."""
        if self._nominal_track is None:
            steps = self.spec.max_episode_steps if self.spec is not None and self.spec.max_episode_steps else 600
            times = np.arange(0.0, steps * self.control_dt + 1e-9, NOMINAL_GRID_DT)
            etas = np.array([vehicle_pose_for_object(self._kin, pose) for pose in self.task.reference(times)])
            self._nominal_track = robot_track(self._kin, times, etas, np.zeros((times.size, 12)), True)
        track = self._nominal_track
        states = np.tile(obstacle_states([obstacle], 0.0), (track.times.size, 1))
        states[:, POS] = obstacle.position_at(track.times)
        return track.times, track_gaps(track, self.params, states)

    def _nominal_links(self, pose: np.ndarray) -> np.ndarray:
        self._kin.set_state(vehicle_pose_for_object(self._kin, pose), np.zeros(12))
        return self._kin.link_segments().copy()

    def _after_sim_reset(self) -> None:
        self._nominal_track = None
        if self._scripted is not None:
            obstacles = self._scripted
            self._check_start(obstacles, self._initial_state())
        else:
            obstacles = random_obstacles(
                self.np_random,
                self.task.reference,
                self.task.move_time,
                self._nominal_links,
                self._nominal_gaps,
                (self.params.obj.radius, self.params.arm.link_radius),
            )
        self.obstacles = obstacles
        self._sim.set_obstacles(obstacles)
        self._states0 = obstacle_states(obstacles, 0.0)
        self._scripted_rows = [k for k, ob in enumerate(obstacles) if ob.waypoints]

    def _obstacle_rows(self, t: float) -> np.ndarray | None:
        return self._states_at(t)

    def _states_at(self, t: float) -> np.ndarray:
        """:func:`~uvdms_gym.physics.obstacles.obstacle_states` at ``t`` (constant-velocity rows in one update)."""
        states = self._states0.copy()
        states[:, POS] += t * states[:, VEL]
        if self._scripted_rows:
            states[self._scripted_rows] = obstacle_states([self.obstacles[k] for k in self._scripted_rows], t)
        return states

    # ----------------------------------------------------------------- observation
    def _observe(self) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = super()._observe()  # leaves the kinematic model at the current state
        states = self._states_at(self.t)
        res = compute_outer_distances(self._kin, states, True)
        gaps = res.per_obstacle()
        gap_min = float(gaps.min()) if gaps.size else math.inf
        n_contacts = self._obstacle_contacts(gaps, gap_min)
        info["contacts"] += n_contacts
        info["obstacle_contacts"] = n_contacts
        info["cost_contact"] = 1.0 if info["contacts"] > 0 else 0.0
        info["cost"] = info["cost_contact"] + info["cost_zone"]
        info["obstacles"] = states
        info["obstacle_distances"] = gaps
        info["min_obstacle_distance"] = gap_min
        r_nb = self._kin.frame_placement("vehicle")[1]  # the kinematic model holds the observed state
        full = np.concatenate([obs, self._obstacle_block(states, gaps, info, r_nb)]).astype(np.float32)
        self._obs = full
        return full.copy(), info

    def observe_estimate(
        self,
        eta: np.ndarray,
        nu: np.ndarray,
        q: np.ndarray,
        qdot: np.ndarray,
        obstacles: np.ndarray | None = None,
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """As :meth:`UVDMSEnv.observe_estimate`, with the obstacle slots and keys seen from the estimated state.

        ``obstacles``: rows as ``info["obstacles"]`` (the sonar's track; ``None``: the true rows).
        """
        obs, keys = super().observe_estimate(eta, nu, q, qdot)
        states = self._states_at(self.t) if obstacles is None else np.asarray(obstacles, dtype=float)
        kin = self._measured_kin
        gaps = compute_outer_distances(kin, states, True).per_obstacle()
        keys["obstacles"] = states
        keys["obstacle_distances"] = gaps
        keys["min_obstacle_distance"] = float(gaps.min()) if gaps.size else math.inf
        block = self._obstacle_block(states, gaps, keys, kin.frame_placement("vehicle")[1])
        return np.concatenate([obs, block]).astype(np.float32), keys

    def _obstacle_contacts(self, gaps: np.ndarray, gap_min: float) -> int:
        """PyBullet's contact report for the (part, obstacle) pairs within a margin of contact (none: no query)."""
        if gap_min >= CONTACT_MARGIN:  # the usual case, without argwhere's cost
            return 0
        near = np.argwhere(gaps < CONTACT_MARGIN)
        if near.size == 0:
            return 0
        return self._sim.count_obstacle_contacts([(self._parts[i], int(k)) for k, i in near])

    def _obstacle_block(
        self, states: np.ndarray, gaps: np.ndarray, info: dict[str, Any], r_nb: np.ndarray
    ) -> np.ndarray:
        """The observation slots (class docstring) seen from a state of rotation ``r_nb``, nearest obstacle first."""
        block = np.zeros(OBSTACLE_SLOT * self.n_observed_obstacles)
        if len(states) and self.n_observed_obstacles:
            nearest_gap = gaps.min(axis=1)
            order = np.argsort(nearest_gap, kind="stable")[: self.n_observed_obstacles]
            _fill_slots(states, nearest_gap, order, info["eta"], info["nu"], r_nb, block)
        return block


@jit
def _fill_slots(states, nearest_gap, order, eta, nu, r_nb, block):  # pragma: no cover - compiled
    """The slots of :meth:`TransportObstaclesV1Env._obstacle_block` in one compiled loop.

    numpy's per-call cost on these few 3-vectors was most of the work (20 µs for 3 obstacles).
    """
    v0 = r_nb[0, 0] * nu[0] + r_nb[0, 1] * nu[1] + r_nb[0, 2] * nu[2]  # NED velocity of the body origin
    v1 = r_nb[1, 0] * nu[0] + r_nb[1, 1] * nu[1] + r_nb[1, 2] * nu[2]
    v2 = r_nb[2, 0] * nu[0] + r_nb[2, 1] * nu[1] + r_nb[2, 2] * nu[2]
    for slot in range(order.shape[0]):
        k = order[slot]
        base = OBSTACLE_SLOT * slot
        rel = (states[k, 0] - eta[0], states[k, 1] - eta[1], states[k, 2] - eta[2])
        vel = (states[k, 3] - v0, states[k, 4] - v1, states[k, 5] - v2)
        for j in range(3):  # body-frame components: r_nb^T x
            block[base + j] = (rel[0] * r_nb[0, j] + rel[1] * r_nb[1, j] + rel[2] * r_nb[2, j]) / OBSTACLE_POS_SCALE
            block[base + 3 + j] = (vel[0] * r_nb[0, j] + vel[1] * r_nb[1, j] + vel[2] * r_nb[2, j]) / OBSTACLE_VEL_SCALE
            block[base + 6 + j] = states[k, 8] * r_nb[0, j] + states[k, 9] * r_nb[1, j] + states[k, 10] * r_nb[2, j]
        block[base + 9] = states[k, 6] / OBSTACLE_SIZE_SCALE
        block[base + 10] = states[k, 7] / OBSTACLE_SIZE_SCALE
        block[base + 11] = (min(max(nearest_gap[k], 0.0), CLEARANCE_CLIP) - D1) / (D2 - D1)
        block[base + 12] = 1.0
        for j in range(OBSTACLE_SLOT):
            block[base + j] = min(max(block[base + j], -OBS_CLIP), OBS_CLIP)
