"""Common machinery of the UVDMS Gymnasium environments (action, observation, reward, cost, episode end).

Subclasses define the task (reference, tracked output ``y``, initial state). See the class docstrings of
:class:`~uvdms_gym.envs.circle.CircleTrackEnv` and :class:`~uvdms_gym.envs.transport.TransportEnv` for the
full description in Gymnasium's sections; this module documents the shared parts.

Observation (float32, 80 values, each scaled to order 1 and clipped to [-10, 10]):

==========  ====  =====================================================================================
slice       size  content
==========  ====  =====================================================================================
0:18        18    reference preview: ``y_ref(t + h) - y`` at ``h`` in :data:`PREVIEW_TIMES`, in the body frame
                  (circle: left and right end-effector position errors; transport: object position error
                  and orientation error as a rotation vector), divided by
                  :data:`~uvdms_gym.envs.tracking.POS_SCALE` m / 1 rad
18:20       2     vehicle roll and pitch, rad
20:26       6     vehicle body velocity ``nu`` divided by its limits ``zeta_max[:6]``
26:50       24    joint angles as ``sin q`` (12) then ``cos q`` (12)
50:62       12    joint rates divided by their limits ``zeta_max[6:]``
62:80       18    the 18 clearances of docs/MODEL.md section 4 (rows as in ``docs/ARCHITECTURE.md``), as
                  ``(clip(d, 0, 0.3) - d1) / (d2 - d1)``
==========  ====  =====================================================================================
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar, NamedTuple

import gymnasium as gym
import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.utils import EzPickle

from uvdms_gym.distances import compute_distances, contact_thresholds, velocity_damper
from uvdms_gym.envs.lowlevel import VelocityLoop
from uvdms_gym.envs.measured import COMPILED_EQUIVALENT, MeasuredState
from uvdms_gym.envs.tracking import CLEARANCE_CLIP, OBS_CLIP
from uvdms_gym.physics.current import CurrentModel, CurrentState, parse_current
from uvdms_gym.physics.hydro import HydroScale
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.nominal import NominalDynamics
from uvdms_gym.physics.params import D1, D2, UVDMSParams
from uvdms_gym.physics.render import CAMERA_YAW_OFFSET_DEG, ReferenceScene
from uvdms_gym.physics.sim import UVDMSSim
from uvdms_gym.physics.state import PhysicsError
from uvdms_gym.realism.config import RealismConfig, parse_realism
from uvdms_gym.utils.display import gui_available, require_display
from uvdms_gym.utils.kwargs import check_init_kwargs
from uvdms_gym.utils.legacy import MOVED_NAMES, moved_names

PREVIEW_TIMES: tuple[float, ...] = (0.0, 0.4, 0.8)
"""Reference preview horizon of the observation, s."""
OBS_DIM = 80
ACTION_DIM = 18
N_THRUSTERS = 8
"""Thrusters of the vehicle (``action_mode="thrusters"`` commands them, then the 12 joint torques)."""
ACTION_MODES: tuple[str, ...] = ("velocity", "torque", "thrusters")
"""``velocity`` and ``torque``: 18 values; ``thrusters``: 8 thruster commands and 12 joint torques (20 values)."""
CONTACT_MARGIN = 0.01
"""Rows whose exact distance is within this of contact (m) are checked with PyBullet for contact."""
PHYSICS_ERROR_REWARD = -100.0
"""Reward of the step on which the physics blew up (the episode then terminates)."""


class _Episode(NamedTuple):
    """What a copy of an environment replays: the generator after ``reset()``'s seeding, and the actions since."""

    generator: np.random.Generator
    seed: int | None
    options: dict[str, Any] | None
    actions: list[np.ndarray]
    noise_key: tuple[int, int] = (0, 0)
    """The sensors' random streams: the seed and the episode's index since it (:func:`noise_streams`)."""


