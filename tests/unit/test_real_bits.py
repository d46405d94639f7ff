"""st/RealBits.st RealBitPattern against Python's own IEEE 754 packing (struct), over the
special values, every binade from the smallest subnormal to the largest REAL, and random
float32 bit patterns."""

from __future__ import annotations

import math
import struct
from typing import Any

import numpy as np

CANONICAL_NAN = 0x7FC00000


def reference_bits(x: float) -> int:
    """The float32 pattern, with the two canonical cases the header documents."""
    if math.isnan(x):
        return CANONICAL_NAN
    if x == 0.0:
        return 0  # -0.0 too
    return int(struct.unpack(">I", struct.pack(">f", x))[0])


def as_float32(bits: int) -> float:
    return float(struct.unpack(">f", struct.pack(">I", bits))[0])


def check(st_module: Any, values: list[float]) -> None:
    for x in values:
        got = st_module.call("RealBitPattern", X=x)
        assert got == reference_bits(x), f"RealBitPattern({x!r}) = {got:#010x}, want " \
                                         f"{reference_bits(x):#010x}"


def test_documented_examples(st_module: Any) -> None:
    assert st_module.call("RealBitPattern", X=1.5) == 0x3FC00000
    assert st_module.call("RealBitPattern", X=-2.0) == 0xC0000000
    assert st_module.call("RealBitPattern", X=math.inf) == 0x7F800000
    assert st_module.call("RealBitPattern", X=-math.inf) == 0xFF800000
    assert st_module.call("RealBitPattern", X=as_float32(1)) == 0x00000001
    assert st_module.call("RealBitPattern", X=-0.0) == 0
    assert st_module.call("RealBitPattern", X=math.nan) == CANONICAL_NAN
    assert st_module.call("RealBitPattern", X=as_float32(0xFFC12345)) == CANONICAL_NAN


def test_every_binade_and_its_neighbours(st_module: Any) -> None:
    values: list[float] = []
    for biased in range(0, 255):
        for fraction in (0, 1, 0x400000, 0x7FFFFF):
            for sign in (0, 0x80000000):
                values.append(as_float32(sign | (biased << 23) | fraction))
    check(st_module, values)


def test_random_patterns(st_module: Any) -> None:
    rng = np.random.default_rng(20261126)
    bits = rng.integers(0, 2**32, size=4000, dtype=np.uint64)
    check(st_module, [as_float32(int(b)) for b in bits])
