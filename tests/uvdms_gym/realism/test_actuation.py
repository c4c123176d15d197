"""Thrusters and drive limits (uvdms_gym.realism.actuation), each against its definition."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from uvdms_gym.realism.actuation import (
    DEFAULT_LAYOUT,
    Thrusters,
    actuate,
    allocation_matrix,
    limit_joint_speed,
)
from uvdms_gym.realism.config import LEVELS, ThrusterLayout

DT = 0.01
F = DEFAULT_LAYOUT.max_forward
R = DEFAULT_LAYOUT.max_reverse
N_THRUSTERS = 8
H = math.sqrt(0.5)

# The measured extremes (benchmarks/task_wrenches.py, campc, the first 12 validation draws of CircleTrack-v1
# case="random" and Transport-v1 goal="random" with hydro_randomization=0.3, current="random"; one draw of cases 1,
# 2 and the paper's transport): per run the applied body wrench [X, Y, Z, K, M, N] (N, N m) that needs the largest
# thrust fraction of DEFAULT_LAYOUT, and the one with the largest |component| on each axis, over the scored samples
# (the transport's whole run, the circles after their 5 s approach).
SCORED_WRENCHES = np.array(
    [
        [-5.5, -2.1, -166.6, -12.9, 69.6, -0.4],  # circle-case1 (0.394)
        [-6.8, -1.8, -167.1, -5.3, 65.7, -0.7],  # circle-case1 (0.350)
        [-5.7, -2.1, -166.9, -12.8, 69.6, -0.5],  # circle-case1 (0.394)
        [0.3, -1.7, -167.9, -5.5, 65.5, -0.7],  # circle-case1 (0.352)
        [-4.9, -1.9, -165.8, -13.0, 69.5, -0.4],  # circle-case1 (0.393)
        [-6.1, -2.0, -167.3, -12.5, 69.7, -0.5],  # circle-case1 (0.393)
        [2.9, -1.2, -167.6, -5.6, 65.6, -1.0],  # circle-case1 (0.353)
        [-10.3, -1.2, -165.5, -10.2, 66.0, 0.1],  # circle-case2 (0.371)
        [-11.2, -1.4, -166.2, -9.2, 65.9, -0.1],  # circle-case2 (0.367)
        [-10.0, -1.7, -166.1, -6.7, 65.1, 0.1],  # circle-case2 (0.354)
        [-8.2, 0.2, -166.3, -5.1, 63.9, -0.1],  # circle-case2 (0.344)
        [-10.2, -1.2, -165.4, -10.2, 66.0, 0.1],  # circle-case2 (0.371)
        [-10.6, -1.3, -165.6, -10.1, 66.0, 0.1],  # circle-case2 (0.371)
        [-8.2, -0.4, -164.4, -9.2, 65.8, 0.4],  # circle-case2 (0.366)
        [-368.3, 70.6, 427.1, -3.2, 54.6, 2.5],  # circle-random (0.804)
        [418.3, -50.5, -324.4, 9.1, 101.9, -3.0],  # circle-random (0.677)
        [-32.2, -144.1, 251.2, 12.0, 63.3, -2.7],  # circle-random (0.627)
        [344.2, -27.8, -500.0, 3.2, 77.0, -2.0],  # circle-random (0.751)
        [-1.4, -0.0, -112.9, 23.5, 75.6, -0.3],  # circle-random (0.404)
        [286.9, 22.3, -214.7, 3.0, 115.5, -1.0],  # circle-random (0.540)
        [28.3, -18.5, -464.4, 3.1, 76.3, -5.1],  # circle-random (0.672)
        [12.9, -15.8, -213.2, 1.1, 115.3, 1.1],  # transport-paper (0.505)
        [14.4, -20.4, -198.6, 1.6, 113.7, 1.0],  # transport-paper (0.490)
        [11.6, -26.2, -201.0, 2.2, 115.6, 0.8],  # transport-paper (0.500)
        [8.6, -25.7, -197.2, 2.2, 115.0, 0.5],  # transport-paper (0.495)
        [13.5, -23.9, -202.5, 1.8, 115.9, 1.0],  # transport-paper (0.500)
        [9.3, -18.3, -178.3, 1.4, 108.0, 1.1],  # transport-paper (0.453)
        [100.3, -18.6, -500.0, 1.8, 150.0, 0.7],  # transport-random (0.890)
        [115.5, -15.3, -500.0, 1.3, 150.0, 0.2],  # transport-random (0.889)
        [-2.6, 36.6, -242.9, -0.8, 116.1, 0.3],  # transport-random (0.538)
        [-16.0, -1.7, -500.0, 0.0, 121.0, -1.2],  # transport-random (0.794)
        [-59.5, -14.9, -289.7, 4.6, 91.7, -1.8],  # transport-random (0.530)
        [36.7, -3.9, -500.0, 0.0, 150.0, 1.0],  # transport-random (0.871)
        [20.2, -29.3, -500.0, 2.7, 124.7, -5.3],  # transport-random (0.826)
    ]
)
APPROACH_WRENCHES = np.array(
    [
        [500.0, -22.3, -218.5, 3.7, 97.0, 1.2],  # circle-case1 (0.742)
        [500.0, -123.3, -408.3, 4.8, 90.9, 0.9],  # circle-case2 (0.884)
        [500.0, -305.3, -500.0, 16.2, 102.8, 2.3],  # circle-random (1.145)
    ]
)
SCORED_MAX_FRACTION = 0.9
"""The thrust fraction the scored wrenches may use at most (module docstring of actuation: 0.89 measured)."""
APPROACH_MIN_SCALE = 0.85
"""The smallest allocation scale of the circles' approach transient (0.87 measured; the 500 N box saturates too)."""


