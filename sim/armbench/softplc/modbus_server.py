"""Modbus TCP server over a :class:`ProcessImage` with OpenPLC v3's address map
(docs/matiec-facts.md), or with the CODESYS variant's layout when given a
:class:`~armbench.softplc.codesys_device.CodesysDevice` (its requests and rules are that
module's; the connection handling below is shared).

Hand-written MBAP/PDU handling instead of pymodbus: it is several times faster per request,
lets every request run under the scan lock (so function 16 lands atomically between scans),
and keeps pymodbus out of everything but the client module.

Parity with the OpenPLC v3 runtime (docs/modbus-parity.md; measured on the real runtime and
pinned by tests/modbus/test_modbus_openplc_parity.py, which runs against both). The server
answers the way the runtime does, not the way the Modbus specification would:

* Quantity 0 is not an error: FC1-FC4 answer with an empty data field, FC15/FC16 (byte
  count 0) echo address and quantity 0 and write nothing.
* Size limits come from the one-byte byte count, not from the spec's ADU limits: reads of
  more than 255 data bytes (FC1/FC2 above 2040 bits, FC3/FC4 above 127 registers) are
  exception 2 (not 3). FC15/FC16 take up to 255/254 data bytes (2040 coils, 127 registers);
  a byte count that does not match the quantity, or fewer data bytes than it, is exception 3.
  Frames of any MBAP length up to 9994 are read whole.
* Bit requests work on whole bytes: FC1/FC2/FC15 cover start .. start + 8 * byte count - 1,
  so the range is checked against 8192 rounded up to whole bytes (FC1 at 8185 for 1 coil is
  exception 2); the unused bits of a read reply carry the neighbouring bits' values, and FC15
  writes the padding bits of its data to the neighbouring coils.
* Writes that run past the end of a table (FC15, FC16) write the part inside it, then answer
  exception 2.
* FC5 treats any non-zero value as TRUE (0x1234 sets the coil) and echoes it.
* Trailing bytes after a complete PDU are ignored; a PDU shorter than 5 bytes is exception 3.

Not copied: the runtime's accept loop takes one connection per 100 ms and can lose a client
that connects within that window; this server accepts at once. The runtime has no idle
timeout and no connection limit (one thread per connection, for ever); this server closes a
connection that completes no request for ``idle_timeout_s`` (default 300 s) and, when
``max_clients`` connections (default 64) are open, makes room for a new client by closing the
one that has been idle longest, so forgotten, half-open or trickling connections can never
lock a client out. The runtime always binds every interface; this server binds loopback by
default and logs a warning when bound to anything else.

Threading model: one accept thread (selector + wake-up socket so ``stop`` needs no polling)
and one thread per connection with a blocking socket. The accept thread also enforces the
idle timeout: it sleeps in ``select`` until the oldest deadline and shuts expired sockets
down, which wakes their threads (blocked in ``recv``, or in ``sendall`` to a peer that does
not read) so they close and exit. A connection thread only records the time of each complete
request, so the request path costs one clock read more. A connection that sends a broken
frame is dropped without affecting the others.

Two request paths answer alike: by default each connection thread hands its socket to the
compiled loop of ``modbus_fast.c`` (fastpath.py), which serves it in C with the GIL released
and takes the scan lock (an :class:`~armbench.softplc.fastpath.ImageLock`) around each
request; with a plain ``threading.Lock`` (or ``fast_path=False``) the thread runs
``_serve_frames`` and :class:`PduHandler` below, the Python reference of every rule above
(docs/modbus-parity.md, Performance).
"""

from __future__ import annotations

import contextlib
import ipaddress
import logging
import selectors
import socket
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final, Protocol

from .codesys_device import CodesysDevice
from .fastpath import FastConnection, ImageLock, ScanLock, new_scan_lock
from .image import MD_OFFSET, ML_OFFSET, QW_OFFSET, ProcessImage
from .modbus_map import (
    COIL_COUNT,
    DISCRETE_INPUT_COUNT,
    HOLDING_REGISTER_COUNT,
    ILLEGAL_DATA_ADDRESS,
    ILLEGAL_DATA_VALUE,
    ILLEGAL_FUNCTION,
    INPUT_REGISTER_COUNT,
    MD_BASE,
    ML_BASE,
)
from .openplc_v4 import OpenPlcV4Device

