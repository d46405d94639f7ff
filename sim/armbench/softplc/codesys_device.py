"""The soft PLC as a CODESYS Modbus TCP Server Device: the register layout of ``armbench
export``'s CODESYS variant (plc_project/codesys/register-map.md) in front of the program's
process image.

What the device does, after CODESYS's documentation of it ("Modbus TCP Server Device -
General": holding registers are the application's ``%IW`` inputs, input registers its ``%QW``
outputs, coils and discrete inputs the bits of the same data, the incoming data is the ``%I``
range):

- The holding registers are the data of the application's ``%I`` area, byte for byte from
  ``%IW0``: clients write them (functions 6, 16; coils 5, 15) and read them back (3; coils 1).
  Each task, when it starts, copies them into the ``%I`` variables it is laid out with, as a
  CODESYS task updates its inputs; so a variable there starts at 0, whatever initial value the
  program declares, and a multi-register write reaches the program whole (it lands between two
  scans, under the scan lock).
- The input registers are the ``%Q`` area from ``%QW0``: each task, when it ends, copies the
  ``%Q`` variables into them; clients read them (function 4; discrete inputs 2) and nothing
  writes them. A faulted scan copies nothing: they keep the last good scan's values.
- A register is two bytes of that data in the CPU's byte order, little-endian (the CPUs
  CODESYS runs on: x86, the Raspberry Pi's ARM), sent big-endian like any Modbus register: a
  32/64-bit value arrives least significant word first.
- Requests follow the Modbus specification (Application Protocol V1.1b3): quantities 1..2000
  bits read, 1..1968 written, 1..125 registers read, 1..123 written, else exception 3; a range
  past the end of a table, exception 2; function 5 takes 0x0000 or 0xFF00 only; other
  functions, exception 1. None of this was measured on a CODESYS runtime (none can be
  installed here).

The program still runs on OpenPLC's image (the compiler's layout: %MD in ``md``, ...); each
located variable is bound to its bytes there and its place in the device's data (the CODESYS
variant's address). Requests are served in Python (:class:`ModbusServer` with a device never
takes the compiled path of ``modbus_fast.c``).
"""

from __future__ import annotations

import logging
import struct
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Final

from .fastpath import ScanLock
from .image import ProcessImage, image_span
from .modbus_map import ILLEGAL_DATA_ADDRESS, ILLEGAL_DATA_VALUE, ILLEGAL_FUNCTION

if TYPE_CHECKING:
    from ..compiler.symbols import CheckedProgram

_log = logging.getLogger(__name__)

# Modbus Application Protocol V1.1b3, 6.1..6.12: the quantity limits of each function.
MAX_READ_BITS: Final = 2000
MAX_WRITE_BITS: Final = 0x7B0
MAX_READ_REGISTERS: Final = 125
MAX_WRITE_REGISTERS: Final = 0x7B
SERVER_DEVICE_FAILURE: Final = 4

_ADDR_QTY = struct.Struct(">BHH")
_WRITE_MULTI = struct.Struct(">BHHB")
_AREA = ("I", "Q")


@dataclass(frozen=True)
class Binding:
    """One located variable: its bytes in the image and its place in the device's data.
    ``bit`` None: ``size`` bytes from ``device_byte``; else the BOOL at that bit of the byte
    (one byte, 0 or 1, in the image)."""

    name: str
    area: str  # "I": holding registers, copied in; "Q": input registers, copied out
    device_byte: int
    bit: int | None
    image_offset: int
    size: int


def bind(name: str, declared: str, codesys: str) -> Binding:
    """The binding of a variable declared at ``declared`` (the image's address) and placed at
    ``codesys``; ValueError for addresses the image or the device do not have."""
    from ..export.codesys import SIZE_BYTES, Location

    loc = Location.parse(codesys)
    if loc.area not in _AREA:
        raise ValueError(f"{name} at {codesys}: the Modbus device serves %I and %Q only")
    try:
        offset, size = image_span(declared)
    except ValueError as exc:
        raise ValueError(f"{name} ({declared}) cannot be served in the CODESYS layout: "
                         f"{exc}") from exc
    if loc.size == "X":
        return Binding(name, loc.area, loc.index, loc.bit, offset, 1)
    width = SIZE_BYTES[loc.size]
    if width != size:
        raise ValueError(f"{name}: {declared} and {codesys} differ in size")
    return Binding(name, loc.area, width * loc.index, None, offset, size)


