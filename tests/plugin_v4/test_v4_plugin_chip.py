"""The v4 plugin's loops, stepped by hand against the stand-in runtime args and the chip
models on a simulated bus: the PCA9685 initialisation and prescale, the register bytes of
the controller's words, the relaxed state, the IMU words, and every fault with its one log
line, its safe outputs and its recovery (conftest's ``rig``)."""

from __future__ import annotations

import random
from typing import Any

import pytest
from v4_rig import ADDR, PRESCALE, Rig

from armbench.plant.pca9685 import PCA9685

OSC = 25_000_000.0
FULL_OFF = (0x00, 0x00, 0x00, 0x10)


def tick_us(prescale: int = PRESCALE) -> float:
    """One PCA9685 count: (PRE_SCALE + 1) / 25 MHz (data sheet, Equation 1)."""
    return (prescale + 1) / OSC * 1e6


def regs(chip: PCA9685, ch: int) -> tuple[int, ...]:
    base = 0x06 + 4 * ch
    return tuple(chip.registers[base:base + 4])


def started(rig: Rig, **overrides: Any) -> Any:
    """A plugin that has run a few periods with the controller's words all off."""
    plugin = rig.plugin(**overrides)
    rig.step(plugin, 3)
    assert rig.flags() == (True, False), rig.shown()
    return plugin


def mode_frames(rig: Rig) -> list[tuple[int, int]]:
    return [(reg, data[0]) for reg, data in rig.bus.writes_to(ADDR) if reg in (0x00, 0x01, 0xFE)]


def sleep_frames(rig: Rig) -> int:
    """Initialisations tried: the MODE1 writes that put the chip to sleep."""
    return sum(1 for reg, data in rig.bus.writes_to(ADDR) if reg == 0x00 and data[0] & 0x10)


# ------------------------------------------------------------------ initialisation and prescale

def test_init_sequence_with_the_controllers_prescale(rig: Rig) -> None:
    started(rig)
    assert mode_frames(rig) == [
        (0x00, 0x31),  # SLEEP | AI | ALLCALL: PRE_SCALE is writable only asleep
        (0x01, 0x04),  # OUTDRV
        (0xFE, PRESCALE),
        (0x00, 0x21),  # awake
        (0x00, 0xA1),  # RESTART | AI | ALLCALL, after the oscillator's 500 us
    ]
    times = [t for t, a, reg, data in rig.bus.log if a == ADDR and reg == 0x00]
    assert times[2] - times[1] >= 500e-6 - 1e-9
    assert rig.chip.prescale == PRESCALE and rig.chip.running
    assert rig.chip.update_rate_hz == pytest.approx(50.0, abs=0.1)
    assert all(line.startswith("[ARM_IO] IMU ready") for line in rig.shown()), rig.shown()


def test_a_new_prescale_from_the_controller_reinitialises(rig: Rig) -> None:
    plugin = started(rig)
    rig.runtime.set("%MD14", 30)  # 200 Hz
    rig.step(plugin, 2)
    assert mode_frames(rig)[-5:] == [(0x00, 0x31), (0x01, 0x04), (0xFE, 30), (0x00, 0x21),
                                     (0x00, 0xA1)]
    assert rig.chip.prescale == 30 and rig.chip.running
    assert rig.chip.update_rate_hz == pytest.approx(OSC / (4096 * 31))


def test_no_initialisation_before_the_controller_publishes_its_prescale(rig: Rig) -> None:
    rig.runtime.set("%MD14", 0)  # the program has not scanned yet
    plugin = rig.plugin(imu_enabled=False)
    rig.step(plugin, 300)  # 1.5 s
    assert rig.bus.writes_to(ADDR) == [] and rig.shown() == []
    rig.step(plugin, 120)  # past 2 s: said once, at warning level
    said = rig.shown()
    assert len(said) == 1 and "PwmPrescale (%MD14): 0" in said[0], said
    rig.runtime.set("%MD14", PRESCALE)
    rig.step(plugin, 2)
    assert rig.chip.prescale == PRESCALE and rig.chip.running
    assert rig.flags() == (True, False)
    assert rig.shown()[-1] == "[ARM_IO] PwmPrescale (%MD14) is 121"


