"""The controller over Modbus: FK∘IK, rejected commands, PWM words, calibration, SolveBatch
(tests/modbus/conftest.py)."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np
import pytest

from armbench.controller_client import (
    CMD_INIT_PWM,
    CMD_RELAX,
    CMD_SOLVE_BATCH,
    ERR_BAD_CALIBRATION,
    ERR_BAD_COUNT,
    ERR_BAD_JOINT,
    ERR_JOINT_LIMIT,
    ERR_NOT_FINITE,
    ERR_UNKNOWN_COMMAND,
    ERR_UNREACHABLE,
    ArmControllerClient,
    Calibration,
    Status,
)
from armbench.plant import arm

OSC_HZ = 25.0e6
PRESCALE = 121
F_UPDATE_HZ = OSC_HZ / (4096 * (PRESCALE + 1))  # datasheet equation 1: 50.03 Hz


def _targets(n: int) -> list[tuple[float, float, float]]:
    """n points spread over a box inside the workspace and the servos' travel."""
    pts = []
    for i in range(n):
        u = (i * 0.618034) % 1.0
        v = (i * 0.754878) % 1.0
        w = (i * 0.569840) % 1.0
        pts.append((120.0 + 60.0 * u, -40.0 + 80.0 * v, 90.0 + 60.0 * w))
    return pts


def _joints(st: Status) -> tuple[float, float, float]:
    return st.joints_deg


def test_fk_of_ik_round_trip(plc: ArmControllerClient) -> None:
    worst_ref = worst_echo = 0.0
    targets = _targets(120)
    for p in targets:
        st = plc.move_xyz(*p)
        assert st.error_id == 0, (p, st)
        worst_ref = max(worst_ref, math.dist(p, arm.forward(*_joints(st))))
        worst_echo = max(worst_echo, math.dist(p, st.echo_mm))
    assert worst_ref <= 0.05
    assert worst_echo <= 0.05


def test_elbow_down_choice(plc: ArmControllerClient) -> None:
    up = plc.move_xyz(150.0, 0.0, 120.0)
    assert up.error_id == 0 and up.joints_deg[2] <= 180.0
    down = plc.move_xyz(150.0, 0.0, 120.0, elbow_down=True)
    # elbow down at this target needs a shoulder outside the servo's travel: rejected, held
    if down.error_id == 0:
        assert down.joints_deg[2] >= 180.0
    else:
        assert down.error_id == ERR_JOINT_LIMIT
        assert down.joints_deg == up.joints_deg


def _rejected(plc: ArmControllerClient, before: Status, after: Status,
              words_before: list[int], code: int) -> None:
    assert after.error_id == code
    assert after.joints_deg == before.joints_deg
    assert after.echo_mm == before.echo_mm
    assert after.pulses_us == before.pulses_us
    assert plc.channel_words() == words_before


@pytest.mark.parametrize("target", [(1000.0, 0.0, 120.0), (0.0, 0.0, 1.0e7), (400.0, 0.0, 100.0)])
def test_unreachable_target_is_rejected(plc: ArmControllerClient,
                                        target: tuple[float, float, float]) -> None:
    before = plc.move_xyz(150.0, 10.0, 120.0, wait=True)
    words = plc.channel_words()
    after = plc.move_xyz(*target)
    _rejected(plc, before, after, words, ERR_UNREACHABLE)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_target_is_rejected(plc: ArmControllerClient, bad: float) -> None:
    before = plc.move_xyz(160.0, -10.0, 110.0, wait=True)
    words = plc.channel_words()
    _rejected(plc, before, plc.move_xyz(bad, 0.0, 120.0), words, ERR_NOT_FINITE)
    _rejected(plc, before, plc.move_xyz(150.0, 0.0, bad), words, ERR_NOT_FINITE)
    _rejected(plc, before, plc.move_joints(0.0, bad, 65.0), words, ERR_NOT_FINITE)


def test_unknown_command_is_rejected(plc: ArmControllerClient) -> None:
    before = plc.move_xyz(150.0, 0.0, 130.0, wait=True)
    words = plc.channel_words()
    for code in (0, 18, 99, -1, 65536):  # 11..17 are the motion commands
        _rejected(plc, before, plc.command(code, args=(1.0, 2.0, 3.0)), words,
                  ERR_UNKNOWN_COMMAND)


def test_joint_outside_servo_travel_is_rejected(plc: ArmControllerClient) -> None:
    before = plc.move_joints(0.0, 70.0, 65.0, wait=True)
    words = plc.channel_words()
    _rejected(plc, before, plc.move_joints(61.0, 70.0, 65.0), words, ERR_JOINT_LIMIT)