def _check_modes(
    action_mode: str, render_mode: str | None, render_modes: list[str], control_dt: float, physics_dt: float
) -> None:
    """``ValueError`` naming an unknown action or render mode or a non-positive time step."""
    if action_mode not in ACTION_MODES:
        raise ValueError(f"action_mode must be 'velocity', 'torque' or 'thrusters', got {action_mode!r}")
    if render_mode is not None and render_mode not in render_modes:
        raise ValueError(f"render_mode must be one of {render_modes} or None, got {render_mode!r}")
    if not (physics_dt > 0 and control_dt > 0):
        raise ValueError(f"control_dt and physics_dt must be positive, got {control_dt}, {physics_dt}")


def _substeps(control_dt: float, physics_dt: float) -> int:
    """Physics steps per control step (``ValueError`` unless ``control_dt`` is a whole multiple of ``physics_dt``)."""
    n_sub = round(control_dt / physics_dt)
    if n_sub < 1 or abs(n_sub * physics_dt - control_dt) > 1e-9:
        raise ValueError(f"control_dt ({control_dt}) must be a whole multiple of physics_dt ({physics_dt})")
    return n_sub


def _weights(*values: float) -> dict[str, float]:
    """The reward weights ``track, orientation, effort, proximity, contact`` by name, as floats.

    Raises:
        ValueError: a weight is not finite and non-negative (the message names ``<name>_weight``).
    """
    weights = dict(zip(("track", "orientation", "effort", "proximity", "contact"), values, strict=True))
    for name, w in weights.items():
        if not (math.isfinite(w) and w >= 0.0):
            raise ValueError(f"{name}_weight must be a finite non-negative number, got {w}")
    return {name: float(w) for name, w in weights.items()}


