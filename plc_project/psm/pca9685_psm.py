"""OpenPLC PSM (Python SubModule) driver: PLC output words -> PCA9685 servo board over I2C.

Runs on the Raspberry Pi next to the OpenPLC v3 runtime. Paste it into the runtime's PSM page
(or run it as the PSM script); OpenPLC starts it with its own `psm` module, which exposes the
PLC's located variables through `psm.get_var("QW0")` / `psm.set_var("IX0.0", value)`.

Each cycle the driver reads the 16 channel words and the init request from the PLC, and writes
the channels whose word changed since the last successful write to the PCA9685 with smbus2.
The chip is initialised once (sleep -> PRE_SCALE -> wake -> 500 us -> RESTART|AI), again on a
rising edge of the init request, and again after any I2C error (the board may have lost power).

The logic lives in `PCA9685Driver`, which takes any object with `write_i2c_block_data` (the
bus) and any object with `get_var`/`set_var` (the PLC variables), so it can be tested against
the armbench PCA9685 model. `psm` and `smbus2` are imported only in `main()`.

Note the PSM's own limits (OpenPLC_v3 webserver/core/psm/psm.py): %QW0..%QW49 and %IW0..%IW49
exist, and %QW50 is reserved (writing 127 there is the runtime's "stop PSM" signal).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

# ---------------------------------------------------------------- PLC variable map
# These are the located variables of plc_project/Controller.st (see docs/register-map.md);
# tests/plant/test_psm.py checks them against the register map derived from the program.
# The PSM exchanges only %IX/%QX 0.0..49.7 and %IW/%QW 0..49 with the runtime, so everything
# the driver needs lives there (the controller's %MW init frames are for other I2C hooks: this
# driver computes the same initialisation itself).

# %QW0..%QW15 (Ch00Off..Ch15Off): channel n's LEDn_OFF word, i.e. the pulse width in PCA9685
# ticks (1 tick = (PRE_SCALE + 1) / 25 MHz = 4.88 us at 50 Hz; 205/307/410 ~ 1.0/1.5/2.0 ms).
# Bit 12 (16#1000) or a zero count means "full OFF": no pulse, the servo goes limp.
# Words above 16#1FFF are invalid: the channel is switched full OFF and FAULT is raised.
CHANNEL_VARS: tuple[str, ...] = tuple(f"QW{channel}" for channel in range(16))
# %QX0.0 (PwmInitRequest): TRUE while the controller's InitPwm command runs. A rising edge
# re-runs the chip initialisation (the driver only writes, so it cannot see a board that was
# power-cycled; the PLC program asks for a re-init).
INIT_REQUEST_VAR = "QX0.0"
# %IX0.0 (PwmDriverReady): TRUE while the chip is initialised and the last cycle's I2C writes
# succeeded.
READY_VAR = "IX0.0"
# %IX0.1 (PwmDriverFault): TRUE when the last cycle had an I2C error or an invalid channel word.
FAULT_VAR = "IX0.1"

# ---------------------------------------------------------------- hardware settings
I2C_BUS_NUMBER = 1  # /dev/i2c-1: the GPIO header's SDA/SCL on every Pi since model B rev 2
PCA9685_ADDRESS = 0x40  # Adafruit board with no address jumper closed
OSCILLATOR_HZ = 25_000_000.0  # nominal internal oscillator; trim here if a scope says otherwise
PWM_FREQUENCY_HZ = 50.0  # MG996R frame rate (20 ms)
CYCLE_S = 0.01  # PSM loop period; 10 ms is well under a 20 ms servo frame
AUTO_INIT = True  # initialise at the first cycle without waiting for INIT_REQUEST
FULL_OFF_ON_EXIT = False  # False: servos keep their last pulse when the PSM stops (arm holds
# its pose instead of dropping); set True to make every servo limp on exit

# ---------------------------------------------------------------- PCA9685 facts (NXP data sheet)
MODE1 = 0x00
MODE2 = 0x01
LED0_ON_L = 0x06
ALL_LED_OFF_H = 0xFD
PRE_SCALE = 0xFE
MODE1_RESTART = 0x80
MODE1_AI = 0x20
MODE1_SLEEP = 0x10
MODE1_ALLCALL = 0x01
MODE2_OUTDRV = 0x04  # totem-pole outputs, as the Adafruit board needs for servo signals
LED_FULL = 0x10
CHANNELS = 16
OSC_STARTUP_S = 500e-6
SMBUS_BLOCK_MAX = 32  # bytes in one SMBus block write: 8 channels of 4 registers
_MAX_OFF_WORD = 0x1FFF

ChannelBytes = tuple[int, int, int, int]
FULL_OFF_BYTES: ChannelBytes = (0x00, 0x00, 0x00, LED_FULL)


class I2CBus(Protocol):
    """What the driver needs from smbus2.SMBus."""

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: list[int]) -> None: ...


class PlcVars(Protocol):
    """What the driver needs from OpenPLC's psm module."""

    def get_var(self, name: str) -> object: ...

    def set_var(self, name: str, value: object) -> object: ...


