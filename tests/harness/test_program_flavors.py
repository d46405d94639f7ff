"""Typed access by name (plc_vars) in both Modbus flavors: a soft PLC serving OpenPLC's map
and one serving the CODESYS variant's layout run the same program, and the same tests pass
on both; the raw registers are checked against each flavor's rules written out here.

The program's addresses are chosen so that no variable moves in the CODESYS variant: each
keeps its size and number in %I (what it never assigns) or %Q (what it assigns), so its
CODESYS register follows from the declaration by hand (a variable at byte offset b of its
area is register b / 2; a BOOL at %X n.i is bit 8 n + i). The expected words come from the
values' bit patterns with struct ('>' and '<'), not from armbench's codecs.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from armbench.harness.program import PlcProgram, ProgramPlc, ReadOnlyVariable
from armbench.harness.pytest_plugin import SoftPlcFactory
from armbench.softplc.modbus_client import PlcClient

TYPES = """
PROGRAM Types
  VAR
    InReal AT %MD0 : REAL;
    InDint AT %MD1 : DINT;
    InLreal AT %ML1 : LREAL;
    InLint AT %ML2 : LINT;
    InInt AT %MW12 : INT;
    InWord AT %MW13 : WORD;
    Signature AT %MD7 : UDINT := 16#5EED0F1A;
    Sensor AT %IW16 : INT;
    InitPct AT %MD9 : REAL := 20.0;
    ScanCount AT %MD100 : UDINT;
    OutReal AT %MD101 : REAL;
    OutDint AT %MD102 : DINT;
    OutUdint AT %MD103 : UDINT;
    OutLreal AT %ML26 : LREAL;
    OutLint AT %ML27 : LINT;
    OutInt AT %QW60 : INT;
    OutUint AT %MW61 : UINT;
    OutSensor AT %QW62 : INT;
    OutInit AT %MD104 : REAL;
  END_VAR
  VAR
    InBool AT %QX40.0 : BOOL;
    Button AT %IX40.1 : BOOL;
    OutBool AT %QX50.0 : BOOL;
    OutButton AT %QX50.1 : BOOL;
  END_VAR
  ScanCount := ScanCount + 1;
  OutReal := InReal * 2.0;
  OutDint := InDint - 1;
  OutUdint := DINT_TO_UDINT(InDint) + 1;
  OutLreal := InLreal * 2.0;
  OutLint := InLint + 1;
  OutInt := InInt - 1;
  OutUint := WORD_TO_UINT(InWord);
  OutSensor := Sensor;
  OutInit := InitPct;
  OutBool := NOT InBool;
  OutButton := Button;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK MainTask(INTERVAL := T#2ms, PRIORITY := 0);
    PROGRAM Inst WITH MainTask : Types;
  END_RESOURCE
END_CONFIGURATION
"""

BYTES = {"D": 4, "L": 8, "W": 2}


def openplc_place(address: str) -> tuple[str, int]:
    """(table, first address) of a declared address on OpenPLC (docs/matiec-facts.md)."""
    area, size, rest = address[1], address[2], address[3:]
    if size == "X":
        byte, bit = map(int, rest.split("."))
        return ("coil" if area == "Q" else "discrete"), 8 * byte + bit
    n = int(rest)
    if (area, size) == ("I", "W"):
        return "input", n
    base = {("Q", "W"): 0, ("M", "W"): 1024, ("M", "D"): 2048, ("M", "L"): 4096}
    return "holding", base[(area, size)] + n * BYTES[size] // 2


def codesys_place(address: str, assigned: bool) -> tuple[str, int]:
    """(table, first address) of the same variable in the CODESYS variant, where it keeps
    its size and number: %I (holding registers, coils) or %Q (input registers, discrete
    inputs) from byte 0 (plc_project/codesys/register-map.md's device settings)."""
    size, rest = address[2], address[3:]
    if size == "X":
        byte, bit = map(int, rest.split("."))
        return ("discrete" if assigned else "coil"), 8 * byte + bit
    return ("input" if assigned else "holding"), int(rest) * BYTES[size] // 2


def words(fmt: str, value: float | int, lsw_first: bool) -> list[int]:
    e = "<" if lsw_first else ">"
    raw = struct.pack(e + fmt, value)
    return list(struct.unpack(f"{e}{len(raw) // 2}H", raw))


def f32(x: float) -> float:
    return float(struct.unpack(">f", struct.pack(">f", x))[0])


@pytest.fixture(params=["openplc", "codesys"])
def types(request: pytest.FixtureRequest, tmp_path: Path,
          soft_plc: SoftPlcFactory) -> ProgramPlc:
    src = tmp_path / "types.st"
    src.write_text(TYPES)
    return soft_plc(src, library=False, flavor=request.param)


def test_the_variables_are_where_each_flavor_puts_them(types: ProgramPlc) -> None:
    prog = types.program
    body = TYPES.split("END_VAR")[-1].split("END_PROGRAM")[0]
    assigned = {stmt.split(":=")[0].strip().upper() for stmt in body.split(";")
                if ":=" in stmt}
    declared = {line.split()[0]: line.split()[2] for line in TYPES.splitlines()
                if " AT %" in line}
    assert len(declared) == 23 and len(assigned) == 12
    for name, address in declared.items():
        var = prog.variable(name)
        want = (openplc_place(address) if prog.flavor.name == "openplc"
                else codesys_place(address, name.upper() in assigned))
        assert (var.table, var.address) == want, name
        assert var.source_location == address


def test_every_type_round_trips_by_name(types: ProgramPlc) -> None:
    with types.connect() as v:
        v.write(InReal=1.1, InDint=-5, InLreal=3.14159, InLint=-(2**40), InInt=-300,
                InWord=0xBEEF, InBool=True)
        types.set_input("Sensor", -21)
        types.set_input("Button", True)
        v.wait_scans(2)
        assert v["OutReal"] == f32(f32(1.1) * 2.0)
        assert v["OutDint"] == -6
        assert v["OutUdint"] == 2**32 - 4
        assert v["OutLreal"] == 3.14159 * 2.0
        assert v["OutLint"] == -(2**40) + 1
        assert v["OutInt"] == -301
        assert v["OutUint"] == 0xBEEF
        assert v["OutSensor"] == -21
        assert v["OutBool"] is False and v["OutButton"] is True
        assert v["InReal"] == f32(1.1) and v["InLint"] == -(2**40)  # read back


def test_the_raw_registers_in_each_flavors_word_order(types: ProgramPlc) -> None:
    lsw = types.program.flavor.name == "codesys"
    with types.connect() as v, PlcClient(*types.address) as raw:
        def read(name: str, count: int) -> list[int]:
            var = types.program.variable(name)
            return raw.read_table(var.table, var.address, count)

        def write(name: str, data: list[int]) -> None:
            raw.write_registers(types.program.variable(name).address, data)

        write("InReal", words("f", -2.5, lsw))
        write("InLreal", words("d", 1e-300, lsw))
        write("InDint", words("i", 0x12345678, lsw))
        write("InInt", [65534])  # INT -2, two's complement
        v.wait_scans(2)
        assert read("OutReal", 2) == words("f", -5.0, lsw)
        assert read("OutReal", 2) == ([0x0000, 0xC0A0] if lsw else [0xC0A0, 0x0000])
        assert read("OutLreal", 4) == words("d", 2e-300, lsw)
        assert read("OutDint", 2) == ([0x5677, 0x1234] if lsw else [0x1234, 0x5677])
        assert read("OutInt", 1) == [65533]
        assert read("OutBool", 1) == [1]  # InBool FALSE
        assert v["InDint"] == 0x12345678


def test_outputs_are_read_only_under_codesys_inputs_under_openplc(types: ProgramPlc) -> None:
    with types.connect() as v:
        if types.program.flavor.name == "openplc":
            with pytest.raises(ReadOnlyVariable, match=r"Sensor at %IW16 is an input"):
                v["Sensor"] = 3
            v["OutReal"] = 7.0  # a holding register: the next scan overwrites it
        else:
            with pytest.raises(ReadOnlyVariable,
                               match=r"OutReal \(%MD101\) is an output of the program in "
                                     r"the CODESYS layout, %QD101: an input register"):
                v["OutReal"] = 7.0
            v["Sensor"] = 3  # a holding register, written by the client
            v.wait_scans(2)
            assert v["OutSensor"] == 3


def test_a_client_written_variables_initial_value(types: ProgramPlc) -> None:
    """InitPct := 20.0 is declared and never assigned: on OpenPLC the variable is the
    register and keeps it; in the CODESYS layout it is %I, which the device's holding
    registers overwrite from the first scan on (initially 0)."""
    with types.connect() as v:
        v.wait_scans(2)
        expected = 20.0 if types.program.flavor.name == "openplc" else 0.0
        assert v["OutInit"] == expected and v["InitPct"] == expected


def test_the_codesys_map_of_a_program_is_the_export_layout(tmp_path: Path) -> None:
    """The flavor map and `armbench export`'s register map of the same program agree row
    for row (one layout, not two copies)."""
    from armbench.export import export_paths, generate

    src = tmp_path / "types.st"
    src.write_text(TYPES)
    prog = PlcProgram.load([src], library=False, flavor="codesys")
    text = generate([src]).files[export_paths("Types")[3]].decode()
    tables = {"holding register": "holding", "input register": "input", "coil": "coil",
              "discrete input": "discrete"}
    rows = 0
    for row in (ln for ln in text.splitlines() if ln.startswith("| `")):
        cells = [c.strip().strip("`") for c in row.strip("|").split("|")]
        var = prog.variable(cells[0])
        assert (var.location, var.table, var.address, var.count) == (
            cells[3], tables[cells[4]], int(cells[5]), int(cells[6]))
        rows += 1
    assert rows == len(prog.names()) == 23
