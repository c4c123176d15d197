"""The friction grasp (``grasp="friction"``) against its definition, each check against an independent computation.

The contact model (:class:`~uvdms_gym.physics.params.GripperParams`): each hand's jaws conform to the cylinder and
hold it against every relative motion but sliding along its axis and turning about it; those two are resisted by
friction only, within the ellipse ``(f / (mu F))^2 + (m / (mu r_t F))^2 <= 1`` of the axial force ``f`` and the
twisting moment ``m`` the hand transmits (``F``: its grip force, ``r_t``: its torsional radius). While the load of
the object fits within the two hands' ellipses nothing slips; beyond it the hands slide.

The physics checks use a held plant: the vehicle's base welded to the world and the twelve arm joints locked by
stiff velocity motors (the simulator's torque control applies ``tau = 0`` each step and leaves those motors in
place), so the hands are still and every load on the grasp comes from the object. Loads are computed here from
:class:`~uvdms_gym.physics.params.ObjectParams` (the object's net weight ``(rho_object - rho_water) V g``) or
applied by the test (an external force along and a torque about the axis), never read from the grasp.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pybullet as pb
import pytest

import uvdms_gym  # noqa: F401  (registers the ids)
from scripts.grasp_model_comparison import held_plant
from uvdms_gym.physics import frames
from uvdms_gym.physics.friction_grasp import FrictionGrasp
from uvdms_gym.physics.grasp import RigidGrasp
from uvdms_gym.physics.grip import FrictionGraspConfig, parse_grasp, slide_bounds, slide_direction, stick_bounds
from uvdms_gym.physics.params import GRAVITY, UVDMSParams
from uvdms_gym.physics.sim import UVDMSSim
from uvdms_gym.seeds import split_seeds
from uvdms_gym.utils.kwargs import check_make_kwargs, parse_kv

P = UVDMSParams()
COOP = "uvdms/CooperativeTransport-v1"
W_NET = (P.obj.density - P.water_density) * P.obj.volume * GRAVITY
"""The object's weight minus its buoyancy, N (4.62 N): its axial load when its axis is vertical."""
ROLLED = math.pi / 2  # vehicle (and object) roll that puts the object's axis (its y) vertical
SEEDS = split_seeds("validation", 4)


def _held_plant(roll: float, grasp: dict, current: list[float] | None = None) -> UVDMSSim:
    """The plant holding the object at ``roll`` with its base welded to the world and its arm joints locked."""
    return held_plant(roll, parse_grasp(grasp), current=current)


def _run(sim: UVDMSSim, steps: int) -> None:
    for _ in range(steps):
        sim.step(np.zeros(18))


def _grasp(sim: UVDMSSim) -> FrictionGrasp:
    g = sim.grasp
    assert isinstance(g, FrictionGrasp)
    return g


# ---------------------------------------------------------------------------------------------- static holds
def test_static_hold_in_still_water_does_not_slip_and_balances_the_net_weight():
    # capacity twice the axial load: 2 mu F = 2 W_net
    sim = _held_plant(ROLLED, {"grip_initial": 2.0 * W_NET / (2 * 0.5)})
    axis = sim.object_rotation()[:, 1]
    assert abs(abs(axis[2]) - 1.0) < 1e-9  # the axis is vertical: the whole net weight is axial
    _run(sim, 1000)  # 10 s
    g = _grasp(sim)
    assert np.abs(g.slip_distance()).max() < 1e-3
    # the hands carry the net weight: sum of hand forces + net weight (NED +z) = 0, and the frictions sum to it
    forces = g.forces()
    np.testing.assert_allclose(forces[:, :3].sum(axis=0) + np.array([0.0, 0.0, W_NET]), 0.0, atol=0.02 * W_NET)
    assert abs(abs(g.friction_efforts()[:, 0].sum()) - W_NET) < 0.02 * W_NET
    assert g.sliding == (False, False)
    sim.close()


