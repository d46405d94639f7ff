"""The soft PLC as OpenPLC v4's Modbus server: the ``modbus_slave`` Python plugin of
Autonomy-Logic/openplc-runtime (``simple_modbus.py``, served by pymodbus 3.11/3.12, the versions
whose ``pymodbus.datastore.store`` it imports) over v4's I/O image and its write journal.
docs/modbus-parity.md sets it beside OpenPLC v3, rule by rule, with the v4 file each rule comes
from; what follows is how this module models them.

Sizing (``image_tables.cpp``, ``image_sizes.py``, ``simple_modbus.py``):

- The runtime allocates each of its image tables per program load, as long as the larger of
  what ``image.conf`` (written by the editor) asks and the floor the loaded program needs: the
  highest index any located variable uses, plus one (the BOOL tables count bytes of 8 bits).
  The editor's ``image.conf`` holds, besides the I/O producers, the Modbus server counts the
  user set on its screen; counts left at their defaults size nothing (:func:`image_tables`).
- The plugin exposes v3's default segments (coils %QX 8192 bits then %MX 0, discrete inputs
  %IX 8192, input registers %IW 1024, holding registers %QW 1024, %MW 1024, %MD 1024 x 2,
  %ML 1024 x 4), each clamped to its own image table, then trimmed from the tail so a block fits
  65536 addresses (:func:`fit_segments`). The holding segments lie head to tail: a %QW segment
  shorter than 1024 moves %MW, %MD and %ML down (:func:`required_counts` says which counts a
  program must set to keep v3's addresses).
- An address outside the segments answers exception 02 (v3 answered zeros below 8192).

Timing (``journal_buffer.c``, ``mutex_manager.py``, the task worker's scan in ``core/src/plc_app``):

- A client's write is not applied to the image: it is queued in the journal (one entry per
  register of %QW/%MW, per 32/64-bit value of %MD/%ML, per coil), and the journal is drained by
  whoever next takes the image lock: the next task's copy-in at the start of its scan, or the
  next Modbus read or register write (the plugin reads under that lock, and the lock drains
  first, so a client always reads back what it wrote).
- Register writes (FC6, FC16, FC22, FC23) take the image lock around all of their entries, so a
  drain never splits one: a function 16 reaches a scan whole. Coil writes (FC5, FC15) take no
  lock, and a scan starting in the middle of one sees part of it.
- The journal holds 4096 entries between two drains; a write past that is dropped (the request
  is still answered as written): the tail of a function 16 can be lost that way.
- After a scan the task commits only the located outputs it changed, into the journal behind
  the client writes that arrived during the scan: a client write to a variable the program
  changes in that scan is lost (v3 applied it after the scan, until the next one).

Protocol (pymodbus 3.12.1, measured with this module's rules over pymodbus's own server):
unit id 1 only (others: exception 0x0B), the register counts pymodbus checks (FC16 1..123,
FC23 1..125 read / 1..121 write, else exception 03), reads as long as their reply encodes (127
registers, 2040 bits; longer ones get no reply), FC5/FC6 echo the value asked for (FC5 as
0xFF00 or 0x0000), FC15 writes only its ``count`` bits, function codes pymodbus does not know
answer exception 1 in a frame of function 0xA8, transaction 0 and unit 1, and pymodbus's way of
reading a TCP stream: one request per read of the socket (further requests in the same read are
dropped), a frame with a protocol id other than 0 blocks the connection, a request too short
for its fields closes it. Requests of all connections run one at a time (pymodbus's one event
loop). Not modelled: the word order ``low_word_first`` the plugin also offers (this flavor sends
the most significant word first, the plugin's default and v3's), %MX coils (the soft PLC's image
has no %MX), the debugger's forced slots, and the placeholder answers pymodbus gives to function
codes 20, 21 and 24 (here: exception 1).
"""

from __future__ import annotations

import logging
import re
import socket
import struct
import threading
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Final

