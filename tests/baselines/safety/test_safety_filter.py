"""The safety filter (baselines/safety/filter.py): a minimal-change projection onto the collision rows."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from scipy.optimize import minimize

import leaderboard as lb
from baselines.controllers import make_baseline
from baselines.safety.filter import SafetyFilter, SafetyFilterConfig
from uvdms_gym.evaluation import run_episode


class Fixed:
    """A controller that returns a given action."""

    def __init__(self, action: np.ndarray) -> None:
        self.action = np.asarray(action, dtype=np.float32)

    def reset(self, seed: int | None = None) -> None:
        pass

    def predict(self, obs: np.ndarray, info: dict) -> np.ndarray:
        return self.action


@pytest.fixture
def case1():
    env = gym.make("uvdms/CircleTrack-v0", case=1)
    yield env
    env.close()


def _near_state(env) -> tuple[np.ndarray, dict, np.ndarray]:
    """A Case 1 state where plain MPC drives an arm toward the frame, and MPC's action there."""
    mpc = make_baseline("mpc", env)
    obs, info = env.reset(seed=0)
    mpc.reset(0)
    rows_filter = SafetyFilter(Fixed(np.zeros(18)), env)
    for _ in range(120):
        action = mpc.predict(obs, info)
        rows, bound = rows_filter.bound(info)
        if np.any(rows @ action > bound + 1e-3):
            return obs, info, action
        obs, *_, info = env.step(action)
    raise AssertionError("plain MPC never pushed a collision row in 120 steps")


def test_far_from_every_obstacle_the_action_is_unchanged(case1):
    obs, info = case1.reset(seed=0)  # arms folded, at rest: every distance beyond d2
    assert info["min_distance"] > 0.12
    action = np.linspace(-0.2, 0.2, 18).astype(np.float32)
    filt = SafetyFilter(Fixed(action), case1)
    filt.reset(0)
    np.testing.assert_array_equal(filt.predict(obs, info), action)
    assert filt.last_record["filter_active"] is False and filt.last_record["filter_change"] == 0.0


def test_the_filtered_command_is_the_projection_onto_the_rows(case1):
    obs, info, action = _near_state(case1)
    filt = SafetyFilter(Fixed(action), case1)
    filt.reset(0)
    u = filt.predict(obs, info).astype(float)
    rows, bound = filt.bound(info)
    assert filt.last_record["filter_active"] and filt.last_record["filter_slack"] < 1e-9
    assert np.all(rows @ u <= bound + 1e-6) and np.all(np.abs(u) <= 1.0)
    # an independent solver of min |u - a|^2 / 2 s.t. rows u <= bound, -1 <= u <= 1
    ref = minimize(
        lambda x: 0.5 * np.sum((x - action) ** 2),
        np.clip(action, -1, 1),
        jac=lambda x: x - action,
        bounds=[(-1.0, 1.0)] * 18,
        constraints=[{"type": "ineq", "fun": lambda x: bound - rows @ x, "jac": lambda x: -rows}],
        method="SLSQP",
        options={"ftol": 1e-14, "maxiter": 500},
    )
    assert ref.success
    np.testing.assert_allclose(u, ref.x, atol=1e-5)


def test_filtered_plain_mpc_avoids_the_case1_collision(case1):
    plain = run_episode(case1, make_baseline("mpc", case1), 0)
    filtered = run_episode(case1, SafetyFilter(make_baseline("mpc", case1), case1), 0)
    assert plain["contacts"] > 0  # the paper's Case 1 collision
    assert filtered["contacts"] == 0 and filtered["steps"] == 500
    # assuming the command is followed within the step (no lag margin) the arm still reaches the frame
    naive = SafetyFilter(make_baseline("mpc", case1), case1, SafetyFilterConfig(tracking_fraction=1.0))
    assert run_episode(case1, naive, 0)["contacts"] > 0


def test_filter_entries_are_entries_of_their_own():
    entries = lb.resolve_entries(["mpc", "mpc+filter", "baselines+filter"])
    names = [e.name for e in entries]
    assert names == ["mpc", "mpc+filter", "campc+filter"]  # the torque baselines of the keyword are not filtered
    plain, filtered = entries[0], entries[1]
    assert filtered.safety_filter and not plain.safety_filter
    assert plain.identity() == {"name": "mpc", "kind": "baseline", "checksum": None}  # unchanged cache keys
    assert filtered.identity()["safety_filter"] is True
    with pytest.raises(ValueError, match="projects velocity commands"):
        lb.resolve_entries(["campc-di+filter"])
    with pytest.raises(ValueError, match="tracking_fraction must be in"):
        SafetyFilterConfig(tracking_fraction=0.0)
