"""Typed access to a running program's located variables (the plugin's ``soft_plc`` factory,
in this process): the program itself computes the expected values from what the test wrote,
and the raw registers are compared with Python's own encoding of the type (struct)."""

from __future__ import annotations

import struct
import time
from pathlib import Path

import pytest

from armbench.harness.program import ProgramError, ProgramPlc, ReadOnlyVariable
from armbench.harness.pytest_plugin import SoftPlcFactory
from armbench.softplc.modbus_client import PlcClient

ECHO = """
PROGRAM Echo
  VAR
    InReal AT %MD0 : REAL;
    OutReal AT %MD1 : REAL;
    InDint AT %MD2 : DINT;
    OutDint AT %MD3 : DINT;
    InLreal AT %ML0 : LREAL;
    OutLreal AT %ML1 : LREAL;
    InLint AT %ML2 : LINT;
    OutLint AT %ML3 : LINT;
    InInt AT %MW0 : INT;
    OutInt AT %MW1 : INT;
    InWord AT %QW0 : WORD;
    OutWord AT %QW1 : WORD;
    InUdint AT %MD4 : UDINT;
    OutUdint AT %MD5 : UDINT;
    SameA AT %MD6 : DINT;
    SameB AT %MD7 : DINT;
    Torn AT %MD8 : UDINT;
    Divisor AT %MD9 : DINT := 1;
    Quotient AT %MD10 : DINT;
    Level AT %IW0 : INT;
    LevelTwice AT %MW2 : INT;
  END_VAR
  VAR
    InBool AT %QX0.0 : BOOL;
    OutBool AT %QX0.1 : BOOL;
    Button AT %IX0.2 : BOOL;
    Pressed AT %QX0.3 : BOOL;
  END_VAR
  OutReal := InReal * 2.0;
  OutDint := InDint - 1;
  OutLreal := InLreal / 4.0;
  OutLint := InLint + 1;
  OutInt := -InInt;
  OutWord := InWord XOR 16#FFFF;
  OutUdint := InUdint + 1;
  OutBool := NOT InBool;
  IF SameA <> SameB THEN
    Torn := Torn + 1;
  END_IF;
  Quotient := 100 / Divisor;
  LevelTwice := Level * 2;
  Pressed := Button;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK MainTask(INTERVAL := T#1ms, PRIORITY := 0);
    PROGRAM Inst WITH MainTask : Echo;
  END_RESOURCE
END_CONFIGURATION
"""

COUNTED = """
PROGRAM Counted
  VAR
    Signature AT %MD0 : UDINT := 16#C0FFEE;
    ScanCount AT %MD1 : UDINT;
  END_VAR
  ScanCount := ScanCount + 1;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK MainTask(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM Inst WITH MainTask : Counted;
  END_RESOURCE
END_CONFIGURATION
"""


def f32(x: float) -> float:
    """x rounded to float32, as a REAL holds it (Python's own struct, not our code)."""
    return float(struct.unpack(">f", struct.pack(">f", x))[0])


@pytest.fixture()
def echo(tmp_path: Path, soft_plc: SoftPlcFactory) -> ProgramPlc:
    src = tmp_path / "echo.st"
    src.write_text(ECHO)
    return soft_plc(src, library=False)


def test_every_type_round_trips_through_the_program(echo: ProgramPlc) -> None:
    with echo.connect() as v:
        v.write(InReal=1.1, InDint=-5, InLreal=3.14159, InLint=-(2**40), InInt=-300,
                InWord=0x1234, InUdint=4_000_000_000, InBool=True)
        v.wait_scans(1)
        assert v["OutReal"] == f32(f32(1.1) * 2.0)
        assert v["OutDint"] == -6
        assert v["OutLreal"] == 3.14159 / 4.0
        assert v["OutLint"] == -(2**40) + 1
        assert v["OutInt"] == 300
        assert v["OutWord"] == 0x1234 ^ 0xFFFF
        assert v["OutUdint"] == 4_000_000_001
        assert v["OutBool"] is False
        v["InBool"] = False
        v.wait_scans(1)
        assert v["OutBool"] is True


def test_the_registers_hold_openplcs_encoding(echo: ProgramPlc) -> None:
    with echo.connect() as v, PlcClient(*echo.address) as raw:
        v["InReal"] = -2.5
        v["InLreal"] = 1e-300
        v["InInt"] = -2
        v["InDint"] = 0x12345678
        assert raw.read_holding_registers(2048, 2) == list(struct.unpack(">2H",
                                                                         struct.pack(">f", -2.5)))
        assert raw.read_holding_registers(4096, 4) == list(
            struct.unpack(">4H", struct.pack(">d", 1e-300)))
        assert raw.read_holding_registers(1024, 1) == [65534]
        assert raw.read_holding_registers(2048 + 4, 2) == [0x1234, 0x5678]
        raw.write_coil(0, True)  # %QX0.0
        assert v["InBool"] is True


def test_one_write_is_seen_whole_by_every_scan(echo: ProgramPlc) -> None:
    """SameA and SameB are neighbours: write() sends them in one request, which lands between
    two scans; the program counts scans that saw them differ."""
    with echo.connect() as v:
        for k in range(300):
            v.write(SameA=k, SameB=k)
        v.wait_scans(2)
        assert v["Torn"] == 0


