"""The obstacle features a policy observes with ``obstacle_features=True``: each observed obstacle's nearest pair.

The obstacle slots of ``uvdms/TransportObstacles-v1``'s observation give each obstacle's centre, velocity, axis and
size relative to the vehicle, but not which robot part is nearest, nor which command opens the gap: a network has
to learn the forward kinematics of twelve links and the object to find out. :class:`ObstacleFeatures` computes it
with the environment's explicit kinematic model, **from the observation alone** (the slots are still the policy's
only view of the obstacles): the joint angles come from the observation's ``sin q`` and ``cos q``, the body
velocity and joint rates from their scaled entries, and each slot's obstacle is placed in the body frame (the robot
at the identity pose: gaps and the gap rates ``J_dis zeta`` do not depend on the frame they are computed in). No
optimisation runs: the features are the rows a collision-avoiding MPC would constrain, handed to the network.

Per slot ``k`` (nearest first, as the observation orders them), with ``i`` the part nearest the obstacle,
``d`` its surface gap (m), ``G = J_dis,i diag(zeta_max)`` the closing rate of the gap per unit of normalised
action (m/s; ``d_dot = -J_dis zeta + n^T v_obs``), ``r = n^T v_obs`` the gap's rate from the obstacle's own
motion, ``d_dot = r - J_dis,i zeta`` its rate under the measured velocity, ``d_pred = d + min(0, d_dot)
LOOKAHEAD`` and ``w = 1 - S(d_pred)`` (the velocity damper of :func:`uvdms_gym.distances.velocity_damper` with
thresholds :data:`FEATURE_D1`, :data:`FEATURE_D2`: 1 inside ``d1``, 0 beyond ``d2``)::

    d / GAP_SCALE, r / RATE_SCALE, d_dot / RATE_SCALE, d_pred / GAP_SCALE,       (4)
    w * (-G) / |G|            (18): the action direction that opens the gap, while it is closing in
    |G| / RATE_SCALE,                                                             (1)
    w * a                     (3): the unit direction out of the obstacle's path (body frame; the part of
                                   p - e across the obstacle's velocity relative to the vehicle)
    mask                      (1)

(27 per slot; a padded slot is all zero), then ``sum_j w_j (-G_j) / |G_j|`` over every part of every observed
obstacle (18): the direction that opens all the gaps closing in. Everything is clipped to
``[-FEATURE_CLIP, FEATURE_CLIP]``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from uvdms_gym.distances.kernels import jdis_rows
from uvdms_gym.distances.outer import compute_outer_distances, part_masks
from uvdms_gym.evaluation import Controller
from uvdms_gym.physics.kinematics import KinematicModel
from uvdms_gym.physics.obstacles import STATE_COLS
from uvdms_gym.residual.clearance import FEATURE_CLIP, KinematicHelper
from uvdms_gym.utils.jit import jit

SLOT_SIZE = 13
"""Values of one obstacle slot of the observation (``uvdms_gym.envs.obstacles.OBSTACLE_SLOT``; a test checks)."""
SLOT_POS_SCALE = 2.0
"""The slots' position scale, m (``uvdms_gym.envs.obstacles.OBSTACLE_POS_SCALE``; a test checks)."""
SLOT_VEL_SCALE = 0.5
"""The slots' velocity scale, m/s (``OBSTACLE_VEL_SCALE``)."""
SLOT_SIZE_SCALE = 0.5
"""The slots' size scale, m (``OBSTACLE_SIZE_SCALE``)."""
NU = slice(20, 26)
"""The body velocity ``nu / zeta_max[:6]`` in the observation (:mod:`uvdms_gym.envs.base`)."""
SIN_Q, COS_Q = slice(26, 38), slice(38, 50)
"""``sin q`` and ``cos q`` in the observation."""
QDOT = slice(50, 62)
"""The joint rates ``qdot / zeta_max[6:]`` in the observation."""

GAP_SCALE = 0.15
"""Scale of the gaps among the features, m (the MPC's outer damper threshold ``outer_d2``)."""
RATE_SCALE = 0.5
"""Scale of the gap rates among the features, m/s."""
LOOKAHEAD = 1.0
"""How far ahead the predicted gap looks on the current gap rate, s."""
FEATURE_D1 = 0.02
"""Gap (m) inside which the weight ``w`` of a pair is 1."""
FEATURE_D2 = 0.4
"""Gap (m) beyond which the weight ``w`` of a pair is 0 (the predicted gap)."""
PER_SLOT = 27
"""Features per observed obstacle."""
_NO_OBSTACLE_MASK = 0.5
"""A slot whose mask entry is below this is padding."""