def thrust_fraction(layout: ThrusterLayout, wrench: np.ndarray) -> np.ndarray:
    """Largest |u| of the least-norm thrusts of each wrench, from numpy's least squares (not the module's pinv)."""
    b = allocation_matrix(layout)
    w = np.atleast_2d(wrench)
    f = np.linalg.lstsq(b, w.T, rcond=None)[0].T
    return np.maximum(f / layout.max_forward, -f / layout.max_reverse).max(axis=1)


def thrusters(**kwargs) -> Thrusters:
    kwargs.setdefault("physics_dt", DT)
    return Thrusters(DEFAULT_LAYOUT, **kwargs)


# --- allocation matrix ---------------------------------------------------------------------------------------------


def test_allocation_matrix_columns_are_force_and_moment_about_the_origin():
    layout = ThrusterLayout(
        positions=((1.0, 2.0, 3.0), (0.0, 0.0, 0.0)),
        directions=((0.0, 0.0, 1.0), (H, H, 0.0)),
        max_forward=1.0,
        max_reverse=1.0,
    )
    b = allocation_matrix(layout)
    # r x d of (1, 2, 3) x (0, 0, 1) = (2*1 - 3*0, 3*0 - 1*1, 1*0 - 2*0)
    np.testing.assert_array_equal(b[:, 0], [0.0, 0.0, 1.0, 2.0, -1.0, 0.0])
    np.testing.assert_array_equal(b[:, 1], [H, H, 0.0, 0.0, 0.0, 0.0])


def test_default_layout_is_inside_the_hull_and_vectored():
    pos = np.array(DEFAULT_LAYOUT.positions)
    d = np.array(DEFAULT_LAYOUT.directions)
    half = np.array([0.92, 0.62, 0.56]) / 2  # VehicleParams.size
    assert (np.abs(pos) < half).all()
    horizontal, vertical = d[:4], d[4:]
    np.testing.assert_allclose(np.abs(horizontal[:, :2]), H, rtol=0, atol=1e-15)  # +-45 deg in the x-y plane
    np.testing.assert_array_equal(horizontal[:, 2], 0.0)
    np.testing.assert_array_equal(vertical, [[0.0, 0.0, -1.0]] * 4)
    assert R / F == pytest.approx(0.78)
    assert np.linalg.matrix_rank(allocation_matrix(DEFAULT_LAYOUT)) == 6


# --- allocate ------------------------------------------------------------------------------------------------------


def test_feasible_wrenches_are_reproduced():
    t = thrusters()
    rng = np.random.default_rng(0)
    for _ in range(200):
        w = rng.normal(size=6) * [300, 300, 300, 100, 100, 100]
        w *= rng.uniform(0.05, 0.999) / thrust_fraction(DEFAULT_LAYOUT, w)[0]  # inside the capacity
        f, scale = t.allocate(w)
        assert scale == 1.0
        np.testing.assert_allclose(allocation_matrix(DEFAULT_LAYOUT) @ f, w, rtol=0, atol=1e-9)
        assert (f <= F).all() and (f >= -R).all()


