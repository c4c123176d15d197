"""``ActionComposition``'s ``navigation_filter``, ``frame_stack``, ``action_history``: recorded, defaulted, checked."""

from __future__ import annotations

import pytest

from uvdms_gym.residual import MAX_FRAME_STACK, RECORD_KEYS, ActionComposition, check_frame_stack


@pytest.mark.parametrize(
    "composition",
    [
        ActionComposition(navigation_filter=True, frame_stack=4),
        ActionComposition(frame_stack=4, action_history=4),
        ActionComposition(frame_stack=MAX_FRAME_STACK),
        ActionComposition("mpc", 0.2, True, "clearance", "nullspace", navigation_filter=True, frame_stack=2),
    ],
)
def test_the_new_keys_round_trip_through_the_record(composition):
    record = composition.to_record()
    assert set(record) == set(RECORD_KEYS)
    assert record["navigation_filter"] is composition.navigation_filter
    assert record["frame_stack"] == composition.frame_stack
    assert record["action_history"] == composition.action_history
    assert ActionComposition.from_record(record) == composition


def test_a_record_written_before_the_keys_existed_is_a_plain_memoryless_agent():
    old = {"residual_base": None, "residual_scale": None, "safety_filter": False}
    composition = ActionComposition.from_record(old)
    assert (composition.navigation_filter, composition.frame_stack, composition.action_history) == (False, 1, 0)
    assert composition.is_plain
    nulls = ActionComposition.from_record({"navigation_filter": None, "frame_stack": None})
    assert (nulls.navigation_filter, nulls.frame_stack) == (False, 1)


@pytest.mark.parametrize(
    ("record", "message"),
    [
        ({"frame_stack": 0}, r"frame_stack must be an integer in \[1, 64\], got 0"),
        ({"frame_stack": 65}, "frame_stack must be an integer in .*got 65"),
        ({"frame_stack": True}, "frame_stack must be an integer in .*got True"),
        ({"frame_stack": 2.0}, "frame_stack must be an integer in .*got 2.0"),
        ({"frame_stack": "4"}, "frame_stack must be an integer in .*got '4'"),
        ({"action_history": -1}, r"action_history must be an integer in \[1, 64\], got -1"),
        ({"action_history": 1.5}, "action_history must be an integer in .*got 1.5"),
        ({"navigation_filter": 1}, "navigation_filter must be true or false, got 1"),
        ({"navigation_filter": "yes"}, "navigation_filter must be true or false, got 'yes'"),
    ],
)
def test_bad_values_are_one_line_errors_naming_the_key(record, message):
    with pytest.raises(ValueError, match=message) as info:
        ActionComposition.from_record(record)
    assert "\n" not in str(info.value)


def test_check_frame_stack_returns_a_valid_value():
    assert [check_frame_stack(k) for k in (1, 2, MAX_FRAME_STACK)] == [1, 2, MAX_FRAME_STACK]