@dataclass(frozen=True)
class _Run:
    """Bytes copied with one slice: ``length`` bytes at ``device`` and at ``image``."""

    device: int
    image: int
    length: int


def _runs(bindings: Sequence[Binding]) -> tuple[_Run, ...]:
    """Byte bindings merged where both sides continue each other (a mailbox's twelve %MD
    fields are one copy)."""
    runs: list[_Run] = []
    for b in sorted(bindings, key=lambda b: b.device_byte):
        last = runs[-1] if runs else None
        if last is not None and last.device + last.length == b.device_byte \
                and last.image + last.length == b.image_offset:
            runs[-1] = _Run(last.device, last.image, last.length + b.size)
        else:
            runs.append(_Run(b.device_byte, b.image_offset, b.size))
    return tuple(runs)


def _addr_qty(pdu: bytes) -> tuple[int, int, int]:
    """(function, address, quantity or value) of a request PDU of at least 5 bytes."""
    function, address, quantity = _ADDR_QTY.unpack_from(pdu)
    return function, address, quantity


def _exception(function: int, code: int) -> bytes:
    return bytes((function | 0x80, code))


def _swap_words(data: bytes | bytearray | memoryview) -> bytes:
    """Little-endian 16-bit words <-> big-endian ones (the same byte swap both ways)."""
    out = bytearray(len(data))
    out[0::2] = data[1::2]
    out[1::2] = data[0::2]
    return bytes(out)


