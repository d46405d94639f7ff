"""Register-level models of the IMU chips document 004 uses: the InvenSense MPU6050 (gyro and
accelerometer) and the Honeywell HMC5883L (magnetometer), as they sit on a GY-87-style board.

They let the PSM's IMU reader (plc_project/psm/arm_io_psm.py) run against something that
behaves like the chips' registers, so a test sees wrong register addresses, byte order, axis
order or a missing wake-up, not only the reader's own idea of the chips. What is modelled,
from the data sheets (MPU-6000/6050 Register Map and Descriptions rev 4.2; HMC5883L data
sheet, Honeywell 2010):

MPU6050 (address 0x68, 0x69 with AD0 high)
  * Power-on values: PWR_MGMT_1 (0x6B) = 0x40 (SLEEP), WHO_AM_I (0x75) = 0x68, others 0.
  * Writes and reads auto-increment the register pointer.
  * PWR_MGMT_1 bit 7 (DEVICE_RESET) restores the power-on values and clears itself.
  * While SLEEP is set the measurement registers (ACCEL_XOUT_H 0x3B .. GYRO_ZOUT_L 0x48) are
    frozen: a loaded sample does not reach them (0 after power-on).
  * Measurement registers are big-endian two's complement: ACCEL X/Y/Z, TEMP, GYRO X/Y/Z.
  * INT_PIN_CFG (0x37) bit 1 I2C_BYPASS_EN with USER_CTRL (0x6A) bit 5 I2C_MST_EN = 0 connects
    the auxiliary I2C bus (where a GY-87 wires the HMC5883L) to the host bus.
HMC5883L (address 0x1E)
  * Power-on values: CRA (0x00) = 0x10, CRB (0x01) = 0x20 (gain 1, 1090 LSB/gauss), MODE
    (0x02) = 0x01 (single measurement), identification 0x0A..0x0C = 'H', '4', '3'.
  * Data output registers in the order X MSB, X LSB, Z MSB, Z LSB, Y MSB, Y LSB (0x03..0x08):
    Z comes before Y. A loaded sample reaches them only in continuous mode (MODE = 0x00).
  * The pointer auto-increments; reading past 0x08 wraps to 0x03, past 0x0C to 0x00.

Errors: a frame to an address no chip answers raises `I2CNackError` (an OSError with errno
121, as smbus2 raises on a Pi).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from armbench.plant.pca9685 import I2CNackError

MPU6050_ADDRESS = 0x68
HMC5883L_ADDRESS = 0x1E

MPU_SMPLRT_DIV = 0x19
MPU_CONFIG = 0x1A
MPU_GYRO_CONFIG = 0x1B
MPU_ACCEL_CONFIG = 0x1C
MPU_INT_PIN_CFG = 0x37
MPU_ACCEL_XOUT_H = 0x3B
MPU_GYRO_ZOUT_L = 0x48
MPU_USER_CTRL = 0x6A
MPU_PWR_MGMT_1 = 0x6B
MPU_WHO_AM_I = 0x75

HMC_CRA = 0x00
HMC_CRB = 0x01
HMC_MODE = 0x02
HMC_DATA_X_MSB = 0x03
HMC_ID_A = 0x0A


def _int16_bytes(value: int) -> tuple[int, int]:
    if not -32768 <= value <= 32767:
        raise ValueError(f"a 16-bit register value must be -32768..32767, got {value}")
    word = value & 0xFFFF
    return word >> 8, word & 0xFF


@dataclass
class MPU6050:
    """The MPU6050's register file; `load` presents one sample (register values, LSB)."""

    address: int = MPU6050_ADDRESS
    who_am_i: int = 0x68  # clones answer otherwise (MPU6500: 0x70)
    regs: bytearray = field(init=False)

    def __post_init__(self) -> None:
        if self.address not in (0x68, 0x69):
            raise ValueError(f"an MPU6050 answers at 0x68 or 0x69, not 0x{self.address:02X}")
        self.power_on_reset()

    def power_on_reset(self) -> None:
        self.regs = bytearray(128)
        self.regs[MPU_PWR_MGMT_1] = 0x40
        self.regs[MPU_WHO_AM_I] = self.who_am_i

    @property
    def sleeping(self) -> bool:
        return bool(self.regs[MPU_PWR_MGMT_1] & 0x40)

    @property
    def gyro_fs_sel(self) -> int:
        return (self.regs[MPU_GYRO_CONFIG] >> 3) & 0x3

    @property
    def accel_afs_sel(self) -> int:
        return (self.regs[MPU_ACCEL_CONFIG] >> 3) & 0x3

    @property
    def bypass(self) -> bool:
        return bool(self.regs[MPU_INT_PIN_CFG] & 0x02) and not self.regs[MPU_USER_CTRL] & 0x20

    def load(self, gyro: Sequence[int], accel: Sequence[int], temp: int = 0) -> None:
        """A new measurement: register values (two's complement LSB) of the configured ranges."""
        if self.sleeping:
            return
        data: list[int] = []
        for v in (*accel, temp, *gyro):
            data.extend(_int16_bytes(int(v)))
        self.regs[MPU_ACCEL_XOUT_H:MPU_GYRO_ZOUT_L + 1] = bytes(data)

    def write(self, register: int, data: bytes) -> None:
        for offset, byte in enumerate(data):
            reg = (register + offset) & 0x7F
            if reg == MPU_WHO_AM_I or MPU_ACCEL_XOUT_H <= reg <= MPU_GYRO_ZOUT_L:
                continue  # read-only
            if reg == MPU_PWR_MGMT_1 and byte & 0x80:
                self.power_on_reset()
                continue
            self.regs[reg] = byte

    def read(self, register: int, length: int) -> bytes:
        return bytes(self.regs[(register + i) & 0x7F] for i in range(length))


