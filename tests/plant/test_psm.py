"""The OpenPLC PSM PCA9685 driver, run against the simulated PCA9685."""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from typing import Any

import pytest

from armbench.plant.pca9685 import PCA9685, I2CNackError
from psm_script import SimBus, load_psm_script

OSC = 25_000_000.0
ADDR = 0x40




psm_mod = load_psm_script("arm_io_psm")


@dataclass
class FakePlc:
    """Stands in for OpenPLC's psm module: located variables in a dict."""

    values: dict[str, object] = field(default_factory=dict)

    def get_var(self, name: str) -> object:
        return self.values.get(name, 0)

    def set_var(self, name: str, value: object) -> None:
        self.values[name] = value


def make(
    address: int = ADDR, chip: PCA9685 | None = None, **kwargs: object
) -> tuple[PCA9685, SimBus, FakePlc, Any]:
    chip = chip or PCA9685(address=address)
    bus = SimBus(chip)
    plc = FakePlc()
    driver = psm_mod.PCA9685Driver(
        bus=bus, plc=plc, address=address, sleep=chip.advance, log=lambda _m: None, **kwargs
    )
    return chip, bus, plc, driver


def set_counts(plc: FakePlc, counts: dict[int, int]) -> None:
    for channel, count in counts.items():
        plc.values[f"QW{channel}"] = count


def tick_us() -> float:
    prescale = round(OSC / (4096 * 50.0)) - 1  # data sheet Equation 1
    return (prescale + 1) / OSC * 1e6


def test_module_imports_without_psm_or_smbus2() -> None:
    assert "psm" not in sys.modules
    assert "smbus2" not in sys.modules
    assert psm_mod.CHANNEL_VARS[0] == "QW0" and len(psm_mod.CHANNEL_VARS) == 16


def test_prescale_for_50_hz() -> None:
    assert psm_mod.prescale_for(OSC, 50.0) == 121
    assert psm_mod.prescale_for(OSC, 200.0) == 30
    with pytest.raises(ValueError, match="Hz"):
        psm_mod.prescale_for(OSC, 5000.0)


def test_init_then_counts_give_commanded_pulses() -> None:
    chip, bus, plc, driver = make()
    set_counts(plc, {0: 205, 1: 307, 2: 410})
    assert driver.poll() == 16  # first cycle writes every channel
    assert chip.prescale == 121
    assert chip.running
    widths = chip.pulse_widths_us()
    tick = tick_us()
    assert widths[:3] == pytest.approx((205 * tick, 307 * tick, 410 * tick))
    assert widths[:3] == pytest.approx((1000, 1500, 2000), abs=tick)
    assert widths[3:] == (0.0,) * 13  # zero words are full OFF, not the forbidden ON == OFF
    assert plc.values[psm_mod.READY_VAR] is True
    assert plc.values[psm_mod.FAULT_VAR] is False


def test_init_sequence_order() -> None:
    _chip, bus, _plc, driver = make()
    driver.initialise()
    mode1 = [(reg, data) for _a, reg, data in bus.log if reg in (0x00, 0x01, 0xFE)]
    assert mode1 == [
        (0x00, bytes([0x31])),  # SLEEP | AI | ALLCALL
        (0x01, bytes([0x04])),  # OUTDRV
        (0xFE, bytes([121])),
        (0x00, bytes([0x21])),  # wake
        (0x00, bytes([0xA1])),  # RESTART | AI | ALLCALL
    ]


def test_only_changed_channels_are_written() -> None:
    _chip, bus, plc, driver = make()
    set_counts(plc, {0: 205, 1: 307, 2: 410})
    driver.poll()
    bus.log.clear()
    assert driver.poll() == 0
    assert bus.log == []
    set_counts(plc, {1: 300})
    assert driver.poll() == 1
    assert bus.log == [(ADDR, 0x06 + 4 * 1, bytes([0, 0, 300 & 0xFF, 300 >> 8]))]


def test_neighbouring_changes_share_one_block_write() -> None:
    _chip, bus, plc, driver = make()
    driver.poll()
    bus.log.clear()
    set_counts(plc, {4: 300, 5: 301, 6: 302, 9: 303})
    assert driver.poll() == 4
    assert [(reg, len(data)) for _a, reg, data in bus.log] == [(0x06 + 16, 12), (0x06 + 36, 4)]


def test_full_refresh_split_into_smbus_sized_blocks() -> None:
    _chip, bus, plc, driver = make()
    set_counts(plc, {ch: 300 + ch for ch in range(16)})
    driver.poll()
    blocks = [(reg, len(data)) for _a, reg, data in bus.log if reg >= 0x06 and reg != 0xFE]
    assert blocks == [(0x06, 32), (0x06 + 32, 32)]


def test_full_off_bit_passes_through() -> None:
    chip, _bus, plc, driver = make()
    set_counts(plc, {0: 0x1000 | 307})
    driver.poll()
    assert chip.channel(0).full_off
    assert chip.pulse_width_us(0) == 0.0


