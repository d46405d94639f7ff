"""A program with STRINGs in the soft PLC, seen as a user's tests see it: its STRINGs are
computed in every scan (MatIEC's functions, see tests/corpus/semantics/strings.st), the
located integers derived from them are read and written over Modbus by name (plc_vars), and
the STRINGs themselves show in the soft PLC's view of the instance. OpenPLC's Modbus maps no
STRING, so a STRING is never located (E0600) and plc_vars has none."""

from __future__ import annotations

from pathlib import Path

import pytest

from armbench.compiler import check_files
from armbench.harness.program import PlcProgram, UnknownVariable, serve_program

PROGRAM = """
PROGRAM Main
VAR
  Code AT %MW100 : INT;
  MsgLen AT %MW101 : INT;
  Found AT %MW102 : INT;
  Parsed AT %MW103 : INT;
END_VAR
VAR
  msg : STRING;
  tail : STRING;
END_VAR
  msg := CONCAT('Code ', INT_TO_STRING(Code));
  MsgLen := LEN(msg);
  Found := FIND(msg, '42');
  tail := RIGHT(msg, MsgLen - 5);
  Parsed := STRING_TO_INT(tail) + 1;
END_PROGRAM
CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK MainTask(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM instance0 WITH MainTask : Main;
  END_RESOURCE
END_CONFIGURATION
"""


@pytest.fixture(scope="module")
def program(tmp_path_factory: pytest.TempPathFactory) -> PlcProgram:
    path = tmp_path_factory.mktemp("strings") / "strings.st"
    path.write_text(PROGRAM, encoding="utf-8")
    return PlcProgram.load([path], library=False)


def test_strings_run_in_the_soft_plc(program: PlcProgram) -> None:
    with serve_program(program) as plc, plc.connect() as v:
        v["Code"] = 42
        v.wait_scans(2)
        assert v["MsgLen"] == len("Code 42")
        assert v["Found"] == 6  # MatIEC: 'Code 42' has '42' from its 6th character
        assert v["Parsed"] == 43
        assert plc.soft is not None
        view = plc.soft.instance_vars("instance0")
        assert view["msg"] == "Code 42"
        assert view["tail"] == "42"
        v["Code"] = -7
        v.wait_scans(2)
        assert plc.soft.instance_vars("instance0")["msg"] == "Code -7"
        assert v["Parsed"] == -6
        with pytest.raises(UnknownVariable):
            v["msg"]  # not located: Modbus does not reach it


def test_a_located_string_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "located.st"
    path.write_text(PROGRAM.replace("  msg : STRING;\n", "").replace(
        "  Code AT %MW100 : INT;", "  Code AT %MW100 : INT;\n  msg AT %MW104 : STRING;"),
        encoding="utf-8")
    codes = [d.code for d in check_files([path])]
    assert "E0600" in codes, codes
