"""The v1 environments: v0's dynamics and costs with the bounded reward of ``uvdms_gym.envs.bounded_reward``."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from uvdms_gym.distances import velocity_damper
from uvdms_gym.envs.bounded_reward import V1_WEIGHTS
from uvdms_gym.physics.params import D1, D2

PAIRS = (("uvdms/CircleTrack-v0", "uvdms/CircleTrack-v1"), ("uvdms/Transport-v0", "uvdms/Transport-v1"))
TERMS = ("track", "orientation", "effort", "proximity", "contact")


def expected_reward_terms(info: dict, action: np.ndarray, orientation: bool) -> dict[str, float]:
    """The v1 terms computed from the step's info with the formulas of the module docstring."""
    w = {k.removesuffix("_weight"): v for k, v in V1_WEIGHTS.items()}
    a = np.clip(np.asarray(action, dtype=float), -1.0, 1.0)
    clearance = velocity_damper(np.asarray(info["distances"]), D1, D2)
    ori = math.exp(-info["orientation_error"] / math.radians(5.0)) if orientation else 0.0
    return {
        "track": w["track"] * math.exp(-info["tracking_error"] / 0.05),
        "orientation": w["orientation"] * ori,
        "effort": w["effort"] * (1.0 - float(a @ a) / 18.0),
        "proximity": w["proximity"] * float(np.mean(clearance)),
        "contact": -w["contact"] * (info["contacts"] > 0),
    }


@pytest.mark.parametrize(("v0", "v1"), PAIRS)
def test_v1_has_v0_dynamics_and_costs_and_a_reward_that_is_the_sum_of_its_bounded_terms(v0, v1):
    envs = [gym.make(env_id, terminate_on_contact=False) for env_id in (v0, v1)]
    rng = np.random.default_rng(3)
    try:
        (obs0, _), (obs1, _) = (env.reset(seed=7) for env in envs)
        np.testing.assert_array_equal(obs0, obs1)
        near_seen = False
        for _ in range(120):
            action = rng.uniform(-1.2, 1.2, 18).astype(np.float32)  # some entries clipped
            (obs0, _, term0, _, info0), (obs1, r1, term1, _, info1) = (env.step(action) for env in envs)
            np.testing.assert_array_equal(obs0, obs1)  # the same physics, task and observation
            assert (term0, info0["cost"], info0["contacts"]) == (term1, info1["cost"], info1["contacts"])
            terms = {k: info1[f"reward_{k}"] for k in TERMS}
            assert r1 == pytest.approx(sum(terms.values()), abs=1e-12)
            expected = expected_reward_terms(info1, action, orientation="Transport" in v1)
            for k in TERMS:
                assert terms[k] == pytest.approx(expected[k], rel=1e-9, abs=1e-12), k
            for k in ("track", "orientation", "effort", "proximity"):
                assert 0.0 <= terms[k] <= V1_WEIGHTS[f"{k}_weight"]
            near_seen |= info1["min_distance"] < D2
            if term0:
                break
        assert near_seen or "Transport" in v1  # the circle rollout exercised the proximity shape
    finally:
        for env in envs:
            env.close()


def test_the_optional_precision_term_is_a_narrow_exp_of_the_tracking_error_and_off_by_default():
    default = gym.make("uvdms/CircleTrack-v1", case=2)
    shaped = gym.make("uvdms/CircleTrack-v1", case=2, precision_weight=0.7, precision_scale=0.02)
    rng = np.random.default_rng(5)
    try:
        default.reset(seed=1)
        shaped.reset(seed=1)
        for _ in range(30):
            action = rng.uniform(-0.3, 0.3, 18).astype(np.float32)
            (_, r0, *_, info0), (_, r1, *_, info1) = default.step(action), shaped.step(action)
            assert info0["reward_precision"] == 0.0
            assert info1["tracking_error"] == info0["tracking_error"]  # a reward option, not a dynamics one
            expected = 0.7 * math.exp(-info1["tracking_error"] / 0.02)
            assert info1["reward_precision"] == pytest.approx(expected, rel=1e-12)
            assert r1 == pytest.approx(r0 + expected, abs=1e-12)
    finally:
        default.close()
        shaped.close()
    for bad in ({"precision_weight": -1.0}, {"precision_scale": 0.0}, {"precision_weight": float("nan")}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            gym.make("uvdms/CircleTrack-v1", **bad)


def _episode_return(env_id: str, action: np.ndarray, **kwargs) -> tuple[float, int, dict]:
    env = gym.make(env_id, case=1, **kwargs)
    try:
        env.reset(seed=0)
        total, steps = 0.0, 0
        while True:
            _, reward, terminated, truncated, info = env.step(action)
            total, steps = total + reward, steps + 1
            if terminated or truncated:
                return total, steps, info
    finally:
        env.close()


def test_driving_into_a_contact_scores_less_than_holding_still():
    crash = np.zeros(18, np.float32)
    crash[7] = 1.0  # the left arm's second joint at full rate: the arm hits the frame
    hold = np.zeros(18, np.float32)
    crash_return, crash_steps, crash_info = _episode_return("uvdms/CircleTrack-v1", crash)
    hold_return, hold_steps, hold_info = _episode_return("uvdms/CircleTrack-v1", hold)
    assert crash_info["contacts"] > 0 and crash_steps * 0.04 <= 2.0  # a contact within 2 s ended it
    assert hold_info["contacts"] == 0 and hold_steps == 500  # holding still runs to the time limit
    assert crash_return < hold_return
    # under v0 the same crash is the better policy: the loophole v1 closes
    v0_crash, _, _ = _episode_return("uvdms/CircleTrack-v0", crash)
    v0_hold, _, _ = _episode_return("uvdms/CircleTrack-v0", hold)
    assert v0_crash > v0_hold


def test_v1_scales_are_validated():
    with pytest.raises(ValueError, match="track_scale must be a finite positive number"):
        gym.make("uvdms/CircleTrack-v1", track_scale=0.0)
    with pytest.raises(ValueError, match="orientation_scale must be a finite positive number"):
        gym.make("uvdms/Transport-v1", orientation_scale=float("nan"))
