"""The type model of the checked program: elementary, array, struct, enum and POU types."""

from __future__ import annotations

from dataclasses import dataclass, field


class Type:
    name: str

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True, eq=False)
class ElemType(Type):
    name: str
    kind: str  # "bool" | "sint" (signed int) | "uint" | "bits" | "real" | "time" | "string"
    bits: int
    ctype: str

    @property
    def is_int(self) -> bool:
        return self.kind in ("sint", "uint")

    @property
    def is_bits(self) -> bool:
        return self.kind in ("bits", "bool")

    @property
    def is_real(self) -> bool:
        return self.kind == "real"

    @property
    def is_numeric(self) -> bool:
        return self.kind in ("sint", "uint", "real")

    def int_range(self) -> tuple[int, int]:
        if self.kind == "sint":
            return -(1 << (self.bits - 1)), (1 << (self.bits - 1)) - 1
        return 0, (1 << self.bits) - 1


def _e(name: str, kind: str, bits: int, ctype: str) -> ElemType:
    return ElemType(name, kind, bits, ctype)


ELEMENTARY: dict[str, ElemType] = {t.name: t for t in [
    _e("BOOL", "bool", 1, "uint8_t"),
    _e("SINT", "sint", 8, "int8_t"), _e("INT", "sint", 16, "int16_t"),
    _e("DINT", "sint", 32, "int32_t"), _e("LINT", "sint", 64, "int64_t"),
    _e("USINT", "uint", 8, "uint8_t"), _e("UINT", "uint", 16, "uint16_t"),
    _e("UDINT", "uint", 32, "uint32_t"), _e("ULINT", "uint", 64, "uint64_t"),
    _e("BYTE", "bits", 8, "uint8_t"), _e("WORD", "bits", 16, "uint16_t"),
    _e("DWORD", "bits", 32, "uint32_t"), _e("LWORD", "bits", 64, "uint64_t"),
    _e("REAL", "real", 32, "float"), _e("LREAL", "real", 64, "double"),
    _e("TIME", "time", 64, "int64_t"),
    # MatIEC's STRING: a length byte (int8_t) and a 126-byte body, whatever was declared
    _e("STRING", "string", 8 * 127, "plc_string_t"),
]}
BOOL = ELEMENTARY["BOOL"]
DINT = ELEMENTARY["DINT"]
LINT = ELEMENTARY["LINT"]
REAL = ELEMENTARY["REAL"]
LREAL = ELEMENTARY["LREAL"]
TIME = ELEMENTARY["TIME"]
STRING = ELEMENTARY["STRING"]
STRING_MAX = 126  # MatIEC's STR_MAX_LEN: the body of every STRING


@dataclass(frozen=True, eq=False)
class LiteralType(Type):
    """The type of an untyped literal (or a constant expression of them) before context."""

    name: str  # "ANY_INT literal" | "ANY_REAL literal"

    @property
    def is_real(self) -> bool:
        return self.name == "real literal"


INT_LIT = LiteralType("integer literal")
ERROR_T = LiteralType("<error>")  # poison type: suppresses follow-up diagnostics
REAL_LIT = LiteralType("real literal")


@dataclass(eq=False)
class ArrayType(Type):
    dims: list[tuple[int, int]]
    element: Type
    name: str = ""
    default: object = None  # ast Init of `TYPE T : ARRAY[..] OF X := [...]; END_TYPE`

    def __post_init__(self) -> None:
        if not self.name:
            rng = ", ".join(f"{lo}..{hi}" for lo, hi in self.dims)
            self.name = f"ARRAY[{rng}] OF {self.element}"

    @property
    def size(self) -> int:
        n = 1
        for lo, hi in self.dims:
            n *= hi - lo + 1
        return n

    def shape_key(self) -> str:
        return "_".join(f"{lo}_{hi}" for lo, hi in self.dims).replace("-", "m")


@dataclass(eq=False)
class StructType(Type):
    name: str
    fields: dict[str, tuple[str, Type]] = field(default_factory=dict)  # UPPER -> (spelling, t)
    inits: dict[str, object] = field(default_factory=dict)  # UPPER -> ast Init
    default: object = None  # ast StructInit of `TYPE S : STRUCT ... END_STRUCT := (...)`


@dataclass(eq=False)
class EnumType(Type):
    name: str
    values: dict[str, tuple[str, int]] = field(default_factory=dict)  # UPPER -> (spelling, v)
    default: int | None = None  # TYPE E : (...) := V; END_TYPE


@dataclass(eq=False)
class PouType(Type):
    """A FUNCTION_BLOCK or PROGRAM used as the type of an instance (filled by the resolver)."""

    name: str
    kind: str
    symbol: object = None  # resolve.PouSym


def same_type(a: Type, b: Type) -> bool:
    if a is b:
        return True
    if isinstance(a, ArrayType) and isinstance(b, ArrayType):
        return a.dims == b.dims and same_type(a.element, b.element)
    return False


def contains_pou(t: Type) -> bool:
    if isinstance(t, PouType):
        return True
    if isinstance(t, ArrayType):
        return contains_pou(t.element)
    return False
