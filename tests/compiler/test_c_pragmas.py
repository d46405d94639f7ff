"""A {pragma} with C that OpenPLC v3 builds: `check --target openplc` accepts it, the bench's soft
PLC (build, run, the pytest plugin) refuses it with E0103 instead of skipping the C silently.
The OpenPLC verdicts of the corpus files are cross-checked in test_diagnostics.py."""

from __future__ import annotations

import pytest
from st_corpus import DIAGNOSTICS

from armbench.compiler import CompileFailed, check_files
from armbench.compiler.driver import emit_files
from armbench.compiler.targets import OPENPLC_ONLY, SOFT_PLC

C_PRAGMAS = DIAGNOSTICS / "E0103_ok_pragma_c.st"


def test_openplc_check_accepts_c_pragmas() -> None:
    assert [d.render() for d in check_files([C_PRAGMAS], target=OPENPLC_ONLY)] == []


def test_soft_plc_refuses_c_pragmas() -> None:
    ds = [d for d in check_files([C_PRAGMAS], target=SOFT_PLC) if d.severity == "error"]
    # the three pragmas with C (two in the FUNCTION, one in the FB); not the comment-only one
    # in the PROGRAM, nor the one outside any POU (declarations only)
    assert [(d.code, d.pos.line) for d in ds] == [("E0103", 13), ("E0103", 16), ("E0103", 30)]
    assert "soft PLC cannot run the C" in ds[0].message
    with pytest.raises(CompileFailed):
        emit_files([C_PRAGMAS])
