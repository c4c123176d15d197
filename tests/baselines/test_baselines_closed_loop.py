"""The reference controllers in closed loop on the simulator: the paper's collision cases, transport, ablation.

These are the acceptance criteria of ``docs/REPRODUCTION.md`` (the same checks as ``uvdms reproduce --check``),
run directly on the environments. About 20 s in total.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import uvdms_gym  # noqa: F401
from baselines.controllers import BASELINES, Controller, make_baseline
from baselines.paper.reproduce import ROW_RIGHT_LINK3_FRAME, ROW_RIGHT_LINK5_LEFT_ARM, transport_numbers
from uvdms_gym.evaluation import run_episode
from uvdms_gym.physics.params import D1

CIRCLE, TRANSPORT = "uvdms/CircleTrack-v0", "uvdms/Transport-v0"


def episode(spec: str, env_id: str, seed: int = 0, save: bool = False, **env_kwargs) -> dict:
    env = gym.make(env_id, action_mode=BASELINES[spec]["action_mode"], terminate_on_contact=False, **env_kwargs)
    try:
        return run_episode(env, make_baseline(spec, env), seed, save_trajectory=save)
    finally:
        env.close()


@pytest.fixture(scope="module")
def circle_runs() -> dict:
    return {(case, spec): episode(spec, CIRCLE, case=case) for case in (1, 2) for spec in ("mpc", "campc")}


@pytest.fixture(scope="module")
def transport_run() -> dict:
    return episode("campc-nndi", TRANSPORT, save=True)


@pytest.mark.slow
@pytest.mark.parametrize("case, row", [(1, ROW_RIGHT_LINK3_FRAME), (2, ROW_RIGHT_LINK5_LEFT_ARM)])
def test_plain_mpc_reproduces_the_papers_collision(circle_runs, case, row):
    """Case 1: right link 3 into the right frame; Case 2: right link 5 into the left arm (paper Fig. 6, 9)."""
    mpc = circle_runs[case, "mpc"]
    assert mpc["min_distance_by_pair"][row] < D1
    assert mpc["zone_steps"] > 0
    assert mpc["rmse_pos"] < 0.01  # it tracks well: the collision is the price


@pytest.mark.slow
@pytest.mark.parametrize("case", [1, 2])
def test_campc_avoids_it_and_tracks(circle_runs, case):
    mpc, campc = circle_runs[case, "mpc"], circle_runs[case, "campc"]
    assert campc["min_distance"] >= D1 - 2e-3
    assert campc["contacts"] == 0 and campc["zone_steps"] == 0
    assert campc["rmse_pos"] <= 0.03 and campc["rmse_pos"] <= 2.0 * mpc["rmse_pos"]
    assert campc["success"] and campc["truncated"] and not campc["terminated"]


@pytest.mark.slow
def test_qp_never_fails_and_slack_is_reported(circle_runs, transport_run):
    for ep in [*circle_runs.values(), transport_run]:
        assert ep["qp_unsolved"] == 0
        assert ep["qp_slack_max"] is not None and 0.0 <= ep["qp_slack_max"] < 1e-4
        assert ep["physics_error"] is None


@pytest.mark.slow
def test_transport_with_the_full_stack(transport_run):
    tn = transport_numbers(transport_run)
    assert tn["final_pos_error_m"] <= 0.02
    assert tn["final_yaw_error_deg"] <= 2.0
    assert tn["max_roll_pitch_deg"] <= 3.0
    assert tn["contacts"] == 0
    assert tn["max_joint_difference_deg"] <= 1.0
    assert transport_run["success"]
    nn = np.array(transport_run["trajectory"]["nn_output"][1:], dtype=float)
    assert nn.shape == (600, 18) and np.abs(nn).max() > 0.0  # the network does compensate


@pytest.mark.slow
def test_ablation_network_beats_plain_inversion_under_randomised_hydrodynamics():
    """Case 1, hydro_randomization = 0.3, seeds 0-4: campc-nndi tracks better on average than campc-di."""
    rmse = {
        spec: [episode(spec, CIRCLE, seed=s, case=1, hydro_randomization=0.3)["rmse_pos"] for s in range(5)]
        for spec in ("campc-di", "campc-nndi")
    }
    assert np.mean(rmse["campc-nndi"]) < np.mean(rmse["campc-di"])


# ---------------------------------------------------------------------------------------------------- interface
@pytest.mark.parametrize("spec", sorted(name for name, spec in BASELINES.items() if not spec.get("hold")))
def test_baselines_follow_the_controller_interface(spec):  # the MPC baselines; hold: tests/baselines/test_hold.py
    mode = BASELINES[spec]["action_mode"]
    friction = BASELINES[spec].get("grasp") == "friction"  # campc-coop: the cooperative transport only
    env = gym.make("uvdms/CooperativeTransport-v1" if friction else CIRCLE, action_mode=mode)
    try:
        ctl = make_baseline(spec, env)
        assert isinstance(ctl, Controller)
        obs, info = env.reset(seed=3)
        ctl.reset(3)
        for _ in range(3):
            a = ctl.predict(obs, info)
            assert a.shape == env.action_space.shape and np.all(np.abs(a) <= 1.0)
            rec = ctl.last_record
            assert rec["status"] == "solved" and rec["iterations"] > 0 and rec["wall_us"] > 0
            assert "max_slack" in rec and isinstance(rec["clipped"], bool)
            obs, _, _, _, info = env.step(a)
    finally:
        env.close()


@pytest.mark.parametrize("spec", sorted(BASELINES))
def test_action_mode_mismatch_names_the_required_mode(spec):
    required = BASELINES[spec]["action_mode"]
    wrong = "torque" if required == "velocity" else "velocity"
    env = gym.make(TRANSPORT, action_mode=wrong)
    try:
        with pytest.raises(ValueError, match=f"action_mode='{required}'"):
            make_baseline(spec, env)
    finally:
        env.close()


def test_unknown_controller_is_rejected():
    env = gym.make(CIRCLE)
    try:
        with pytest.raises(ValueError, match=r"unknown baseline .no-such-controller.; choose one of"):
            make_baseline("no-such-controller", env)
    finally:
        env.close()


@pytest.mark.slow
@pytest.mark.parametrize("env_id, kwargs", [(CIRCLE, {"case": 2}), (TRANSPORT, {})])
def test_recorded_qps_match_an_independent_solver(env_id, kwargs):
    """QPs recorded in closed loop on the simulator, re-solved by OSQP (polished, tight tolerances).

    ProxSuite at a tight tolerance and OSQP agree in the metric of the QP's Hessian (``0.5 d' H d < 1e-6``) and
    on the applied command ``zeta_0`` to 5e-4; the controller's own solution (``eps_abs = 1e-6``, warm-started)
    is feasible and optimal to 1e-5 in objective. The cost is flat to ~1e-9 along the cheap joints'
    directions, so single components are only determined to a few 1e-4 (on an AMD EPYC machine the
    worst recorded QP differed by 3.9e-4 in one joint rate with ``0.5 d' H d = 6e-8``; on an Intel one
    every QP agreed to 1e-4).
    """
    from dataclasses import replace

    from baselines.bench import OSQPReplay
    from baselines.mpc.config import N_DOF
    from baselines.mpc.kinematic import KinematicMPC

    env = gym.make(env_id, action_mode="velocity", **kwargs)
    try:
        ctl = make_baseline("campc", env)
        obs, info = env.reset(seed=0)
        ctl.reset(0)
        recorded = []
        for k in range(140):
            action = ctl.predict(obs, info)
            problem = ctl.mpc.last_problem
            active = np.any(problem.d < 0.12)  # a collision row inside the anti-collision zone
            if k % 10 == 5 or (active and len(recorded) < 12):
                recorded.append((problem, ctl.mpc.mpc.qp.results.x.copy()))
            obs, _, _, _, info = env.step(action)
    finally:
        env.close()
    assert len(recorded) >= 14
    mpc = ctl.mpc.mpc
    tight = KinematicMPC(replace(mpc.config, eps_abs=1e-9), mpc.params, mpc.m)
    # After another campc run in the same process the recorded QPs differ slightly (measured: actions differ by
    # ~1e-9 from step 1, 5e-3 by step 140; the cause is not identified, each fresh process is deterministic), and
    # at 1e-10 OSQP then ends one of them "solved inaccurate"; the comparisons below check its accuracy either way.
    ref = OSQPReplay(mpc, eps_abs=1e-10, eps_rel=1e-10, polishing=True, max_iter=200000)
    statuses = []
    for problem, x_ctl in recorded:
        mats = mpc.qp_matrices(problem)
        xo, status, _, _ = ref.solve(mats)
        statuses.append(status)
        assert status in ("solved", "solved inaccurate")
        tight.reset()
        assert tight.solve(problem).status == "solved"
        diff = tight.qp.results.x - xo
        assert 0.5 * diff @ mats.H @ diff < 1e-6
        assert np.max(np.abs(diff[:N_DOF])) < 5e-4
        assert np.max(np.abs(x_ctl[:N_DOF] - xo[:N_DOF])) < 1e-3

        def objective(x, m=mats):
            return 0.5 * x @ m.H @ x + m.g @ x

        x_ctl = x_ctl.copy()
        x_ctl[mpc.n_u :] = np.maximum(x_ctl[mpc.n_u :], 0.0)  # slacks within the solver's 1e-9 of s >= 0
        c, lo, up = mats.full_inequalities()
        assert np.all(c @ x_ctl >= lo - 1e-5) and np.all(c @ x_ctl <= up + 1e-5)
        assert np.allclose(mats.A @ x_ctl, mats.b, atol=1e-5)
        assert objective(x_ctl) - objective(xo) < 1e-5 * (1.0 + abs(objective(xo)))
    assert statuses.count("solved") >= len(statuses) - 2
