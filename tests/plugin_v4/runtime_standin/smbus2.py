"""STAND-IN, for the tests only, of the smbus2 package (0.6) the plugin's venv holds on a Pi:
``SMBus(n)`` opens simulated bus n of ``BUSES`` (a test puts v4_standin.SimI2CBus objects
there) and fails like os.open("/dev/i2c-n") when there is none; transfers keep smbus2's
signatures and its 32-byte block limit. Installed by the tests into the stand-in runtime
tree's venv (venvs/arm_io/lib/pythonX.Y/site-packages/), where plugins.conf points."""

from __future__ import annotations

import errno
from typing import Any

BUSES: dict[int, Any] = {}
ATTEMPTS: list[int] = []  # every SMBus(n) opened or tried, for the tests to count
I2C_SMBUS_BLOCK_MAX = 32


class SMBus:
    def __init__(self, bus: int | str | None = None, force: bool = False) -> None:
        self.fd: int | None = None
        if bus is None:
            return
        number = bus if isinstance(bus, int) else int(str(bus).rsplit("-", 1)[-1])
        ATTEMPTS.append(number)
        sim = BUSES.get(number)
        if sim is None:
            raise FileNotFoundError(errno.ENOENT, "No such file or directory",
                                    f"/dev/i2c-{number}")
        self._sim = sim
        self.fd = sim.open()

    def __enter__(self) -> SMBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self.fd is not None:
            self._sim.close()
            self.fd = None

    def _open_sim(self) -> Any:
        if self.fd is None:
            raise OSError(errno.EBADF, "Bad file descriptor")
        return self._sim

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: list[int],
                             force: bool | None = None) -> None:
        if len(data) > I2C_SMBUS_BLOCK_MAX:
            raise ValueError(f"Data length cannot exceed {I2C_SMBUS_BLOCK_MAX} bytes")
        self._open_sim().write(i2c_addr, register, bytes(data))

    def write_byte_data(self, i2c_addr: int, register: int, value: int,
                        force: bool | None = None) -> None:
        self._open_sim().write(i2c_addr, register, bytes([value & 0xFF]))

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int,
                            force: bool | None = None) -> list[int]:
        if length > I2C_SMBUS_BLOCK_MAX:
            raise ValueError(f"Desired block length over {I2C_SMBUS_BLOCK_MAX} bytes")
        return list(self._open_sim().read(i2c_addr, register, length))

    def read_byte_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        return int(self._open_sim().read(i2c_addr, register, 1)[0])
