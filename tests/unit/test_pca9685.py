"""st/PCA9685.st against the NXP PCA9685 datasheet.

The expected numbers are written from the datasheet here (register map, MODE1/MODE2 bits,
prescale formula, full-on/full-off bits), not taken from the ST.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

# Datasheet: register addresses
MODE1, MODE2, LED0_ON_L, ALL_LED_ON_L, PRE_SCALE = 0x00, 0x01, 0x06, 0xFA, 0xFE
# Datasheet: MODE1 bits
RESTART, EXTCLK, AI, SLEEP, ALLCALL = 0x80, 0x40, 0x20, 0x10, 0x01
# Datasheet: MODE2 bits
OUTDRV = 0x04
FULL_BIT = 0x10  # bit 4 of LEDn_ON_H / LEDn_OFF_H
DEFAULT_ADDRESS = 0x40
OSC = 25.0e6

NO_ERROR, NOT_FINITE, BAD_FREQUENCY = 0, 3, 7


def datasheet_prescale(freq_hz: float, osc_hz: float) -> tuple[int, bool]:
    """round(osc / (4096 * f)) - 1, rounding halves up, clamped to the hardware 3..255."""
    raw = math.floor(osc_hz / (4096.0 * freq_hz) + 0.5) - 1
    clamped = min(max(raw, 3), 255)
    return clamped, clamped != raw


def test_prescale_vs_datasheet_formula(st_module: Any) -> None:
    checked = 0
    for osc in (25.0e6, 24.5e6, 26.2e6, 27.0e6):
        for freq in (24.0, 30.0, 40.0, 50.0, 60.0, 100.0, 200.0, 333.0, 500.0, 1000.0, 1500.0):
            ratio = osc / (4096.0 * freq)
            if abs(ratio - math.floor(ratio) - 0.5) < 1e-3:
                continue  # a half: float32 and float64 may round differently
            want, clamped = datasheet_prescale(freq, osc)
            got = st_module.call("PCA9685_Prescale", FrequencyHz=freq, OscillatorHz=osc)
            assert got["Prescale"] == want, (osc, freq)
            assert got["Clamped"] == clamped
            assert not got["Error"]
            assert got["ActualHz"] == pytest.approx(osc / (4096.0 * (want + 1)), rel=1e-6)
            checked += 1
    assert checked > 30
    got = st_module.call("PCA9685_Prescale", FrequencyHz=50.0, OscillatorHz=OSC)
    assert got["Prescale"] == 121  # the datasheet's servo example
    assert got["ActualHz"] == pytest.approx(50.03, abs=0.01)


def test_prescale_clamps_to_hardware_range(st_module: Any) -> None:
    for freq, want in ((2000.0, 3), (1e6, 3), (20.0, 255), (1.0, 255), (1e-3, 255)):
        got = st_module.call("PCA9685_Prescale", FrequencyHz=freq, OscillatorHz=OSC)
        assert got["Prescale"] == want and got["Clamped"] and not got["Error"], (freq, got)
    # The hardware limits themselves are not clamped: 1526 Hz -> 3, 24 Hz -> 253.
    got = st_module.call("PCA9685_Prescale", FrequencyHz=1526.0, OscillatorHz=OSC)
    assert got["Prescale"] == 3 and not got["Clamped"]


def test_prescale_bad_inputs(st_module: Any) -> None:
    for freq, osc in (
        (0.0, OSC),
        (-50.0, OSC),
        (math.nan, OSC),
        (math.inf, OSC),
        (50.0, 0.0),
        (50.0, math.nan),
    ):
        got = st_module.call("PCA9685_Prescale", FrequencyHz=freq, OscillatorHz=osc)
        assert got["Error"] and got["ErrorId"] == BAD_FREQUENCY
        assert got["Prescale"] == 0 and got["ActualHz"] == 0.0


def counts(mod: Any, pulse: float, prescale: int = 121, osc: float = OSC, phase: int = 0) -> Any:
    return mod.call(
        "PCA9685_PulseToCounts",
        PulseUs=pulse,
        Prescale=prescale,
        OscillatorHz=osc,
        PhaseCounts=phase,
    )


def test_counts_for_servo_pulses(st_module: Any) -> None:
    tick_us = 122 / OSC * 1e6  # (prescale + 1) / osc = 4.88 us
    for pulse, want in ((1000.0, 205), (1500.0, 307), (2000.0, 410)):
        assert want == math.floor(pulse / tick_us + 0.5)
        got = counts(st_module, pulse)
        assert got["OnCount"] == 0 and got["OffCount"] == want
        assert got["OnWord"] == 0 and got["OffWord"] == want
        assert not got["FullOn"] and not got["FullOff"] and not got["Error"]


def test_counts_with_phase_wrap(st_module: Any) -> None:
    got = counts(st_module, 1500.0, phase=4000)
    assert got["OnCount"] == 4000 and got["OffCount"] == (4000 + 307) % 4096
    got = counts(st_module, 1500.0, phase=4096 + 10)  # taken modulo 4096
    assert got["OnCount"] == 10 and got["OffCount"] == 317


def test_full_on_and_full_off(st_module: Any) -> None:
    period_us = 4096 * 122 / OSC * 1e6
    for pulse in (period_us, period_us + 100.0, 1.0e6):
        got = counts(st_module, pulse)
        assert got["FullOn"] and not got["FullOff"]
        assert got["OnWord"] == FULL_BIT << 8 and got["OffWord"] == 0
    for pulse in (0.0, -5.0, 1.0):  # below half a count
        got = counts(st_module, pulse)
        assert got["FullOff"] and not got["FullOn"]
        assert got["OffWord"] == FULL_BIT << 8 and got["OnWord"] == 0
    got = counts(st_module, math.nan)
    assert got["Error"] and got["ErrorId"] == NOT_FINITE and got["FullOff"]
    got = counts(st_module, 1500.0, osc=0.0)
    assert got["Error"] and got["ErrorId"] == BAD_FREQUENCY and got["FullOff"]
    # One count short of the period is still a real pulse.
    got = counts(st_module, period_us * 4095.0 / 4096.0)
    assert not got["FullOn"] and got["OffCount"] == 4095


def test_led_registers_and_channel_frame(st_module: Any) -> None:
    for ch in range(16):
        assert st_module.call("PCA9685_LedRegister", ch) == LED0_ON_L + 4 * ch
    assert st_module.call("PCA9685_LedRegister", 15) == 0x42
    for bad in (-1, 16, 100):
        assert st_module.call("PCA9685_LedRegister", bad) == 0x00
        frame = st_module.call(
            "PCA9685_ChannelFrame", Address=DEFAULT_ADDRESS, Channel=bad, OnWord=0, OffWord=307
        )
        assert frame["Length"] == 0
    frame = st_module.call(
        "PCA9685_ChannelFrame",
        Address=DEFAULT_ADDRESS,
        Channel=15,
        OnWord=0x0FA0,
        OffWord=(0x0FA0 + 307) % 4096,
    )
    off = (0x0FA0 + 307) % 4096
    assert frame["Address"] == 0x40 and frame["Register"] == 0x42 and frame["Length"] == 4
    assert frame["Data"] == [0xA0, 0x0F, off & 0xFF, off >> 8]
    frame = st_module.call(
        "PCA9685_ChannelFrame", Address=0x41, Channel=0, OnWord=0, OffWord=FULL_BIT << 8
    )
    assert frame["Address"] == 0x41 and frame["Register"] == 0x06
    assert frame["Data"] == [0x00, 0x00, 0x00, FULL_BIT]


def test_all_off_frame(st_module: Any) -> None:
    frame = st_module.call("PCA9685_AllOffFrame", DEFAULT_ADDRESS)
    assert frame["Register"] == ALL_LED_ON_L and frame["Length"] == 4
    assert frame["Data"] == [0x00, 0x00, 0x00, FULL_BIT]


def expected_init_frames(prescale: int) -> list[tuple[int, int, int]]:
    """(register, value, minimum delay after, us) per the datasheet's sleep/restart rules."""
    return [
        (MODE1, SLEEP | ALLCALL, 0),  # oscillator off: PRE_SCALE only writable in sleep
        (PRE_SCALE, prescale, 0),
        (MODE2, OUTDRV, 0),  # totem-pole outputs
        (MODE1, ALLCALL, 500),  # SLEEP cleared: wait >= 500 us for the oscillator
        (MODE1, RESTART | AI | ALLCALL, 0),  # restart PWM, auto-increment for LED writes
    ]


