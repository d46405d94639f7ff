"""Joint moves over Modbus (MoveJointsProfile, MoveXyz through the motion layer): targets
reached, speeds within the limits, the output stage's slew guarantee on the recorded path,
and the durations of the closed forms (constant speed d/v + v/a with ramps at the limit,
trapezoid d/v + v/a or 2 sqrt(d/a)). Runs against the soft PLC or a real one by address."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest
from motion_checks import DT, assert_slew_limited

from armbench.controller_client import (
    ERR_BAD_PARAMETER,
    ERR_JOINT_LIMIT,
    ArmControllerClient,
    MotionRecorder,
)

START = (0.0, 70.0, 65.0)
TARGET = (40.0, 100.0, 40.0)
LIMIT_VEL, LIMIT_ACC = 150.0, 1000.0  # the controller's defaults (ServoSlew.st)


def trapezoid_time(d: float, v: float, a: float) -> float:
    return d / v + v / a if d >= v * v / a else 2.0 * math.sqrt(d / a)


def arrival_scan(samples: list, j: int, target: float) -> int:  # type: ignore[type-arg]
    """First scan from which joint j's setpoint stays at its target."""
    first = samples[-1].scan
    for s in reversed(samples):
        if abs(s.set_deg[j] - target) > 1e-3:
            break
        first = s.scan
    return first


@pytest.mark.parametrize("profile", [0, 1, 2, 3])
def test_profile_reaches_target_within_limits(
        plc: ArmControllerClient, motion_recorder: Callable[[], MotionRecorder],
        profile: int) -> None:
    assert plc.move_joints(*START, wait=True).error_id == 0
    v, a = 80.0, 400.0
    rec = motion_recorder()
    rec.start()
    st = plc.move_joints_profile(TARGET, profile, v, a, jerk=4000.0)
    assert st.error_id == 0
    outcome, run = rec.record_until_idle(plc)
    assert outcome.state == "done", outcome
    final = run.samples[-1]
    for j in range(3):
        assert final.out_deg[j] == pytest.approx(TARGET[j], abs=1e-3)
        assert final.set_deg[j] == pytest.approx(TARGET[j], abs=1e-3)
    moving = [s for s in run.samples if s.ticket == plc.last_ticket]
    peak = [max(abs(s.set_vel[j]) for s in moving) for j in range(3)]
    assert max(peak) <= v * (1 + 1e-4)
    assert_slew_limited(run)
    start_scan = min(s.scan for s in moving if s.busy)
    dist = [abs(t - s0) for t, s0 in zip(TARGET, START, strict=True)]
    arrive = [(arrival_scan(run.samples, j, TARGET[j]) - start_scan) * DT for j in range(3)]
    if profile == 0:  # every joint at the speed v, ramps at the limit: own times
        for j in range(3):
            assert arrive[j] == pytest.approx(trapezoid_time(dist[j], v, LIMIT_ACC), abs=3 * DT)
    else:  # synchronised: all arrive together
        assert max(arrive) - min(arrive) <= 2 * DT
    if profile in (1, 2):
        ramp = LIMIT_ACC if profile == 1 else a
        assert max(arrive) == pytest.approx(trapezoid_time(max(dist), v, ramp), abs=3 * DT)


def test_move_xyz_is_a_smooth_joint_move(plc: ArmControllerClient,
                                         motion_recorder: Callable[[], MotionRecorder]) -> None:
    assert plc.move_joints(*START, wait=True).error_id == 0
    rec = motion_recorder()
    rec.start()
    st = plc.move_xyz(120.0, 60.0, 90.0)
    assert st.error_id == 0
    outcome, run = rec.record_until_idle(plc)
    assert outcome.state == "done"
    assert run.samples[-1].out_deg == pytest.approx(st.joints_deg, abs=1e-3)
    assert len([s for s in run.samples if s.busy]) > 10  # several scans, not a jump
    assert_slew_limited(run)


@pytest.mark.parametrize("args,code", [
    ((TARGET, 2, math.nan, 400.0), ERR_BAD_PARAMETER),
    ((TARGET, 2, -5.0, 400.0), ERR_BAD_PARAMETER),
    ((TARGET, 2, 80.0, 0.0), ERR_BAD_PARAMETER),
    ((TARGET, 7, 80.0, 400.0), 20),  # BadProfile (st/MotionProfiles.st)
    (((0.0, 70.0, 200.0), 2, 80.0, 400.0), ERR_JOINT_LIMIT),
])
def test_bad_joint_move_is_rejected_and_changes_nothing(
        plc: ArmControllerClient, args: tuple, code: int) -> None:  # type: ignore[type-arg]
    assert plc.move_joints(*START, wait=True).error_id == 0
    before = plc.motion()
    st = plc.move_joints_profile(*args)
    assert st.error_id == code
    after = plc.motion()
    assert after.ticket == before.ticket and after.out_deg == before.out_deg
