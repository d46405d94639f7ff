"""``wait_motion`` on what a motion command returns: the Status of a MoveLinear (or any motion
command) names the motion it started, so waiting on it waits for that motion, on the soft
PLC running the controller (the plugin's ``plc`` fixture)."""

from __future__ import annotations

import math

import pytest

from armbench.controller_client import ArmControllerClient

START = (150.0, 0.0, 120.0)
TARGET = (170.0, 20.0, 130.0)


def test_waiting_on_a_move_linear_status_waits_for_that_motion(
        plc: ArmControllerClient) -> None:
    assert plc.move_xyz(*START, wait=True).error_id == 0
    st = plc.move_linear(TARGET, velocity=60.0, acceleration=300.0)
    assert st.error_id == 0
    outcome = plc.wait_motion(st)
    assert outcome.state == "done", outcome
    assert outcome.by is None
    # the line is 30 mm long: at 60 mm/s it takes at least half a second of scans
    assert outcome.sample.progress == 1.0
    assert math.dist(outcome.sample.cart_mm, TARGET) < 0.01


def test_waiting_on_the_status_of_a_joint_move_too(plc: ArmControllerClient) -> None:
    st = plc.move_joints(10.0, 70.0, 70.0)
    assert st.error_id == 0
    assert plc.wait_motion(st).state == "done"
    assert plc.motion().out_deg == pytest.approx((10.0, 70.0, 70.0), abs=1e-3)


def test_a_status_that_started_no_motion_is_refused(plc: ArmControllerClient) -> None:
    hello = plc.hello()
    with pytest.raises(ValueError, match="started no motion"):
        plc.wait_motion(hello)
    rejected = plc.move_linear((1000.0, 0.0, 0.0), velocity=60.0)  # out of reach
    assert rejected.error_id != 0
    with pytest.raises(ValueError, match=f"result code {rejected.error_id}"):
        plc.wait_motion(rejected)


def test_something_else_is_a_type_error(plc: ArmControllerClient) -> None:
    assert plc.move_joints(0.0, 70.0, 65.0).error_id == 0
    with pytest.raises(TypeError, match="MotionTicket or the Status"):
        plc.wait_motion(3)  # type: ignore[arg-type]
