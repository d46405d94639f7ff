"""Straight lines and jog over Modbus: the recorded path of a linear move stays on the line
(the PLC's Cartesian setpoint, and the numpy reference FK of its joint setpoints), the jog
stops at the workspace boundary without a jump, the dead-man stops a jog whose client went
silent, and only the jog's own client may steer it."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import pytest
from motion_checks import assert_slew_limited

from armbench.controller_client import (
    ERR_JOG_TIMEOUT,
    ERR_NOT_MOTION_OWNER,
    JOG_DEADMAN_SCANS,
    ArmControllerClient,
    MotionRecorder,
)
from armbench.plant import arm
from armbench.softplc.modbus_client import PlcClient

A = (150.0, -40.0, 110.0)
B = (150.0, 40.0, 130.0)


def line_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    d = b - a
    t = float(np.clip(np.dot(p - a, d) / np.dot(d, d), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * d)))


@pytest.mark.parametrize("method,fineness,bound_mm", [
    (2, 1.0, 0.01),   # ours: the path parameter is time-scaled, the point is on the line
    (1, 2.0, 0.5 * math.sqrt(3) / 2.0 + 0.01),  # Bresenham: within half a grid step per axis
    (0, 1.0, 0.5 * math.sqrt(3) / 1.0 + 0.01),
])
def test_linear_move_stays_on_the_line(plc: ArmControllerClient,
                                       motion_recorder: Callable[[], MotionRecorder],
                                       method: int, fineness: float, bound_mm: float) -> None:
    assert plc.move_xyz(*A, wait=True).error_id == 0
    rec = motion_recorder()
    rec.start()
    st = plc.move_linear(B, velocity=60.0, acceleration=300.0, fineness=fineness,
                         method=method)
    assert st.error_id == 0
    outcome, run = rec.record_until_idle(plc)
    assert outcome.state == "done", outcome
    a, b = np.array(A), np.array(B)
    cart = [s for s in run.samples if s.cart_valid]
    assert len(cart) > 20
    worst_cart = max(line_distance(np.array(s.cart_mm), a, b) for s in cart)
    worst_fk = max(line_distance(arm.forward(*s.set_deg), a, b) for s in run.samples
                   if s.ticket == plc.last_ticket)
    assert worst_cart <= bound_mm
    assert worst_fk <= bound_mm + 0.05  # float32 IK on the PLC vs the float64 reference FK
    # where the servos were sent once the motion is done: read now, since the recorder's last
    # sample can be several scans old when the host starves its thread
    final = plc.motion()
    assert final.done and final.ticket == plc.last_ticket, final
    end = arm.forward(*final.out_deg)
    assert np.linalg.norm(end - b) <= 0.05
    assert_slew_limited(run)


def _jog_until_rest(plc: ArmControllerClient, stick: tuple[float, float, float],
                    seconds: float) -> None:
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        plc.jog_update(stick)
        time.sleep(0.05)


def test_jog_stops_at_the_workspace_boundary(plc: ArmControllerClient,
                                             motion_recorder: Callable[[], MotionRecorder]
                                             ) -> None:
    assert plc.move_xyz(180.0, 0.0, 120.0, wait=True).error_id == 0
    rec = motion_recorder()
    rec.start()
    assert plc.jog_start((1.0, 0.0, 0.0), 60.0, 300.0).error_id == 0
    _jog_until_rest(plc, (1.0, 0.0, 0.0), 4.0)  # far enough to meet the boundary
    held = plc.motion()
    assert held.busy and held.at_limit, held
    assert plc.jog_stop().error_id == 0
    outcome, run = rec.record_until_idle(plc)
    assert outcome.state == "done"
    assert all(math.isfinite(v) for s in run.samples for v in (*s.out_deg, *s.set_deg))
    reach = arm.forward(*run.samples[-1].out_deg)
    # the shoulder (x = A2, z = A1 of the default geometry) to the tool: within the links
    shoulder_dist = math.hypot(math.hypot(reach[0], reach[1]) - 20.0, reach[2] - 100.0)
    assert shoulder_dist <= 120.0 + 130.0
    assert reach[0] > 180.0  # it did move outwards
    assert_slew_limited(run)


def test_dead_man_stops_a_silent_jog(plc: ArmControllerClient,
                                     motion_recorder: Callable[[], MotionRecorder]) -> None:
    assert plc.move_xyz(150.0, 0.0, 120.0, wait=True).error_id == 0
    rec = motion_recorder()
    rec.start()
    st = plc.jog_start((0.0, 1.0, 0.0), 40.0, 200.0)
    assert st.error_id == 0
    started = plc.motion().scan
    outcome, run = rec.record_until_idle(plc, timeout_s=10.0)  # the client says nothing more
    assert outcome.state == "error" and outcome.error_id == ERR_JOG_TIMEOUT
    moving = [s for s in run.samples if s.scan >= started and any(abs(v) > 1e-6
                                                                  for v in s.out_vel)]
    assert moving and moving[-1].scan - started >= JOG_DEADMAN_SCANS
    assert run.samples[-1].out_vel == (0.0, 0.0, 0.0)
    assert_slew_limited(run)


def test_only_the_jogging_client_steers_the_jog(plc: ArmControllerClient,
                                                plc_address: tuple[str, int]) -> None:
    assert plc.move_xyz(150.0, 0.0, 120.0, wait=True).error_id == 0
    assert plc.jog_start((0.0, 0.0, 0.3), 30.0, 200.0).error_id == 0
    with PlcClient(*plc_address) as modbus, ArmControllerClient(modbus, flavor=plc.flavor) as other:
        assert other.jog_update((1.0, 0.0, 0.0)).error_id == ERR_NOT_MOTION_OWNER
        assert other.jog_stop().error_id == ERR_NOT_MOTION_OWNER
    assert plc.jog_stop().error_id == 0
    assert plc.wait_motion().state == "done"
