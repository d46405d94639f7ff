"""A small typed Modbus TCP client for talking to the soft PLC or a real PLC, with
REAL/DINT/LREAL helpers by %MD/%ML index in OpenPLC's map and word order (for another flavor's
layout, read and write by table and address: :meth:`PlcClient.read_table`, and encode with
:class:`armbench.registermap.Register`).

This is the only module of the package that imports pymodbus: its API moves between minor
releases, so every use of it is kept here. It works with the pymodbus versions pyproject.toml
allows, tested at both ends: ``device_id`` is the unit id keyword since 3.10, and 3.10.0 sends
and reads lists of more than 8 coils in the wrong bit order, so 3.11 is the oldest.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException
from pymodbus.pdu import ModbusPDU

from . import modbus_map as mm


class ModbusError(Exception):
    """The server answered with a Modbus exception response (``code`` 1, 2, 3, ...)."""

    def __init__(self, function: int, code: int) -> None:
        super().__init__(f"function {function}: Modbus exception {code}")
        self.function = function
        self.code = code


class ModbusIoError(Exception):
    """No usable answer: not connected, timeout, or a garbled response."""


# Function codes whose request changes nothing in the PLC: after a lost or garbled reply they
# are sent again on a new connection. Writes never are (a write may have landed even when its
# reply was lost; the caller decides, e.g. the mailbox handshake reads its block back).
_READS = frozenset({1, 2, 3, 4})


@dataclass
class PlcClient:
    """Synchronous client; use as a context manager or call :meth:`connect`/:meth:`close`."""

    host: str = "127.0.0.1"
    port: int = 5020
    timeout_s: float = 3.0
    device_id: int = 1
    _client: ModbusTcpClient = field(init=False, repr=False)

    # The first reply on a new connection is awaited this long (doubled at each new try, at
    # most timeout_s): OpenPLC v3's accept loop can hand a new socket to no thread at all (two
    # threads get the next one), and such a connection is never answered.
    first_reply_s: float = 1.0
    # False: a read is tried once, its reply awaited timeout_s (a probe that tells a silent
    # peer from a garbled one by the time it waited)
    retry_reads: bool = True
    _served: bool = field(default=False, init=False, repr=False)

    def __post_init__(self) -> None:
        # retries=0: a request that timed out may still have been executed; resending a write
        # silently would hide that from the tests.
        self._client = ModbusTcpClient(
            self.host, port=self.port, timeout=self.timeout_s, retries=0
        )

    # pymodbus 3.16 leaves ModbusTcpClient.connect/close unannotated.
    def connect(self) -> None:
        self._served = False
        if not self._client.connect():  # type: ignore[no-untyped-call]
            raise ModbusIoError(f"cannot connect to {self.host}:{self.port}")

    def close(self) -> None:
        self._served = False
        self._client.close()  # type: ignore[no-untyped-call]

    def __enter__(self) -> PlcClient:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _set_reply_timeout(self, seconds: float) -> None:
        self._client.comm_params.timeout_connect = seconds

    def _stream_dirty(self) -> bool:
        """Bytes wait on the connection while no request is outstanding: the tail of a reply
        sent longer than its MBAP length says (OpenPLC v3 writes each reply with a length
        that another connection's thread may have just set). Whatever comes next on this
        stream cannot be trusted."""
        sock = self._client.socket
        if sock is None:
            return False
        try:
            return bool(sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT))
        except (BlockingIOError, InterruptedError):
            return False
        except OSError:
            return True  # reset: reconnect before sending

    def _open_served(self, deadline: float) -> None:
        """Make sure the connection is open and has answered once: a new connection is
        proved by a read (exception replies count: the server read the request), reconnecting
        while it stays silent, so a write is never sent on a connection nobody serves."""
        wait = self.first_reply_s
        while True:
            if self._client.socket is None:
                self.connect()
            if self._served:
                return
            self._set_reply_timeout(max(0.05, min(wait, deadline - time.monotonic())))
            try:
                response = self._client.read_holding_registers(0, count=1,
                                                               device_id=self.device_id)
                consistent = response.function_code & 0x7F == 3
            except (ModbusException, OSError):
                consistent = False
            finally:
                self._set_reply_timeout(self.timeout_s)
            if consistent and not self._stream_dirty():
                self._served = True
                return
            self.close()
            if time.monotonic() >= deadline:
                raise ModbusIoError(f"{self.host}:{self.port}: no answer on a new connection "
                                    f"for {self.timeout_s:g} s")
            wait = min(2.0 * wait, self.timeout_s)

    def _check(self, request: Callable[[], ModbusPDU], function: int,
               consistent: Callable[[ModbusPDU], bool] | None = None) -> ModbusPDU:
        """Send ``request``; pymodbus's own errors (connection lost, no answer) become
        :class:`ModbusIoError`, a Modbus exception reply :class:`ModbusError`.

        A reply that does not fit the request (another function code, another count or
        address: ``consistent`` says), or bytes left over after it, drops the connection, as
        does any failure: a garbled stream is never read on. Reads (functions 1-4) are then
        sent again on a new connection until ``timeout_s`` (at least once); writes raise."""
        deadline = time.monotonic() + self.timeout_s
        tries = 0
        while True:
            tries += 1
            if self._served and self._stream_dirty():
                self.close()
            if function not in _READS:
                self._open_served(deadline)
            elif self._client.socket is None:
                self.connect()
            retry = function in _READS and self.retry_reads
            fresh = not self._served and retry
            if fresh:
                self._set_reply_timeout(max(0.05, min(self.first_reply_s,
                                                      deadline - time.monotonic())))
            problem = ""
            try:
                response = request()
            except ModbusException as exc:
                problem = str(exc)
            except OSError as exc:
                # pymodbus's sync client lets a reset connection (ECONNRESET from recv)
                # through as it is; it is a broken connection like any other (OpenPLC v3's
                # accept race resets them: a soak client died of it)
                problem = f"connection broken ({exc})"
            finally:
                if fresh:
                    self._set_reply_timeout(self.timeout_s)
            if not problem:
                if response.function_code & 0x7F != function:
                    problem = (f"garbled reply: function code {response.function_code} "
                               f"to a request of function {function}")
                elif not response.isError() and consistent is not None \
                        and not consistent(response):
                    problem = "garbled reply: its contents do not fit the request"
            if not problem:
                self._served = True
                if response.isError():
                    raise ModbusError(function, response.exception_code)
                return response
            self.close()
            if not retry or (time.monotonic() >= deadline and tries > 1):
                raise ModbusIoError(f"{self.host}:{self.port}: function {function}: {problem}")
            # a read is sent again at least once, however long its first reply was awaited
            deadline = max(deadline, time.monotonic() + self.timeout_s) if tries == 1 \
                else deadline

    # -- raw tables ------------------------------------------------------------------------

    def read_coils(self, address: int, count: int = 1) -> list[bool]:
        r = self._check(lambda: self._client.read_coils(address, count=count,
                                                       device_id=self.device_id), 1,
                        lambda r: len(r.bits) == 8 * -(-count // 8))
        # pymodbus pads bits to a whole byte; the caller asked for exactly `count`.
        return list(r.bits[:count])

    def read_discrete_inputs(self, address: int, count: int = 1) -> list[bool]:
        r = self._check(lambda: self._client.read_discrete_inputs(
            address, count=count, device_id=self.device_id), 2,
            lambda r: len(r.bits) == 8 * -(-count // 8))
        return list(r.bits[:count])

    def read_holding_registers(self, address: int, count: int = 1) -> list[int]:
        r = self._check(lambda: self._client.read_holding_registers(
            address, count=count, device_id=self.device_id), 3,
            lambda r: len(r.registers) == count)
        return list(r.registers)

    def read_input_registers(self, address: int, count: int = 1) -> list[int]:
        r = self._check(lambda: self._client.read_input_registers(
            address, count=count, device_id=self.device_id), 4,
            lambda r: len(r.registers) == count)
        return list(r.registers)

    def read_table(self, table: str, address: int, count: int = 1) -> list[int]:
        """``count`` values of ``table`` ("holding", "input", "coil", "discrete", as
        :class:`armbench.registermap.Register` names them) with its read function (3, 4, 1,
        2); bits as 0 or 1."""
        if table == "holding":
            return self.read_holding_registers(address, count)
        if table == "input":
            return self.read_input_registers(address, count)
        if table == "coil":
            return [int(b) for b in self.read_coils(address, count)]
        if table == "discrete":
            return [int(b) for b in self.read_discrete_inputs(address, count)]
        raise ValueError(f"no Modbus table {table!r}: holding, input, coil or discrete")

    def write_coil(self, address: int, value: bool) -> None:
        self._check(lambda: self._client.write_coil(address, value, device_id=self.device_id), 5,
                    lambda r: r.address == address)

    def write_register(self, address: int, value: int) -> None:
        self._check(lambda: self._client.write_register(address, value,
                                                        device_id=self.device_id), 6,
                    lambda r: r.address == address and r.registers == [value])

    def write_coils(self, address: int, values: Sequence[bool]) -> None:
        self._check(lambda: self._client.write_coils(address, list(values),
                                                     device_id=self.device_id), 15,
                    lambda r: (r.address, r.count) == (address, len(values)))

    def write_registers(self, address: int, values: Sequence[int]) -> None:
        self._check(lambda: self._client.write_registers(address, list(values),
                                                         device_id=self.device_id), 16,
                    lambda r: (r.address, r.count) == (address, len(values)))

    # -- located variables -----------------------------------------------------------------

    def read_qx(self, byte: int, bit: int) -> bool:
        return self.read_coils(mm.bit_address(byte, bit))[0]

    def write_qx(self, byte: int, bit: int, value: bool) -> None:
        self.write_coil(mm.bit_address(byte, bit), value)

    def read_ix(self, byte: int, bit: int) -> bool:
        return self.read_discrete_inputs(mm.bit_address(byte, bit))[0]

    def read_int(self, address: int) -> int:
        """A signed 16-bit register (INT at %QW/%MW/%IW)."""
        return mm.word_to_int(self.read_holding_registers(address)[0])

    def write_int(self, address: int, value: int) -> None:
        self.write_register(address, mm.int_to_word(value))

    # The wide helpers take the %MD/%ML index, not a register address, and always move whole
    # values with one request: function 16 is atomic between scans, two 06 writes are not.

    def read_real(self, md_index: int) -> float:
        return mm.words_to_real(self.read_holding_registers(mm.md_address(md_index), 2))

    def write_real(self, md_index: int, value: float) -> None:
        self.write_registers(mm.md_address(md_index), mm.real_to_words(value))

    def read_dint(self, md_index: int) -> int:
        return mm.words_to_dint(self.read_holding_registers(mm.md_address(md_index), 2))

    def write_dint(self, md_index: int, value: int) -> None:
        self.write_registers(mm.md_address(md_index), mm.dint_to_words(value))

    def read_udint(self, md_index: int) -> int:
        return mm.words_to_udint(self.read_holding_registers(mm.md_address(md_index), 2))

    def write_udint(self, md_index: int, value: int) -> None:
        self.write_registers(mm.md_address(md_index), mm.udint_to_words(value))

    def read_lreal(self, ml_index: int) -> float:
        return mm.words_to_lreal(self.read_holding_registers(mm.ml_address(ml_index), 4))

    def write_lreal(self, ml_index: int, value: float) -> None:
        self.write_registers(mm.ml_address(ml_index), mm.lreal_to_words(value))

    def read_lint(self, ml_index: int) -> int:
        return mm.words_to_lint(self.read_holding_registers(mm.ml_address(ml_index), 4))

    def write_lint(self, ml_index: int, value: int) -> None:
        self.write_registers(mm.ml_address(ml_index), mm.lint_to_words(value))