def test_prescale_from_the_settings_when_the_program_publishes_none(rig: Rig) -> None:
    rig.runtime.set("%MD14", 0)
    plugin = started(rig, prescale_from=None, pwm_frequency_hz=200.0)
    del plugin
    assert rig.chip.prescale == round(OSC / (4096 * 200.0)) - 1 == 30


# ------------------------------------------------------------------ words to registers

ON_WORDS = (1, 2, 204, 205, 255, 256, 307, 410, 511, 512, 2048, 4094, 4095)


def test_words_across_the_range_become_the_led_registers(rig: Rig) -> None:
    plugin = started(rig)
    rig.words(**{f"ch{ch}": w for ch, w in enumerate(ON_WORDS)})
    rig.step(plugin)
    for ch, w in enumerate(ON_WORDS):
        # LEDn_ON = 0, LEDn_OFF = the word: ON_L, ON_H, OFF_L, OFF_H
        assert regs(rig.chip, ch) == (0x00, 0x00, w & 0xFF, w >> 8), (ch, w)
        assert rig.chip.pulse_width_us(ch) == pytest.approx(w * tick_us())
    assert rig.chip.pulse_width_us(6) == pytest.approx(1498.16, abs=0.01)  # 307: 1.5 ms


@pytest.mark.parametrize("word", [0, 0x1000, 0x1000 | 307, 0x1000 | 0x0FFF])
def test_off_words_are_full_off(rig: Rig, word: int) -> None:
    plugin = started(rig)
    rig.words(ch3=307)
    rig.step(plugin)
    assert rig.chip.pulse_width_us(3) > 0
    rig.words(ch3=word)
    rig.step(plugin)
    assert regs(rig.chip, 3) == FULL_OFF  # bit 12 of OFF_H: never the forbidden ON == OFF
    assert rig.chip.pulse_width_us(3) == 0.0 and rig.chip.channel(3).full_off
    assert rig.flags() == (True, False)


def test_only_changed_channels_are_written(rig: Rig) -> None:
    plugin = started(rig)
    rig.words(ch0=300, ch1=301, ch2=302)
    rig.step(plugin)
    before = len(rig.bus.writes_to(ADDR))
    rig.step(plugin, 5)
    assert len(rig.bus.writes_to(ADDR)) == before  # nothing changed, nothing written
    rig.words(ch1=320)
    rig.step(plugin)
    assert rig.bus.writes_to(ADDR)[before:] == [(0x06 + 4, bytes([0, 0, 320 & 0xFF, 1]))]
    rig.words(ch4=330, ch5=331, ch9=332)
    rig.step(plugin)
    assert [(reg, len(d)) for reg, d in rig.bus.writes_to(ADDR)[before + 1:]] == [
        (0x06 + 16, 8), (0x06 + 36, 4)]  # neighbours in one block write


# ------------------------------------------------------------------ relaxed

def test_relax_makes_the_servos_limp(rig: Rig) -> None:
    plugin = started(rig)
    rig.words(ch0=307, ch1=350, ch2=280)
    rig.step(plugin)
    assert all(p > 0 for p in rig.chip.pulse_widths_us()[:3])
    rig.words(ch0=0x1000, ch1=0x1000, ch2=0x1000)  # the controller's Relax
    rig.step(plugin)
    assert rig.chip.pulse_widths_us() == (0.0,) * 16
    assert [regs(rig.chip, ch) for ch in range(3)] == [FULL_OFF] * 3


def test_stop_keeps_the_pose_unless_relax_on_stop(rig: Rig) -> None:
    plugin = started(rig)
    rig.words(ch0=307)
    rig.step(plugin)
    assert plugin.stop() is True
    assert rig.chip.pulse_width_us(0) == pytest.approx(307 * tick_us())  # the arm holds
    assert rig.bus.opened == rig.bus.closed == 2  # both loops' handles closed


def test_relax_on_stop(rig: Rig) -> None:
    plugin = started(rig, relax_on_stop=True)
    rig.words(ch0=307, ch1=410)
    rig.step(plugin)
    assert plugin.stop() is True
    assert rig.bus.writes_to(ADDR)[-1] == (0xFD, bytes([0x10]))  # ALL_LED_OFF_H full OFF
    assert rig.chip.pulse_widths_us() == (0.0,) * 16
    assert rig.shown()[-1] == "[ARM_IO] servos relaxed on stop (relax_on_stop)"


