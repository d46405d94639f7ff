"""The soft PLC's Modbus server answers edge-case requests exactly like the OpenPLC v3 runtime
(docs/modbus-parity.md).

Every expected reply below was measured on a real OpenPLC v3 runtime (webserver/core
modbus.cpp, 127.0.0.1:5502) with raw requests, not taken from the Modbus specification, which
the runtime does not follow on these points. The tests run against whatever
``plc_address`` is (tests/modbus/conftest.py): the soft PLC by default, the real runtime with
``--plc-host/--plc-port``, so the same file checks both sides of the parity.

Only areas Controller.st does not use are written (coils 800.., 4000.., 8184..8191; holding
registers 1100..1226 = %MW76.., 1500 = %MW476, 8188..8191 = %ML1023), and each test leaves
them at 0. Each test has its own connection, so one that a server drops fails that test only;
a test's first request waits for its reply, so no two connections are ever pending together
(the runtime can lose one of two clients that connect within its 100 ms accept period, see
test_disconnect.py).
"""

from __future__ import annotations

import socket
import struct
from collections.abc import Iterator

import pytest

pytestmark = pytest.mark.openplc_only

MBAP = struct.Struct(">HHHB")
ADDR_QTY = struct.Struct(">BHH")


class RawModbus:
    """One TCP connection sending hand-built PDUs (pymodbus refuses most of them)."""

    def __init__(self, address: tuple[str, int]) -> None:
        self.sock = socket.create_connection(address, timeout=3.0)
        self.transaction = 0

    def call(self, pdu: bytes, unit: int = 1) -> bytes:
        self.transaction = (self.transaction + 1) & 0xFFFF
        self.sock.sendall(MBAP.pack(self.transaction, 0, len(pdu) + 1, unit) + pdu)
        header = self._recv_exact(MBAP.size)
        transaction, protocol, length, reply_unit = MBAP.unpack(header)
        assert (transaction, protocol, reply_unit) == (self.transaction, 0, unit)
        return self._recv_exact(length - 1)

    def _recv_exact(self, n: int) -> bytes:
        data = b""
        while len(data) < n:
            chunk = self.sock.recv(n - len(data))
            assert chunk, "the PLC closed the connection"
            data += chunk
        return data

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def raw(plc_address: tuple[str, int]) -> Iterator[RawModbus]:
    conn = RawModbus(plc_address)
    try:
        yield conn
    finally:
        conn.close()


def req(function: int, address: int, quantity_or_value: int) -> bytes:
    return ADDR_QTY.pack(function, address, quantity_or_value)


def write_multi(function: int, address: int, quantity: int, data: bytes) -> bytes:
    return ADDR_QTY.pack(function, address, quantity) + bytes([len(data) & 0xFF]) + data


def exc(function: int, code: int) -> bytes:
    return bytes([function | 0x80, code])


def echo(pdu: bytes) -> bytes:
    """Reply of FC5/6/15/16: function, address and quantity/value of the request."""
    return pdu[:5]


