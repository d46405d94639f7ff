"""Register-level model of the NXP PCA9685 16-channel, 12-bit PWM I2C controller.

The model follows the NXP product data sheet (PCA9685, "16-channel, 12-bit PWM Fm+ I2C-bus
LED controller"); section and figure numbers below are those of its Rev. 3/4 editions.

What is modelled
----------------
* The 256-byte register map with the power-on values (MODE1 = 0x11 SLEEP|ALLCALL, MODE2 = 0x04
  OUTDRV, SUBADR1..3 = 0xE2/0xE4/0xE8, ALLCALLADR = 0xE0, every LEDn_OFF_H = 0x10 "full OFF",
  PRE_SCALE = 0x1E). Reserved bits read as 0 and ignore writes.
* I2C write and combined write/read transactions. The control register (the byte after the
  slave address) is the register pointer. With MODE1.AI = 1 the pointer advances after every
  data byte; past LED15_OFF_H (0x45) it wraps to MODE1 (0x00), and from ALL_LED_ON_L (0xFA) it
  runs up to PRE_SCALE (0xFE) and then wraps to MODE1 (remark under the register summary).
  AI is re-evaluated after each byte, so a frame that sets AI in its first (MODE1) byte
  auto-increments from then on (Fig 21). With AI = 0 the pointer does not move: every further
  data byte of the frame lands in the same register and the last one wins.
* PRE_SCALE writes are blocked while MODE1.SLEEP = 0 (note [1] of the register summary); the
  hardware forces a minimum of 3 (section 7.3.5).
  Output update rate = clock / (4096 * (PRE_SCALE + 1)).
* ALL_LED_ON/OFF (0xFA..0xFD) load the same byte into all 16 channels and read back as zero.
* LEDn_ON_H bit 4 = full ON, LEDn_OFF_H bit 4 = full OFF; full OFF wins when both are set.
* RESTART (MODE1 bit 7, section 7.3.1.1): putting the chip to sleep while any channel is active
  sets RESTART and halts the channels. After waking they stay halted until 1 is written to
  RESTART, which the data sheet allows only after SLEEP has been 0 for at least 500 us. Other
  actions that clear RESTART are modelled too: power-on/software reset, and a PWM register write
  (OCH = 0: any PWM register in the frame; OCH = 1: all four registers of one channel).
* Addressing: the primary address (A5..A0 pins, 0x40..0x7F), the LED All Call address while
  MODE1.ALLCALL = 1 and the three sub-addresses while MODE1.SUBn = 1, all write-only here, and the
  General Call software reset (address 0x00, data byte 0x06).
* EXTCLK (MODE1 bit 6): sticky once set while asleep; the model then uses `extclk_hz`.

Decisions worth knowing
-----------------------
* A transaction the chip would not acknowledge (wrong slave address, a reserved register,
  general call with anything but SWRST) raises `I2CNackError`. It subclasses `OSError` with
  errno EREMOTEIO (121), which is exactly what Linux i2c-dev/smbus2 raise on a NAK, so a driver
  can be tested against this model with its real error handling. The model raises rather than
  returning False so that a forgotten return-value check cannot hide a NAK.
* Reads are answered on the primary address only: the group addresses exist to write many
  chips at once, and a read there would have several chips drive the bus.
* Writing TestMode (0xFF) raises: the data sheet calls the result unpredictable.
* Time only passes through `advance()`. With `strict_timing` (the default) a RESTART write that
  comes less than 500 us (of model time) after waking raises `PCA9685TimingError`, because on the
  real chip the oscillator may not be stable yet; with `strict_timing=False` it is accepted.
* Outputs are evaluated from the registers at the end of every transaction, i.e. the model does
  not reproduce the "update at the end of the LOW cycle" / OCH=ACK timing within one PWM period.
* Output pulse width is 0 while the chip sleeps or its channels are halted for RESTART, whatever
  INVRT says (the pin level in that state also depends on OE/OUTNE, which are not modelled: OE is
  taken as tied low, as on the Adafruit board). INVRT = 1 while running inverts the waveform.
* LEDn_ON == LEDn_OFF (not full on/off) is forbidden by the data sheet (section 7.3.4); measured
  chips then give a constantly low output, which is what the model reports.
"""

