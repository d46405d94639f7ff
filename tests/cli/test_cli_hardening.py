"""The command line with bad input: one-line usage errors (rc 2), the library added by use
without duplicate definitions, export only where asked, check's summary line."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from armbench.cli import main

REPO = Path(__file__).resolve().parents[2]
LIBRARY = sorted((REPO / "st").glob("*.st"))
# the controller's blocks: added to a user's files only when they use one of them
BLOCKS = sorted((REPO / "plc_project" / "controller").glob("*.st"))
CONTROLLER = REPO / "plc_project" / "Controller.st"
EXPORTS = [REPO / "plc_project" / "openplc" / "arm_controller.st",
           REPO / "plc_project" / "plcopen" / "arm_controller.xml"]

NO_CONFIG = """FUNCTION Twice : REAL
  VAR_INPUT X : REAL; END_VAR
  Twice := X * 2.0;
END_FUNCTION
"""
# a POU header, not a CONFIGURATION's `PROGRAM inst WITH task : Type;`
_POU = re.compile(r"^\s*(FUNCTION_BLOCK|FUNCTION|PROGRAM)\s+\w+\s*(:[^;]*)?$", re.MULTILINE)


def pous_in(paths: list[Path]) -> int:
    """POU headers counted in the text, independently of the compiler."""
    total = 0
    for p in paths:
        text = re.sub(r"\(\*.*?\*\)", "", p.read_text(encoding="utf-8"), flags=re.DOTALL)
        total += len(_POU.findall(text))
    return total


@pytest.mark.parametrize("argv, option", [
    (["serve", "{prog}", "--port", "99999"], "--port"),
    (["serve", "{prog}", "--port", "-1"], "--port"),
    (["serve", "{prog}", "--duration", "-1"], "--duration"),
    (["serve", "{prog}", "--duration", "nan"], "--duration"),
    (["run", "{prog}", "--cycles", "-5"], "--cycles"),
    (["run", "{prog}", "--cycles", "two"], "--cycles"),
    (["demo", "--points", "0"], "--points"),
    (["demo", "--radius", "-3"], "--radius"),
    (["frobnicate"], "frobnicate"),
])
def test_usage_errors_are_one_line_rc_2(argv: list[str], option: str, prog: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    assert main([a.format(prog=prog) for a in argv]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and option in lines[0] and "error" in lines[0], err


def test_missing_file_is_one_line_rc_2(tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(tmp_path / "nope.st")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope.st" in err[0]


def test_check_ends_with_a_summary(prog: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(prog)]) == 0
    out, err = capsys.readouterr()
    assert out == ""
    # the program uses nothing of the library: nothing of it is added
    assert err.strip().splitlines()[-1] == "checked 1 file, 1 POU: 0 errors"
    assert main(["check", "--no-library", str(prog)]) == 0
    assert capsys.readouterr().err.strip() == "checked 1 file, 1 POU: 0 errors"
    assert main(["check"]) == 0  # no files: the library, the controller and its blocks
    assert capsys.readouterr().err.strip() == (
        f"checked {len(LIBRARY) + len(BLOCKS) + 1} files (the armbench library and "
        f"plc_project/Controller.st), {pous_in([*LIBRARY, *BLOCKS, CONTROLLER])} POUs: "
        "0 errors")


def test_check_summary_counts_errors(prog: Path, capsys: pytest.CaptureFixture[str]) -> None:
    prog.write_text(prog.read_text().replace("n := n + 1;", "n := n + 1.5;"))
    assert main(["check", "--no-library", str(prog)]) == 1
    out, err = capsys.readouterr()
    assert len(out.strip().splitlines()) == 1
    assert err.strip() == "checked 1 file: 1 error"


def test_run_controller_alone_takes_the_library(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(CONTROLLER), "--cycles", "2"]) == 0
    assert "ran 2 cycle(s)" in capsys.readouterr().out


def test_no_library_says_which_files_are_missing(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--no-library", str(CONTROLLER)]) == 1
    hint = capsys.readouterr().err.strip().splitlines()[-1]
    assert hint.startswith("armbench: note: unknown names are declared in the armbench library")
    # what Controller.st itself uses: library files and the controller's blocks
    for name in ("ArmAngles.st", "Kinematics.st", "PCA9685.st", "MailboxServer.st",
                 "ArmOutputStage.st"):
        assert name in hint


def test_library_given_by_the_user_is_not_added_twice(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", *map(str, LIBRARY), str(CONTROLLER), "--cycles", "1"]) == 0
    assert main(["check", str(REPO / "st"), str(CONTROLLER)]) == 0
    err = capsys.readouterr().err
    assert "E0201" not in err and "note" not in err


def test_users_modified_copy_replaces_the_library_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    original = REPO / "st" / "MG996R.st"
    extra = "\nFUNCTION ServoExtra : REAL\n  VAR_INPUT X : REAL; END_VAR\n" \
            "  ServoExtra := X;\nEND_FUNCTION\n"
    (tmp_path / "copy").mkdir()
    same_name = tmp_path / "MG996R.st"
    same_name.write_text(original.read_text(encoding="utf-8") + extra)
    unchanged = tmp_path / "copy" / "MG996R.st"
    unchanged.write_text(original.read_text(encoding="utf-8"))
    assert main(["check", str(unchanged), str(CONTROLLER)]) == 0
    pous = int(re.findall(r", (\d+) POUs: 0 errors$", capsys.readouterr().err)[-1])
    assert main(["check", str(same_name), str(CONTROLLER)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    # the user's copy (one POU more) instead of the library's: no duplicate declarations
    assert err[-1].endswith(f", {pous + 1} POUs: 0 errors")

    renamed = tmp_path / "my_servo.st"
    renamed.write_text(original.read_text(encoding="utf-8"))
    assert main(["run", str(renamed), str(CONTROLLER), "--cycles", "1"]) == 0
    err = capsys.readouterr().err
    # the controller's blocks that use the servo types get the user's copies of them
    assert re.search(r"^armbench: note: your (TYPE|FUNCTION) \w+, .* replace the armbench "
                     r"library's \(MG996R\.st\) in the library declarations you use: ", err,
                     re.M), err
    assert "E0201" not in err


def _committed() -> list[bytes]:
    return [p.read_bytes() for p in EXPORTS]


def test_export_never_touches_plc_project_unless_regenerating(
        prog: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = _committed()
    user = tmp_path / "user.st"
    user.write_text(prog.read_text())
    assert main(["export", str(user)]) == 2
    assert "--out" in capsys.readouterr().err
    assert main(["export", str(user), "--out", str(tmp_path / "out")]) == 0
    assert (tmp_path / "out" / "openplc" / "Main.st").is_file()  # named after its PROGRAM
    assert _committed() == before


def test_export_refuses_a_program_without_configuration(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = _committed()
    lib = tmp_path / "twice.st"
    lib.write_text(NO_CONFIG)
    out = tmp_path / "out"
    assert main(["export", str(lib), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no CONFIGURATION" in err[0]
    assert not out.exists() and _committed() == before


def test_regenerate_needs_a_checkout(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["export", "--regenerate"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not inside a checkout" in err[0]
    assert main(["export", "--regenerate", "--repo", str(tmp_path)]) == 2
    assert "is not a checkout" in capsys.readouterr().err
    # from inside the checkout (any subfolder) it verifies the committed exports
    monkeypatch.chdir(REPO / "docs")
    assert main(["export", "--regenerate", "--check"]) == 0


KEYWORD_NAMES = """PROGRAM Main
  VAR
    r : REAL;
    n : DINT;
  END_VAR
  n := n + 1;
  r := DINT_TO_REAL(n);
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM inst0 WITH task0 : Main;
  END_RESOURCE
END_CONFIGURATION
"""


def test_export_warns_what_codesys_refuses_and_still_exports(
        prog: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The export builds for OpenPLC; its CODESYS XML carries the same names, so a name
    CODESYS keeps as a keyword (R, IL's reset operator) is a warning there, not a failure."""
    user = tmp_path / "user.st"
    user.write_text(KEYWORD_NAMES)
    out = tmp_path / "out"
    assert main(["export", str(user), "--out", str(out)]) == 0
    assert (out / "openplc" / "Main.st").is_file()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2, err
    assert "CODESYS refuses this" in err[0] and "E0214" in err[0] and "'r'" in err[0].lower()
    assert "the OpenPLC upload is fine" in err[1] and "1 change " in err[1]
    clean = tmp_path / "clean.st"
    clean.write_text(prog.read_text())
    assert main(["export", str(clean), "--out", str(tmp_path / "out2")]) == 0
    assert "warning" not in capsys.readouterr().err