_log = logging.getLogger(__name__)

DEFAULT_HOST: Final = "127.0.0.1"
DEFAULT_PORT: Final = 5020
# Lockout is prevented by closing the longest-idle connection when the table is full, so the
# timeout only has to free the thread and socket of a vanished peer (cable pulled, process
# killed without FIN) eventually; it can be long enough for a person pausing in a REPL, after
# which a pymodbus client's next request fails once and the one after reconnects.
DEFAULT_IDLE_TIMEOUT_S: Final = 300.0
DEFAULT_MAX_CLIENTS: Final = 64
SERVER_DEVICE_FAILURE: Final = 4

# OpenPLC v3 runtime limits (docs/modbus-parity.md), not the Modbus spec's (2000 bits, 125
# registers, 253-byte PDU): a byte count is one byte, so a request or reply carries at most
# 255 data bytes, and the runtime reads frames into a 10000-byte buffer.
MAX_DATA_BYTES: Final = 255
MAX_REGISTERS: Final = MAX_DATA_BYTES // 2  # 127
# MBAP length counts unit id + PDU; longer frames do not fit the runtime's buffer.
MAX_MBAP_LENGTH: Final = 10000 - 6

_MBAP = struct.Struct(">HHHB")
_MBAP_SIZE: Final = _MBAP.size
_ADDR_QTY = struct.Struct(">BHH")  # function code, address, quantity/value
_WRITE_MULTI = struct.Struct(">BHHB")  # ... plus byte count
_EXCEPTION = struct.Struct(">BB")
_READ_REPLY = struct.Struct(">BB")  # function code, byte count

