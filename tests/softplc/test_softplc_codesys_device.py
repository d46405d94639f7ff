"""The soft PLC's CODESYS Modbus TCP Server Device (armbench.softplc.codesys_device): the
data model of CODESYS's documentation (holding registers = the %I data, input registers = the
%Q data, coils and discrete inputs = their bits), copied in and out of the image each scan,
and the Modbus specification's request rules.

Expected words are written out from the values' bit patterns here (struct.pack with '<' and
the words assembled by hand from its bytes, or the hexadecimal patterns of
docs/matiec-facts.md reversed word by word), not from armbench.softplc.modbus_map.
"""

from __future__ import annotations

import math
import struct
import threading

import pytest
from softplc_fakes import FakeProgram, raw_call, task

from armbench.softplc import ProcessImage, SoftPlc
from armbench.softplc.codesys_device import CodesysDevice, bind
from armbench.softplc.modbus_client import ModbusError, PlcClient
from armbench.softplc.modbus_server import ModbusServer

# (name, declared address: where the program and the image have it, CODESYS address)
LAYOUT = (
    ("InReal", "%MD0", "%ID0"),  # holding 0..1
    ("InInt", "%IW3", "%IW2"),  # holding 2
    ("InBit", "%IX0.0", "%IX6.1"),  # coil 49: bit 1 of register 3's low byte
    ("InLint", "%ML5", "%IL1"),  # holding 4..7
    ("OutReal", "%MD1", "%QD0"),  # input 0..1
    ("OutBit", "%QX0.0", "%QX4.7"),  # discrete input 39: bit 7 of register 2 (its low byte)
    ("OutLreal", "%ML0", "%QL1"),  # input 4..7
    ("OutDint", "%MD2", "%QD4"),  # input 8..9
    ("OutWord", "%QW7", "%QW10"),  # input 10
)


def le_words(fmt: str, value: float | int) -> list[int]:
    """A value's registers least significant word first, from its little-endian bytes."""
    b = struct.pack("<" + fmt, value)
    return [b[i] | b[i + 1] << 8 for i in range(0, len(b), 2)]


def native(fmt: str, code: str, value: float | int) -> int:
    """The image's element holding ``value`` (native order, as the compiled program has it)."""
    return int(struct.unpack("=" + code, struct.pack("=" + fmt, value))[0])


@pytest.fixture
def device() -> CodesysDevice:
    return CodesysDevice(ProcessImage.allocate(), threading.Lock(),
                         [bind(*row) for row in LAYOUT], holding_registers=8,
                         input_registers=12)


def req(function: int, address: int, value: int) -> bytes:
    return struct.pack(">BHH", function, address, value)


def fc16(address: int, words: list[int]) -> bytes:
    return struct.pack(f">BHHB{len(words)}H", 16, address, len(words), 2 * len(words), *words)


def read_words(device: CodesysDevice, function: int, address: int, count: int) -> list[int]:
    reply = device.handle(req(function, address, count))
    assert reply[:2] == bytes((function, 2 * count)), reply
    return list(struct.unpack(f">{count}H", reply[2:]))


def test_words_of_the_reference_patterns() -> None:
    """The helper above against docs/matiec-facts.md's MSW-first patterns, reversed."""
    assert le_words("f", 1.5) == [0x0000, 0x3FC0]
    assert le_words("d", 3.14159) == [0x866E, 0xF01B, 0x21F9, 0x4009]
    assert le_words("i", 0x12345678) == [0x5678, 0x1234]


def test_outputs_are_input_registers_least_significant_word_first(
        device: CodesysDevice) -> None:
    im = device.image
    im.md[1] = native("f", "I", 1.5)
    im.ml[0] = native("d", "Q", 3.14159)
    im.md[2] = 0x12345678
    im.qw[7] = 0xBEEF
    im.qx[0] = 1
    assert read_words(device, 4, 0, 11) == [0] * 11  # nothing copied before a scan ends
    device.write_outputs()
    assert read_words(device, 4, 0, 11) == [0x0000, 0x3FC0, 0x0080, 0,
                                            0x866E, 0xF01B, 0x21F9, 0x4009,
                                            0x5678, 0x1234, 0xBEEF]
    # the BOOL is discrete input 39 = 8 * 4 + 7
    assert device.handle(req(2, 32, 8)) == bytes((2, 1, 0x80))
    assert device.handle(req(2, 39, 1)) == bytes((2, 1, 1))
    im.qx[0] = 0
    device.write_outputs()
    assert device.handle(req(2, 39, 1)) == bytes((2, 1, 0))
    # outputs are not holding registers: function 3 reads the %I data
    assert read_words(device, 3, 0, 2) == [0, 0]


