"""OpenPLC v3's Modbus address map and word order (docs/matiec-facts.md), shared by the
server and the client so both sides agree by construction; and the word order of each Modbus
flavor the bench speaks.

Holding registers: 0..1023 %QW, 1024..2047 %MW, 2048..4095 %MD (two registers each),
4096..8191 %ML (four each). 32/64-bit values travel as their raw bit pattern, most significant
word first, each word big-endian: i.e. the big-endian encoding of the whole value.

The CODESYS flavor (the Modbus TCP Server Device serving ``armbench export``'s CODESYS
variant, plc_project/codesys/register-map.md) puts a 32/64-bit value's words in the CPU's byte
order, least significant word first on the little-endian CPUs it runs on: each register is
still sent big-endian, so the words are the little-endian encoding of the value read as
little-endian 16-bit words. Where each variable is under a flavor is derived from the program
(:mod:`armbench.registermap`); this module knows only the word order.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Final

COIL_COUNT: Final = 8192
DISCRETE_INPUT_COUNT: Final = 8192
INPUT_REGISTER_COUNT: Final = 1024
HOLDING_REGISTER_COUNT: Final = 8192

QW_BASE: Final = 0
MW_BASE: Final = 1024
MD_BASE: Final = 2048
ML_BASE: Final = 4096

# Modbus exception codes used by the server.
ILLEGAL_FUNCTION: Final = 1
ILLEGAL_DATA_ADDRESS: Final = 2
ILLEGAL_DATA_VALUE: Final = 3


def bit_address(byte: int, bit: int) -> int:
    """Coil / discrete-input address of ``%QXbyte.bit`` / ``%IXbyte.bit``."""
    if not 0 <= bit < 8:
        raise ValueError(f"bit index {bit} is not in 0..7")
    return 8 * byte + bit


def qw_address(n: int) -> int:
    """Holding register of ``%QWn``."""
    return QW_BASE + n


def mw_address(n: int) -> int:
    """Holding register of ``%MWn``."""
    return MW_BASE + n


def md_address(n: int) -> int:
    """First (most significant) holding register of ``%MDn``."""
    return MD_BASE + 2 * n


def ml_address(n: int) -> int:
    """First (most significant) holding register of ``%MLn``."""
    return ML_BASE + 4 * n


_REAL = struct.Struct(">f")
_LREAL = struct.Struct(">d")
_DINT = struct.Struct(">i")
_UDINT = struct.Struct(">I")
_LINT = struct.Struct(">q")
_WORDS2 = struct.Struct(">2H")
_WORDS4 = struct.Struct(">4H")


def real_to_words(value: float) -> tuple[int, int]:
    """REAL (float32) as the two registers OpenPLC serves, MSW first."""
    return _WORDS2.unpack(_REAL.pack(value))


def words_to_real(words: tuple[int, int] | list[int]) -> float:
    result: float = _REAL.unpack(_WORDS2.pack(*words))[0]
    return result


def lreal_to_words(value: float) -> tuple[int, int, int, int]:
    return _WORDS4.unpack(_LREAL.pack(value))


def words_to_lreal(words: tuple[int, int, int, int] | list[int]) -> float:
    result: float = _LREAL.unpack(_WORDS4.pack(*words))[0]
    return result


def dint_to_words(value: int) -> tuple[int, int]:
    return _WORDS2.unpack(_DINT.pack(value))


def words_to_dint(words: tuple[int, int] | list[int]) -> int:
    result: int = _DINT.unpack(_WORDS2.pack(*words))[0]
    return result


def udint_to_words(value: int) -> tuple[int, int]:
    return _WORDS2.unpack(_UDINT.pack(value))


def words_to_udint(words: tuple[int, int] | list[int]) -> int:
    result: int = _UDINT.unpack(_WORDS2.pack(*words))[0]
    return result


def lint_to_words(value: int) -> tuple[int, int, int, int]:
    return _WORDS4.unpack(_LINT.pack(value))


def words_to_lint(words: tuple[int, int, int, int] | list[int]) -> int:
    result: int = _LINT.unpack(_WORDS4.pack(*words))[0]
    return result


def int_to_word(value: int) -> int:
    """INT (signed 16-bit) as its two's-complement register value (−2 → 65534)."""
    if not -0x8000 <= value <= 0x7FFF:
        raise ValueError(f"{value} does not fit in an INT")
    return value & 0xFFFF


def word_to_int(word: int) -> int:
    return word - 0x10000 if word & 0x8000 else word


# ST type -> struct code of its bit pattern (BOOL travels as a coil or discrete input).
_CODES: Final = {"INT": "h", "UINT": "H", "WORD": "H", "DINT": "i", "UDINT": "I", "DWORD": "I",
                 "REAL": "f", "LINT": "q", "ULINT": "Q", "LWORD": "Q", "LREAL": "d"}


def struct_code(st_type: str) -> str | None:
    """The struct code of an elementary ST type's registers ("f" for REAL), None for a type
    with no register encoding (BOOL, BYTE, STRING, ...)."""
    return _CODES.get(st_type.upper())


@dataclass(frozen=True)
class Flavor:
    """A kind of Modbus server the bench speaks to: ``name`` as the options spell it
    (``--plc-flavor``), ``title`` for messages, the order of a wide value's words, and the
    ``layout`` of its registers: "openplc" (v3's map of the declared addresses, which OpenPLC
    v4 keeps when its segments are set up as docs/modbus-parity.md says) or "codesys" (the
    CODESYS variant's)."""

    name: str
    title: str
    lsw_first: bool
    layout: str = "openplc"

    @property
    def openplc_map(self) -> bool:
        """True when variables are where OpenPLC's map puts their declared addresses."""
        return self.layout == OPENPLC_LAYOUT

    def _endian(self) -> str:
        return "<" if self.lsw_first else ">"

    def encode(self, st_type: str, value: int | float) -> list[int]:
        """The registers of ``value`` as an ``st_type`` (struct.error when it does not fit)."""
        code = _require(st_type)
        data = struct.pack(self._endian() + code, value)
        return list(struct.unpack(f"{self._endian()}{len(data) // 2}H", data))

    def decode(self, st_type: str, words: tuple[int, ...] | list[int]) -> int | float:
        """The ``st_type`` value of its registers."""
        code = _require(st_type)
        e = self._endian()
        value: int | float = struct.unpack(e + code, struct.pack(f"{e}{len(words)}H", *words))[0]
        return value


def _require(st_type: str) -> str:
    code = struct_code(st_type)
    if code is None:
        raise TypeError(f"{st_type} has no Modbus register encoding")
    return code


OPENPLC_LAYOUT: Final = "openplc"
OPENPLC: Final = Flavor("openplc", "OpenPLC", lsw_first=False)
# OpenPLC v4's Modbus plugin: v3's map and word order, its own protocol rules
# (armbench.softplc.openplc_v4)
OPENPLC_V4: Final = Flavor("openplc-v4", "OpenPLC v4", lsw_first=False)
CODESYS: Final = Flavor("codesys", "CODESYS", lsw_first=True, layout="codesys")
FLAVORS: Final = {f.name: f for f in (OPENPLC, OPENPLC_V4, CODESYS)}


def flavor(name: str | Flavor) -> Flavor:
    """The flavor named ``name`` (a Flavor is returned as it is); ValueError naming the
    choices for any other name."""
    if isinstance(name, Flavor):
        return name
    found = FLAVORS.get(name.lower())
    if found is None:
        raise ValueError(f"unknown Modbus flavor {name!r}: choose "
                         f"{', '.join(list(FLAVORS)[:-1])} or {list(FLAVORS)[-1]}")
    return found
