"""FollowImu (Controller.st IMU COMMANDS 46): the simulated hand drives the 5-axis arm.

The plant (armbench.follow_demo.HandRig, hooked before every scan of the fast_controller)
writes one IMU sample per scan, as the PSM does on a Pi, and records the slew limiter's five
joint outputs. References are independent of the ST code: the hand's ground truth is the
trajectory's own quaternion (armbench.plant.imu), the arm's tool direction and tip are the
closed-form FK of the recorded joint outputs in numpy (follow_demo.arm_frames).

Bounds (docs/orientation.md section 11, measured with the default dead band 2 deg and rate
90 deg/s, Madgwick MARG): after 2 s the angle between the hand's and the arm's tool direction
stays under 3.5 deg at the 95th percentile and 5 deg at most (measured 2.0 / 2.8: dead band
2 deg + filter error + one scan of latency); the tip drifts at most 5 mm in tip-fixed mode
(measured 3.2 mm: the dead band's stop-and-go at the rate limit, smoothed joint by joint by
the slew limiter), the flange at most 0.01 mm in flange-fixed mode (only the wrist moves).
The same bounds hold with the IMU at 50 Hz (a sample every second scan; measured 1.9 / 3.2
deg, 3.7 mm).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np
import pytest
from fast_plc import FastPlc

from armbench.controller_client import (
    ERR_BAD_PARAMETER,
    ERR_IMU_TIMEOUT,
    ERR_NOT_MOTION_OWNER,
    ERR_OK,
    FOLLOW_TIMEOUT_SCANS,
    KIND_FOLLOW,
    KIND_STOP,
    ArmControllerClient,
)
from armbench.follow_demo import (
    SCAN_S,
    START_TIP_MM,
    TOOL_MM,
    HandRig,
    analyse,
    arm_frames,
    earth_to_base,
    run_follow,
)
from armbench.plant.imu import HandTrajectory, ImuModel, ImuRecord, simulate
from armbench.softplc.modbus_client import PlcClient

ERROR_P95_DEG = 3.5
ERROR_MAX_DEG = 5.0
TIP_DRIFT_MM = 5.0
FLANGE_DRIFT_MM = 0.01
ACC_LIMIT = 1000.0  # deg/s^2, the slew limiter's MG996R default (ServoSlew.st)
VEL_LIMIT = 150.0


@pytest.fixture()
def rig(fast_controller: FastPlc) -> Iterator[HandRig]:
    r = HandRig(fast_controller.plc.image, fast_controller.plc.lock)
    fast_controller.before_scan.append(r.before_scan)
    try:
        yield r
    finally:
        fast_controller.before_scan.remove(r.before_scan)
        with PlcClient(*fast_controller.address) as modbus, ArmControllerClient(modbus) as c:
            c.stop(wait=True)  # leave the arm at rest for the next test


def accelerations(joints: np.ndarray) -> np.ndarray:
    return np.diff(joints, n=2, axis=0) / SCAN_S ** 2


def assert_smooth(joints: np.ndarray) -> None:
    """Every servo output within the limiter's speed and acceleration (float32 slack)."""
    assert np.all(np.isfinite(joints))
    assert np.abs(np.diff(joints, axis=0)).max() / SCAN_S <= VEL_LIMIT * 1.001
    assert np.abs(accelerations(joints)).max() <= ACC_LIMIT * 1.01