def test_static_hold_in_a_cross_current_does_not_slip():
    # A 0.5 m/s current across the object's axis (NED x; the axis is vertical) along the arms' reach: the object's
    # axial drag (Morison, on the axial relative speed, 0 here) and its axial added-mass force (on the axial
    # relative velocity, 0) vanish, its cross-flow drag is taken by the jaws, and the arms' drag has no lever about
    # the axis: the axial load stays the net weight. (A current across the arms' reach, NED y here, is different:
    # the arms' drag twists the locked loop about the axis; see the report of docs/cooperative.md.)
    current = [0.5, 0.0, 0.0]
    sim = _held_plant(ROLLED, {"grip_initial": 2.0 * W_NET / (2 * 0.5)}, current=current)
    axis = sim.object_rotation()[:, 1]
    assert abs(float(np.dot(axis, current))) < 1e-9
    _run(sim, 1000)
    g = _grasp(sim)
    assert np.abs(g.slip_distance()).max() < 1e-3
    assert abs(abs(g.friction_efforts()[:, 0].sum()) - W_NET) < 0.02 * W_NET
    sim.close()


def test_object_between_still_hands_does_not_drift():
    sim = _held_plant(0.0, {})
    g = _grasp(sim)

    def rel() -> np.ndarray:  # the object's pose in the left grasp frame
        p_h, r_h = sim.link_pose("left_grasp")
        p_o, r_o = sim.object_pose()[0], sim.object_rotation()
        return np.r_[r_h.T @ (p_o - p_h), frames.rot_error(r_h.T @ r_o, np.eye(3))]

    start = rel()
    _run(sim, 1000)
    assert np.abs(rel() - start).max() < 1e-4
    assert np.abs(g.slip()).max() < 1e-4
    sim.close()


# ---------------------------------------------------------------------------------------------- slip onset
def _onset_grip(mu: tuple[float, float], f_star: float) -> float:
    """Lower the grip from 1.5 F* to 0.5 F* over 4 s on the rolled plant; the grip at which slip starts."""
    sim = _held_plant(ROLLED, {"mu": list(mu), "grip_initial": 1.5 * f_star})
    g = _grasp(sim)
    _run(sim, 50)
    assert np.abs(g.slip()).max() < 1e-6
    onset = math.nan
    for grip in np.linspace(1.5 * f_star, 0.5 * f_star, 401):
        g.set_grip(grip, grip)
        sim.step(np.zeros(18))
        if np.abs(g.slip()[:, 0]).max() > 1e-6:
            onset = float(grip)
            break
    sim.close()
    return onset


@pytest.mark.parametrize("mu", [(0.5, 0.5), (0.3, 0.6)])
def test_slip_starts_at_the_grip_the_load_predicts(mu):
    f_star = W_NET / (mu[0] + mu[1])  # both hands at their capacity mu_k F carry the net weight
    onset = _onset_grip(mu, f_star)
    assert abs(onset / f_star - 1.0) < 0.1, f"slip at {onset:.3f} N, predicted {f_star:.3f} N"