def clear_coils(raw: RawModbus, start: int, count: int) -> None:
    pdu = write_multi(15, start, count, bytes((count + 7) // 8))
    assert raw.call(pdu) == echo(pdu)


def write_regs(raw: RawModbus, start: int, words: list[int]) -> None:
    pdu = write_multi(16, start, len(words), struct.pack(f">{len(words)}H", *words))
    assert raw.call(pdu) == echo(pdu)


# -- quantity 0: a normal, empty reply (the spec says exception 3) ---------------------------


@pytest.mark.parametrize(
    ("pdu", "reply"),
    [
        (req(1, 800, 0), b"\x01\x00"),
        (req(2, 0, 0), b"\x02\x00"),
        (req(3, 1500, 0), b"\x03\x00"),
        (req(4, 0, 0), b"\x04\x00"),
        # The address is not checked when nothing is read.
        (req(1, 65535, 0), b"\x01\x00"),
        (req(3, 65535, 0), b"\x03\x00"),
        (write_multi(15, 800, 0, b""), req(15, 800, 0)),
        (write_multi(16, 3048, 0, b""), req(16, 3048, 0)),
    ],
)
def test_quantity_zero_is_an_empty_reply(raw: RawModbus, pdu: bytes, reply: bytes) -> None:
    assert raw.call(pdu) == reply


# -- size limits: 255 data bytes (a one-byte byte count), exception 2 beyond --------------


def test_read_size_limits(raw: RawModbus) -> None:
    reply = raw.call(req(1, 0, 2040))
    assert reply[:2] == b"\x01\xff" and len(reply) == 2 + 255
    reply = raw.call(req(2, 0, 2040))
    assert reply[:2] == b"\x02\xff" and len(reply) == 2 + 255
    assert raw.call(req(1, 0, 2041)) == exc(1, 2)
    assert raw.call(req(2, 0, 2041)) == exc(2, 2)
    reply = raw.call(req(3, 1024, 127))
    assert reply[:2] == b"\x03\xfe" and len(reply) == 2 + 254
    reply = raw.call(req(4, 0, 127))
    assert reply[:2] == b"\x04\xfe" and len(reply) == 2 + 254
    assert raw.call(req(3, 1024, 128)) == exc(3, 2)
    assert raw.call(req(4, 0, 128)) == exc(4, 2)
    assert raw.call(req(3, 9000, 200)) == exc(3, 2)  # too many and out of range: still 2


def test_fc16_up_to_127_registers(raw: RawModbus) -> None:
    words = list(range(1, 125))
    # 124 registers: MBAP length 255, past the spec's 253-byte PDU; written.
    write_regs(raw, 1100, words)
    assert raw.call(req(3, 1100, 124)) == b"\x03\xf8" + struct.pack(">124H", *words)
    write_regs(raw, 1100, [0xA5A5] * 127)
    assert raw.call(req(3, 1100, 127)) == b"\x03\xfe" + b"\xa5" * 254
    # 128 registers need byte count 256, which does not fit its byte: exception 3.
    pdu = ADDR_QTY.pack(16, 1100, 128) + b"\x00" + bytes(256)
    assert raw.call(pdu) == exc(16, 3)
    write_regs(raw, 1100, [0] * 127)
    assert raw.call(req(3, 1100, 127)) == b"\x03\xfe" + bytes(254)


def test_fc15_up_to_2040_coils(raw: RawModbus) -> None:
    pdu = write_multi(15, 4000, 2040, b"\x5a" * 255)
    assert raw.call(pdu) == echo(pdu)
    assert raw.call(req(1, 4000, 2040)) == b"\x01\xff" + b"\x5a" * 255
    clear_coils(raw, 4000, 2040)
    assert raw.call(req(1, 4000, 2040)) == b"\x01\xff" + bytes(255)


@pytest.mark.parametrize(
    "pdu",
    [
        write_multi(16, 3048, 2, b"\x00\x00\x00"),  # byte count != 2 * quantity
        ADDR_QTY.pack(16, 3048, 2) + b"\x04\x00\x00",  # fewer data bytes than announced
        write_multi(15, 800, 9, b"\x01"),  # byte count too small for 9 coils
        write_multi(15, 800, 2, b"\x00\x00"),  # too large
        struct.pack(">BH", 3, 0),  # PDU shorter than address + quantity
        struct.pack(">BHB", 6, 1500, 0),
    ],
)
def test_malformed_requests_are_exception_3(raw: RawModbus, pdu: bytes) -> None:
    assert raw.call(pdu) == exc(pdu[0], 3)


def test_trailing_bytes_are_ignored(raw: RawModbus) -> None:
    assert raw.call(req(3, 1500, 1) + b"\x55") == b"\x03\x02\x00\x00"
    pdu = req(6, 1500, 7) + b"\x99\x99"
    assert raw.call(pdu) == echo(pdu)
    pdu = write_multi(16, 1500, 1, b"\x00\x09") + b"\x99"
    assert raw.call(pdu) == echo(pdu)
    assert raw.call(req(3, 1500, 1)) == b"\x03\x02\x00\x09"
    write_regs(raw, 1500, [0])


# -- FC5: any non-zero value is TRUE, echoed as sent -------------------------------------


@pytest.mark.parametrize("value", [0x0001, 0x1234, 0x00FF, 0xFFFF, 0xFF00])
def test_fc5_any_non_zero_value_is_true(raw: RawModbus, value: int) -> None:
    clear_coils(raw, 800, 8)
    assert raw.call(req(5, 800, value)) == req(5, 800, value)
    assert raw.call(req(1, 800, 1)) == b"\x01\x01\x01"
    assert raw.call(req(5, 800, 0)) == req(5, 800, 0)
    assert raw.call(req(1, 800, 1)) == b"\x01\x01\x00"


# -- bit tables work on whole bytes ------------------------------------------------------


@pytest.mark.parametrize(
    ("pdu", "reply"),
    [
        (req(1, 8184, 8), None),
        (req(1, 8184, 1), None),
        (req(1, 8185, 1), exc(1, 2)),  # 8185 + 8 > 8192 although 8185 exists
        (req(1, 8191, 1), exc(1, 2)),
        (req(1, 8184, 9), exc(1, 2)),
        (req(1, 8192, 1), exc(1, 2)),
        (req(2, 8184, 8), None),
        (req(2, 8185, 1), exc(2, 2)),
        (req(2, 8191, 1), exc(2, 2)),
        (req(5, 8191, 0), req(5, 8191, 0)),  # single coil: no rounding
        (req(5, 8192, 0), exc(5, 2)),
        (req(6, 8191, 0), req(6, 8191, 0)),
        (req(6, 8192, 0), exc(6, 2)),
        (write_multi(15, 8184, 8, b"\x00"), req(15, 8184, 8)),
        (write_multi(15, 8191, 1, b"\x00"), exc(15, 2)),
    ],
)
def test_end_of_bit_tables(raw: RawModbus, pdu: bytes, reply: bytes | None) -> None:
    got = raw.call(pdu)
    if reply is None:
        assert got == bytes([pdu[0], 1]) + got[2:] and len(got) == 3
    else:
        assert got == reply


def test_read_reply_padding_carries_neighbouring_bits(raw: RawModbus) -> None:
    clear_coils(raw, 800, 16)
    assert raw.call(req(5, 801, 0xFF00)) == req(5, 801, 0xFF00)
    # One coil asked for, but the byte from 800 comes back whole: 801 is in bit 1.
    assert raw.call(req(1, 800, 1)) == b"\x01\x01\x02"
    assert raw.call(req(1, 801, 1)) == b"\x01\x01\x01"
    assert raw.call(req(1, 799, 3)) == b"\x01\x01\x04"
    clear_coils(raw, 800, 16)


def test_fc15_writes_its_padding_bits(raw: RawModbus) -> None:
    clear_coils(raw, 800, 16)
    # Quantity 1, data byte 0xFF: coils 800..807 are all set, not only 800.
    pdu = write_multi(15, 800, 1, b"\xff")
    assert raw.call(pdu) == echo(pdu)
    assert raw.call(req(1, 800, 8)) == b"\x01\x01\xff"
    pdu = write_multi(15, 803, 2, b"\xf0")
    assert raw.call(pdu) == echo(pdu)
    assert raw.call(req(1, 800, 16)) == b"\x01\x02\x87\x07"
    # And so a one-coil FC15 of a conforming client (padding 0) clears 7 neighbours.
    pdu = write_multi(15, 800, 1, b"\x01")
    assert raw.call(pdu) == echo(pdu)
    assert raw.call(req(1, 800, 16)) == b"\x01\x02\x01\x07"
    clear_coils(raw, 800, 16)


# -- writes past the end of a table: the part inside is written, then exception 2 --------


def test_fc16_past_the_end_writes_the_part_inside(raw: RawModbus) -> None:
    write_regs(raw, 8188, [0, 0, 0, 0])
    pdu = write_multi(16, 8190, 3, struct.pack(">3H", 0x1111, 0x2222, 0x3333))
    assert raw.call(pdu) == exc(16, 2)
    assert raw.call(req(3, 8188, 4)) == b"\x03\x08" + struct.pack(">4H", 0, 0, 0x1111, 0x2222)
    assert raw.call(write_multi(16, 65535, 2, bytes(4))) == exc(16, 2)
    write_regs(raw, 8188, [0, 0, 0, 0])
    assert raw.call(req(3, 8188, 4)) == b"\x03\x08" + bytes(8)


def test_fc15_past_the_end_writes_the_part_inside(raw: RawModbus) -> None:
    clear_coils(raw, 8184, 8)
    assert raw.call(write_multi(15, 8190, 1, b"\x01")) == exc(15, 2)
    assert raw.call(req(1, 8184, 8)) == b"\x01\x01\x40"  # 8190 set
    # Quantity 2 at 8185, data 0x03: 8185..8191 get bits 0..6, so 8185 and 8186 are set.
    assert raw.call(write_multi(15, 8185, 2, b"\x03")) == exc(15, 2)
    assert raw.call(req(1, 8184, 8)) == b"\x01\x01\x06"
    clear_coils(raw, 8184, 8)
    assert raw.call(req(1, 8184, 8)) == b"\x01\x01\x00"