def test_a_servo_powered_before_the_start_stays_relaxed_until_the_controller_relaxes(
        rig: Rig) -> None:
    rig.words(ch0=307)  # not the controller at power-up: a pulse the plugin never saw reached
    plugin = rig.plugin()
    rig.step(plugin, 3)
    assert rig.chip.pulse_width_us(0) == 0.0
    assert rig.flags() == (True, True)  # ready, and the fault says a servo is held
    rig.words(ch0=0x1000)
    rig.step(plugin)
    assert rig.flags() == (True, False)
    rig.words(ch0=307)
    rig.step(plugin)
    assert rig.chip.pulse_width_us(0) == pytest.approx(307 * tick_us())


# ------------------------------------------------------------------ the IMU

def test_imu_samples_reach_the_input_words_whole(rig: Rig) -> None:
    rig.runtime.scan_between_writes = True  # a scan wherever a writer lets one in
    plugin = started(rig)
    samples = [([3, -2, 1], [120, -80, 16384], [300, -40, -520]),
               ([-32768, 32767, 0], [-16384, 0, 1], [-4096, 2047, -2048])]
    seq = rig.runtime.get("%IW9")
    for k, (gyro, accel, mag) in enumerate(samples, start=1):
        rig.board.load(gyro, accel, mag)
        rig.step(plugin, 4)  # 20 ms: one sample
        want = [v & 0xFFFF for v in (*gyro, *accel, *mag)]
        assert [rig.runtime.get(f"%IW{i}") for i in range(9)] == want
        assert rig.runtime.get("%IW9") == (seq + k) & 0xFFFF
    int_input = 5  # journal type JOURNAL_INT_INPUT
    for drain in rig.runtime.drains:
        words = sorted(i for t, i, _b, _v in drain if t == int_input)
        assert words in ([], list(range(10))), f"a scan took half a sample: {words}"


def test_no_imu_wired_is_one_line_and_the_servos_carry_on(rig: Rig) -> None:
    rig.bus.imu = None
    plugin = started(rig)
    rig.words(ch0=307)
    rig.step(plugin, 1000)  # 5 s: the IMU is tried again every 2 s
    imu_lines = [line for line in rig.shown() if "IMU" in line]
    assert len(imu_lines) == 1 and "imu_enabled false" in imu_lines[0], imu_lines
    assert rig.chip.pulse_width_us(0) == pytest.approx(307 * tick_us())
    reads = [e for e in rig.bus.log if e[1] == 0x68]
    assert 2 <= len(reads) <= 4  # at start, then once per imu_retry_s


# ------------------------------------------------------------------ faults

def test_missing_bus_is_one_line_bounded_retries_and_recovery(rig: Rig) -> None:
    smbus2 = rig.loaded.smbus2
    bus = smbus2.BUSES.pop(1)
    plugin = rig.plugin()
    rig.step(plugin, 1000)  # 5 s
    said = rig.shown()
    assert said == ["[ARM_IO] I2C bus /dev/i2c-1: not found; enable I2C (sudo raspi-config "
                    "nonint do_i2c 0) and reboot, or set i2c_bus in arm_io.json; servos stay "
                    "relaxed, retrying every 1 s"], said
    assert len(smbus2.ATTEMPTS) <= 5 + 3  # the PWM loop each 1 s, the IMU loop each 2 s
    assert rig.flags() == (False, True)
    assert rig.runtime.format_faults == []
    smbus2.BUSES[1] = bus
    rig.words(ch0=307)
    rig.step(plugin, 200)  # within retry_s
    assert rig.shown()[1] == "[ARM_IO] I2C bus /dev/i2c-1 open"
    assert rig.flags() == (True, True) and rig.chip.running
    assert rig.chip.pulse_width_us(0) == 0.0  # held: the controller has not relaxed it
    rig.words(ch0=0x1000)
    rig.step(plugin)
    rig.words(ch0=307)
    rig.step(plugin)
    assert rig.flags() == (True, False)
    assert rig.chip.pulse_width_us(0) == pytest.approx(307 * tick_us())