def _combined_onset(angle: float, grip: float) -> float:
    """Ramp ``s`` of a pull ``s cos(a) 2 mu F`` along and a twist ``s sin(a) 2 mu r_t F`` about the object's axis.

    On the rolled plant (the axis vertical: the arms' weight has no lever about it, so the locked loop puts no
    torsion on the grasp), with the net weight cancelled by an upward force ``W_net`` computed from the object's
    parameters: the hands' load is then the applied pull and twist alone. Returns the ``s`` at which slip starts
    (the ellipse of the two equal hands together predicts 1).
    """
    cfg = FrictionGraspConfig()
    sim = _held_plant(ROLLED, {"grip_initial": grip})
    g = _grasp(sim)
    f_tot, m_tot = 2 * cfg.capacity(0, grip)[0], 2 * cfg.capacity(0, grip)[1]
    c, obj = sim.client, sim.object_id
    lift = np.array([0.0, 0.0, W_NET])  # z-up world

    def load(s: float) -> None:  # external forces are cleared after every physics step: apply before each
        pos, orn = c.getBasePositionAndOrientation(obj)
        axis = np.array(c.getMatrixFromQuaternion(orn)).reshape(3, 3)[:, 1]  # the object's y, z-up world
        c.applyExternalForce(obj, -1, (s * math.cos(angle) * f_tot * axis + lift).tolist(), pos, pb.WORLD_FRAME)
        c.applyExternalTorque(obj, -1, (s * math.sin(angle) * m_tot * axis).tolist(), pb.WORLD_FRAME)

    for _ in range(20):
        load(0.0)
        sim.step(np.zeros(18), n_substeps=1)
    assert np.abs(g.friction_efforts()).max() < 1e-3 * f_tot  # unloaded: the lift cancels the net weight
    onset = math.nan
    for s in np.linspace(0.0, 1.4, 281):  # 2.8 s
        load(float(s))
        sim.step(np.zeros(18), n_substeps=1)
        sl = g.slip()
        if max(np.abs(sl[:, 0]).max(), cfg.torsion_radius[0] * np.abs(sl[:, 1]).max()) > 1e-6:
            onset = float(s)
            break
    sim.close()
    return onset


@pytest.mark.parametrize("angle_deg", [0.0, 45.0, 70.0])
def test_combined_pull_and_twist_slip_on_the_ellipse(angle_deg):
    # on the ellipse s = 1; a box limit (each capacity alone) would give s = 1 / max(|cos a|, |sin a|) (1.41 at 45)
    onset = _combined_onset(math.radians(angle_deg), grip=10.0)
    assert abs(onset - 1.0) < 0.1, f"slip at s = {onset:.3f}, predicted 1"


# ---------------------------------------------------------------------------------------------- the law
def test_stick_bounds_keep_the_capacities_inside_and_scale_onto_the_ellipse_outside():
    rng = np.random.default_rng(SEEDS[0])
    for _ in range(200):
        f_max, m_max = rng.uniform(0.1, 100.0), rng.uniform(0.01, 5.0)
        a = rng.uniform(-math.pi, math.pi)
        r_in, r_out = rng.uniform(0.0, 0.999), rng.uniform(1.001, 5.0)
        f, m = math.cos(a) * f_max, math.sin(a) * m_max
        assert stick_bounds(f_max, m_max, r_in * f, r_in * m) == (f_max, m_max)
        fb, mb = stick_bounds(f_max, m_max, r_out * f, r_out * m)
        assert math.isclose((fb / f_max) ** 2 + (mb / m_max) ** 2, 1.0, rel_tol=1e-12)
        # along the demand: the bounds are the demand scaled by 1 / rho
        assert math.isclose(fb, abs(f), rel_tol=1e-9, abs_tol=1e-12)
        assert math.isclose(mb, abs(m), rel_tol=1e-9, abs_tol=1e-12)
    assert stick_bounds(0.0, 0.0, 1.0, 1.0) == (0.0, 0.0)


def test_slide_bounds_lie_on_the_ellipse_and_maximise_dissipation():
    rng = np.random.default_rng(SEEDS[1])
    for _ in range(200):
        f_max, m_max = rng.uniform(0.1, 100.0), rng.uniform(0.01, 5.0)
        v, w = rng.normal(size=2) * rng.uniform(1e-5, 1.0)
        fb, mb = slide_bounds(f_max, m_max, v, w)
        assert math.isclose((fb / f_max) ** 2 + (mb / m_max) ** 2, 1.0, rel_tol=1e-12)
        # the friction (-sign(v) fb, -sign(w) mb) opposes the slip; it dissipates at least as much as any point of
        # the ellipse (maximum dissipation), checked against a fine sampling of the ellipse
        power = fb * abs(v) + mb * abs(w)
        t = np.linspace(0.0, 2.0 * math.pi, 4001)
        assert power >= float(np.max(f_max * np.cos(t) * v + m_max * np.sin(t) * w)) - 1e-9 * (1.0 + power)
    assert slide_bounds(3.0, 0.5, 0.0, 0.0) == (3.0, 0.5)
    assert slide_bounds(3.0, 0.5, 0.2, 0.0) == pytest.approx((3.0, 0.0), rel=1e-12)  # axial capacity, no torsion
    assert slide_bounds(3.0, 0.5, 0.0, -1.0) == pytest.approx((0.0, 0.5), rel=1e-12)