def test_holding_registers_reach_the_program_when_a_scan_starts(
        device: CodesysDevice) -> None:
    im = device.image
    words = le_words("f", 2.5)
    assert device.handle(fc16(0, words)) == req(16, 0, 2)
    assert device.handle(req(6, 2, 0xFFFE)) == req(6, 2, 0xFFFE)  # INT -2
    assert device.handle(req(5, 49, 0xFF00)) == req(5, 49, 0xFF00)
    assert device.handle(fc16(4, le_words("q", -3))) == req(16, 4, 4)
    assert im.md[0] == 0 and im.iw[3] == 0 and im.ix[0] == 0  # not before the scan
    device.read_inputs()
    assert struct.unpack("=f", struct.pack("=I", im.md[0]))[0] == 2.5
    assert im.iw[3] == 0xFFFE
    assert im.ix[0] == 1
    assert struct.unpack("=q", struct.pack("=Q", im.ml[5]))[0] == -3
    assert read_words(device, 3, 0, 3) == [*words, 0xFFFE]


def test_a_declared_initial_value_of_an_input_does_not_survive(device: CodesysDevice) -> None:
    """The holding registers' data overwrites the %I variables at every scan: a program's
    initial value there is gone after the first one, as on CODESYS."""
    device.image.md[0] = native("f", "I", 20.0)  # InReal := 20.0 in the declaration
    device.read_inputs()
    assert device.image.md[0] == 0


def test_coils_are_the_bits_of_the_holding_registers(device: CodesysDevice) -> None:
    assert device.handle(req(5, 49, 0xFF00)) == req(5, 49, 0xFF00)
    assert read_words(device, 3, 3, 1) == [0x0002]  # byte 6 is register 3's low byte
    # 16 coils from 48 = register 3 bit for bit; the neighbours keep their bits
    device.handle(req(5, 64, 0xFF00))
    pdu = struct.pack(">BHHB2B", 15, 48, 16, 2, 0x34, 0x12)
    assert device.handle(pdu) == pdu[:5]
    assert read_words(device, 3, 3, 2) == [0x1234, 0x0001]
    assert device.handle(req(1, 48, 17)) == bytes((1, 3, 0x34, 0x12, 0x01))
    # unaligned: 5 coils from 50 are bits 2..6 of 0x34
    assert device.handle(req(1, 50, 5)) == bytes((1, 1, (0x34 >> 2) & 0x1F))


@pytest.mark.parametrize(("pdu", "reply"), [
    (req(3, 0, 0), bytes((0x83, 3))),  # quantity 0
    (req(3, 0, 126), bytes((0x83, 3))),  # more than 125 registers
    (req(3, 7, 2), bytes((0x83, 2))),  # past the 8 holding registers
    (req(4, 11, 2), bytes((0x84, 2))),  # past the 12 input registers
    (req(1, 0, 2001), bytes((0x81, 3))),
    (req(1, 127, 2), bytes((0x81, 2))),  # 8 registers = 128 coils
    (req(2, 191, 2), bytes((0x82, 2))),  # 12 registers = 192 discrete inputs
    (req(5, 0, 0x1234), bytes((0x85, 3))),  # function 5 takes 0x0000 or 0xFF00 only
    (req(5, 128, 0xFF00), bytes((0x85, 2))),
    (req(6, 8, 1), bytes((0x86, 2))),
    (fc16(0, [0] * 124), bytes((0x90, 3))),  # more than 123 registers
    (struct.pack(">BHHB2H", 16, 0, 2, 3, 1, 2), bytes((0x90, 3))),  # byte count 3 for 2
    (fc16(7, [1, 2]), bytes((0x90, 2))),
    (struct.pack(">BHHB", 15, 0, 0, 0), bytes((0x8F, 3))),  # quantity 0
    (struct.pack(">BHHBB", 15, 0, 9, 1, 0xFF), bytes((0x8F, 3))),  # 9 coils need 2 bytes
    (struct.pack(">BHHBB", 15, 127, 2, 1, 3), bytes((0x8F, 2))),
    (req(23, 0, 1), bytes((0x97, 1))),  # not served
    (bytes((3, 0, 0)), bytes((0x83, 3))),  # shorter than a request
])
def test_requests_follow_the_modbus_specification(device: CodesysDevice, pdu: bytes,
                                                  reply: bytes) -> None:
    assert device.handle(pdu) == reply