from __future__ import annotations

import errno
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

# Register addresses (register summary table).
MODE1 = 0x00
MODE2 = 0x01
SUBADR1 = 0x02
SUBADR2 = 0x03
SUBADR3 = 0x04
ALLCALLADR = 0x05
LED0_ON_L = 0x06
LED15_OFF_H = 0x45
ALL_LED_ON_L = 0xFA
ALL_LED_ON_H = 0xFB
ALL_LED_OFF_L = 0xFC
ALL_LED_OFF_H = 0xFD
PRE_SCALE = 0xFE
TESTMODE = 0xFF

# MODE1 bits (MODE1 register table).
MODE1_RESTART = 0x80
MODE1_EXTCLK = 0x40
MODE1_AI = 0x20
MODE1_SLEEP = 0x10
MODE1_SUB1 = 0x08
MODE1_SUB2 = 0x04
MODE1_SUB3 = 0x02
MODE1_ALLCALL = 0x01

# MODE2 bits (MODE2 register table).
MODE2_INVRT = 0x10
MODE2_OCH = 0x08
MODE2_OUTDRV = 0x04
MODE2_OUTNE = 0x03

LED_FULL = 0x10  # bit 4 of LEDn_ON_H (full ON) and of LEDn_OFF_H (full OFF)
CHANNELS = 16
REGISTERS_PER_CHANNEL = 4
COUNTS_PER_PERIOD = 4096
INTERNAL_OSC_HZ = 25_000_000.0
PRESCALE_MIN = 3
OSC_STARTUP_S = 500e-6
DEFAULT_ADDRESS = 0x40
GENERAL_CALL_ADDRESS = 0x00
SWRST_DATA = 0x06

POWER_ON_MODE1 = MODE1_SLEEP | MODE1_ALLCALL  # 0x11
POWER_ON_MODE2 = MODE2_OUTDRV  # 0x04
POWER_ON_PRESCALE = 0x1E
POWER_ON_SUBADR = (0xE2, 0xE4, 0xE8)
POWER_ON_ALLCALLADR = 0xE0

# Register bits that exist; the rest are reserved, read as 0 and ignore writes.
_H_REGISTER_MASK = 0x1F  # LEDn_ON_H / LEDn_OFF_H: bit 4 full ON/OFF + count bits 11..8
_MODE2_MASK = 0x1F
_ADDRESS_REGISTER_MASK = 0xFE  # bit 0 of SUBADRx/ALLCALLADR is reserved
_OFF_WORD_MAX = 0x1FFF  # 12-bit count plus the full-OFF bit (bit 12)


class PCA9685Error(Exception):
    """Base class of the errors raised by the PCA9685 model."""


class I2CNackError(PCA9685Error, OSError):
    """The chip would not acknowledge the transaction (raised like smbus2's OSError 121)."""

    def __init__(self, message: str) -> None:
        super().__init__(errno.EREMOTEIO, message)


class PCA9685TimingError(PCA9685Error):
    """A write broke a timing rule of the data sheet (only raised with strict_timing)."""


@dataclass(frozen=True)
class ChannelOutput:
    """One channel's registers and the output waveform they produce."""

    channel: int
    on_count: int
    off_count: int
    full_on: bool
    full_off: bool
    high_counts: int  # 0..4096 ticks of the PWM period the pin is high
    duty: float  # high_counts / 4096
    pulse_width_us: float


def _is_reserved_register(register: int) -> bool:
    return LED15_OFF_H < register < ALL_LED_ON_L


def _channel_register_base(channel: int) -> int:
    return LED0_ON_L + REGISTERS_PER_CHANNEL * channel


