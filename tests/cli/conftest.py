"""The CLI suites' shared program: a counter with a located INT and a located REAL."""

from __future__ import annotations

from pathlib import Path

import pytest

PROGRAM = """
PROGRAM Main
VAR
  n : DINT;
  rate : REAL := 0.5;
END_VAR
VAR
  out AT %QW2 : INT;
  val AT %MD0 : REAL;
END_VAR
  n := n + 1;
  out := DINT_TO_INT(n);
  val := rate * DINT_TO_REAL(n);
END_PROGRAM
CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM inst0 WITH task0 : Main;
  END_RESOURCE
END_CONFIGURATION
"""


@pytest.fixture()
def prog(tmp_path: Path) -> Path:
    """A file holding PROGRAM (a whole CONFIGURATION: run, serve and export take it)."""
    p = tmp_path / "prog.st"
    p.write_text(PROGRAM)
    return p
