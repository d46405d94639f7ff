"""The 5-axis arm over Modbus (5-AXIS of plc_project/Controller.st: MoveToolAngles,
MoveToolVector, the wrist servos on PCA9685 channels 3 and 4). Runs against the soft PLC, or a
real PLC with ``--plc-host``/``--plc-port`` like the rest of tests/modbus.

The reference is independent of the PLC: a float64 numpy product of elementary transforms
Rz(base) Tz(A1) Tx(A2) Ry(-shoulder) Tx(A3) Ry(180 - elbow) Tx(A4) Ry(-wrist pitch)
Rx(wrist roll) Tx(tool) (the joint conventions of st/Kinematics5Axis.st's header), evaluated
on the joints the servos are really sent (the slew limiter's outputs) once the move has ended.
Poses are commanded from joint sets inside every servo's travel, pushed through the same
reference, so each command has a known reachable answer.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from armbench.controller_client import (
    CMD_MOVE_TOOL_ANGLES,
    CMD_MOVE_TOOL_VECTOR,
    ERR_BAD_CALIBRATION,
    ERR_BAD_JOINT,
    ERR_BAD_PARAMETER,
    ERR_FLANGE_UNREACHABLE,
    ERR_JOINT_LIMIT,
    ERR_NOT_FINITE,
    ERR_OK,
    ERR_TOOL_OUT_OF_PLANE,
    ERR_TOOL_VECTOR_ZERO,
    ERR_UNREACHABLE,
    FIVE_FLAG_FLANGE_FIXED,
    JOINT_GRIPPER,
    JOINT_WRIST_PITCH,
    JOINT_WRIST_ROLL,
    ArmControllerClient,
    Calibration,
)
from armbench.plant import arm
from five_axis_ref import fk5, pitch_from_joints

GEOM = arm.DEFAULT_GEOMETRY  # the controller's ArmGeometry (library defaults)
TOOL_MM = 60.0  # FiveAxisGeometry.ToolMm default: the controller's tool (5-AXIS header)
POS_TOL_MM = 0.01  # float32 IK at a ~300 mm reach, then float32 registers
DIR_TOL = 1e-4
F_UPDATE_HZ = 25e6 / (4096 * 122)  # PCA9685 at prescale 121 (datasheet eq. 1)

# joint sets (base, shoulder, elbow, wrist pitch, wrist roll), deg, all inside the default
# servo travel: base -60..60, shoulder 10..130, elbow 5..125, wrist -60..60
POSES = [
    (20.0, 80.0, 100.0, -20.0, 30.0),
    (-35.0, 60.0, 110.0, 40.0, -45.0),
    (10.0, 95.0, 70.0, -50.0, 10.0),
    (45.0, 50.0, 120.0, 15.0, 55.0),
]


def fk(joints: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Reference FK (tests/five_axis_ref.py): (flange frame, tool frame), 4x4, mm."""
    return fk5(joints, GEOM, TOOL_MM)


def reached(plc: ArmControllerClient) -> tuple[float, float, float, float, float]:
    """The five joints the servos are sent now (slew limiter outputs)."""
    m, w = plc.motion(), plc.wrist()
    return (*m.out_deg, *w.out_deg)


def datasheet_count(pulse_us: float) -> int:
    return round(pulse_us * 4096 * F_UPDATE_HZ / 1e6)


def check_pose(plc: ArmControllerClient, tip: np.ndarray, frame: np.ndarray,
               flange: np.ndarray | None = None) -> tuple[float, ...]:
    """FK of the reached joints carries the commanded tip (or flange) and tool frame."""
    q = reached(plc)
    f_ref, t_ref = fk(q)
    if flange is not None:
        assert np.linalg.norm(f_ref[:3, 3] - flange) < POS_TOL_MM, (q, f_ref[:3, 3], flange)
    assert np.linalg.norm(t_ref[:3, 3] - tip) < POS_TOL_MM, (q, t_ref[:3, 3], tip)
    assert np.abs(t_ref[:3, :3] - frame).max() < DIR_TOL, (q, t_ref[:3, :3], frame)
    return q


def check_echo_and_channels(plc: ArmControllerClient, tip: np.ndarray,
                            direction: np.ndarray) -> None:
    echo = plc.five_axis_echo()
    assert echo.session == plc.session and echo.error_id == ERR_OK
    assert np.linalg.norm(np.array(echo.tip_mm) - tip) < POS_TOL_MM
    assert np.abs(np.array(echo.direction) - direction).max() < DIR_TOL
    # channels 3 and 4 carry the wrist pulses of the MG996R mapping (1..2 ms = -60..+60 deg)
    words = plc.channel_words()
    w = plc.wrist()
    for ch, cal, angle, pulse in zip((3, 4), plc.wrist_calibration(), w.out_deg, w.pulses_us,
                                     strict=True):
        expect_us = 1500.0 + cal.direction * (angle - cal.zero_offset_deg) * 1000.0 / 120.0
        assert pulse == pytest.approx(expect_us, abs=1e-3)
        assert words[ch] == datasheet_count(expect_us), (ch, expect_us)