# Precompiled per-quantity structs: big-endian for the wire, native ('=', standard sizes)
# for the image. Index = element count.
# A misaligned span of n registers touches up to n // k + 2 values of k registers each.
_BE_H: Final = tuple(struct.Struct(f">{n}H") for n in range(MAX_REGISTERS + 1))
_BE_I: Final = tuple(struct.Struct(f">{n}I") for n in range(MAX_REGISTERS // 2 + 3))
_BE_Q: Final = tuple(struct.Struct(f">{n}Q") for n in range(MAX_REGISTERS // 4 + 3))
_NE_H: Final = tuple(struct.Struct(f"={n}H") for n in range(MAX_REGISTERS + 1))
_NE_I: Final = tuple(struct.Struct(f"={n}I") for n in range(MAX_REGISTERS // 2 + 3))
_NE_Q: Final = tuple(struct.Struct(f"={n}Q") for n in range(MAX_REGISTERS // 4 + 3))

# bytes.translate tables between 0/1 bytes and ASCII '0'/'1', for bit packing via int().
_BYTE_TO_ASCII01: Final = bytes([0x30] + [0x31] * 255)
_ASCII01_TO_BYTE: Final = bytes.maketrans(b"01", b"\x00\x01")


def _pack_bits(values: bytes) -> bytes:
    """0/non-zero bytes → Modbus bit field (first value in bit 0 of the first byte)."""
    bits = int(values.translate(_BYTE_TO_ASCII01)[::-1], 2)
    return bits.to_bytes((len(values) + 7) // 8, "little")


def _unpack_bits(data: bytes, count: int) -> bytes:
    """Modbus bit field → ``count`` bytes of 0/1."""
    text = format(int.from_bytes(data, "little"), f"0{8 * len(data)}b")
    return text[::-1][:count].encode("ascii").translate(_ASCII01_TO_BYTE)


def _addr_qty(pdu: bytes) -> tuple[int, int, int]:
    """(function, address, quantity-or-value) of a request PDU of at least 5 bytes."""
    function, address, quantity = _ADDR_QTY.unpack_from(pdu)
    return function, address, quantity


def _exception(function: int, code: int) -> bytes:
    return _EXCEPTION.pack(function | 0x80, code)


@dataclass(frozen=True)
class _WideArea:
    """A holding-register area whose variables span several registers (%MD, %ML)."""

    base_register: int
    image_offset: int
    regs_per_item: int
    view: memoryview
    be: tuple[struct.Struct, ...]
    ne: tuple[struct.Struct, ...]

    def read(self, rel: int, count: int) -> bytes:
        k = self.regs_per_item
        first = rel // k
        last = (rel + count - 1) // k + 1
        # The big-endian encoding of each whole value is exactly its registers, MSW first.
        wire = self.be[last - first].pack(*self.view[first:last])
        skip = 2 * (rel - first * k)
        return wire[skip : skip + 2 * count]

    def write(self, raw: memoryview, rel: int, data: bytes) -> None:
        k = self.regs_per_item
        count = len(data) // 2
        first = rel // k
        last = (rel + count - 1) // k + 1
        n = last - first
        # Read-modify-write so a write covering part of a value keeps its other words (FC6 on
        # one half of a REAL).
        wire = bytearray(self.be[n].pack(*self.view[first:last]))
        skip = 2 * (rel - first * k)
        wire[skip : skip + len(data)] = data
        itemsize = 2 * k
        self.ne[n].pack_into(raw, self.image_offset + itemsize * first, *self.be[n].unpack(wire))


class RequestHandler(Protocol):
    """Answers one Modbus request PDU with a response PDU (never raises)."""

    def handle(self, pdu: bytes) -> bytes: ...


@dataclass
class PduHandler:
    """Executes one Modbus request PDU against the image and returns the response PDU.

    Socket-free so the protocol logic is testable on its own. Image access happens under
    ``lock`` (the scan lock), parsing and encoding outside it.
    """

    image: ProcessImage
    lock: ScanLock
    _dispatch: dict[int, Callable[[bytes], bytes]] = field(init=False, repr=False)
    _md: _WideArea = field(init=False, repr=False)
    _ml: _WideArea = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._dispatch = {
            1: self._read_coils,
            2: self._read_discrete_inputs,
            3: self._read_holding,
            4: self._read_input,
            5: self._write_coil,
            6: self._write_register,
            15: self._write_coils,
            16: self._write_registers,
        }
        self._md = _WideArea(MD_BASE, MD_OFFSET, 2, self.image.md, _BE_I, _NE_I)
        self._ml = _WideArea(ML_BASE, ML_OFFSET, 4, self.image.ml, _BE_Q, _NE_Q)

    def handle(self, pdu: bytes) -> bytes:
        function = pdu[0]
        handler = self._dispatch.get(function)
        if handler is None:
            return _exception(function, ILLEGAL_FUNCTION)
        try:
            return handler(pdu)
        except Exception:  # a bug here must cost one request, not the connection
            _log.exception("modbus request %r failed", pdu[:16])
            return _exception(function, SERVER_DEVICE_FAILURE)

    # -- bits ----------------------------------------------------------------------------
    # OpenPLC works on whole bytes of bits: a request for ``count`` bits at ``start`` covers
    # the 8 * ceil(count / 8) bits from ``start``, all of which must exist, are read into the
    # reply (the padding bits too) and, for FC15, are written from the request's data.

    def _read_bits(self, pdu: bytes, view: memoryview, size: int) -> bytes:
        if len(pdu) < 5:
            return _exception(pdu[0], ILLEGAL_DATA_VALUE)
        function, start, count = _addr_qty(pdu)
        nbytes = (count + 7) // 8
        if nbytes == 0:
            return _READ_REPLY.pack(function, 0)
        end = start + 8 * nbytes
        if nbytes > MAX_DATA_BYTES or end > size:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        with self.lock:
            values = view[start:end].tobytes()
        return _READ_REPLY.pack(function, nbytes) + _pack_bits(values)

    def _read_coils(self, pdu: bytes) -> bytes:
        return self._read_bits(pdu, self.image.qx, COIL_COUNT)

    def _read_discrete_inputs(self, pdu: bytes) -> bytes:
        return self._read_bits(pdu, self.image.ix, DISCRETE_INPUT_COUNT)

    def _write_coil(self, pdu: bytes) -> bytes:
        if len(pdu) < 5:
            return _exception(pdu[0], ILLEGAL_DATA_VALUE)
        function, address, value = _addr_qty(pdu)
        if address >= COIL_COUNT:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        with self.lock:
            self.image.qx[address] = 1 if value else 0  # any non-zero value is TRUE
        return pdu[:5]

    def _write_coils(self, pdu: bytes) -> bytes:
        if len(pdu) < 5:
            return _exception(pdu[0], ILLEGAL_DATA_VALUE)
        function, start, count = _addr_qty(pdu)
        nbytes = (count + 7) // 8
        if len(pdu) < _WRITE_MULTI.size + nbytes or pdu[5] != nbytes:
            return _exception(function, ILLEGAL_DATA_VALUE)
        if nbytes == 0:
            return pdu[:5]
        end = start + 8 * nbytes
        stop = min(end, COIL_COUNT)
        if stop > start:
            data = pdu[_WRITE_MULTI.size : _WRITE_MULTI.size + nbytes]
            values = _unpack_bits(data, 8 * nbytes)[: stop - start]
            with self.lock:
                self.image.qx[start:stop] = values
        # Past the end: the part inside the table is written all the same.
        if end > COIL_COUNT:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        return pdu[:5]

    # -- registers -----------------------------------------------------------------------

    def _read_holding(self, pdu: bytes) -> bytes:
        if len(pdu) < 5:
            return _exception(pdu[0], ILLEGAL_DATA_VALUE)
        function, start, count = _addr_qty(pdu)
        if count == 0:
            return _READ_REPLY.pack(function, 0)
        end = start + count
        if count > MAX_REGISTERS or end > HOLDING_REGISTER_COUNT:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        if end <= MD_BASE:  # the common case: %QW/%MW only, one contiguous uint16 array
            with self.lock:
                data = _BE_H[count].pack(*self.image.qw_mw[start:end])
        else:
            with self.lock:
                data = self._read_holding_span(start, end)
        return _READ_REPLY.pack(function, 2 * count) + data

    def _read_holding_span(self, start: int, end: int) -> bytes:
        parts: list[bytes] = []
        address = start
        while address < end:
            if address < MD_BASE:
                stop = min(end, MD_BASE)
                parts.append(_BE_H[stop - address].pack(*self.image.qw_mw[address:stop]))
            elif address < ML_BASE:
                stop = min(end, ML_BASE)
                parts.append(self._md.read(address - MD_BASE, stop - address))
            else:
                stop = end
                parts.append(self._ml.read(address - ML_BASE, stop - address))
            address = stop
        return b"".join(parts)

    def _read_input(self, pdu: bytes) -> bytes:
        if len(pdu) < 5:
            return _exception(pdu[0], ILLEGAL_DATA_VALUE)
        function, start, count = _addr_qty(pdu)
        if count == 0:
            return _READ_REPLY.pack(function, 0)
        end = start + count
        if count > MAX_REGISTERS or end > INPUT_REGISTER_COUNT:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        with self.lock:
            data = _BE_H[count].pack(*self.image.iw[start:end])
        return _READ_REPLY.pack(function, 2 * count) + data

    def _write_register(self, pdu: bytes) -> bytes:
        if len(pdu) < 5:
            return _exception(pdu[0], ILLEGAL_DATA_VALUE)
        function, address, value = _addr_qty(pdu)
        if address >= HOLDING_REGISTER_COUNT:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        if address < MD_BASE:
            with self.lock:
                self.image.qw_mw[address] = value
        else:
            with self.lock:
                self._write_holding_span(address, pdu[3:5])
        return pdu[:5]

    def _write_registers(self, pdu: bytes) -> bytes:
        if len(pdu) < 5:
            return _exception(pdu[0], ILLEGAL_DATA_VALUE)
        function, start, count = _addr_qty(pdu)
        nbytes = 2 * count
        # The byte count is one byte, so this also limits count to 127.
        if len(pdu) < _WRITE_MULTI.size + nbytes or pdu[5] != nbytes:
            return _exception(function, ILLEGAL_DATA_VALUE)
        if count == 0:
            return pdu[:5]
        end = start + count
        stop = min(end, HOLDING_REGISTER_COUNT)
        if stop > start:
            data = pdu[_WRITE_MULTI.size : _WRITE_MULTI.size + 2 * (stop - start)]
            # One lock hold for the whole request: a scan sees all of it or none of it.
            with self.lock:
                self._write_holding_span(start, data)
        # Past the end: the part inside the table is written all the same.
        if end > HOLDING_REGISTER_COUNT:
            return _exception(function, ILLEGAL_DATA_ADDRESS)
        return pdu[:5]

    def _write_holding_span(self, start: int, data: bytes) -> None:
        raw = self.image.raw
        end = start + len(data) // 2
        address = start
        while address < end:
            offset = 2 * (address - start)
            if address < MD_BASE:
                stop = min(end, MD_BASE)
                n = stop - address
                values = _BE_H[n].unpack_from(data, offset)
                _NE_H[n].pack_into(raw, QW_OFFSET + 2 * address, *values)
            elif address < ML_BASE:
                stop = min(end, ML_BASE)
                self._md.write(raw, address - MD_BASE, data[offset : 2 * (stop - start)])
            else:
                stop = end
                self._ml.write(raw, address - ML_BASE, data[offset:])
            address = stop


def non_loopback_warning(host: str, port: int) -> str | None:
    """The warning for a listener bound to ``host`` (an IPv4 address as the socket reports
    it), or None when only this machine can connect."""
    if ipaddress.ip_address(host).is_loopback:
        return None
    where = "all network interfaces" if host == "0.0.0.0" else "a non-loopback address"
    return (
        f"Modbus TCP on {host}:{port} listens on {where}: any host that can reach this port "
        "can write any register and move the servos (Modbus has no authentication). Bind "
        "127.0.0.1 (the default) unless the network is isolated and trusted."
    )


@dataclass(eq=False)
class _Connection:
    """One client connection; ``last_request`` is written by its own thread only (on the
    compiled path, ``fast``'s C loop keeps the time instead)."""

    sock: socket.socket
    peer: str
    last_request: float  # time.monotonic() of the accept or of the last complete request
    thread: threading.Thread | None = None
    closing: bool = False  # shut down by the server: no longer counts towards max_clients
    fast: FastConnection | None = None

    def activity(self) -> float:
        """time.monotonic() of the accept or of the last complete request."""
        return self.fast.last_request if self.fast is not None else self.last_request


class ModbusServer:
    """Modbus TCP server for one image.

    ``port=0`` binds a free port; read the chosen one from :attr:`port` after :meth:`start`.
    Pass the soft PLC's ``lock`` so requests interleave with scans, never inside one.

    ``idle_timeout_s``: a connection that completes no request for this long is closed (bytes
    of an unfinished frame do not count, so a trickling or half-sent request does not keep it
    open); None or 0 turns the timeout off. ``max_clients``: open connections; when all are
    taken, a new client is accepted and the connection idle longest is closed to make room.

    Requests run on the compiled path (``modbus_fast.c``: one C loop per connection, GIL
    released) when ``lock`` is an :class:`ImageLock` -- the soft PLC's default scan lock, and
    what the server makes for itself without one -- and ``fast_path`` is true; with a
    ``threading.Lock`` or ``fast_path=False`` they run through :class:`PduHandler` in Python.
    Both answer alike; :attr:`fast_path` says which one serves.

    ``device``: serve the CODESYS layout instead of OpenPLC's map
    (:class:`~armbench.softplc.codesys_device.CodesysDevice`, which the soft PLC must also
    get, to copy its data in and out of the image each scan), or answer as OpenPLC v4's
    Modbus plugin (:class:`~armbench.softplc.openplc_v4.OpenPlcV4Device`, which also reads
    each connection's bytes as pymodbus does, and whose journal the soft PLC drains each
    scan); always in Python.
    """

    def __init__(
        self,
        image: ProcessImage,
        lock: ScanLock | None = None,
        *,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        max_clients: int = DEFAULT_MAX_CLIENTS,
        idle_timeout_s: float | None = DEFAULT_IDLE_TIMEOUT_S,
        fast_path: bool = True,
        device: CodesysDevice | OpenPlcV4Device | None = None,
    ) -> None:
        if max_clients < 1:
            raise ValueError(f"max_clients must be at least 1, not {max_clients}")
        if idle_timeout_s is not None and not idle_timeout_s >= 0.0:  # also rejects NaN
            raise ValueError(
                f"idle timeout must be 0 (off) or a positive number of seconds, not "
                f"{idle_timeout_s}"
            )
        if device is not None:
            if device.image is not image or (lock is not None and device.lock is not lock):
                raise ValueError("the device must share the server's image and scan lock")
            lock, fast_path = device.lock, False
        if lock is None:
            lock = new_scan_lock() if fast_path else threading.Lock()
        self.handler: RequestHandler = (device if isinstance(device, CodesysDevice)
                                        else PduHandler(image, lock))
        self.device = device
        self.image = image
        self._image_lock = lock if fast_path and isinstance(lock, ImageLock) else None
        self.host = host
        self._requested_port = port
        self.max_clients = max_clients
        self.idle_timeout_s: float | None = idle_timeout_s or None
        self._listener: socket.socket | None = None
        self._wake_r: socket.socket | None = None
        self._wake_w: socket.socket | None = None
        self._accept_thread: threading.Thread | None = None
        # Also guards every shutdown()/close() of a client socket, so the accept thread never
        # shuts down a descriptor number that its connection thread has just closed and that
        # the process has already reused.
        self._clients_lock = threading.Lock()
        self._clients: list[_Connection] = []
        self._closing = threading.Event()

    @property
    def fast_path(self) -> bool:
        """True when connections are served by the compiled request path."""
        return self._image_lock is not None

    @property
    def port(self) -> int:
        if self._listener is None:
            raise RuntimeError("server not started")
        port: int = self._listener.getsockname()[1]
        return port

    @property
    def address(self) -> tuple[str, int]:
        return self.host, self.port

    @property
    def exposure_warning(self) -> str | None:
        """The non-loopback warning :meth:`start` logged, or None on a loopback address."""
        if self._listener is None:
            raise RuntimeError("server not started")
        host, port = self._listener.getsockname()
        return non_loopback_warning(host, port)

    def start(self) -> None:
        if self._listener is not None:
            raise RuntimeError("server already started")
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            # A restarted bench must be able to rebind the fixed port while old connections
            # sit in TIME_WAIT.
            listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            listener.bind((self.host, self._requested_port))
            listener.listen(min(self.max_clients, socket.SOMAXCONN))
            listener.setblocking(False)
        except OSError:
            listener.close()
            raise
        self._listener = listener
        warning = self.exposure_warning
        if warning is not None:
            _log.warning("%s", warning)
        self._wake_r, self._wake_w = socket.socketpair()
        self._closing.clear()
        self._accept_thread = threading.Thread(
            target=self._accept_loop, name=f"modbus-accept-{self.port}", daemon=True
        )
        self._accept_thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        """Close the listener and every connection; join all server threads."""
        if self._listener is None:
            return
        self._closing.set()
        assert self._wake_w is not None
        with contextlib.suppress(OSError):
            self._wake_w.send(b"x")
        if self._accept_thread is not None:
            self._accept_thread.join(timeout_s)
        with self._clients_lock:
            clients = list(self._clients)
            for client in clients:
                self._shut_down(client)
        for client in clients:
            if client.thread is not None:
                client.thread.join(timeout_s)
        with self._clients_lock:
            self._clients.clear()
        for sock in (self._listener, self._wake_r, self._wake_w):
            if sock is not None:
                sock.close()
        self._listener = self._wake_r = self._wake_w = None
        self._accept_thread = None

    def __enter__(self) -> ModbusServer:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def client_count(self) -> int:
        """Connection threads still running (including ones closing right now)."""
        with self._clients_lock:
            return sum(c.thread is not None and c.thread.is_alive() for c in self._clients)

    def _shut_down(self, client: _Connection) -> None:
        """Make ``client``'s thread return; caller holds ``_clients_lock``. Never blocks."""
        client.closing = True
        # shutdown() wakes a thread blocked in recv() or sendall(); the thread closes the
        # socket itself. OSError: it has already closed it.
        with contextlib.suppress(OSError):
            client.sock.shutdown(socket.SHUT_RDWR)

    def _accept_loop(self) -> None:
        assert self._listener is not None and self._wake_r is not None
        with selectors.DefaultSelector() as selector:
            selector.register(self._listener, selectors.EVENT_READ)
            selector.register(self._wake_r, selectors.EVENT_READ)
            while not self._closing.is_set():
                for key, _events in selector.select(self._close_idle()):
                    if key.fileobj is self._listener:
                        self._accept_one()

    def _close_idle(self) -> float | None:
        """Shut down connections past the idle timeout and forget finished ones; returns
        the seconds until the next connection can expire (None: nothing to wait for)."""
        timeout = self.idle_timeout_s
        now = time.monotonic()
        oldest: float | None = None
        with self._clients_lock:
            # Finished connections stay listed until here (not removed by their own thread)
            # so that stop() can join every thread that may still be running.
            self._clients = [c for c in self._clients if c.thread is None or c.thread.is_alive()]
            if timeout is None:
                return None
            for client in self._clients:
                if client.closing:
                    continue
                last = client.activity()
                if now - last >= timeout:
                    _log.info("closing connection from %s: no request for %.3g s",
                              client.peer, now - last)
                    self._shut_down(client)
                elif oldest is None or last < oldest:
                    oldest = last
        # The deadline may move on while we sleep (a request arrives); waking early then only
        # costs one more pass.
        return None if oldest is None else oldest + timeout - now

    def _accept_one(self) -> None:
        assert self._listener is not None
        try:
            conn, peer = self._listener.accept()
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            _log.exception("accept failed")
            return
        now = time.monotonic()
        client = _Connection(conn, f"{peer[0]}:{peer[1]}", now)
        if self._image_lock is not None:
            client.fast = FastConnection(self.image, self._image_lock, now)
        with self._clients_lock:
            if self._closing.is_set():
                conn.close()
                return
            open_clients = [c for c in self._clients if not c.closing]
            if len(open_clients) >= self.max_clients:
                # Refusing the newcomer would let forgotten or hostile idle connections lock
                # everyone out; the longest-idle one is the least likely to be in use.
                victim = min(open_clients, key=lambda c: c.activity())
                _log.info("%d connections open: closing the one idle longest (%s) for %s",
                          len(open_clients), victim.peer, client.peer)
                self._shut_down(victim)
            conn.setblocking(True)
            # Request/response traffic: Nagle would hold each small reply for the peer's ACK.
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            client.thread = threading.Thread(
                target=self._serve_connection, args=(client,), name="modbus-conn", daemon=True
            )
            self._clients.append(client)
        try:
            client.thread.start()
        except RuntimeError:  # out of threads: this client cannot be served
            _log.exception("cannot start a thread for %s", client.peer)
            with self._clients_lock:
                self._clients.remove(client)
                conn.close()

    def _serve_connection(self, client: _Connection) -> None:
        try:
            if client.fast is not None:
                # Returns when the peer closes, the framing is lost or the socket fails (an
                # error code, no exception: there is nothing to answer in any of these).
                client.fast.serve(client.sock.fileno())
            elif isinstance(self.device, OpenPlcV4Device):
                # OpenPLC v4: pymodbus's own way of reading the stream (openplc_v4.py)
                def answered() -> None:
                    client.last_request = time.monotonic()

                self.device.serve(client.sock, answered)
            else:
                self._serve_frames(client)
        except OSError:
            pass  # peer reset, idle timeout or server shutdown: nothing to answer any more
        except Exception:
            _log.exception("modbus connection failed")
        finally:
            with self._clients_lock:
                client.sock.close()

    def _serve_frames(self, client: _Connection) -> None:
        conn = client.sock
        handle = self.handler.handle
        mbap = _MBAP
        clock = time.monotonic
        pending = b""
        while True:
            chunk = conn.recv(4096)
            if not chunk:
                return
            data = pending + chunk if pending else chunk
            replies: list[bytes] = []
            pos = 0
            size = len(data)
            # Several pipelined frames may arrive in one chunk, or one frame over several.
            while size - pos >= _MBAP_SIZE:
                transaction, protocol, length, unit = mbap.unpack_from(data, pos)
                if protocol != 0 or not 2 <= length <= MAX_MBAP_LENGTH:
                    # Framing is lost; nothing after this can be trusted on this stream.
                    if replies:
                        conn.sendall(b"".join(replies))
                    return
                end = pos + 6 + length
                if end > size:
                    break
                reply = handle(data[pos + _MBAP_SIZE : end])
                replies.append(mbap.pack(transaction, 0, len(reply) + 1, unit) + reply)
                pos = end
            pending = data[pos:]
            if replies:
                # Only complete requests count as activity: a peer trickling bytes of a frame
                # it never finishes still times out.
                client.last_request = clock()
                conn.sendall(replies[0] if len(replies) == 1 else b"".join(replies))
