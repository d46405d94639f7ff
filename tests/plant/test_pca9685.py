"""PCA9685 model against numbers from the NXP data sheet, computed here from its formulas."""

from __future__ import annotations

import errno

import pytest

from armbench.plant.pca9685 import (
    PCA9685,
    I2CNackError,
    PCA9685Error,
    PCA9685TimingError,
)

ADDR = 0x40
OSC = 25_000_000.0
# Register numbers typed from the data sheet's register summary, not imported from the model.
MODE1, MODE2, PRE_SCALE = 0x00, 0x01, 0xFE
LED0_ON_L = 0x06
ALL_LED_ON_L = 0xFA
AI, SLEEP, RESTART, ALLCALL = 0x20, 0x10, 0x80, 0x01


def led(channel: int) -> int:
    return LED0_ON_L + 4 * channel


def datasheet_prescale(osc_hz: float, rate_hz: float) -> int:
    # Equation 1: prescale value = round(osc_clock / (4096 * update_rate)) - 1
    return round(osc_hz / (4096 * rate_hz)) - 1


def tick_us(osc_hz: float, prescale: int) -> float:
    return (prescale + 1) / osc_hz * 1e6


def running_chip(prescale: int = 121, **kwargs: object) -> PCA9685:
    """Chip brought up the way a driver does it: sleep, prescale, wake, wait, restart|AI."""
    chip = PCA9685(**kwargs)  # type: ignore[arg-type]
    chip.write(ADDR, MODE1, bytes([SLEEP | AI | ALLCALL]))
    chip.write(ADDR, PRE_SCALE, bytes([prescale]))
    chip.write(ADDR, MODE1, bytes([AI | ALLCALL]))
    chip.advance(500e-6)
    chip.write(ADDR, MODE1, bytes([RESTART | AI | ALLCALL]))
    return chip


def set_channel(chip: PCA9685, channel: int, on: int, off: int) -> None:
    chip.write(ADDR, led(channel), bytes([on & 0xFF, on >> 8, off & 0xFF, off >> 8]))


# ------------------------------------------------------------------ power-on state


def test_power_on_register_values() -> None:
    chip = PCA9685()
    regs = chip.read(ADDR, MODE1, 6)
    assert regs == bytes([0x11] * 6)  # without AI every byte comes from the same register
    expected = {0x00: 0x11, 0x01: 0x04, 0x02: 0xE2, 0x03: 0xE4, 0x04: 0xE8, 0x05: 0xE0, 0xFE: 0x1E}
    for register, value in expected.items():
        assert chip.read(ADDR, register) == bytes([value]), hex(register)
    for channel in range(16):
        assert chip.read(ADDR, led(channel) + 1) == b"\x00"  # ON_H: full ON clear
        assert chip.read(ADDR, led(channel) + 3) == b"\x10"  # OFF_H: full OFF set
    assert chip.sleeping
    assert chip.pulse_widths_us() == (0.0,) * 16


def test_power_on_update_rate_is_200_hz_example() -> None:
    # Equation 2 of the data sheet: 200 Hz at 25 MHz gives prescale 30 = 0x1E, the reset value.
    assert datasheet_prescale(OSC, 200.0) == 0x1E
    assert PCA9685().update_rate_hz == pytest.approx(OSC / (4096 * 31))


# ------------------------------------------------------------------ frequency and pulses


def test_50_hz_prescale_and_servo_pulses() -> None:
    prescale = datasheet_prescale(OSC, 50.0)
    assert prescale == 121
    chip = running_chip(prescale)
    assert chip.prescale == 121
    assert chip.update_rate_hz == pytest.approx(OSC / (4096 * 122))  # 50.03 Hz
    assert chip.period_us == pytest.approx(4096 * 122 / OSC * 1e6)
    tick = tick_us(OSC, prescale)  # 4.88 us
    for channel, (count, nominal_us) in enumerate([(205, 1000), (307, 1500), (410, 2000)]):
        set_channel(chip, channel, 0, count)
        assert chip.pulse_width_us(channel) == pytest.approx(count * tick)
        assert chip.pulse_width_us(channel) == pytest.approx(nominal_us, abs=tick)
        assert chip.duty(channel) == pytest.approx(count / 4096)


def test_oscillator_trim_scales_frequency_and_pulse() -> None:
    chip = running_chip(121, osc_hz=26_000_000.0)
    set_channel(chip, 0, 0, 307)
    assert chip.update_rate_hz == pytest.approx(26e6 / (4096 * 122))
    assert chip.pulse_width_us(0) == pytest.approx(307 * 122 / 26e6 * 1e6)


