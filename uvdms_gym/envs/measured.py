"""What every environment does at ``realism > 0``: measured observations, the truth kept aside, the realism layer.

:class:`MeasuredState` is a base class of :class:`uvdms_gym.envs.base.UVDMSEnv` holding its realism part, so that
the oracle's machinery (``base.py``) and the measured one (here) are read apart:

* :meth:`MeasuredState.true_state`, the one documented path to the truth;
* :meth:`MeasuredState.observe_estimate`, the observation and ``info`` state keys of a measured or estimated state;
* the realism layer's construction (:meth:`MeasuredState._make_layer`, :mod:`uvdms_gym.envs.realism_layer`) and the
  swap of the truth for the measurements at the end of ``reset()`` and ``step()`` (:meth:`MeasuredState._measured`).

At ``realism=0`` none of it runs in a step (``true_state()`` reads the step's ``info``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from uvdms_gym.distances import compute_distances
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.realism.config import RealismConfig

if TYPE_CHECKING:  # the realism layer is imported where it is built (realism > 0 or thrusters mode)
    from uvdms_gym.envs.realism_layer import Measurements, RealismLayer

TRUTH_KEYS: tuple[str, ...] = (
    "eta",
    "nu",
    "q",
    "qdot",
    "y",
    "distances",
    "min_distance",
    "current",
    "obstacles",
    "obstacle_distances",
    "min_obstacle_distance",
)
"""The ``info`` keys that describe the state: measured at ``realism > 0``, true in :meth:`UVDMSEnv.true_state`."""
GENERALIZED_FORCES = 18
"""Components of the generalized force (``info["tau_cmd"]``): the vehicle's wrench (6), then 12 joint torques."""
COMPILED_EQUIVALENT = "compiled_equivalent"
"""Attribute marking an ``_assemble`` whose values :func:`~uvdms_gym.envs.measured_kinematics.assemble_observation`
computes (a subclass that overrides ``_assemble`` loses it and keeps its own)."""


