"""Ocean current processes: the environments' ``current`` keyword, parsed into a :class:`CurrentModel`.

The current is a uniform, irrotational water velocity ``v_c`` in NED (m/s). The simulator
(:meth:`uvdms_gym.physics.sim.UVDMSSim.set_current`) makes every hydrodynamic load act on the velocity relative to
the water (Fossen's relative-velocity form, :mod:`uvdms_gym.physics.hydro`); this module only decides what
``v_c`` is at each control step:

* ``None`` (default): no current; the simulator's code path is the one without a current, bit for bit.
* a NED vector of 3 finite floats (magnitude at most :data:`MAX_CONSTANT_SPEED`): :class:`ConstantCurrent`.
* ``"random"``: :class:`RandomCurrent`, a per-episode draw (magnitude uniform in ``[0, max_speed]``, heading
  uniform, small elevation) around which the current varies slowly as a first-order Gauss-Markov process
  (Fossen 2011, section 8.3: ``V_dot + mu V = w``), discretised exactly per control step.

All randomness comes from the ``np.random.Generator`` passed in (the environment's ``np_random``), so the same
seed gives the same currents.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from uvdms_gym.utils.validation import finite_vector

MAX_CONSTANT_SPEED = 2.0
"""Largest accepted magnitude of a constant current, m/s (far beyond what the vehicle can hold against)."""
RANDOM = "random"
"""The string value of the ``current`` keyword that selects :class:`RandomCurrent`."""


@dataclass(frozen=True)
class CurrentState:
    """The state of a current process within an episode.

    Attributes:
        mean: the episode's mean current ``x0`` (NED, m/s), around which the process varies.
        value: the current of the present control step (NED, m/s).
    """

    mean: tuple[float, float, float]
    value: tuple[float, float, float]


@dataclass(frozen=True)
class CurrentModel:
    """Base class of the current processes: a per-episode start and a per-control-step update."""

    random: bool = False
    """Whether the process draws random numbers (the environment advances only these every step)."""

    def start(self, rng: np.random.Generator) -> CurrentState:  # pragma: no cover - abstract
        """The state at the start of an episode."""
        raise NotImplementedError

    def advance(self, state: CurrentState, dt: float, rng: np.random.Generator) -> CurrentState:
        """The state one control step ``dt`` (s) later (default: unchanged)."""
        return state


@dataclass(frozen=True)
class ConstantCurrent(CurrentModel):
    """A current that is the same in every episode and at every step."""

    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """The current, NED, m/s."""

    def start(self, rng: np.random.Generator) -> CurrentState:
        """The constant current (``rng`` is not used)."""
        return CurrentState(mean=self.velocity, value=self.velocity)


@dataclass(frozen=True)
class RandomCurrent(CurrentModel):
    """A per-episode random current that varies slowly within the episode (first-order Gauss-Markov).

    At the start of an episode the mean ``x0`` is drawn: magnitude uniform in ``[0, max_speed]``, heading uniform
    in ``[0, 2 pi)``, elevation uniform in ``[-max_elevation, max_elevation]`` (mostly horizontal). The process
    starts at ``x0`` and each control step of length ``dt`` updates every NED component exactly as the solution of
    ``V_dot + mu (V - x0) = w`` over ``dt``::

        x_{k+1} = x0 + (x_k - x0) exp(-mu dt) + sigma_i sqrt(1 - exp(-2 mu dt)) n_k,   n_k ~ N(0, 1)

    (``sigma_i`` the stationary standard deviation of component ``i``), then scales the vector down to
    ``max_speed`` if it is longer.
    """

    random: bool = True
    max_speed: float = 0.2
    """Upper bound of the current's magnitude (the draw and every step), m/s."""
    max_elevation: float = math.radians(10.0)
    """Largest angle of the drawn mean current out of the horizontal plane, rad."""
    mu: float = 0.05
    """Inverse correlation time of the Gauss-Markov process, 1/s (20 s: slow against a 20 s episode)."""
    sigma: float = 0.02
    """Stationary standard deviation of each horizontal component about the episode's mean, m/s."""
    sigma_vertical: float = 0.005
    """Stationary standard deviation of the vertical (down) component, m/s."""

    def __post_init__(self) -> None:
        for name in ("max_speed", "max_elevation", "mu", "sigma", "sigma_vertical"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"RandomCurrent.{name} must be finite and >= 0, got {value!r}")

    def start(self, rng: np.random.Generator) -> CurrentState:
        """Draw the episode's mean current (three draws from ``rng``) and start there."""
        speed = float(rng.uniform(0.0, self.max_speed))
        heading = float(rng.uniform(0.0, 2.0 * math.pi))
        elevation = float(rng.uniform(-self.max_elevation, self.max_elevation))
        horizontal = speed * math.cos(elevation)
        x0 = (horizontal * math.cos(heading), horizontal * math.sin(heading), speed * math.sin(elevation))
        return CurrentState(mean=x0, value=x0)

    def advance(self, state: CurrentState, dt: float, rng: np.random.Generator) -> CurrentState:
        """One exact Gauss-Markov step of ``dt`` seconds (three normal draws from ``rng``), magnitude clipped."""
        decay = math.exp(-self.mu * dt)
        spread = math.sqrt(max(0.0, 1.0 - decay * decay))
        sigmas = np.array([self.sigma, self.sigma, self.sigma_vertical])
        x0 = np.array(state.mean)
        x = x0 + (np.array(state.value) - x0) * decay + sigmas * spread * rng.standard_normal(3)
        norm = float(np.linalg.norm(x))
        if norm > self.max_speed:
            x *= self.max_speed / norm
        return CurrentState(mean=state.mean, value=(float(x[0]), float(x[1]), float(x[2])))


def parse_current(spec: Any) -> CurrentModel | None:
    """The :class:`CurrentModel` of the environments' ``current`` keyword.

    Args:
        spec: ``None`` (no current), a :class:`CurrentModel`, a NED vector of 3 finite floats in m/s with magnitude
            at most :data:`MAX_CONSTANT_SPEED`, or ``"random"``.

    Returns:
        The model, or ``None`` for no current.

    Raises:
        ValueError: anything else (unknown string, wrong shape, non-numeric, NaN/inf, too fast), naming the problem.
    """
    if spec is None or isinstance(spec, CurrentModel):
        return spec
    if isinstance(spec, str):
        if spec == RANDOM:
            return RandomCurrent()
        raise ValueError(f"current must be None, {RANDOM!r} or a NED vector of 3 floats (m/s); got the string {spec!r}")
    return ConstantCurrent(velocity=_constant_velocity(spec))


def _constant_velocity(spec: Any) -> tuple[float, float, float]:
    """Validate a constant current: 3 finite floats, magnitude at most :data:`MAX_CONSTANT_SPEED`."""
    prefix = f"current must be None, {RANDOM!r} or a NED vector of 3 floats (m/s)"
    if isinstance(spec, (dict, bool, bytes)):
        raise ValueError(f"{prefix}; got a {type(spec).__name__}: {spec!r}")
    try:
        arr = finite_vector(spec, 3, "current")
    except ValueError as exc:
        raise ValueError(f"{prefix}; {exc}") from None
    speed = float(np.linalg.norm(arr))
    if speed > MAX_CONSTANT_SPEED:
        raise ValueError(f"current {spec!r} has magnitude {speed:.3g} m/s, above the limit of {MAX_CONSTANT_SPEED} m/s")
    return (float(arr[0]), float(arr[1]), float(arr[2]))
