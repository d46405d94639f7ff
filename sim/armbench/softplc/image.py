"""The PLC process image: one flat buffer laid out exactly like OpenPLC v3's located-variable
buffers (``plc_image_t`` in the compiler's generated C), with typed views onto each area.

The compiled program, the scan cycle and the Modbus server all share the same bytes, so
nothing is ever copied between a "datastore" and the program: a Modbus write lands in the
variable itself, as on the real runtime.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Final

if TYPE_CHECKING:
    # Only for the annotation: typing_extensions is a dev (mypy) dependency, not a runtime one,
    # and collections.abc.Buffer needs Python 3.12.
    from typing_extensions import Buffer

# Areas in declaration order: (name, element count, element size in bytes, memoryview format).
# The C struct has no padding because every offset is already a multiple of the next element's
# size; keep this table and the compiler's struct in lockstep.
IX_COUNT: Final = 8192
QX_COUNT: Final = 8192
IW_COUNT: Final = 1024
QW_COUNT: Final = 1024
MW_COUNT: Final = 1024
MD_COUNT: Final = 1024
ML_COUNT: Final = 1024

IX_OFFSET: Final = 0
QX_OFFSET: Final = IX_OFFSET + IX_COUNT
IW_OFFSET: Final = QX_OFFSET + QX_COUNT
QW_OFFSET: Final = IW_OFFSET + 2 * IW_COUNT
MW_OFFSET: Final = QW_OFFSET + 2 * QW_COUNT
MD_OFFSET: Final = MW_OFFSET + 2 * MW_COUNT
ML_OFFSET: Final = MD_OFFSET + 4 * MD_COUNT
IMAGE_SIZE: Final = ML_OFFSET + 8 * ML_COUNT

# memoryview.cast uses native byte order and these formats are fixed-size on every platform
# CPython supports ('I' is 4 bytes, 'Q' 8), matching uint32_t/uint64_t in the C struct.
assert IMAGE_SIZE == 34816


def _check_native_formats() -> None:
    probe = memoryview(bytearray(8))
    if probe.cast("I").itemsize != 4 or probe.cast("Q").itemsize != 8:
        raise RuntimeError("platform C int sizes do not match plc_image_t")


_check_native_formats()

NATIVE_BYTEORDER: Final = sys.byteorder

# (area, size letter) -> (offset of the area, bytes per element); bits are one byte each.
_AREAS: Final = {("I", "X"): (IX_OFFSET, 1), ("Q", "X"): (QX_OFFSET, 1),
                 ("I", "W"): (IW_OFFSET, 2), ("Q", "W"): (QW_OFFSET, 2),
                 ("M", "W"): (MW_OFFSET, 2), ("M", "D"): (MD_OFFSET, 4),
                 ("M", "L"): (ML_OFFSET, 8)}
_LOCATION = re.compile(r"^%([IQM])([XWDL])(\d+)(?:\.([0-7]))?$", re.IGNORECASE)


def image_span(location: str) -> tuple[int, int]:
    """(byte offset in the image, bytes) of the variable at a direct address; a BOOL takes one
    byte (0 or 1). ValueError for an address the image does not hold (%MX, %IB, %QD, ...: the
    compiled program keeps those in storage of its own)."""
    m = _LOCATION.match(location.strip())
    found = None if m is None else _AREAS.get((m.group(1).upper(), m.group(2).upper()))
    if m is None or found is None or (m.group(2).upper() == "X") != (m.group(4) is not None):
        raise ValueError(f"{location} is not in the process image (it holds %IX %QX %IW %QW "
                         "%MW %MD %ML)")
    offset, size = found
    index = int(m.group(3))
    if m.group(4) is not None:
        index = 8 * index + int(m.group(4))
    start = offset + size * index
    # each area is followed by the next: the element must end inside its own area
    area_end = min((o for o, _ in _AREAS.values() if o > offset), default=IMAGE_SIZE)
    if start + size > area_end:
        raise ValueError(f"{location} is outside the process image")
    return start, size


@dataclass(frozen=True, eq=False)
class ProcessImage:
    """Typed views over one writable ``plc_image_t`` buffer.

    Build it with :meth:`from_buffer` (C memory handed over by the compiler's FFI layer) or
    :meth:`allocate` (a zeroed bytearray, for tests and tools). ``raw`` is the whole image as
    unsigned bytes; the other attributes are native-endian element views into the same memory.
    """

    raw: memoryview
    ix: memoryview = field(init=False)
    qx: memoryview = field(init=False)
    iw: memoryview = field(init=False)
    qw: memoryview = field(init=False)
    mw: memoryview = field(init=False)
    md: memoryview = field(init=False)
    ml: memoryview = field(init=False)
    # Holding registers 0..2047 are %QW then %MW, adjacent in memory, so the Modbus server can
    # treat them as one uint16 array.
    qw_mw: memoryview = field(init=False)

    def __post_init__(self) -> None:
        raw = self.raw
        if raw.readonly:
            raise ValueError("process image buffer must be writable")
        if raw.nbytes != IMAGE_SIZE or raw.format != "B" or not raw.c_contiguous:
            raise ValueError(
                f"process image must be {IMAGE_SIZE} contiguous bytes, got {raw.nbytes} "
                f"bytes of format {raw.format!r}"
            )
        views = {
            "ix": raw[IX_OFFSET:QX_OFFSET],
            "qx": raw[QX_OFFSET:IW_OFFSET],
            "iw": raw[IW_OFFSET:QW_OFFSET].cast("H"),
            "qw": raw[QW_OFFSET:MW_OFFSET].cast("H"),
            "mw": raw[MW_OFFSET:MD_OFFSET].cast("H"),
            "md": raw[MD_OFFSET:ML_OFFSET].cast("I"),
            "ml": raw[ML_OFFSET:IMAGE_SIZE].cast("Q"),
            "qw_mw": raw[QW_OFFSET:MD_OFFSET].cast("H"),
        }
        # frozen=True keeps callers from rebinding the views; the buffer itself stays mutable.
        for name, view in views.items():
            object.__setattr__(self, name, view)

    @classmethod
    def from_buffer(cls, buffer: Buffer) -> ProcessImage:
        """Wrap existing memory (e.g. ``ffi.buffer(image_ptr, IMAGE_SIZE)``) without copying."""
        view = memoryview(buffer)
        if view.format != "B":
            view = view.cast("B")
        return cls(view)

    @classmethod
    def allocate(cls) -> ProcessImage:
        """A zeroed image in Python memory."""
        return cls(memoryview(bytearray(IMAGE_SIZE)))

    def snapshot(self) -> bytes:
        """A copy of the whole image (e.g. to compare before/after a faulted scan)."""
        return self.raw.tobytes()

    def restore(self, data: bytes) -> None:
        """Overwrite the whole image with a previous :meth:`snapshot`."""
        if len(data) != IMAGE_SIZE:
            raise ValueError(f"snapshot must be {IMAGE_SIZE} bytes, got {len(data)}")
        self.raw[:] = data

    def clear(self) -> None:
        """Zero every area."""
        self.raw[:] = bytes(IMAGE_SIZE)