from .fastpath import ScanLock
from .image import (
    IW_COUNT,
    IW_OFFSET,
    IX_COUNT,
    IX_OFFSET,
    MD_COUNT,
    MD_OFFSET,
    ML_COUNT,
    ML_OFFSET,
    MW_COUNT,
    MW_OFFSET,
    QW_COUNT,
    QW_OFFSET,
    QX_COUNT,
    QX_OFFSET,
    ProcessImage,
)
from .modbus_map import ILLEGAL_DATA_ADDRESS, ILLEGAL_DATA_VALUE, ILLEGAL_FUNCTION

_log = logging.getLogger(__name__)

# simple_modbus.py: DEFAULT_HOLDING_REG_CONFIG, DEFAULT_COILS_CONFIG, ... ("matches v3 behavior")
DEFAULT_COUNTS: Final[Mapping[str, int]] = {
    "qw_count": 1024, "mw_count": 1024, "md_count": 1024, "ml_count": 1024,
    "qx_bits": 8192, "mx_bits": 0, "ix_bits": 8192, "iw_count": 1024}
# simple_modbus.py SEGMENT_TABLES: the image table each segment lives in
SEGMENT_TABLES: Final[Mapping[str, str]] = {
    "qw_count": "int_output", "mw_count": "int_memory", "md_count": "dint_memory",
    "ml_count": "lint_memory", "qx_bits": "bool_output", "mx_bits": "bool_memory",
    "ix_bits": "bool_input", "iw_count": "int_input"}
# the order the holding block lays its segments in, and the registers per element
HOLDING: Final = (("qw_count", 1), ("mw_count", 1), ("md_count", 2), ("ml_count", 4))
MODBUS_MAX_ADDRESSES: Final = 65536  # simple_modbus.py
IMAGE_MAX_ELEMENTS: Final = 65536  # image_tables.h
JOURNAL_MAX_ENTRIES: Final = 4096  # journal_buffer.h
V3_SEGMENT: Final = 1024  # a holding segment of v3's map (%QW, %MW, %MD, %ML: 1024 values)
UNIT_ID: Final = 1  # simple_modbus.py: ModbusServerContext(devices={1: device}, single=False)
GATEWAY_NO_RESPONSE: Final = 0x0B  # pymodbus's answer for any other unit id
SERVER_DEVICE_FAILURE: Final = 0x04
MAX_REPLY_DATA: Final = 255  # pymodbus encodes a read reply's byte count in one byte
MAX_WRITE_REGISTERS: Final = 123  # pymodbus: WriteMultipleRegistersRequest
MAX_RW_READ, MAX_RW_WRITE = 125, 121  # pymodbus: ReadWriteMultipleRegistersRequest
RECV_BUFFER_CLEAR: Final = 1024  # pymodbus transport: a longer unread buffer is dropped

# The soft PLC's image areas behind each segment (capacity, byte offset, bytes per element)
_AREA: Final[Mapping[str, tuple[int, int, int]]] = {
    "qx_bits": (QX_COUNT, QX_OFFSET, 1), "ix_bits": (IX_COUNT, IX_OFFSET, 1),
    "iw_count": (IW_COUNT, IW_OFFSET, 2), "qw_count": (QW_COUNT, QW_OFFSET, 2),
    "mw_count": (MW_COUNT, MW_OFFSET, 2), "md_count": (MD_COUNT, MD_OFFSET, 4),
    "ml_count": (ML_COUNT, ML_OFFSET, 8)}

# (area, size) -> image table (image_tables.cpp table_for; %MB has none)
_TABLE_OF: Final[Mapping[tuple[str, str], str]] = {
    ("I", "X"): "bool_input", ("Q", "X"): "bool_output", ("M", "X"): "bool_memory",
    ("I", "B"): "byte_input", ("Q", "B"): "byte_output",
    ("I", "W"): "int_input", ("Q", "W"): "int_output", ("M", "W"): "int_memory",
    ("I", "D"): "dint_input", ("Q", "D"): "dint_output", ("M", "D"): "dint_memory",
    ("I", "L"): "lint_input", ("Q", "L"): "lint_output", ("M", "L"): "lint_memory"}