@pytest.mark.parametrize("flange_fixed", [False, True], ids=["tip-fixed", "flange-fixed"])
def test_move_tool_angles_reaches_pose(plc: ArmControllerClient, flange_fixed: bool) -> None:
    for q in POSES:
        f_cmd, t_cmd = fk(q)
        target = f_cmd[:3, 3] if flange_fixed else t_cmd[:3, 3]
        st = plc.move_tool_angles((float(target[0]), float(target[1]), float(target[2])),
                                  pitch_from_joints(q), q[4], flange_fixed=flange_fixed,
                                  wait=True)
        assert st.error_id == ERR_OK, q
        got = check_pose(plc, t_cmd[:3, 3], t_cmd[:3, :3],
                         f_cmd[:3, 3] if flange_fixed else None)
        assert np.abs(np.array(got) - np.array(q)).max() < 0.01  # the one elbow-up solution
        check_echo_and_channels(plc, t_cmd[:3, 3], t_cmd[:3, 0])


@pytest.mark.parametrize("flange_fixed", [False, True], ids=["tip-fixed", "flange-fixed"])
def test_move_tool_vector_reaches_pose(plc: ArmControllerClient, flange_fixed: bool) -> None:
    for q in POSES:
        f_cmd, t_cmd = fk(q)
        target = f_cmd[:3, 3] if flange_fixed else t_cmd[:3, 3]
        direction = 2.5 * t_cmd[:3, 0]  # any length: normalised by the PLC
        st = plc.move_tool_vector((float(target[0]), float(target[1]), float(target[2])),
                                  (float(direction[0]), float(direction[1]),
                                   float(direction[2])),
                                  q[4], flange_fixed=flange_fixed, wait=True)
        assert st.error_id == ERR_OK, q
        check_pose(plc, t_cmd[:3, 3], t_cmd[:3, :3], f_cmd[:3, 3] if flange_fixed else None)
        check_echo_and_channels(plc, t_cmd[:3, 3], t_cmd[:3, 0])


def test_three_joint_move_leaves_the_wrist(plc: ArmControllerClient) -> None:
    q = POSES[1]
    _, t_cmd = fk(q)
    p = t_cmd[:3, 3]
    assert plc.move_tool_angles((float(p[0]), float(p[1]), float(p[2])), pitch_from_joints(q),
                                q[4], wait=True).error_id == ERR_OK
    wrist_before = plc.wrist().out_deg
    words_before = plc.channel_words()[3:5]
    st = plc.move_xyz(150.0, 40.0, 120.0, wait=True)
    assert st.error_id == ERR_OK
    got = reached(plc)
    # the wrist's PWM words do not change; its angle, read back from the pulse through
    # float32 (the output stage works in us), stays within 1e-3 deg (0.008 us of pulse,
    # a 600th of one PCA9685 count)
    assert plc.channel_words()[3:5] == words_before
    assert got[3:] == pytest.approx(wrist_before, abs=1e-3)
    flange, _ = fk(got)
    assert np.linalg.norm(flange[:3, 3] - np.array([150.0, 40.0, 120.0])) < POS_TOL_MM
    # a straight line and a jog (the Cartesian blocks drive joints 1..3 only)
    st = plc.move_linear((170.0, 0.0, 140.0), velocity=100.0, wait=True)
    assert st.error_id == ERR_OK
    got = reached(plc)
    assert plc.channel_words()[3:5] == words_before
    assert got[3:] == pytest.approx(wrist_before, abs=1e-3)
    flange, _ = fk(got)
    assert np.linalg.norm(flange[:3, 3] - np.array([170.0, 0.0, 140.0])) < POS_TOL_MM
    assert plc.jog_start((0.0, 0.0, 1.0), max_speed=50.0, acceleration=500.0).error_id == ERR_OK
    for _ in range(10):
        plc.jog_update((0.0, 0.0, 1.0))
        time.sleep(0.02)
    plc.jog_stop()
    plc.wait_motion()
    got = reached(plc)
    assert plc.channel_words()[3:5] == words_before
    assert got[3:] == pytest.approx(wrist_before, abs=1e-3)
    assert fk(got)[0][2, 3] > 140.0 + 1.0  # the jog did move the arm up


def _snapshot(plc: ArmControllerClient) -> tuple[object, ...]:
    m, w = plc.motion(), plc.wrist()
    return (m.out_deg, m.set_deg, w.out_deg, w.set_deg, m.starts, tuple(plc.channel_words()))


