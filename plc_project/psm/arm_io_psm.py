"""OpenPLC PSM (Python SubModule) I/O layer of the arm controller, for a Raspberry Pi:
PLC output words -> PCA9685 servo board, and MPU6050 + HMC5883L readings -> PLC input words.

Runs on the Pi next to the OpenPLC v3 runtime. Paste it into the runtime's PSM page (the page
keeps one script, so both drivers live in this one file); OpenPLC starts it with its own `psm`
module, which exposes the PLC's located variables through `psm.get_var("QW0")` /
`psm.set_var("IW0", value)`. The runtime reads the PSM's input words once per PLC scan.

Servos (PCA9685Driver): each cycle the driver reads the 16 channel words and the init request
from the PLC, and writes the channels whose word changed since the last successful write to the
PCA9685 with smbus2. The chip is initialised once (sleep -> PRE_SCALE -> wake -> 500 us ->
RESTART|AI), again on a rising edge of the init request, and again after any I2C error (the
board may have lost power).

IMU (ImuReader): every SAMPLE_PERIOD_S it reads one sample of an MPU6050 (gyro,
accelerometer) and an HMC5883L (magnetometer, behind the MPU6050's I2C bypass on GY-87 boards)
and publishes it to %IW0..8 together with the incremented sample counter %IW9 in ONE set_var
call, so the runtime never sees half a sample. Send the controller `ImuSetPeriod` with the same
period (command 41). A chip that does not answer stops the counter (the controller's IMU users
see no new samples); the reader retries the initialisation every IMU_RETRY_S and logs why.

The logic lives in `PCA9685Driver` and `ImuReader`, which take any object with the smbus2
methods they use (the bus) and any object with `get_var`/`set_var` (the PLC variables), so they
are tested against the armbench chip models. `psm` and `smbus2` are imported only in `main()`.

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
    """What the servo driver needs from smbus2.SMBus."""

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: list[int]) -> None: ...


class I2CReadBus(Protocol):
    """What the IMU reader needs from smbus2.SMBus."""

    def write_byte_data(self, i2c_addr: int, register: int, value: int) -> None: ...

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int) -> list[int]: ...


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


# ================================================================ IMU (MPU6050 + HMC5883L)
# %IW0..%IW8 (ImuGyroX..ImuMagZ): the chips' register values, 16-bit two's complement, gyro
# X/Y/Z, accel X/Y/Z, mag X/Y/Z (as unsigned words 0..65535: Modbus registers are unsigned).
# %IW9 (ImuSampleSeq): counter, +1 per published sample, wraps at 65536.
IMU_WORD_VARS: tuple[str, ...] = tuple(f"IW{n}" for n in range(10))
IMU_ENABLED = True  # False: servos only (no IMU wired)
SAMPLE_PERIOD_S = 0.02  # one sample per 20 ms; send the controller ImuSetPeriod 0.02
IMU_RETRY_S = 2.0  # a chip that fails is initialised again after this pause
MPU6050_ADDRESS = 0x68  # AD0 low; 0x69 with AD0 high
HMC5883L_ADDRESS = 0x1E
MAG_ON_AUX_BUS = True  # GY-87: the HMC5883L is reachable only through the MPU6050's bypass
# Magnetometer axes in the MPU6050's frame: (source axis 0/1/2 = HMC X/Y/Z, sign) per X, Y, Z.
# The controller assumes aligned axes; change this where a board mounts the chips rotated.
MAG_AXES: tuple[tuple[int, int], tuple[int, int], tuple[int, int]] = ((0, 1), (1, 1), (2, 1))

# The controller's ImuCalibration expects the chips' default ranges (Controller.st, IMU
# COMMANDS): 250 deg/s (131 LSB per deg/s), 2 g (16384 LSB/g), 1.3 gauss (1090 LSB/gauss).
MPU_SMPLRT_DIV, MPU_CONFIG, MPU_GYRO_CONFIG, MPU_ACCEL_CONFIG = 0x19, 0x1A, 0x1B, 0x1C
MPU_INT_PIN_CFG, MPU_ACCEL_XOUT_H, MPU_USER_CTRL = 0x37, 0x3B, 0x6A
MPU_PWR_MGMT_1, MPU_WHO_AM_I = 0x6B, 0x75
MPU_RESET_S = 0.1  # PWR_MGMT_1 DEVICE_RESET needs 100 ms
MPU_SETUP: tuple[tuple[int, int], ...] = (
    (MPU_PWR_MGMT_1, 0x01),  # awake, clock from the X gyro's PLL (data sheet's advice)
    (MPU_CONFIG, 0x03),  # DLPF_CFG 3: 44 Hz accel / 42 Hz gyro bandwidth, 1 kHz gyro rate
    (MPU_SMPLRT_DIV, 0x09),  # 1 kHz / (1 + 9) = 100 Hz output rate, above SAMPLE_PERIOD_S
    (MPU_GYRO_CONFIG, 0x00),  # FS_SEL 0: +-250 deg/s
    (MPU_ACCEL_CONFIG, 0x00),  # AFS_SEL 0: +-2 g
    (MPU_USER_CTRL, 0x00),  # I2C_MST_EN off, so the bypass can connect the aux bus
    (MPU_INT_PIN_CFG, 0x02),  # I2C_BYPASS_EN
)
MPU_WHO_AM_I_VALUE = 0x68
HMC_CRA, HMC_CRB, HMC_MODE, HMC_DATA, HMC_ID = 0x00, 0x01, 0x02, 0x03, 0x0A
HMC_SETUP: tuple[tuple[int, int], ...] = (
    (HMC_CRA, 0x78),  # 8 samples averaged, 75 Hz output rate, normal measurement
    (HMC_CRB, 0x20),  # gain 1: +-1.3 gauss, 1090 LSB/gauss
    (HMC_MODE, 0x00),  # continuous measurement
)
HMC_ID_VALUE = (0x48, 0x34, 0x33)  # "H43"


def _int16(msb: int, lsb: int) -> int:
    word = (msb << 8) | lsb
    return word - 0x10000 if word & 0x8000 else word


def decode_mpu6050(data: Sequence[int]) -> tuple[list[int], list[int]]:
    """Gyro X/Y/Z and accel X/Y/Z from the 14 bytes read at ACCEL_XOUT_H (0x3B)."""
    if len(data) != 14:
        raise ValueError(f"an MPU6050 sample is 14 bytes from 0x3B, got {len(data)}")
    words = [_int16(data[i], data[i + 1]) for i in range(0, 14, 2)]
    return words[4:7], words[0:3]  # accel, temperature, gyro on the chip


def decode_hmc5883l(data: Sequence[int]) -> list[int]:
    """X, Y, Z from the 6 bytes read at DATA X MSB (0x03): the chip sends X, Z, Y."""
    if len(data) != 6:
        raise ValueError(f"an HMC5883L sample is 6 bytes from 0x03, got {len(data)}")
    x, z, y = (_int16(data[i], data[i + 1]) for i in range(0, 6, 2))
    return [x, y, z]


def map_mag_axes(mag: Sequence[int],
                 axes: tuple[tuple[int, int], tuple[int, int], tuple[int, int]]) -> list[int]:
    """The magnetometer reading in the MPU6050's axes (see MAG_AXES); -4096 stays overflow."""
    if sorted(a for a, _ in axes) != [0, 1, 2] or any(sign not in (1, -1) for _, sign in axes):
        raise ValueError(f"MAG_AXES must use each axis 0, 1, 2 once with sign +1/-1: {axes}")
    out = []
    for axis, sign in axes:
        v = mag[axis]
        out.append(v if v == -4096 else sign * v)
    return out


