"""A program compiled as several translation units (build.py: one C compiler per CPU, then one
library) behaves as when compiled as one: the runtime's state (the fault jump, the clock, the
watchdog) and the POU bodies are shared between the units, a unit the C compiler rejects is
named in the error, and processes building the same program at once all get it."""

from __future__ import annotations

import dataclasses
import os
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

from armbench.compiler.build import BuildError, BuiltLibrary, build, plan_units
from armbench.compiler.driver import emit_files
from armbench.compiler.ffi import Module
from armbench.faults import PlcFault

PROGRAM = """\
FUNCTION Half : DINT
VAR_INPUT
  X : DINT;
END_VAR
  Half := 100 / X;
END_FUNCTION

FUNCTION_BLOCK Looper
VAR_INPUT
  Spin : BOOL;
END_VAR
VAR_OUTPUT
  Count : DINT;
END_VAR
VAR CONSTANT
  Stride : DINT := 7;
END_VAR
  Count := Count + Stride;
  WHILE Spin DO
    Count := Count + 0;
  END_WHILE;
END_FUNCTION_BLOCK

FUNCTION_BLOCK Clock
VAR_INPUT
  Go : BOOL;
END_VAR
VAR_OUTPUT
  Elapsed : TIME;
END_VAR
VAR
  T : TON;
END_VAR
  T(IN := Go, PT := T#1h);
  Elapsed := T.ET;
END_FUNCTION_BLOCK

PROGRAM Main
VAR
  Divisor : DINT := 4;
  Result : DINT;
  Scans : DINT;
  Spin : BOOL;
  L : Looper;
  C : Clock;
END_VAR
VAR
  Flag AT %MX0.0 : BOOL;
  Out AT %QW0 : WORD;
END_VAR
  Scans := Scans + 1;
  Out := DINT_TO_WORD(Scans);
  Flag := NOT Flag;
  Result := Half(Divisor);
  L(Spin := Spin);
  C(Go := TRUE);
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM inst0 WITH task0 : Main;
  END_RESOURCE
END_CONFIGURATION
"""
MS = 1_000_000
POUS = 4  # Half, Looper, Clock, Main: one unit each below


@pytest.fixture
def source(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("ARMBENCH_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "split.st"
    path.write_text(PROGRAM)
    return path


def load(source: Path, jobs: int) -> tuple[Module, BuiltLibrary]:
    prog, unit = emit_files([source])
    lib = build(unit, jobs=jobs, min_unit_bytes=1)
    mod = Module(prog, lib, unit.decls)
    mod.config_init()
    return mod, lib


def qw0(mod: Module) -> int:
    # plc_image_t: ix[8192] u8, qx[8192] u8, iw[1024] u16, then qw (native endian)
    return int(struct.unpack_from("=H", mod.image_buffer(), 8192 + 8192 + 2 * 1024)[0])


def division_line() -> int:
    return PROGRAM.splitlines().index("  Half := 100 / X;") + 1


@pytest.mark.parametrize("jobs", [1, POUS])
def test_scans_give_the_same_values_in_one_unit_or_one_per_pou(source: Path, jobs: int) -> None:
    mod, lib = load(source, jobs)
    assert lib.units == jobs
    for scan in range(3):
        mod.run_task_index(0, scan * 10 * MS)
    main = mod.instance("inst0")
    assert main.get("Scans") == 3
    assert main.get("Result") == 100 // 4
    assert main.get("Flag") is True  # toggled three times: storage outside the Modbus map
    assert qw0(mod) == 3
    assert main.get("L")["Count"] == 3 * 7  # the constant lives in Looper's unit
    assert mod.new_fb("Looper").get("Stride") == 7  # and is read by name from the library
    # TON in Clock's unit reads the clock the entry point (in the main unit) set
    assert main.get("C")["Elapsed"] == 20 * MS


def test_a_fault_in_another_unit_returns_to_the_scan_entry(source: Path) -> None:
    mod, _ = load(source, POUS)
    mod.run_task_index(0, 0)
    main = mod.instance("inst0")
    main.set(Divisor=0)
    with pytest.raises(PlcFault) as fault:
        mod.run_task_index(0, 10 * MS)
    assert "division by zero" in str(fault.value)
    assert fault.value.location.endswith(f"split.st:{division_line()}:11")
    assert qw0(mod) == 1  # the faulting scan's outputs rolled back
    main.set(Divisor=5)
    mod.run_task_index(0, 20 * MS)  # the jump back is set up again by the next scan
    assert main.get("Result") == 20
    assert qw0(mod) == 3


def test_the_watchdog_set_in_the_main_unit_stops_a_loop_in_another(source: Path) -> None:
    mod, _ = load(source, POUS)
    mod.set_watchdog(20 * MS)
    mod.instance("inst0").set(Spin=True)
    start = time.monotonic()
    with pytest.raises(PlcFault) as fault:
        mod.run_task_index(0, 0)
    # a unit with a copy of its own would still have the default budget of one second
    assert time.monotonic() - start < 0.5
    assert "watchdog" in str(fault.value)


def test_a_unit_the_compiler_rejects_is_named_and_kept(source: Path, tmp_path: Path) -> None:
    _, unit = emit_files([source])
    bad = dataclasses.replace(unit, code=unit.code + "/* broken */\n",
                              pieces=[*unit.pieces[:-1], unit.pieces[-1] + "not C at all;\n"])
    with pytest.raises(BuildError) as err:
        build(bad, jobs=POUS, min_unit_bytes=1)
    message = str(err.value)
    named = Path(message.split("(", 1)[1].split(")", 1)[0])
    assert named.name == f"unit{POUS - 1}.c", message
    assert "not C at all" in named.read_text()
    assert "error" in message
    assert list((tmp_path / "cache").glob("*.so")) == []


def test_units_are_runs_of_consecutive_pieces_of_about_equal_size() -> None:
    pieces = [f"/*{i}*/" + "x" * size for i, size in
              enumerate([5, 300, 40, 40, 40, 700, 10, 10, 200, 60, 60, 60])]
    total = sum(map(len, pieces))
    for jobs in range(1, 8):
        groups = plan_units(pieces, jobs, min_unit_bytes=100)
        assert [p for g in groups for p in g] == pieces
        assert 1 <= len(groups) <= min(jobs, total // 100)
        share = total / len(groups)
        assert all(sum(map(len, g)) <= share + max(map(len, pieces)) for g in groups)
    assert plan_units(pieces, 8, min_unit_bytes=total) == [pieces]  # small: one unit
    assert plan_units([], 4) == [[]]


BUILD_ONE = """
import sys
from pathlib import Path
from armbench.compiler.build import build
from armbench.compiler.driver import emit_files
_, unit = emit_files([Path(sys.argv[1])])
print(build(unit, jobs=4, min_unit_bytes=1).path)
"""


def test_processes_building_the_same_program_at_once_all_get_it(source: Path,
                                                                 tmp_path: Path) -> None:
    sim = Path(__file__).resolve().parents[2] / "sim"
    env = {**os.environ, "PYTHONPATH": str(sim), "ARMBENCH_CACHE": str(tmp_path / "cache")}
    procs = [subprocess.Popen([sys.executable, "-c", BUILD_ONE, str(source)], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(3)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0, 0], [err for _, err in outs]
    libs = {out.strip() for out, _ in outs}
    assert len(libs) == 1
    cache = tmp_path / "cache"
    left = sorted(p.name for p in cache.iterdir() if p.name != "units")
    stem = Path(libs.pop()).stem
    assert left == [f"{stem}.c", f"{stem}.so", f"{stem}_ffi.py"]  # no temporary left behind