def _datasheet_count(pulse_us: float) -> int:
    return round(pulse_us * 4096 * F_UPDATE_HZ / 1e6)


@pytest.mark.parametrize("joints", [(0.0, 70.0, 65.0), (-60.0, 10.0, 5.0), (60.0, 130.0, 125.0),
                                    (12.5, 81.25, 40.0), (-33.3, 55.5, 99.9)])
def test_pwm_counts_match_datasheet(plc: ArmControllerClient,
                                   joints: tuple[float, float, float]) -> None:
    zero = [c.zero_offset_deg for c in plc.calibration()]  # read back, not duplicated
    st = plc.move_joints(*joints, wait=True)
    assert st.error_id == 0
    words = plc.channel_words()
    for ch, angle in enumerate(joints):
        pulse_us = 1500.0 + (angle - zero[ch]) * 1000.0 / 120.0  # MG996R: 1..2 ms = -60..+60
        assert st.pulses_us[ch] == pytest.approx(pulse_us, abs=1e-3)
        assert words[ch] == _datasheet_count(pulse_us), (ch, pulse_us)
    # channels 3, 4: the 5-axis arm's wrist, held where it stands by a 3-joint move
    wrist = plc.wrist()
    for ch, cal, angle in zip((3, 4), plc.wrist_calibration(), wrist.out_deg, strict=True):
        pulse_us = 1500.0 + cal.direction * (angle - cal.zero_offset_deg) * 1000.0 / 120.0
        assert words[ch] == _datasheet_count(pulse_us), (ch, pulse_us)
    assert words[5:] == [0x1000] * 11  # unused channels fully off


def test_relax_turns_all_channels_off(plc: ArmControllerClient) -> None:
    plc.move_joints(0.0, 70.0, 65.0)
    st = plc.command(CMD_RELAX)
    assert st.error_id == 0 and st.pulses_us == (0.0, 0.0, 0.0)
    assert plc.channel_words() == [0x1000] * 16


def test_init_pwm_publishes_the_datasheet_sequence(plc: ArmControllerClient) -> None:
    assert plc.read_register("PWMINITREQUEST") == 0
    pending = plc.submit(CMD_INIT_PWM)
    seen = False
    deadline = time.monotonic() + 2.0
    while not seen and plc.answer(pending.mailbox).ack_seq != pending.seq \
            and time.monotonic() < deadline:
        seen = plc.read_register("PWMINITREQUEST") == 1
    assert seen, "PwmInitRequest (%QX0.0, the PSM's init request) never rose"
    assert plc.wait(pending) == 0
    st = plc.status()
    assert plc.read_register("PWMINITREQUEST") == 0
    assert st.error_id == 0 and st.pwm_ready and st.prescale == PRESCALE
    assert st.init_frames == 5
    assert plc.init_frames() == [(0x00, 0x11), (0xFE, PRESCALE), (0x01, 0x04), (0x00, 0x01),
                                 (0x00, 0xA1)]


# -- SetCalibration ----------------------------------------------------------------------------


@pytest.fixture
def restore_calibration(plc: ArmControllerClient) -> Iterator[None]:
    saved = plc.calibration()
    yield
    for joint, cal in enumerate(saved):
        assert plc.set_calibration(joint, cal).error_id == 0


def test_calibration_reads_back_mg996r_defaults(plc: ArmControllerClient) -> None:
    for cal in plc.calibration():
        assert (cal.direction, cal.min_pulse_us, cal.max_pulse_us) == (1, 1000.0, 2000.0)
        assert (cal.min_angle_deg, cal.max_angle_deg) == (-60.0, 60.0)


@pytest.mark.usefixtures("restore_calibration")
def test_set_calibration_changes_the_pulses(plc: ArmControllerClient) -> None:
    # reversed elbow, 10 deg more offset, narrower travel at the same scale
    cal = Calibration(zero_offset_deg=plc.calibration()[2].zero_offset_deg + 10.0, direction=-1,
                      min_pulse_us=1125.0, max_pulse_us=1875.0, min_angle_deg=-45.0,
                      max_angle_deg=45.0)
    st = plc.set_calibration(2, cal)
    assert st.error_id == 0
    assert plc.calibration()[2] == cal
    st = plc.move_joints(0.0, 70.0, cal.zero_offset_deg - 12.0, wait=True)
    assert st.error_id == 0
    assert st.pulses_us[2] == pytest.approx(1500.0 + 12.0 * 1000.0 / 120.0, abs=1e-3)
    st = plc.move_joints(0.0, 70.0, cal.zero_offset_deg - 46.0)  # 46 deg > the new 45 deg travel
    assert st.error_id == ERR_JOINT_LIMIT