def test_init_frames_byte_for_byte(st_module: Any) -> None:
    for prescale in (121, 3, 255):
        for index, (reg, value, delay) in enumerate(expected_init_frames(prescale), start=1):
            frame = st_module.call(
                "PCA9685_InitFrame", Address=DEFAULT_ADDRESS, Prescale=prescale, Index=index
            )
            assert frame["Address"] == DEFAULT_ADDRESS
            assert frame["Register"] == reg, index
            assert frame["Length"] == 1
            assert frame["Data"][0] == value, index
            assert frame["DelayAfterUs"] >= delay
            assert frame["Data"][0] & EXTCLK == 0 or reg != MODE1
    for index in (0, 6, -1):
        frame = st_module.call(
            "PCA9685_InitFrame", Address=DEFAULT_ADDRESS, Prescale=121, Index=index
        )
        assert frame["Length"] == 0
    # A prescale below the hardware minimum is written as 3.
    frame = st_module.call("PCA9685_InitFrame", Address=DEFAULT_ADDRESS, Prescale=1, Index=2)
    assert frame["Data"][0] == 3


def test_init_block_sequence_and_wake_delay(st_module: Any) -> None:
    fb = st_module.new_fb("PCA9685_Init")
    now_ns = 1_000_000_000
    st_module.set_time(now_ns)
    sent: list[tuple[int, int, int]] = []
    sent_at: list[int] = []
    for _ in range(40):
        fb(Execute=True, Address=DEFAULT_ADDRESS, FrequencyHz=50.0, OscillatorHz=OSC)
        if fb.FrameReady:
            f = fb.get("Frame")
            sent.append((f["Register"], f["Data"][0], f["DelayAfterUs"]))
            sent_at.append(now_ns)
        if fb.Done:
            break
        now_ns += 200_000  # 0.2 ms scans
        st_module.set_time(now_ns)
    assert fb.Done and not fb.Busy and not fb.Error
    assert fb.Prescale == 121
    assert [(r, v) for r, v, _ in sent] == [(r, v) for r, v, _ in expected_init_frames(121)]
    assert sent_at[4] - sent_at[3] >= 500_000  # >= 500 us between wake and RESTART
    # Done stays until Execute falls; a new edge runs the sequence again.
    fb(Execute=True)
    assert fb.Done and not fb.FrameReady
    fb(Execute=False)
    assert not fb.Done
    fb(Execute=True)
    assert fb.Busy and fb.FrameReady


