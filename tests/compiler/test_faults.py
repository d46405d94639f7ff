"""Runtime faults of compiled ST: each raises PlcFault at the right ST line, the process survives,
the module keeps working afterwards, and a faulting scan leaves the process image outputs as they
were before the scan (OpenPLC would die on SIGFPE; the bench reports and rolls back instead)."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from armbench.compiler import compile_files
from armbench.faults import PlcFault

FAULTS_ST = """\
FUNCTION SafeDiv : DINT
VAR_INPUT
  a : DINT;
  b : DINT;
END_VAR
  SafeDiv := a / b;
END_FUNCTION

FUNCTION Pick : INT
VAR_INPUT
  i : INT;
END_VAR
VAR
  table : ARRAY[1..4] OF INT := [10, 20, 30, 40];
END_VAR
  Pick := table[i];
END_FUNCTION

FUNCTION Spin : INT
VAR_INPUT
  n : INT;
END_VAR
VAR
  k : INT;
END_VAR
  WHILE k < n DO
    k := k + 0;
  END_WHILE;
  Spin := k;
END_FUNCTION

FUNCTION SumShifted : INT
VAR_INPUT
  shift : INT;
END_VAR
VAR
  table : ARRAY[0..7] OF INT := [1, 2, 3, 4, 5, 6, 7, 8];
  i : INT;
END_VAR
  FOR i := 0 TO 6 DO
    SumShifted := SumShifted + table[i + shift];
  END_FOR;
END_FUNCTION

FUNCTION SkipAhead : INT
VAR_INPUT
  jump : INT;
END_VAR
VAR
  table : ARRAY[0..7] OF INT := [1, 2, 3, 4, 5, 6, 7, 8];
  i : INT;
END_VAR
  FOR i := 0 TO 7 DO
    SkipAhead := SkipAhead + table[i];
    i := i + jump;
  END_FOR;
END_FUNCTION

FUNCTION AfterLoop : INT
VAR_INPUT
  extra : INT;
END_VAR
VAR
  table : ARRAY[0..6] OF INT := [1, 2, 3, 4, 5, 6, 7];
  i : INT;
END_VAR
  FOR i := 0 TO 6 DO
    AfterLoop := table[i] + AfterLoop;
  END_FOR;
  IF extra = 0 THEN
    AfterLoop := AfterLoop + table[i];
  ELSE
    AfterLoop := AfterLoop + table[i - 1];
  END_IF;
END_FUNCTION

FUNCTION PastEnd : INT
VAR_INPUT
  dummy : INT;
END_VAR
VAR
  table : ARRAY[0..6] OF INT := [1, 2, 3, 4, 5, 6, 7];
  i : INT;
END_VAR
  FOR i := 0 TO 6 DO
    PastEnd := PastEnd + table[i] + dummy * table[i + 1];
  END_FOR;
END_FUNCTION

FUNCTION SpinInner : INT
VAR_INPUT
  n : INT;
END_VAR
VAR
  k : INT;
  j : INT;
END_VAR
  WHILE k < n DO
    FOR j := 1 TO 30000 DO
      k := k + 0;
    END_FOR;
  END_WHILE;
  SpinInner := k;
END_FUNCTION

FUNCTION_BLOCK Ratio
VAR_INPUT
  num : INT;
  den : INT;
END_VAR
VAR_OUTPUT
  q : INT;
  calls : INT;
END_VAR
  calls := calls + 1;
  q := num MOD den + num / den;
END_FUNCTION_BLOCK
"""

IMAGE_ST = """\
PROGRAM Main
VAR
  out0 AT %QW0 : WORD;
  out1 AT %QW1 : WORD;
  lamp AT %QX0.0 : BOOL;
END_VAR
VAR
  divisor : INT := 1;
  n : INT;
  q : INT;
END_VAR
  n := n + 1;
  out0 := INT_TO_WORD(n * 100);
  lamp := TRUE;
  q := 1000 / divisor;
  out1 := INT_TO_WORD(q);
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : Main;
  END_RESOURCE