def test_on_after_off_wraps_around_period() -> None:
    chip = running_chip()
    set_channel(chip, 3, 4000, 200)  # high from 4000..4095 and 0..199
    assert chip.channel(3).high_counts == 4096 - 4000 + 200
    set_channel(chip, 4, 100, 100)  # ON == OFF is forbidden; the output stays low
    assert chip.pulse_width_us(4) == 0.0


def test_full_on_full_off_and_precedence() -> None:
    chip = running_chip()
    set_channel(chip, 0, 0x1000, 1234)  # full ON: OFF count ignored
    assert chip.duty(0) == 1.0
    assert chip.pulse_width_us(0) == pytest.approx(chip.period_us)
    set_channel(chip, 1, 0, 0x1000 | 307)  # full OFF: counts ignored
    assert chip.duty(1) == 0.0
    set_channel(chip, 2, 0x1000, 0x1000)  # both set: full OFF wins
    assert chip.duty(2) == 0.0


def test_reserved_bits_of_h_registers_read_zero() -> None:
    chip = running_chip()
    chip.write(ADDR, led(5), bytes([0xFF, 0xFF, 0xFF, 0xFF]))
    assert chip.read(ADDR, led(5), 4) == bytes([0xFF, 0x1F, 0xFF, 0x1F])


def test_invrt_inverts_running_output() -> None:
    chip = running_chip()
    set_channel(chip, 0, 0, 307)
    chip.write(ADDR, MODE2, bytes([0x04 | 0x10]))
    assert chip.channel(0).high_counts == 4096 - 307


# ------------------------------------------------------------------ auto-increment


def test_auto_increment_frame_fills_one_channel() -> None:
    chip = running_chip()
    chip.write(ADDR, led(7), bytes([0x11, 0x02, 0x33, 0x04]))
    assert chip.read(ADDR, led(7), 4) == bytes([0x11, 0x02, 0x33, 0x04])


def test_without_auto_increment_all_bytes_land_in_first_register() -> None:
    chip = PCA9685()  # power-on: AI = 0
    chip.write(ADDR, led(0), bytes([0x11, 0x22, 0x33, 0x44]))
    assert chip.read(ADDR, led(0)) == b"\x44"  # the pointer never moved: last byte wins
    assert chip.read(ADDR, led(0) + 1) == b"\x00"
    assert chip.read(ADDR, led(0) + 2) == b"\x00"
    assert chip.read(ADDR, led(0) + 3) == b"\x10"


def test_ai_set_by_first_byte_applies_to_rest_of_frame() -> None:
    # Data sheet Fig 21: control register = MODE1 with AI initially clear, first data byte
    # sets AI, then MODE2, SUBADR1.. follow in the same frame.
    chip = PCA9685()
    chip.write(ADDR, MODE1, bytes([SLEEP | AI | ALLCALL, 0x14, 0xC2]))
    assert chip.read(ADDR, MODE1, 3) == bytes([SLEEP | AI | ALLCALL, 0x14, 0xC2])


def test_auto_increment_wraps_from_led15_to_mode1() -> None:
    chip = running_chip()
    mode1 = AI | ALLCALL | 0x08  # also enable SUB1 so the write is visible
    chip.write(ADDR, 0x44, bytes([0x34, 0x01, mode1]))
    assert chip.read(ADDR, 0x44, 2) == bytes([0x34, 0x01])
    assert chip.read(ADDR, MODE1) == bytes([mode1])


def test_auto_increment_all_led_then_prescale_then_mode1() -> None:
    chip = PCA9685()
    chip.write(ADDR, MODE1, bytes([SLEEP | AI]))
    # 0xFA..0xFD, PRE_SCALE (asleep, so accepted), then rolls over to MODE1
    chip.write(ADDR, ALL_LED_ON_L, bytes([0, 0, 0x33, 0x01, 121, SLEEP | AI | ALLCALL]))
    assert chip.prescale == 121
    assert chip.read(ADDR, MODE1) == bytes([SLEEP | AI | ALLCALL])
    assert chip.read(ADDR, led(15) + 2, 2) == bytes([0x33, 0x01])


def test_read_auto_increment_wraps() -> None:
    chip = running_chip()
    data = chip.read(ADDR, 0x45, 2)
    assert data == bytes([0x10, AI | ALLCALL])


# ------------------------------------------------------------------ ALL_LED


