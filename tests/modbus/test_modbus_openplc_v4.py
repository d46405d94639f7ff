"""What OpenPLC v4's Modbus plugin answers that v3 did not (docs/modbus-parity.md, OpenPLC v3
and v4): each segment ends where the program's image ends (exception 02 past it, not inside),
reads may span segments, FC5/FC6 echo the value asked for, only unit id 1 is served.

Runs with ``--plc-flavor openplc-v4``, against the soft PLC serving the controller as v4 or a
v4 runtime running it, its Modbus server set up as docs/modbus-parity.md says (the counts the
map needs, the rest at their defaults): the segments expected here are computed from the
controller's map the same way."""

from __future__ import annotations

import socket
import struct
from collections.abc import Iterator

import pytest

from armbench.registermap import SOURCES, program_map
from armbench.softplc.modbus_client import ModbusError, PlcClient
from armbench.softplc.openplc_v4 import Segments, V4Settings

pytestmark = pytest.mark.openplc_v4_only

ILLEGAL_DATA_ADDRESS = 2


@pytest.fixture(scope="module")
def segments() -> Segments:
    pm = program_map([str(p) for p in SOURCES])
    return V4Settings().segments([r.location for r in pm.registers]
                                 + [u.location for u in pm.unreachable])


@pytest.fixture
def modbus(plc_address: tuple[str, int]) -> Iterator[PlcClient]:
    with PlcClient(*plc_address) as client:
        yield client


def raw(address: tuple[str, int], pdu: bytes, unit: int = 1,
        timeout_s: float = 1.0) -> bytes | None:
    """The reply PDU to one request on a connection of its own (None: no reply)."""
    with socket.create_connection(address, timeout=timeout_s) as s:
        s.sendall(struct.pack(">HHHB", 0x1234, 0, len(pdu) + 1, unit) + pdu)
        data = b""
        try:
            while len(data) < 6 or len(data) < 6 + struct.unpack_from(">H", data, 4)[0]:
                chunk = s.recv(512)
                if not chunk:
                    return None
                data += chunk
        except TimeoutError:
            return None
    assert data[:2] == b"\x12\x34"
    return data[7:]


def refused(read: object) -> int:
    """The exception code a read raises, 0 when it is answered."""
    try:
        read()  # type: ignore[operator]
    except ModbusError as exc:
        return exc.code
    return 0


def test_each_segment_ends_where_the_program_needs_it(modbus: PlcClient,
                                                     segments: Segments) -> None:
    """The last element of every segment answers, the first past it is exception 02 (v3
    answered zeros up to 8192 coils, discrete inputs and holding registers, 1024 input
    registers)."""
    tables = {"coil": (modbus.read_coils, segments.coils),
              "discrete input": (modbus.read_discrete_inputs, segments.ix_bits),
              "input register": (modbus.read_input_registers, segments.iw_count),
              "holding register": (modbus.read_holding_registers, segments.holding_registers)}
    for name, (read, size) in tables.items():
        assert size > 0, name
        assert refused(lambda r=read, s=size: r(s - 1, 1)) == 0, f"last {name} ({size - 1})"
        assert refused(lambda r=read, s=size: r(s, 1)) == ILLEGAL_DATA_ADDRESS, \
            f"first {name} past the segment ({size})"
    # the controller's segments: %QX0 and %IX0 (one byte each), %IW0..9, holding registers
    # %QW 0..1023, %MW 1024..2047, %MD 2048..3847 (%MD0..899)
    assert (segments.coils, segments.ix_bits, segments.iw_count) == (8, 8, 10)
    assert segments.holding_start("md_count") == 2048 and segments.holding_registers == 3848


def test_inside_a_segment_unused_registers_answer(modbus: PlcClient) -> None:
    """%QW16..1023 and %MW10..1023 hold no variable of the controller but lie inside the
    segments the counts set: they answer (zeros), as on v3."""
    assert modbus.read_holding_registers(16, 125) == [0] * 125
    assert modbus.read_holding_registers(1023, 1) == [0]
    assert modbus.read_holding_registers(2047 - 124, 125) == [0] * 125


