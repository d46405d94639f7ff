"""The map of a user's program, from its declarations: each located variable's Modbus table and
address per OpenPLC's map, its type's encoding, and the names a test reaches it by. The
expected addresses and words are the facts measured on the OpenPLC v3 runtime (coil 8·byte +
bit, %MWn 1024 + n, %MDn 2048 + 2n, %MLn 4096 + 4n; REAL 1.5 -> 0x3FC0 0x0000, LREAL 3.14159 ->
0x4009 0x21F9 0xF01B 0x866E, DINT 0x12345678 -> 0x1234 0x5678, INT -2 -> 65534)."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from armbench.compiler import CompileFailed
from armbench.harness.program import PlcProgram, ProgramError, UnknownVariable

EVERY_AREA = """
PROGRAM Every
  VAR
    Coil AT %QX2.5 : BOOL;       (* a coil *)
    Contact AT %IX1.3 : BOOL;
    Sensor AT %IW7 : INT;
    Out16 AT %QW3 : UINT;
    Mem16 AT %MW5 : WORD;
    Mem32 AT %MD4 : REAL;
    Mem64 AT %ML2 : LREAL;
    ByteIn AT %IB0 : BYTE;
    MemBit AT %MX0.1 : BOOL;
    Out32 AT %QD1 : DINT;
  END_VAR
  Out16 := Out16 + 1;
END_PROGRAM

PROGRAM Other
  VAR
    Out16 AT %QW4 : UINT;
  END_VAR
  Out16 := 7;
END_PROGRAM