def test_bad_input_is_rejected_and_nothing_moves(plc: ArmControllerClient) -> None:
    q = POSES[0]
    f_cmd, t_cmd = fk(q)
    tip = tuple(float(c) for c in t_cmd[:3, 3])
    assert plc.move_tool_angles(tip, pitch_from_joints(q), q[4], wait=True).error_id == ERR_OK
    before = _snapshot(plc)
    direction = t_cmd[:3, 0]
    side = np.cross(direction, [0.0, 0.0, 1.0])  # the arm plane's normal direction
    out_of_plane = tuple(float(c) for c in direction + 0.2 * side / np.linalg.norm(side))
    nan = float("nan")
    cases = [
        (CMD_MOVE_TOOL_VECTOR, (0, 0), (*tip, *out_of_plane), ERR_TOOL_OUT_OF_PLANE),
        (CMD_MOVE_TOOL_VECTOR, (0, 0), (*tip, 0.0, 0.0, 0.0), ERR_TOOL_VECTOR_ZERO),
        (CMD_MOVE_TOOL_ANGLES, (0, 0), (nan, tip[1], tip[2], 0.0, 0.0), ERR_NOT_FINITE),
        (CMD_MOVE_TOOL_ANGLES, (0, 0), (*tip, 0.0, nan), ERR_NOT_FINITE),
        # flange-fixed: the flange point 1 m away
        (CMD_MOVE_TOOL_ANGLES, (FIVE_FLAG_FLANGE_FIXED, 0), (1000.0, 0.0, 100.0, 0.0, 0.0),
         ERR_UNREACHABLE),
        # tip-fixed: the tip 20 mm inside the reach, the tool pointing back at the base: the
        # tip is fine, the flange the orientation asks for (40 mm beyond the reach) is not
        (CMD_MOVE_TOOL_ANGLES, (0, 0), (GEOM.a2 + GEOM.a3 + GEOM.a4 - 20.0, 0.0, GEOM.a1,
                                        180.0, 0.0), ERR_FLANGE_UNREACHABLE),
        (CMD_MOVE_TOOL_ANGLES, (0, 0), (*tip, 0.0, 400.0), ERR_UNREACHABLE),
        # a wrist roll beyond the roll servo's +/-60 deg travel
        (CMD_MOVE_TOOL_ANGLES, (0, 0), (*tip, pitch_from_joints(q), 80.0), ERR_JOINT_LIMIT),
        (CMD_MOVE_TOOL_ANGLES, (4, 0), (*tip, pitch_from_joints(q), q[4]), ERR_BAD_PARAMETER),
        (CMD_MOVE_TOOL_VECTOR, (0, 36001), (*tip, *direction), ERR_BAD_PARAMETER),
    ]
    for code, ints, args, expect in cases:
        st = plc.command(code, ints=ints, args=tuple(float(a) for a in args))
        assert st.error_id == expect, (code, ints, args, st.error_id)
        echo = plc.five_axis_echo()
        assert (echo.session, echo.seq, echo.error_id) == (plc.session, st.ack_seq, expect)
        # the pose block still holds the last started move
        assert np.linalg.norm(np.array(echo.tip_mm) - t_cmd[:3, 3]) < POS_TOL_MM
        assert _snapshot(plc) == before, (code, args)
    with pytest.raises(ValueError, match="roll"):
        plc.move_tool_vector(tip, (1.0, 0.0, 0.0), 361.0)
    assert f_cmd is not None


def test_wrist_calibration(plc: ArmControllerClient) -> None:
    default = Calibration()
    assert plc.wrist_calibration() == (default, default)
    shifted = Calibration(zero_offset_deg=10.0, direction=-1, min_pulse_us=1100.0,
                          max_pulse_us=1900.0, min_angle_deg=-50.0, max_angle_deg=50.0)
    try:
        assert plc.set_calibration(JOINT_WRIST_ROLL, shifted).error_id == ERR_OK
        assert plc.wrist_calibration() == (default, shifted)
        # a roll of 10 deg is now the roll servo's centre: 1500 us on channel 4
        q = (0.0, 80.0, 100.0, 0.0, 10.0)
        _, t_cmd = fk(q)
        p = t_cmd[:3, 3]
        st = plc.move_tool_angles((float(p[0]), float(p[1]), float(p[2])), pitch_from_joints(q),
                                  q[4], wait=True)
        assert st.error_id == ERR_OK
        assert plc.wrist().pulses_us[1] == pytest.approx(1500.0, abs=1e-3)
        bad = Calibration(min_pulse_us=100.0)
        assert plc.set_calibration(JOINT_WRIST_PITCH, bad).error_id == ERR_BAD_CALIBRATION
        # joint 5 is the gripper (tests/modbus/test_wrist_jog_gripper.py): 6 is none
        assert plc.set_calibration(JOINT_GRIPPER + 1, default).error_id == ERR_BAD_JOINT
        assert plc.wrist_calibration() == (default, shifted)
    finally:
        assert plc.set_calibration(JOINT_WRIST_ROLL, default).error_id == ERR_OK
