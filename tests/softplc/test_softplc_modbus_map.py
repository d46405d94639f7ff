"""OpenPLC's Modbus map (docs/matiec-facts.md) through a real pymodbus client against our server.

Expected register values are computed here with struct.pack, independently of the
armbench.softplc.modbus_map helpers the server and client share.
"""

from __future__ import annotations

import struct
from collections.abc import Callable

import pytest
from softplc_fakes import raw_call

from armbench.softplc import ModbusServer, ProcessImage
from armbench.softplc import image as im
from armbench.softplc.modbus_client import ModbusError, PlcClient


def be_words(fmt: str, value: float | int) -> list[int]:
    raw = struct.pack(">" + fmt, value)
    return list(struct.unpack(f">{len(raw) // 2}H", raw))


def native_md(value: float) -> int:
    return int(struct.unpack("=I", struct.pack("=f", value))[0])


# -- bits -------------------------------------------------------------------------------------


def test_coils_are_qx(image: ProcessImage, client: PlcClient) -> None:
    client.write_coil(21, True)  # %QX2.5
    assert image.qx[21] == 1
    assert client.read_qx(2, 5) is True
    client.write_qx(2, 5, False)
    assert image.qx[21] == 0
    pattern = [bool((i * 7) % 3) for i in range(19)]
    client.write_coils(5, pattern)  # crosses byte boundaries of the bit field
    assert [bool(b) for b in image.qx[5:24]] == pattern
    assert client.read_coils(5, 19) == pattern
    image.qx[8191] = 1
    assert client.read_coils(8184, 8) == [False] * 7 + [True]


def test_discrete_inputs_are_ix(image: ProcessImage, client: PlcClient) -> None:
    image.ix[8 * 3 + 1] = 1  # %IX3.1
    image.ix[8191] = 1
    assert client.read_ix(3, 1) is True
    assert client.read_discrete_inputs(24, 3) == [False, True, False]
    # OpenPLC rounds bit requests up to whole bytes: 8191 is readable only as part of 8184..8191.
    assert client.read_discrete_inputs(8184, 8) == [False] * 7 + [True]
    big = client.read_discrete_inputs(0, 2000)
    assert big.count(True) == 1 and big[25]


def test_bit_tables_end_at_8191(client: PlcClient) -> None:
    calls: list[Callable[[], object]] = [
        lambda: client.read_coils(8192, 1),
        lambda: client.read_coils(8190, 3),
        lambda: client.read_discrete_inputs(8192, 1),
        lambda: client.write_coil(8192, True),
        lambda: client.write_coils(8190, [True] * 3),
    ]
    for call in calls:
        with pytest.raises(ModbusError) as err:
            call()
        assert err.value.code == 2


# -- registers --------------------------------------------------------------------------------


def test_input_registers_are_iw(image: ProcessImage, client: PlcClient) -> None:
    image.iw[0] = 11
    image.iw[1023] = 0xFFFF
    assert client.read_input_registers(0, 1) == [11]
    assert client.read_input_registers(1020, 4) == [0, 0, 0, 0xFFFF]
    for start, count in [(1024, 1), (1022, 3)]:
        with pytest.raises(ModbusError) as err:
            client.read_input_registers(start, count)
        assert err.value.code == 2


def test_holding_qw_and_mw(image: ProcessImage, client: PlcClient) -> None:
    client.write_register(0, 100)
    client.write_register(1023, 101)
    client.write_register(1024, 200)  # %MW0
    client.write_register(1024 + 1023, 201)  # %MW1023
    assert (image.qw[0], image.qw[1023], image.mw[0], image.mw[1023]) == (100, 101, 200, 201)
    client.write_registers(1022, [1, 2, 3, 4])  # %QW1022..%MW1
    assert list(image.qw[1022:1024]) == [1, 2] and list(image.mw[0:2]) == [3, 4]
    assert client.read_holding_registers(1021, 5) == [0, 1, 2, 3, 4]