def test_a_rejected_write_changes_nothing(device: CodesysDevice) -> None:
    device.handle(fc16(6, [1, 2, 3]))  # one register past the end
    device.handle(struct.pack(">BHHB", 15, 120, 9, 2) + b"\xff\xff")
    assert read_words(device, 3, 0, 8) == [0] * 8


def test_bindings_the_image_or_the_device_cannot_hold() -> None:
    with pytest.raises(ValueError, match=r"Flag \(%MX0.1\) cannot be served in the CODESYS "
                                         r"layout: %MX0.1 is not in the process image"):
        bind("Flag", "%MX0.1", "%IX4.0")
    with pytest.raises(ValueError, match=r"the Modbus device serves %I and %Q only"):
        bind("Level", "%MD0", "%MD0")
    with pytest.raises(ValueError, match=r"Big lies past the device's input registers \(2\)"):
        CodesysDevice(ProcessImage.allocate(), threading.Lock(),
                      [bind("Big", "%ML0", "%QL0")], 1, 2)
    with pytest.raises(ValueError, match=r"Bit and Real share bit 7 of byte 2 of the %Q data"):
        CodesysDevice(ProcessImage.allocate(), threading.Lock(),
                      [bind("Real", "%MD0", "%QD0"), bind("Bit", "%QX0.0", "%QX2.7")], 1, 2)


def test_the_scan_copies_around_each_task_and_not_after_a_fault() -> None:
    """A program that doubles InReal into OutReal: a write lands at the next scan, the result
    shows once that scan has ended; a faulted scan leaves the input registers as they were."""
    def double(image: ProcessImage, now_ns: int) -> None:
        value = struct.unpack("=f", struct.pack("=I", image.md[0]))[0]
        image.md[1] = native("f", "I", 2.0 * value)

    prog = FakeProgram([task("Main", 10.0)], {"Main": double}, fault_at={"Main": 3})
    lock = threading.Lock()
    device = CodesysDevice(prog.image, lock, [bind(*row) for row in LAYOUT], 8, 12)
    plc = SoftPlc(prog, lock=lock, io=device)
    plc.run()
    device.handle(fc16(0, le_words("f", 1.25)))
    plc.step(0)
    assert read_words(device, 4, 0, 2) == le_words("f", 2.5)
    device.handle(fc16(0, le_words("f", -4.0)))
    plc.step(10_000_000)
    assert read_words(device, 4, 0, 2) == le_words("f", -8.0)
    device.handle(fc16(0, le_words("f", math.pi)))
    plc.step(20_000_000)  # the third scan faults
    assert plc.fault is not None
    assert read_words(device, 4, 0, 2) == le_words("f", -8.0)


def test_served_over_tcp_on_the_python_path() -> None:
    image = ProcessImage.allocate()
    lock = threading.Lock()
    device = CodesysDevice(image, lock, [bind(*row) for row in LAYOUT], 8, 12)
    with pytest.raises(ValueError, match="share the server's image and scan lock"):
        ModbusServer(ProcessImage.allocate(), lock, port=0, device=device)
    with ModbusServer(image, port=0, device=device) as server, \
            PlcClient(port=server.port, timeout_s=5.0) as client:
        assert not server.fast_path
        client.write_registers(0, le_words("f", 0.1))
        client.write_coil(49, True)
        assert client.read_holding_registers(0, 4) == [*le_words("f", 0.1), 0, 0x0002]
        assert client.read_coils(49, 1) == [True]
        image.md[1] = native("f", "I", -0.5)
        with lock:
            device.write_outputs()
        assert client.read_input_registers(0, 2) == le_words("f", -0.5)
        with pytest.raises(ModbusError) as err:
            client.read_holding_registers(2048, 2)  # OpenPLC's %MD0: not on this device
        assert err.value.code == 2
        assert raw_call(server.port, req(4, 0, 0)) == bytes((0x84, 3))