class UVDMSEnv(MeasuredState, gym.Env, EzPickle):
    """Base class: one simulator, one kinematic model, a task; see the module docstring.

    Pickling and ``copy.deepcopy`` work the Gymnasium way (:class:`gymnasium.utils.EzPickle`): the constructor's
    arguments are pickled and the copy is a new environment built from them, with its own PyBullet client. During
    an episode the copy also carries the episode (the random generator as the last ``reset()`` left it, and the
    actions stepped since), and replays it when it is unpickled: the copy is in the original's state, bit for bit,
    and can be stepped at once (the Gymnasium wrappers around it, which pickle their own flags and step counts, then
    tell the truth). Replaying costs one step per step of the episode so far. A copy of an environment that was
    never reset, or was closed, is a fresh environment: stepping it before ``reset()`` raises
    :class:`gymnasium.error.ResetNeeded`. ``reset()`` after ``close()`` connects a new client.

    Subclasses implement :meth:`_build_task`, :meth:`_initial_state`, :meth:`_output` and
    :meth:`_errors` and set :attr:`with_object`.

    Each instance has its own ``metadata``: ``render_fps`` is ``1 / control_dt`` (one frame per step, so that
    recorded videos play in real time) and ``render_modes`` lists ``"human"`` only where PyBullet's GUI can
    open (:mod:`uvdms_gym.utils.display`); ``render_mode="human"`` without a display raises
    :class:`~uvdms_gym.utils.display.DisplayUnavailableError`.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 25}
    with_object: ClassVar[bool] = False
    camera_yaw_deg: ClassVar[float] = CAMERA_YAW_OFFSET_DEG
    has_outer_obstacles: ClassVar[bool] = False
    """The task has outer obstacles (their sonar track is measured at ``realism > 0``)."""
    episode_steps: ClassVar[int | None] = None
    """The registered ``max_episode_steps`` (a delay or latency of the ``realism`` knobs must be shorter)."""
    """Yaw of the ``rgb_array`` camera relative to the vehicle's heading, degrees (:mod:`uvdms_gym.physics.render`)."""

    def __new__(cls, *args: Any, **kwargs: Any) -> UVDMSEnv:
        """Record the most-derived constructor's arguments for pickling (each subclass takes its own keywords)."""
        check_init_kwargs(cls, kwargs)  # left_center="abc": one line naming the key and the type it takes
        env = super().__new__(cls)
        EzPickle.__init__(env, *args, **kwargs)
        return env

    def __init__(
        self,
        *,
        action_mode: str = "velocity",
        control_dt: float = 0.04,
        physics_dt: float = 0.01,
        hydro_randomization: float = 0.0,
        current: CurrentModel | str | Sequence[float] | None = None,
        terminate_on_contact: bool = True,
        track_weight: float = 1.0,
        orientation_weight: float = 0.3,
        effort_weight: float = 0.01,
        proximity_weight: float = 0.1,
        contact_weight: float = 10.0,
        max_tracking_error: float = 2.0,
        render_mode: str | None = None,
        render_width: int = 320,
        render_height: int = 240,
        params: UVDMSParams | None = None,
        realism: int | Mapping[str, Any] | RealismConfig | None = 0,
    ) -> None:
        _check_modes(action_mode, render_mode, self.metadata["render_modes"], control_dt, physics_dt)
        if render_mode == "human":
            require_display()  # a clear exception where PyBullet's GUI connect would call exit()
        # Per-instance metadata (Gymnasium convention): frames come once per control step, and "human" is listed
        # only where a display exists, so that check_env's render-mode sweep passes on a headless machine.
        self.metadata = {
            **type(self).metadata,
            "render_fps": 1.0 / float(control_dt),
            "render_modes": [m for m in type(self).metadata["render_modes"] if m != "human" or gui_available()],
        }
        n_sub = _substeps(control_dt, physics_dt)
        if not 0.0 <= hydro_randomization < 1.0:
            raise ValueError(f"hydro_randomization must be in [0, 1), got {hydro_randomization}")
        self.current_model = parse_current(current)  # ValueError naming the problem, before any client exists
        """The ocean-current process (:mod:`uvdms_gym.physics.current`), or ``None`` for still water."""
        weights = _weights(track_weight, orientation_weight, effort_weight, proximity_weight, contact_weight)
        self.params = params or UVDMSParams()
        episode_time = None if self.episode_steps is None else self.episode_steps * float(control_dt)
        self.realism: RealismConfig | None = parse_realism(realism, episode_time=episode_time)
        """The sensing and actuation realism (:mod:`uvdms_gym.realism`), or ``None`` for the oracle (level 0)."""
        self.action_mode = action_mode
        self.control_dt = float(control_dt)
        self.physics_dt = float(physics_dt)
        self.n_substeps = n_sub
        self.hydro_randomization = float(hydro_randomization)
        self._current_state: CurrentState | None = None
        self._current_value = (0.0, 0.0, 0.0)
        self.terminate_on_contact = bool(terminate_on_contact)
        self.weights = weights
        self.max_tracking_error = float(max_tracking_error)
        self._reward_keys = {k: f"reward_{k}" for k in self.weights}
        self.render_mode = render_mode
        self.render_width, self.render_height = int(render_width), int(render_height)

        self.zeta_max = self.params.zeta_max.copy()
        """Velocity-mode scale: ``zeta_cmd = action * zeta_max`` (m/s, rad/s)."""
        self.tau_max = self.params.tau_max.copy()
        """Torque-mode scale: ``tau = action * tau_max`` (N, N m)."""
        self.action_dim = N_THRUSTERS + 12 if action_mode == "thrusters" else ACTION_DIM
        self.action_space = gym.spaces.Box(-1.0, 1.0, (self.action_dim,), np.float32)
        self.observation_space = gym.spaces.Box(-OBS_CLIP, OBS_CLIP, (OBS_DIM,), np.float32)
        self._build_models()

    def _build_models(self) -> None:
        """The simulator, the kinematic and nominal models, the velocity loop and the per-episode state."""
        self._sim = self._make_sim()
        self._episode: _Episode | None = None  # set by reset(): what a copy replays (__getstate__)
        self._kin = KinematicModel(self.params)
        self._nominal = NominalDynamics(self._kin)
        self._loop = VelocityLoop(self._nominal, self.tau_max)
        self._controller_kin: KinematicModel | None = None
        self.task: Any = None
        self.t = 0.0
        self._obs = np.zeros(OBS_DIM, np.float32)
        self._preview_times = np.asarray(PREVIEW_TIMES)
        self._contact_d = contact_thresholds(self.params)
        self._contact_check_d = self._contact_d + CONTACT_MARGIN
        self._nu_scale = self.zeta_max[:6].copy()
        self._qdot_scale = self.zeta_max[6:].copy()
        self._closed = False
        self._layer = self._make_layer()
        self._measured_kin = KinematicModel(self.params) if self.realism is not None else None
        self._truth: dict[str, Any] = {}
        self._episode_count = 0

    def __getstate__(self) -> dict[str, Any]:
        """The constructor's arguments (:class:`~gymnasium.utils.EzPickle`) and, during an episode, the episode."""
        state = EzPickle.__getstate__(self)
        if self._episode is not None and not self._closed:
            state["_episode"] = self._episode
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Build the environment from its constructor's arguments, then replay the episode if there was one."""
        state = dict(state)
        episode = state.pop("_episode", None)
        EzPickle.__setstate__(self, state)
        if episode is not None:
            self._np_random, self._np_random_seed = copy.deepcopy(episode.generator), episode.seed
            self._episode = _Episode(episode.generator, episode.seed, episode.options, [], episode.noise_key)
            self._start_episode(episode.noise_key)
            for action in episode.actions:
                self.step(action)

    def _make_sim(self) -> UVDMSSim:
        """A simulator with its own PyBullet client (DIRECT, or the GUI with ``render_mode="human"``)."""
        return UVDMSSim(self.params, physics_dt=self.physics_dt, gui=self.render_mode == "human")

    # ----------------------------------------------------------------- task hooks
    def _build_task(self, rng: np.random.Generator) -> Any:  # pragma: no cover - abstract
        raise NotImplementedError

    def _initial_state(self) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - abstract
        """Initial ``(eta, q)``."""
        raise NotImplementedError

    def _output(self) -> np.ndarray:  # pragma: no cover - abstract
        """Tracked output ``y`` (6) at the kinematic model's state."""
        raise NotImplementedError

    def _errors(self, y: np.ndarray, refs: np.ndarray, r_nb: np.ndarray) -> tuple[np.ndarray, float, float]:
        """Observation error blocks for the preview references ``refs`` (P, 6).

        Returns the (6 P,) scaled body-frame errors, and the position (m) and orientation (rad) errors at the
        first (current) reference.
        """
        raise NotImplementedError  # pragma: no cover - abstract

    def _success(self, pos_err: float, ori_err: float) -> bool:
        """Task success at the current step (default: none)."""
        return False

    def _after_sim_reset(self) -> None:
        """Hook after the simulator's reset and before the first observation (default: nothing)."""

    # ----------------------------------------------------------------- public helpers
    def reference(self, t: np.ndarray | float) -> np.ndarray:
        """The task's reference ``y_ref`` on any time grid (s from episode start): (6,) or (N, 6)."""
        if self.task is None:
            raise RuntimeError("call reset() before reference()")
        return self.task.reference(t)

    @property
    def kinematic_model(self) -> KinematicModel:
        """A kinematic model (Jacobians, distances, ``J_dis``) built from the environment's parameters.

        It is a separate instance from the environment's own (a controller may ``set_state`` it freely);
        it knows nothing of the simulator's state beyond what ``info`` reports.
        """
        if self._controller_kin is None:
            self._controller_kin = KinematicModel(self.params)
        return self._controller_kin

    # ----------------------------------------------------------------- gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode: draw the task (and hydrodynamic factors) from the seeded generator."""
        super().reset(seed=seed)
        self._episode_count = 0 if seed is not None else self._episode_count + 1
        noise_key = (max(int(self._np_random_seed or 0), 0), self._episode_count)
        episode = _Episode(copy.deepcopy(self.np_random), self._np_random_seed, options, [], noise_key)
        self._episode = None  # until the episode has started: a reset that raises leaves no episode to step or copy
        out = self._start_episode(noise_key)
        self._episode = episode
        return out

    def _start_episode(self, noise_key: tuple[int, int] = (0, 0)) -> tuple[np.ndarray, dict[str, Any]]:
        """The part of :meth:`reset` after the generator is set: draw the task, reset the simulator, observe."""
        if self._closed:  # reset after close: a new client, as Gymnasium's classic environments do
            self._sim = self._make_sim()
            self._closed = False
        if self._layer is not None and self._layer.sensing:
            self._sim.set_probe(self._layer.probe)
        self.task = self._build_task(self.np_random)
        self._apply_hydro_randomization()
        self._reset_current()  # after the task and hydro draws: the episodes without a current are unchanged
        eta, q = self._initial_state()
        self._sim.reset(eta, np.zeros(6), q, np.zeros(12), with_object=self.with_object)
        self._after_sim_reset()
        self._loop.reset()
        self.t = 0.0
        self._last_action = np.zeros(self.action_dim)
        obs, info = self._observe()
        info.update({f"reward_{k}": 0.0 for k in self.weights})
        if self._layer is not None:
            obs, info = self._reset_layer(noise_key, obs, info)
        return obs, info

    def step(self, action):
        """Apply the action over ``control_dt``, then observe, score and check the episode end."""
        if self._episode is None:
            raise ResetNeeded(
                "this environment has no episode (never reset, or copied or unpickled after close()): "
                "call reset() before step()"
            )
        a, clipped = self._validate_action(action)
        self._episode.actions.append(np.array(action, dtype=np.float64))  # what a copy replays (__setstate__)
        if self._current_state is not None and self.current_model.random:
            self._advance_current()
        physics_error = None
        try:
            tau_applied, saturated = self._apply(a)
        except PhysicsError as exc:
            physics_error = str(exc)
            tau_applied, saturated = np.zeros(18), False
        self.t += self.control_dt
        if physics_error is not None:
            info = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in self._last_info.items()}
            info.update(self._physics_error_info(physics_error))
            return self._obs.copy(), PHYSICS_ERROR_REWARD, True, False, info
        obs, info = self._observe()
        terms = self._reward_terms(a, info)
        reward = float(sum(terms.values()))
        keys = self._reward_keys
        info.update({keys[k]: v for k, v in terms.items()})
        info.update(tau=tau_applied, tau_saturated=saturated, action_clipped=clipped)
        terminated = (self.terminate_on_contact and info["contacts"] > 0) or (
            info["tracking_error"] > self.max_tracking_error
        )
        if self._layer is not None:
            info.update(self._layer.end_step())
            if self._layer.sensing:
                obs, info = self._measured(obs, info, self._layer_measure(info))
        self._last_action = a
        self._last_info = info
        if self.render_mode == "human":
            self.render()
        return obs, reward, bool(terminated), False, info

    def render(self):
        """``rgb_array``: an HxWx3 uint8 image from a camera beside the vehicle; ``human``: the GUI window.

        An ``rgb_array`` frame draws the task's reference (:meth:`_reference_scene`, e.g. the two circles and the
        current reference points, or the object's path and goal) with visual-only bodies, created in the
        simulator at the first frame of an episode that is rendered; they change neither the physics nor the
        observations (:mod:`uvdms_gym.physics.render`).
        """
        if self.render_mode == "rgb_array":
            if self.task is not None:
                self._sim.show_reference(self._reference_scene())
            return self._sim.render_rgb(self.render_width, self.render_height, camera_yaw_deg=self.camera_yaw_deg)
        return None

    def _reference_scene(self) -> ReferenceScene:
        """What a frame draws of the task's reference at the current time (default: nothing)."""
        return ReferenceScene()

    def close(self) -> None:
        """Disconnect the simulator (idempotent)."""
        if not self._closed:
            self._sim.close()
            self._closed = True

    # ----------------------------------------------------------------- step parts
    def _validate_action(self, action) -> tuple[np.ndarray, bool]:
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (self.action_dim,):
            raise ValueError(f"action must have shape ({self.action_dim},), got {a.shape}")
        within = np.abs(a) <= 1.0  # False for NaN/inf and for entries to clip
        if False not in within.tolist():  # (a list scan: ndarray.all() costs several times more)
            return a, False
        bad = ~np.isfinite(a)
        if bad.any():
            raise ValueError(f"action contains NaN or inf at indices {np.flatnonzero(bad).tolist()}")
        return np.clip(a, -1.0, 1.0), True

    def _apply(self, a: np.ndarray) -> tuple[np.ndarray, bool]:
        """Run the control step's physics substeps; return the applied tau and the saturation flag."""
        n, dt = self.n_substeps, self.physics_dt
        if self._layer is not None:  # realism > 0 or thrusters mode: delay, actuators, sensors (realism_layer)
            self._layer.begin_step(a)
            res = self._sim.step(np.zeros(ACTION_DIM), n, feedback=self._layer_law)
            return res.tau, res.any_saturated
        if self.action_mode == "torque":
            res = self._sim.step(a * self.tau_max, n)
        else:
            loop = self._loop
            loop.begin(a * self.zeta_max)  # the kinematic model holds the current state (from _observe)
            res = self._sim.step(np.zeros(ACTION_DIM), n, feedback=lambda z: loop.torque(z, dt))
        return res.tau, res.any_saturated

    def _contacts(self, dist) -> int:
        """PyBullet's contact report for the rows whose exact distance is within a margin of contact.

        Only the closest obstacle of a monitored link can touch it first, so checking each near row's pair is
        enough; far rows (almost always all of them) cost nothing.
        """
        near = dist.d < self._contact_check_d
        if True not in near.tolist():
            return 0
        pairs = [(dist.link_frame[i], self._obstacle_link(dist, i)) for i in np.flatnonzero(near)]
        return self._sim.count_contacts(pairs)

    def _obstacle_link(self, dist, i: int) -> str:
        if dist.obstacle_frame[i] == "vehicle":  # plate rows: E lies on plate obstacle_index[i]
            return f"plate_{self.params.plates[int(dist.obstacle_index[i])].name}"
        return dist.obstacle_frame[i]

    def _observe(self) -> tuple[np.ndarray, dict[str, Any]]:
        st = self._sim.state()
        self._kin.set_state(st.eta, st.q, st.zeta)
        dist = compute_distances(self._kin, "exact")
        d = dist.d.copy()
        contacts = self._contacts(dist)
        y = self._output()
        refs = self.task.reference(self.t + self._preview_times)
        blocks, pos_err, ori_err = self._errors(y, refs, self._kin.frame_placement("vehicle")[1])
        q = st.q
        self._obs = self._assemble(blocks, st.eta, st.nu, q, st.qdot, d)
        d_min = min(d.tolist())
        cost_contact = 1.0 if contacts > 0 else 0.0
        cost_zone = 1.0 if d_min < D1 else 0.0
        info: dict[str, Any] = {  # the state arrays are fresh copies from sim.state(), owned by info
            "t": self.t,
            "eta": st.eta,
            "nu": st.nu,
            "q": q,
            "qdot": st.qdot,
            "y": y,
            "y_ref": refs[0],
            "distances": d,
            "min_distance": d_min,
            "contacts": int(contacts),
            "tracking_error": pos_err,
            "orientation_error": ori_err,
            "cost_contact": cost_contact,
            "cost_zone": cost_zone,
            "cost": cost_contact + cost_zone,
            "is_success": self._success(pos_err, ori_err),
            "physics_error": None,
            "current": np.array(self._current_value),
        }
        self._last_info = info
        return self._obs.copy(), info

    def _assemble(
        self, blocks: np.ndarray, eta: np.ndarray, nu: np.ndarray, q: np.ndarray, qdot: np.ndarray, d: np.ndarray
    ) -> np.ndarray:
        """The 80 observation values (module docstring) of a state and its clearances ``d``, as float32."""
        obs = np.concatenate(
            (
                blocks,
                eta[3:5],
                nu / self._nu_scale,
                np.sin(q),
                np.cos(q),
                qdot / self._qdot_scale,
                (np.minimum(np.maximum(d, 0.0), CLEARANCE_CLIP) - D1) / (D2 - D1),
            )
        )
        # np.clip(obs, -OBS_CLIP, OBS_CLIP) as two selections (the same values; np.clip's wrapper costs more)
        np.minimum(np.maximum(obs, -OBS_CLIP, out=obs), OBS_CLIP, out=obs)
        return obs.astype(np.float32)

    setattr(_assemble, COMPILED_EQUIVALENT, True)  # assemble_observation computes the same values

    def _reward_terms(self, a: np.ndarray, info: dict[str, Any]) -> dict[str, float]:
        w = self.weights
        # S(d) = 1 exactly for d >= D2 ((d - D1) / (D2 - D1) >= 1 is clipped to 1 and sin(pi / 2) rounds to 1),
        # so the sum is exactly 0 when no distance is below D2 (the usual case): skip evaluating it
        if info["min_distance"] < D2:
            s = velocity_damper(info["distances"], D1, D2)
            near = float(np.add.reduce(1.0 - s))  # np.sum without its wrapper
        else:
            near = 0.0
        return {
            "track": -w["track"] * info["tracking_error"],
            "orientation": -w["orientation"] * info["orientation_error"],
            "effort": -w["effort"] * float(a @ a) / self.action_dim,
            "proximity": -w["proximity"] * near,
            "contact": -w["contact"] * info["cost_contact"],
        }

    def _physics_error_info(self, msg: str) -> dict[str, Any]:
        terms = {f"reward_{k}": 0.0 for k in self.weights}
        terms["reward_physics_error"] = PHYSICS_ERROR_REWARD
        return {**terms, "physics_error": msg, "t": self.t, "current": np.array(self._current_value)}

    def _reset_current(self) -> None:
        """Start the episode's current process (draws from ``np_random`` only for a random current)."""
        model = self.current_model
        if model is None:
            self._current_state = None
            self._current_value = (0.0, 0.0, 0.0)
            self._sim.set_current(None)
            return
        self._current_state = model.start(self.np_random)
        self._set_current_value()

    def _advance_current(self) -> None:
        """One control step of the current process; the simulator applies the new value during the step."""
        self._current_state = self.current_model.advance(self._current_state, self.control_dt, self.np_random)
        self._set_current_value()

    def _set_current_value(self) -> None:
        self._current_value = self._current_state.value
        self._sim.set_current(self._current_value)

    def _apply_hydro_randomization(self) -> None:
        s = self.hydro_randomization
        if s == 0.0:
            self._sim.set_hydro_scale(HydroScale())
            return
        lo, hi = 1.0 - s, 1.0 + s
        rng = self.np_random
        self._sim.set_hydro_scale(
            HydroScale(
                added_mass=float(rng.uniform(lo, hi)),
                damping=float(rng.uniform(lo, hi)),
                buoyancy=float(rng.uniform(lo, hi)),
                link_drag=float(rng.uniform(lo, hi)),
            )
        )


# Names this module held before 0.4.0 that live in other modules now: one line naming their module (utils/legacy.py).
__getattr__ = moved_names(__name__, MOVED_NAMES[__name__])