def test_init_block_bad_frequency_sends_nothing(st_module: Any) -> None:
    fb = st_module.new_fb("PCA9685_Init")
    fb(Execute=True, Address=DEFAULT_ADDRESS, FrequencyHz=0.0, OscillatorHz=OSC)
    assert fb.Error and fb.ErrorId == BAD_FREQUENCY and not fb.Busy and not fb.FrameReady
    fb(Execute=True)
    assert not fb.FrameReady


def test_channels_block_words_and_changes(st_module: Any) -> None:
    fb = st_module.new_fb("PCA9685_Channels")
    pulses = [0.0] * 16
    pulses[0], pulses[1], pulses[2], pulses[15] = 1000.0, 1500.0, 2000.0, 30000.0
    fb(PulseUs=pulses, Prescale=121, OscillatorHz=OSC)
    on, off = fb.get("OnWords"), fb.get("OffWords")
    assert off[:3] == [205, 307, 410] and on[:3] == [0, 0, 0]
    assert on[15] == FULL_BIT << 8 and off[15] == 0  # full on
    assert all(off[ch] == FULL_BIT << 8 and on[ch] == 0 for ch in range(3, 15))  # full off
    assert fb.ChangedMask == 0xFFFF and not fb.Error  # first scan: everything is new
    fb(PulseUs=pulses)
    assert fb.ChangedMask == 0
    pulses[1], pulses[9] = 1600.0, math.nan
    fb(PulseUs=pulses)
    assert fb.ChangedMask == (1 << 1)  # channel 9 was full off already
    assert fb.Error and fb.ErrorId == NOT_FINITE
    assert fb.get("OffWords")[9] == FULL_BIT << 8