def test_int_minus_two_reads_65534(image: ProcessImage, client: PlcClient) -> None:
    struct.pack_into("=h", image.raw, im.QW_OFFSET + 2 * 3, -2)
    assert client.read_holding_registers(3, 1) == [65534]
    assert client.read_int(3) == -2
    client.write_int(1024 + 5, -300)
    assert struct.unpack_from("=h", image.raw, im.MW_OFFSET + 2 * 5)[0] == -300


def test_real_word_order(image: ProcessImage, client: PlcClient) -> None:
    image.md[0] = native_md(1.5)
    assert client.read_holding_registers(2048, 2) == [0x3FC0, 0x0000] == be_words("f", 1.5)
    assert client.read_real(0) == 1.5
    client.write_real(7, -0.1)
    assert struct.unpack_from("=f", image.raw, im.MD_OFFSET + 4 * 7)[0] == pytest.approx(-0.1)
    assert client.read_holding_registers(2048 + 14, 2) == be_words("f", -0.1)


def test_dint_word_order(image: ProcessImage, client: PlcClient) -> None:
    image.md[1] = 0x12345678
    assert client.read_holding_registers(2050, 2) == [0x1234, 0x5678]
    client.write_dint(2, -5)
    assert struct.unpack_from("=i", image.raw, im.MD_OFFSET + 8)[0] == -5
    assert client.read_holding_registers(2052, 2) == be_words("i", -5)
    client.write_udint(1023, 0xCAFEBABE)
    assert image.md[1023] == 0xCAFEBABE
    assert client.read_holding_registers(4094, 2) == [0xCAFE, 0xBABE]


def test_lreal_and_lint_word_order(image: ProcessImage, client: PlcClient) -> None:
    struct.pack_into("=d", image.raw, im.ML_OFFSET, 3.14159)
    expected = [0x4009, 0x21F9, 0xF01B, 0x866E]
    assert be_words("d", 3.14159) == expected
    assert client.read_holding_registers(4096, 4) == expected
    assert client.read_lreal(0) == 3.14159
    client.write_lreal(1023, -2.5e-300)  # the last %ML: registers 8188..8191
    assert struct.unpack_from("=d", image.raw, im.ML_OFFSET + 8 * 1023)[0] == -2.5e-300
    assert client.read_holding_registers(8188, 4) == be_words("d", -2.5e-300)
    client.write_lint(3, -(2**62) - 7)
    assert struct.unpack_from("=q", image.raw, im.ML_OFFSET + 24)[0] == -(2**62) - 7


def test_single_register_writes_half_a_real(image: ProcessImage, client: PlcClient) -> None:
    image.md[0] = native_md(1.5)
    client.write_register(2049, 0x0001)  # low word only
    assert image.md[0] == 0x3FC00001
    client.write_register(2048, 0x4000)  # high word only
    assert image.md[0] == 0x40000001
    image.ml[0] = 0x1111222233334444
    client.write_register(4098, 0xABCD)  # third word of %ML0
    assert image.ml[0] == 0x11112222ABCD4444


def test_reads_and_writes_across_area_boundaries(image: ProcessImage, client: PlcClient) -> None:
    image.mw[1023] = 9
    image.md[0] = 0xAAAABBBB
    image.md[1023] = 0x01020304
    image.ml[0] = 0x0506070809101112
    assert client.read_holding_registers(2047, 3) == [9, 0xAAAA, 0xBBBB]
    assert client.read_holding_registers(4095, 3) == [0x0304, 0x0506, 0x0708]
    # Starts in the low half of %MD0 and ends in the high half of %MD2.
    client.write_registers(2049, [1, 2, 3, 4])
    assert list(image.md[0:3]) == [0xAAAA0001, 0x00020003, 0x0004_0000]
    # %MW1023, all of %MD0..%MD1023 is too long for one request; span %MD1023 → %ML1.
    values = list(range(1, 8))
    client.write_registers(4094, values)
    assert image.md[1023] == 0x00010002
    assert image.ml[0] == 0x0003000400050006
    assert image.ml[1] >> 48 == 7
    assert client.read_holding_registers(4094, 7) == values


