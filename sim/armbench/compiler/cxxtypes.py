"""The C++ type STruC++ (OpenPLC v4's compiler) gives an ST expression, where g++ depends on it.

STruC++ writes ST expressions into C++ almost token for token: variables are ``IECVar<T>``
wrappers (``IEC_INT`` is ``IECVar<int16_t>``), its operators ``+ - * / % & | ^`` are templates
that keep the wrapper only when both sides have the one ``T`` (``IECVar<T> op IECVar<T>`` or
``IECVar<T> op T``); anything else is C++'s built-in operator on the unwrapped values, with
C++'s integer promotions: ``(a > b) AND (c < d)`` is ``bool & bool``, an ``int``. Its runtime's
``NOT``, ``ROL``, ``ROR`` take IEC bit types only, and ``MUX`` and the named forms of ``AND``,
``OR``, ``XOR``, ``MIN``, ``MAX`` deduce one ``T`` from several arguments; an ``int`` or two
different types there are a g++ error in code STruC++ accepted. Measured on STruC++ 0.6.1
(fb7980f) with its runtime headers (src/runtime/include: iec_var.hpp's operators,
iec_std_lib.hpp's functions, iec_global.hpp's ``read()``) and g++ 12, -std=c++17; the cases are
tests/corpus/diagnostics/E0310_* and E0412_*.

``cxx_type`` answers None where it does not know (enumerations, STRUCTs, arrays, TRUNC, EXPT):
the rules built on it then say nothing rather than guess.
"""

from __future__ import annotations

from dataclasses import dataclass

from . import ast as A
from .symbols import CheckedProgram
from .types import ElemType