def test_writes_past_a_segment_are_refused(modbus: PlcClient, segments: Segments) -> None:
    end = segments.holding_registers
    for write in (lambda: modbus.write_register(end, 1),
                  lambda: modbus.write_registers(end - 2, [0, 0, 0, 0]),
                  lambda: modbus.write_coil(segments.coils, True),
                  lambda: modbus.write_coils(segments.coils - 4, [False] * 8)):
        assert refused(write) == ILLEGAL_DATA_ADDRESS


def test_reads_span_segment_borders(modbus: PlcClient, segments: Segments) -> None:
    """The holding segments lie head to tail: one read crosses from %QW into %MW and from
    %MW into %MD; only the end of the last one refuses a read."""
    mw, md, end = (segments.holding_start("mw_count"), segments.holding_start("md_count"),
                   segments.holding_registers)
    assert len(modbus.read_holding_registers(mw - 4, 8)) == 8
    assert len(modbus.read_holding_registers(md - 4, 8)) == 8
    assert len(modbus.read_holding_registers(end - 8, 8)) == 8
    assert refused(lambda: modbus.read_holding_registers(end - 4, 8)) == ILLEGAL_DATA_ADDRESS
    # the whole table in reads of 125, the last one ending at its end
    start = 0
    while start < end:
        n = min(125, end - start)
        assert len(modbus.read_holding_registers(start, n)) == n
        start += n


def test_the_longest_read_is_the_one_whose_reply_encodes(plc_address: tuple[str, int]) -> None:
    """pymodbus checks no read quantity: 127 registers (254 bytes) are answered, 128 get no
    reply at all (its byte count does not fit the reply); quantity 0 is an empty reply."""
    reply = raw(plc_address, struct.pack(">BHH", 3, 0, 127))
    assert reply is not None and reply[:2] == b"\x03\xfe" and len(reply) == 2 + 254
    assert raw(plc_address, struct.pack(">BHH", 3, 0, 128), timeout_s=0.5) is None
    assert raw(plc_address, struct.pack(">BHH", 3, 0, 0)) == b"\x03\x00"
    # function 16: 1..123 registers, else exception 03 (v3 took 127)
    assert raw(plc_address, struct.pack(">BHHB", 16, 100, 124, 248) + bytes(248)) == b"\x90\x03"


def test_fc5_and_fc6_echo_the_value_asked_for(plc_address: tuple[str, int],
                                              modbus: PlcClient) -> None:
    """The plugin answers FC6 with the value written (not a read-back of the image, which
    the journal has not reached yet), FC5 with 0xFF00 or 0x0000: pymodbus decodes any
    non-zero value as TRUE (v3 echoed the value sent, 0x1234 included)."""
    spare = 1024 + 100  # %MW100: inside the %MW segment, no variable of the controller
    before = modbus.read_holding_registers(spare, 1)[0]
    try:
        assert raw(plc_address, struct.pack(">BHH", 6, spare, 0xBEEF)) == \
            struct.pack(">BHH", 6, spare, 0xBEEF)
        assert modbus.read_holding_registers(spare, 1) == [0xBEEF]
    finally:
        modbus.write_register(spare, before)
    coil = 7  # %QX0.7: inside the coil segment (its byte), no variable of the controller
    try:
        for value, echo in ((0x1234, 0xFF00), (0x0000, 0x0000), (0xFF00, 0xFF00)):
            assert raw(plc_address, struct.pack(">BHH", 5, coil, value)) == \
                struct.pack(">BHH", 5, coil, echo)
            assert modbus.read_coils(coil, 1) == [value != 0]
    finally:
        modbus.write_coil(coil, False)


def test_only_unit_id_1_is_served(plc_address: tuple[str, int]) -> None:
    """ModbusServerContext(devices={1: ...}, single=False): any other unit id (0 included) is
    exception 0x0B, gateway target failed to respond (v3 answered every unit id)."""
    for unit in (0, 2, 255):
        assert raw(plc_address, struct.pack(">BHH", 3, 0, 1), unit=unit) == b"\x83\x0b"
    assert raw(plc_address, struct.pack(">BHH", 3, 0, 1), unit=1)[:2] == b"\x03\x02"  # type: ignore[index]