def test_invalid_word_goes_full_off_and_raises_fault() -> None:
    chip, _bus, plc, driver = make()
    set_counts(plc, {0: 307, 1: 0x2000})
    driver.poll()
    assert chip.pulse_width_us(0) > 0
    assert chip.pulse_width_us(1) == 0.0
    assert plc.values[psm_mod.FAULT_VAR] is True
    assert plc.values[psm_mod.READY_VAR] is True
    assert "QW1" in (driver.last_error or "")


def test_i2c_error_sets_fault_and_reinitialises_next_cycle() -> None:
    chip, bus, plc, driver = make()
    set_counts(plc, {0: 307})
    driver.poll()
    set_counts(plc, {0: 410})
    bus.fail_next = 1
    driver.poll()
    assert plc.values[psm_mod.FAULT_VAR] is True
    assert plc.values[psm_mod.READY_VAR] is False
    bus.log.clear()
    driver.poll()
    assert plc.values[psm_mod.FAULT_VAR] is False
    assert bus.log[0][1:] == (0x00, bytes([0x31]))  # re-init first
    assert chip.pulse_width_us(0) == pytest.approx(410 * tick_us())


def test_wrong_address_reports_fault() -> None:
    chip = PCA9685(address=0x41)
    _chip, _bus, plc, driver = make(address=0x40, chip=chip)
    driver.poll()
    assert plc.values[psm_mod.FAULT_VAR] is True
    assert plc.values[psm_mod.READY_VAR] is False
    assert "0x40" in (driver.last_error or "")
    assert issubclass(I2CNackError, OSError)


def test_init_request_rising_edge_reinitialises_running_chip() -> None:
    # The chip is running with active channels, so the re-init's sleep sets RESTART: the
    # driver's 500 us wait (model time) must come before its RESTART write.
    chip, bus, plc, driver = make()
    set_counts(plc, {0: 307})
    driver.poll()
    plc.values[psm_mod.INIT_REQUEST_VAR] = True
    bus.log.clear()
    driver.poll()
    assert bus.log[0][1:] == (0x00, bytes([0x31]))
    assert chip.running
    assert chip.pulse_width_us(0) == pytest.approx(307 * tick_us())
    bus.log.clear()
    driver.poll()  # level held high: no second init
    assert bus.log == []


def test_no_auto_init_waits_for_request() -> None:
    chip, bus, plc, driver = make(auto_init=False)
    set_counts(plc, {0: 307})
    assert driver.poll() == 0
    assert bus.log == []
    assert plc.values[psm_mod.READY_VAR] is False
    plc.values[psm_mod.INIT_REQUEST_VAR] = True
    driver.poll()
    assert chip.pulse_width_us(0) == pytest.approx(307 * tick_us())


def test_shutdown_turns_all_off() -> None:
    chip, _bus, plc, driver = make()
    set_counts(plc, {0: 307, 1: 410})
    driver.poll()
    driver.shutdown()
    assert chip.pulse_widths_us() == (0.0,) * 16


def test_channel_bytes() -> None:
    assert psm_mod.channel_bytes(307) == (0, 0, 0x33, 0x01)
    assert psm_mod.channel_bytes(0) == (0, 0, 0, 0x10)
    assert psm_mod.channel_bytes(0x1000) == (0, 0, 0, 0x10)
    for bad in (-1, 0x2000, True, "307"):
        with pytest.raises(ValueError, match="OFF word"):
            psm_mod.channel_bytes(bad)


def test_model_catches_a_driver_that_skips_the_oscillator_wait() -> None:
    from armbench.plant.pca9685 import PCA9685TimingError

    chip, _bus, plc, driver = make()
    set_counts(plc, {0: 307})
    driver.poll()
    driver.sleep = lambda _s: None  # a driver that forgets the 500 us
    with pytest.raises(PCA9685TimingError, match="500 us"):
        driver.initialise()
    assert chip.restart_pending


def test_psm_variables_are_the_controllers_located_variables() -> None:
    """The PSM's names are Controller.st's locations (register map derived from the program)."""
    from armbench.registermap import controller_map

    regs = controller_map()
    assert [f"%{v}" for v in psm_mod.CHANNEL_VARS] == [
        regs[f"CH{n:02d}OFF"].location for n in range(16)
    ]
    assert f"%{psm_mod.INIT_REQUEST_VAR}" == regs["PWMINITREQUEST"].location
    assert f"%{psm_mod.READY_VAR}" == regs["PWMDRIVERREADY"].location
    assert f"%{psm_mod.FAULT_VAR}" == regs["PWMDRIVERFAULT"].location
    for name in ("PWMINITREQUEST", "PWMDRIVERREADY", "PWMDRIVERFAULT", "CH15OFF"):
        # what the PSM can exchange with the runtime: %QX/%IX bytes 0..49, %QW/%IW 0..49
        assert regs[name].address < (400 if regs[name].table in ("coil", "discrete") else 50)