CONFIGURATION Config0
  VAR_GLOBAL
    Shared AT %MD9 : DINT;
  END_VAR
  RESOURCE Res0 ON PLC
    TASK Fast(INTERVAL := T#2ms, PRIORITY := 0);
    TASK Slow(INTERVAL := T#20ms, PRIORITY := 1);
    PROGRAM A WITH Slow : Every;
    PROGRAM B WITH Fast : Other;
  END_RESOURCE
END_CONFIGURATION
"""


def program(tmp_path: Path, text: str, **options: str) -> PlcProgram:
    src = tmp_path / "prog.st"
    src.write_text(text)
    return PlcProgram.load([src], library=False, **options)


def single(decls: str, body: str = "") -> str:
    return f"""
PROGRAM Probe
  VAR
{decls}
  END_VAR
{body}
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK MainTask(INTERVAL := T#5ms, PRIORITY := 0);
    PROGRAM Inst WITH MainTask : Probe;
  END_RESOURCE
END_CONFIGURATION
"""


def test_every_area_at_openplcs_address(tmp_path: Path) -> None:
    p = program(tmp_path, EVERY_AREA)
    got = {n: (v.table, v.address, v.count, v.st_type, v.instance)
           for n in p.names() for v in [p.variable(n)]}
    assert got == {
        "Shared": ("holding", 2048 + 2 * 9, 2, "DINT", None),
        "Coil": ("coil", 8 * 2 + 5, 1, "BOOL", "A"),
        "Contact": ("discrete", 8 * 1 + 3, 1, "BOOL", "A"),
        "Sensor": ("input", 7, 1, "INT", "A"),
        "A.Out16": ("holding", 3, 1, "UINT", "A"),
        "Mem16": ("holding", 1024 + 5, 1, "WORD", "A"),
        "Mem32": ("holding", 2048 + 2 * 4, 2, "REAL", "A"),
        "Mem64": ("holding", 4096 + 4 * 2, 4, "LREAL", "A"),
        "B.Out16": ("holding", 4, 1, "UINT", "B"),
    }
    assert p.variable("coil").description == "a coil"
    assert p.variable("a.mem32") is p.variable("MEM32")
    assert (p.scan_task, p.scan_interval_ns) == ("Slow", 20_000_000)  # the first instance's
    assert p.signature is None and p.scan_counter is None
    assert not p.variable("Contact").writable and not p.variable("Sensor").writable
    assert p.variable("Coil").writable and p.variable("Mem64").writable


@pytest.mark.parametrize(("name", "message"), [
    ("ByteIn", "ByteIn is located at %IB0, which OpenPLC does not serve over Modbus"),
    ("MemBit", "%MX0.1, which OpenPLC does not serve"),
    ("Out32", "%QD1, which OpenPLC does not serve"),
    ("Out16", "declared by 2 program instances: say which, A.Out16 or B.Out16"),
    ("Mem", "no located variable Mem (did you mean Mem16, Mem32, Mem64?)"),
])
def test_names_a_test_cannot_use_say_why(tmp_path: Path, name: str, message: str) -> None:
    p = program(tmp_path, EVERY_AREA)
    with pytest.raises(UnknownVariable) as err:
        p.variable(name)
    assert message in str(err.value)
    assert isinstance(err.value, KeyError)


def test_encodings_are_openplcs(tmp_path: Path) -> None:
    p = program(tmp_path, single("""
    R AT %MD0 : REAL;
    L AT %ML1 : LREAL;
    D AT %MD2 : DINT;
    I AT %MW0 : INT;
    U AT %MD3 : UDINT;
    W AT %QW0 : WORD;
    Q AT %ML2 : LINT;"""))
    v = p.variable
    assert v("R").encode(1.5) == [0x3FC0, 0x0000]
    assert v("L").encode(3.14159) == [0x4009, 0x21F9, 0xF01B, 0x866E]
    assert v("D").encode(0x12345678) == [0x1234, 0x5678]
    assert v("D").encode(-1) == [0xFFFF, 0xFFFF]
    assert v("I").encode(-2) == [65534]
    assert v("I").decode([65534]) == -2
    assert v("U").decode([0xFFFF, 0xFFFE]) == 2**32 - 2
    assert v("R").decode([0x3FC0, 0x0000]) == 1.5
    assert v("Q").encode(-(2**63)) == [0x8000, 0, 0, 0]
    # the float32 a REAL register pair holds, whatever float was written
    assert v("R").decode(v("R").encode(0.1)) == struct.unpack(">f", struct.pack(">f", 0.1))[0]


@pytest.mark.parametrize(("name", "value", "error", "message"), [
    ("I", 40000, ValueError, "INT (-32768..32767): 40000 does not fit"),
    ("W", -1, ValueError, "WORD (0..65535): -1 does not fit"),
    ("U", 2**32, ValueError, "UDINT (0..4294967295)"),
    ("D", 1.5, TypeError, "D is DINT: give an int, not float"),
    ("D", True, TypeError, "give an int, not bool"),
    ("R", "1.0", TypeError, "R is REAL: give a number, not str"),
    ("R", 1e39, ValueError, "beyond its range"),
])
def test_values_that_do_not_fit_are_refused_before_sending(tmp_path: Path, name: str,
                                                           value: object, error: type,
                                                           message: str) -> None:
    p = program(tmp_path, single("""
    R AT %MD0 : REAL;
    D AT %MD2 : DINT;
    I AT %MW0 : INT;
    U AT %MD3 : UDINT;
    W AT %QW0 : WORD;"""))
    with pytest.raises(error, match=message.replace("(", r"\(").replace(")", r"\)")):
        p.variable(name).encode(value)  # type: ignore[arg-type]


def test_signature_and_scan_counter_by_convention_and_by_name(tmp_path: Path) -> None:
    decls = """
    Signature AT %MD0 : UDINT := 16#7A4B0001;
    Ident AT %MD1 : DINT := 42;
    ScanCount AT %MD2 : UDINT;
    Ticks AT %MW0 : UINT;"""
    p = program(tmp_path, single(decls))
    assert p.signature is not None and p.scan_counter is not None
    assert (p.signature.variable.name, p.signature.value) == ("Signature", 0x7A4B0001)
    assert p.scan_counter.name == "ScanCount"
    named = program(tmp_path, single(decls), signature="ident", scan_counter="Ticks")
    assert named.signature is not None and named.signature.value == 42
    assert named.scan_counter is not None and named.scan_counter.location == "%MW0"


@pytest.mark.parametrize(("decls", "options", "message"), [
    ("Signature AT %MD0 : UDINT;", {}, "needs a non-zero literal initial value"),
    ("Signature AT %MD0 : UDINT := 0;", {}, "needs a non-zero literal initial value"),
    ("Signature AT %MD0 : REAL := 1.0;", {}, "declare it as an integer"),
    ("X AT %MD0 : UDINT := 1;", {"signature": "Ident"}, "no located variable Ident"),
    ("X AT %MD0 : UDINT;", {"scan_counter": "Scans"}, "no located variable Scans"),
    ("ScanCount AT %MD0 : REAL;", {}, "scan counter ScanCount is REAL"),
])
def test_unusable_signature_or_counter_is_a_program_error(tmp_path: Path, decls: str,
                                                          options: dict[str, str],
                                                          message: str) -> None:
    with pytest.raises(ProgramError, match=message):
        program(tmp_path, single(decls), **options)


def test_a_program_that_does_not_check_or_is_missing(tmp_path: Path) -> None:
    with pytest.raises(CompileFailed, match="has no CONFIGURATION"):
        program(tmp_path, "PROGRAM Probe\n  VAR X AT %MD0 : DINT; END_VAR\n  X := 1;\n"
                          "END_PROGRAM\n")
    with pytest.raises(CompileFailed, match="Y"):
        program(tmp_path, single("X AT %MD0 : DINT;", "X := Y;"))
    with pytest.raises(ProgramError, match="no such file"):
        PlcProgram.load([tmp_path / "missing.st"])


def test_the_soft_plc_takes_any_configuration_name(tmp_path: Path) -> None:
    """Config0/Res0 are OpenPLC's upload's names: the plugin's soft PLC runs a program whose
    CONFIGURATION and RESOURCE are named otherwise, as `armbench run` does."""
    text = single("X AT %MD0 : DINT;", "X := X + 1;")
    named = text.replace("CONFIGURATION Config0", "CONFIGURATION Tank") \
        .replace("RESOURCE Res0", "RESOURCE Cpu")
    assert named != text
    assert program(tmp_path, named).variable("X").location == "%MD0"
