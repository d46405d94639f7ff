"""The C++ type model of STruC++'s output (armbench.compiler.cxxtypes) and its reserved names,
on the cases measured with the real STruC++ and g++ (test_strucpp_verdicts.py runs whole
programs)."""

from __future__ import annotations

import pytest

from armbench.compiler import ast as A
from armbench.compiler.cxxtypes import CxxType, binary, literal_type, strucpp_literal_value
from armbench.compiler.reserved import strucpp_reserves
from armbench.compiler.source import SourcePos

POS = SourcePos("t.st", 1, 1)


def lit(text: str, value: int, prefix: str | None = None) -> A.Literal:
    return A.Literal(POS, "int", value, text, prefix)


@pytest.mark.parametrize(("text", "written"), [
    ("9007199254740992", 9007199254740992),  # 2^53: exact
    ("9007199254740993", 9007199254740992),  # 2^53 + 1: the first that changes
    ("9007199254740994", 9007199254740994),  # a double, printed in full
    ("9007199254740995", 9007199254740996),
    ("2305843009213693952", 2305843009213694000),  # 2^61
    ("9223372036854775807", 9223372036854776000),  # 2^63 - 1
    ("18446744073709551615", 18446744073709552000),  # 2^64 - 1 (384 in a ULINT)
    ("-9007199254740993", -9007199254740992),
    ("10000000000000000000", 10000000000000000000),  # 1e19: a double, shortest form exact
    ("16#20000000000001", 9007199254740993),  # based literals are copied
])
def test_decimal_literals_pass_through_a_double(text: str, written: int) -> None:
    value = int(text[3:], 16) if text.startswith("16#") else int(text)
    assert strucpp_literal_value(lit(text, value)) == written


@pytest.mark.parametrize(("a", "b", "want"), [
    (CxxType("bool", False), CxxType("bool", False), CxxType("int", False)),  # bool & bool
    (CxxType("bool", True), CxxType("bool", False), CxxType("bool", True)),  # IECVar<bool> & bool
    (CxxType("bool", False), CxxType("bool", True), CxxType("bool", True)),
    (CxxType("unsigned short", True), CxxType("int", False), CxxType("int", False)),
    (CxxType("unsigned int", True), CxxType("int", False), CxxType("unsigned int", False)),
    (CxxType("unsigned long", True), CxxType("long", False), CxxType("unsigned long", False)),
    (CxxType("short", True), CxxType("short", True), CxxType("short", True)),  # A + B
    (CxxType("float", True), CxxType("double", False), CxxType("double", False)),  # Y * 2.0
    (CxxType("long", True), CxxType("long long", False), CxxType("long long", False)),  # t + T#1s
    (CxxType("long", False), CxxType("unsigned int", False), CxxType("long", False)),
])
def test_binary_operators(a: CxxType, b: CxxType, want: CxxType) -> None:
    assert binary(a, b) == want


@pytest.mark.parametrize(("text", "value", "prefix", "want"), [
    ("5", 5, None, CxxType("int", False)),
    ("16#FF", 255, None, CxxType("int", False)),
    ("16#FFFFFFFF", 0xFFFFFFFF, None, CxxType("unsigned int", False)),  # measured: NOT compiles
    ("16#FFFFFFFFFF", 0xFFFFFFFFFF, None, CxxType("long", False)),  # measured: NOT fails
    ("4294967295", 4294967295, None, CxxType("long", False)),  # decimal: never unsigned
    ("WORD#16#FF", 255, "WORD", CxxType("unsigned short", True)),
])
def test_integer_literals(text: str, value: int, prefix: str | None, want: CxxType) -> None:
    assert literal_type(lit(text, value, prefix)) == want


@pytest.mark.parametrize(("name", "global_scope", "reserved"), [
    ("Toggle", True, True), ("Toggle", False, False),  # OSCAT Basic's FB: as a variable, fine
    ("Time_To_Ns", True, True), ("Time_To_Ns", False, False),  # its runtime's function
    ("Atan2", True, True), ("Mc_Power", True, True), ("Ltime", True, True),
    ("Little_Endian", False, True), ("Cpu_Set", False, True),  # C macros: any name
    ("Iec_Int", False, True),  # its runtime's types: any name
    ("Public", False, True), ("Super", False, True),  # keywords refused in declarations
    ("Get", False, False), ("Get", True, True),  # a keyword it takes as a variable only
    ("ArcTan2", True, False), ("FlipFlop", True, False), ("Count", False, False),
])
def test_names_strucpp_reserves(name: str, global_scope: bool, reserved: bool) -> None:
    assert (strucpp_reserves(name, global_scope) is not None) == reserved
