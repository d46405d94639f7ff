"""ProcessImage layout matches plc_image_t and its views share one buffer."""

from __future__ import annotations

import ctypes
import struct

import pytest

from armbench.softplc import IMAGE_SIZE, ProcessImage
from armbench.softplc import image as im


class PlcImageT(ctypes.Structure):
    """The compiler's C struct, declared independently here to check offsets and sizes."""

    _fields_ = [
        ("ix", ctypes.c_uint8 * 8192),
        ("qx", ctypes.c_uint8 * 8192),
        ("iw", ctypes.c_uint16 * 1024),
        ("qw", ctypes.c_uint16 * 1024),
        ("mw", ctypes.c_uint16 * 1024),
        ("md", ctypes.c_uint32 * 1024),
        ("ml", ctypes.c_uint64 * 1024),
    ]


def test_layout_matches_c_struct() -> None:
    assert ctypes.sizeof(PlcImageT) == IMAGE_SIZE == 34816
    for name, offset in [
        ("ix", im.IX_OFFSET),
        ("qx", im.QX_OFFSET),
        ("iw", im.IW_OFFSET),
        ("qw", im.QW_OFFSET),
        ("mw", im.MW_OFFSET),
        ("md", im.MD_OFFSET),
        ("ml", im.ML_OFFSET),
    ]:
        assert getattr(PlcImageT, name).offset == offset


def test_views_alias_c_memory() -> None:
    c_image = PlcImageT()
    image = ProcessImage.from_buffer(c_image)
    image.md[3] = 0xDEADBEEF
    image.ml[5] = 0x0123456789ABCDEF
    image.qx[21] = 1
    image.mw[7] = 0xBEEF
    assert c_image.md[3] == 0xDEADBEEF
    assert c_image.ml[5] == 0x0123456789ABCDEF
    assert c_image.qx[21] == 1
    assert c_image.mw[7] == 0xBEEF
    c_image.iw[1023] = 4242
    assert image.iw[1023] == 4242


def test_view_formats_and_lengths(image: ProcessImage) -> None:
    expected = {"ix": ("B", 8192), "qx": ("B", 8192), "iw": ("H", 1024), "qw": ("H", 1024),
                "mw": ("H", 1024), "md": ("I", 1024), "ml": ("Q", 1024), "qw_mw": ("H", 2048)}
    for name, (fmt, length) in expected.items():
        view = getattr(image, name)
        assert (view.format, len(view)) == (fmt, length), name


def test_native_raw_bits(image: ProcessImage) -> None:
    struct.pack_into("=f", image.raw, im.MD_OFFSET, 1.5)
    assert image.md[0] == struct.unpack("=I", struct.pack("=f", 1.5))[0]
    image.qw_mw[1024 + 2] = 77
    assert image.mw[2] == 77


def test_snapshot_restore(image: ProcessImage) -> None:
    image.qw[0] = 1
    snap = image.snapshot()
    image.qw[0] = 2
    image.restore(snap)
    assert image.qw[0] == 1
    image.clear()
    assert image.snapshot() == bytes(IMAGE_SIZE)
    with pytest.raises(ValueError):
        image.restore(b"short")


def test_rejects_wrong_buffers() -> None:
    with pytest.raises(ValueError):
        ProcessImage.from_buffer(bytearray(IMAGE_SIZE - 1))
    with pytest.raises(ValueError):
        ProcessImage.from_buffer(bytes(IMAGE_SIZE))