def test_all_led_registers_load_every_channel_and_read_zero() -> None:
    chip = running_chip()
    chip.write(ADDR, ALL_LED_ON_L, bytes([0x00, 0x00, 307 & 0xFF, 307 >> 8]))
    tick = tick_us(OSC, 121)
    assert chip.pulse_widths_us() == pytest.approx((307 * tick,) * 16)
    assert chip.read(ADDR, ALL_LED_ON_L, 4) == bytes(4)


def test_all_led_off_h_turns_everything_off() -> None:
    chip = running_chip()
    chip.write(ADDR, ALL_LED_ON_L, bytes([0, 0, 100, 1]))
    chip.write(ADDR, 0xFD, bytes([0x10]))  # data sheet Fig 24
    assert chip.pulse_widths_us() == (0.0,) * 16


# ------------------------------------------------------------------ sleep, prescale, restart


def test_prescale_ignored_while_awake() -> None:
    chip = running_chip(121)
    chip.write(ADDR, PRE_SCALE, bytes([30]))
    assert chip.prescale == 121


def test_prescale_minimum_is_three() -> None:
    chip = PCA9685()  # asleep at power-on
    chip.write(ADDR, PRE_SCALE, bytes([1]))
    assert chip.prescale == 3
    assert chip.update_rate_hz == pytest.approx(OSC / (4096 * 4))  # 1526 Hz maximum


def test_outputs_zero_while_sleeping_and_registers_kept() -> None:
    chip = running_chip()
    set_channel(chip, 0, 0, 307)
    chip.write(ADDR, MODE1, bytes([SLEEP | AI | ALLCALL]))
    assert chip.pulse_width_us(0) == 0.0
    assert chip.read(ADDR, led(0), 4) == bytes([0, 0, 307 & 0xFF, 307 >> 8])


def test_sleep_with_active_channel_sets_restart_and_halts_until_restart() -> None:
    chip = running_chip()
    set_channel(chip, 0, 0, 307)
    chip.write(ADDR, MODE1, bytes([SLEEP | AI | ALLCALL]))
    assert chip.read(ADDR, MODE1)[0] & RESTART
    chip.write(ADDR, MODE1, bytes([AI | ALLCALL]))  # wake
    assert chip.read(ADDR, MODE1)[0] & RESTART
    assert chip.pulse_width_us(0) == 0.0  # halted until restarted
    chip.advance(500e-6)
    chip.write(ADDR, MODE1, bytes([RESTART | AI | ALLCALL]))  # writing 1 clears it
    assert not chip.read(ADDR, MODE1)[0] & RESTART
    assert chip.pulse_width_us(0) == pytest.approx(307 * tick_us(OSC, 121))


def test_sleep_after_orderly_shutdown_does_not_set_restart() -> None:
    chip = running_chip()
    set_channel(chip, 0, 0, 307)
    chip.write(ADDR, 0xFD, bytes([0x10]))
    chip.write(ADDR, MODE1, bytes([SLEEP | AI | ALLCALL]))
    assert not chip.read(ADDR, MODE1)[0] & RESTART


def test_restart_before_500_us_raises_in_strict_mode() -> None:
    chip = running_chip()
    set_channel(chip, 0, 0, 307)
    chip.write(ADDR, MODE1, bytes([SLEEP | AI]))
    chip.write(ADDR, MODE1, bytes([AI]))
    chip.advance(100e-6)
    with pytest.raises(PCA9685TimingError, match="500 us"):
        chip.write(ADDR, MODE1, bytes([RESTART | AI]))


def test_restart_before_500_us_accepted_when_not_strict() -> None:
    chip = running_chip(strict_timing=False)
    set_channel(chip, 0, 0, 307)
    chip.write(ADDR, MODE1, bytes([SLEEP | AI]))
    chip.write(ADDR, MODE1, bytes([RESTART | AI]))
    assert chip.running


def test_pwm_write_clears_restart_when_och_is_stop() -> None:
    chip = running_chip()
    set_channel(chip, 0, 0, 307)
    chip.write(ADDR, MODE1, bytes([SLEEP | AI]))
    chip.write(ADDR, MODE1, bytes([AI]))
    chip.write(ADDR, led(1) + 2, bytes([0x10]))  # one PWM byte, then STOP
    assert chip.running
    assert chip.pulse_width_us(0) > 0


def test_och_ack_needs_all_four_registers_to_clear_restart() -> None:
    chip = running_chip()
    chip.write(ADDR, MODE2, bytes([0x04 | 0x08]))  # OCH = 1
    set_channel(chip, 0, 0, 307)
    chip.write(ADDR, MODE1, bytes([SLEEP | AI]))
    chip.write(ADDR, MODE1, bytes([AI]))
    chip.write(ADDR, led(0) + 2, bytes([0x33, 0x01]))  # two of four registers
    assert chip.restart_pending
    set_channel(chip, 0, 0, 307)  # all four
    assert not chip.restart_pending