def prescale_for(oscillator_hz: float, frequency_hz: float) -> int:
    """PRE_SCALE = round(osc / (4096 * rate)) - 1 (data sheet Equation 1); 121 for 50 Hz."""
    if oscillator_hz <= 0 or frequency_hz <= 0:
        raise ValueError(
            f"oscillator and PWM frequency must be > 0 Hz, got {oscillator_hz} and {frequency_hz}"
        )
    value = round(oscillator_hz / (4096.0 * frequency_hz)) - 1
    if not 3 <= value <= 255:
        low = oscillator_hz / (4096.0 * 256)
        high = oscillator_hz / (4096.0 * 4)
        raise ValueError(
            f"PWM frequency {frequency_hz} Hz needs PRE_SCALE {value}, outside 3..255: with a "
            f"{oscillator_hz / 1e6:g} MHz clock choose {low:.1f}..{high:.0f} Hz"
        )
    return value


def channel_bytes(word: object) -> ChannelBytes:
    """LEDn_ON_L, ON_H, OFF_L, OFF_H for a PLC channel word (ON fixed at count 0).

    Zero and bit-12 words give full OFF: ON == OFF is forbidden by the data sheet, and a
    missing pulse is the servo's safe "limp" state. Raises ValueError for words > 16#1FFF.
    """
    if not isinstance(word, int) or isinstance(word, bool) or not 0 <= word <= _MAX_OFF_WORD:
        raise ValueError(
            f"channel word {word!r} is not a PCA9685 OFF word: use 1..4095 ticks, "
            "or 0 / 16#1000 for no pulse"
        )
    count = word & 0x0FFF
    if word & LED_FULL << 8 or count == 0:
        return FULL_OFF_BYTES
    return (0x00, 0x00, count & 0xFF, count >> 8)