@pytest.mark.parametrize(("joint", "cal", "code"), [
    (0, Calibration(min_angle_deg=60.0, max_angle_deg=-60.0), ERR_BAD_CALIBRATION),
    (1, Calibration(min_pulse_us=2000.0, max_pulse_us=1000.0), ERR_BAD_CALIBRATION),
    (2, Calibration(max_pulse_us=25000.0), ERR_BAD_CALIBRATION),
    (0, Calibration(direction=0), ERR_BAD_CALIBRATION),
    (1, Calibration(zero_offset_deg=math.nan), ERR_NOT_FINITE),
    (6, Calibration(), ERR_BAD_JOINT),  # 0..2 the arm, 3..4 the wrist, 5 the gripper (5-AXIS)
    (-1, Calibration(), ERR_BAD_JOINT),
])
def test_bad_calibration_is_rejected(plc: ArmControllerClient, joint: int, cal: Calibration,
                                     code: int) -> None:
    before = plc.move_joints(5.0, 75.0, 60.0, wait=True)
    cals = plc.calibration()
    words = plc.channel_words()
    after = plc.set_calibration(joint, cal)
    _rejected(plc, before, after, words, code)
    assert plc.calibration() == cals


# -- SolveBatch --------------------------------------------------------------------------------


def test_batch_fk_of_ik_over_1000_points(plc: ArmControllerClient) -> None:
    targets = _targets(1000)
    plc.open()  # the mailbox claim (a Hello) is not one of the batch's commands
    answered_before = plc.status().commands_answered
    results = plc.batch_roundtrip(targets)
    assert len(results) == len(targets)
    assert all(r.error_id == 0 for r in results), [r for r in results if r.error_id][:3]
    want = np.array(targets)
    ref = arm.forward_batch(np.array([r.joints_deg for r in results]))  # numpy reference FK
    echo = np.array([r.echo_mm for r in results])
    assert np.max(np.linalg.norm(ref - want, axis=1)) <= 0.05
    assert np.max(np.linalg.norm(echo - want, axis=1)) <= 0.05
    # each SolveBatch is one command of 32 points, not one per point: counted in the PLC's
    # answered commands (ReserveBatch, the SolveBatches, ReleaseBatch). Counting scans
    # instead measured the client too: on a loaded machine it writes and reads slower while
    # the PLC scans on (123 scans for 32 batches, a run against the real v3 runtime)
    batches = math.ceil(len(targets) / plc.batch_max)
    assert plc.status().commands_answered - answered_before == batches + 2


def test_batch_matches_single_moves(plc: ArmControllerClient) -> None:
    targets = _targets(7)
    batch = plc.solve_batch(targets)
    for p, r in zip(targets, batch, strict=True):
        st = plc.move_xyz(*p)
        assert (r.joints_deg, r.echo_mm, r.error_id) == (st.joints_deg, st.echo_mm, 0)


def test_batch_reports_each_points_error_and_moves_nothing(plc: ArmControllerClient) -> None:
    before = plc.move_xyz(150.0, 0.0, 120.0, wait=True)
    words = plc.channel_words()
    targets = [(150.0, 10.0, 120.0), (1000.0, 0.0, 120.0), (math.nan, 0.0, 0.0),
               (150.0, -10.0, 120.0)]
    res = plc.solve_batch(targets)
    assert [r.error_id for r in res] == [0, ERR_UNREACHABLE, ERR_NOT_FINITE, 0]
    assert res[1].joints_deg == res[1].echo_mm == (0.0, 0.0, 0.0)
    st = plc.status()
    assert (st.batch_count, st.batch_failures) == (4, 2)
    assert st.joints_deg == before.joints_deg and plc.channel_words() == words
    # points beyond the count are cleared
    full = plc.batch_results(plc.batch_max)
    assert all(r == full[-1] for r in full[4:]) and full[-1].echo_mm == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("count", [0, -1, 33, 1000])
def test_batch_bad_count_is_rejected(plc: ArmControllerClient, count: int) -> None:
    before = plc.move_xyz(150.0, 5.0, 120.0, wait=True)
    plc.solve_batch([(150.0, 0.0, 120.0)])
    st_before = plc.status()
    results = plc.batch_results(1)
    words = plc.channel_words()
    with plc.batch_buffer():
        after = plc.command(CMD_SOLVE_BATCH, ints=(0, count))
    _rejected(plc, before, after, words, ERR_BAD_COUNT)
    assert (after.batch_count, after.batch_failures) == (st_before.batch_count,
                                                         st_before.batch_failures)
    assert plc.batch_results(1) == results