# ------------------------------------------------------------------ addressing


def test_wrong_address_is_nacked_as_oserror_121() -> None:
    chip = PCA9685(address=0x41)
    with pytest.raises(I2CNackError, match="0x40") as info:
        chip.write(0x40, MODE1, b"\x00")
    assert isinstance(info.value, OSError)
    assert info.value.errno == errno.EREMOTEIO
    with pytest.raises(I2CNackError):
        chip.read(0x40, MODE1)


def test_reserved_register_is_nacked() -> None:
    with pytest.raises(I2CNackError, match="reserved"):
        PCA9685().write(ADDR, 0x46, b"\x00")


def test_all_call_and_sub_addresses() -> None:
    chip = PCA9685()
    chip.write(0x70, PRE_SCALE, bytes([121]))  # ALLCALL on at power-on, 0xE0 >> 1
    assert chip.prescale == 121
    with pytest.raises(I2CNackError):
        chip.write(0x71, MODE1, b"\x00")  # SUB1 disabled at power-on
    chip.write(ADDR, MODE1, bytes([SLEEP | 0x08]))  # SUB1 on, ALLCALL off
    chip.write(0x71, PRE_SCALE, bytes([50]))
    assert chip.prescale == 50
    with pytest.raises(I2CNackError):
        chip.write(0x70, MODE1, b"\x00")
    with pytest.raises(I2CNackError, match="read"):
        chip.read(0x71, MODE1)


def test_software_reset_restores_power_on_values() -> None:
    chip = running_chip()
    set_channel(chip, 0, 0, 307)
    chip.write(0x00, 0x06)
    assert chip.read(ADDR, MODE1) == b"\x11"
    assert chip.prescale == 0x1E
    assert chip.pulse_width_us(0) == 0.0
    with pytest.raises(I2CNackError):
        chip.write(0x00, 0x05)


# ------------------------------------------------------------------ EXTCLK, test mode, args


def test_extclk_is_sticky_and_used() -> None:
    chip = PCA9685(extclk_hz=20e6)
    chip.write(ADDR, MODE1, bytes([SLEEP | 0x40]))
    chip.write(ADDR, MODE1, bytes([SLEEP]))  # writing 0 does not clear EXTCLK
    assert chip.read(ADDR, MODE1)[0] & 0x40
    assert chip.update_rate_hz == pytest.approx(20e6 / (4096 * 31))
    no_clock = PCA9685()
    no_clock.write(ADDR, MODE1, bytes([SLEEP | 0x40]))
    with pytest.raises(PCA9685Error, match="extclk_hz"):
        _ = no_clock.update_rate_hz


def test_extclk_ignored_when_awake() -> None:
    chip = running_chip()
    chip.write(ADDR, MODE1, bytes([0x40 | AI]))
    assert not chip.read(ADDR, MODE1)[0] & 0x40


def test_testmode_write_refused() -> None:
    with pytest.raises(PCA9685Error, match="TestMode"):
        PCA9685().write(ADDR, 0xFF, b"\x00")


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="0x40..0x7F"):
        PCA9685(address=0x20)
    with pytest.raises(ValueError, match="osc_hz"):
        PCA9685(osc_hz=0.0)
    chip = PCA9685()
    with pytest.raises(ValueError, match="channel"):
        chip.pulse_width_us(16)
    with pytest.raises(ValueError, match="register"):
        chip.write(ADDR, 0x100, b"")
    with pytest.raises(ValueError, match="bytes"):
        chip.write(ADDR, MODE1, [1, 2])  # type: ignore[arg-type]


# ------------------------------------------------------------------ OpenPLC word interface


def test_load_off_counts_matches_i2c_writes() -> None:
    chip = running_chip()
    words = [205, 307, 410] + [0x1000] * 13
    chip.load_off_counts(words)
    tick = tick_us(OSC, 121)
    widths = chip.pulse_widths_us()
    assert widths[:3] == pytest.approx((205 * tick, 307 * tick, 410 * tick))
    assert widths[3:] == (0.0,) * 13
    with pytest.raises(ValueError, match="16"):
        chip.load_off_counts([0] * 15)
    with pytest.raises(ValueError, match="channel 2"):
        chip.load_off_counts([0, 0, 0x2000] + [0] * 13)