@dataclass
class CodesysDevice:
    """The device's data (``holding``: the %I area, ``inputs``: the %Q area) over one image,
    with its request handler (:meth:`handle`, for :class:`ModbusServer`) and the copies each
    scan makes (:meth:`read_inputs` before it, :meth:`write_outputs` after it, for
    :class:`SoftPlc`). ``lock`` is the soft PLC's scan lock."""

    image: ProcessImage
    lock: ScanLock
    bindings: Sequence[Binding]
    holding_registers: int
    input_registers: int
    holding: bytearray = field(init=False, repr=False)
    inputs: bytearray = field(init=False, repr=False)
    _in_runs: tuple[_Run, ...] = field(init=False, repr=False)
    _out_runs: tuple[_Run, ...] = field(init=False, repr=False)
    _in_bits: tuple[tuple[int, int], ...] = field(init=False, repr=False)
    _out_bits: tuple[tuple[int, int], ...] = field(init=False, repr=False)
    _dispatch: dict[int, Callable[[bytes], bytes]] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if sys.byteorder != "little":
            # the image is native-endian, the device's data little-endian: the copies below
            # are plain slices only when both agree
            raise RuntimeError("the CODESYS layout is served on little-endian hosts only")
        for count, what in ((self.holding_registers, "holding"),
                            (self.input_registers, "input")):
            if not 0 <= count <= 0x10000:
                raise ValueError(f"{count} {what} registers: a Modbus table has 0..65536")
        self.holding = bytearray(2 * self.holding_registers)
        self.inputs = bytearray(2 * self.input_registers)
        size = {"I": len(self.holding), "Q": len(self.inputs)}
        owner: dict[tuple[str, int], str] = {}
        for b in self.bindings:
            end = b.device_byte + (1 if b.bit is not None else b.size)
            if end > size[b.area]:
                raise ValueError(f"{b.name} lies past the device's "
                                 f"{'holding' if b.area == 'I' else 'input'} registers "
                                 f"({size[b.area] // 2})")
            covered = (range(8 * b.device_byte + b.bit, 8 * b.device_byte + b.bit + 1)
                       if b.bit is not None else range(8 * b.device_byte, 8 * end))
            for bit in covered:
                other = owner.setdefault((b.area, bit), b.name)
                if other != b.name:
                    raise ValueError(f"{b.name} and {other} share bit {bit % 8} of byte "
                                     f"{bit // 8} of the %{b.area} data")
        words = [b for b in self.bindings if b.bit is None]
        bits = [b for b in self.bindings if b.bit is not None]
        self._in_runs = _runs([b for b in words if b.area == "I"])
        self._out_runs = _runs([b for b in words if b.area == "Q"])
        self._in_bits = tuple((8 * b.device_byte + (b.bit or 0), b.image_offset)
                              for b in bits if b.area == "I")
        self._out_bits = tuple((8 * b.device_byte + (b.bit or 0), b.image_offset)
                               for b in bits if b.area == "Q")
        self._dispatch = {1: self._read_coils, 2: self._read_discrete_inputs,
                          3: self._read_holding, 4: self._read_input, 5: self._write_coil,
                          6: self._write_register, 15: self._write_coils,
                          16: self._write_registers}

    @classmethod
    def for_program(cls, program: CheckedProgram, image: ProcessImage,
                    lock: ScanLock) -> CodesysDevice:
        """The device for ``program`` laid out as ``armbench export`` lays it out for CODESYS,
        sized as its register map asks (plc_project/codesys/register-map.md for the
        controller)."""
        from ..export.codesys import device_registers, layout

        placed = layout(program)
        holding, inputs = device_registers(placed)
        return cls(image, lock, [bind(p.name, str(p.openplc), str(p.codesys)) for p in placed],
                   holding, inputs)

    # -- the scan's copies (called by the soft PLC, under the scan lock) ------------------

    def read_inputs(self) -> None:
        """Holding registers and coils -> the program's %I variables."""
        raw, data = self.image.raw, self.holding
        for r in self._in_runs:
            raw[r.image: r.image + r.length] = data[r.device: r.device + r.length]
        for bit, offset in self._in_bits:
            raw[offset] = (data[bit >> 3] >> (bit & 7)) & 1

    def write_outputs(self) -> None:
        """The program's %Q variables -> input registers and discrete inputs."""
        raw, data = self.image.raw, self.inputs
        for r in self._out_runs:
            data[r.device: r.device + r.length] = raw[r.image: r.image + r.length]
        for bit, offset in self._out_bits:
            mask = 1 << (bit & 7)
            if raw[offset]:
                data[bit >> 3] |= mask
            else:
                data[bit >> 3] &= ~mask & 0xFF

    # -- requests --------------------------------------------------------------------------

    def handle(self, pdu: bytes) -> bytes:
        """The response PDU to one request PDU."""
        function = pdu[0]
        handler = self._dispatch.get(function)
        if handler is None:
            return _exception(function, ILLEGAL_FUNCTION)
        if len(pdu) < _ADDR_QTY.size:
            return _exception(function, ILLEGAL_DATA_VALUE)
        try:
            return handler(pdu)
        except Exception:  # a bug here must cost one request, not the connection
            _log.exception("modbus request %r failed", pdu[:16])
            return _exception(function, SERVER_DEVICE_FAILURE)

    def _read_bits(self, pdu: bytes, data: bytearray) -> bytes:
        function, start, count = _addr_qty(pdu)
        if not 1 <= count <= MAX_READ_BITS:
            return _exception(function, ILLEGAL_DATA_VALUE)
        if start + count > 8 * len(data):
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        first, last = start >> 3, (start + count - 1) >> 3
        with self.lock:
            covered = int.from_bytes(data[first: last + 1], "little")
        nbytes = (count + 7) // 8
        bits = (covered >> (start & 7)) & ((1 << count) - 1)
        return bytes((function, nbytes)) + bits.to_bytes(nbytes, "little")

    def _read_coils(self, pdu: bytes) -> bytes:
        return self._read_bits(pdu, self.holding)

    def _read_discrete_inputs(self, pdu: bytes) -> bytes:
        return self._read_bits(pdu, self.inputs)

    def _read_registers(self, pdu: bytes, data: bytearray) -> bytes:
        function, start, count = _addr_qty(pdu)
        if not 1 <= count <= MAX_READ_REGISTERS:
            return _exception(function, ILLEGAL_DATA_VALUE)
        if 2 * (start + count) > len(data):
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        with self.lock:
            words = data[2 * start: 2 * (start + count)]
        return bytes((function, 2 * count)) + _swap_words(words)

    def _read_holding(self, pdu: bytes) -> bytes:
        return self._read_registers(pdu, self.holding)

    def _read_input(self, pdu: bytes) -> bytes:
        return self._read_registers(pdu, self.inputs)

    def store_registers(self, address: int, words: Sequence[int]) -> None:
        """Write holding registers as a client would (one hold of the scan lock), e.g. the
        soft PLC's stand-in for the PLC's own input I/O."""
        if not 0 <= address <= address + len(words) <= self.holding_registers:
            raise ValueError(f"holding registers {address}..{address + len(words) - 1} are "
                             f"not all among the device's {self.holding_registers}")
        data = b"".join(w.to_bytes(2, "little") for w in words)
        with self.lock:
            self.holding[2 * address: 2 * address + len(data)] = data

    def store_coil(self, address: int, value: bool) -> None:
        """Write one coil as a client would."""
        if not 0 <= address < 8 * len(self.holding):
            raise ValueError(f"coil {address} is not among the device's "
                             f"{8 * len(self.holding)}")
        with self.lock:
            self._store_bits(address, 1, int(value))

    def _store_bits(self, start: int, count: int, bits: int) -> None:
        """Set ``count`` coils from ``start`` to the low bits of ``bits``; caller locks."""
        first, last = start >> 3, (start + count - 1) >> 3
        shift = start & 7
        mask = ((1 << count) - 1) << shift
        covered = int.from_bytes(self.holding[first: last + 1], "little")
        covered = (covered & ~mask) | ((bits << shift) & mask)
        self.holding[first: last + 1] = covered.to_bytes(last + 1 - first, "little")

    def _write_coil(self, pdu: bytes) -> bytes:
        function, address, value = _addr_qty(pdu)
        if value not in (0x0000, 0xFF00):
            return _exception(function, ILLEGAL_DATA_VALUE)
        if address >= 8 * len(self.holding):
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        with self.lock:
            self._store_bits(address, 1, 1 if value else 0)
        return pdu[:5]

    def _write_coils(self, pdu: bytes) -> bytes:
        if len(pdu) < _WRITE_MULTI.size:
            return _exception(pdu[0], ILLEGAL_DATA_VALUE)
        function, start, count, nbytes = _WRITE_MULTI.unpack_from(pdu)
        data = pdu[_WRITE_MULTI.size: _WRITE_MULTI.size + nbytes]
        if not 1 <= count <= MAX_WRITE_BITS or nbytes != (count + 7) // 8 \
                or len(data) != nbytes:
            return _exception(function, ILLEGAL_DATA_VALUE)
        if start + count > 8 * len(self.holding):
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        with self.lock:
            self._store_bits(start, count, int.from_bytes(data, "little"))
        return pdu[:5]

    def _write_register(self, pdu: bytes) -> bytes:
        function, address, _value = _addr_qty(pdu)
        if address >= self.holding_registers:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        with self.lock:
            self.holding[2 * address: 2 * address + 2] = (pdu[4], pdu[3])
        return pdu[:5]

    def _write_registers(self, pdu: bytes) -> bytes:
        if len(pdu) < _WRITE_MULTI.size:
            return _exception(pdu[0], ILLEGAL_DATA_VALUE)
        function, start, count, nbytes = _WRITE_MULTI.unpack_from(pdu)
        data = pdu[_WRITE_MULTI.size: _WRITE_MULTI.size + nbytes]
        if not 1 <= count <= MAX_WRITE_REGISTERS or nbytes != 2 * count \
                or len(data) != nbytes:
            return _exception(function, ILLEGAL_DATA_VALUE)
        if start + count > self.holding_registers:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        swapped = _swap_words(data)
        with self.lock:  # one hold: a scan sees the whole write or none of it
            self.holding[2 * start: 2 * (start + count)] = swapped
        return pdu[:5]
