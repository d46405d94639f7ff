"""The controller over Modbus: FK∘IK, rejected commands, PWM words (tests/modbus/conftest.py)."""

from __future__ import annotations

import math

import pytest

from armbench.controller_client import (
    CMD_RELAX,
    ERR_JOINT_LIMIT,
    ERR_NOT_FINITE,
    ERR_UNKNOWN_COMMAND,
    ERR_UNREACHABLE,
    ArmControllerClient,
    Status,
)
from armbench.plant import arm

OSC_HZ = 25.0e6
PRESCALE = 121
F_UPDATE_HZ = OSC_HZ / (4096 * (PRESCALE + 1))  # datasheet equation 1: 50.03 Hz
ZERO_DEG = (0.0, 70.0, 65.0)  # Controller.st servo zero offsets


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
    before = plc.move_xyz(150.0, 10.0, 120.0)
    words = plc.channel_words()
    after = plc.move_xyz(*target)
    _rejected(plc, before, after, words, ERR_UNREACHABLE)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_target_is_rejected(plc: ArmControllerClient, bad: float) -> None:
    before = plc.move_xyz(160.0, -10.0, 110.0)
    words = plc.channel_words()
    _rejected(plc, before, plc.move_xyz(bad, 0.0, 120.0), words, ERR_NOT_FINITE)
    _rejected(plc, before, plc.move_xyz(150.0, 0.0, bad), words, ERR_NOT_FINITE)
    _rejected(plc, before, plc.move_joints(0.0, bad, 65.0), words, ERR_NOT_FINITE)


def test_unknown_command_is_rejected(plc: ArmControllerClient) -> None:
    before = plc.move_xyz(150.0, 0.0, 130.0)
    words = plc.channel_words()
    for code in (0, 5, 99, -1, 65536):
        _rejected(plc, before, plc.command(code, xyz=(1.0, 2.0, 3.0)), words,
                  ERR_UNKNOWN_COMMAND)


def test_joint_outside_servo_travel_is_rejected(plc: ArmControllerClient) -> None:
    before = plc.move_joints(0.0, 70.0, 65.0)
    words = plc.channel_words()
    _rejected(plc, before, plc.move_joints(61.0, 70.0, 65.0), words, ERR_JOINT_LIMIT)


def _datasheet_count(pulse_us: float) -> int:
    return round(pulse_us * 4096 * F_UPDATE_HZ / 1e6)


@pytest.mark.parametrize("joints", [(0.0, 70.0, 65.0), (-60.0, 10.0, 5.0), (60.0, 130.0, 125.0),
                                    (12.5, 81.25, 40.0), (-33.3, 55.5, 99.9)])
def test_pwm_counts_match_datasheet(plc: ArmControllerClient,
                                   joints: tuple[float, float, float]) -> None:
    st = plc.move_joints(*joints)
    assert st.error_id == 0
    words = plc.channel_words()
    for ch, (angle, zero) in enumerate(zip(joints, ZERO_DEG, strict=True)):
        pulse_us = 1500.0 + (angle - zero) * 1000.0 / 120.0  # MG996R: 1..2 ms = -60..+60 deg
        assert st.pulses_us[ch] == pytest.approx(pulse_us, abs=1e-3)
        assert words[ch] == _datasheet_count(pulse_us), (ch, pulse_us)
    assert words[3:] == [0x1000] * 13  # unused channels fully off


def test_relax_turns_all_channels_off(plc: ArmControllerClient) -> None:
    plc.move_joints(0.0, 70.0, 65.0)
    st = plc.command(CMD_RELAX)
    assert st.error_id == 0 and st.pulses_us == (0.0, 0.0, 0.0)
    assert plc.channel_words() == [0x1000] * 16


def test_init_pwm_publishes_the_datasheet_sequence(plc: ArmControllerClient) -> None:
    st = plc.init_pwm()
    assert st.error_id == 0 and st.pwm_ready and st.prescale == PRESCALE
    assert st.init_frames == 5
    assert plc.init_frames() == [(0x00, 0x11), (0xFE, PRESCALE), (0x01, 0x04), (0x00, 0x01),
                                 (0x00, 0xA1)]