class ObstacleFeatures(KinematicHelper):
    """The features of the module docstring, from one observation of ``uvdms/TransportObstacles-v1``.

    Args:
        kin: A kinematic model of the environment's vehicle (its state is overwritten on every call).
        zeta_max: The velocity-mode action scale (18).
        n_slots: The observation's obstacle slots (the environment's ``n_observed_obstacles``).
        with_object: The robot holds the object (its rows are part of each obstacle's).
    """

    option = "obstacle_features=True"

    def __init__(self, kin: Any, zeta_max: np.ndarray, n_slots: int, with_object: bool = True) -> None:
        super().__init__(kin, zeta_max)
        if isinstance(n_slots, bool) or not isinstance(n_slots, int) or n_slots < 1:
            raise ValueError(f"obstacle features need at least one obstacle slot, got n_slots={n_slots!r}")
        self.n_slots = n_slots
        self.with_object = bool(with_object)
        self.size = PER_SLOT * n_slots + 18
        self._masks: dict[int, np.ndarray] = {}

    @classmethod
    def for_env(cls, env: Any) -> ObstacleFeatures:
        """The features of an environment with obstacle slots (through wrappers).

        Raises:
            ValueError: ``env`` is not a UVDMS environment with observed obstacles.
        """
        base = getattr(env, "unwrapped", env)
        n_slots = getattr(base, "n_observed_obstacles", 0)
        if not hasattr(base, "params") or not hasattr(base, "zeta_max") or not n_slots:
            name = env.spec.id if getattr(env, "spec", None) is not None else type(base).__name__
            raise ValueError(
                f"{cls.option} needs an environment whose observation has obstacle slots "
                f"(uvdms/TransportObstacles-v1 with n_observed_obstacles >= 1), not {name}"
            )
        return cls(KinematicModel(base.params), base.zeta_max, int(n_slots))

    def slot_states(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The observed obstacles as ``obstacle_states`` rows in the body frame, and the indices of their slots."""
        obs = np.asarray(obs, dtype=np.float64)
        return _slot_states(obs, self.n_slots, self.zeta_max[:3] * obs[NU][:3])

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The features (``size``, float64) of one observation."""
        obs = np.asarray(obs, dtype=np.float64)
        out = np.zeros(self.size)
        states, used = self.slot_states(obs)
        if used.size == 0:
            return out
        zeta = np.concatenate([obs[NU] * self.zeta_max[:6], obs[QDOT] * self.zeta_max[6:]])
        self.kin.set_state(np.zeros(6), np.arctan2(obs[SIN_Q], obs[COS_Q]))
        res = compute_outer_distances(self.kin, states, self.with_object)
        sel = self._masks.get(used.size)
        if sel is None:
            sel = self._masks[used.size] = np.tile(part_masks(self.kin.model, self.with_object), (used.size, 1))
        jac = jdis_rows(sel, self.kin.data.J, res.p, res.e)
        _assemble(res.d, res.p, res.e, jac, states, used, self.zeta_max, zeta, res.n_parts, out)
        return out


@jit
def _slot_states(obs, n_slots, nu_lin):  # pragma: no cover - compiled
    """:meth:`ObstacleFeatures.slot_states` in one compiled loop (``nu_lin``: the body's linear velocity, m/s)."""
    first = obs.shape[0] - SLOT_SIZE * n_slots
    used = np.array([k for k in range(n_slots) if obs[first + SLOT_SIZE * k + 12] >= _NO_OBSTACLE_MASK], np.int64)
    states = np.zeros((used.shape[0], STATE_COLS))
    for row in range(used.shape[0]):
        s = obs[first + SLOT_SIZE * used[row] : first + SLOT_SIZE * (used[row] + 1)]
        for j in range(3):
            states[row, j] = SLOT_POS_SCALE * s[j]
            states[row, 3 + j] = SLOT_VEL_SCALE * s[3 + j] + nu_lin[j]  # the slot's is relative to the body origin's
            states[row, 8 + j] = s[6 + j]
        states[row, 6] = SLOT_SIZE_SCALE * s[9]
        states[row, 7] = SLOT_SIZE_SCALE * s[10]
    return states, used


@jit
def _assemble(d, p, e, jac, states, used, zeta_max, zeta, n_parts, out):  # pragma: no cover - compiled
    """The features of :meth:`ObstacleFeatures.__call__` from the pairs' gaps, points and ``J_dis`` rows."""
    n_rows = d.shape[0]
    total = out.shape[0] - 18
    nearest = 0
    for r in range(n_rows):
        k = r // n_parts
        if r % n_parts == 0:  # the first part of obstacle k: find its nearest part once
            nearest = r + np.argmin(d[r : r + n_parts])
        n = e[r] - p[r]
        nrm = np.sqrt(n @ n)
        if nrm > 0.0:
            n = n / nrm
        rate = n @ states[k, 3:6]
        gain = jac[r] * zeta_max
        g = max(np.sqrt(gain @ gain), 1e-12)
        d_dot = rate - jac[r] @ zeta
        d_pred = d[r] + min(d_dot, 0.0) * LOOKAHEAD
        x = min(max((d_pred - FEATURE_D1) / (FEATURE_D2 - FEATURE_D1), 0.0), 1.0)
        w = 1.0 - np.sin(0.5 * np.pi * x) ** 2
        out[total:] -= (w / g) * gain
        if r != nearest:
            continue
        base = PER_SLOT * used[k]
        out[base] = d[r] / GAP_SCALE
        out[base + 1] = rate / RATE_SCALE
        out[base + 2] = d_dot / RATE_SCALE
        out[base + 3] = d_pred / GAP_SCALE
        out[base + 4 : base + 22] = -(w / g) * gain
        out[base + 22] = g / RATE_SCALE
        away = p[r] - e[r]
        vel = states[k, 3:6] - zeta[:3]  # the obstacle's velocity relative to the vehicle's
        speed2 = vel @ vel
        if speed2 > 1e-12:
            away = away - (away @ vel) / speed2 * vel
        norm = np.sqrt(away @ away)
        if norm > 1e-9:
            out[base + 23 : base + 26] = (w / norm) * away
        out[base + 26] = 1.0
    for j in range(out.shape[0]):
        out[j] = min(max(out[j], -FEATURE_CLIP), FEATURE_CLIP)


def obstacle_feature_space(space: gym.spaces.Box, features: ObstacleFeatures) -> gym.spaces.Box:
    """``space`` extended by the features (bounds ``+-FEATURE_CLIP``), in its dtype."""
    low = np.concatenate([space.low, np.full(features.size, -FEATURE_CLIP)])
    high = np.concatenate([space.high, np.full(features.size, FEATURE_CLIP)])
    return gym.spaces.Box(low.astype(space.dtype), high.astype(space.dtype), dtype=space.dtype)


def with_features(obs: np.ndarray, features: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """``[obs; features(obs)]`` in the observation's dtype."""
    obs = np.asarray(obs)
    return np.concatenate([obs, features(obs).astype(obs.dtype)])


def opening_columns(n_slots: int) -> np.ndarray:
    """Where each slot's weighted opening direction ``w (-G) / |G|`` lies in the features, ``(n_slots, 18)``.

    Indices into the :class:`ObstacleFeatures` vector (the last ``PER_SLOT * n_slots + 18`` values of an observation
    with the features): the command directions along which a learner's error matters most near an obstacle.
    """
    return np.array([[PER_SLOT * k + 4 + j for j in range(18)] for k in range(n_slots)], dtype=np.int64)


class ObstacleFeatureObservation(gym.ObservationWrapper):
    """Training wrapper: the observation followed by its :class:`ObstacleFeatures`.

    Attributes:
        features: The features it appends.
        opening_index: The columns of each slot's opening direction in this wrapper's observation, ``(n_slots, 18)``
            as nested lists (plain data, which a vectorised env's ``get_attr`` can report from a worker).
        featured_dim: The size of this wrapper's observation.

    Raises:
        ValueError: ``env`` has no obstacle slots (:meth:`ObstacleFeatures.for_env`).
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.features = ObstacleFeatures.for_env(env)
        self.observation_space = obstacle_feature_space(env.observation_space, self.features)  # type: ignore[arg-type]
        self.featured_dim = int(self.observation_space.shape[0])
        first = self.featured_dim - self.features.size
        self.opening_index = (first + opening_columns(self.features.n_slots)).tolist()

    def observation(self, observation: np.ndarray) -> np.ndarray:
        """``[obs; features(obs)]``."""
        return with_features(observation, self.features)


class FeatureController:
    """Evaluation: a policy trained with features of its observation receives ``[obs; features(obs)]``.

    ``obstacle_features=True`` (:class:`ObstacleFeatures`) and ``tracking_features=True``
    (:class:`~uvdms_gym.residual.TrackingFeatures`); with both, the tracking controller inside the obstacle one, as
    the training wrappers nest.

    Args:
        policy: The trained policy's controller (``reset(seed)``, ``predict(obs, info)``).
        features: The features of the environment it drives (a callable of one observation with a ``size``).
    """

    def __init__(self, policy: Controller, features: Callable[[np.ndarray], np.ndarray]) -> None:
        self.policy = policy
        self.features = features

    def reset(self, seed: int | None = None) -> None:
        """Reset the policy."""
        self.policy.reset(seed)

    def predict(self, obs: np.ndarray, info: Mapping[str, Any] | None = None) -> np.ndarray:
        """The policy's action on the observation with its features."""
        return self.policy.predict(with_features(obs, self.features), info)


ObstacleFeatureController = FeatureController
"""The name :class:`FeatureController` had when the obstacle features were the only ones (0.9.0-0.9.2)."""