def test_slide_direction_keeps_the_fixed_point_of_maximum_dissipation_and_damps_the_alternation():
    rng = np.random.default_rng(SEEDS[2])
    for _ in range(200):
        f_max, m_max = rng.uniform(0.1, 100.0), rng.uniform(0.01, 5.0)
        v, w = rng.normal(size=2) * rng.uniform(1e-5, 1.0)
        fb, mb = slide_bounds(f_max, m_max, v, w)
        target = (fb / f_max, mb / m_max)  # the unit direction of maximum dissipation
        # its fixed point: a hand already at the direction of maximum dissipation keeps it
        assert slide_direction(target, f_max, m_max, v, w) == pytest.approx(target, rel=1e-12, abs=1e-12)
        # from any direction it moves towards it (strictly closer) and stays a unit vector (a point of the ellipse)
        prev = tuple(np.abs(rng.normal(size=2)) / 1.0)
        prev = (prev[0] / math.hypot(*prev), prev[1] / math.hypot(*prev))
        new = slide_direction(prev, f_max, m_max, v, w)
        assert math.isclose(math.hypot(*new), 1.0, rel_tol=1e-12)
        assert math.dist(new, target) <= math.dist(prev, target) + 1e-12
    # the alternation of the first model: axial friction only, then a purely twisting slip -> both, not twist only
    cf, cm = slide_direction((1.0, 0.0), 10.0, 0.5, 0.0, 1.0)
    assert cf == pytest.approx(math.sqrt(0.5)) and cm == pytest.approx(math.sqrt(0.5))
    assert slide_direction((0.6, 0.8), 10.0, 0.5, 0.0, 0.0) == (0.6, 0.8)  # no slip: unchanged


# ---------------------------------------------------------------------------------------------- the environment
def _rollout(seed: int, steps: int) -> list[bytes]:
    env = gym.make(COOP)
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    out = [obs.tobytes()]
    for _ in range(steps):
        a = rng.uniform(-0.3, 0.3, env.action_space.shape).astype(np.float32)
        a[-2:] = rng.uniform(-0.9, -0.7, 2)  # grips of 15-45 N: the object slips at times but is held
        obs, r, term, trunc, info = env.step(a)
        out.append(obs.tobytes() + np.float64(r).tobytes())
        for key in ("grip", "hand_forces", "slip", "slip_distance", "slip_max", "internal_force", "load_share"):
            out.append(np.asarray(info[key], dtype=float).tobytes())
        if term or trunc:
            obs, info = env.reset()
    env.close()
    return out


def test_same_seed_same_trajectory():
    seed = SEEDS[2]
    assert _rollout(seed, 40) == _rollout(seed, 40)


def test_bang_bang_actions_stay_finite():
    env = gym.make(COOP)
    rng = np.random.default_rng(SEEDS[3])
    obs, info = env.reset(seed=SEEDS[3])
    ends, errors = 0, []
    for k in range(200):
        a = rng.choice([-1.0, 1.0], size=env.action_space.shape).astype(np.float32)
        if k % 2:  # every other step the grips stay below the crush limit, so episodes last and slip
            a[-2:] = rng.choice([-1.0, 0.2], size=2)
        obs, r, term, trunc, info = env.step(a)
        assert np.all(np.isfinite(obs)) and math.isfinite(r)
        for key in ("hand_forces", "slip", "internal_force", "load_share"):
            assert np.all(np.isfinite(info[key])), key
        if info["physics_error"] is not None:
            errors.append(info["physics_error"])
        if term or trunc:
            ends += 1
            obs, info = env.reset()
    env.close()
    assert ends > 0  # bang-bang grips crush the object: the episode ends, and resets cleanly
    assert errors == [], errors