def test_infeasible_wrench_is_scaled_keeping_its_direction():
    t = thrusters()
    b = allocation_matrix(DEFAULT_LAYOUT)
    rng = np.random.default_rng(1)
    for _ in range(200):
        w = rng.normal(size=6) * [300, 300, 300, 100, 100, 100]
        need = thrust_fraction(DEFAULT_LAYOUT, w)[0]
        w *= rng.uniform(1.01, 5.0) / need
        f, scale = t.allocate(w)
        expected = 1.0 / thrust_fraction(DEFAULT_LAYOUT, w)[0]
        assert scale == pytest.approx(expected, rel=1e-12)
        np.testing.assert_allclose(b @ f, scale * w, rtol=0, atol=1e-9)  # parallel to w, same sense
        assert ((f == F) | (f == -R)).any()  # one thruster exactly at its limit
        assert (f <= F).all() and (f >= -R).all()  # none beyond


def test_asymmetric_limits_heave_up_and_down():
    # pure heave: the four vertical thrusters share it equally (the least-norm solution), the horizontal ones idle
    t = thrusters()
    up, scale_up = t.allocate([0.0, 0.0, -4000.0, 0.0, 0.0, 0.0])  # z down: -Z is up, the verticals' forward
    assert scale_up == pytest.approx(4 * F / 4000.0, rel=1e-12)
    np.testing.assert_allclose(up, [0, 0, 0, 0, F, F, F, F], rtol=0, atol=1e-9)
    down, scale_down = t.allocate([0.0, 0.0, 4000.0, 0.0, 0.0, 0.0])
    assert scale_down == pytest.approx(4 * R / 4000.0, rel=1e-12)
    np.testing.assert_allclose(down, [0, 0, 0, 0, -R, -R, -R, -R], rtol=0, atol=1e-9)


def test_asymmetric_limits_surge():
    # pure surge: all four horizontal thrusters at cos 45 deg; forward F each, backward R each
    t = thrusters()
    _, fwd = t.allocate([1e4, 0, 0, 0, 0, 0])
    _, back = t.allocate([-1e4, 0, 0, 0, 0, 0])
    assert fwd * 1e4 == pytest.approx(4 * F * H, rel=1e-12)
    assert back * 1e4 == pytest.approx(4 * R * H, rel=1e-12)


def test_allocate_rejects_bad_wrenches():
    t = thrusters()
    with pytest.raises(ValueError, match=r"realism: wrench must have shape \(6,\)"):
        t.allocate(np.zeros(5))
    with pytest.raises(ValueError, match="realism: wrench must be finite"):
        t.allocate([0.0, math.nan, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="realism: wrench must be finite"):
        t.allocate([math.inf, 0.0, 0.0, 0.0, 0.0, 0.0])


# --- layout validation ---------------------------------------------------------------------------------------------


def _replace(**changes) -> ThrusterLayout:
    return dataclasses.replace(DEFAULT_LAYOUT, **changes)


@pytest.mark.parametrize(
    ("layout", "match"),
    [
        (  # all horizontal: no heave (roll and pitch only from the heights)
            _replace(directions=tuple((H, s * H, 0.0) for s in (-1, 1, 1, -1, 1, -1, -1, 1))),
            r"realism: layout has rank 5 < 6",
        ),
        (_replace(positions=DEFAULT_LAYOUT.positions[:7]), "realism: layout has 7 positions but 8 directions"),
        (
            _replace(directions=((1.0, 0.0, 0.0),) * 7 + ((0.0, 0.0, 0.0),)),
            "realism: layout direction 7 must be a unit",
        ),
        (_replace(directions=((2.0, 0.0, 0.0), *DEFAULT_LAYOUT.directions[1:])), "direction 0 must be a unit vector"),
        (_replace(max_forward=0.0), "realism: layout max_forward must be a finite number > 0"),
        (_replace(max_reverse=-1.0), "realism: layout max_reverse must be a finite number > 0"),
        (_replace(max_forward=math.inf), "realism: layout max_forward"),
        (_replace(positions=((0.0, 0.0),) * 8), r"realism: layout positions and directions must be \(x, y, z\)"),
        (_replace(positions=((math.nan, 0.0, 0.0),) * 8), "realism: layout positions and directions must be finite"),
    ],
)
def test_bad_layouts_are_refused(layout, match):
    with pytest.raises(ValueError, match=match):
        Thrusters(layout, physics_dt=DT)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"rotor_time_constant": -0.1}, "realism: rotor_time_constant must be a finite number >= 0"),
        ({"rotor_time_constant": math.nan}, "realism: rotor_time_constant"),
        ({"dead_zone": 1.0}, "realism: dead_zone must be below 1"),
        ({"dead_zone": -0.1}, "realism: dead_zone must be a finite number >= 0"),
        ({"physics_dt": 0.0}, "realism: physics_dt must be a finite number > 0"),
    ],
)
def test_bad_thruster_arguments_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        thrusters(**kwargs)


