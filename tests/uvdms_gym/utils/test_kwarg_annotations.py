"""``gymnasium.make`` checks each keyword's value against its annotation: one error naming the key and the type."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import uvdms_gym  # noqa: F401  (registers the ids)


@pytest.mark.parametrize(
    ("env_id", "kwargs", "message"),
    [
        ("uvdms/CircleTrack-v1", {"left_center": "abc"}, "left_center='abc': expected a sequence of 3 floats or None"),
        ("uvdms/CircleTrack-v0", {"radius": [1, 2]}, "radius=[1, 2]: expected a float or None"),
        ("uvdms/Transport-v1", {"start_pose": "here"}, "start_pose='here': expected a sequence of floats or None"),
        ("uvdms/CircleTrack-v1", {"terminate_on_contact": "maybe"}, "terminate_on_contact='maybe': expected true or"),
    ],
)
def test_make_names_the_key_and_type_of_a_wrong_value(env_id, kwargs, message):
    with pytest.raises(ValueError, match=r"^[A-Za-z0-9]+Env: ") as exc:
        gym.make(env_id, **kwargs)
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_values_of_the_right_type_and_unknown_types_pass():
    from uvdms_gym.utils.kwargs import kwarg_value_problem

    env = gym.make("uvdms/CircleTrack-v1", left_center=np.array([2.4, -0.25, 3.08]), period=10, current=None)
    env.close()
    assert kwarg_value_problem({"any": "mapping"}, "UVDMSParams | None") is None  # a class: its constructor checks
    assert kwarg_value_problem("abc", "int | str") is None
    assert kwarg_value_problem([1.0, None], "tuple[float, float | None]") is None
    assert kwarg_value_problem(True, "float") == "expected a float"
    assert kwarg_value_problem([1, 2], "tuple[float, float, float]") == "expected a sequence of 3 floats"