class MeasuredState:
    """The realism part of :class:`uvdms_gym.envs.base.UVDMSEnv` (module docstring), on the attributes it sets."""

    def _make_layer(self) -> RealismLayer | None:
        """The action path and sensors at ``realism > 0`` or in thrusters mode (``None``: the oracle's direct path)."""
        self._estimate_refs: tuple[float, Any, np.ndarray] | None = None
        """:meth:`observe_estimate`'s preview reference: ``(t, task, refs)``."""
        if self.realism is None and self.action_mode != "thrusters":
            return None
        from uvdms_gym.envs.realism_layer import RealismLayer

        layer = RealismLayer(
            self.realism or RealismConfig(level=0, thrusters=True),
            action_mode=self.action_mode,
            zeta_max=self.zeta_max,
            tau_max=self.tau_max,
            physics_dt=self.physics_dt,
            n_substeps=self.n_substeps,
            with_obstacles=self.has_outer_obstacles,
            sensing=self.realism is not None,
        )
        loop, zeta_max, tau_max, dt = self._loop, self.zeta_max, self.tau_max, self.physics_dt
        velocity = self.action_mode == "velocity"

        def torque(action: np.ndarray, zeta: np.ndarray, begin: bool) -> np.ndarray:
            if velocity:
                if begin:
                    loop.begin(action * zeta_max)  # the kinematic model holds the step's starting state
                return loop.torque(zeta, dt)
            return action * tau_max

        self._layer_law = layer.feedback(torque)
        return layer

    # ----------------------------------------------------------------- realism: measurements and the truth
    def true_state(self) -> dict[str, Any]:
        """The true state of the current step: the one documented path to the truth.

        The ``info`` keys of :data:`TRUTH_KEYS` the environment has (``eta``, ``nu``, ``q``, ``qdot``, ``y``, the
        distances, the current, the obstacles' rows and gaps), computed from the simulator. At ``realism=0`` they
        equal ``info``'s; at ``realism > 0`` ``info`` holds their measured values instead. For metrics
        (:func:`uvdms_gym.evaluation.run_episode` judges on it), training-time teachers and the leaderboard's
        privileged reference rows only: a controller that reads it is not evaluated as a measured one.
        """
        if self.task is None:
            raise RuntimeError("call reset() before true_state()")
        if self.realism is None:
            return {k: self._last_info[k] for k in TRUTH_KEYS if k in self._last_info}
        return dict(self._truth)

    def observe_estimate(
        self,
        eta: np.ndarray,
        nu: np.ndarray,
        q: np.ndarray,
        qdot: np.ndarray,
        obstacles: np.ndarray | None = None,
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """The observation and ``info`` state keys of an estimated (or measured) state, at the current time.

        What the environment builds from the truth at ``realism=0``, built from ``(eta, nu, q, qdot)`` instead: the
        tracking errors against the reference, the clearances, the scaled velocities (and, with obstacles, their
        slots from the given rows). The navigation filter's wrapper (:mod:`uvdms_gym.realism.navigation`) puts
        its estimate where the oracle state was with it.

        Returns:
            ``(obs, keys)``: the observation and the ``info`` keys ``eta``, ``nu``, ``q``, ``qdot``, ``y``,
            ``distances``, ``min_distance`` (and the obstacle keys) of that state.
        """
        if self.task is None:
            raise RuntimeError("call reset() before observe_estimate()")
        from uvdms_gym.envs.measured_kinematics import MeasuredKinematics, assemble_observation

        kin = self._measured_kin
        if kin is None or type(kin) is KinematicModel:  # once: the compiled placements, where the model allows
            model = kin or KinematicModel(self.params)
            kin = MeasuredKinematics(model) if MeasuredKinematics.supports(model) else model
            self._measured_kin = kin
        eta, nu, q, qdot = (np.array(v, dtype=float) for v in (eta, nu, q, qdot))
        kin.set_state(eta, q)
        fast = type(kin) is MeasuredKinematics
        d = kin.clearances() if fast else compute_distances(kin, "exact").d  # a new array
        y, rot = self._output_at(kin)
        cached = self._estimate_refs  # the preview reference at this time, if the step's truth computed it
        if cached is not None and cached[0] == self.t and cached[1] is self.task:
            refs = cached[2]
        else:
            refs = self.task.reference(self.t + self._preview_times)
            self._estimate_refs = (self.t, self.task, refs)
        blocks, _, _ = self._errors_at(y, rot, refs, kin.frame_placement("vehicle")[1])
        if fast and getattr(type(self)._assemble, COMPILED_EQUIVALENT, False):  # the same values in one compiled call
            obs = assemble_observation(blocks, eta, nu, q, qdot, d, self._nu_scale, self._qdot_scale)
        else:
            obs = self._assemble(blocks, eta, nu, q, qdot, d)
        keys = {"eta": eta, "nu": nu, "q": q, "qdot": qdot, "y": y, "distances": d, "min_distance": min(d.tolist())}
        return obs, keys

    def _output_at(self, kin: KinematicModel) -> tuple[np.ndarray, np.ndarray | None]:
        """Tracked output ``y`` (6) of a kinematic model's state and the rotation it came from (if any)."""
        raise NotImplementedError  # pragma: no cover - abstract

    def _errors_at(
        self, y: np.ndarray, rot: np.ndarray | None, refs: np.ndarray, r_nb: np.ndarray
    ) -> tuple[np.ndarray, float, float]:
        """:meth:`_errors` of an output from :meth:`_output_at` (default: the output alone)."""
        return self._errors(y, refs, r_nb)

    def _obstacle_rows(self, t: float) -> np.ndarray | None:
        """The outer obstacles' true rows at time ``t`` (``None``: the task has none)."""
        return None

    def _reset_layer(
        self, noise_key: tuple[int, int], obs: np.ndarray, info: dict[str, Any]
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start the realism layer's episode at the true initial state; the measured observation at ``realism > 0``."""
        layer = self._layer
        assert layer is not None
        source = self._obstacle_rows if self.has_outer_obstacles else None
        measurements = layer.reset(*noise_key, info["eta"], info["nu"], info["q"], obstacles_at=source)
        info.update(tau_cmd=np.zeros(GENERALIZED_FORCES), thrust_saturated=False)
        if layer.thrusters is not None:
            info["thrust"] = layer.thrusters.thrust.copy()
        if not layer.sensing:
            return obs, info
        return self._measured(obs, info, measurements)

    def _layer_measure(self, info: dict[str, Any]) -> Measurements:
        """The sensors' samples at the end of the step (from the true ``info``) and what arrived by now."""
        assert self._layer is not None
        return self._layer.measure(self.t, info["eta"], info["nu"], info["q"], info.get("obstacles"))

    def _measured(
        self, obs: np.ndarray, info: dict[str, Any], measurements: Measurements
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Keep the truth aside and put the raw measured state where it was (observation and state keys)."""
        layer = self._layer
        assert layer is not None
        self._truth = {k: info[k] for k in TRUTH_KEYS if k in info}
        ref0 = info.get("y_ref")  # row 0 of the truth's preview reference at this time: reuse the whole of it
        refs = ref0.base if isinstance(ref0, np.ndarray) else None
        if (
            isinstance(refs, np.ndarray)
            and refs.shape == (self._preview_times.size, ref0.size)
            and refs.__array_interface__["data"][0] == ref0.__array_interface__["data"][0]
        ):
            self._estimate_refs = (self.t, self.task, refs)
        eta, nu, q, qdot = layer.measured_state()
        rows = info.get("obstacles")
        obs_m, keys = self.observe_estimate(eta, nu, q, qdot, None if rows is None else layer.measured_obstacles(rows))
        info.pop("current", None)
        info.update(keys)
        info["measurements"] = measurements
        self._obs = obs_m
        return obs_m.copy(), info