def test_missing_chip_is_one_line_bounded_retries_and_recovery(rig: Rig) -> None:
    rig.bus.pca = PCA9685(address=0x41)  # jumpers on the wrong address
    plugin = rig.plugin(imu_enabled=False)
    rig.step(plugin, 1000)  # 5 s
    said = rig.shown()
    assert len(said) == 1, said
    assert said[0].startswith("[ARM_IO] PCA9685 at 0x40 on I2C: ") and \
        "retrying every 1 s" in said[0] and "Relax, code 4" in said[0], said
    assert sleep_frames(rig) <= 6  # one initialisation tried per retry_s
    assert rig.flags() == (False, True)
    rig.bus.pca = rig.chip  # the right board plugged in
    rig.step(plugin, 200)
    assert rig.shown()[1].startswith("[ARM_IO] PCA9685 at 0x40 answers again")
    assert rig.flags() == (True, False) and rig.chip.running


def test_i2c_error_mid_run_relaxes_holds_and_recovers(rig: Rig) -> None:
    plugin = started(rig)
    rig.words(ch0=307, ch1=350, ch2=280)
    rig.step(plugin)
    rig.bus.down = True  # a loose wire: every transfer fails
    rig.words(ch0=310)
    rig.step(plugin, 400)  # 2 s of failures
    assert rig.flags() == (False, True)
    # the chip could not be told: it keeps its outputs, and is relaxed at its re-init
    rig.bus.down = False
    rig.step(plugin, 200)
    assert rig.chip.running and rig.chip.pulse_widths_us() == (0.0,) * 16
    assert rig.flags() == (True, True)  # chip back, servos held relaxed
    pwm_lines = [line for line in rig.shown() if "PCA9685" in line]
    assert len(pwm_lines) == 2 and "answers again" in pwm_lines[1], "\n".join(rig.shown())
    rig.words(ch0=0x1000, ch1=0x1000)  # the controller relaxes two of the three
    rig.step(plugin)
    assert rig.flags() == (True, True)  # channel 2 still held
    rig.words(ch2=0x1000)
    rig.step(plugin)
    assert rig.flags() == (True, False)
    rig.words(ch0=310, ch1=350, ch2=280)
    rig.step(plugin)
    assert rig.chip.pulse_widths_us()[:3] == pytest.approx(
        (310 * tick_us(), 350 * tick_us(), 280 * tick_us()))


@pytest.mark.parametrize("fault", ["bus", "power"])
def test_a_fault_at_rest_is_seen_within_retry_s(rig: Rig, fault: str) -> None:
    """Nothing to write at rest: the read-back of MODE1 finds a dead bus, or a board that lost
    power (it wakes asleep: the servos limp, and words written to it would give no pulse)."""
    plugin = started(rig, imu_enabled=False)
    rig.words(ch0=307)
    rig.step(plugin)
    if fault == "bus":
        rig.bus.down = True
    else:
        rig.chip.power_on_reset()
    for _ in range(201):  # within retry_s and one period
        rig.step(plugin)
        if rig.shown():
            break
    else:
        pytest.fail("the fault at rest went unseen for retry_s")
    assert rig.flags() == (False, True)  # from the step that saw it
    said = [line for line in rig.shown() if "PCA9685" in line]
    assert len(said) == 1, said
    assert ("Remote I/O error" if fault == "bus" else "was reset (MODE1 reads 0x11") in said[0]
    rig.bus.down = False
    rig.step(plugin, 220)
    assert rig.chip.running and rig.chip.pulse_widths_us() == (0.0,) * 16
    assert rig.flags() == (True, True)  # held until the controller relaxes channel 0
    rig.words(ch0=0x1000)
    rig.step(plugin)
    rig.words(ch0=307)
    rig.step(plugin)
    assert rig.flags() == (True, False)
    assert rig.chip.pulse_width_us(0) == pytest.approx(307 * tick_us())