def test_inputs_are_read_only_over_modbus_and_set_on_the_soft_plc(echo: ProgramPlc) -> None:
    with echo.connect() as v:
        with pytest.raises(ReadOnlyVariable, match=r"Level at %IW0 is an input"):
            v["Level"] = 3
        with pytest.raises(ReadOnlyVariable, match=r"Button at %IX0.2 is an input"):
            v.write(Button=True)
        echo.set_input("Level", -21)
        echo.set_input("Button", True)
        v.wait_scans(1)
        assert v["Level"] == -21  # read as an input register (function 4)
        assert v["LevelTwice"] == -42
        assert v["Button"] is True and v["Pressed"] is True
        with pytest.raises(ProgramError, match="not an input"):
            echo.set_input("InInt", 1)


def test_wait_until_and_the_soft_plcs_own_scan_count(echo: ProgramPlc) -> None:
    with echo.connect() as v:
        # Echo declares no ScanCount: the soft PLC's count of its task's scans serves
        before = v.scan_count()
        v.wait_scans(5)
        assert v.scan_count() - before >= 5
        v["InDint"] = 41
        assert v.wait_until("OutDint", 40) == 40
        assert v.wait_until("OutDint", lambda x: x < 100) == 40
        with pytest.raises(TimeoutError, match=r"wait_until\('OutDint', 7\) gave up after "
                           r"0.1 s: OutDint last read 40; if it only needs longer, raise the "
                           r"limit: timeout_s=0.4 on this call, or for every wait the pytest "
                           r"option --plc-wait-timeout 0.4 \(plc_wait_timeout = 0.4 in the ini "
                           r"file\)"):
            v.wait_until("OutDint", 7, timeout_s=0.1)


def test_a_waits_timeout_names_the_condition_and_the_last_value(echo: ProgramPlc) -> None:
    """The TimeoutError of a wait says what it waited for, as the test wrote it, and what it
    saw last."""
    def above_a_hundred(x: object) -> bool:
        return isinstance(x, int) and x > 100

    with echo.connect() as v:
        v["InDint"] = 41
        v.wait_until("OutDint", 40)
        here = Path(__file__).name
        with pytest.raises(TimeoutError) as lam:
            v.wait_until("OutDint", lambda x: x > 100, timeout_s=0.05)
        assert str(lam.value).startswith("wait_until('OutDint', lambda x: x > 100 "
                                         f"({here}:"), lam.value
        assert "OutDint last read 40;" in str(lam.value)
        with pytest.raises(TimeoutError) as named:
            v.wait_until("outdint", above_a_hundred, timeout_s=0.05)
        assert str(named.value).startswith(
            "wait_until('OutDint', test_a_waits_timeout_names_the_condition_and_the_last_value"
            f".<locals>.above_a_hundred ({here}:"), named.value
        with pytest.raises(TimeoutError, match=r"wait_scans\(1000000\) gave up after 0.05 s: "
                           r"the PLC ran fewer scans .*timeout_s=0.2"):
            v.wait_scans(1_000_000, timeout_s=0.05)
        with pytest.raises(ValueError, match="timeout_s must be a number of seconds above 0"):
            v.wait_until("OutDint", 40, timeout_s=0)


def test_the_default_wait_timeout_is_five_seconds_and_settable(echo: ProgramPlc) -> None:
    from armbench.harness import pytest_plugin
    from armbench.harness.program import DEFAULT_WAIT_TIMEOUT_S

    assert DEFAULT_WAIT_TIMEOUT_S == pytest_plugin.DEFAULT_WAIT_TIMEOUT_S == 5.0
    with echo.connect() as v:
        assert v.wait_timeout_s == 5.0
    with echo.connect(wait_timeout_s=0.2) as v:
        t0 = time.monotonic()
        with pytest.raises(TimeoutError, match="gave up after 0.2 s"):
            v.wait_until("OutDint", 7)
        assert time.monotonic() - t0 < 3.0
        with pytest.raises(TimeoutError, match="gave up after 0.2 s"):
            v.wait_scans(1_000_000)
    with pytest.raises(ValueError, match="wait_timeout_s must be a number of seconds above 0"):
        echo.connect(wait_timeout_s=float("nan"))


def test_a_fault_ends_a_wait_with_its_place(echo: ProgramPlc) -> None:
    with echo.connect() as v:
        v["Divisor"] = 0  # 100 / 0: the soft PLC faults, as OpenPLC dies of SIGFPE
        with pytest.raises(ProgramError, match=r"FAULT: .*echo.st:\d+:\d+: .*division"):
            v.wait_scans(5)
        assert echo.fault() is not None


def test_scan_counter_waits_on_a_plc_found_by_address(tmp_path: Path,
                                                      soft_plc: SoftPlcFactory) -> None:
    src = tmp_path / "counted.st"
    src.write_text(COUNTED)
    running = soft_plc(src, library=False)
    # the same PLC seen as a real one would be: by address, no access to its scan thread
    remote = ProgramPlc(running.host, running.port, running.program)
    with remote.connect() as v:
        first = v["ScanCount"]
        v.wait_scans(3)
        assert (v["ScanCount"] - first) % 2**32 >= 3
        assert v["Signature"] == 0xC0FFEE
        with pytest.raises(ProgramError, match="only a soft PLC this process runs"):
            remote.set_input("ScanCount", 1)


def test_without_a_scan_counter_a_plc_by_address_cannot_count_scans(
        echo: ProgramPlc) -> None:
    remote = ProgramPlc(echo.host, echo.port, echo.program)
    with remote.connect() as v, pytest.raises(ProgramError, match="declares no scan counter"):
        v.wait_scans(1)


def test_iterating_reads_every_variable(echo: ProgramPlc) -> None:
    with echo.connect() as v:
        names = list(v)
        assert names[:2] == ["InReal", "OutReal"] and len(v) == len(names) == 25
        assert "outreal" in v and "Nothing" not in v
        values = v.read()
        assert set(values) == set(names)
        assert values["Divisor"] == 1  # the declared initial value