@dataclass
class PCA9685:
    """One PCA9685 on an I2C bus.

    address: 7-bit slave address set by the A5..A0 pins (0x40..0x7F; Adafruit board default 0x40).
    osc_hz: internal oscillator frequency; 25 MHz nominal, set it to model a trimmed or
        off-nominal chip (individual parts deviate by a few percent).
    extclk_hz: frequency on the EXTCLK pin, used once MODE1.EXTCLK has been set.
    strict_timing: raise PCA9685TimingError when RESTART is written too soon after waking.
    """

    address: int = DEFAULT_ADDRESS
    osc_hz: float = INTERNAL_OSC_HZ
    extclk_hz: float | None = None
    strict_timing: bool = True
    _regs: bytearray = field(init=False, repr=False, default_factory=lambda: bytearray(256))
    _restart_pending: bool = field(init=False, repr=False, default=False)
    _time_s: float = field(init=False, repr=False, default=0.0)
    _wake_time_s: float | None = field(init=False, repr=False, default=None)

    def __post_init__(self) -> None:
        if not isinstance(self.address, int) or not 0x40 <= self.address <= 0x7F:
            raise ValueError(
                f"PCA9685 address {self.address!r} is impossible: the 7-bit address is "
                "0b1 A5 A4 A3 A2 A1 A0, i.e. 0x40..0x7F (Adafruit board default 0x40)"
            )
        if not (math.isfinite(self.osc_hz) and self.osc_hz > 0):
            raise ValueError(f"osc_hz must be a positive frequency in Hz, got {self.osc_hz!r}")
        if self.extclk_hz is not None and not (
            math.isfinite(self.extclk_hz) and self.extclk_hz > 0
        ):
            raise ValueError(
                f"extclk_hz must be a positive frequency in Hz or None, got {self.extclk_hz!r}"
            )
        self.power_on_reset()

    # ----------------------------------------------------------------- reset and time

    def power_on_reset(self) -> None:
        """Put every register back to its power-on value (also what SWRST does)."""
        regs = bytearray(256)
        regs[MODE1] = POWER_ON_MODE1
        regs[MODE2] = POWER_ON_MODE2
        regs[SUBADR1], regs[SUBADR2], regs[SUBADR3] = POWER_ON_SUBADR
        regs[ALLCALLADR] = POWER_ON_ALLCALLADR
        for channel in range(CHANNELS):
            regs[_channel_register_base(channel) + 3] = LED_FULL
        regs[PRE_SCALE] = POWER_ON_PRESCALE
        self._regs = regs
        self._restart_pending = False
        self._wake_time_s = None  # SLEEP = 1 at power-on: the oscillator is off

    def advance(self, dt_s: float) -> None:
        """Let dt_s seconds of model time pass (only matters for the 500 us RESTART rule)."""
        if not (math.isfinite(dt_s) and dt_s >= 0):
            raise ValueError(f"dt_s must be a finite, non-negative time in seconds, got {dt_s!r}")
        self._time_s += dt_s

    @property
    def time_s(self) -> float:
        """Model time in seconds since construction."""
        return self._time_s

    # ----------------------------------------------------------------- I2C side

    def acknowledges(self, address: int) -> bool:
        """True when a write to this 7-bit slave address would be acknowledged."""
        if address == self.address:
            return True
        mode1 = self._regs[MODE1]
        group = (
            (MODE1_ALLCALL, ALLCALLADR),
            (MODE1_SUB1, SUBADR1),
            (MODE1_SUB2, SUBADR2),
            (MODE1_SUB3, SUBADR3),
        )
        return any(mode1 & bit and self._regs[reg] >> 1 == address for bit, reg in group)

    def write(self, address: int, register: int, data: bytes = b"") -> None:
        """One I2C write: START, address+W, control register, data bytes, STOP.

        Raises I2CNackError (an OSError, errno 121) if the chip would NAK the frame.
        For a General Call software reset pass address 0x00 and register 0x06 (the SWRST byte).
        """
        _check_byte_args(address, register, data, what="write")
        if address == GENERAL_CALL_ADDRESS:
            self._general_call(register, data)
            return
        if not self.acknowledges(address):
            raise I2CNackError(
                f"no ACK from address 0x{address:02X}: this PCA9685 answers 0x{self.address:02X}"
                " (plus the All Call/sub-addresses enabled in MODE1); check the A0..A5 jumpers"
                " and the address your driver uses"
            )
        self._check_register_acknowledged(register)
        self._apply(register, data, force_auto_increment=False)

    def read(self, address: int, register: int, length: int = 1) -> bytes:
        """Combined transaction: write the control register, repeated START, read `length` bytes.

        Follows the same auto-increment rules as writes. Only the primary address answers.
        """
        _check_byte_args(address, register, b"", what="read")
        if not isinstance(length, int) or length < 1:
            raise ValueError(f"read length must be an int >= 1, got {length!r}")
        if address != self.address:
            raise I2CNackError(
                f"no ACK for a read from 0x{address:02X}: reads are answered only on the primary"
                f" address 0x{self.address:02X} (group addresses are write-only in this model)"
            )
        self._check_register_acknowledged(register)
        out = bytearray()
        pointer = register
        for _ in range(length):
            out.append(self._read_register(pointer))
            pointer = self._next_pointer(pointer)
        return bytes(out)

    def load_off_counts(self, words: Sequence[int]) -> None:
        """Convenience: load 16 OFF words as an OpenPLC program would hand them over Modbus.

        Word n becomes LEDn_ON = 0 and LEDn_OFF = word (bits 11..0 the OFF count, bit 12 the
        full-OFF flag). It acts like an auto-incremented I2C write of all channel registers, so
        SLEEP and RESTART rules apply as for a real write.
        """
        if len(words) != CHANNELS:
            raise ValueError(f"expected {CHANNELS} OFF words (one per channel), got {len(words)}")
        frame = bytearray()
        for channel, word in enumerate(words):
            if not isinstance(word, int) or not 0 <= word <= _OFF_WORD_MAX:
                raise ValueError(
                    f"channel {channel}: OFF word {word!r} out of range 0..0x1FFF "
                    "(12-bit count, bit 12 = full OFF)"
                )
            frame += bytes((0x00, 0x00, word & 0xFF, word >> 8))
        self._apply(LED0_ON_L, bytes(frame), force_auto_increment=True)

    # ----------------------------------------------------------------- outputs

    @property
    def registers(self) -> bytes:
        """Raw register file (ALL_LED registers hold 0, MODE1 without the RESTART flag)."""
        return bytes(self._regs)

    @property
    def sleeping(self) -> bool:
        """MODE1.SLEEP: oscillator off, all outputs stopped."""
        return bool(self._regs[MODE1] & MODE1_SLEEP)

    @property
    def restart_pending(self) -> bool:
        """MODE1.RESTART as read back: channels halted, waiting for a restart."""
        return self._restart_pending

    @property
    def running(self) -> bool:
        """True when the PWM channels produce output."""
        return not self.sleeping and not self._restart_pending

    @property
    def prescale(self) -> int:
        """Current PRE_SCALE value."""
        return self._regs[PRE_SCALE]

    @property
    def clock_hz(self) -> float:
        """PWM clock: the internal oscillator, or EXTCLK once MODE1.EXTCLK is set."""
        if self._regs[MODE1] & MODE1_EXTCLK:
            if self.extclk_hz is None:
                raise PCA9685Error(
                    "MODE1.EXTCLK is set but the model has no external clock: construct "
                    "PCA9685(extclk_hz=...) with the frequency fed to the EXTCLK pin"
                )
            return self.extclk_hz
        return self.osc_hz

    @property
    def update_rate_hz(self) -> float:
        """PWM output frequency: clock / (4096 * (PRE_SCALE + 1)), Equation 1."""
        return self.clock_hz / (COUNTS_PER_PERIOD * (self.prescale + 1))

    @property
    def period_us(self) -> float:
        """PWM period in microseconds."""
        return 1e6 / self.update_rate_hz

    def channel(self, channel: int) -> ChannelOutput:
        """Registers of one channel and the waveform they produce right now."""
        base = _channel_register_base(_check_channel(channel))
        on_l, on_h, off_l, off_h = self._regs[base : base + REGISTERS_PER_CHANNEL]
        on_count = ((on_h & 0x0F) << 8) | on_l
        off_count = ((off_h & 0x0F) << 8) | off_l
        full_on = bool(on_h & LED_FULL)
        full_off = bool(off_h & LED_FULL)
        if full_off:
            high = 0
        elif full_on:
            high = COUNTS_PER_PERIOD
        elif on_count == off_count:
            high = 0
        else:
            # ON > OFF means the pulse wraps around the end of the 4096-tick period.
            high = (off_count - on_count) % COUNTS_PER_PERIOD
        if not self.running:
            high = 0
        elif self._regs[MODE2] & MODE2_INVRT:
            high = COUNTS_PER_PERIOD - high
        return ChannelOutput(
            channel=channel,
            on_count=on_count,
            off_count=off_count,
            full_on=full_on,
            full_off=full_off,
            high_counts=high,
            duty=high / COUNTS_PER_PERIOD,
            pulse_width_us=high * self.period_us / COUNTS_PER_PERIOD if high else 0.0,
        )

    def pulse_width_us(self, channel: int) -> float:
        """High time of the channel's output in microseconds (0 while stopped)."""
        return self.channel(channel).pulse_width_us

    def duty(self, channel: int) -> float:
        """Fraction of the period the channel's output is high (0..1)."""
        return self.channel(channel).duty

    def pulse_widths_us(self) -> tuple[float, ...]:
        """High times of all 16 channels in microseconds."""
        return tuple(self.pulse_width_us(channel) for channel in range(CHANNELS))

    # ----------------------------------------------------------------- internals

    def _general_call(self, data_byte: int, rest: bytes) -> None:
        if data_byte != SWRST_DATA or rest:
            raise I2CNackError(
                "General Call (address 0x00) is acknowledged only for the single software-reset"
                f" byte 0x06; got control byte 0x{data_byte:02X} and {len(rest)} more byte(s)"
            )
        self.power_on_reset()

    def _check_register_acknowledged(self, register: int) -> None:
        if _is_reserved_register(register):
            raise I2CNackError(
                f"register 0x{register:02X} is reserved (0x46..0xF9) and is not acknowledged;"
                " channel registers are 0x06..0x45, ALL_LED 0xFA..0xFD, PRE_SCALE 0xFE"
            )

    def _next_pointer(self, pointer: int) -> int:
        if not self._regs[MODE1] & MODE1_AI:
            return pointer
        if pointer in (LED15_OFF_H, PRE_SCALE, TESTMODE):
            return MODE1
        return pointer + 1

    def _apply(self, register: int, data: bytes, *, force_auto_increment: bool) -> None:
        # Which channel registers the frame touched decides whether STOP clears RESTART.
        touched: dict[int, set[int]] = {}
        pointer = register
        for value in data:
            self._write_register(pointer, value)
            if LED0_ON_L <= pointer <= LED15_OFF_H:
                channel, offset = divmod(pointer - LED0_ON_L, REGISTERS_PER_CHANNEL)
                touched.setdefault(channel, set()).add(offset)
            elif ALL_LED_ON_L <= pointer <= ALL_LED_OFF_H:
                touched.setdefault(-1, set()).add(pointer - ALL_LED_ON_L)
            if force_auto_increment:
                pointer = pointer + 1 if pointer != LED15_OFF_H else MODE1
            else:
                pointer = self._next_pointer(pointer)
        self._stop_condition(touched)

    def _stop_condition(self, touched: dict[int, set[int]]) -> None:
        if not self._restart_pending or not touched:
            return
        if self._regs[MODE2] & MODE2_OCH:
            # OCH = 1: outputs change per channel, so only a complete channel counts.
            complete = any(len(offsets) == REGISTERS_PER_CHANNEL for offsets in touched.values())
            if complete:
                self._restart_pending = False
        else:
            self._restart_pending = False

    def _read_register(self, register: int) -> int:
        if register == MODE1:
            return self._regs[MODE1] | (MODE1_RESTART if self._restart_pending else 0)
        return self._regs[register]

    def _write_register(self, register: int, value: int) -> None:
        if register == MODE1:
            self._write_mode1(value)
        elif register == MODE2:
            self._regs[MODE2] = value & _MODE2_MASK
        elif SUBADR1 <= register <= ALLCALLADR:
            self._regs[register] = value & _ADDRESS_REGISTER_MASK
        elif LED0_ON_L <= register <= LED15_OFF_H:
            self._regs[register] = value & _led_register_mask(register - LED0_ON_L)
        elif ALL_LED_ON_L <= register <= ALL_LED_OFF_H:
            offset = register - ALL_LED_ON_L
            masked = value & _led_register_mask(offset)
            for channel in range(CHANNELS):
                self._regs[_channel_register_base(channel) + offset] = masked
        elif register == PRE_SCALE:
            if self.sleeping:
                self._regs[PRE_SCALE] = max(value, PRESCALE_MIN)
            # Awake: the chip blocks the write silently, and so does the model.
        elif register == TESTMODE:
            raise PCA9685Error(
                "write to TestMode register 0xFF: the data sheet says this may cause "
                "unpredictable results, so the model refuses it; check the register pointer"
            )
        else:  # pragma: no cover - reserved registers are NAKed before any data byte
            raise AssertionError(f"unreachable register 0x{register:02X}")

    def _write_mode1(self, value: int) -> None:
        old = self._regs[MODE1]
        was_sleeping = bool(old & MODE1_SLEEP)
        # EXTCLK can only be switched on while the oscillator is already off, and only a
        # power cycle or SWRST switches it back (section 7.3.1, EXTCLK bit).
        extclk = old & MODE1_EXTCLK
        if value & MODE1_EXTCLK and was_sleeping and value & MODE1_SLEEP:
            extclk = MODE1_EXTCLK
        new = (value & ~(MODE1_RESTART | MODE1_EXTCLK) & 0xFF) | extclk
        self._regs[MODE1] = new
        now_sleeping = bool(new & MODE1_SLEEP)
        if now_sleeping and not was_sleeping:
            self._wake_time_s = None
            if any(self._channel_active(channel) for channel in range(CHANNELS)):
                # The chip sets RESTART at the end of the PWM cycle; the cycle is not modelled.
                self._restart_pending = True
        elif was_sleeping and not now_sleeping:
            self._wake_time_s = self._time_s
        if value & MODE1_RESTART and self._restart_pending and not now_sleeping:
            self._restart(value)

    def _restart(self, value: int) -> None:
        assert self._wake_time_s is not None
        awake_s = self._time_s - self._wake_time_s
        if awake_s < OSC_STARTUP_S and self.strict_timing:
            raise PCA9685TimingError(
                f"RESTART (MODE1=0x{value:02X}) written {awake_s * 1e6:.0f} us after SLEEP was "
                f"cleared; the data sheet requires at least {OSC_STARTUP_S * 1e6:.0f} us for the "
                "oscillator to settle: wait (call advance() in the model) before writing RESTART,"
                " or build the model with strict_timing=False"
            )
        self._restart_pending = False

    def _channel_active(self, channel: int) -> bool:
        base = _channel_register_base(channel)
        on_l, on_h, off_l, off_h = self._regs[base : base + REGISTERS_PER_CHANNEL]
        if off_h & LED_FULL:
            return False
        return bool(on_h & LED_FULL) or (on_l, on_h & 0x0F) != (off_l, off_h & 0x0F)


def _led_register_mask(offset_in_channel: int) -> int:
    # Offsets 1 and 3 are the _H registers, whose bits 7..5 are reserved.
    return _H_REGISTER_MASK if offset_in_channel % 2 else 0xFF


def _check_channel(channel: int) -> int:
    if not isinstance(channel, int) or not 0 <= channel < CHANNELS:
        raise ValueError(f"PCA9685 channel must be 0..{CHANNELS - 1}, got {channel!r}")
    return channel


def _check_byte_args(address: int, register: int, data: bytes, *, what: str) -> None:
    if not isinstance(address, int) or not 0 <= address <= 0x7F:
        raise ValueError(f"I2C {what}: address must be a 7-bit int 0..0x7F, got {address!r}")
    if not isinstance(register, int) or not 0 <= register <= 0xFF:
        raise ValueError(f"I2C {what}: register must be a byte 0..0xFF, got {register!r}")
    if not isinstance(data, (bytes, bytearray)):
        raise ValueError(
            f"I2C {what}: data must be bytes (e.g. bytes([0x21])), got {type(data).__name__}"
        )