def test_every_level_builds_its_thrusters():
    for level in (1, 2, 3):
        cfg = LEVELS[level]
        t = Thrusters(cfg.layout, rotor_time_constant=cfg.rotor_time_constant, dead_zone=cfg.dead_zone, physics_dt=DT)
        assert t.layout is DEFAULT_LAYOUT


# --- normalisation -------------------------------------------------------------------------------------------------


def test_normalisation_is_asymmetric_and_inverts():
    t = thrusters()
    f = np.array([F, -R, 0.5 * F, -0.5 * R, 0.0, 10.0, -10.0, F])
    np.testing.assert_allclose(t.to_normalized(f), [1, -1, 0.5, -0.5, 0, 10 / F, -10 / R, 1], rtol=1e-15)
    np.testing.assert_allclose(t.from_normalized(t.to_normalized(f)), f, rtol=1e-15)
    with pytest.raises(ValueError, match=r"realism: normalised thruster commands must be in \[-1, 1\]"):
        t.from_normalized([1.5])


# --- rotor dynamics and dead zone ----------------------------------------------------------------------------------


@pytest.mark.parametrize("time_constant", [0.05, 0.1, 0.2])
def test_rotor_step_response_reaches_63_percent_at_its_time_constant(time_constant):
    t = thrusters(rotor_time_constant=time_constant)
    cmd = np.array([0.8 * F, -0.8 * R, 0.5 * F, 0, 0.3 * F, -0.3 * R, F, -R])
    n = round(3 * time_constant / DT)
    history = []
    for _ in range(n):
        t.step(cmd)
        history.append(t.thrust)
    history = np.array(history)
    times = DT * np.arange(1, n + 1)
    active = cmd != 0
    ratio = history[:, active] / cmd[active]
    np.testing.assert_allclose(ratio, np.repeat((1 - np.exp(-times / time_constant))[:, None], active.sum(), axis=1))
    first = times[np.argmax((ratio >= 1 - math.exp(-1) - 1e-12).all(axis=1))]
    assert abs(first - time_constant) <= 0.05 * time_constant
    np.testing.assert_array_equal(history[:, ~active], 0.0)


def test_zero_time_constant_follows_at_once_and_step_returns_b_f():
    t = thrusters()
    cmd = np.array([0.8 * F, -0.8 * R, 0.5 * F, 0.1 * F, 0.3 * F, -0.3 * R, F, -R])
    wrench = t.step(cmd)
    np.testing.assert_array_equal(t.thrust, cmd)
    np.testing.assert_allclose(wrench, allocation_matrix(DEFAULT_LAYOUT) @ cmd, rtol=0, atol=1e-12)
    t.reset()
    np.testing.assert_array_equal(t.thrust, 0.0)


def test_step_clamps_commands_beyond_the_limits():
    t = thrusters()
    t.step(np.array([2 * F, -2 * R, 0, 0, 0, 0, 0, 0]))
    np.testing.assert_array_equal(t.thrust[:2], [F, -R])


def test_dead_zone_just_inside_is_zero_just_outside_is_the_command():
    dz = 0.1
    t = thrusters(dead_zone=dz)
    eps = 1e-9
    inside = np.array([dz * F * (1 - eps), -dz * R * (1 - eps)] * 4)
    t.step(inside)
    np.testing.assert_array_equal(t.thrust, 0.0)
    outside = np.array([dz * F * (1 + eps), -dz * R * (1 + eps)] * 4)
    t.step(outside)
    np.testing.assert_array_equal(t.thrust, outside)  # not re-scaled


def test_step_rejects_bad_commands():
    t = thrusters()
    with pytest.raises(ValueError, match=r"realism: thrust_cmd must have shape \(8,\)"):
        t.step(np.zeros(6))
    with pytest.raises(ValueError, match="realism: thrust_cmd must be finite"):
        t.step([math.nan] + [0.0] * 7)
    np.testing.assert_array_equal(t.thrust, 0.0)


# --- the tasks' wrenches -------------------------------------------------------------------------------------------


