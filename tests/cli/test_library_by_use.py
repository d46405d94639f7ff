"""The armbench library is added by use: a user's program gets exactly the library TYPEs and
POUs it refers to, its own declarations of library names do not break anything it does not
use, a real clash is one line, and deep nesting is a diagnostic with the library added too."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from armbench.cli import main

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "compiler"))
from st_deep import program  # noqa: E402

CONFIG = """
CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM inst0 WITH task0 : Main;
  END_RESOURCE
END_CONFIGURATION
"""

# Each declares a name the library declares too (st/ArmAngles.st, st/Kinematics.st), in its
# own spelling and shape, and uses nothing of the library.
OWN_DECLARATIONS = {
    "VEC3": "TYPE\n  VEC3 : ARRAY[1..3] OF REAL;\nEND_TYPE\n",
    "Mat4": "TYPE\n  Mat4 : ARRAY[0..15] OF REAL;\nEND_TYPE\n",
    "Coordinates": "TYPE\n  Coordinates : STRUCT\n    Lat : REAL;\n    Lon : REAL;\n"
                   "  END_STRUCT;\nEND_TYPE\n",
    "DegToRad": "FUNCTION DegToRad : REAL\n  VAR_INPUT\n    D : DINT;\n  END_VAR\n"
                "  DegToRad := DINT_TO_REAL(D) * 0.0174533;\nEND_FUNCTION\n",
}
USE = {"VEC3": "v : VEC3;", "Mat4": "v : Mat4;", "Coordinates": "v : Coordinates;",
       "DegToRad": "v : REAL;"}
BODY = {"VEC3": "v[1] := 1.0;", "Mat4": "v[0] := 1.0;", "Coordinates": "v.Lat := 1.0;",
        "DegToRad": "v := DegToRad(n);"}


def own_program(name: str) -> str:
    return (OWN_DECLARATIONS[name] + "\nPROGRAM Main\nVAR\n  n : DINT;\n  " + USE[name]
            + "\nEND_VAR\n  n := n + 1;\n  " + BODY[name] + "\nEND_PROGRAM\n" + CONFIG)


def summary(err: str) -> str:
    return err.strip().splitlines()[-1]


@pytest.mark.parametrize("name", sorted(OWN_DECLARATIONS))
def test_own_declaration_of_a_library_name_checks_runs_and_exports(
        name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "mine.st"
    src.write_text(own_program(name))
    pous = 2 if name == "DegToRad" else 1
    assert main(["check", str(src)]) == 0
    out, err = capsys.readouterr()
    assert out == ""
    assert summary(err) == f"checked 1 file, {pous} POU{'s' if pous > 1 else ''}: 0 errors"
    assert main(["run", str(src), "--cycles", "3", "--dump"]) == 0
    out, err = capsys.readouterr()
    assert '"n": 3' in out and err == ""
    assert main(["export", str(src), "--out", str(tmp_path / "out")]) == 0
    upload = (tmp_path / "out" / "openplc" / "Main.st").read_text(encoding="utf-8")
    # only the user's program: no library file was needed
    assert "st/ArmAngles.st" not in upload and "ArmAngles" not in upload


def test_library_declarations_used_are_added_beside_own_names(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # VEC3 is the program's; DegToRad and ArcTan2 (case as the user spells it) come from the
    # library, without the library's Vec3
    src = tmp_path / "mine.st"
    src.write_text(own_program("VEC3").replace(
        "v[1] := 1.0;", "v[1] := DEGTORAD(90.0);\n  v[2] := arctan2(v[1], 1.0);"))
    assert main(["run", str(src), "--cycles", "1", "--dump"]) == 0
    out, _ = capsys.readouterr()
    v = [float(x) for x in re.search(r'"v": \[([^\]]*)\]', out).group(1).split(",")]  # type: ignore[union-attr]
    assert v[0] == pytest.approx(1.5707963, abs=1e-6)  # pi/2
    assert v[1] == pytest.approx(1.0038848, abs=1e-6)  # atan2(pi/2, 1)
    assert main(["check", str(src)]) == 0
    assert summary(capsys.readouterr().err) == (
        "checked 2 files (1 from the armbench library), 3 POUs: 0 errors")


def test_a_real_clash_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the program's Mat4 has 16 elements in one dimension; the library's MatMul4, which it
    # calls, indexes Mat4 in two
    src = tmp_path / "mine.st"
    src.write_text(own_program("Mat4").replace(
        "  v : Mat4;", "  v : Mat4;\n  w : Mat4;").replace("v[0] := 1.0;", "w := MatMul4(v, v);"))
    assert main(["check", str(src)]) == 1
    out, err = capsys.readouterr()
    lines = out.strip().splitlines()
    assert len(lines) == 1, out
    assert re.fullmatch(r".*mine\.st:2:3: error\[E0213\]: your TYPE Mat4 replaces the armbench "
                        r"library's declaration of the same name \(ArmAngles\.st\), but the "
                        r"library's MatMul4, which your program uses, needs the library's own: "
                        r"rename yours, or check with --no-library and pass the library files "
                        r"you need", lines[0]), lines[0]
    assert summary(err) == "checked 2 files (1 from the armbench library): 1 error"
    # renamed, it checks
    src.write_text(src.read_text().replace("Mat4 : ARRAY[0..15]", "Flat16 : ARRAY[0..15]")
                   .replace("v : Mat4;\n  w : Mat4;", "v : Flat16;\n  w : Mat4;")
                   .replace("w := MatMul4(v, v);", "w := MatMul4(w, w);"))
    # (for OpenPLC v3: a 2-D array in a PROGRAM's state is E0511 for v4's debugger table)
    assert main(["check", "--target", "openplc", str(src)]) == 0, capsys.readouterr()
    assert main(["check", str(src)]) == 1
    assert "error[E0511]: w " in capsys.readouterr().out


def test_atan2_is_e0400_with_and_without_the_library(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the lab's angle.st: the library's two-argument arc tangent is ArcTan2, a name no dialect
    # reserves (CODESYS and RuSTy declare ATAN2 themselves, MatIEC has none), so ATAN2 stays
    # unknown with the library too and the message points at the library's name
    src = tmp_path / "angle.st"
    src.write_text("FUNCTION P2Angle : REAL\n  VAR_INPUT\n    X : REAL;\n    Z : REAL;\n"
                   "  END_VAR\n  P2Angle := ATAN2(Z, X);\nEND_FUNCTION\n")
    message = ("angle.st:6:14: error[E0400]: ATAN2 is not an IEC standard function: MatIEC has "
               "none (use the library's ArcTan2)")
    for library in ([], ["--no-library"]):
        assert main(["check", *library, str(src)]) == 1
        out, err = capsys.readouterr()
        assert out.strip().endswith(message), out
        assert summary(err) == "checked 1 file: 1 error"
    src.write_text(src.read_text().replace("ATAN2(Z, X)", "ArcTan2(Z, X)"))
    assert main(["check", str(src)]) == 0
    assert summary(capsys.readouterr().err) == (
        "checked 2 files (1 from the armbench library), 2 POUs: 0 errors")


@pytest.mark.parametrize(("construct", "n"), [("if", 491), ("paren", 982), ("not", 3000)])
def test_deep_nesting_with_the_library_is_one_diagnostic(
        construct: str, n: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "deep.st"
    src.write_text(program(construct, n))
    assert main(["check", str(src)]) == 1
    out, err = capsys.readouterr()
    assert "internal error" not in err
    lines = out.strip().splitlines()
    assert len(lines) == 1 and re.search(r"deep\.st:\d+:\d+: error\[E0108\]", lines[0]), out
