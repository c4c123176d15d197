"""The friction grasp's configuration (what the ``grasp`` keyword takes) and its contact law, in plain arithmetic.

``grasp="rigid"`` (the default) welds the object to both hands (:class:`~uvdms_gym.physics.grasp.RigidGrasp`);
``grasp="friction"`` holds it by friction (:class:`~uvdms_gym.physics.friction_grasp.FrictionGrasp`), with the
defaults of :class:`~uvdms_gym.physics.params.GripperParams`; a mapping ``{"type": "friction", "mu": 0.4, ...}``
overrides single knobs, and ``mu`` and ``torsion_radius`` take one value for both hands or a pair
``[left, right]``. :func:`parse_grasp` reads it; every bad value raises one ``ValueError`` naming the knob.

The contact law of one hand (:class:`~uvdms_gym.physics.params.GripperParams` states the model): with the grip force
``F``, the axial capacity ``f_max = mu F`` and the torsional capacity ``m_max = mu r_t F``; the hand sticks while
its axial force ``f`` and twisting moment ``m`` satisfy ``(f / f_max)^2 + (m / m_max)^2 <= 1``; sliding at axial
speed ``v`` and twist rate ``w``, it transmits the friction of maximum dissipation on that ellipse,
``f = -f_max^2 v / L``, ``m = -m_max^2 w / L``, ``L = sqrt(f_max^2 v^2 + m_max^2 w^2)`` (for the band of radius
``r_t``, the friction opposing the slip velocity ``(v, r_t w)`` of its surface).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from uvdms_gym.physics.params import GripperParams

GRASP_TYPES: tuple[str, ...] = ("rigid", "friction")
"""The values of the ``grasp`` keyword."""
STICK_SPEED = 1.0e-6
"""Slip speed ``sqrt(v^2 + (r_t w)^2)`` (m/s) below which a hand is sticking: a held joint's speed is zero to the
solver's precision (1e-12), a sliding one's is many orders above this."""


@dataclass(frozen=True)
class FrictionGraspConfig:
    """The friction grasp's knobs (defaults: :class:`~uvdms_gym.physics.params.GripperParams`).

    Attributes:
        mu: friction coefficient of each hand ``(left, right)``.
        torsion_radius: torsional radius of each hand's contact ``(left, right)``, m.
        grip_max: the grippers' force limit, N (a commanded grip force is clipped to ``[0, grip_max]``).
        crush_force: the object's squeeze limit, N (a grip force above it crushes the object).
        drop_slip: axial slip at which a hand has lost the object, m.
        grip_initial: grip force of both hands at reset, N.
    """

    mu: tuple[float, float] = (GripperParams.mu, GripperParams.mu)
    torsion_radius: tuple[float, float] = (GripperParams.torsion_radius, GripperParams.torsion_radius)
    grip_max: float = GripperParams.grip_max
    crush_force: float = GripperParams.crush_force
    drop_slip: float = GripperParams.drop_slip
    grip_initial: float = GripperParams.grip_initial

    def capacity(self, side: int, grip: float) -> tuple[float, float]:
        """Axial (N) and torsional (N m) capacity ``(mu F, mu r_t F)`` of hand ``side`` (0 left, 1 right)."""
        f_max = self.mu[side] * grip
        return f_max, f_max * self.torsion_radius[side]


_KNOBS = tuple(f.name for f in dataclasses.fields(FrictionGraspConfig))


def parse_grasp(value: Any) -> FrictionGraspConfig | None:
    """The friction grasp the ``grasp`` keyword names, or ``None`` for the rigid grasp.

    Args:
        value: ``"rigid"``, ``"friction"``, a :class:`FrictionGraspConfig`, or a mapping with ``type`` (default
            ``"friction"``) and knob overrides.

    Raises:
        ValueError: one line naming the problem (an unknown grasp or knob, ``mu <= 0``, NaN, a grip force beyond
            the gripper's limit).
    """
    if isinstance(value, FrictionGraspConfig):
        cfg = value
    elif isinstance(value, str):
        if value not in GRASP_TYPES:
            raise ValueError(f"unknown grasp {value!r}: expected one of {list(GRASP_TYPES)} (or a mapping of knobs)")
        if value == "rigid":
            return None
        cfg = FrictionGraspConfig()
    elif isinstance(value, Mapping):
        cfg = _from_mapping(value)
        if cfg is None:
            return None
    else:
        raise ValueError(f"grasp must be 'rigid', 'friction' or a mapping of knobs, got {value!r}")
    check_grasp(cfg)
    return cfg


def _from_mapping(value: Mapping[str, Any]) -> FrictionGraspConfig | None:
    """The knobs of a mapping ``{"type": "friction", "mu": ..., ...}`` (``None``: ``{"type": "rigid"}``)."""
    items = dict(value)
    kind = items.pop("type", "friction")
    if kind != "friction":
        if kind == "rigid" and not items:
            return None
        raise ValueError(f"grasp: type must be 'friction' for a mapping of knobs, got {kind!r}")
    unknown = sorted(set(items) - set(_KNOBS))
    if unknown:
        raise ValueError(f"grasp: unknown knob(s) {unknown}; knobs are {list(_KNOBS)}")
    for key in ("mu", "torsion_radius"):
        if key in items:
            items[key] = _pair(key, items[key])
    return dataclasses.replace(FrictionGraspConfig(), **items)


def _pair(key: str, value: Any) -> tuple[float, float]:
    """One value for both hands or a ``[left, right]`` pair."""
    if isinstance(value, (list, tuple)):
        if len(value) != 2:
            raise ValueError(f"grasp: {key} must be one number or a pair [left, right], got {value!r}")
        return (value[0], value[1])
    return (value, value)


def _number(key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"grasp: {key} must be a finite number, got {value!r}")
    return float(value)


def check_grasp(cfg: FrictionGraspConfig) -> None:
    """Raise one ``ValueError`` naming the first bad knob of ``cfg``."""
    for key in ("mu", "torsion_radius"):
        for side, v in zip(("left", "right"), getattr(cfg, key), strict=True):
            if _number(f"{key} ({side})", v) <= 0.0:
                raise ValueError(f"grasp: {key} must be > 0, got {v!r} for the {side} hand")
    for key in ("grip_max", "crush_force", "drop_slip"):
        if _number(key, getattr(cfg, key)) <= 0.0:
            raise ValueError(f"grasp: {key} must be > 0, got {getattr(cfg, key)!r}")
    grip = _number("grip_initial", cfg.grip_initial)
    if not 0.0 <= grip <= cfg.grip_max:
        raise ValueError(
            f"grasp: grip_initial {grip!r} N is beyond the gripper's limit: "
            f"it must be in [0, grip_max = {cfg.grip_max} N]"
        )


def stick_bounds(f_max: float, m_max: float, f: float, m: float) -> tuple[float, float]:
    """Force bounds of a sticking hand given last step's axial force ``f`` and moment ``m``.

    Inside the ellipse the full capacities (the solver holds the hand where the demand fits); a demand beyond it
    (the box's corners exceed the ellipse) is scaled back onto it, so the hand starts to slide along the demand.
    """
    if f_max <= 0.0:
        return 0.0, 0.0
    rho2 = (f / f_max) ** 2 + (m / m_max) ** 2
    if rho2 <= 1.0:
        return f_max, m_max
    rho = math.sqrt(rho2)
    return abs(f) / rho, abs(m) / rho


def slide_bounds(f_max: float, m_max: float, v: float, w: float) -> tuple[float, float]:
    """Force bounds of a hand sliding at axial speed ``v`` and twist rate ``w``: maximum dissipation on the ellipse."""
    lam = math.sqrt((f_max * v) ** 2 + (m_max * w) ** 2)
    if lam == 0.0:
        return f_max, m_max
    return f_max * f_max * abs(v) / lam, m_max * m_max * abs(w) / lam


def slide_direction(prev: tuple[float, float], f_max: float, m_max: float, v: float, w: float) -> tuple[float, float]:
    """The direction ``(c_f, c_m)`` (a unit vector of ``(|f| / f_max, |m| / m_max)``) of a sliding hand's friction.

    The mean of the last direction ``prev`` and that of :func:`slide_bounds` for the last step's slip ``(v, w)``,
    normalised; the hand's bounds are then ``(c_f f_max, c_m m_max)``, a point of the ellipse. The slip is the
    velocity that *resulted* from the last step's bounds, so taking its direction alone is a fixed-point iteration
    that oscillates: a direction held still (speed exactly zero) gets no friction the next step, slides, and takes
    the friction from the other. Averaging damps that iteration; its fixed point is the same direction, where the
    friction opposes the slip (maximum dissipation).

    Args:
        prev: the last physics step's direction (unit vector).
        f_max: axial capacity, N.
        m_max: torsional capacity, N m.
        v: axial slip speed, m/s.
        w: twist rate, rad/s.
    """
    lam = math.sqrt((f_max * v) ** 2 + (m_max * w) ** 2)
    if lam == 0.0:
        return prev
    cf, cm = prev[0] + f_max * abs(v) / lam, prev[1] + m_max * abs(w) / lam
    n = math.sqrt(cf * cf + cm * cm)
    return cf / n, cm / n
