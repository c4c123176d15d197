"""``uvdms bench env``: its figures are the medians of interleaved blocks they claim to be (no timing asserted)."""

import numpy as np

from uvdms_cli.bench import BENCH_ENV_IDS, bench_env


def test_bench_env_reports_block_medians():
    out = bench_env(quick=True)
    n_blocks = out["blocks"]["n_blocks"]
    assert len(out["grasp"]["ratio_blocks"]) == n_blocks  # the friction grasp against the rigid grasp
    for env_id in BENCH_ENV_IDS:
        row = out[env_id]
        assert len(row["step_us_blocks"]) == len(row["ratio_blocks"]) == n_blocks
        assert row["step_us"] == np.median(row["step_us_blocks"]) > 0
        assert row["ratio_to_bare_physics"] == np.median(row["ratio_blocks"]) > 0
        assert np.isclose(row["steps_per_s"] * row["step_us"], 1e6)
        # each block's ratio divides by a bare step timed just before it, not by one global figure
        implied_bare = np.array(row["step_us_blocks"]) / (row["substeps"] * np.array(row["ratio_blocks"]))
        assert np.all(implied_bare > 0)
        assert np.isclose(np.median(implied_bare), out["bare_step_us"], rtol=1.0)


def test_bench_env_reports_the_obstacle_task_against_transport_v1():
    from uvdms_cli.bench import OBSTACLE_ENV_ID

    row = bench_env(quick=True)[OBSTACLE_ENV_ID]
    assert row["n_obstacles"] == 3
    assert row["ratio_to_transport_v1"] == np.median(row["ratio_blocks"]) > 0
    assert row["step_us"] > 0 and row["reference_step_us"] > 0 and row["reset_ms"] > 0
    import gymnasium as gym

    env = gym.make(OBSTACLE_ENV_ID)
    env.reset(seed=row["seed"])
    assert len(env.unwrapped.obstacles) == 3  # the seed it reports has the 3 obstacles it claims
    env.close()


def test_bench_env_reports_the_friction_grasp_against_the_rigid_grasp():
    from uvdms_cli.bench import GRASP_BENCH_ENV_ID, GRASP_BENCH_GRIP, _bench_grasp

    row = _bench_grasp(2, 20, 5)  # (what bench_env reports under "grasp"; fewer blocks here)
    assert row["env_id"] == GRASP_BENCH_ENV_ID and row["grip_command"] == GRASP_BENCH_GRIP
    assert len(row["ratio_blocks"]) == 2
    assert row["ratio_to_rigid"] == np.median(row["ratio_blocks"]) > 0
    assert row["step_us"] > 0 and row["rigid_step_us"] > 0
    assert isinstance(row["resets"], int) and row["resets"] >= 0