def start(ctl: ArmControllerClient, rig: HandRig, record: ImuRecord, *, heading: float = 10.0,
          flange_fixed: bool = False,
          mount_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
    assert ctl.move_tool_angles(START_TIP_MM, 0.0, 0.0, wait=True).error_id == ERR_OK
    assert ctl.imu_select_filter("madgwick_marg", 0.0) == ERR_OK
    assert ctl.imu_set_period(record.period_s) == ERR_OK
    assert ctl.imu_reset(tuple(float(v) for v in record.quat_true[0])) == ERR_OK
    rig.play(record, 1)
    rig.wait_samples(20)
    rig.start_recording()
    assert ctl.follow_imu(heading_deg=heading, flange_fixed=flange_fixed,
                          mount_rpy_deg=mount_rpy_deg).error_id == ERR_OK


def finite_block(ctl: ArmControllerClient) -> None:
    fs = ctl.follow_state()
    for v in (fs.heading_deg, fs.dead_band_deg, fs.max_rate_dps, *fs.anchor_mm,
              *fs.direction, fs.pitch_deg, fs.roll_deg, fs.lag_deg, fs.off_plane_deg,
              fs.error_deg, fs.drift_mm):
        assert math.isfinite(v)


@pytest.mark.parametrize(("flange_fixed", "rate_hz"), [(False, 100.0), (True, 100.0),
                                                      (False, 50.0)])
def test_arm_follows_hand(fast_controller: FastPlc, rig: HandRig, flange_fixed: bool,
                          rate_hz: float) -> None:
    run = run_follow(fast_controller.address, rig, duration_s=12.0, heading_deg=10.0,
                     flange_fixed=flange_fixed, seed=5, rate_hz=rate_hz)
    ok = run.t >= 2.0
    assert ok.sum() > 900
    assert np.percentile(run.error_deg[ok], 95) < ERROR_P95_DEG
    assert run.error_deg[ok].max() < ERROR_MAX_DEG
    # it really moved: the hand tilts by tens of degrees and the arm went along
    assert np.ptp(run.arm_pitch) > 30.0 and np.ptp(run.arm_roll) > 60.0
    assert run.drift_mm.max() < (FLANGE_DRIFT_MM if flange_fixed else TIP_DRIFT_MM)
    assert_smooth(run.joints)


def test_arm_follows_hand_jerk_limited(fast_controller: FastPlc, rig: HandRig) -> None:
    """FollowImu with a jerk limit (Int2, 3000 deg/s^3): the same bounds as without, and the
    joint setpoints the follow writes are smoother (their third differences, the joints'
    jerk, at the 99th percentile) than in the same run without the limit. Not at their
    peak: the limit holds for the turning speed along the arc to the hand, and a hand that
    swerves turns that arc (ToolOrientationFollower's header)."""
    runs = {}
    for jerk in (0, 3000):
        runs[jerk] = run_follow(fast_controller.address, rig, duration_s=8.0, heading_deg=10.0,
                                seed=5, max_jerk_dps3=jerk)
    run = runs[3000]
    ok = run.t >= 2.0
    assert np.percentile(run.error_deg[ok], 95) < ERROR_P95_DEG
    assert run.error_deg[ok].max() < ERROR_MAX_DEG
    assert run.drift_mm.max() < TIP_DRIFT_MM
    assert_smooth(run.joints)
    jerk = {k: np.abs(np.diff(r.setpoints, n=3, axis=0)).max(axis=1) / SCAN_S ** 3
            for k, r in runs.items()}
    p99 = {k: float(np.percentile(v, 99)) for k, v in jerk.items()}
    peak = {k: float(v.max()) for k, v in jerk.items()}
    print(f"joint setpoint jerk p99 / max, deg/s^3: without {p99[0]:.0f} / {peak[0]:.0f}, "
          f"with 3000 {p99[3000]:.0f} / {peak[3000]:.0f}")
    assert p99[3000] < 0.5 * p99[0]


def _trajectory(pitch: tuple[tuple[float, float, float], ...], pitch_offset: float = 0.0,
                yaw_offset: float = 10.0) -> HandTrajectory:
    return HandTrajectory(roll=((20.0, 0.15, 0.0),), pitch=pitch, yaw=(),
                          pitch_offset_deg=pitch_offset, yaw_offset_deg=yaw_offset)


def test_sample_timeout_brakes(ctl: ArmControllerClient, rig: HandRig) -> None:
    record = simulate(_trajectory(((25.0, 0.3, 0.0),)), ImuModel(), duration_s=20.0,
                      rate_hz=100.0, seed=2)
    start(ctl, rig, record)
    rig.wait_samples(20 + 180)  # the hand moves fast (tool pitch up to 47 deg/s)
    rig.pause()  # the IMU goes silent in mid-motion
    outcome = ctl.wait_motion(timeout_s=20.0)
    ctl.wait_scans(3)  # the rig records a scan's outputs before the next one
    rows = rig.take_rows()
    assert outcome.state == "error" and outcome.error_id == ERR_IMU_TIMEOUT
    assert ctl.follow_state().error_id == ERR_IMU_TIMEOUT
    joints = np.array([r.joints for r in rows])
    assert_smooth(joints)
    # it was moving when the samples stopped, and it ends at rest
    silent = next(i for i, r in enumerate(rows) if i > 0 and r.sample == rows[-1].sample
                  and rows[i - 1].sample < r.sample)
    speed = np.abs(np.diff(joints, axis=0)).max(axis=1) / SCAN_S
    assert speed[silent - 5:silent].max() > 5.0
    assert speed[-3:].max() < 1e-3
    # between samples the follow holds the last IK setpoints: after the last one the limiter
    # brings the servos to rest exactly there (no overshoot, within the limits), and the
    # follow ends FOLLOW_TIMEOUT_SCANS scans later (+1: a sample is filtered at the end of a
    # scan, the follow steps in the next), braking from rest
    setpoints = np.array([r.setpoints for r in rows])
    last = setpoints[silent + 2]
    assert np.abs(setpoints[silent + 2:] - last).max() < 1e-4
    assert np.abs(joints[-1] - last).max() < 1e-3
    ended = next(i for i in range(silent, len(rows)) if rows[i].follow_state != 1)
    assert FOLLOW_TIMEOUT_SCANS <= ended - silent <= FOLLOW_TIMEOUT_SCANS + 3
    assert speed[silent + FOLLOW_TIMEOUT_SCANS:].max() < 1e-3  # at rest before the end
    finite_block(ctl)


@pytest.mark.parametrize("bad", ["zero_accel", "saturated_gyro", "mag_overflow"])
def test_bad_samples_stop_without_jump(ctl: ArmControllerClient, rig: HandRig,
                                       bad: str) -> None:
    record = simulate(_trajectory(((20.0, 0.2, 0.0),)), ImuModel(), duration_s=6.0,
                      rate_hz=100.0, seed=4)
    k = 150
    if bad == "zero_accel":
        record.accel_raw[k:] = 0
    elif bad == "saturated_gyro":
        record.gyro_raw[k:, 0] = 32767
    else:
        record.mag_raw[k:, 1] = -4096
    start(ctl, rig, record)
    outcome = ctl.wait_motion(timeout_s=20.0)
    rows = rig.take_rows()
    rig.pause()
    assert outcome.state == "error"
    assert 40 <= outcome.error_id <= 45  # the filter's verdict (OrientationFilters.st)
    assert ctl.imu_state().error_id == outcome.error_id
    assert_smooth(np.array([r.joints for r in rows]))
    finite_block(ctl)


def test_bad_arguments_rejected(ctl: ArmControllerClient, rig: HandRig) -> None:
    record = simulate(_trajectory(((10.0, 0.2, 0.0),)), ImuModel(), duration_s=3.0,
                      rate_hz=100.0, seed=6)
    assert ctl.move_tool_angles(START_TIP_MM, 0.0, 0.0, wait=True).error_id == ERR_OK
    rig.play(record, 1)
    rig.wait_samples(10)
    for kwargs in ({"dead_band_deg": math.nan}, {"max_rate_dps": -1.0},
                   {"heading_deg": 400.0}, {"mount_rpy_deg": (0.0, math.inf, 0.0)},
                   {"max_jerk_dps3": -1}, {"max_jerk_dps3": 1_000_001}):
        assert ctl.follow_imu(**kwargs).error_id == ERR_BAD_PARAMETER  # type: ignore[arg-type]
    assert ctl.command(46, ints=(4, 0)).error_id == ERR_BAD_PARAMETER
    assert ctl.follow_state().state == 0
    rig.pause()
    ctl.wait_scans(FOLLOW_TIMEOUT_SCANS + 5)
    assert ctl.follow_imu().error_id == ERR_IMU_TIMEOUT  # no recent sample: no follow


def test_other_client_stop_ends_follow(fast_controller: FastPlc, ctl: ArmControllerClient,
                                       rig: HandRig) -> None:
    record = simulate(_trajectory(((15.0, 0.2, 0.0),)), ImuModel(), duration_s=20.0,
                      rate_hz=100.0, seed=8)
    start(ctl, rig, record)
    rig.wait_samples(150)
    with PlcClient(*fast_controller.address) as modbus, ArmControllerClient(modbus) as other:
        assert other.follow_imu_stop().error_id == ERR_NOT_MOTION_OWNER
        assert ctl.follow_state().state == 1
        assert other.stop().error_id == ERR_OK
        other.wait_motion(timeout_s=10.0)
    m = ctl.motion()
    fs = ctl.follow_state()
    assert m.kind == KIND_STOP and not m.busy
    assert fs.state == 0 and fs.aborted
    steps = fs.steps
    # the hand goes on for 250 scans after the stop ended: the arm does not (counted in scans,
    # not samples: under load the Modbus round trips above can outlast sample 250)
    settled = rig.scans + 250
    deadline = time.monotonic() + 60.0
    while rig.scans < settled and time.monotonic() < deadline:
        time.sleep(0.005)
    assert rig.scans >= settled, "the soft PLC ran fewer than 250 scans in 60 s"
    rows = rig.take_rows()
    rig.pause()
    assert ctl.follow_state().steps == steps
    joints = np.array([r.joints for r in rows])
    assert_smooth(joints)
    assert np.ptp(joints[-40:], axis=0).max() < 1e-4


def test_own_stop_brakes_done(ctl: ArmControllerClient, rig: HandRig) -> None:
    record = simulate(_trajectory(((15.0, 0.2, 0.0),)), ImuModel(), duration_s=10.0,
                      rate_hz=100.0, seed=9)
    start(ctl, rig, record)
    assert ctl.motion().kind == KIND_FOLLOW
    rig.wait_samples(150)
    assert ctl.follow_imu_stop(wait=True).error_id == ERR_OK
    m = ctl.motion()
    rows = rig.take_rows()
    rig.pause()
    assert m.kind == KIND_FOLLOW and m.done and not m.error
    assert ctl.follow_state().error_id == 0
    assert_smooth(np.array([r.joints for r in rows]))


def test_unreachable_orientation_holds(ctl: ArmControllerClient, rig: HandRig) -> None:
    # the tool tips down to 70 deg: below about 40 the wrist and elbow servos run out
    record = simulate(_trajectory(((35.0, 0.1, -math.pi / 2),), pitch_offset=35.0),
                      ImuModel(), duration_s=8.0, rate_hz=100.0, seed=10)
    start(ctl, rig, record)
    rig.wait_samples(len(record) - 2, timeout_s=60.0)
    fs = ctl.follow_state()
    rows = rig.take_rows()
    rig.pause()
    assert fs.unreachable_count > 0 and fs.unreachable_id != 0
    run = analyse(rows, record, 10.0, False)
    assert_smooth(run.joints)
    finite_block(ctl)
    # the arm never tipped further than its reach, and held there (no NaN, no wrap)
    assert run.arm_pitch.min() > -45.0
    held = run.hand_pitch < run.arm_pitch - 10.0
    assert held.sum() > 50
    assert np.ptp(run.arm_pitch[held]) < 15.0
    assert run.drift_mm.max() < TIP_DRIFT_MM


def test_lab_heading(ctl: ArmControllerClient, rig: HandRig) -> None:
    """docs/orientation.md lab question: the arm's X axis points 30 deg east of magnetic
    north, so FollowImu's heading is -30 deg; a hand pointing its tool horizontally at
    magnetic north then points 30 deg off the arm plane (the tip stands on the base X axis),
    which the arm cannot follow: FollowOffPlaneDeg = 30."""
    heading = -30.0  # the lab's answer
    record = simulate(_trajectory(((1.0, 0.2, 0.0),), yaw_offset=0.0), ImuModel(),
                      duration_s=6.0, rate_hz=100.0, seed=12)
    north = earth_to_base(np.array([1.0, 0.0, 0.0]), heading)[0]
    assert np.allclose(north, [math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0])
    start(ctl, rig, record, heading=heading)
    rig.wait_samples(400)
    fs = ctl.follow_state()
    rig.take_rows()
    rig.pause()
    assert fs.state == 1
    assert abs(fs.off_plane_deg - 30.0) < 2.0
    assert abs(fs.direction[1]) < 1e-4  # the commanded direction stays in the plane y = 0


def test_reference_fk_matches_start_pose() -> None:
    """The numpy FK used above, against the closed form at the start pose (Shoulder 75,
    Elbow 95, wrist +10: tool horizontal, tip at START_TIP_MM)."""
    x, y, tip = arm_frames(np.array([[0.0, 75.0, 95.0, 10.0, 0.0]]))
    assert np.allclose(x[0], [1.0, 0.0, 0.0], atol=1e-12)
    assert np.allclose(y[0], [0.0, 1.0, 0.0], atol=1e-12)
    assert np.allclose(tip[0], START_TIP_MM, atol=0.01)
    r = 20.0 + 120.0 * math.cos(math.radians(75)) + 130.0 * math.cos(math.radians(-10))
    assert math.isclose(tip[0][0], r + TOOL_MM, abs_tol=1e-9)



def test_mount_offset_rolls_the_tool(ctl: ArmControllerClient, rig: HandRig) -> None:
    """A sensor mounted rolled by -20 deg about the tool axis (Arg4): the tool frame is the
    sensor's turned by +20 deg about x, so the arm rolls 20 deg further than the sensor."""
    record = simulate(_trajectory(((2.0, 0.2, 0.0),)), ImuModel(), duration_s=6.0,
                      rate_hz=100.0, seed=13)
    start(ctl, rig, record, heading=10.0, mount_rpy_deg=(20.0, 0.0, 0.0))
    rig.wait_samples(400)
    rows = rig.take_rows()
    rig.pause()
    run = analyse(rows, record, 10.0, False)
    late = run.t >= 2.0
    assert np.abs(run.arm_roll[late] - (run.hand_roll[late] + 20.0)).max() < 3.5
    assert np.abs(run.arm_pitch[late] - run.hand_pitch[late]).max() < 3.5