def test_default_layout_produces_the_scored_task_wrenches_with_margin():
    t = thrusters()
    b = allocation_matrix(DEFAULT_LAYOUT)
    assert thrust_fraction(DEFAULT_LAYOUT, SCORED_WRENCHES).max() <= SCORED_MAX_FRACTION
    for w in SCORED_WRENCHES:
        f, scale = t.allocate(w)
        assert scale == 1.0
        np.testing.assert_allclose(b @ f, w, rtol=0, atol=1e-9)


def test_the_circle_approach_saturates_little_and_keeps_direction():
    t = thrusters()
    b = allocation_matrix(DEFAULT_LAYOUT)
    for w in APPROACH_WRENCHES:
        f, scale = t.allocate(w)
        assert APPROACH_MIN_SCALE <= scale <= 1.0
        np.testing.assert_allclose(b @ f, scale * w, rtol=0, atol=1e-9)


# --- joint speed limit ---------------------------------------------------------------------------------------------


def test_limit_joint_speed_cuts_only_torque_toward_faster_motion():
    limit = 1.0
    qdot = np.array([0.5, 1.0, 1.2, 1.2, -1.0, -1.5, -1.5, 0.0, 2.0])
    tau = np.array([10.0, 10.0, 10.0, -10.0, -10.0, -10.0, 10.0, 10.0, 0.0])
    out = limit_joint_speed(tau, qdot, limit)
    # below the limit: kept; at/above in the direction of motion: cut; opposing the motion: kept; zero stays zero
    np.testing.assert_array_equal(out, [10.0, 0.0, 0.0, -10.0, 0.0, 0.0, 10.0, 10.0, 0.0])
    np.testing.assert_array_equal(tau[0], 10.0)  # the input is not modified


def test_limit_joint_speed_per_joint_limits_and_errors():
    out = limit_joint_speed([5.0, 5.0], [0.9, 0.9], np.array([1.0, 0.5]))
    np.testing.assert_array_equal(out, [5.0, 0.0])
    with pytest.raises(ValueError, match="realism: joint_speed_limit must be finite and > 0"):
        limit_joint_speed([1.0], [1.0], 0.0)
    with pytest.raises(ValueError, match="realism: limit_joint_speed needs tau_q and qdot"):
        limit_joint_speed([1.0, 2.0], [1.0], 1.0)


# --- the environment's per-substep path ----------------------------------------------------------------------------


@pytest.mark.parametrize("limit", [np.ones(1), np.linspace(0.5, 1.5, 12), np.zeros(0)])
def test_actuate_is_allocate_step_and_limit_bit_for_bit(limit):
    """One compiled call equals the three documented steps, thrusts, commanded sums and saturation included."""
    fused = thrusters(rotor_time_constant=0.05, dead_zone=0.125)
    plain = thrusters(rotor_time_constant=0.05, dead_zone=0.125)
    rng = np.random.default_rng(4)
    total_fused, total_plain = np.zeros(18), np.zeros(18)
    saturated = 0
    for _ in range(300):
        tau = rng.normal(size=18) * np.r_[[600.0] * 3, [200.0] * 3, [20.0] * 12]  # saturates now and then
        qdot = rng.normal(size=12)
        out = np.empty(18)
        scale = actuate(fused, tau, qdot, limit, total_fused, out)
        cmd, scale_plain = plain.allocate(tau[:6])
        total_plain[:6] += scale_plain * tau[:6]
        wrench = plain.step(cmd)
        joints = tau[6:] if limit.size == 0 else limit_joint_speed(tau[6:], qdot, limit if limit.size > 1 else 1.0)
        total_plain[6:] += joints
        assert scale == scale_plain
        np.testing.assert_array_equal(out, np.r_[wrench, joints])
        np.testing.assert_array_equal(fused.thrust, plain.thrust)
        saturated += scale < 1.0
    np.testing.assert_array_equal(total_fused, total_plain)
    assert 0 < saturated < 300


def test_actuate_rejects_bad_input():
    t = thrusters()
    tau = np.zeros(18)
    tau[2] = math.nan
    with pytest.raises(ValueError, match="realism: wrench must be finite"):
        actuate(t, tau, np.zeros(12), np.ones(1), np.zeros(18), np.empty(18))
    with pytest.raises(ValueError, match="realism: joint_speed_limit must be finite and > 0"):
        actuate(t, np.zeros(18), np.zeros(12), np.array([-1.0]), np.zeros(18), np.empty(18))