_LOCATION = re.compile(r"^%([IQM])([XBWDL])(\d+)(?:\.([0-7]))?$", re.IGNORECASE)


def image_floor(locations: Iterable[str]) -> dict[str, int]:
    """The elements each image table must have for these located variables
    (image_tables.cpp image_sizes_derive_floor): the highest index plus one, a BOOL table's
    index being the byte of ``%QXbyte.bit``. Tables no variable uses are absent (0)."""
    floor: dict[str, int] = {}
    for loc in locations:
        m = _LOCATION.match(loc.strip())
        if m is None:
            raise ValueError(f"{loc} is not a direct address")
        table = _TABLE_OF.get((m.group(1).upper(), m.group(2).upper()))
        if table is None:
            continue  # %MB: no table on v4 (the runtime logs it and serves nothing)
        floor[table] = max(floor.get(table, 0), int(m.group(3)) + 1)
    return floor


def configured_tables(counts: Mapping[str, int]) -> dict[str, int]:
    """The tables the editor's ``image.conf`` asks for from the Modbus server counts the user
    set (a count left at its default sizes nothing); BOOL tables in bytes, rounded up."""
    tables: dict[str, int] = {}
    for key, count in counts.items():
        if count > 0:
            tables[SEGMENT_TABLES[key]] = (count + 7) // 8 if key.endswith("_bits") else count
    return tables


def image_tables(floor: Mapping[str, int], configured: Mapping[str, int],
                 square: bool = False) -> dict[str, int]:
    """The tables the runtime allocates: per table the larger of ``image.conf`` and the
    program's floor (image_sizes_take_max). ``square``: a loaded plugin does not understand
    per-table sizes, and the runtime makes every table as long as the longest
    (image_sizes_flatten)."""
    tables = {t: max(floor.get(t, 0), configured.get(t, 0)) for t in {*floor, *configured}}
    if square and tables:
        longest = max(tables.values())
        tables = {t: longest for t in set(_TABLE_OF.values())}
    return tables


