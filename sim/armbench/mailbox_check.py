"""The check word of a controller mailbox command block (MailboxCheckWord of
``plc_project/controller/MailboxServer.st``), for the client, the docs and the tests.

The PLC cannot see a REAL's bits (IEC 61131-3 has no bit cast), so it rebuilds them from the
value (RealBitPattern of ``st/RealBits.st``); two values it cannot tell apart get one
pattern: every NaN counts as 0x7FC00000 and -0.0 as 0x00000000. Everything here follows that.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Sequence

from .softplc import modbus_map as mm

CANONICAL_NAN = 0x7FC00000
ARGS = 6
_MASK = 0xFFFFFFFF


def real_bit_pattern(value: float) -> int:
    """The float32 pattern the PLC computes for a REAL register holding ``value`` (rounded
    to float32 as the register does; beyond float32's range: ``OverflowError``)."""
    hi, lo = mm.real_to_words(value)
    bits = (hi << 16) | lo
    if bits & 0x7F800000 == 0x7F800000 and bits & 0x007FFFFF:
        return CANONICAL_NAN
    if bits == 0x80000000:
        return 0
    return bits


def check_word(seq: int, session: int, code: int, int1: int = 0, int2: int = 0,
               args: Sequence[float] = ()) -> int:
    """CRC-32 (zlib's) of Seq, Session, Code, Int1, Int2, Arg1..Arg6 as 44 bytes, each
    32-bit value most significant byte first, as a function 16 request carries them: each
    DINT as its two's complement pattern, each REAL as :func:`real_bit_pattern` (missing
    arguments are 0.0, as the client writes them)."""
    if len(args) > ARGS:
        raise ValueError(f"a command takes at most {ARGS} REAL arguments, got {len(args)}")
    reals = [*args, *([0.0] * (ARGS - len(args)))]
    values = [v & _MASK for v in (seq, session, code, int1, int2)]
    values += [real_bit_pattern(float(a)) for a in reals]
    return zlib.crc32(struct.pack(">11I", *values))