def test_holding_ends_at_8191(client: PlcClient) -> None:
    client.write_register(8191, 1)
    assert client.read_holding_registers(8191, 1) == [1]
    calls: list[Callable[[], object]] = [
        lambda: client.read_holding_registers(8192, 1),
        lambda: client.read_holding_registers(8190, 3),
        lambda: client.write_register(8192, 1),
        lambda: client.write_registers(8190, [1, 2, 3]),
        lambda: client.read_holding_registers(65535, 1),
    ]
    for call in calls:
        with pytest.raises(ModbusError) as err:
            call()
        assert err.value.code == 2


# -- exceptions 1 and 3 (raw PDUs: pymodbus refuses bad quantities client-side) -------------


@pytest.mark.parametrize("function", [7, 8, 0x11, 0x16, 0x17, 0x2B, 0x7F])
def test_unknown_function_is_exception_1(server: ModbusServer, function: int) -> None:
    assert raw_call(server.port, bytes([function, 0, 0, 0, 1])) == bytes([function | 0x80, 1])


@pytest.mark.parametrize(
    "pdu",
    [
        # Quantity 0, oversized reads, FC5 values other than 0xFF00 and trailing bytes are not
        # exception 3 on OpenPLC: tests/modbus/test_modbus_openplc_parity.py.
        struct.pack(">BHHB", 15, 0, 9, 1) + b"\x01",  # byte count too small for 9 coils
        struct.pack(">BHHB", 15, 0, 2, 2) + bytes(2),  # byte count too large
        struct.pack(">BHHB", 16, 0, 124, 248) + bytes(200),  # fewer data bytes than announced
        struct.pack(">BHHB", 16, 0, 2, 4) + bytes(2),
        struct.pack(">BHHB", 16, 0, 2, 3) + bytes(3),  # byte count != 2 * quantity
        struct.pack(">BHHB", 16, 0, 128, 0) + bytes(256),  # 256 does not fit the byte count
        struct.pack(">BHH", 15, 0, 0),  # no byte count
        struct.pack(">BH", 3, 0),  # PDU too short for its function
    ],
)
def test_bad_quantity_or_shape_is_exception_3(server: ModbusServer, pdu: bytes) -> None:
    assert raw_call(server.port, pdu) == bytes([pdu[0] | 0x80, 3])


def test_oversized_read_is_exception_2(server: ModbusServer) -> None:
    # OpenPLC: more than 255 data bytes is "illegal data address", checked with the range.
    assert raw_call(server.port, struct.pack(">BHH", 3, 9000, 200)) == bytes([0x83, 2])
    assert raw_call(server.port, struct.pack(">BHH", 3, 0, 128)) == bytes([0x83, 2])
    assert raw_call(server.port, struct.pack(">BHH", 1, 0, 2041)) == bytes([0x81, 2])


def test_maximum_quantities(image: ProcessImage, server: ModbusServer) -> None:
    # OpenPLC's limits (255 data bytes), above the spec's 125/123 registers and 2000/1968 bits.
    reply = raw_call(server.port, struct.pack(">BHH", 3, 8191 - 126, 127))
    assert reply[:2] == bytes([3, 254]) and len(reply) == 256
    reply = raw_call(server.port, struct.pack(">BHHB", 16, 0, 127, 254) + b"\x00\x05" * 127)
    assert reply == struct.pack(">BHH", 16, 0, 127)
    assert list(image.qw[0:127]) == [5] * 127
    bits = b"\xff" * 255
    reply = raw_call(server.port, struct.pack(">BHHB", 15, 1, 2040, 255) + bits)
    assert reply == struct.pack(">BHH", 15, 1, 2040)
    assert image.qx[0] == 0 and all(image.qx[1:2041]) and image.qx[2041] == 0
    reply = raw_call(server.port, struct.pack(">BHH", 1, 0, 2040))
    assert reply[:2] == bytes([1, 255])
    assert int.from_bytes(reply[2:], "little") == ((1 << 2040) - 1) << 1 & ((1 << 2040) - 1)