def _trim(fitted: dict[str, int], layout: Iterable[tuple[str, int]]) -> None:
    """simple_modbus.py _trim_to_one_table: shrink tail segments until the block fits one
    Modbus table (65536 addresses)."""
    layout = list(layout)
    total = sum(fitted[k] * w for k, w in layout)
    for key, width in reversed(layout):
        if total <= MODBUS_MAX_ADDRESSES:
            return
        drop = min(fitted[key], -(-(total - MODBUS_MAX_ADDRESSES) // width))
        fitted[key] -= drop
        total -= drop * width


@dataclass(frozen=True)
class Segments:
    """What the plugin exposes: elements per segment (bits for coils and discrete inputs)."""

    qw_count: int
    mw_count: int
    md_count: int
    ml_count: int
    qx_bits: int
    mx_bits: int
    ix_bits: int
    iw_count: int

    @property
    def holding_registers(self) -> int:
        return self.qw_count + self.mw_count + 2 * self.md_count + 4 * self.ml_count

    @property
    def coils(self) -> int:
        return self.qx_bits + self.mx_bits

    def holding_start(self, key: str) -> int:
        """The first holding register of a segment ("mw_count": where %MW0 is)."""
        start = 0
        for k, width in HOLDING:
            if k == key:
                return start
            start += getattr(self, k) * width
        raise KeyError(key)

    def as_dict(self) -> dict[str, int]:
        return {k: getattr(self, k) for k in DEFAULT_COUNTS}


def fit_segments(counts: Mapping[str, int], tables: Mapping[str, int]) -> Segments:
    """The plugin's segments (parse_buffer_mapping_config, _fit_counts): each count asked
    (``counts``, the defaults for the rest) clamped to its own table, then each block trimmed
    to 65536 addresses."""
    unknown = set(counts) - set(DEFAULT_COUNTS)
    if unknown:
        raise ValueError(f"unknown Modbus segment count(s) {sorted(unknown)}: the plugin's are "
                         f"{', '.join(DEFAULT_COUNTS)}")
    fitted = {}
    for key, default in DEFAULT_COUNTS.items():
        reach = tables.get(SEGMENT_TABLES[key], 0)
        fitted[key] = min(counts.get(key, default), 8 * reach if key.endswith("_bits") else reach)
    _trim(fitted, HOLDING)
    _trim(fitted, (("qx_bits", 1), ("mx_bits", 1)))
    _trim(fitted, (("ix_bits", 1),))
    _trim(fitted, (("iw_count", 1),))
    return Segments(**fitted)


def required_counts(locations: Iterable[str]) -> dict[str, int]:
    """The Modbus server counts a program must set in the editor (so that they reach
    ``image.conf``) for every located variable to keep v3's address: each holding segment
    before the last one the program uses must be v3's 1024 long, or the segments after it
    move down. Counts of segments that start at address 0 (coils, discrete inputs, input
    registers) and of the last holding segment can stay at their defaults: the program's
    floor sizes them."""
    floor = image_floor(locations)
    used = [i for i, (key, _) in enumerate(HOLDING) if floor.get(SEGMENT_TABLES[key], 0) > 0]
    counts: dict[str, int] = {}
    for key, _ in HOLDING[:used[-1]] if used else ():
        if floor.get(SEGMENT_TABLES[key], 0) < V3_SEGMENT:
            counts[key] = V3_SEGMENT
    return counts


def v3_map_problems(segments: Segments, locations: Iterable[str]) -> list[str]:
    """Why a variable would not be at its v3 address (or not be served at all) on these
    segments; empty when every one is."""
    floor = image_floor(locations)
    problems: list[str] = []
    used = [i for i, (key, _) in enumerate(HOLDING) if floor.get(SEGMENT_TABLES[key], 0) > 0]
    for key, _ in HOLDING[:used[-1]] if used else ():
        if getattr(segments, key) != V3_SEGMENT:
            problems.append(f"{key} is {getattr(segments, key)}, not {V3_SEGMENT}: the "
                            "holding segments after it move")
    for key in DEFAULT_COUNTS:
        need = floor.get(SEGMENT_TABLES[key], 0) * (8 if key.endswith("_bits") else 1)
        if getattr(segments, key) < need:
            problems.append(f"{key} is {getattr(segments, key)}: the program uses {need}")
    return problems


@dataclass(frozen=True)
class V4Settings:
    """How the soft PLC serves a program as v4 would: the Modbus server counts set in the
    editor (``counts``; :func:`required_counts` of the program by default), whether the image
    is square, and the journal's capacity (4096, as v4's; smaller ones let a test lose the
    tail of a write as v4 does when its journal overflows)."""

    counts: Mapping[str, int] | None = None
    square: bool = False
    journal_capacity: int = JOURNAL_MAX_ENTRIES

    def segments(self, locations: Iterable[str]) -> Segments:
        locs = list(locations)
        counts = required_counts(locs) if self.counts is None else dict(self.counts)
        tables = image_tables(image_floor(locs), configured_tables(counts), self.square)
        seg = fit_segments(counts, tables)
        for key, (capacity, _, _) in _AREA.items():
            if getattr(seg, key) > capacity:
                raise ValueError(f"{key} {getattr(seg, key)}: the soft PLC's image holds "
                                 f"{capacity} there (v3's default)")
        if seg.mx_bits:
            raise ValueError("mx_bits: the soft PLC's image has no %MX coils")
        return seg


# -- the journal ---------------------------------------------------------------------------


@dataclass(frozen=True)
class _Entry:
    """One journal write: ``data`` (native order) at ``offset`` of the image."""

    offset: int
    data: bytes


class Close(Exception):
    """The request cannot be decoded: pymodbus drops the connection."""


@dataclass
class OpenPlcV4Device:
    """v4's Modbus server over the soft PLC's image: segments, journal, pymodbus's framing.
    :meth:`serve` serves one connection (for :class:`ModbusServer`); :meth:`read_inputs` and
    :meth:`write_outputs` are the task's copy-in and copy-out (for :class:`SoftPlc`), called
    under the scan lock ``lock``."""

    image: ProcessImage
    lock: ScanLock
    segments: Segments
    journal_capacity: int = JOURNAL_MAX_ENTRIES
    dropped: int = 0  # journal writes lost to overflow since start
    _journal: list[_Entry] = field(default_factory=list, repr=False)
    _journal_lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    # pymodbus serves every connection from one event loop: one request at a time
    _loop_lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    _scan_start: bytes = field(default=b"", repr=False)

    def __post_init__(self) -> None:
        if self.journal_capacity < 1:
            raise ValueError(f"journal capacity {self.journal_capacity}: at least 1")
        self._dispatch: dict[int, Callable[[int, bytes], bytes | None]] = {
            1: self._read_coils, 2: self._read_discrete_inputs, 3: self._read_holding,
            4: self._read_input_registers, 5: self._write_coil, 6: self._write_register,
            15: self._write_coils, 16: self._write_registers, 22: self._mask_write,
            23: self._read_write}

    # -- journal ---------------------------------------------------------------------------

    def _append(self, entries: Iterable[_Entry]) -> None:
        with self._journal_lock:
            for e in entries:
                if len(self._journal) >= self.journal_capacity:
                    # journal_add: the bank is full, the write is dropped; the plugin logs
                    # the failed write and answers the request all the same
                    self.dropped += 1
                    _log.warning("journal full (%d entries): a write at image byte %d dropped",
                                 self.journal_capacity, e.offset)
                    continue
                self._journal.append(e)

    def drain(self) -> None:
        """Apply the journal to the image (journal_apply_and_clear); caller holds the lock."""
        with self._journal_lock:
            entries, self._journal = self._journal, []
        raw = self.image.raw
        for e in entries:
            raw[e.offset: e.offset + len(e.data)] = e.data

    @property
    def pending(self) -> int:
        """Journal entries not yet applied."""
        with self._journal_lock:
            return len(self._journal)

    # -- the task's copy-in and copy-out (ScanIo) --------------------------------------------

    def read_inputs(self) -> None:
        """The scan's copy-in: image_lock drains the journal; remember the image to tell
        later which outputs the program changed."""
        self.drain()
        self._scan_start = self.image.raw.tobytes()

    def write_outputs(self) -> None:
        """The scan's copy-out: the program's changed outputs go into the journal behind the
        client writes that arrived during the scan, so those client writes to a slot the
        program changed are overwritten at the next drain: dropped here, the same result."""
        raw, before = self.image.raw, self._scan_start
        with self._journal_lock:
            if self._journal:
                self._journal = [e for e in self._journal
                                 if raw[e.offset: e.offset + len(e.data)]
                                 == before[e.offset: e.offset + len(e.data)]]

    # -- addresses -------------------------------------------------------------------------

    def _holding_slot(self, address: int) -> tuple[str, int, int]:
        """(segment, index, word) of a holding register inside the segments."""
        seg = self.segments
        for key, width in HOLDING:
            n = getattr(seg, key) * width
            if address < n:
                return key, address // width, address % width
            address -= n
        raise IndexError(address)

    def _holding_word(self, address: int) -> int:
        key, index, word = self._holding_slot(address)
        if key == "qw_count":
            return int(self.image.qw[index])
        if key == "mw_count":
            return int(self.image.mw[index])
        if key == "md_count":  # high_word_first, the plugin's default word order
            return (int(self.image.md[index]) >> (16 * (1 - word))) & 0xFFFF
        return (int(self.image.ml[index]) >> (16 * (3 - word))) & 0xFFFF

    def _holding_entries(self, address: int, words: list[int]) -> list[_Entry]:
        """The journal entries of a register write (caller holds the lock, journal drained):
        one per %QW/%MW register, one per touched %MD/%ML value, its other words read from the
        image (the plugin's read-modify-write)."""
        singles: list[_Entry] = []
        wide: dict[tuple[str, int], list[int]] = {}
        for i, w in enumerate(words):
            key, index, word = self._holding_slot(address + i)
            _, offset, size = _AREA[key]
            if size == 2:
                singles.append(_Entry(offset + 2 * index, struct.pack("=H", w & 0xFFFF)))
                continue
            n = size // 2
            if (key, index) not in wide:
                view = self.image.md if key == "md_count" else self.image.ml
                cur = int(view[index])
                wide[(key, index)] = [(cur >> (16 * (n - 1 - k))) & 0xFFFF for k in range(n)]
            wide[(key, index)][word] = w & 0xFFFF
        entries = singles
        for (key, index), ws in wide.items():
            _, offset, size = _AREA[key]
            value = 0
            for w in ws:
                value = (value << 16) | w
            entries.append(_Entry(offset + size * index,
                                  value.to_bytes(size, "little" if _NATIVE_LITTLE else "big")))
        return entries

    # -- requests --------------------------------------------------------------------------

    def handle(self, unit: int, pdu: bytes) -> tuple[bytes | None, bool]:
        """(reply PDU or None for no reply, whether it goes in pymodbus's frame of an
        undecodable request); raises Close when pymodbus would drop the connection."""
        function = pdu[0]
        handler = self._dispatch.get(function)
        if function > 0x80 and len(pdu) >= 2:
            # decoded as an exception response, which has nothing to run: device failure
            return bytes((function, SERVER_DEVICE_FAILURE)), False
        if handler is None:
            fixed = _diagnostic(pdu)
            if fixed is not None:
                return fixed, False
            if function in (20, 21, 24):  # known to pymodbus, not modelled here
                return bytes((function | 0x80, ILLEGAL_FUNCTION)), False
            return bytes((40 | 0x80, ILLEGAL_FUNCTION)), True
        _need(pdu, _MIN_PDU[function])
        if unit != UNIT_ID:
            # decoded, then NoSuchIdException from the context: exception 0x0B
            return bytes((function | 0x80, GATEWAY_NO_RESPONSE)), False
        with self._loop_lock:
            return handler(function, pdu), False

    def _read_bits(self, function: int, pdu: bytes, offset: int, size: int,
                   per_address: bool) -> bytes | None:
        start, count = struct.unpack_from(">HH", pdu, 1)
        if _outside(start, count, size, per_address):
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        with self.lock:
            self.drain()
            bits = self.image.raw[offset + start: offset + start + count].tobytes()
        nbytes = (count + 7) // 8
        if nbytes > MAX_REPLY_DATA:
            return None  # the reply's byte count does not fit: pymodbus sends nothing
        packed = int("".join("1" if b else "0" for b in reversed(bits)) or "0", 2)
        return bytes((function, nbytes)) + packed.to_bytes(nbytes, "little")

    def _read_coils(self, function: int, pdu: bytes) -> bytes | None:
        # the coil block checks each address it reads: quantity 0 reads nothing anywhere
        return self._read_bits(function, pdu, QX_OFFSET, self.segments.coils, True)

    def _read_discrete_inputs(self, function: int, pdu: bytes) -> bytes | None:
        # the discrete-input block checks the range first: quantity 0 past the end is refused
        return self._read_bits(function, pdu, IX_OFFSET, self.segments.ix_bits, False)

    def _read_holding(self, function: int, pdu: bytes) -> bytes | None:
        start, count = struct.unpack_from(">HH", pdu, 1)
        words = self._holding_read(start, count)
        if words is None:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        return _words_reply(function, words)

    def _holding_read(self, start: int, count: int) -> list[int] | None:
        # the holding block checks each address it reads (quantity 0: nothing, anywhere)
        if _outside(start, count, self.segments.holding_registers, True):
            return None
        with self.lock:
            self.drain()
            return [self._holding_word(start + i) for i in range(count)]

    def _read_input_registers(self, function: int, pdu: bytes) -> bytes | None:
        start, count = struct.unpack_from(">HH", pdu, 1)
        if start + count > self.segments.iw_count:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        with self.lock:
            self.drain()
            words = [int(w) for w in self.image.iw[start: start + count]]
        return _words_reply(function, words)

    def _write_coil(self, function: int, pdu: bytes) -> bytes | None:
        address, value = struct.unpack_from(">HH", pdu, 1)
        on = value != 0  # pymodbus decodes any non-zero value as TRUE
        err = self._store_coils(address, [on])
        if err is not None:
            return _exception(function, err)
        return struct.pack(">BHH", function, address, 0xFF00 if on else 0x0000)

    def _store_coils(self, start: int, bits: list[bool]) -> int | None:
        if start + len(bits) > self.segments.coils:
            return ILLEGAL_DATA_ADDRESS
        # no image lock: journal writes one by one, which a scan's drain may split
        for i, b in enumerate(bits):
            self._append((_Entry(QX_OFFSET + start + i, b"\x01" if b else b"\x00"),))
        return None

    def _write_coils(self, function: int, pdu: bytes) -> bytes | None:
        start, count = struct.unpack_from(">HH", pdu, 1)
        data = pdu[6:]  # pymodbus reads the bits from what follows, whatever the byte count
        bits = [bool(data[i // 8] >> (i % 8) & 1) for i in range(min(count, 8 * len(data)))]
        err = self._store_coils(start, bits)
        if err is not None:
            return _exception(function, err)
        return struct.pack(">BHH", function, start, len(bits))

    def _store_registers(self, start: int, words: list[int]) -> int | None:
        if start + len(words) > self.segments.holding_registers:
            return ILLEGAL_DATA_ADDRESS
        with self.lock:  # the plugin holds the image lock over all of its journal writes
            self.drain()
            self._append(self._holding_entries(start, words))
        return None

    def _write_register(self, function: int, pdu: bytes) -> bytes | None:
        address, value = struct.unpack_from(">HH", pdu, 1)
        err = self._store_registers(address, [value])
        if err is not None:
            return _exception(function, err)
        return pdu[:5]  # the value asked for (OpenPLCDeviceContext's echo)

    def _write_registers(self, function: int, pdu: bytes) -> bytes | None:
        start, count = struct.unpack_from(">HH", pdu, 1)
        if not 1 <= count <= MAX_WRITE_REGISTERS:
            return _exception(function, ILLEGAL_DATA_VALUE)
        words = list(struct.unpack_from(f">{count}H", pdu, 6))
        err = self._store_registers(start, words)
        if err is not None:
            return _exception(function, err)
        return struct.pack(">BHH", function, start, count)

    def _mask_write(self, function: int, pdu: bytes) -> bytes | None:
        address, and_mask, or_mask = struct.unpack_from(">HHH", pdu, 1)
        current = self._holding_read(address, 1)
        if current is None:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        value = (current[0] & and_mask) | (or_mask & ~and_mask & 0xFFFF)
        err = self._store_registers(address, [value])
        if err is not None:
            return _exception(function, err)
        return pdu[:7]

    def _read_write(self, function: int, pdu: bytes) -> bytes | None:
        r_start, r_count, w_start, w_count, nbytes = struct.unpack_from(">HHHHB", pdu, 1)
        if not 1 <= r_count <= MAX_RW_READ or not 1 <= w_count <= MAX_RW_WRITE:
            return _exception(function, ILLEGAL_DATA_VALUE)
        # the registers written are as many as the byte count holds, whatever w_count says
        words = list(struct.unpack_from(f">{(nbytes + 1) // 2}H", pdu, 10))
        err = self._store_registers(w_start, words)
        if err is not None:
            return _exception(function, err)
        read = self._holding_read(r_start, r_count)
        if read is None:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        return _words_reply(function, read)

    # -- one connection --------------------------------------------------------------------

    def serve(self, conn: socket.socket, answered: Callable[[], None]) -> None:
        """Serve one connection as pymodbus's transport does, until the peer closes it or a
        request cannot be decoded; ``answered`` is called after each reply."""
        stream = PymodbusStream(self)
        while True:
            data = conn.recv(4096)
            if not data:
                return
            try:
                reply = stream.feed(data)
            except Close:
                return
            if reply is not None:
                conn.sendall(reply)
                answered()


@dataclass
class PymodbusStream:
    """pymodbus's reading of one TCP connection (transport.py datagram_received, the socket
    framer, ServerRequestHandler.callback_data), for the bytes of each read of the socket:
    one request is handled per read; sending its reply empties the receive buffer, so further
    requests that arrived in the same read are never answered; a frame with a protocol id
    other than 0 is never consumed (nothing after it is answered until more than 1024 unread
    bytes clear the buffer)."""

    device: OpenPlcV4Device
    buffer: bytes = b""

    def feed(self, data: bytes) -> bytes | None:
        """The reply frame to send for one read of ``data`` (None: nothing is sent); raises
        Close when pymodbus would drop the connection."""
        if len(self.buffer) > RECV_BUFFER_CLEAR:
            self.buffer = b""
        self.buffer += data
        used, reply = self._one_frame(self.buffer)
        self.buffer = b"" if reply is not None else self.buffer[used:]
        return reply

    def _one_frame(self, buf: bytes) -> tuple[int, bytes | None]:
        """(bytes consumed, reply frame or None) for the first frame of ``buf``."""
        if len(buf) < 8:
            return 0, None
        tid, protocol, length, unit = struct.unpack_from(">HHHB", buf)
        if protocol != 0:
            return 0, None
        end = length + 6
        if len(buf) < end:
            return 0, None
        if end == 8 and len(buf) == 9:
            end = 9  # FramerSocket.decode takes a lone ninth byte into a 2-byte PDU
        pdu = buf[7:end]
        if not pdu:
            return end, None
        reply, undecodable = self.device.handle(unit, pdu)
        if reply is None:
            return end, None
        if undecodable:  # ExceptionResponse(40, ...): transaction 0, unit 1; buffer consumed
            return len(buf), struct.pack(">HHHB", 0, 0, len(reply) + 1, 1) + reply
        return end, struct.pack(">HHHB", tid, 0, len(reply) + 1, unit) + reply


_NATIVE_LITTLE: Final = struct.pack("=H", 1) == b"\x01\x00"

# bytes each request's fields need, function code included (pymodbus decodes with struct and
# drops the connection when they are missing)
_MIN_PDU: Final[Mapping[int, Callable[[bytes], int]]] = {
    1: lambda p: 5, 2: lambda p: 5, 3: lambda p: 5, 4: lambda p: 5, 5: lambda p: 5,
    6: lambda p: 5, 15: lambda p: 6, 22: lambda p: 7,
    16: lambda p: 6 + 2 * struct.unpack_from(">H", p, 3)[0] if len(p) >= 5 else 6,
    23: lambda p: 10 + 2 * ((p[9] + 1) // 2) if len(p) >= 10 else 10}


def _need(pdu: bytes, size: Callable[[bytes], int]) -> None:
    if len(pdu) < size(pdu):
        raise Close


def _outside(start: int, count: int, size: int, per_address: bool) -> bool:
    """Whether a read of ``count`` from ``start`` is refused: blocks that check each address
    refuse only addresses they read, the others the whole range first."""
    if per_address and count == 0:
        return False
    return start + count > size


def _exception(function: int, code: int) -> bytes:
    return bytes((function | 0x80, code))


def _words_reply(function: int, words: list[int]) -> bytes | None:
    if 2 * len(words) > MAX_REPLY_DATA:
        return None  # the byte count does not fit one byte: pymodbus sends nothing
    return bytes((function, 2 * len(words))) + struct.pack(f">{len(words)}H", *words)


def _diagnostic(pdu: bytes) -> bytes | None:
    """pymodbus's own answers to the diagnostic and identification functions (measured on
    3.12.1 with the plugin's empty identity); None for any other function."""
    function = pdu[0]
    if function == 7:
        return b"\x07\x00"
    if function == 8 and len(pdu) >= 3:
        return pdu
    if function == 11:
        return b"\x0b\x00\x00\x00\x00"
    if function == 12:
        return b"\x0c\x06" + bytes(6)
    if function == 17:
        return b"\x11\x09Pymodbus\xff"
    if function == 43:
        if len(pdu) < 4:
            raise Close
        if pdu[1] == 0x0E:
            return bytes((43, 0x0E, pdu[2], 0x83, 0, 0, 0))
    return None