@dataclass
class PCA9685Driver:
    """Mirror the PLC's channel words onto a PCA9685; call poll() once per PSM cycle."""

    bus: I2CBus
    plc: PlcVars
    address: int = PCA9685_ADDRESS
    oscillator_hz: float = OSCILLATOR_HZ
    frequency_hz: float = PWM_FREQUENCY_HZ
    auto_init: bool = AUTO_INIT
    sleep: Callable[[float], None] = time.sleep
    log: Callable[[str], None] = print
    prescale: int = field(init=False)
    initialised: bool = field(init=False, default=False)
    last_error: str | None = field(init=False, default=None)
    _written: list[ChannelBytes | None] = field(init=False, repr=False)
    _last_init_request: bool = field(init=False, repr=False, default=False)

    def __post_init__(self) -> None:
        if not 0x40 <= self.address <= 0x7F:
            raise ValueError(f"PCA9685 address must be 0x40..0x7F, got 0x{self.address:X}")
        self.prescale = prescale_for(self.oscillator_hz, self.frequency_hz)
        self._written = [None] * CHANNELS

    def initialise(self) -> None:
        """Sleep, set PRE_SCALE (only writable asleep), wake, wait 500 us, RESTART with AI."""
        awake = MODE1_AI | MODE1_ALLCALL
        self._write(MODE1, [awake | MODE1_SLEEP])
        self._write(MODE2, [MODE2_OUTDRV])
        self._write(PRE_SCALE, [self.prescale])
        self._write(MODE1, [awake])
        self.sleep(OSC_STARTUP_S)
        # RESTART resumes channels that were running before the sleep; harmless otherwise.
        self._write(MODE1, [awake | MODE1_RESTART])
        # Registers may hold anything after a re-init, so every channel is rewritten.
        self._written = [None] * CHANNELS
        self.initialised = True

    def poll(self) -> int:
        """One PSM cycle; returns how many channels were written to the chip."""
        request = bool(self.plc.get_var(INIT_REQUEST_VAR))
        rising = request and not self._last_init_request
        self._last_init_request = request
        wanted, bad_words = self._read_channels()
        written = 0
        bus_error: str | None = None
        try:
            if rising or (self.auto_init and not self.initialised):
                self.initialise()
            if self.initialised:
                written = self._write_changed(wanted)
        except OSError as exc:
            # A failed write may mean the board lost power: start again from initialisation.
            self.initialised = False
            bus_error = (
                f"PCA9685 at 0x{self.address:02X} on I2C: {exc}; check wiring, power and address"
            )
        error = bus_error
        if error is None and bad_words:
            error = "invalid channel word(s), driven full OFF: " + "; ".join(bad_words)
        self._report(error)
        self.plc.set_var(READY_VAR, self.initialised and bus_error is None)
        self.plc.set_var(FAULT_VAR, error is not None)
        return written

    def shutdown(self) -> None:
        """Orderly stop: ALL_LED_OFF_H full OFF, so a later SLEEP does not arm RESTART."""
        self._write(ALL_LED_OFF_H, [LED_FULL])
        self._written = [FULL_OFF_BYTES] * CHANNELS

    def _read_channels(self) -> tuple[list[ChannelBytes], list[str]]:
        wanted: list[ChannelBytes] = []
        bad: list[str] = []
        for name in CHANNEL_VARS:
            raw = self.plc.get_var(name)
            try:
                wanted.append(channel_bytes(raw))
            except ValueError as exc:
                wanted.append(FULL_OFF_BYTES)
                bad.append(f"%{name}: {exc}")
        return wanted, bad

    def _write_changed(self, wanted: Sequence[ChannelBytes]) -> int:
        changed = [ch for ch in range(CHANNELS) if wanted[ch] != self._written[ch]]
        per_block = SMBUS_BLOCK_MAX // 4
        written = 0
        index = 0
        # Neighbouring changed channels go out in one auto-incremented block write.
        while index < len(changed):
            run = [changed[index]]
            while (
                index + len(run) < len(changed)
                and changed[index + len(run)] == run[-1] + 1
                and len(run) < per_block
            ):
                run.append(changed[index + len(run)])
            data = [byte for ch in run for byte in wanted[ch]]
            self._write(LED0_ON_L + 4 * run[0], data)
            for ch in run:
                self._written[ch] = wanted[ch]
            written += len(run)
            index += len(run)
        return written

    def _write(self, register: int, data: list[int]) -> None:
        self.bus.write_i2c_block_data(self.address, register, data)

    def _report(self, error: str | None) -> None:
        # Print only on change: the PSM's stdout is the runtime dashboard log.
        if error != self.last_error:
            self.log(error if error is not None else "PCA9685 OK")
        self.last_error = error


def main() -> None:
    """Entry point when OpenPLC runs this file as its PSM script."""
    import psm  # provided by the OpenPLC runtime
    from smbus2 import SMBus

    psm.start()
    try:
        with SMBus(I2C_BUS_NUMBER) as bus:
            driver = PCA9685Driver(bus=bus, plc=psm)
            try:
                while not psm.should_quit():
                    driver.poll()
                    time.sleep(CYCLE_S)
            finally:
                if FULL_OFF_ON_EXIT:
                    driver.shutdown()
    finally:
        psm.stop()


if __name__ == "__main__":
    main()