@dataclass
class ImuReader:
    """Publish one MPU6050 + HMC5883L sample per period; call poll(now) once per PSM cycle."""

    bus: I2CReadBus
    plc: PlcVars
    period_s: float = SAMPLE_PERIOD_S
    mpu_address: int = MPU6050_ADDRESS
    hmc_address: int = HMC5883L_ADDRESS
    mag_on_aux_bus: bool = MAG_ON_AUX_BUS
    mag_axes: tuple[tuple[int, int], tuple[int, int], tuple[int, int]] = MAG_AXES
    retry_s: float = IMU_RETRY_S
    sleep: Callable[[float], None] = time.sleep
    log: Callable[[str], None] = print
    initialised: bool = field(init=False, default=False)
    seq: int = field(init=False, default=0)
    published: int = field(init=False, default=0)
    overruns: int = field(init=False, default=0)
    last_error: str | None = field(init=False, default=None)
    _next_s: float | None = field(init=False, default=None, repr=False)
    _retry_at_s: float = field(init=False, default=float("-inf"), repr=False)
    _last_s: float = field(init=False, default=float("-inf"), repr=False)

    def __post_init__(self) -> None:
        if not 0.005 <= self.period_s <= 1.0:
            raise ValueError(f"IMU sample period must be 0.005..1 s, got {self.period_s}")
        if self.mpu_address not in (0x68, 0x69):
            raise ValueError(f"MPU6050 address must be 0x68 or 0x69, got 0x{self.mpu_address:X}")
        map_mag_axes([0, 0, 0], self.mag_axes)  # validates the axis map

    def initialise(self) -> None:
        """Reset and configure both chips; raises OSError (I2C) or RuntimeError (wrong chip)."""
        self.bus.write_byte_data(self.mpu_address, MPU_PWR_MGMT_1, 0x80)  # DEVICE_RESET
        self.sleep(MPU_RESET_S)
        who = self.bus.read_i2c_block_data(self.mpu_address, MPU_WHO_AM_I, 1)[0]
        if who != MPU_WHO_AM_I_VALUE:
            raise RuntimeError(f"the chip at 0x{self.mpu_address:02X} says WHO_AM_I 0x{who:02X}, "
                               f"an MPU6050 says 0x{MPU_WHO_AM_I_VALUE:02X}: check the board")
        for register, value in MPU_SETUP:
            self.bus.write_byte_data(self.mpu_address, register, value)
        try:
            ident = tuple(self.bus.read_i2c_block_data(self.hmc_address, HMC_ID, 3))
        except OSError as exc:
            where = " (behind the MPU6050's bypass)" if self.mag_on_aux_bus else ""
            raise RuntimeError(
                f"no HMC5883L answers at 0x{self.hmc_address:02X}{where}: {exc}; a QMC5883L "
                "(address 0x0D, sold on many 'HMC5883L' boards) is a different chip") from exc
        if ident != HMC_ID_VALUE:
            raise RuntimeError(f"the chip at 0x{self.hmc_address:02X} identifies as "
                               f"{bytes(ident)!r}, an HMC5883L as b'H43'")
        for register, value in HMC_SETUP:
            self.bus.write_byte_data(self.hmc_address, register, value)
        self.initialised = True
        self.log(f"IMU ready: MPU6050 at 0x{self.mpu_address:02X}, HMC5883L at "
                 f"0x{self.hmc_address:02X}, one sample per {self.period_s * 1000:g} ms "
                 f"(send the controller ImuSetPeriod {self.period_s:g})")

    def read_sample(self) -> list[int]:
        """Gyro X/Y/Z, accel X/Y/Z, mag X/Y/Z register values (signed) of the chips now."""
        gyro, accel = decode_mpu6050(
            self.bus.read_i2c_block_data(self.mpu_address, MPU_ACCEL_XOUT_H, 14))
        mag = decode_hmc5883l(self.bus.read_i2c_block_data(self.hmc_address, HMC_DATA, 6))
        return [*gyro, *accel, *map_mag_axes(mag, self.mag_axes)]

    def poll(self, now_s: float) -> bool:
        """One PSM cycle at time now_s (s, monotonic); True when a sample was published."""
        if self._next_s is not None:
            # a quarter period of slack: cycle jitter and float sums must not skip a grid point
            if now_s < self._next_s - 0.25 * self.period_s:
                return False
            # catching up after a late cycle, samples keep 3/4 of a period apart: the PLC
            # takes one sample per scan, and two within one scan would lose the first
            if now_s - self._last_s < 0.75 * self.period_s:
                return False
        if not self.initialised:
            if now_s < self._retry_at_s:
                return False
            try:
                self.initialise()
            except (OSError, RuntimeError) as exc:
                self._fail(now_s, f"IMU not ready: {exc}")
                return False
        try:
            raw = self.read_sample()
        except OSError as exc:
            self.initialised = False
            self._fail(now_s, f"IMU read failed: {exc}; check wiring and power")
            return False
        self.seq = (self.seq + 1) & 0xFFFF
        # One call: the runtime reads the PSM's input words between two calls, never within.
        self.plc.set_var(IMU_WORD_VARS[0], [v & 0xFFFF for v in raw] + [self.seq])
        self.published += 1
        # Samples stay on the period's grid; a late cycle is caught up, not drifted.
        if self._next_s is None or now_s - self._next_s > self.period_s:
            if self._next_s is not None:
                self.overruns += 1
            self._next_s = now_s
        self._next_s += self.period_s
        self._last_s = now_s
        self._report(None)
        return True

    def _fail(self, now_s: float, message: str) -> None:
        self._retry_at_s = now_s + self.retry_s
        self._next_s = None
        self._report(message)

    def _report(self, error: str | None) -> None:
        if error != self.last_error:
            self.log(error if error is not None else "IMU OK")
        self.last_error = error


def main() -> None:
    """Entry point when OpenPLC runs this file as its PSM script."""
    import psm  # provided by the OpenPLC runtime
    from smbus2 import SMBus

    psm.start()
    try:
        with SMBus(I2C_BUS_NUMBER) as bus:
            driver = PCA9685Driver(bus=bus, plc=psm)
            imu = ImuReader(bus=bus, plc=psm) if IMU_ENABLED else None
            try:
                while not psm.should_quit():
                    driver.poll()
                    if imu is not None:
                        imu.poll(time.monotonic())
                    time.sleep(CYCLE_S)
            finally:
                if FULL_OFF_ON_EXIT:
                    driver.shutdown()
    finally:
        psm.stop()


if __name__ == "__main__":
    main()
