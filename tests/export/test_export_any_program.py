"""`armbench export` of a user's program: named after it, holding only the library
declarations it uses; a library-only export (blocks and types, no program) for CODESYS;
messages that name the files as the user gave them."""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest
from lxml import etree

from armbench.cli import main
from armbench.compiler import check_files, compile_files

REPO = Path(__file__).resolve().parents[2]
SCHEMA = REPO.parent / "shared" / "schemas" / "tc6_xml_v201.xsd"
N = {"p": "http://www.plcopen.org/xml/tc6_0201"}

BLINK = """\
(* A 20-line user program: counts scans, converts an angle with the library. *)
PROGRAM Blink
  VAR
    Count AT %MD0 : DINT;   (* scans since start *)
    Lamp AT %QX0.0 : BOOL;  (* toggles every 10 scans *)
    Angle AT %MD1 : REAL;   (* rad *)
  END_VAR
  Count := Count + 1;
  Lamp := (Count MOD 20) < 10;
  Angle := DegToRad(90.0);
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK Main(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM Inst0 WITH Main : Blink;
  END_RESOURCE
END_CONFIGURATION
"""

BLOCKS = """\
(* A user's block: an angle in degrees to radians, times a gain. *)
FUNCTION_BLOCK GainRad
  VAR_INPUT
    Deg : REAL;
    Gain : REAL := 1.0;
  END_VAR
  VAR_OUTPUT
    Rad : REAL;
  END_VAR
  Rad := Gain * DegToRad(Deg);
END_FUNCTION_BLOCK
"""


def pous(text: str) -> list[str]:
    return re.findall(r"^(?:FUNCTION_BLOCK|FUNCTION|PROGRAM) (\w+)", text, re.M)


def library_pous() -> set[str]:
    """Every FUNCTION and FUNCTION_BLOCK of st/*.st, read with a regular expression."""
    return {name for f in (REPO / "st").glob("*.st")
            for name in re.findall(r"^(?:FUNCTION_BLOCK|FUNCTION) (\w+)", f.read_text(), re.M)}


@pytest.fixture()
def work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    (tmp_path / "Blink.st").write_text(BLINK)
    (tmp_path / "Blocks.st").write_text(BLOCKS)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_user_program_export_is_named_after_it_and_holds_what_it_uses(
        work: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["export", "Blink.st", "--out", "out"]) == 0
    assert sorted(p.relative_to(work / "out").as_posix() for p in (work / "out").rglob("*.*")) \
        == ["codesys/Blink_codesys.xml", "codesys/register-map.md", "openplc-v4/Blink/pous/"
            "functions/DegToRad.st", "openplc-v4/Blink/pous/programs/Blink.st",
            "openplc-v4/Blink/project.json", "openplc/Blink.st", "plcopen/Blink.xml"]
    upload = (work / "out" / "openplc" / "Blink.st").read_text()
    header = upload.split("*)", 1)[0]
    assert "upload file of the program Blink" in header and "arm controller" not in header
    assert pous(upload) == ["DegToRad", "Blink"]
    assert len(upload.encode()) < 4000  # 2.4 KB: the program, one library function, header
    xml = etree.fromstring((work / "out" / "plcopen" / "Blink.xml").read_bytes())
    assert [p.get("name") for p in xml.iterfind(".//p:pou", N)] == ["DegToRad", "Blink"]
    assert xml.find("p:contentHeader", N).get("name") == "Blink"
    register_map = (work / "out" / "codesys" / "register-map.md").read_text()
    assert "`Blink_codesys.xml`" in register_map and "arm_controller" not in register_map
    # the upload stands alone: it checks and compiles without the library
    assert check_files([work / "out" / "openplc" / "Blink.st"]) == []
    assert compile_files([work / "out" / "openplc" / "Blink.st"]) is not None


def test_name_option(work: Path) -> None:
    assert main(["export", "Blink.st", "--out", "out", "--name", "lamp_demo"]) == 0
    assert (work / "out" / "openplc" / "lamp_demo.st").is_file()
    assert (work / "out" / "codesys" / "lamp_demo_codesys.xml").is_file()


def test_block_only_file_without_library_only_is_refused_in_one_line(
        work: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["export", "Blocks.st", "--out", "out"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert "Blocks.st declares no CONFIGURATION" in err[0] and "--library-only" in err[0]
    assert "/" not in err[0].split("declares")[0]  # the path as given, nothing else
    assert not (work / "out").exists()


def test_library_only_export_of_the_users_blocks(work: Path) -> None:
    assert main(["export", "--library-only", "Blocks.st", "--out", "out"]) == 0
    xml = etree.fromstring((work / "out" / "codesys" / "Blocks.xml").read_bytes())
    assert sorted((p.get("name"), p.get("pouType")) for p in xml.iterfind(".//p:pou", N)) == \
        [("DegToRad", "function"), ("GainRad", "functionBlock")]
    assert xml.find(".//p:configuration", N) is None


def test_library_only_export_of_the_armbench_library(work: Path) -> None:
    assert main(["export", "--library-only", "--out", "out"]) == 0
    data = (work / "out" / "codesys" / "armbench_library.xml").read_bytes()
    xml = etree.fromstring(data)
    kinds = {p.get("pouType") for p in xml.iterfind(".//p:pou", N)}
    assert kinds == {"function", "functionBlock"}  # no program
    assert {p.get("name") for p in xml.iterfind(".//p:pou", N)} == library_pous()
    assert xml.find(".//p:configuration", N) is None
    assert len(xml.findall(".//p:dataType", N)) > 10
    if SCHEMA.is_file():  # beside the repository in CI
        xsd = etree.XMLSchema(etree.parse(str(SCHEMA)))
        assert xsd.validate(xml), "\n".join(str(e) for e in xsd.error_log)


def test_library_only_refuses_a_program(work: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["export", "--library-only", "Blink.st", "--out", "out"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "PROGRAM Blink" in err[0] and "CONFIGURATION Config0" in err[0]


def test_user_upload_accepted_by_matiec(work: Path) -> None:
    tool = os.environ.get("MATIEC_CHECK", "")
    if not tool or not Path(tool).is_file():
        pytest.skip("MATIEC_CHECK (e.g. /opt/realplc/check-st.sh) not set or missing")
    assert main(["export", "Blink.st", "--out", "out"]) == 0
    res = subprocess.run([tool, str(work / "out" / "openplc" / "Blink.st")],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout + res.stderr
