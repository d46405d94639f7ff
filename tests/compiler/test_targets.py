"""`armbench check --target`: the severity of the dialect rules, and the library clean for
every target.

The rules themselves are checked against the diagnostics corpus (test_diagnostics.py: one
positive and one negative case per code, per target) and against the real tools: MatIEC
(test_diagnostics.test_matiec_rejects), STruC++ (test_strucpp_verdicts.py) and RuSTy
(tests/export/test_rusty.py).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from armbench.compiler.diagnostics import CompileFailed
from armbench.compiler.driver import analyse_program, emit_files
from armbench.compiler.reserved import codesys_family_reserves, matiec_reserves
from armbench.compiler.targets import (
    ALL,
    CODESYS,
    CODESYS_ONLY,
    OPENPLC,
    OPENPLC_ONLY,
    OPENPLC_V4,
    OPENPLC_V4_ONLY,
    SOFT_PLC,
    Target,
)
from armbench.locate import default_project


def test_targets_by_name() -> None:
    assert Target.named("all") == ALL and ALL.dialects == {OPENPLC, OPENPLC_V4, CODESYS}
    assert Target.named(" OpenPLC ") == OPENPLC_ONLY and OPENPLC_ONLY.name == "openplc"
    assert Target.named("OpenPLC-v4") == OPENPLC_V4_ONLY and OPENPLC_V4_ONLY.name == "openplc-v4"
    assert Target.named("codesys") == CODESYS_ONLY and ALL.name == "all"
    with pytest.raises(ValueError, match="unknown target 'twincat': use openplc, openplc-v4, "
                       "codesys, all"):
        Target.named("twincat")


@pytest.mark.parametrize(("target", "refused_by", "warned_by", "want"), [
    (ALL, {CODESYS}, set(), "error"),
    (CODESYS_ONLY, {CODESYS}, set(), "error"),
    (OPENPLC_ONLY, {CODESYS}, set(), "warning"),  # builds where it runs, not everywhere
    (CODESYS_ONLY, {OPENPLC}, set(), "warning"),
    (OPENPLC_ONLY, {OPENPLC, CODESYS}, set(), "error"),
    (ALL, set(), {CODESYS}, "warning"),  # RuSTy only warns: so do we
    (CODESYS_ONLY, set(), {CODESYS}, "warning"),
    (OPENPLC_ONLY, set(), {CODESYS}, None),
    (ALL, set(), set(), None),
    (OPENPLC_V4_ONLY, {OPENPLC_V4}, set(), "error"),  # what STruC++ refuses or miscompiles
    (OPENPLC_ONLY, {OPENPLC_V4}, set(), "warning"),
    (CODESYS_ONLY, {OPENPLC_V4}, set(), "warning"),
    (OPENPLC_V4_ONLY, {OPENPLC}, set(), "warning"),
])
def test_severity(target: Target, refused_by: set[str], warned_by: set[str],
                  want: str | None) -> None:
    assert target.severity(frozenset(refused_by), frozenset(warned_by)) == want


@pytest.mark.parametrize(("target", "want"), [
    (ALL, "error"), (OPENPLC_ONLY, "error"),  # a check for OpenPLC, or its upload (export)
    (CODESYS_ONLY, "warning"),  # CODESYS takes any name
    (SOFT_PLC, "warning"),  # build/run/serve: OpenPLC's rules, but nothing is uploaded
])
def test_upload_severity(target: Target, want: str) -> None:
    """What only OpenPLC's upload refuses (the names Config0 and Res0)."""
    assert target.upload_severity(frozenset({OPENPLC})) == want
    assert SOFT_PLC.severity(frozenset({OPENPLC})) == "error"  # the compiler's own rules stay
    assert SOFT_PLC.name == "openplc" and SOFT_PLC != OPENPLC_ONLY


@pytest.mark.parametrize(("target", "want"), [
    (ALL, "error"),  # the code cannot mean the same on both
    (OPENPLC_ONLY, "warning"),
    (OPENPLC_V4_ONLY, "warning"),
    (CODESYS_ONLY, None),
])
def test_severity_between(target: Target, want: str | None) -> None:
    """A construct MatIEC and STruC++ both build, with different values (E0312)."""
    assert target.severity_between(frozenset({OPENPLC, OPENPLC_V4})) == want


@pytest.mark.parametrize("name", ["Bit", "bit", "BIT", "Cal", "S", "R", "Ld", "Get", "Endif",
                                  "ATAN2", "Round", "Lower_Bound", "LTIME", "Namespace",
                                  "REAL_TRUNC_DINT", "TO_BIG_ENDIAN", "LINT_TO_BCD_WORD"])
def test_names_other_dialects_reserve(name: str) -> None:
    assert not matiec_reserves(name)
    assert codesys_family_reserves(name) is not None


@pytest.mark.parametrize("name", ["ChannelBit", "ArcTan2", "Calibration", "Terms", "Coord",
                                  "Turns", "Reset", "DegToRad", "Vec3", "REAL_TO_Q16"])
def test_names_no_dialect_reserves(name: str) -> None:
    assert not matiec_reserves(name)
    assert codesys_family_reserves(name) is None


def test_a_function_name_is_reserved_for_pous_only() -> None:
    round_, bit = codesys_family_reserves("Round"), codesys_family_reserves("Bit")
    assert round_ is not None and not round_.every_name
    assert bit is not None and bit.every_name


@pytest.mark.parametrize("target", [ALL, OPENPLC_ONLY, OPENPLC_V4_ONLY, CODESYS_ONLY],
                         ids=lambda t: t.name)
def test_library_and_controller_are_clean(target: Target) -> None:
    """st/, plc_project/controller/ and Controller.st: no error and no warning, whatever the
    target (what `armbench check --target all` checks without files)."""
    analysis = analyse_program(default_project().sources(), target=target)
    assert [d.render() for d in analysis.diagnostics.sorted()] == []
    assert analysis.program is not None


def test_the_soft_plc_compiles_any_configuration_name(tmp_path: Path) -> None:
    """The Python API compiles for the soft PLC, as `armbench run` does: a CONFIGURATION not
    named Config0 is a warning there, an error when compiling for OpenPLC's upload."""
    src = tmp_path / "plant.st"
    src.write_text("PROGRAM Main\n  VAR n : DINT; END_VAR\n  n := n + 1;\nEND_PROGRAM\n"
                   "CONFIGURATION Plant\n  RESOURCE Res0 ON PLC\n"
                   "    TASK T1(INTERVAL := T#10ms, PRIORITY := 0);\n"
                   "    PROGRAM Inst WITH T1 : Main;\n  END_RESOURCE\nEND_CONFIGURATION\n")
    prog, _ = emit_files([src])
    assert prog.config is not None and prog.config.name == "Plant"
    with pytest.raises(CompileFailed, match="needs it to be named Config0"):
        emit_files([src], target=OPENPLC_ONLY)