def test_info_keys_against_the_hand_forces():
    env = gym.make(COOP)
    u = env.unwrapped
    rng = np.random.default_rng(SEEDS[0])
    env.reset(seed=SEEDS[0])
    for _ in range(20):
        a = rng.uniform(-0.5, 0.5, env.action_space.shape).astype(np.float32)
        a[-2:] = -0.8
        info = env.step(a)[4]
        forces = np.asarray(info["hand_forces"])
        axis = u._sim.object_rotation()[:, 1]  # the object's axis in NED
        axial = forces[:, :3] @ axis
        assert info["internal_force"] == pytest.approx(0.5 * (axial[1] - axial[0]), rel=1e-9, abs=1e-9)
        assert float(np.sum(info["load_share"])) == pytest.approx(1.0, abs=1e-12)
        f_int = info["internal_force"]
        carried = np.linalg.norm([forces[0, :3] + f_int * axis, forces[1, :3] - f_int * axis], axis=1)
        assert info["load_share"][0] == pytest.approx(carried[0] / carried.sum(), rel=1e-9, abs=1e-12)
        assert 0.0 <= info["load_share"][0] <= 1.0
        # what the hands carry adds up to the net force, with its axial component shared equally
        carried_l, carried_r = forces[0, :3] + f_int * axis, forces[1, :3] - f_int * axis
        np.testing.assert_allclose(carried_l + carried_r, forces[0, :3] + forces[1, :3], atol=1e-9)
        assert carried_l @ axis == pytest.approx(carried_r @ axis, abs=1e-9)
        np.testing.assert_allclose(info["grip"], [0.1 * FrictionGraspConfig().grip_max] * 2, rtol=1e-6)  # a = -0.8
    env.close()


# ---------------------------------------------------------------------------------------------- bad values
BAD = [
    ({"mu": 0.0}, "mu"),
    ({"mu": -0.2}, "mu"),
    ({"mu": float("nan")}, "mu"),
    ({"mu": [0.3, 0.0]}, "mu"),
    ({"grip_initial": 400.0}, "grip_initial"),
    ({"grip_initial": 100.0, "grip_max": 50.0}, "grip_initial"),
    ({"velcro": 1}, "velcro"),
    ("velcro", "velcro"),
]


@pytest.mark.parametrize(("grasp", "knob"), BAD)
def test_bad_grasp_values_name_the_problem_through_make_and_env_kwargs(grasp, knob):
    with pytest.raises(ValueError, match=knob) as exc:
        gym.make(COOP, grasp=grasp)
    assert "\n" not in str(exc.value)
    if isinstance(grasp, dict) and any(isinstance(v, float) and math.isnan(v) for v in grasp.values()):
        return  # no NaN literal on the command line
    text = grasp if isinstance(grasp, str) else "{" + ", ".join(f"{k}: {v}" for k, v in grasp.items()) + "}"
    kwargs = parse_kv([f"grasp={text}"], "--env-kwargs")
    with pytest.raises(ValueError, match=knob) as exc:
        check_make_kwargs(COOP, kwargs, "--env-kwargs")
        gym.make(COOP, **kwargs)
    assert "\n" not in str(exc.value)


def test_rigid_grasp_keeps_the_rigid_weld():
    sim = UVDMSSim(P, grasp=parse_grasp("rigid"))
    assert type(sim.grasp) is RigidGrasp
    sim.close()
    env = gym.make(COOP, grasp="rigid")
    assert type(env.unwrapped._sim.grasp) is RigidGrasp
    assert env.action_space.shape == (18,)
    env.close()
