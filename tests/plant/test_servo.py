"""MG996R servo model against the figures of document 002 and the MG996R sheet."""

from __future__ import annotations

import pytest

from armbench.plant.servo import MG996R, ServoParams, SignalLoss

DT = 0.001
SPEED_DEG_S = 60.0 / 0.17  # rated 0.17 s per 60 degrees


def run(servo: MG996R, pulse_us: float | None, seconds: float) -> float:
    for _ in range(round(seconds / DT)):
        servo.step(DT, pulse_us)
    return servo.angle_deg


def settle_time(servo: MG996R, pulse_us: float, limit_s: float = 2.0) -> float:
    elapsed = 0.0
    servo.step(DT, pulse_us)
    elapsed += DT
    while servo.moving:
        servo.step(DT, pulse_us)
        elapsed += DT
        assert elapsed < limit_s, "servo never settled"
    return elapsed


@pytest.mark.parametrize(
    ("pulse_us", "angle_deg"),
    [(1000.0, -60.0), (1500.0, 0.0), (2000.0, 60.0), (1250.0, -30.0), (1750.0, 30.0)],
)
def test_pulse_to_angle_map(pulse_us: float, angle_deg: float) -> None:
    servo = MG996R()
    assert run(servo, pulse_us, 0.5) == pytest.approx(angle_deg)
    assert not servo.moving


def test_120_degree_slew_takes_0_34_s() -> None:
    servo = MG996R(initial_angle_deg=-60.0)
    expected_s = 120.0 / SPEED_DEG_S  # = 2 * 0.17 s
    assert expected_s == pytest.approx(0.34)
    assert settle_time(servo, 2000.0) == pytest.approx(expected_s, abs=2 * DT)
    assert servo.angle_deg == 60.0


def test_position_is_linear_in_time_while_slewing() -> None:
    servo = MG996R(initial_angle_deg=-60.0)
    assert run(servo, 2000.0, 0.1) == pytest.approx(-60.0 + SPEED_DEG_S * 0.1)


def test_speed_is_configurable() -> None:
    servo = MG996R(ServoParams(seconds_per_60deg=0.14), initial_angle_deg=-60.0)
    assert settle_time(servo, 2000.0) == pytest.approx(2 * 0.14, abs=2 * DT)


def test_deadband_ignores_small_changes() -> None:
    servo = MG996R()
    run(servo, 1500.0, 0.1)
    run(servo, 1502.0, 0.1)  # 2 us < half of the 5 us band
    assert servo.angle_deg == 0.0
    run(servo, 1504.0, 0.1)  # 4 us > 2.5 us: moves, all the way
    assert servo.angle_deg == pytest.approx(4 * 0.12)


def test_deadband_configurable() -> None:
    servo = MG996R(ServoParams(deadband_width_us=0.0))
    run(servo, 1501.0, 0.1)
    assert servo.angle_deg == pytest.approx(0.12)


def test_target_follows_command_while_moving() -> None:
    servo = MG996R()
    run(servo, 2000.0, 0.05)
    run(servo, 1000.0, 0.5)
    assert servo.angle_deg == pytest.approx(-60.0)


def test_limp_on_missing_or_invalid_pulse() -> None:
    servo = MG996R(initial_angle_deg=-60.0)
    run(servo, 2000.0, 0.1)
    held = servo.angle_deg
    assert servo.torque_on
    for bad in (None, 0.0, 400.0, 2600.0):
        run(servo, bad, 0.1)
        assert servo.angle_deg == held
        assert not servo.torque_on
        assert not servo.moving


def test_hold_keeps_last_command_on_signal_loss() -> None:
    servo = MG996R(ServoParams(signal_loss=SignalLoss.HOLD), initial_angle_deg=-60.0)
    run(servo, 2000.0, 0.1)
    run(servo, None, 0.5)
    assert servo.angle_deg == pytest.approx(60.0)
    assert servo.torque_on


def test_no_torque_before_first_pulse() -> None:
    servo = MG996R()
    assert not servo.torque_on
    servo.step(DT, None)
    assert servo.angle_deg == 0.0


def test_mechanical_limits_clamp_target() -> None:
    servo = MG996R(ServoParams(min_angle_deg=-45.0, max_angle_deg=45.0))
    assert run(servo, 2400.0, 1.0) == 45.0  # asks 108 deg
    assert run(servo, 600.0, 1.0) == -45.0
    with pytest.raises(ValueError, match="mechanical"):
        MG996R(ServoParams(min_angle_deg=-45.0, max_angle_deg=45.0), initial_angle_deg=50.0)


def test_reversed_calibration() -> None:
    params = ServoParams(angle_low_deg=60.0, angle_high_deg=-60.0)
    assert run(MG996R(params), 1000.0, 0.5) == pytest.approx(60.0)


def test_deterministic() -> None:
    pulses = [1000.0, 1500.0, None, 1800.0, 2000.0, 1499.0] * 20
    a, b = MG996R(), MG996R()
    trace_a = [a.step(0.013, p) for p in pulses]
    trace_b = [b.step(0.013, p) for p in pulses]
    assert trace_a == trace_b


def test_bad_arguments() -> None:
    servo = MG996R()
    with pytest.raises(ValueError, match="dt_s"):
        servo.step(-0.1, 1500.0)
    with pytest.raises(ValueError, match="pulse_us"):
        servo.step(0.1, float("nan"))
    with pytest.raises(ValueError, match="calibration"):
        ServoParams(pulse_low_us=1500.0, pulse_high_us=1500.0)
    with pytest.raises(ValueError, match="seconds_per_60deg"):
        ServoParams(seconds_per_60deg=0.0)