END_CONFIGURATION
"""


def _line_of(src: str, needle: str) -> int:
    return next(i for i, line in enumerate(src.splitlines(), 1) if needle in line)


@pytest.fixture(scope="module")
def faults(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    path = tmp_path_factory.mktemp("faults") / "faults.st"
    path.write_text(FAULTS_ST, encoding="utf-8")
    mod = compile_files([path])
    mod.set_watchdog(50_000_000)  # 50 ms
    return mod


def _assert_at(exc: PlcFault, line: int) -> None:
    file, ln, col = exc.location.rsplit(":", 2)
    assert Path(file).name == "faults.st", exc.location
    assert int(ln) == line, f"fault at {exc.location}, expected line {line}: {exc}"
    assert int(col) >= 1


def test_division_by_zero(faults) -> None:  # type: ignore[no-untyped-def]
    assert faults.call("SafeDiv", -7, 2) == -3
    with pytest.raises(PlcFault) as ei:
        faults.call("SafeDiv", 5, 0)
    _assert_at(ei.value, _line_of(FAULTS_ST, "SafeDiv := a / b"))
    assert faults.call("SafeDiv", a=100, b=7) == 14  # the module still works


def test_division_by_zero_in_fb_keeps_instance_usable(faults) -> None:  # type: ignore[no-untyped-def]
    fb = faults.new_fb("Ratio")
    fb(num=7, den=2)
    assert fb.q == 1 + 3
    with pytest.raises(PlcFault) as ei:
        fb(num=7, den=0)
    _assert_at(ei.value, _line_of(FAULTS_ST, "q := num MOD den"))
    fb(num=-7, den=2)
    assert fb.q == -1 + -3


def test_array_index_out_of_range(faults) -> None:  # type: ignore[no-untyped-def]
    assert faults.call("Pick", 4) == 40
    for bad in (0, 5, -1, 32767):
        with pytest.raises(PlcFault) as ei:
            faults.call("Pick", bad)
        _assert_at(ei.value, _line_of(FAULTS_ST, "Pick := table[i]"))
    assert faults.call("Pick", i=1) == 10


def test_for_loop_indices_are_checked_where_the_range_is_unknown(faults) -> None:  # type: ignore[no-untyped-def]
    """A FOR loop with literal bounds whose variable nothing in it writes indexes without a
    check where its range fits the array; an index beyond it, a shifted one, a variable the
    body writes and the variable after the loop are still checked."""
    assert faults.call("SumShifted", 0) == 28
    assert faults.call("SumShifted", 1) == 35
    for bad in (2, -1):  # the last (first) iteration is out of bounds
        with pytest.raises(PlcFault) as ei:
            faults.call("SumShifted", bad)
        _assert_at(ei.value, _line_of(FAULTS_ST, "table[i + shift]"))
    assert faults.call("SkipAhead", 0) == 36
    assert faults.call("SkipAhead", 1) == 1 + 3 + 5 + 7
    with pytest.raises(PlcFault) as ei:
        faults.call("SkipAhead", -9)  # i := -9 + 1: table[-8]
    _assert_at(ei.value, _line_of(FAULTS_ST, "SkipAhead := SkipAhead + table[i]"))
    assert faults.call("AfterLoop", 1) == 28 + 7
    with pytest.raises(PlcFault) as ei:
        faults.call("AfterLoop", 0)  # the loop leaves i = 7
    _assert_at(ei.value, _line_of(FAULTS_ST, "AfterLoop := AfterLoop + table[i];"))
    with pytest.raises(PlcFault) as ei:
        faults.call("PastEnd", 0)  # table[i + 1] at i = 6
    _assert_at(ei.value, _line_of(FAULTS_ST, "dummy * table[i + 1]"))


def test_endless_loop_hits_the_watchdog(faults) -> None:  # type: ignore[no-untyped-def]
    assert faults.call("Spin", 0) == 0
    with pytest.raises(PlcFault) as ei:
        faults.call("Spin", 1)
    loc_line = int(ei.value.location.rsplit(":", 2)[1])
    first = _line_of(FAULTS_ST, "WHILE k < n DO")
    assert first <= loc_line <= first + 2, ei.value.location  # inside the loop
    assert faults.call("Spin", -5) == 0  # and the module is usable again


def test_endless_loop_around_a_counted_loop_hits_the_watchdog(faults) -> None:  # type: ignore[no-untyped-def]
    """A FOR loop with literal bounds counts its iterations for the watchdog at once, before
    it runs: 30000 of every 30001 iterations are the FOR's, so the clock is read (and the
    budget found spent) there but once in 65536 outer iterations."""
    assert faults.call("SpinInner", 0) == 0
    with pytest.raises(PlcFault) as ei:
        faults.call("SpinInner", 1)
    _assert_at(ei.value, _line_of(FAULTS_ST, "FOR j := 1 TO 30000 DO"))


def _qw(mod, i: int) -> int:  # type: ignore[no-untyped-def]
    # struct: ix[8192] u8, qx[8192] u8, iw[1024] u16, qw[1024] u16, ... (native endian)
    buf = mod.image_buffer()
    off = 8192 + 8192 + 2 * 1024 + 2 * i
    return int(struct.unpack_from("=H", buf, off)[0])


def _qx(mod, i: int) -> int:  # type: ignore[no-untyped-def]
    return int(mod.image_buffer()[8192 + i])


def test_faulting_scan_restores_the_outputs(tmp_path: Path) -> None:
    path = tmp_path / "image.st"
    path.write_text(IMAGE_ST, encoding="utf-8")
    mod = compile_files([path])
    interval = mod.program.config.tasks[0].interval_ns
    mod.config_init()
    mod.run_task_index(0, 0)
    assert (_qw(mod, 0), _qw(mod, 1), _qx(mod, 0)) == (100, 1000, 1)
    inst = mod.instance("instance0")
    inst.divisor = 0
    with pytest.raises(PlcFault) as ei:
        mod.run_task_index(0, interval)  # writes %QW0 := 200, then divides by zero
    assert ei.value.location.rsplit(":", 2)[1] == str(_line_of(IMAGE_ST, "q := 1000 / divisor"))
    assert _qw(mod, 0) == 100, "%QW0 written by the faulting scan was not rolled back"
    assert _qw(mod, 1) == 1000
    assert _qx(mod, 0) == 1
    inst.divisor = 4
    mod.run_task_index(0, 2 * interval)
    assert (_qw(mod, 0), _qw(mod, 1)) == (inst.n * 100, 250)
