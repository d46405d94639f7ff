"""The Modbus server's compiled request path (``modbus_fast.c``) and the scan lock it shares
with the soft PLC.

Profiling the Python server (docs/modbus-parity.md, Performance) showed the time per request
in the interpreter: framing, dispatch, struct packing and the lock, about 10 µs per FC16 of
three REALs where the OpenPLC runtime's C spends well under one. ``modbus_fast.c`` serves a
whole connection in C with the GIL released, answering byte for byte like
:class:`~armbench.softplc.modbus_server.PduHandler`.

The C loop cannot take a Python ``threading.Lock``, so the scan lock is an :class:`ImageLock`:
a C binary semaphore with ``threading.Lock``'s interface, which the scan thread (Python) and
the C connection loops both take. :class:`~armbench.softplc.scan.SoftPlc` creates one by
default; a server given a plain ``threading.Lock`` keeps the Python path.

The C file is built with the system C compiler, as the ST programs are, and cached by content
hash beside them (``ARMBENCH_CACHE``, else ``~/.cache/armbench``).
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
import subprocess
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeAlias

import cffi

from ..compiler.build import BuildError, cache_dir, find_cc
from .image import ProcessImage

_log = logging.getLogger(__name__)

SOURCE = Path(__file__).with_name("modbus_fast.c")
CFLAGS = ("-O2", "-fPIC", "-shared", "-std=gnu11", "-pthread")
REPLY_MAX = 260  # MB_REPLY_MAX in modbus_fast.c

_CDEF = """
typedef struct mb_lock mb_lock;
mb_lock *mb_lock_new(void);
void mb_lock_free(mb_lock *l);
int mb_lock_acquire(mb_lock *l, double timeout_s);
int mb_lock_release(mb_lock *l);
int mb_lock_locked(mb_lock *l);
size_t mb_handle(uint8_t *img, mb_lock *lock, const uint8_t *pdu, size_t n, uint8_t *out);
int mb_serve(int fd, uint8_t *img, mb_lock *lock, double *last_request);
"""


@dataclass(frozen=True)
class FastLib:
    """The loaded library and its cffi handle."""

    ffi: cffi.FFI
    lib: Any


def build_library() -> Path:
    """Compile modbus_fast.c (once per content and flags); returns the shared library."""
    code = SOURCE.read_bytes()
    digest = hashlib.sha256(code + b"\0" + " ".join(CFLAGS).encode()).hexdigest()[:24]
    out_dir = cache_dir()
    out_dir.mkdir(parents=True, exist_ok=True)
    so = out_dir / f"modbus_fast_{digest}.so"
    if so.exists():
        return so
    cc = find_cc()
    # compile to a temporary name, then rename: concurrent builds (xdist workers) never load
    # a partial file
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=out_dir)
    os.close(fd)
    proc = subprocess.run([cc, *CFLAGS, str(SOURCE), "-o", tmp], capture_output=True, text=True)
    if proc.returncode != 0:
        Path(tmp).unlink(missing_ok=True)
        raise BuildError(f"the C compiler rejected {SOURCE}:\n{proc.stderr[:4000]}")
    os.replace(tmp, so)
    return so


@functools.cache
def load() -> FastLib:
    """The library, built and loaded once per process (it keeps no state of its own: every
    lock and connection lives in memory its caller passes in, so one copy serves all)."""
    ffi = cffi.FFI()
    ffi.cdef(_CDEF)
    return FastLib(ffi, ffi.dlopen(str(build_library())))


class ImageLock:
    """The scan lock, usable from Python like ``threading.Lock`` and from the C request path.

    A binary semaphore (as ``threading.Lock`` is): any thread may release it. Acquiring
    releases the GIL while it waits, so a Python thread waiting for a scan never holds up the
    scan thread.
    """

    def __init__(self) -> None:
        self._fast = load()
        handle = self._fast.lib.mb_lock_new()
        if handle == self._fast.ffi.NULL:
            raise MemoryError("cannot allocate the scan lock")
        self.handle: Any = self._fast.ffi.gc(handle, self._fast.lib.mb_lock_free)

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        if not blocking:
            if timeout != -1:
                raise ValueError("can't specify a timeout for a non-blocking call")
            timeout = 0.0
        elif timeout < 0 and timeout != -1:
            raise ValueError("timeout value must be a non-negative number")
        return bool(self._fast.lib.mb_lock_acquire(self.handle, float(timeout)))

    def release(self) -> None:
        if self._fast.lib.mb_lock_release(self.handle) != 0:
            raise RuntimeError("release unlocked lock")

    def locked(self) -> bool:
        return bool(self._fast.lib.mb_lock_locked(self.handle))

    def __enter__(self) -> bool:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


class FastHandler:
    """One request PDU through the C path; the same interface as ``PduHandler.handle``
    (used by the tests that compare the two, and by nothing on the request path)."""

    def __init__(self, image: ProcessImage, lock: ImageLock) -> None:
        self._fast = load()
        self.image = image
        self.lock = lock
        self._img = self._fast.ffi.from_buffer(image.raw)
        self._out = self._fast.ffi.new("uint8_t[]", REPLY_MAX)

    def handle(self, pdu: bytes) -> bytes:
        if not pdu:
            raise ValueError("a request PDU has at least a function code")
        n = self._fast.lib.mb_handle(self._img, self.lock.handle, pdu, len(pdu), self._out)
        return bytes(self._fast.ffi.buffer(self._out, n))


class FastConnection:
    """Serves one connected socket in C until it closes; see ``mb_serve`` in modbus_fast.c."""

    def __init__(self, image: ProcessImage, lock: ImageLock, accepted_at: float) -> None:
        self._fast = load()
        self._img = self._fast.ffi.from_buffer(image.raw)
        self._lock = lock
        # Written by the C loop, read by the server's accept thread (a double is written in
        # one store on every platform CPython supports; a torn read would only move one
        # idle deadline).
        self._last = self._fast.ffi.new("double[1]", [accepted_at])

    @property
    def last_request(self) -> float:
        return float(self._last[0])

    def serve(self, fd: int) -> int:
        """0 when the peer closed or the framing was lost, -errno on a socket error."""
        rc: int = self._fast.lib.mb_serve(fd, self._img, self._lock.handle, self._last)
        return rc


# A string: threading.Lock is a factory function, not a class, before Python 3.13.
ScanLock: TypeAlias = "threading.Lock | ImageLock"


def new_scan_lock() -> ScanLock:
    """An :class:`ImageLock`, or a ``threading.Lock`` (and so the Python request path) where
    the C file cannot be built; the reason is logged once per process."""
    try:
        return ImageLock()
    except (BuildError, OSError) as exc:
        _warn_no_fast_path(str(exc))
        return threading.Lock()


@functools.cache
def _warn_no_fast_path(reason: str) -> None:
    _log.warning("Modbus server: compiled request path unavailable, using the Python one "
                 "(%s)", reason.splitlines()[0] if reason else "unknown reason")