# C++ fundamental types: (size in bytes, signed, conversion rank); bool and the small types
# are promoted to int before any arithmetic.
_FUNDAMENTAL = {
    "bool": (1, False, 0), "signed char": (1, True, 1), "unsigned char": (1, False, 1),
    "short": (2, True, 2), "unsigned short": (2, False, 2),
    "int": (4, True, 3), "unsigned int": (4, False, 3),
    "long": (8, True, 4), "unsigned long": (8, False, 4),
    "long long": (8, True, 5), "unsigned long long": (8, False, 5),
}
_FLOATING = ("float", "double")
# the types of iec_types.hpp's BOOL_t ... LWORD_t, REAL_t, TIME_t on an LP64 target (the v4
# runtime's Linux devices: x86-64, aarch64)
_IEC_BASE = {
    "BOOL": "bool", "SINT": "signed char", "INT": "short", "DINT": "int", "LINT": "long",
    "USINT": "unsigned char", "UINT": "unsigned short", "UDINT": "unsigned int",
    "ULINT": "unsigned long", "BYTE": "unsigned char", "WORD": "unsigned short",
    "DWORD": "unsigned int", "LWORD": "unsigned long", "REAL": "float", "LREAL": "double",
    "TIME": "long",
}
# iec_traits.hpp's is_any_bit: bool, uint8_t .. uint64_t, and IECVar of those
_ANY_BIT = frozenset({"bool", "unsigned char", "unsigned short", "unsigned int", "unsigned long"})
# standard functions whose parameters share one generic constraint: STruC++ casts their bare
# literal arguments to the IEC type of the others (codegen.ts harmonizeStdFuncArgs)
_HARMONISED = frozenset({"MIN", "MAX", "LIMIT", "AND", "OR", "XOR", "EXPT", "MOD"})
# standard functions returning their (first) argument's type (runtime templates T f(T, ...))
_SAME_AS_FIRST = frozenset({"ABS", "MOVE", "SHL", "SHR", "ROL", "ROR", "NOT", "SQRT", "LN",
                            "LOG", "EXP", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN"})


@dataclass(frozen=True)
class CxxType:
    """A C++ type of STruC++'s output: a fundamental type, raw or in the IECVar wrapper."""

    base: str
    wrapped: bool

    def __str__(self) -> str:
        return f"IECVar<{self.base}>" if self.wrapped else self.base

    @property
    def is_any_bit(self) -> bool:
        return self.base in _ANY_BIT


def iec_base(t: object) -> str | None:
    return _IEC_BASE.get(t.name) if isinstance(t, ElemType) else None


def _promote(base: str) -> str:
    if base in _FLOATING:
        return base
    size, _, rank = _FUNDAMENTAL[base]
    return "int" if rank < 3 else base


def _arith(a: str, b: str) -> str:
    """C++'s usual arithmetic conversions of two fundamental types (LP64)."""
    if "double" in (a, b):
        return "double"
    if "float" in (a, b):
        return "float"
    a, b = _promote(a), _promote(b)
    if a == b:
        return a
    sa, ga, ra = _FUNDAMENTAL[a]
    sb, gb, rb = _FUNDAMENTAL[b]
    if ga == gb:
        return a if ra >= rb else b
    (u, su, ru), (s, ss, rs) = ((a, sa, ra), (b, sb, rb)) if not ga else ((b, sb, rb), (a, sa, ra))
    if ru >= rs:
        return u
    if ss > su:
        return s
    return "unsigned " + s


def binary(a: CxxType, b: CxxType) -> CxxType:
    """``a op b`` for + - * / % & | ^: iec_var.hpp's templates keep the wrapper for one T."""
    if a.base == b.base and (a.wrapped or b.wrapped):
        return CxxType(a.base, True)
    return CxxType(_arith(a.base, b.base), False)


def common(types: list[CxxType]) -> CxxType:
    """std::common_type of the unwrapped types (the mixed MIN/MAX/LIMIT/SEL overloads)."""
    base = types[0].base
    for t in types[1:]:
        base = _arith(base, t.base) if base != t.base else base
    return CxxType(base, False)


def literal_type(e: A.Literal) -> CxxType | None:
    """The C++ type of the literal STruC++ writes for ``e`` (codegen.ts
    generateLiteralExpression): a typed literal is static_cast to its IEC type, TRUE is
    ``true``, a REAL a double, T#... an ``LL`` constant, an integer a C++ integer literal in the
    base it was written in (its value as strucpp_literal_value says)."""
    text = e.text.upper().replace("_", "")
    if e.kind == "time":
        return CxxType("long long", False)
    if e.type_prefix is not None:
        base = _IEC_BASE.get(e.type_prefix.upper())
        return CxxType(base, True) if base is not None else None
    if e.kind == "bool":
        return CxxType("bool", False)
    if e.kind == "real":
        return CxxType("double", False)
    if e.kind != "int":
        return None
    negative = text.startswith("-")
    magnitude = abs(strucpp_literal_value(e))
    based = "#" in text
    kinds = (("int", 31), ("unsigned int", 32), ("long", 63), ("unsigned long", 64)) if based \
        else (("int", 31), ("long", 63))
    for base, bits in kinds:
        if magnitude < 1 << bits:
            return CxxType(_promote(base) if negative else base, False)
    return None  # g++: "integer constant is so large that it is unsigned" (__int128)


def strucpp_literal_value(e: A.Literal) -> int:
    """The value of the C++ literal STruC++ writes for an untyped integer literal: based ones
    (16#, 8#, 2#) are copied in C++ notation, exactly; a decimal one is parsed into a
    JavaScript double and printed back (String(parseInt(text))), so above 2^53 it is the
    shortest decimal that rounds to the same double, padded with zeros (2^61 is written
    2305843009213694000)."""
    value = int(e.value)
    text = e.text.replace("_", "")
    if "#" in text or abs(value) <= 1 << 53:
        return value
    return _js_number_string(value)


def _js_number_string(value: int) -> int:
    """int(String(Number(value))) for |value| < 1e21: Python's repr of a float is the same
    shortest round-trip digit string as JavaScript's Number::toString."""
    digits = repr(float(abs(value)))  # e.g. '2.305843009213694e+18' or '9007199254740992.0'
    mantissa, _, exponent = digits.partition("e")
    whole, _, frac = mantissa.partition(".")
    frac = frac.rstrip("0")
    shift = int(exponent or 0) - len(frac)
    magnitude = int(whole + frac) * 10 ** shift if shift >= 0 else int(float(digits))
    return -magnitude if value < 0 else magnitude


def cxx_type(prog: CheckedProgram, e: A.Expr) -> CxxType | None:
    """The C++ type of STruC++'s translation of ``e``, or None where the rules need not know."""
    if isinstance(e, A.Literal):
        return literal_type(e)
    if isinstance(e, A.Name):
        ref = prog.names.get(e)
        base = iec_base(prog.expr_types.get(e))
        if ref is None or base is None or ref.kind == "enum":
            return None
        # a VAR_EXTERNAL is read through GlobalVar::read(), which returns the raw value
        return CxxType(base, ref.kind != "global")
    if isinstance(e, A.Member | A.Index):
        base = iec_base(prog.expr_types.get(e))
        return CxxType(base, True) if base is not None else None
    if isinstance(e, A.Unary):
        inner = cxx_type(prog, e.operand)
        if inner is None:
            return None
        if e.op == "NOT":
            if e.parenthesised:  # the runtime's NOT(T) -> T
                return inner
            # `!x` for BOOL; `~x` otherwise, which iec_var.hpp's operator~ keeps wrapped
            if iec_base(prog.expr_types.get(e.operand)) == "bool":
                return CxxType("bool", False)
            return inner if inner.wrapped else CxxType(_promote(inner.base), False)
        return CxxType(_promote(inner.base), False)  # no unary -/+ on IECVar: built-in
    if isinstance(e, A.Binary):
        if e.op in ("=", "<>", "<", ">", "<=", ">="):
            return CxxType("bool", False)
        if e.op == "**":
            return CxxType("double", False)  # std::pow(double, double)
        left, right = cxx_type(prog, e.left), cxx_type(prog, e.right)
        if left is None or right is None:
            return None
        return binary(left, right)
    if isinstance(e, A.Call):
        return _call_type(prog, e)
    return None


def call_arguments(prog: CheckedProgram, c: A.Call) -> list[CxxType | None] | None:
    """The C++ types of a standard function's arguments as STruC++ passes them: positionally in
    the order written, bare literals cast to the others' IEC type where it harmonises them."""
    tgt = prog.calls.get(c)
    if tgt is None or tgt.kind != "std" or tgt.std is None:
        return None
    values = [a.value for a in c.args if not a.is_output]
    types = [cxx_type(prog, v) for v in values]
    if tgt.std.name in _HARMONISED:
        bare = [_bare_literal(v) for v in values]
        others = [prog.expr_types.get(v) for v, b in zip(values, bare, strict=True) if not b]
        base = next((iec_base(t) for t in others if iec_base(t) is not None), None)
        if base is not None:
            types = [CxxType(base, True) if b else t for t, b in zip(types, bare, strict=True)]
    return types


def _bare_literal(e: A.Expr) -> bool:
    """codegen.ts isBareLiteral: an untyped literal, or one under a unary operator."""
    if isinstance(e, A.Unary):
        e = e.operand
    return isinstance(e, A.Literal) and e.type_prefix is None and e.kind != "time"


def _call_type(prog: CheckedProgram, c: A.Call) -> CxxType | None:
    tgt = prog.calls.get(c)
    if tgt is None:
        return None
    if tgt.kind == "function" and tgt.pou is not None:
        base = iec_base(tgt.pou.return_type)
        return CxxType(base, True) if base is not None else None
    if tgt.kind == "conv" and tgt.conv is not None:
        base = iec_base(tgt.conv[1])  # TO_INT(...) returns IEC_INT
        return CxxType(base, True) if base is not None else None
    if tgt.kind != "std" or tgt.std is None:
        return None
    args = call_arguments(prog, c)
    name = tgt.std.name
    if not args or any(a is None for a in args):
        return None
    known = [a for a in args if a is not None]
    if name in _SAME_AS_FIRST:
        return known[0]
    if name == "SEL":
        inputs = known[1:]
    elif name == "MUX":
        inputs = known[1:]
        return inputs[0] if inputs and all(t == inputs[0] for t in inputs) else None
    elif name in ("MIN", "MAX", "LIMIT", "AND", "OR", "XOR", "MOD"):
        inputs = known
    else:
        return None
    if not inputs:
        return None
    if all(t == inputs[0] for t in inputs):
        return inputs[0]
    return common(inputs) if name in ("MIN", "MAX", "LIMIT", "SEL") else None