@dataclass
class HMC5883L:
    """The HMC5883L's register file; `load` presents one measurement (X, Y, Z register values)."""

    regs: bytearray = field(init=False)
    pointer: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        self.power_on_reset()

    def power_on_reset(self) -> None:
        self.regs = bytearray(13)
        self.regs[HMC_CRA] = 0x10
        self.regs[HMC_CRB] = 0x20
        self.regs[HMC_MODE] = 0x01
        self.regs[HMC_ID_A:HMC_ID_A + 3] = b"H43"
        self.pointer = 0

    @property
    def continuous(self) -> bool:
        return self.regs[HMC_MODE] & 0x03 == 0

    @property
    def gain_code(self) -> int:
        return self.regs[HMC_CRB] >> 5

    def load(self, mag: Sequence[int]) -> None:
        """A new measurement in continuous mode: X, Y, Z register values (-4096 = overflow)."""
        if not self.continuous:
            return
        x, y, z = (int(v) for v in mag)
        for v in (x, y, z):
            if not (-2048 <= v <= 2047 or v == -4096):
                raise ValueError(f"HMC5883L data registers hold -2048..2047 or -4096, got {v}")
        data = [*_int16_bytes(x), *_int16_bytes(z), *_int16_bytes(y)]
        self.regs[HMC_DATA_X_MSB:HMC_DATA_X_MSB + 6] = bytes(data)

    def write(self, register: int, data: bytes) -> None:
        self.pointer = register
        for byte in data:
            if self.pointer <= HMC_MODE:
                self.regs[self.pointer] = byte
            self._advance()

    def read(self, register: int, length: int) -> bytes:
        self.pointer = register
        out = []
        for _ in range(length):
            out.append(self.regs[self.pointer] if self.pointer < len(self.regs) else 0)
            self._advance()
        return bytes(out)

    def _advance(self) -> None:
        if self.pointer == 0x08:
            self.pointer = HMC_DATA_X_MSB
        elif self.pointer >= 0x0C:
            self.pointer = 0
        else:
            self.pointer += 1


@dataclass
class Gy87Board:
    """An MPU6050 with an HMC5883L on its auxiliary bus, as on GY-87 boards.

    The methods are those of smbus2.SMBus that an I2C driver uses, so a driver written for
    the Pi runs against it unchanged. The HMC5883L answers only while the MPU6050's bypass is
    on (or when `aux_on_host_bus` says it is wired to the host bus directly).
    """

    mpu: MPU6050 = field(default_factory=MPU6050)
    hmc: HMC5883L | None = field(default_factory=HMC5883L)
    aux_on_host_bus: bool = False

    def _chip(self, address: int) -> MPU6050 | HMC5883L:
        if address == self.mpu.address:
            return self.mpu
        if address == HMC5883L_ADDRESS and self.hmc is not None and (
                self.aux_on_host_bus or self.mpu.bypass):
            return self.hmc
        raise I2CNackError(f"no device acknowledged address 0x{address:02X}")

    def write_byte_data(self, i2c_addr: int, register: int, value: int) -> None:
        self._chip(i2c_addr).write(register, bytes([value & 0xFF]))

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: Sequence[int]) -> None:
        self._chip(i2c_addr).write(register, bytes(data))

    def read_byte_data(self, i2c_addr: int, register: int) -> int:
        return self._chip(i2c_addr).read(register, 1)[0]

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int) -> list[int]:
        if not 1 <= length <= 32:
            raise ValueError(f"an SMBus block read carries 1..32 bytes, got {length}")
        return list(self._chip(i2c_addr).read(register, length))

    def load(self, gyro: Sequence[int], accel: Sequence[int], mag: Sequence[int]) -> None:
        """The chips' next measurement (register values)."""
        self.mpu.load(gyro, accel)
        if self.hmc is not None:
            self.hmc.load(mag)