def test_a_failed_transfer_relaxes_at_once_when_the_chip_still_listens(rig: Rig) -> None:
    plugin = started(rig)
    rig.words(ch0=307, ch1=350)
    rig.step(plugin)
    rig.bus.fail_next = 1  # one transfer lost; the chip itself answers
    rig.words(ch0=310)
    rig.step(plugin)
    assert rig.chip.pulse_widths_us() == (0.0,) * 16
    assert rig.bus.writes_to(ADDR)[-1] == (0xFD, bytes([0x10]))
    rig.step(plugin, 220)  # past retry_s
    assert rig.flags() == (True, True) and rig.chip.pulse_widths_us() == (0.0,) * 16


def test_an_unexpected_error_is_contained(rig: Rig, monkeypatch: pytest.MonkeyPatch) -> None:
    plugin = started(rig)
    rig.words(ch0=307)
    rig.step(plugin)

    def broken(*_args: object) -> None:
        raise RuntimeError("driver bug")

    monkeypatch.setattr(rig.bus, "write", broken)
    rig.words(ch0=310)
    rig.step(plugin, 400)  # nothing escapes step()
    loop_lines = [line for line in rig.shown() if "unexpected" in line]
    assert len(loop_lines) == 1 and "RuntimeError('driver bug')" in loop_lines[0]
    assert rig.flags() == (False, True)
    monkeypatch.undo()
    rig.step(plugin, 220)
    assert rig.chip.pulse_widths_us() == (0.0,) * 16 and rig.flags() == (True, True)
    assert rig.shown()[-1] == "[ARM_IO] PWM loop runs again"


def test_an_invalid_word_is_logged_with_its_percent_sign_intact(rig: Rig) -> None:
    plugin = started(rig)
    rig.words(ch0=307, ch1=0x2000)
    rig.step(plugin, 10)
    said = [line for line in rig.shown() if "invalid" in line]
    assert len(said) == 1 and "%QW1" in said[0], rig.shown()
    assert rig.runtime.format_faults == []  # every "%" reached log.c doubled
    assert rig.chip.pulse_width_us(1) == 0.0 and rig.flags() == (True, True)
    assert rig.chip.pulse_width_us(0) == pytest.approx(307 * tick_us())


@pytest.mark.parametrize("seed", range(6))
def test_the_chip_carries_the_controllers_words_or_nothing(rig: Rig, seed: int) -> None:
    """Random words and random faults. Whenever a channel's pulse changes on the chip, it
    changes to the controller's present word or to no pulse, and after a fault it changes to
    a pulse only once the controller's word for it has been full OFF; between a fault and the
    re-initialisation that relaxes it, the chip may keep a pulse written before (it cannot be
    reached), never one the controller did not compute."""
    rng = random.Random(seed)
    rig.bus.imu = None
    plugin = started(rig, imu_enabled=False, retry_s=0.1)
    words = [0x1000] * 4
    seen: list[set[int]] = [set() for _ in range(4)]
    armed = [True] * 4
    before = [regs(rig.chip, ch) for ch in range(4)]
    changes = 0
    for _ in range(2000):
        if rng.random() < 0.3:
            ch = rng.randrange(4)
            words[ch] = rng.choice([0x1000, 0, rng.randrange(1, 4096)])
            rig.words(**{f"ch{ch}": words[ch]})
        fault = rng.random() < 0.01
        if fault:
            if rng.random() < 0.5:
                rig.bus.fail_next = 1
            else:
                rig.bus.down = True
        elif rig.bus.down and rng.random() < 0.2:
            rig.bus.down = False
        failures = rig.bus.failures
        rig.step(plugin)
        if rig.bus.failures != failures:  # a transfer failed: the plugin saw a fault
            armed = [False] * 4
        for ch in range(4):
            seen[ch].add(words[ch] & 0x0FFF)
            if words[ch] == 0 or words[ch] & 0x1000:
                armed[ch] = True
            now = regs(rig.chip, ch)
            count = now[2] | (now[3] & 0x0F) << 8
            off = bool(now[3] & 0x10) or count == 0
            assert off or count in seen[ch], f"channel {ch}: {count} never computed"
            if now != before[ch] and not off:
                changes += 1
                assert count == words[ch] & 0x0FFF, f"channel {ch}: not the present word"
                assert armed[ch], f"channel {ch} powered after a fault before a relax"
            before[ch] = now
    assert changes > 100 and rig.runtime.format_faults == []
